//! Bytes -> `read_tdms_bytes`: must only ever return `Err` or records, never panic, and
//! allocate no more than the input justifies.
#![no_main]

use std::path::Path;

use forcemap_io::tdms::read_tdms_bytes;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = read_tdms_bytes(data, Path::new("fuzz.tdms"));
});
