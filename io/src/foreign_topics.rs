//! The topics a [`ChannelMap`] names, decoded message by message from their CDR payloads with
//! the dynamic decoder, aligned into samples by [`crate::stamp_align`] and labelled with the
//! map's `step` and `frequency_hz`: the one reader of a bench's own messages, which the live
//! `foreign` node feeds as they are received and [`crate::foreign_bag`] feeds from a bag in
//! log-time order (a log time is a receive time), so that the same messages give the same
//! samples. No ROS runtime here.
//!
//! The reference topic is the first stamped data topic (the bag's rule,
//! [`data_topic_order`]); its interval (the median over its first [`LEARN_MESSAGES`] messages)
//! and its receive delay ([`ReceiveTiming`]) are measured first, the messages of every topic
//! waiting until then. **A topic without a header** (e.g. `std_msgs/Float64MultiArray`) is timed
//! by its receive time less the reference's delay and taken by the nearest reference message
//! within half an interval; when the reference's delays spread over half an interval or more
//! there is no consistent offset: reported, and the messages learnt from are dropped.
//!
//! **Labels** (the map's `step` and `frequency_hz`, on any topic, stamped or not) are timed the
//! same way and hold from the sample nearest their time until the next message ([`LabelTrack`]).
//! A sample is handed out once the labels at its time are known: a later label message came,
//! or the stream has gone [`LABEL_WAIT_NS`] past it (by the receive times, less the delay), or
//! the stream ended ([`ForeignTopics::flush`]). Live, the map must name each topic's type
//! (`type:` in one of its entries), as a subscriber needs it before any message comes.

use std::collections::VecDeque;

use forcemap_math::record::Channel;

use crate::channel_map::{ChannelMap, FREQUENCY_LABEL, STEP_LABEL, Source};
use crate::foreign_bag::{data_topic_order, registry_for};
use crate::ros_msg::{Registry, decode, has_header, header_stamp_ns};
use crate::stamp_align::{
    Aligned, LabelTrack, ReceiveTiming, StampAligner, median_interval_ns, tolerance_ns,
};

pub use crate::stamp_align::LEARN_MESSAGES;

/// Reference messages that may wait for a quiet topic before they count as lost.
pub const MAX_PENDING: usize = 100_000;
/// How long after a sample a label may still arrive and apply to it [ns of the stream]: a
/// labelled sample waits this long unless a later label message comes first.
pub const LABEL_WAIT_NS: i64 = 500_000_000;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ForeignTopicsError {
    #[error(
        "{file}: topic {topic}: the channel map names no message type (add type: pkg/msg/Type to its entry, e.g. type: std_msgs/msg/Float64MultiArray)"
    )]
    NoType { file: String, topic: String },
    #[error(
        "{file}: topic {topic}: cannot decode message type {type_name}: it is neither built in (std_msgs/msg/Float64, Float64MultiArray, sensor_msgs/msg/JointState, geometry_msgs/msg/WrenchStamped, ...) nor in the map's definitions"
    )]
    UnknownType {
        file: String,
        topic: String,
        type_name: String,
    },
    #[error("{file}: topic {topic}: definition of {type_name}: {problem}")]
    Definition {
        file: String,
        topic: String,
        type_name: String,
        problem: String,
    },
    #[error("{file}: topic {topic}, field {field} (for {entry}): {problem}")]
    Field {
        file: String,
        topic: String,
        field: String,
        entry: String,
        problem: String,
    },
    #[error(
        "{file}: the channel map gives {given} but no {missing} (map both step and frequency_hz, or neither)"
    )]
    OneLabel {
        file: String,
        given: &'static str,
        missing: &'static str,
    },
}

/// A topic read: its type, and the channels and labels it supplies.
#[derive(Debug, Clone)]
pub struct LiveTopic {
    pub name: String,
    pub type_name: String,
    registry: Registry,
    /// Times are header stamps (else receive times).
    pub stamped: bool,
    channels: Vec<(Channel, Source)>,
    /// The labels it carries: 0 the step, 1 the frequency.
    labels: Vec<(usize, Source)>,
}

