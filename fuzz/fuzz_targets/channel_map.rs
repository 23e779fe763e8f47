//! Any text as a channel map (its own YAML, with topic or file-column entries, or a ROS 2
//! params file): the parser of `forcemap_io::channel_map` must return a map or an error, never
//! panic.
#![no_main]

use forcemap_io::channel_map::MapFile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        match MapFile::from_yaml_str(text, "fuzz.yaml") {
            Ok(MapFile::Topics(map)) => {
                for (_, s) in map.sources() {
                    let _ = s.apply(1.0);
                }
            }
            Ok(MapFile::Columns(map)) => {
                for (_, s) in map.sources() {
                    let _ = s.column.to_string();
                }
            }
            Err(_) => {}
        }
    }
});
