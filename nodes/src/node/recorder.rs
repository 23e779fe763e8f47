//! The recorder node: records topics into a rosbag2 MCAP bag.
//!
//! Chunks are closed at least once a second (and on every idle second), so a recorder killed
//! without warning loses at most the last second; `forcemap bag recover` rebuilds such a bag.
//! On SIGINT/SIGTERM the bag is finished (summary, footer, metadata.yaml) and moved into place.
//!
//! Parameters: `bag` (the bag directory to write; required), `topics` (names relative to the
//! namespace or absolute; default: samples, excitation, parameters, phasors, theta,
//! /diagnostics). The type of each topic is known from its last name component (forcemap's
//! topics) or given as `name:pkg/msg/Type`. `overwrite` (false): replace an existing bag there.
//! `log_flushes` (false): log the message count each time a chunk is closed (what a crash
//! would keep).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use forcemap_msgs::RosMessage;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{
    ExcitationState, GapDiagnosis, HarmonicPhasors, IdentifiedParameters, RigSample,
};
use ros2_client::QosProfile;
use tokio::sync::mpsc;

use crate::log_line;
use crate::ros::{NodeSetup, OnTakeError, RosNode, qos};
use forcemap_io::bag::{BagSink, BagWriter, QosProfile as BagQos, TopicId, TopicSpec};
use forcemap_io::topics;

const DEFAULT_TOPICS: [&str; 6] = [
    topics::SAMPLES,
    topics::EXCITATION,
    topics::PARAMETERS,
    topics::PHASORS,
    topics::THETA,
    topics::DIAGNOSTICS,
];

/// One received message for the writer.
#[derive(Debug, Clone, PartialEq)]
pub struct Received {
    pub topic: usize,
    pub log_time: u64,
    pub publish_time: u64,
    pub cdr: Vec<u8>,
}

/// A message type the recorder knows: its ROS name, the last name component of the topic that
/// carries it in forcemap's graph, the QoS it is published with, its schema, and how to
/// subscribe to it.
pub struct KnownType {
    pub type_name: &'static str,
    pub topic_base: &'static str,
    pub qos: fn() -> QosProfile,
    pub schema: fn() -> String,
    subscribe: Subscribe,
}

impl std::fmt::Debug for KnownType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KnownType")
            .field("type_name", &self.type_name)
            .field("topic_base", &self.topic_base)
            .finish_non_exhaustive()
    }
}

type Subscribe = fn(
    &mut RosNode,
    &str,
    QosProfile,
    usize,
    mpsc::UnboundedSender<Received>,
) -> anyhow::Result<()>;

const fn known<M>(topic_base: &'static str, qos: fn() -> QosProfile) -> KnownType
where
    M: RosMessage + serde::de::DeserializeOwned + Send + Sync + 'static,
{
    KnownType {
        type_name: M::TYPE_NAME,
        topic_base,
        qos,
        schema: M::schema,
        subscribe: forward::<M>,
    }
}

/// The one registry of the message types the recorder knows.
pub const KNOWN_TYPES: [KnownType; 7] = [
    known::<RigSample>(topics::SAMPLES, qos::samples),
    known::<ExcitationState>(topics::EXCITATION, qos::excitation),
    known::<DiagnosticStatus>(topics::PARAMETERS, qos::parameters),
    known::<HarmonicPhasors>(topics::PHASORS, qos::phasors),
    known::<IdentifiedParameters>(topics::THETA, qos::theta),
    known::<DiagnosticArray>("diagnostics", qos::diagnostics),
    known::<GapDiagnosis>(topics::DIAGNOSIS, qos::theta),
];

/// The type of the topic `name`: `explicit` (`pkg/msg/Type`) when given, else by the topic's
/// last name component.
pub fn known_type(name: &str, explicit: Option<&str>) -> anyhow::Result<&'static KnownType> {
    if let Some(t) = explicit {
        return KNOWN_TYPES
            .iter()
            .find(|k| k.type_name == t)
            .with_context(|| {
                format!("topic {name}: type {t} is not one the recorder knows (forcemap_msgs and diagnostic_msgs types)")
            });
    }
    let base = name.rsplit('/').next().unwrap_or(name);
    KNOWN_TYPES
        .iter()
        .find(|k| k.topic_base == base)
        .with_context(|| {
            format!(
                "topic {name}: unknown type; write it as {name}:pkg/msg/Type (e.g. forcemap_msgs/msg/RigSample)"
            )
        })
}