impl LiveTopic {
    /// The definitions its messages are decoded with.
    pub fn registry(&self) -> &Registry {
        &self.registry
    }

    /// A topic of `type_name`, decoded with `registry` (which must define it).
    pub fn new(name: &str, type_name: &str, registry: Registry) -> LiveTopic {
        LiveTopic {
            name: name.to_string(),
            stamped: has_header(&registry, type_name),
            type_name: type_name.to_string(),
            registry,
            channels: Vec::new(),
            labels: Vec::new(),
        }
    }
}

/// The labels of a sample: the step and the frequency, each `None` before its first message.
pub type SampleLabels = [Option<f64>; 2];

/// A sample's labels as its step and frequency (`None`: random excitation), or which label is
/// wrong and why: a step is a whole number from 0, a frequency at least 0 (0 for random).
pub fn step_of_labels(
    step: f64,
    frequency_hz: f64,
) -> Result<(usize, Option<f64>), (&'static str, String)> {
    if !(step.is_finite() && step >= 0.0 && step.fract() == 0.0 && step <= u32::MAX as f64) {
        return Err((STEP_LABEL, format!("{step} is not a whole number from 0")));
    }
    if !(frequency_hz.is_finite() && frequency_hz >= 0.0) {
        return Err((
            FREQUENCY_LABEL,
            format!("{frequency_hz} Hz is not a frequency (0 for random excitation)"),
        ));
    }
    Ok((step as usize, (frequency_hz > 0.0).then_some(frequency_hz)))
}

/// What a payload gives.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// An aligned sample: its time, the mapped channels' values (in forcemap's units) and,
    /// when the map has labels, its labels.
    Sample {
        t_ns: i64,
        values: Vec<(Channel, f64)>,
        labels: Option<SampleLabels>,
    },
    /// A message that did not decode, or lacks what the map reads: skipped.
    Malformed { topic: String, problem: String },
    /// A message the alignment rule leaves out (lost, extra, out of order), or timing that
    /// cannot be learnt.
    Misaligned(String),
}

/// A message decoded, waiting for the timing or for the aligner.
#[derive(Debug, Clone)]
struct Message {
    topic: usize,
    /// Its stamp, else its receive time.
    raw_ns: i64,
    receive_ns: i64,
    values: Vec<f64>,
    labels: Vec<(usize, f64)>,
}

/// The decoders, the aligner and the labels of a map's topics.
#[derive(Debug, Clone)]
pub struct ForeignTopics {
    /// The data topics (the reference first), then those that carry labels only.
    topics: Vec<LiveTopic>,
    data_topics: usize,
    aligner: Option<StampAligner>,
    /// Messages held while the timing is learnt.
    learning: Vec<Message>,
    /// Per sample row (the data topics' values concatenated), the channels in map order.
    channels: Vec<Channel>,
    timing: Option<ReceiveTiming>,
    /// The step and the frequency, when the map has them.
    labels: Option<[LabelTrack; 2]>,
    /// Aligned samples waiting for their labels.
    held: VecDeque<(i64, Vec<f64>)>,
    newest_receive_ns: Option<i64>,
    /// Each data topic's message times (stamp, else receive time), when recorded.
    times: Option<Vec<Vec<i64>>>,
}

