//! Recovery of bags whose writer died: the MCAP file cut at many offsets.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::Path;

use forcemap_io::bag::{BagReader, BagWriter, BagWriterOptions, TopicSpec, recover};

fn cdr(x: f64) -> Vec<u8> {
    let mut v = vec![0x00, 0x01, 0x00, 0x00];
    v.extend_from_slice(&x.to_le_bytes());
    v
}

/// (topic, log_time, publish_time, data) in write order (= log-time order).
type Msg = (String, u64, u64, Vec<u8>);

fn write(dir: &Path, zstd: bool, n: u64) -> Vec<Msg> {
    let opts = BagWriterOptions {
        zstd,
        chunk_size: 400,
        max_chunk_age: None,
        ..BagWriterOptions::default()
    };
    let mut w = BagWriter::create_with(dir, opts).unwrap();
    let ids = [
        w.add_topic(&TopicSpec::new(
            "/a",
            "forcemap_test/msg/Value",
            "float64 data\n",
        ))
        .unwrap(),
        w.add_topic(&TopicSpec::new(
            "/b",
            "forcemap_test/msg/Value",
            "float64 data\n",
        ))
        .unwrap(),
    ];
    let mut out = Vec::new();
    for i in 0..n {
        let topic = (i % 2) as usize;
        let t = 1_000_000_000 + i * 10_000_000;
        let data = cdr(i as f64 * 1.25);
        w.write(ids[topic], t, t - 7, &data).unwrap();
        out.push((["/a", "/b"][topic].to_string(), t, t - 7, data));
    }
    w.finish().unwrap();
    out
}

fn read_all(path: &Path) -> Vec<Msg> {
    let bag = BagReader::open(path).unwrap();
    bag.messages()
        .unwrap()
        .map(|m| {
            let m = m.unwrap();
            (m.topic.name.clone(), m.log_time, m.publish_time, m.data)
        })
        .collect()
}

/// For an uncompressed file: the end offset of every message record, in file order.
fn message_ends(bytes: &[u8]) -> Vec<u64> {
    let summary = mcap::Summary::read(bytes).unwrap().unwrap();
    let mut ends = Vec::new();
    for ci in &summary.chunk_indexes {
        // chunk record: op(1) len(8) start(8) end(8) usize(8) crc(4) compression ""(4) len(8)
        let data_start = ci.chunk_start_offset as usize + 9 + 40;
        let data_end = (ci.chunk_start_offset + ci.chunk_length) as usize;
        let mut pos = data_start;
        while pos < data_end {
            let op = bytes[pos];
            let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
            pos += 9 + len;
            if op == 0x05 {
                ends.push(pos as u64);
            }
        }
    }
    ends
}

