//! rosbag2 `metadata.yaml` (version 8), written by hand so that the layout is the one rosbag2
//! writes, read leniently with serde.
use std::fmt::Write as _;
use std::path::Path;

use serde::Deserialize;

use super::BagError;

/// The metadata version written. Version 8 (Jazzy's before 9) is the newest one whose QoS
/// profiles are a YAML *string* with integer policies, which Humble and Jazzy both read.
pub const METADATA_VERSION: u32 = 8;

/// The QoS profile a topic's publishers offered, in the form rosbag2 stores it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QosProfile {
    /// History depth (history is KEEP_LAST).
    pub depth: u32,
    /// RELIABLE (true) or BEST_EFFORT (false).
    pub reliable: bool,
    /// TRANSIENT_LOCAL (true) or VOLATILE (false).
    pub transient_local: bool,
}

impl Default for QosProfile {
    /// rclcpp's default publisher profile: keep last 10, reliable, volatile.
    fn default() -> Self {
        QosProfile {
            depth: 10,
            reliable: true,
            transient_local: false,
        }
    }
}

impl QosProfile {
    /// The YAML string rosbag2 (metadata version <= 8) stores in `offered_qos_profiles` and in
    /// the MCAP channel metadata: a YAML list with one profile, integer enum values
    /// (rmw: history KEEP_LAST = 1; reliability RELIABLE = 1, BEST_EFFORT = 2; durability
    /// TRANSIENT_LOCAL = 1, VOLATILE = 2; liveliness AUTOMATIC = 1) and infinite durations.
    pub fn to_yaml_string(&self) -> String {
        const INF: &str = "\n    sec: 9223372036\n    nsec: 854775807";
        format!(
            "- history: 1\n  depth: {}\n  reliability: {}\n  durability: {}\n  deadline:{INF}\n  \
             lifespan:{INF}\n  liveliness: 1\n  liveliness_lease_duration:{INF}\n  \
             avoid_ros_namespace_conventions: false",
            self.depth,
            if self.reliable { 1 } else { 2 },
            if self.transient_local { 1 } else { 2 },
        )
    }
}

/// One topic's entry in metadata.yaml.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicEntry {
    pub name: String,
    pub type_name: String,
    pub offered_qos_profiles: String,
    pub type_description_hash: String,
    pub message_count: u64,
}

/// What metadata.yaml says about a single-file MCAP bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMetadata {
    pub version: u32,
    pub storage_identifier: String,
    pub starting_time_ns: u64,
    pub duration_ns: u64,
    pub message_count: u64,
    pub topics: Vec<TopicEntry>,
    pub relative_file_paths: Vec<String>,
    pub ros_distro: String,
}

