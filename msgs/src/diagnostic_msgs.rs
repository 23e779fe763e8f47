//! Mirror of `diagnostic_msgs` for the `/diagnostics` topic.

use serde::{Deserialize, Serialize};

use crate::std_msgs::{HEADER_DEF, Header};
use crate::{MsgDef, ros_message};

pub const KEY_VALUE_DEF: MsgDef = MsgDef {
    name: "diagnostic_msgs/KeyValue",
    text: include_str!("../deps/diagnostic_msgs/msg/KeyValue.msg"),
    deps: &[],
};

pub const DIAGNOSTIC_STATUS_DEF: MsgDef = MsgDef {
    name: "diagnostic_msgs/DiagnosticStatus",
    text: include_str!("../deps/diagnostic_msgs/msg/DiagnosticStatus.msg"),
    deps: &[KEY_VALUE_DEF],
};

pub const DIAGNOSTIC_ARRAY_DEF: MsgDef = MsgDef {
    name: "diagnostic_msgs/DiagnosticArray",
    text: include_str!("../deps/diagnostic_msgs/msg/DiagnosticArray.msg"),
    deps: &[HEADER_DEF, DIAGNOSTIC_STATUS_DEF],
};

/// `diagnostic_msgs/msg/KeyValue`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct KeyValue {
    pub key: String,
    pub value: String,
}

ros_message!(KeyValue, "diagnostic_msgs/msg/KeyValue", KEY_VALUE_DEF);

impl KeyValue {
    pub fn new(key: impl Into<String>, value: impl Into<String>) -> KeyValue {
        KeyValue {
            key: key.into(),
            value: value.into(),
        }
    }
}

/// `diagnostic_msgs/msg/DiagnosticStatus`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// One of [`Self::OK`], [`Self::WARN`], [`Self::ERROR`], [`Self::STALE`].
    pub level: u8,
    pub name: String,
    pub message: String,
    pub hardware_id: String,
    pub values: Vec<KeyValue>,
}

ros_message!(
    DiagnosticStatus,
    "diagnostic_msgs/msg/DiagnosticStatus",
    DIAGNOSTIC_STATUS_DEF
);

impl DiagnosticStatus {
    pub const OK: u8 = 0;
    pub const WARN: u8 = 1;
    pub const ERROR: u8 = 2;
    pub const STALE: u8 = 3;

    pub fn new(
        level: u8,
        name: impl Into<String>,
        message: impl Into<String>,
        hardware_id: impl Into<String>,
    ) -> DiagnosticStatus {
        DiagnosticStatus {
            level,
            name: name.into(),
            message: message.into(),
            hardware_id: hardware_id.into(),
            values: Vec::new(),
        }
    }

    /// Adds a key-value pair.
    pub fn with_value(mut self, key: impl Into<String>, value: impl ToString) -> Self {
        self.values.push(KeyValue::new(key, value.to_string()));
        self
    }
}

/// `diagnostic_msgs/msg/DiagnosticArray`, the message of `/diagnostics`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct DiagnosticArray {
    pub header: Header,
    pub status: Vec<DiagnosticStatus>,
}

ros_message!(
    DiagnosticArray,
    "diagnostic_msgs/msg/DiagnosticArray",
    DIAGNOSTIC_ARRAY_DEF
);
