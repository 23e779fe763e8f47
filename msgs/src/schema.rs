//! Message definitions and MCAP `ros2msg` schema text.

/// The MCAP schema encoding of [`MsgDef::schema`].
pub const SCHEMA_ENCODING: &str = "ros2msg";

/// The line (without its newline) that separates the definitions in a schema: 80 `=`.
pub const SEPARATOR: &str =
    "================================================================================";

/// The `.msg` text of one type and the types its fields use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MsgDef {
    /// Name as a `MSG:` line spells it: `pkg/Type` (e.g. `std_msgs/Header`).
    pub name: &'static str,
    /// The `.msg` text.
    pub text: &'static str,
    /// Types used by the fields, in field order (each once).
    pub deps: &'static [MsgDef],
}

impl MsgDef {
    /// Full ROS 2 type name: `pkg/msg/Type`.
    pub fn type_name(&self) -> String {
        match self.name.split_once('/') {
            Some((pkg, ty)) => format!("{pkg}/msg/{ty}"),
            None => self.name.to_string(),
        }
    }

    /// All dependencies, recursively, depth first in field order, each once, without `self`.
    pub fn all_dependencies(&self) -> Vec<MsgDef> {
        fn walk(d: &MsgDef, top: &str, out: &mut Vec<MsgDef>) {
            for dep in d.deps {
                if dep.name != top && !out.iter().any(|o| o.name == dep.name) {
                    out.push(*dep);
                    walk(dep, top, out);
                }
            }
        }
        let mut out = Vec::new();
        walk(self, self.name, &mut out);
        out
    }

    /// The MCAP `ros2msg` schema text (see [`crate::RosMessage::schema`]).
    pub fn schema(&self) -> String {
        let mut s = String::from(self.text.trim_end_matches('\n'));
        s.push('\n');
        for dep in self.all_dependencies() {
            s.push_str(SEPARATOR);
            s.push_str("\nMSG: ");
            s.push_str(dep.name);
            s.push('\n');
            s.push_str(dep.text.trim_end_matches('\n'));
            s.push('\n');
        }
        s
    }
}