/// A YAML double-quoted scalar. Every character YAML does not allow raw in a document (C0 and
/// C1 controls, DEL, the line and paragraph separators, the byte-order mark) is escaped as
/// \uXXXX; JSON string syntax alone leaves DEL and C1 raw (found by fuzzing `recover`).
fn q(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20
                || ('\u{7f}'..='\u{9f}').contains(&c)
                || matches!(c, '\u{2028}' | '\u{2029}' | '\u{feff}') =>
            {
                out.push_str(&format!("\\u{:04X}", c as u32));
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

impl BagMetadata {
    /// The metadata.yaml text, in rosbag2's layout.
    pub fn to_yaml(&self) -> String {
        let mut y = String::new();
        let (start, dur, count) = (self.starting_time_ns, self.duration_ns, self.message_count);
        let _ = writeln!(y, "rosbag2_bagfile_information:");
        let _ = writeln!(y, "  version: {}", self.version);
        let _ = writeln!(y, "  storage_identifier: {}", q(&self.storage_identifier));
        let _ = writeln!(y, "  duration:\n    nanoseconds: {dur}");
        let _ = writeln!(y, "  starting_time:\n    nanoseconds_since_epoch: {start}");
        let _ = writeln!(y, "  message_count: {count}");
        if self.topics.is_empty() {
            let _ = writeln!(y, "  topics_with_message_count: []");
        } else {
            let _ = writeln!(y, "  topics_with_message_count:");
        }
        for t in &self.topics {
            let _ = writeln!(y, "    - topic_metadata:");
            let _ = writeln!(y, "        name: {}", q(&t.name));
            let _ = writeln!(y, "        type: {}", q(&t.type_name));
            let _ = writeln!(y, "        serialization_format: cdr");
            let _ = writeln!(
                y,
                "        offered_qos_profiles: {}",
                q(&t.offered_qos_profiles)
            );
            let _ = writeln!(
                y,
                "        type_description_hash: {}",
                q(&t.type_description_hash)
            );
            let _ = writeln!(y, "      message_count: {}", t.message_count);
        }
        let _ = writeln!(y, "  compression_format: \"\"");
        let _ = writeln!(y, "  compression_mode: \"\"");
        let _ = writeln!(y, "  relative_file_paths:");
        for f in &self.relative_file_paths {
            let _ = writeln!(y, "    - {}", q(f));
        }
        let _ = writeln!(y, "  files:");
        for f in &self.relative_file_paths {
            let _ = writeln!(y, "    - path: {}", q(f));
            let _ = writeln!(
                y,
                "      starting_time:\n        nanoseconds_since_epoch: {start}"
            );
            let _ = writeln!(y, "      duration:\n        nanoseconds: {dur}");
            let _ = writeln!(y, "      message_count: {count}");
        }
        let _ = writeln!(y, "  custom_data: {{}}");
        let _ = writeln!(y, "  ros_distro: {}", q(&self.ros_distro));
        y
    }

    /// Reads and checks `dir/metadata.yaml`.
    pub fn read(dir: &Path) -> Result<Self, BagError> {
        let path = dir.join("metadata.yaml");
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(BagError::Metadata {
                    path,
                    reason: "missing (a bag whose recorder died has none: \
                             `forcemap bag recover` rebuilds it)"
                        .to_string(),
                });
            }
            Err(e) => {
                return Err(BagError::Metadata {
                    path,
                    reason: e.to_string(),
                });
            }
        };
        Self::parse(&text).map_err(|reason| BagError::Metadata { path, reason })
    }

    /// Parses metadata.yaml text.
    pub fn parse(text: &str) -> Result<Self, String> {
        let file: File = serde_saphyr::from_str(text).map_err(|e| e.to_string())?;
        let m = file.rosbag2_bagfile_information;
        if m.storage_identifier != "mcap" {
            return Err(format!(
                "storage_identifier is '{}', only 'mcap' is supported",
                m.storage_identifier
            ));
        }
        if !m.compression_format.is_empty() {
            return Err(format!(
                "compression_format '{}' (file-level compression) is not supported",
                m.compression_format
            ));
        }
        let topics = m
            .topics_with_message_count
            .into_iter()
            .map(|t| TopicEntry {
                name: t.topic_metadata.name,
                type_name: t.topic_metadata.type_name,
                offered_qos_profiles: match t.topic_metadata.offered_qos_profiles {
                    Qos::Text(s) => s,
                    Qos::Other(_) => String::new(),
                },
                type_description_hash: t.topic_metadata.type_description_hash,
                message_count: t.message_count,
            })
            .collect();
        Ok(BagMetadata {
            version: m.version,
            storage_identifier: m.storage_identifier,
            starting_time_ns: m.starting_time.nanoseconds_since_epoch,
            duration_ns: m.duration.nanoseconds,
            message_count: m.message_count,
            topics,
            relative_file_paths: m.relative_file_paths,
            ros_distro: m.ros_distro,
        })
    }
}

#[derive(Deserialize)]
struct File {
    rosbag2_bagfile_information: Info,
}

#[derive(Deserialize)]
struct Info {
    version: u32,
    storage_identifier: String,
    #[serde(default)]
    duration: Nanos,
    #[serde(default)]
    starting_time: Since,
    #[serde(default)]
    message_count: u64,
    #[serde(default)]
    topics_with_message_count: Vec<TopicWithCount>,
    #[serde(default)]
    compression_format: String,
    relative_file_paths: Vec<String>,
    #[serde(default)]
    ros_distro: String,
}

#[derive(Deserialize, Default)]
struct Nanos {
    nanoseconds: u64,
}

#[derive(Deserialize, Default)]
struct Since {
    nanoseconds_since_epoch: u64,
}

#[derive(Deserialize)]
struct TopicWithCount {
    topic_metadata: TopicMeta,
    #[serde(default)]
    message_count: u64,
}

#[derive(Deserialize)]
struct TopicMeta {
    name: String,
    #[serde(rename = "type")]
    type_name: String,
    #[serde(default = "empty_qos")]
    offered_qos_profiles: Qos,
    #[serde(default)]
    type_description_hash: String,
}

/// Version <= 8 stores the profiles as a YAML string, version 9 as a YAML list.
#[derive(Deserialize)]
#[serde(untagged)]
enum Qos {
    Text(String),
    Other(serde::de::IgnoredAny),
}

fn empty_qos() -> Qos {
    Qos::Text(String::new())
}
