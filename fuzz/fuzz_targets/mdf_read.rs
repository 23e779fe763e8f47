//! Bytes written to a temporary `fuzz.mf4` -> `read_mdf` (mdf4-rs opens paths only): must only
//! ever return `Err` or records, never panic.
//!
//! `read_mdf` turns a panic inside mdf4-rs 0.3.0 (links it follows unchecked) into an error on
//! purpose (`std::panic::catch_unwind`), but libfuzzer-sys's panic hook aborts before any
//! unwinding, so every panic the reader handles would count as a crash. The hook is replaced by
//! a quiet one; a panic that escapes `read_mdf` (ours, or the crate's outside the guarded call)
//! still reaches libfuzzer-sys's own catch around this closure, which aborts: a crash.
#![no_main]

use forcemap_io::mdf::read_mdf;
use libfuzzer_sys::fuzz_target;

static QUIET_HOOK: std::sync::Once = std::sync::Once::new();

fuzz_target!(|data: &[u8]| {
    QUIET_HOOK.call_once(|| std::panic::set_hook(Box::new(|_| {})));
    let dir = tempfile::tempdir().expect("temporary directory");
    let input = dir.path().join("fuzz.mf4");
    std::fs::write(&input, data).expect("write the input file");
    let _ = read_mdf(&input);
});