impl ForeignTopics {
    /// Resolves every topic of `map` by the type the map names: its definitions and fields.
    pub fn new(map: &ChannelMap) -> Result<ForeignTopics, ForeignTopicsError> {
        let file = map.file.clone();
        let mut resolved: Vec<LiveTopic> = Vec::new();
        for name in map.topics() {
            let type_name = map
                .topic_type(name)
                .ok_or_else(|| ForeignTopicsError::NoType {
                    file: file.clone(),
                    topic: name.to_string(),
                })?
                .to_string();
            let registry = registry_for(map, &type_name, "").map_err(|(unknown, problem)| {
                if unknown {
                    ForeignTopicsError::UnknownType {
                        file: file.clone(),
                        topic: name.to_string(),
                        type_name: type_name.clone(),
                    }
                } else {
                    ForeignTopicsError::Definition {
                        file: file.clone(),
                        topic: name.to_string(),
                        type_name: type_name.clone(),
                        problem,
                    }
                }
            })?;
            for (entry, s) in map.sources().filter(|(_, s)| s.topic == name) {
                s.field
                    .check(&registry, &type_name)
                    .map_err(|e| ForeignTopicsError::Field {
                        file: file.clone(),
                        topic: name.to_string(),
                        field: s.field.text.clone(),
                        entry: entry.to_string(),
                        problem: e.to_string(),
                    })?;
            }
            resolved.push(LiveTopic::new(name, &type_name, registry));
        }
        match (&map.step, &map.frequency_hz) {
            (Some(_), None) => Err(ForeignTopicsError::OneLabel {
                file,
                given: STEP_LABEL,
                missing: FREQUENCY_LABEL,
            }),
            (None, Some(_)) => Err(ForeignTopicsError::OneLabel {
                file,
                given: FREQUENCY_LABEL,
                missing: STEP_LABEL,
            }),
            _ => Ok(ForeignTopics::of_topics(map, resolved)),
        }
    }

    /// The reader of `map` over `resolved`, every topic the map names (types and fields
    /// checked by the caller: a bag's reader checks them against the bag).
    pub fn of_topics(map: &ChannelMap, resolved: Vec<LiveTopic>) -> ForeignTopics {
        let order: Vec<String> =
            data_topic_order(map, |n| resolved.iter().any(|t| t.name == n && t.stamped))
                .into_iter()
                .map(str::to_string)
                .collect();
        let data_topics = order.len();
        let mut topics = Vec::new();
        let mut channels = Vec::new();
        let names = order.iter().chain(
            resolved
                .iter()
                .map(|t| &t.name)
                .filter(|n| !order.contains(n)),
        );
        for name in names {
            let Some(mut t) = resolved.iter().find(|t| t.name == *name).cloned() else {
                continue;
            };
            t.channels = map
                .channels
                .iter()
                .filter(|(_, s)| s.topic == *name)
                .cloned()
                .collect();
            t.labels = [&map.step, &map.frequency_hz]
                .into_iter()
                .enumerate()
                .filter_map(|(k, s)| {
                    s.as_ref()
                        .filter(|s| s.topic == *name)
                        .map(|s| (k, s.clone()))
                })
                .collect();
            if t.channels.is_empty() && t.labels.is_empty() {
                continue;
            }
            channels.extend(t.channels.iter().map(|(c, _)| *c));
            topics.push(t);
        }
        let labelled = map.step.is_some() && map.frequency_hz.is_some();
        ForeignTopics {
            topics,
            data_topics,
            aligner: None,
            learning: Vec::new(),
            channels,
            timing: None,
            labels: labelled.then(Default::default),
            held: VecDeque::new(),
            newest_receive_ns: None,
            times: None,
        }
    }

    /// The same reader keeping every data topic's message times ([`ForeignTopics::times`]).
    pub fn recording_times(self) -> ForeignTopics {
        let n = self.data_topics;
        ForeignTopics {
            times: Some(vec![Vec::new(); n]),
            ..self
        }
    }

    /// The topics to read, the reference first, then the other data topics, then those that
    /// carry labels only.
    pub fn topics(&self) -> &[LiveTopic] {
        &self.topics
    }

    /// How many of [`ForeignTopics::topics`] carry channels.
    pub fn data_topics(&self) -> usize {
        self.data_topics
    }

    /// The channels every sample carries.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// Whether the samples carry labels.
    pub fn labelled(&self) -> bool {
        self.labels.is_some()
    }

    /// The stamps' alignment tolerance [ns], once the interval is measured.
    pub fn tolerance_ns(&self) -> Option<f64> {
        self.aligner.as_ref().map(StampAligner::tolerance_ns)
    }

    /// The receive timing, once learnt.
    pub fn timing(&self) -> Option<ReceiveTiming> {
        self.timing
    }

