//! Bytes -> the CSV dialect detection (`dialect::prepare`): must never panic, and what it
//! prepares must never be longer than the input nor lose the header line.
#![no_main]

use std::path::Path;

use forcemap_io::csv_export::dialect::prepare;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(p) = prepare(data, Path::new("fuzz.csv")) {
        assert!(p.text.len() <= data.len(), "prepared text grew");
        let body = data.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(data);
        let first = |b: &[u8]| b.iter().position(|&c| c == b'\n').map(|i| b[..i].to_vec());
        if let Some(header) = first(body) {
            assert_eq!(first(&p.text), Some(header), "the header line changed");
        }
    }
});
