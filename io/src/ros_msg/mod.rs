//! ROS 2 messages of any type, decoded from their definition with no generated code, as
//! rosbags and Foxglove do: the `.msg` language and the schema text of MCAP bags ([`parse`]),
//! built-in definitions of common standard messages ([`builtin`]), plain CDR decoding into a
//! value tree ([`decode`]) and field paths into it ([`path`]).
//!
//! Why not a crate: the Rust crates that decode ROS 2 messages dynamically were not fit when
//! this was written: `ros2_message` (0.0.5, last released July 2024) decodes little-endian CDR
//! only and says it is not tested much; `mcap2arrow-ros2msg` decodes into Apache Arrow (a large
//! dependency tree for a few numbers); `ros2msg` parses `.msg` files but does not decode CDR.

pub mod builtin;
pub mod decode;
pub mod parse;
pub mod path;

pub use builtin::builtin_registry;
pub use decode::{DecodeError, Value, decode};
pub use parse::{MsgDef, MsgError, Registry, full_type_name, parse_msg};
pub use path::{FieldPath, PathError};

/// The name of the `std_msgs/Header` type.
pub const HEADER_TYPE: &str = "std_msgs/msg/Header";

/// True when messages of `type_name` carry a `header` of type `std_msgs/Header` (their stamp
/// is the time of the data).
pub fn has_header(reg: &Registry, type_name: &str) -> bool {
    reg.get(type_name).is_some_and(|d| {
        d.fields.iter().any(|f| {
            f.name == "header"
                && f.array == parse::ArrayKind::Single
                && f.ty == parse::FieldType::Message(HEADER_TYPE.to_string())
        })
    })
}

/// The header stamp of a decoded message (nanoseconds since the epoch), if it has one.
pub fn header_stamp_ns(msg: &Value) -> Option<i128> {
    let stamp = msg.field("header")?.field("stamp")?;
    let sec = stamp.field("sec")?.as_f64()? as i128;
    let nanosec = stamp.field("nanosec")?.as_f64()? as i128;
    Some(sec * 1_000_000_000 + nanosec)
}

#[cfg(test)]
mod tests;