    /// Each data topic's message times (stamps, else receive times), when recorded.
    pub fn times(&self) -> Option<&[Vec<i64>]> {
        self.times.as_deref()
    }

    /// Takes the CDR payload (with its encapsulation header) of a message on topic `topic`
    /// (an index into [`ForeignTopics::topics`]) received at `receive_ns`, and appends what it
    /// completes to `out`. Never panics on any bytes.
    pub fn push(&mut self, topic: usize, payload: &[u8], receive_ns: i64, out: &mut Vec<Output>) {
        let Some(t) = self.topics.get(topic) else {
            return;
        };
        let malformed = |problem: String| Output::Malformed {
            topic: t.name.clone(),
            problem,
        };
        let value = match decode(&t.registry, &t.type_name, payload) {
            Ok(v) => v,
            Err(e) => {
                out.push(malformed(format!("{} does not decode: {e}", t.type_name)));
                return;
            }
        };
        let raw_ns = if t.stamped {
            match header_stamp_ns(&value).and_then(|ns| i64::try_from(ns).ok()) {
                Some(ns) => ns,
                None => {
                    out.push(malformed("no usable header stamp".into()));
                    return;
                }
            }
        } else {
            receive_ns
        };
        let field = |s: &Source, entry: &str| {
            s.field
                .get(&value)
                .map(|raw| s.apply(raw))
                .map_err(|e| malformed(format!("field {} (for {entry}): {e}", s.field.text)))
        };
        let mut values = Vec::with_capacity(t.channels.len());
        for (c, s) in &t.channels {
            match field(s, c.name()) {
                Ok(v) => values.push(v),
                Err(m) => return out.push(m),
            }
        }
        let mut labels = Vec::with_capacity(t.labels.len());
        for (k, s) in &t.labels {
            match field(s, [STEP_LABEL, FREQUENCY_LABEL][*k]) {
                Ok(v) => labels.push((*k, v)),
                Err(m) => return out.push(m),
            }
        }
        if let Some(times) = &mut self.times
            && topic < times.len()
        {
            times[topic].push(raw_ns);
        }
        self.newest_receive_ns = Some(
            self.newest_receive_ns
                .map_or(receive_ns, |n| n.max(receive_ns)),
        );
        let m = Message {
            topic,
            raw_ns,
            receive_ns,
            values,
            labels,
        };
        if self.timing.is_none() {
            self.learning.push(m);
            self.learn(false, out);
        } else {
            self.accept(m, out);
        }
        self.release(false, out);
    }

    /// The end of the stream: timing learnt from what came (at least two reference messages),
    /// and every sample held for its labels handed out.
    pub fn flush(&mut self, out: &mut Vec<Output>) {
        if self.timing.is_none() {
            self.learn(true, out);
        }
        self.release(true, out);
    }

    /// Learns the interval and the receive delay once [`LEARN_MESSAGES`] reference messages
    /// have come (or, `now`, from those that came), then takes the messages held.
    fn learn(&mut self, now: bool, out: &mut Vec<Output>) {
        let reference: Vec<&Message> = self.learning.iter().filter(|m| m.topic == 0).collect();
        if reference.len() < LEARN_MESSAGES && !(now && reference.len() >= 2) {
            if now && !self.learning.is_empty() {
                out.push(Output::Misaligned(format!(
                    "{}: {} messages: too few for a sample rate; dropped the {} messages held",
                    self.topics.first().map_or("", |t| t.name.as_str()),
                    reference.len(),
                    self.learning.len()
                )));
                self.learning.clear();
            }
            return;
        }
        let interval = median_interval_ns(reference.iter().map(|m| m.raw_ns));
        let reference_name = self.topics[0].name.clone();
        if interval <= 0.0 {
            out.push(Output::Misaligned(format!(
                "{reference_name}: most of its first {} messages share one stamp: no sample interval; dropped them",
                reference.len()
            )));
            self.learning.clear();
            return;
        }
        let timing = if self.topics[0].stamped {
            ReceiveTiming::learn(
                reference.iter().map(|m| m.receive_ns - m.raw_ns).collect(),
                interval,
            )
        } else {
            ReceiveTiming::unstamped(interval)
        };
        let headerless: Vec<&str> = self
            .topics
            .iter()
            .filter(|t| !t.stamped)
            .map(|t| t.name.as_str())
            .collect();
        if self.topics[0].stamped && !headerless.is_empty() && !timing.consistent() {
            out.push(Output::Misaligned(format!(
                "{}; dropped them",
                timing.inconsistency(&reference_name, &headerless)
            )));
            self.learning.clear();
            return;
        }
        let mut aligner = StampAligner::new(self.data_topics, tolerance_ns(interval), MAX_PENDING);
        for (k, t) in self.topics.iter().enumerate().take(self.data_topics) {
            if !t.stamped {
                aligner = aligner.with_window(k, timing.window_ns());
            }
        }
        self.aligner = Some(aligner);
        self.timing = Some(timing);
        for m in std::mem::take(&mut self.learning) {
            self.accept(m, out);
        }
    }

