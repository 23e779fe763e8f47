//! A rig run as a rosbag2 bag: the sensor node's topics, written from records and read back
//! into records ([`read`]: one reader of the rig topics, for the analysis and for playback).
//!
//! Topics (under the rig's namespace, `/rig` by default):
//! - `/rig/samples` (`forcemap_msgs/msg/RigSample`): one message per sample, stamped with the
//!   sample time;
//! - `/rig/excitation` (`forcemap_msgs/msg/ExcitationState`, transient local): one message per
//!   step, when the step starts;
//! - `/rig/parameters` (`diagnostic_msgs/msg/DiagnosticStatus`, transient local, optional): the
//!   rig constants (e.g. `mass_kg`) as key/value pairs, so that a bag carries what its analysis
//!   needs.

use std::path::{Path, PathBuf};

use forcemap_math::record::{Channel, Record};
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::DiagnosticStatus;
use forcemap_msgs::msg::{ExcitationState, RigSample};

use crate::bag::{BagError, BagReader, BagWriter, QosProfile, TopicSpec};
use crate::rig_messages::{RigMessage, constants_status, rig_messages};
use crate::topics::{RIG_EXCITATION, RIG_PARAMETERS, RIG_SAMPLES};

mod read;
pub use read::{RigBag, RigBagReader, RigTopic, read_rig_bag, read_rig_messages};

/// Name of the parameters status message.
pub const PARAMETERS_NAME: &str = "rig parameters";
/// Time of t = 0 of a simulated or imported run unless told otherwise: 2026-01-01T00:00:00Z.
/// Fixed, so that regenerating a bag gives identical messages.
pub const DEFAULT_RUN_START: Time = Time {
    sec: 1_767_225_600,
    nanosec: 0,
};

#[derive(Debug, thiserror::Error)]
pub enum RigBagError {
    #[error(transparent)]
    Bag(#[from] BagError),
    #[error("{path}: topic {topic} holds {found}, expected {expected}")]
    WrongType {
        path: String,
        topic: String,
        found: String,
        expected: String,
    },
    #[error(
        "{path}: topic {topic}: the {type_name} schema in the bag does not match this forcemap's definition ({detail})"
    )]
    SchemaMismatch {
        path: String,
        topic: String,
        type_name: String,
        detail: String,
    },
    #[error("{path}: topic {topic}, message {index}: {problem}")]
    Message {
        path: String,
        topic: String,
        index: usize,
        problem: String,
    },
    #[error("{path}: step {step}: {problem}")]
    Step {
        path: String,
        step: usize,
        problem: String,
    },
    #[error("{path}: {topics} are all {kind} topics of a rig: which one to read is ambiguous")]
    Ambiguous {
        path: String,
        kind: String,
        topics: String,
    },
    #[error("{path}: no samples on {topic}")]
    Empty { path: String, topic: String },
}

/// The field lines ("type name") of the top-level section of a ros2msg schema, without
/// comments and constants: what must agree for the bytes to decode as the type.
fn schema_fields(schema: &str) -> Vec<String> {
    schema
        .split(&"=".repeat(80))
        .next()
        .unwrap_or("")
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty() && !l.contains('='))
        .map(|l| l.split_whitespace().collect::<Vec<_>>().join(" "))
        .collect()
}

pub(crate) fn check_topic<M: RosMessage>(
    reader: &BagReader,
    path: &str,
    topic: &str,
) -> Result<(), RigBagError> {
    let info = reader.topic(topic)?;
    if info.type_name != M::TYPE_NAME {
        return Err(RigBagError::WrongType {
            path: path.into(),
            topic: topic.into(),
            found: info.type_name.clone(),
            expected: M::TYPE_NAME.into(),
        });
    }
    let (ours, theirs) = (
        schema_fields(&M::schema()),
        schema_fields(&info.schema_text),
    );
    if ours != theirs {
        let detail = match ours.iter().zip(&theirs).find(|(a, b)| a != b) {
            Some((a, b)) => format!("field '{b}' where '{a}' is expected"),
            None => format!("{} fields where {} are expected", theirs.len(), ours.len()),
        };
        return Err(RigBagError::SchemaMismatch {
            path: path.into(),
            topic: topic.into(),
            type_name: M::TYPE_NAME.into(),
            detail,
        });
    }
    Ok(())
}

fn nanos(t: Time) -> u64 {
    t.as_nanos().max(0) as u64
}

/// Writes `records` (and the rig constants `parameters`, if any) as a bag at `out`
/// (atomically). `driven` is the channel whose amplitude the excitation gives.
pub fn write_rig_bag(
    out: &Path,
    records: &[Record],
    driven: Channel,
    parameters: &[(&str, f64)],
    run_start: Time,
) -> Result<PathBuf, RigBagError> {
    let mut w = BagWriter::create(out)?;
    let latched = QosProfile {
        depth: 1,
        reliable: true,
        transient_local: true,
    };
    let mut spec = TopicSpec::new(RIG_SAMPLES, RigSample::TYPE_NAME, &RigSample::schema());
    spec.offered_qos_profiles = QosProfile {
        depth: 1000,
        reliable: true,
        transient_local: false,
    }
    .to_yaml_string();
    let samples = w.add_topic(&spec)?;
    let mut spec = TopicSpec::new(
        RIG_EXCITATION,
        ExcitationState::TYPE_NAME,
        &ExcitationState::schema(),
    );
    spec.offered_qos_profiles = latched.to_yaml_string();
    let excitation = w.add_topic(&spec)?;
    let parameters_topic = if parameters.is_empty() {
        None
    } else {
        let mut spec = TopicSpec::new(
            RIG_PARAMETERS,
            DiagnosticStatus::TYPE_NAME,
            &DiagnosticStatus::schema(),
        );
        spec.offered_qos_profiles = latched.to_yaml_string();
        Some(w.add_topic(&spec)?)
    };
    let status = parameters_topic.map(|_| constants_status("rig constants", "rig", parameters));
    for m in rig_messages(records, driven, status, run_start, "rig") {
        match m {
            RigMessage::Parameters(status) => {
                if let Some(id) = parameters_topic {
                    w.write(id, nanos(run_start), nanos(run_start), &status.to_cdr())?;
                }
            }
            // A bag ends where its recording ended: no IDLE (a player adds it).
            RigMessage::Excitation(state) if state.is_idle() => {}
            RigMessage::Excitation(state) => {
                let t = nanos(state.start_time);
                w.write(excitation, t, t, &state.to_cdr())?;
            }
            RigMessage::Sample(msg) => {
                let t = nanos(msg.header.stamp);
                w.write(samples, t, t, &msg.to_cdr())?;
            }
        }
    }
    Ok(w.finish()?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schema_fields_ignore_comments_constants_and_dependencies() {
        let s = format!(
            "# c\nuint8 A=1\nstd_msgs/Header header # h\nfloat64  x\n{}\nMSG: std_msgs/Header\nstring frame_id\n",
            "=".repeat(80)
        );
        assert_eq!(schema_fields(&s), ["std_msgs/Header header", "float64 x"]);
    }
}
