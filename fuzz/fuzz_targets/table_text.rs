//! Bytes as a text file of columns (`forcemap_io::tabular::text`: separators, header, units
//! row, decimal commas, comments, a truncated last line) read through a map of three columns
//! into records: must return records or an error, never panic, and every data row's line must
//! be a line of the input.
#![no_main]

use std::path::Path;

use forcemap_io::channel_map::MapFile;
use forcemap_io::tabular::{ColumnFile, read_through, text::TextColumns};
use forcemap_io::table_map::TextOptions;
use libfuzzer_sys::fuzz_target;

const MAP: &str = "channels:
  time_s: {channel: 1}
  relative_displacement_m: {channel: 2, unit: mm}
  force_n: {channel: 3, unit: N}
";

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.txt");
    let Ok(mut file) = TextColumns::from_bytes(data.to_vec(), path, &TextOptions::default()) else {
        return;
    };
    let lines = data.iter().filter(|&&b| b == b'\n').count() as u64 + 1;
    if let Some(rows) = file.row_lines() {
        assert!(rows.iter().all(|&l| l >= 1 && l <= lines), "a row on no line");
    }
    let picks: Vec<(usize, bool)> = (0..file.columns().len()).map(|k| (k, k == 0)).collect();
    let _ = file.read(&picks);
    let Ok(MapFile::Columns(map)) = MapFile::from_yaml_str(MAP, "map.yaml") else {
        panic!("the fixed map parses");
    };
    if let Ok(mut file) = TextColumns::from_bytes(data.to_vec(), path, &map.text) {
        let _ = read_through(&mut file, path, &map);
    }
});