    /// Times a message and takes its labels and values (timing learnt).
    fn accept(&mut self, m: Message, out: &mut Vec<Output>) {
        let (Some(timing), Some(aligner)) = (self.timing, &mut self.aligner) else {
            return;
        };
        let t_ns = if self.topics[m.topic].stamped {
            m.raw_ns
        } else {
            timing.time_ns(m.receive_ns)
        };
        if let Some(tracks) = &mut self.labels {
            for (k, v) in &m.labels {
                if let Err(newest) = tracks[*k].push(t_ns, *v) {
                    out.push(Output::Misaligned(format!(
                        "the {} message at {t_ns} ns on {} comes after one at {newest} ns (labels out of order): skipped",
                        [STEP_LABEL, FREQUENCY_LABEL][*k],
                        self.topics[m.topic].name
                    )));
                }
            }
        }
        if m.topic >= self.data_topics {
            return;
        }
        let mut aligned = Vec::new();
        aligner.push(m.topic, t_ns, m.values, &mut aligned);
        for a in aligned {
            match a {
                Aligned::Sample { t_ns, values } => self.held.push_back((t_ns, values)),
                Aligned::Misaligned(x) => {
                    let names = self.topic_labels();
                    let names: Vec<&str> = names.iter().map(String::as_str).collect();
                    let text = self
                        .aligner
                        .as_ref()
                        .map_or_else(String::new, |a| a.describe(&x, &names));
                    out.push(Output::Misaligned(text));
                }
            }
        }
    }

    /// The data topics named with the fields they supply, so a report says what it concerns.
    fn topic_labels(&self) -> Vec<String> {
        self.topics[..self.data_topics]
            .iter()
            .map(|t| {
                let fields: Vec<&str> = t
                    .channels
                    .iter()
                    .map(|(_, s)| s.field.text.as_str())
                    .collect();
                format!("{} ({})", t.name, fields.join(", "))
            })
            .collect()
    }

    /// Hands out the samples whose labels are known (all of them when `all`).
    fn release(&mut self, all: bool, out: &mut Vec<Output>) {
        let Some(timing) = self.timing else {
            return;
        };
        let window = timing.window_ns();
        let now = self.newest_receive_ns.map(|n| timing.time_ns(n));
        while let Some(&(t_ns, _)) = self.held.front() {
            let labels = match &mut self.labels {
                None => None,
                Some(tracks) => {
                    let known = all
                        || tracks.iter().all(|tr| tr.settled_at(t_ns, window))
                        || now.is_some_and(|n| n >= t_ns + LABEL_WAIT_NS);
                    if !known {
                        return;
                    }
                    Some([tracks[0].at(t_ns, window), tracks[1].at(t_ns, window)])
                }
            };
            let Some((t_ns, values)) = self.held.pop_front() else {
                return;
            };
            out.push(Output::Sample {
                t_ns,
                values: self.channels.iter().copied().zip(values).collect(),
                labels,
            });
        }
    }
}
