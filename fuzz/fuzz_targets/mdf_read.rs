//! Bytes written to a temporary `fuzz.mf4` -> `read_mdf` (mdf4-rs opens paths only): must only
//! ever return `Err` or records, never panic.
#![no_main]

use forcemap_io::mdf::read_mdf;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().expect("temporary directory");
    let input = dir.path().join("fuzz.mf4");
    std::fs::write(&input, data).expect("write the input file");
    let _ = read_mdf(&input);
});
