//! Bytes as a JSON file of columns (`forcemap_io::tabular::json`: named arrays, matrices of
//! rows) read through a map of a matrix's columns as one record: must return records or an
//! error, never panic.
#![no_main]

use std::path::Path;

use forcemap_io::channel_map::MapFile;
use forcemap_io::tabular::{ColumnFile, json::JsonColumns, read_through};
use libfuzzer_sys::fuzz_target;

const MAP: &str = "channels:
  time_s: {channel: data, column: 1}
  relative_displacement_m: {channel: data, column: 2, unit: in}
  force_n: {channel: data, column: 3, unit: kip}
table:
  records: whole
";

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.json");
    let Ok(mut file) = JsonColumns::from_bytes(data, path) else {
        return;
    };
    let picks: Vec<(usize, bool)> = (0..file.columns().len()).map(|k| (k, false)).collect();
    let _ = file.read(&picks);
    let Ok(MapFile::Columns(map)) = MapFile::from_yaml_str(MAP, "map.yaml") else {
        panic!("the fixed map parses");
    };
    if let Ok(mut file) = JsonColumns::from_bytes(data, path) {
        let _ = read_through(&mut file, path, &map);
    }
});
