//! Any text as a channel map (its own YAML or a ROS 2 params file): the parser of
//! `forcemap_io::channel_map` must return a map or an error, never panic.
#![no_main]

use forcemap_io::channel_map::ChannelMap;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(map) = ChannelMap::from_yaml_str(text, "fuzz.yaml")
    {
        for (_, s) in map.sources() {
            let _ = s.apply(1.0);
        }
    }
});
