//! The live counterpart of [`crate::foreign_bag`]: the topics a [`ChannelMap`] names, decoded
//! message by message from their CDR payloads with the dynamic decoder and aligned into samples
//! by [`crate::stamp_align`] (the same rule as the bag, so the same messages give the same
//! samples). No ROS runtime here: the `foreign` node subscribes and feeds the payloads in.
//!
//! Live, the map must name each topic's type (`type:` in one of its entries), as a subscriber
//! needs it before any message comes. The reference topic and the tolerance are those of the
//! bag (the first stamped data topic; 1 % of its median interval), the interval measured on
//! its first [`LEARN_MESSAGES`] messages, which wait with the others' until then. The labels
//! (`step`, `frequency_hz`) are not read: the harmonic node finds the steps itself.
//!
//! **A topic without a header** (e.g. `std_msgs/Float64`) is timed by when its messages were
//! received. Beside a stamped reference, receive times lag the stamps by the network and
//! scheduling delay (milliseconds, with jitter), far more than the 1 % tolerance, so such a
//! message is put on the reference's sample times ([`on_reference_times`]): its receive time
//! less the reference's own delay (the median of receive time less stamp over the reference's
//! first [`LEARN_MESSAGES`] messages), rounded to the nearest sample time (the latest reference
//! stamp plus whole intervals). This assumes the headerless topic is published at the same
//! instants as the reference and travels alike: a message whose delay differs from the
//! reference's median by more than half a sample interval lands on a neighbouring sample. When
//! the reference's delays spread over half an interval or more (interquartile range), no
//! consistent offset exists: reported, and the messages learnt from are dropped. With an
//! unstamped reference every topic is timed by receive times as they are.

use forcemap_math::record::Channel;

use crate::channel_map::{ChannelMap, Source};
use crate::foreign_bag::{data_topic_order, registry_for};
use crate::ros_msg::{Registry, decode, has_header, header_stamp_ns};
use crate::stamp_align::{Aligned, StampAligner, median_interval_ns, tolerance_ns};

/// Reference messages that measure the sample interval before the first sample is made.
pub const LEARN_MESSAGES: usize = 16;
/// Reference messages that may wait for a quiet topic before they count as lost.
pub const MAX_PENDING: usize = 100_000;

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
}

/// A subscribed topic: its type and the channels it supplies.
#[derive(Debug, Clone)]
pub struct LiveTopic {
    pub name: String,
    pub type_name: String,
    registry: Registry,
    /// Times are header stamps (else receive times).
    pub stamped: bool,
    channels: Vec<(Channel, Source)>,
}

/// What a payload gives.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// An aligned sample: its time and the mapped channels' values (in forcemap's units).
    Sample {
        t_ns: i64,
        values: Vec<(Channel, f64)>,
    },
    /// A message that did not decode, or lacks what the map reads: skipped.
    Malformed { topic: String, problem: String },
    /// A message the alignment rule leaves out (lost, extra, out of order).
    Misaligned(String),
}

/// The decoders and the aligner of a map's topics.
#[derive(Debug, Clone)]
pub struct ForeignTopics {
    topics: Vec<LiveTopic>,
    aligner: Option<StampAligner>,
    /// Messages (topic, time, values) held while the interval is measured.
    learning: Vec<(usize, i64, Vec<f64>)>,
    /// Per sample row (the topics' values concatenated), the channels in map order.
    channels: Vec<Channel>,
    /// Receive time less stamp of the reference's messages while the interval is measured.
    reference_delays_ns: Vec<i64>,
    /// The reference's delay and interval [ns], once learnt with a stamped reference: for
    /// the topics without a header.
    receive_timing: Option<(i64, f64)>,
    /// The latest reference stamp [ns].
    last_reference_ns: Option<i64>,
}

/// The time of a message received at `receive_ns` on the reference's sample times: the receive
/// time less the reference's median delay `delay_ns`, rounded to the nearest of `anchor_ns`
/// (a reference stamp) plus whole intervals of `interval_ns`.
pub fn on_reference_times(receive_ns: i64, delay_ns: i64, anchor_ns: i64, interval_ns: f64) -> i64 {
    let intervals = ((receive_ns - delay_ns - anchor_ns) as f64 / interval_ns).round();
    anchor_ns + (intervals * interval_ns).round() as i64
}

