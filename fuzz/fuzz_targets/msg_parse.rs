//! Any text as a `.msg` definition, a bag's ros2msg schema and a field path: the parsers of
//! `forcemap_io::ros_msg` must return a value or an error, never panic; a schema that parses
//! is checked (unresolved or recursive types are errors, not stack overflows).
#![no_main]

use forcemap_io::ros_msg::{FieldPath, Registry, builtin_registry, parse_msg};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_msg("fuzz/Root", text);
    if let Ok(mut reg) = Registry::parse_schema("fuzz/msg/Root", text) {
        reg.extend_missing(&builtin_registry());
        if reg.check("fuzz/msg/Root").is_ok() {
            for line in text.lines() {
                if let Ok(path) = line.trim().parse::<FieldPath>() {
                    let _ = path.check(&reg, "fuzz/msg/Root");
                }
            }
        }
    }
    let _ = text.parse::<FieldPath>();
});
