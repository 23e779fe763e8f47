//! `forcemap bag info|recover` at the process boundary.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use common::forcemap;

use std::process::Command;

use forcemap_io::bag::{BagWriter, BagWriterOptions, TopicSpec};

fn value_cdr(v: f64) -> Vec<u8> {
    let mut b = vec![0, 1, 0, 0];
    b.extend_from_slice(&v.to_le_bytes());
    b
}

/// A bag with `n` messages on /value, chunks closed after every 10 messages.
fn write_bag(dir: &std::path::Path, n: u64) -> std::path::PathBuf {
    let opts = BagWriterOptions {
        zstd: false,
        ..BagWriterOptions::default()
    };
    let mut w = BagWriter::create_with(dir, opts).unwrap();
    let id = w
        .add_topic(&TopicSpec::new(
            "/value",
            "forcemap_test/msg/Value",
            "float64 data\n",
        ))
        .unwrap();
    for i in 0..n {
        let t = 1_700_000_000_000_000_000 + i * 10_000_000;
        w.write(id, t, t, &value_cdr(i as f64)).unwrap();
        if i % 10 == 9 {
            w.flush_chunk().unwrap();
        }
    }
    w.finish().unwrap()
}

#[test]
fn info_reports_topics_counts_and_duration() {
    let tmp = tempfile::tempdir().unwrap();
    let bag = write_bag(&tmp.path().join("run"), 101);
    let o = forcemap(&["bag", "info", bag.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["messages"], 101);
    assert_eq!(v["topics"][0]["name"], "/value");
    assert_eq!(v["topics"][0]["type"], "forcemap_test/msg/Value");
    assert!((v["duration_s"].as_f64().unwrap() - 1.0).abs() < 1e-9);
}

#[test]
fn recover_restores_every_flushed_message_of_a_truncated_bag() {
    let tmp = tempfile::tempdir().unwrap();
    let bag = write_bag(&tmp.path().join("run"), 100);
    let mcap = bag.join("run_0.mcap");
    let bytes = std::fs::read(&mcap).unwrap();
    // cut the file in the middle: the footer, summary and later chunks are lost
    let cut = tmp.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let o = forcemap(&["bag", "info", cut.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(
        e.contains("recover"),
        "the error should point to `forcemap bag recover`: {e}"
    );
    let out = tmp.path().join("fixed");
    let o = forcemap(&[
        "bag",
        "recover",
        cut.to_str().unwrap(),
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = forcemap(&["bag", "info", out.to_str().unwrap(), "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let n = v["messages"].as_u64().unwrap();
    // Uncompressed chunks of 10: every message wholly inside the cut file survives, in order,
    // and nothing after the cut.
    let reader = forcemap_io::bag::BagReader::open(&out).unwrap();
    let values: Vec<f64> = reader
        .messages()
        .unwrap()
        .map(|m| f64::from_le_bytes(m.unwrap().data[4..12].try_into().unwrap()))
        .collect();
    assert_eq!(values, (0..n).map(|i| i as f64).collect::<Vec<_>>());
    let whole = bytes[..bytes.len() / 2]
        .windows(12)
        .filter(|w| w[..4] == [0, 1, 0, 0])
        .count() as u64;
    assert!(
        n >= 10 && n <= whole && n < 100,
        "recovered {n}; {whole} messages lie wholly before the cut"
    );
    // a second recover onto an existing output is refused, and changes nothing
    let o = forcemap(&[
        "bag",
        "recover",
        cut.to_str().unwrap(),
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
}

/// Found by fuzzing (fuzz/regressions/bag_read): a 156-byte file whose header claims a 4 GiB
/// string. Under a 2 GB address-space limit the reader must answer with an error, not abort on
/// the allocation.
#[test]
fn a_huge_length_in_a_tiny_file_is_an_error_not_an_allocation() {
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/regressions/bag_read/oom-header-string-len-4GiB.mcap");
    let o = Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v 2000000; exec '{}' bag info '{}'",
            env!("CARGO_BIN_EXE_forcemap"),
            input.display()
        ))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(
        e.starts_with("error:") && !e.contains("memory allocation"),
        "{e}"
    );
}