fn bag_qos(q: &QosProfile) -> BagQos {
    use ros2_client::qos::{Durability, History, Reliability};
    BagQos {
        depth: match q.history {
            History::KeepLast { depth } => depth as u32,
            History::KeepAll => 0,
        },
        reliable: matches!(q.reliability, Reliability::Reliable { .. }),
        transient_local: matches!(q.durability, Durability::TransientLocal),
    }
}

/// The bag's entry of a topic: its absolute name, type, schema and offered QoS.
pub fn topic_spec(absolute: &str, known: &KnownType) -> TopicSpec {
    let mut spec = TopicSpec::new(absolute, known.type_name, &(known.schema)());
    spec.offered_qos_profiles = bag_qos(&(known.qos)()).to_yaml_string();
    spec
}

/// Subscribes to `name` with type `M` and forwards every message as CDR.
fn forward<M>(
    ros: &mut RosNode,
    name: &str,
    q: QosProfile,
    index: usize,
    tx: mpsc::UnboundedSender<Received>,
) -> anyhow::Result<()>
where
    M: RosMessage + serde::de::DeserializeOwned + Send + Sync + 'static,
{
    let sub = ros.subscription::<M>(name, q)?;
    crate::ros::forward(sub, tx, OnTakeError::Warn("a message"), move |m, info| {
        let log_time = crate::ros::now_time().as_nanos().max(0) as u64;
        let publish_time = info
            .source_timestamp()
            .map_or(log_time, |t| t.to_nanos().max(0) as u64);
        Some(Received {
            topic: index,
            log_time,
            publish_time,
            cdr: m.to_cdr(),
        })
    });
    Ok(())
}

/// Chunks are closed at least this often, so a recorder killed without warning loses at most
/// this much.
pub const FLUSH_INTERVAL: Duration = Duration::from_secs(1);

/// The recorder's logic without the middleware: received messages into a sink, the chunk
/// closed every [`FLUSH_INTERVAL`] even when nothing arrives.
pub struct RecorderCore {
    sink: Box<dyn BagSink + Send>,
    ids: Vec<TopicId>,
    last_flush: Instant,
    count: u64,
}

impl RecorderCore {
    /// Declares `topics` (absolute name and type, in subscription order) in `sink`.
    pub fn new(
        mut sink: Box<dyn BagSink + Send>,
        topics: &[(String, &KnownType)],
        now: Instant,
    ) -> anyhow::Result<RecorderCore> {
        let mut ids = Vec::new();
        for (name, known) in topics {
            ids.push(sink.add_topic(&topic_spec(name, known))?);
        }
        Ok(RecorderCore {
            sink,
            ids,
            last_flush: now,
            count: 0,
        })
    }

    /// Writes a message.
    pub fn record(&mut self, m: &Received) -> anyhow::Result<()> {
        let id = *self
            .ids
            .get(m.topic)
            .with_context(|| format!("message for topic {} of {}", m.topic, self.ids.len()))?;
        self.sink.write(id, m.log_time, m.publish_time, &m.cdr)?;
        self.count += 1;
        Ok(())
    }

    /// Closes the chunk when [`FLUSH_INTERVAL`] has passed; true when it did.
    pub fn tick(&mut self, now: Instant) -> anyhow::Result<bool> {
        if now.duration_since(self.last_flush) < FLUSH_INTERVAL {
            return Ok(false);
        }
        self.sink.flush_chunk()?;
        self.last_flush = now;
        Ok(true)
    }

