//! Bytes -> `read_csv_from`: must only ever return `Err`, never panic.
#![no_main]

use std::path::Path;

use forcemap_io::csv_export::read_csv_from;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = read_csv_from(data, Path::new("fuzz.csv"));
});