impl ForeignTopics {
    /// Resolves every data topic of `map`: its type (named by the map), definitions and fields.
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
            resolved.push(LiveTopic {
                name: name.to_string(),
                stamped: has_header(&registry, &type_name),
                type_name,
                registry,
                channels: Vec::new(),
            });
        }
        // The data topics in the bag's order (reference first); label-only topics are not read.
        let order: Vec<String> =
            data_topic_order(map, |n| resolved.iter().any(|t| t.name == n && t.stamped))
                .into_iter()
                .map(str::to_string)
                .collect();
        let mut topics = Vec::new();
        let mut channels = Vec::new();
        for name in &order {
            let Some(mut t) = resolved.iter().find(|t| t.name == *name).cloned() else {
                continue;
            };
            t.channels = map
                .channels
                .iter()
                .filter(|(_, s)| s.topic == *name)
                .cloned()
                .collect();
            channels.extend(t.channels.iter().map(|(c, _)| *c));
            topics.push(t);
        }
        Ok(ForeignTopics {
            topics,
            aligner: None,
            learning: Vec::new(),
            channels,
            reference_delays_ns: Vec::new(),
            receive_timing: None,
            last_reference_ns: None,
        })
    }

    /// The topics to subscribe to, the reference first.
    pub fn topics(&self) -> &[LiveTopic] {
        &self.topics
    }

    /// The channels every sample carries.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// The alignment tolerance [ns], once the interval is measured.
    pub fn tolerance_ns(&self) -> Option<f64> {
        self.aligner.as_ref().map(StampAligner::tolerance_ns)
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
        let t_ns = if t.stamped {
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
        let reference_stamped = self.topics[0].stamped;
        if topic == 0 && reference_stamped {
            if self.aligner.is_none() {
                self.reference_delays_ns.push(receive_ns - t_ns);
            }
            self.last_reference_ns = Some(t_ns);
        }
        // A headerless topic beside a stamped reference, once the delay is known (while it is
        // learnt, its receive times wait in `learning` and are moved at the end).
        let t_ns = match (t.stamped || !reference_stamped, self.receive_timing) {
            (false, Some((delay_ns, interval_ns))) => on_reference_times(
                t_ns,
                delay_ns,
                self.last_reference_ns.unwrap_or(t_ns - delay_ns),
                interval_ns,
            ),
            _ => t_ns,
        };
        let mut values = Vec::with_capacity(t.channels.len());
        for (c, s) in &t.channels {
            match s.field.get(&value) {
                Ok(raw) => values.push(s.apply(raw)),
                Err(e) => {
                    out.push(malformed(format!(
                        "field {} (for {}): {e}",
                        s.field.text,
                        c.name()
                    )));
                    return;
                }
            }
        }
        self.align(topic, t_ns, values, out);
    }

    fn align(&mut self, topic: usize, t_ns: i64, values: Vec<f64>, out: &mut Vec<Output>) {
        let mut aligned = Vec::new();
        match &mut self.aligner {
            Some(a) => a.push(topic, t_ns, values, &mut aligned),
            None => {
                self.learning.push((topic, t_ns, values));
                let reference: Vec<i64> = self
                    .learning
                    .iter()
                    .filter(|(k, _, _)| *k == 0)
                    .map(|(_, t, _)| *t)
                    .collect();
                if reference.len() < LEARN_MESSAGES {
                    return;
                }
                let interval = median_interval_ns(reference);
                if interval <= 0.0 {
                    self.reference_delays_ns.clear();
                    out.push(Output::Misaligned(format!(
                        "{}: most of its first {LEARN_MESSAGES} messages share one stamp: no sample interval; dropped them",
                        self.topics[0].name
                    )));
                    self.learning.clear();
                    return;
                }
                let delays = std::mem::take(&mut self.reference_delays_ns);
                let headerless = self.topics[0].stamped && self.topics.iter().any(|t| !t.stamped);
                if headerless {
                    match receive_delay_ns(delays, interval) {
                        Ok(delay_ns) => self.receive_timing = Some((delay_ns, interval)),
                        Err(spread_ns) => {
                            out.push(Output::Misaligned(format!(
                                "{}: its receive times lag its stamps by amounts that spread over {:.6} s (interquartile range of its first {LEARN_MESSAGES} messages), half a sample interval ({:.6} s) or more: no consistent offset to time the topics without a header ({}) by; dropped them (publish a type with a header, stamped with the reference's clock)",
                                self.topics[0].name,
                                spread_ns as f64 * 1e-9,
                                0.5 * interval * 1e-9,
                                self.topics
                                    .iter()
                                    .filter(|t| !t.stamped)
                                    .map(|t| t.name.as_str())
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            )));
                            self.learning.clear();
                            return;
                        }
                    }
                }
                let mut a =
                    StampAligner::new(self.topics.len(), tolerance_ns(interval), MAX_PENDING);
                // The learnt messages in arrival order, the headerless ones moved onto the
                // reference's sample times as they would have been live.
                let mut anchor = self.learning.iter().find(|(k, _, _)| *k == 0).map(|m| m.1);
                for (k, t, v) in self.learning.drain(..) {
                    let t = match (k, self.receive_timing) {
                        (0, _) => {
                            anchor = Some(t);
                            t
                        }
                        (_, Some((delay_ns, interval_ns))) if !self.topics[k].stamped => {
                            on_reference_times(t, delay_ns, anchor.unwrap_or(t), interval_ns)
                        }
                        _ => t,
                    };
                    a.push(k, t, v, &mut aligned);
                }
                self.aligner = Some(a);
            }
        }
        // Topics named with the fields they supply, so a report says what it concerns.
        let labels: Vec<String> = self
            .topics
            .iter()
            .map(|t| {
                let fields: Vec<&str> = t
                    .channels
                    .iter()
                    .map(|(_, s)| s.field.text.as_str())
                    .collect();
                format!("{} ({})", t.name, fields.join(", "))
            })
            .collect();
        let names: Vec<&str> = labels.iter().map(String::as_str).collect();
        let tol = self.tolerance_ns().unwrap_or_default();
        for a in aligned {
            out.push(match a {
                Aligned::Sample { t_ns, values } => Output::Sample {
                    t_ns,
                    values: self.channels.iter().copied().zip(values).collect(),
                },
                Aligned::Misaligned(m) => Output::Misaligned(m.describe(&names, tol)),
            });
        }
    }
}

/// The reference's delay [ns] (median of receive time less stamp), or the spread of the delays
/// (interquartile range) when it is half of `interval_ns` or more.
fn receive_delay_ns(mut delays_ns: Vec<i64>, interval_ns: f64) -> Result<i64, i64> {
    delays_ns.sort_unstable();
    let n = delays_ns.len();
    if n == 0 {
        return Err(0);
    }
    let spread = delays_ns[(3 * n) / 4] - delays_ns[n / 4];
    if spread as f64 >= 0.5 * interval_ns {
        return Err(spread);
    }
    Ok(delays_ns[n / 2])
}