    /// Messages written so far.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Completes the recording.
    pub fn finish(self) -> anyhow::Result<PathBuf> {
        Ok(self.sink.finish()?)
    }
}

/// The node: subscriptions into [`RecorderCore`] with a [`BagWriter`] as its sink.
pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = setup.params.clone();
    let bag = PathBuf::from(
        p.opt_str("bag")?
            .context("the recorder needs the parameter bag (the bag directory to write)")?,
    );
    let wanted: Vec<String> = p
        .opt_str_array("topics")?
        .unwrap_or_else(|| DEFAULT_TOPICS.iter().map(ToString::to_string).collect());
    if wanted.is_empty() {
        bail!("topics is empty: nothing to record");
    }
    let mut plan = Vec::new();
    for w in &wanted {
        let (name, explicit) = match w.split_once(':') {
            Some((n, t)) => (n.to_string(), Some(t)),
            None => (w.clone(), None),
        };
        plan.push((name.clone(), known_type(&name, explicit)?));
    }

    if p.opt_bool("overwrite")?.unwrap_or(false) && bag.exists() {
        // Only ever remove a bag (a directory holding metadata.yaml or an .mcap).
        let is_bag = bag.join("metadata.yaml").exists()
            || std::fs::read_dir(&bag).is_ok_and(|d| {
                d.flatten()
                    .any(|e| e.path().extension().is_some_and(|x| x == "mcap"))
            });
        if !is_bag {
            bail!(
                "{} exists and is not a bag; overwrite only replaces bags",
                bag.display()
            );
        }
        std::fs::remove_dir_all(&bag)
            .with_context(|| format!("removing the previous bag {}", bag.display()))?;
    }
    if let Some(parent) = bag.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    // Create the bag first: a bad path fails before anything is subscribed.
    let writer = BagWriter::create(&bag)?;
    let absolute: Vec<(String, &KnownType)> = plan
        .iter()
        .map(|(name, k)| (setup.absolute_topic(name), *k))
        .collect();
    let mut core = RecorderCore::new(Box::new(writer), &absolute, Instant::now())?;
    let mut ros = RosNode::start(setup.clone())?;
    let (tx, mut rx) = mpsc::unbounded_channel::<Received>();
    for (i, (name, known)) in plan.iter().enumerate() {
        // Samples come fast: subscribe with the readers' deeper history (the bag still
        // records the QoS they are published with).
        let reader_qos = if known.topic_base == topics::SAMPLES {
            qos::samples_reader()
        } else {
            (known.qos)()
        };
        (known.subscribe)(&mut ros, name, reader_qos, i, tx.clone())?;
    }
    drop(tx);
    log_line!("recording {} topics into {}", plan.len(), bag.display());
    let mut tick = tokio::time::interval(Duration::from_millis(250));
    let log_flushes = p.opt_bool("log_flushes")?.unwrap_or(false);
    loop {
        tokio::select! {
            m = rx.recv() => {
                let Some(m) = m else { break };
                core.record(&m)?;
            }
            _ = tick.tick() => {
                // Close the chunk every second even when nothing else arrives.
                if core.tick(Instant::now())? && log_flushes {
                    log_line!("on disk: {} messages", core.count());
                }
            }
            () = crate::ros::shutdown_signal() => break,
        }
    }
    // Take what already arrived, then finish.
    while let Ok(m) = rx.try_recv() {
        core.record(&m)?;
    }
    let count = core.count();
    let path = core.finish()?;
    log_line!("recorded {count} messages into {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use forcemap_io::bag::BagError;
    use std::sync::{Arc, Mutex};

    /// What a memory sink saw.
    #[derive(Default)]
    struct Seen {
        topics: Vec<TopicSpec>,
        messages: Vec<(u16, u64, Vec<u8>)>,
        flushes: usize,
        finished: bool,
    }

    struct MemorySink(Arc<Mutex<Seen>>);

    impl BagSink for MemorySink {
        fn add_topic(&mut self, spec: &TopicSpec) -> Result<TopicId, BagError> {
            let mut s = self.0.lock().unwrap();
            s.topics.push(spec.clone());
            Ok(TopicId(s.topics.len() as u16))
        }
        fn write(&mut self, t: TopicId, log: u64, _: u64, cdr: &[u8]) -> Result<(), BagError> {
            self.0
                .lock()
                .unwrap()
                .messages
                .push((t.0, log, cdr.to_vec()));
            Ok(())
        }
        fn flush_chunk(&mut self) -> Result<(), BagError> {
            self.0.lock().unwrap().flushes += 1;
            Ok(())
        }
        fn finish(self: Box<Self>) -> Result<PathBuf, BagError> {
            self.0.lock().unwrap().finished = true;
            Ok(PathBuf::from("memory"))
        }
    }

    #[test]
    fn every_forcemap_topic_has_one_known_type_with_its_schema() {
        for base in DEFAULT_TOPICS.iter().chain([&topics::DIAGNOSIS]) {
            let k = known_type(base, None).unwrap();
            assert!(
                (k.schema)().contains("MSG: std_msgs/Header")
                    || k.type_name.contains("DiagnosticStatus"),
                "{}",
                k.type_name
            );
            assert_eq!(
                known_type(base, Some(k.type_name)).unwrap().type_name,
                k.type_name
            );
        }
        assert_eq!(
            known_type("/dyno/force", Some("forcemap_msgs/msg/RigSample"))
                .unwrap()
                .topic_base,
            topics::SAMPLES
        );
        let e = known_type("/dyno/force", None).unwrap_err().to_string();
        assert!(e.contains("write it as /dyno/force:pkg/msg/Type"), "{e}");
        let e = known_type("x", Some("std_msgs/msg/Float64"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not one the recorder knows"), "{e}");
    }

    #[test]
    fn messages_go_to_their_topics_and_chunks_close_every_second() {
        let seen = Arc::new(Mutex::new(Seen::default()));
        let t0 = Instant::now();
        let topics = vec![
            (
                "/rig/samples".to_string(),
                known_type("samples", None).unwrap(),
            ),
            ("/rig/theta".to_string(), known_type("theta", None).unwrap()),
        ];
        let mut core = RecorderCore::new(Box::new(MemorySink(seen.clone())), &topics, t0).unwrap();
        let msg = |topic, log_time| Received {
            topic,
            log_time,
            publish_time: log_time,
            cdr: vec![0, 1, 0, 0, topic as u8],
        };
        core.record(&msg(1, 10)).unwrap();
        core.record(&msg(0, 20)).unwrap();
        assert!(core.record(&msg(2, 30)).is_err(), "no third topic");
        assert!(!core.tick(t0 + Duration::from_millis(900)).unwrap());
        assert!(core.tick(t0 + Duration::from_millis(1000)).unwrap());
        assert!(!core.tick(t0 + Duration::from_millis(1500)).unwrap());
        assert!(core.tick(t0 + Duration::from_millis(2100)).unwrap());
        assert_eq!(core.count(), 2);
        assert_eq!(core.finish().unwrap(), PathBuf::from("memory"));
        let s = seen.lock().unwrap();
        assert_eq!(s.topics[0].name, "/rig/samples");
        assert_eq!(s.topics[0].type_name, "forcemap_msgs/msg/RigSample");
        assert!(
            s.topics[0].offered_qos_profiles.contains("reliability: 1"),
            "{}",
            s.topics[0].offered_qos_profiles
        );
        assert_eq!(
            s.topics[1].type_name,
            "forcemap_msgs/msg/IdentifiedParameters"
        );
        assert_eq!(
            s.messages,
            vec![(2, 10, vec![0, 1, 0, 0, 1]), (1, 20, vec![0, 1, 0, 0, 0])]
        );
        assert_eq!(s.flushes, 2);
        assert!(s.finished);
    }
}
