//! Definitions of common standard messages, so that topics of these types decode with no
//! schema (field lines as in ros2/common_interfaces and rcl_interfaces, comments left out).

use super::parse::{Registry, parse_msg};

/// (type, definition) of the built-in messages.
pub const BUILTIN_DEFINITIONS: &[(&str, &str)] = &[
    ("builtin_interfaces/msg/Time", "int32 sec\nuint32 nanosec\n"),
    (
        "builtin_interfaces/msg/Duration",
        "int32 sec\nuint32 nanosec\n",
    ),
    (
        "std_msgs/msg/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    ),
    ("std_msgs/msg/Float64", "float64 data\n"),
    ("std_msgs/msg/Float32", "float32 data\n"),
    ("std_msgs/msg/Int32", "int32 data\n"),
    ("std_msgs/msg/UInt32", "uint32 data\n"),
    ("std_msgs/msg/Int64", "int64 data\n"),
    (
        "std_msgs/msg/MultiArrayDimension",
        "string label\nuint32 size\nuint32 stride\n",
    ),
    (
        "std_msgs/msg/MultiArrayLayout",
        "MultiArrayDimension[] dim\nuint32 data_offset\n",
    ),
    (
        "std_msgs/msg/Float64MultiArray",
        "MultiArrayLayout layout\nfloat64[] data\n",
    ),
    (
        "std_msgs/msg/Float32MultiArray",
        "MultiArrayLayout layout\nfloat32[] data\n",
    ),
    (
        "sensor_msgs/msg/JointState",
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
    ),
    (
        "geometry_msgs/msg/Vector3",
        "float64 x\nfloat64 y\nfloat64 z\n",
    ),
    (
        "geometry_msgs/msg/Wrench",
        "Vector3 force\nVector3 torque\n",
    ),
    (
        "geometry_msgs/msg/WrenchStamped",
        "std_msgs/Header header\nWrench wrench\n",
    ),
];

/// The registry of [`BUILTIN_DEFINITIONS`].
pub fn builtin_registry() -> Registry {
    let mut reg = Registry::new();
    for (name, text) in BUILTIN_DEFINITIONS {
        // Fixed texts, checked by the tests: a failure here is a typo in the table.
        if let Ok(def) = parse_msg(name, text) {
            reg.insert(def);
        }
    }
    reg
}
