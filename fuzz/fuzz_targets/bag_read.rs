//! Bytes written to a temporary `fuzz.mcap` -> `BagReader::open`, `summary`, every message (all
//! topics, then the first topic alone), then `recover` into a temporary output bag. None of it
//! may panic; errors are fine. A bag that `recover` reports as written must open again and
//! hold the messages the report counts (the writer is the project's own).
#![no_main]

use forcemap_io::bag::{BagReader, recover};
use libfuzzer_sys::fuzz_target;

/// Reads at most this many messages per pass (the input is small; this only bounds the time).
const MAX_MESSAGES: usize = 100_000;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().expect("temporary directory");
    let input = dir.path().join("fuzz.mcap");
    std::fs::write(&input, data).expect("write the input file");

    if let Ok(bag) = BagReader::open(&input) {
        let summary = bag.summary();
        if let Ok(messages) = bag.messages() {
            for m in messages.take(MAX_MESSAGES) {
                if m.is_err() {
                    break;
                }
            }
        }
        if let Some(first) = summary.topics.first() {
            let _ = bag.topic(&first.name);
            if let Ok(messages) = bag.messages_on(&[first.name.as_str()]) {
                for m in messages.take(MAX_MESSAGES) {
                    if m.is_err() {
                        break;
                    }
                }
            }
        }
        let _ = bag.messages_on(&["/no/such/topic"]);
    }

    let output = dir.path().join("recovered");
    if let Ok(report) = recover(&input, &output) {
        let bag = BagReader::open(&report.output)
            .unwrap_or_else(|e| panic!("recovered bag does not open: {e}"));
        let n = bag
            .messages()
            .unwrap_or_else(|e| panic!("recovered bag: messages(): {e}"))
            .map(|m| m.unwrap_or_else(|e| panic!("recovered bag: reading a message: {e}")))
            .count() as u64;
        assert_eq!(
            n, report.messages,
            "recovered bag holds {n} messages, the report says {}",
            report.messages
        );
    }
});
