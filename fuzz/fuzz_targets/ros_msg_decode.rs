//! Any bytes against any definition: the dynamic CDR decoder of `forcemap_io::ros_msg` must
//! return a value or an error, never panic (a foreign participant's malformed message must not
//! crash a node). Input: a 2-byte little-endian length N, N bytes of text (a type name line,
//! then that type's ros2msg schema as a bag embeds it), then the CDR bytes. The CDR bytes are also
//! decoded against every built-in definition, and a decoded value is read at a few paths.
#![no_main]

use forcemap_io::ros_msg::{FieldPath, Registry, builtin, builtin_registry, decode, header_stamp_ns};
use libfuzzer_sys::fuzz_target;

const PATHS: [&str; 5] = ["data", "data[0]", "position[a]", "wrench.force.z", "header.stamp.sec"];

fn read(reg: &Registry, type_name: &str, bytes: &[u8]) {
    if let Ok(v) = decode(reg, type_name, bytes) {
        let _ = header_stamp_ns(&v);
        for p in PATHS {
            if let Ok(path) = p.parse::<FieldPath>() {
                let _ = path.check(reg, type_name);
                let _ = path.get(&v);
            }
        }
    }
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 2 {
        return;
    }
    let n = (u16::from_le_bytes([data[0], data[1]]) as usize).min(data.len() - 2);
    let (text, cdr) = data[2..].split_at(n);
    let builtins = builtin_registry();
    if let Ok(text) = std::str::from_utf8(text)
        && let Some((root, schema)) = text.split_once('\n')
        && let Ok(mut reg) = Registry::parse_schema(root, schema)
        && let Ok(root) = forcemap_io::ros_msg::full_type_name(root)
    {
        reg.extend_missing(&builtins);
        if reg.check(&root).is_ok() {
            read(&reg, &root, cdr);
        }
    }
    for (name, _) in builtin::BUILTIN_DEFINITIONS {
        read(&builtins, name, cdr);
    }
});
