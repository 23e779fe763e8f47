//! rosbag2 bags with MCAP storage, generic over (topic, type name, schema text, CDR bytes).
//!
//! A bag is a directory `NAME/` with `metadata.yaml` (rosbag2 metadata version 8, which ROS 2
//! Humble and Jazzy both read) and `NAME_0.mcap` (profile `ros2`, schemas `pkg/msg/Type` in
//! encoding `ros2msg`, messages in `cdr`, channel metadata `offered_qos_profiles`, zstd chunks
//! closed at least once a second).
//!
//! - [`BagWriter`] writes a bag atomically (in `.NAME.partial/`, renamed at the end);
//! - [`BagReader`] reads a bag directory or a bare `.mcap` in log-time order;
//! - [`recover`] rebuilds a bag from the MCAP file of a recorder that died.
mod error;
mod guard;
mod metadata;
mod reader;
mod recover;
mod scan;
mod writer;

pub use error::BagError;
pub use metadata::{BagMetadata, METADATA_VERSION, QosProfile, TopicEntry};
pub use reader::{BagMessage, BagReader, BagSummary, Messages, TopicInfo};
pub use recover::{RecoveryReport, recover};
pub use writer::{BagSink, BagWriter, BagWriterOptions, TopicId, TopicSpec, partial_dir};

/// Schema encoding of ROS 2 .msg definitions.
pub const SCHEMA_ENCODING: &str = "ros2msg";
/// MCAP channel metadata key of the offered QoS profiles (as in rosbag2's MCAP storage).
pub const QOS_METADATA_KEY: &str = "offered_qos_profiles";
