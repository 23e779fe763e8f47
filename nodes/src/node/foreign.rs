//! The foreign node: the live source of a bench's own topics. It subscribes to the topics a
//! channel map names, with the types the map gives (std_msgs/msg/Float64, Float64MultiArray,
//! sensor_msgs/msg/JointState, geometry_msgs/msg/WrenchStamped built in; any other from a
//! `.msg` file the map lists), takes each message's raw CDR payload with its receive time, and
//! hands it to [`ForeignTopics`] (io: the one reader of a bench's messages, which a foreign bag
//! is read through too: decoding, alignment, a headerless topic timed by its receive time less
//! the reference's delay, the labels), publishing the aligned samples as forcemap `RigSample`s
//! on `samples`. With the map's `step` and `frequency_hz` labels, each sample carries its step
//! and each step's first sample follows an `ExcitationState` (a sine at the labelled frequency,
//! or random for 0; its amplitude unknown, NaN), and an IDLE state ends the run once no message
//! has come for [`RUN_END_SILENCE`]: run the harmonic node as for the rig's own sensor. Without
//! labels it publishes no `ExcitationState`: run the harmonic node with `find_steps:=true`.
//!
//! Parameters:
//! - the map, either `channels.NAME.{topic,type,field,scale,offset}` in the node's own
//!   parameters (a params file or a launch file), or `channels:=FILE` (a channel map file);
//! - `reliability`: `reliable` (default: no loss, matches reliable publishers only) or
//!   `best_effort` (matches any publisher);
//! - `min_subscribers` (1) and `startup_timeout_s` (20): the subscribers on `samples` to wait
//!   for before subscribing to the foreign topics (samples before that would be lost);
//! - `frame_id` (`rig`): the samples' header frame.
//!
//! A malformed message (it does not decode, or lacks a mapped field) and a message the alignment
//! leaves out are counted, logged (the first few and then every thousandth) and skipped: a
//! foreign participant cannot crash the node.

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_io::channel_map::{CHANNELS_KEY, ChannelMap};
use forcemap_io::foreign_topics::{ForeignTopics, Output, SampleLabels, step_of_labels};
use forcemap_io::steps::estimated_excitation;
use forcemap_io::topics;
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Channel;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;
use futures::StreamExt as _;
use ros2_client::{MessageTypeName, Name, QosProfile, qos::WhenFull};
use serde::de::{DeserializeSeed, Deserializer, SeqAccess, Visitor};
use tokio::sync::mpsc;

use crate::log_line;
use crate::node::harmonic::RUN_END_SILENCE;
use crate::ros::{NodeSetup, RosNode, publish_blocking, qos};

/// A message's payload as it came: the CDR encapsulation header and the bytes after it.
pub struct RawCdr(pub Vec<u8>);

/// Takes a payload byte by byte through the CDR deserializer (ros2-client's subscriptions
/// decode through serde; this seed asks for one `u8` after another until the input ends, so
/// no type is needed). The byte order is not visible through serde: it is read from the
/// deserializer's type name (RustDDS's `CdrDeserializer<BigEndian>` or `<LittleEndian>`) and
/// written back as the encapsulation header the dynamic decoder reads.
#[derive(Clone, Copy)]
pub struct RawCdrSeed;

struct BytesVisitor;

impl<'de> Visitor<'de> for BytesVisitor {
    type Value = Vec<u8>;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("the bytes of a CDR payload")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Vec<u8>, A::Error> {
        let mut out = Vec::new();
        // The end of the input is an error of the deserializer: it ends the payload.
        while let Ok(Some(b)) = seq.next_element::<u8>() {
            out.push(b);
        }
        Ok(out)
    }
}

impl<'de> DeserializeSeed<'de> for RawCdrSeed {
    type Value = RawCdr;

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<RawCdr, D::Error> {
        let big_endian = std::any::type_name::<D>().contains("BigEndian");
        let body = deserializer.deserialize_tuple(usize::MAX, BytesVisitor)?;
        let mut bytes = Vec::with_capacity(body.len() + 4);
        bytes.extend_from_slice(&[0, if big_endian { 0 } else { 1 }, 0, 0]);
        bytes.extend(body);
        Ok(RawCdr(bytes))
    }
}