fn check_cuts(zstd: bool) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("whole");
    let written = write(&dir, zstd, 120);
    let bytes = std::fs::read(dir.join("whole_0.mcap")).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert!(summary.chunk_indexes.len() > 5, "want many chunks");
    // messages per chunk, in file order
    let per_chunk: Vec<u64> = summary
        .chunk_indexes
        .iter()
        .map(|ci| {
            written
                .iter()
                .filter(|m| m.1 >= ci.message_start_time && m.1 <= ci.message_end_time)
                .count() as u64
        })
        .collect();
    assert_eq!(per_chunk.iter().sum::<u64>(), written.len() as u64);
    let ends = if zstd {
        Vec::new()
    } else {
        message_ends(&bytes)
    };

    // offsets: every chunk boundary and its neighbours, mid-chunk, data end, before the footer
    let mut cuts = vec![
        8,
        9,
        20,
        bytes.len() - 1,
        bytes.len() - 8,
        bytes.len() - 9,
        bytes.len() - 30,
    ];
    for ci in &summary.chunk_indexes {
        let (s, l) = (ci.chunk_start_offset as usize, ci.chunk_length as usize);
        cuts.extend([
            s,
            s + 1,
            s + 9,
            s + 50,
            s + l / 2,
            s + l - 1,
            s + l,
            s + l + 1,
            s + l + 20,
        ]);
    }
    for c in (8..bytes.len()).step_by(37) {
        cuts.push(c);
    }
    cuts.sort_unstable();
    cuts.dedup();
    for (k, &cut) in cuts.iter().enumerate() {
        let cut_dir = tmp.path().join(format!("cut{k}"));
        std::fs::create_dir(&cut_dir).unwrap();
        let cut_file = cut_dir.join("cut_0.mcap");
        std::fs::write(&cut_file, &bytes[..cut]).unwrap();
        let out = tmp.path().join(format!("rec{k}"));
        let report = recover(&cut_dir, &out).unwrap_or_else(|e| panic!("cut at {cut}: {e}"));
        let got = read_all(&out);
        // a prefix of what was written
        assert_eq!(got[..], written[..got.len()], "cut at {cut}: not a prefix");
        // every message of every chunk that is whole before the cut
        let mut min = 0;
        let mut max = 0;
        for (ci, n) in summary.chunk_indexes.iter().zip(&per_chunk) {
            if ci.chunk_start_offset + ci.chunk_length <= cut as u64 {
                min += n;
            }
            if ci.chunk_start_offset < cut as u64 {
                max += n;
            }
        }
        let n = got.len() as u64;
        assert!(
            n >= min && n <= max,
            "cut at {cut}: {n} messages, expected {min}..={max}"
        );
        if !zstd {
            // uncompressed: exactly the messages whose record is complete
            let exact = ends.iter().filter(|&&e| e <= cut as u64).count() as u64;
            assert_eq!(n, exact, "cut at {cut}");
        }
        assert_eq!(report.messages, n);
        // only the end magic missing: the footer was read, nothing is reported as cut
        if cut < bytes.len() - 8 {
            let at = report.cut_offset.expect("a cut file is reported as cut");
            assert!(at <= cut as u64, "cut at {cut}: reported at {at}");
        }
    }
    // the whole file recovers to everything
    let out = tmp.path().join("rec_whole");
    let report = recover(dir.join("whole_0.mcap"), &out).unwrap();
    assert_eq!(report.cut_offset, None);
    assert_eq!(read_all(&out), written);
}

#[test]
fn recover_uncompressed_cut_anywhere() {
    check_cuts(false);
}

#[test]
fn recover_zstd_cut_anywhere() {
    check_cuts(true);
}

#[test]
fn killed_writer_loses_nothing_before_the_last_flush() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("live");
    let mut w = BagWriter::create(&dir).unwrap();
    let a = w
        .add_topic(&TopicSpec::new(
            "/a",
            "forcemap_test/msg/Value",
            "float64 data\n",
        ))
        .unwrap();
    let mut expected = Vec::new();
    for i in 0..50u64 {
        let t = 5_000 + i;
        w.write(a, t, t, &cdr(i as f64)).unwrap();
        expected.push(("/a".to_string(), t, t, cdr(i as f64)));
        if i % 10 == 9 {
            w.flush_chunk().unwrap();
        }
    }
    // written after the last flush: may be lost
    w.write(a, 9_999, 9_999, &cdr(-1.0)).unwrap();
    let partial = w.partial_path().to_path_buf();
    std::mem::forget(w); // the process "dies": no footer, no metadata.yaml, no rename
    assert!(!dir.exists());
    // the damaged file is reported as such, with the way out
    let err = BagReader::open(partial.join("live_0.mcap")).unwrap_err();
    let text = err.to_string();
    assert!(text.contains("forcemap bag recover"), "{text}");
    assert!(matches!(
        err,
        forcemap_io::bag::BagError::Corrupt {
            offset: Some(_),
            ..
        }
    ));

    let out = tmp.path().join("live_recovered");
    let report = recover(&partial, &out).unwrap();
    assert_eq!(report.messages, 50);
    assert_eq!(read_all(&out), expected);
    let meta = BagReader::open(&out).unwrap().metadata().cloned().unwrap();
    assert_eq!(meta.message_count, 50);
    assert_eq!(meta.topics[0].message_count, 50);
    // recover never overwrites
    assert!(recover(&partial, &out).is_err());
}
