//! Mirror of `std_msgs/msg/Header`.

use serde::{Deserialize, Serialize};

use crate::builtin_interfaces::{TIME_DEF, Time};
use crate::{MsgDef, ros_message};

pub const HEADER_DEF: MsgDef = MsgDef {
    name: "std_msgs/Header",
    text: include_str!("../deps/std_msgs/msg/Header.msg"),
    deps: &[TIME_DEF],
};

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

ros_message!(Header, "std_msgs/msg/Header", HEADER_DEF);

impl Header {
    pub fn new(stamp: Time, frame_id: impl Into<String>) -> Header {
        Header {
            stamp,
            frame_id: frame_id.into(),
        }
    }
}