/// The channel map from the node's parameters: `channels.*` entries, else `channels:=FILE`.
fn channel_map(setup: &NodeSetup) -> anyhow::Result<ChannelMap> {
    let p = &setup.params;
    let prefix = format!("{CHANNELS_KEY}.");
    if let Some((first, _)) = p.iter().find(|(n, _)| n.starts_with(&prefix)) {
        let origin = p
            .origin(first)
            .map_or_else(|| "the node's parameters".to_string(), str::to_string);
        return Ok(ChannelMap::from_params(p, &origin)?);
    }
    let file = p.opt_str(CHANNELS_KEY)?.context(
        "no channel map: give channels:=FILE or channels.NAME.{topic,type,field} parameters",
    )?;
    Ok(ChannelMap::read(Path::new(file))?)
}

/// Logs the first few reports of a kind, then every thousandth.
fn worth_logging(count: u64) -> bool {
    count <= 10 || count.is_multiple_of(1000)
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = &setup.params;
    let map = channel_map(&setup)?;
    let mut foreign = ForeignTopics::new(&map)?;
    let labelled = foreign.labelled();
    let driven = SetupKind::of_channels(|c| foreign.channels().contains(&c))?.driven_channel();
    let reliable = match p.opt_str("reliability")?.unwrap_or("reliable") {
        "reliable" => true,
        "best_effort" => false,
        other => bail!("reliability = '{other}': expected reliable or best_effort"),
    };
    let min_subscribers = p.opt_usize("min_subscribers")?.unwrap_or(1);
    let startup_timeout = p.opt_f64("startup_timeout_s")?.unwrap_or(20.0);
    let frame = p.opt_str("frame_id")?.unwrap_or("rig").to_string();

    let mut ros = RosNode::start(setup.clone())?;
    let samples_pub = ros.publisher::<RigSample>(topics::SAMPLES, qos::samples())?;
    let excitation_pub = match labelled {
        true => Some(ros.publisher::<ExcitationState>(topics::EXCITATION, qos::excitation())?),
        false => None,
    };
    let out_topic = setup.absolute_topic(topics::SAMPLES);
    let deadline = Instant::now() + Duration::from_secs_f64(startup_timeout);
    if !crate::ros::wait_for_subscribers(
        &ros.node,
        &samples_pub,
        min_subscribers,
        &out_topic,
        "min_subscribers",
        deadline,
        startup_timeout,
    )
    .await?
    {
        return Ok(());
    }

    // One task per foreign topic forwards its payloads into the node's loop.
    let (tx, mut rx) = mpsc::unbounded_channel::<(usize, Vec<u8>, i64)>();
    let reader_qos = if reliable {
        QosProfile::subscription_default().reliability_reliable(WhenFull::Block)
    } else {
        QosProfile::subscription_default().reliability_best_effort()
    }
    .history(ros2_client::qos::History::KeepLast {
        depth: qos::SAMPLES_READER_DEPTH,
    });
    for (k, t) in foreign.topics().iter().enumerate() {
        let name = Name::parse(&t.name).map_err(|e| anyhow::anyhow!("topic {}: {e:?}", t.name))?;
        let mut parts = t.type_name.split('/');
        let (pkg, ty) = (parts.next().unwrap_or(""), parts.next_back().unwrap_or(""));
        let topic = ros
            .node
            .create_topic(&name, MessageTypeName::new(pkg, ty), &reader_qos)
            .map_err(|e| anyhow::anyhow!("topic {}: {e:?}", t.name))?;
        let subscription = ros
            .node
            .create_subscription::<RawCdr>(&topic, Some(reader_qos.clone()))
            .map_err(|e| anyhow::anyhow!("subscription to {}: {e:?}", t.name))?;
        let tx = tx.clone();
        let topic_name = t.name.clone();
        tokio::spawn(async move {
            let stream = subscription.async_stream_seed(RawCdrSeed);
            futures::pin_mut!(stream);
            while let Some(m) = stream.next().await {
                match m {
                    Ok((RawCdr(bytes), info)) => {
                        // When the DDS reader received it (RustDDS stamps each incoming
                        // sample), not when this task ran: under load the task runs
                        // milliseconds late, and a topic without a header is timed by it.
                        let received = info
                            .received_timestamp()
                            .map_or_else(|| crate::ros::now_time().as_nanos(), |t| t.to_nanos());
                        if tx.send((k, bytes, received)).is_err() {
                            break;
                        }
                    }
                    Err(e) => log_line!("warning: receiving {topic_name}: {e:?}"),
                }
            }
        });
        log_line!(
            "subscribed to {} ({}{}): {}",
            t.name,
            t.type_name,
            if t.stamped {
                ", timed by its header stamps"
            } else {
                ", no header: timed by receive time"
            },
            map.sources()
                .filter(|(_, s)| s.topic == t.name)
                .map(|(e, s)| format!("{e} = {}", s.field.text))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    drop(tx);
    log_line!(
        "publishing aligned samples ({}) on {out_topic}{}",
        foreign
            .channels()
            .iter()
            .map(|c| c.name())
            .collect::<Vec<_>>()
            .join(", "),
        if labelled {
            ", each step's ExcitationState from the step and frequency_hz labels"
        } else {
            " (no labels: no ExcitationState)"
        }
    );

    let (mut published, mut malformed, mut misaligned) = (0u64, 0u64, 0u64);
    let mut steps = Steps::new(driven, frame.clone());
    let mut last_report = Instant::now();
    let mut out = Vec::new();
    // Once the stream has been quiet for the silence, the samples held for their labels are
    // handed out and the run ends (IDLE), once.
    let mut quiet_at: Option<tokio::time::Instant> = None;
    loop {
        let quiet = async {
            match quiet_at {
                Some(t) => tokio::time::sleep_until(t).await,
                None => std::future::pending().await,
            }
        };
        let received = tokio::select! {
            m = rx.recv() => m.map(Some),
            () = quiet => Some(None),
            () = crate::ros::shutdown_signal() => None,
        };
        let Some(received) = received else {
            break;
        };
        let ended = received.is_none();
        match received {
            Some((k, bytes, receive_ns)) => {
                foreign.push(k, &bytes, receive_ns, &mut out);
                quiet_at = Some(tokio::time::Instant::now() + RUN_END_SILENCE);
            }
            None => {
                foreign.flush(&mut out);
                quiet_at = None;
            }
        }
        for o in out.drain(..) {
            match o {
                Output::Sample {
                    t_ns,
                    values,
                    labels,
                } => {
                    let Some(step) = steps.of_sample(t_ns, labels) else {
                        continue;
                    };
                    if let (Some(state), Some(p)) = (step.starts, &excitation_pub) {
                        publish_blocking(p, state).await?;
                    }
                    let header = Header {
                        stamp: Time::from_nanos(t_ns),
                        frame_id: frame.clone(),
                    };
                    let mut s = RigSample::new(header, step.step);
                    for (c, v) in values {
                        s = s.with(c, v);
                    }
                    publish_blocking(&samples_pub, s).await?;
                    published += 1;
                }
                Output::Malformed { topic, problem } => {
                    malformed += 1;
                    if worth_logging(malformed) {
                        log_line!(
                            "warning: skipped a malformed message on {topic} ({malformed} so far): {problem}"
                        );
                    }
                }
                Output::Misaligned(problem) => {
                    misaligned += 1;
                    if worth_logging(misaligned) {
                        log_line!("warning: cannot align ({misaligned} so far): {problem}");
                    }
                }
            }
        }
        if ended && let (Some(idle), Some(p)) = (steps.idle(), &excitation_pub) {
            log_line!("no message for {RUN_END_SILENCE:?}: the run ended (IDLE)");
            publish_blocking(p, idle).await?;
        }
        if last_report.elapsed() > Duration::from_secs(5) {
            log_line!(
                "{published} samples published, {malformed} malformed and {misaligned} misaligned messages skipped"
            );
            last_report = Instant::now();
        }
    }
    log_line!(
        "stopped: {published} samples published, {malformed} malformed and {misaligned} misaligned messages skipped"
    );
    Ok(())
}

/// A labelled sample's step, and the state to publish first when it starts one.
struct SampleStep {
    step: u32,
    starts: Option<ExcitationState>,
}

/// The steps the labels make: the state of each step as its first sample comes, and IDLE at
/// the end.
struct Steps {
    driven: Channel,
    frame: String,
    /// The step in progress and its last sample's time [ns].
    current: Option<(u32, i64)>,
    /// The interval between the last two samples [ns].
    interval_ns: i64,
    /// Samples skipped for want of labels or with labels that are not a step.
    skipped: u64,
}

impl Steps {
    fn new(driven: Channel, frame: String) -> Steps {
        Steps {
            driven,
            frame,
            current: None,
            interval_ns: 0,
            skipped: 0,
        }
    }

    /// The step of the sample at `t_ns` with `labels` (`None`: not labelled, step 0); `None`
    /// when the sample is to be skipped (before the first labels, or labels that are not a
    /// step index and a frequency), said in the log.
    fn of_sample(&mut self, t_ns: i64, labels: Option<SampleLabels>) -> Option<SampleStep> {
        let Some(labels) = labels else {
            return Some(SampleStep {
                step: 0,
                starts: None,
            });
        };
        let [Some(step), Some(frequency)] = labels else {
            self.skip(t_ns, "before the first step and frequency_hz labels");
            return None;
        };
        let (step, frequency) = match step_of_labels(step, frequency) {
            Ok((step, frequency)) => (step as u32, frequency),
            Err((label, problem)) => {
                self.skip(t_ns, &format!("{label}: {problem}"));
                return None;
            }
        };
        let starts = match self.current {
            Some((s, last)) if s == step => {
                self.interval_ns = t_ns - last;
                None
            }
            _ => {
                let excitation = estimated_excitation(frequency, f64::NAN);
                let time = Time::from_nanos(t_ns);
                Some(ExcitationState::from_excitation(
                    Header::new(time, &self.frame),
                    step as usize,
                    time,
                    &excitation,
                    self.driven,
                    0,
                ))
            }
        };
        self.current = Some((step, t_ns));
        Some(SampleStep { step, starts })
    }

    fn skip(&mut self, t_ns: i64, why: &str) {
        self.skipped += 1;
        if worth_logging(self.skipped) {
            log_line!(
                "skipped the sample at {t_ns} ns ({} so far): {why}",
                self.skipped
            );
        }
    }

    /// The state that ends the run after its last step, once.
    fn idle(&mut self) -> Option<ExcitationState> {
        let (step, last) = self.current.take()?;
        let end = Time::from_nanos(last + self.interval_ns);
        Some(ExcitationState::idle(
            Header::new(end, &self.frame),
            step as usize + 1,
            end,
            self.driven,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seed through RustDDS's own CDR decoding, both byte orders: the payload comes back
    /// whole, with the encapsulation header of its byte order.
    #[test]
    fn the_raw_seed_gives_back_the_payload_with_its_byte_order() {
        use ros2_client::dds::rustdds::RepresentationIdentifier as R;
        use ros2_client::dds::rustdds::serialization::deserialize_from_cdr_with_decoder_and_rep_id;
        let body: Vec<u8> = (0u8..13).collect();
        for (rep, first) in [(R::CDR_LE, 1u8), (R::CDR_BE, 0u8)] {
            let (raw, used) =
                deserialize_from_cdr_with_decoder_and_rep_id(&body, rep, RawCdrSeed).unwrap();
            assert_eq!(used, body.len());
            assert_eq!(raw.0[..4], [0, first, 0, 0]);
            assert_eq!(raw.0[4..], body[..]);
        }
    }

    /// The shipped launch example: the foreign node's parameters (the params file the launch
    /// file names) give a channel map the live source resolves.
    #[test]
    fn the_launch_example_gives_a_map_of_two_topics() {
        let configs = Path::new(env!("CARGO_MANIFEST_DIR")).join("../launch_configs");
        let nodes = crate::launch::plan(&configs.join("foreign.launch.yaml"), &[]).unwrap();
        let node = nodes.iter().find(|n| n.exec == "foreign").unwrap();
        let args = crate::ros::RosArgs::parse(&node.args).unwrap();
        let setup = NodeSetup::from_args("foreign", &args).unwrap();
        let map = channel_map(&setup).unwrap();
        assert!(map.file.ends_with("bench.channels.yaml"), "{}", map.file);
        let live = ForeignTopics::new(&map).unwrap();
        let topics: Vec<(&str, &str, bool)> = live
            .topics()
            .iter()
            .map(|t| (t.name.as_str(), t.type_name.as_str(), t.stamped))
            .collect();
        assert_eq!(
            topics,
            [
                ("/bench/joints", "sensor_msgs/msg/JointState", true),
                ("/bench/load", "geometry_msgs/msg/WrenchStamped", true)
            ]
        );
        assert_eq!(live.channels().len(), 5);
    }
}
