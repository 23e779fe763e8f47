//! ROS 2 messages of forcemap (`forcemap_msgs`) and the Rust types that carry them.
//!
//! The `.msg` files in `msgs/msg/` are the single source of the message definitions: they are
//! built into a ROS package by colcon (`package.xml`, `CMakeLists.txt`) and embedded here with
//! `include_str!` for the MCAP `ros2msg` schemas. Each Rust type is a serde struct with the
//! fields in `.msg` order, so it is published as is by `ros2-client` (RustDDS) and encodes to
//! the same CDR bytes as any other ROS 2 implementation:
//!
//! - [`msg`]: `forcemap_msgs/msg/{RigSample, ExcitationState, HarmonicPhasors, IdentifiedParameters,
//!   AxisSample, GapDiagnosis}`;
//! - [`builtin_interfaces`], [`std_msgs`], [`diagnostic_msgs`]: mirrors of the upstream types
//!   the messages and the `/diagnostics` topic use.
//!
//! [`RosMessage`] gives each type its ROS type name, its schema text and CDR encoding with the
//! 4-byte encapsulation header (as stored in rosbag2 / MCAP files):
//!
//! ```
//! use forcemap_msgs::{RosMessage, builtin_interfaces::Time, std_msgs::Header};
//! let h = Header::new(Time { sec: 1, nanosec: 2 }, "rig");
//! let bytes = h.to_cdr();
//! assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
//! assert_eq!(Header::from_cdr(&bytes).unwrap(), h);
//! assert_eq!(Header::TYPE_NAME, "std_msgs/msg/Header");
//! assert!(Header::schema().contains("MSG: builtin_interfaces/Time"));
//! ```

pub mod builtin_interfaces;
mod cdr;
mod convert;
pub mod diagnostic_msgs;
pub mod msg;
mod schema;
pub mod std_msgs;

pub use cdr::{CdrError, ENCAPSULATION_CDR_BE, ENCAPSULATION_CDR_LE, decode, encode};
pub use convert::ConversionError;
pub use schema::{MsgDef, SCHEMA_ENCODING, SEPARATOR};

use serde::{Serialize, de::DeserializeOwned};

/// A ROS 2 message type.
pub trait RosMessage: Serialize + DeserializeOwned {
    /// Full ROS 2 type name, e.g. `forcemap_msgs/msg/RigSample`.
    const TYPE_NAME: &'static str;
    /// The `.msg` text of this type and its dependencies.
    const DEFINITION: MsgDef;

    /// The MCAP `ros2msg` schema text: this type's `.msg` text, then each dependency
    /// (recursively, each once) after a line of 80 `=` and a line `MSG: pkg/Type`.
    fn schema() -> String {
        Self::DEFINITION.schema()
    }

    /// CDR bytes (XCDR1 little endian) with the encapsulation header `00 01 00 00`.
    fn to_cdr(&self) -> Vec<u8> {
        cdr::encode(self)
    }

    /// Decodes CDR bytes that start with the encapsulation header (little or big endian).
    fn from_cdr(bytes: &[u8]) -> Result<Self, CdrError> {
        cdr::decode(bytes, Self::TYPE_NAME)
    }
}

/// Implements [`RosMessage`] for a type.
macro_rules! ros_message {
    ($ty:ty, $type_name:literal, $def:expr) => {
        impl $crate::RosMessage for $ty {
            const TYPE_NAME: &'static str = $type_name;
            const DEFINITION: $crate::MsgDef = $def;
        }
    };
}
pub(crate) use ros_message;

#[cfg(feature = "ros2-client")]
mod ros2_client_impls {
    use crate::builtin_interfaces::Time;
    use crate::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus, KeyValue};
    use crate::msg::{
        AxisSample, ExcitationState, GapDiagnosis, HarmonicPhasors, IdentifiedParameters, RigSample,
    };
    use crate::std_msgs::Header;

    impl ros2_client::Message for Time {}
    impl ros2_client::Message for Header {}
    impl ros2_client::Message for KeyValue {}
    impl ros2_client::Message for DiagnosticStatus {}
    impl ros2_client::Message for DiagnosticArray {}
    impl ros2_client::Message for RigSample {}
    impl ros2_client::Message for ExcitationState {}
    impl ros2_client::Message for HarmonicPhasors {}
    impl ros2_client::Message for IdentifiedParameters {}
    impl ros2_client::Message for AxisSample {}
    impl ros2_client::Message for GapDiagnosis {}
}
