//! Bag round trip: write messages on three topics, read them back from the bag directory and
//! from the bare .mcap, check metadata.yaml; optionally check with independent Python readers.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;
use std::path::Path;

use forcemap_io::bag::{
    BagMetadata, BagReader, BagWriter, BagWriterOptions, QosProfile, TopicSpec,
};

const VALUE_SCHEMA: &str = "float64 data\n";
const PAIR_SCHEMA: &str = "float64 a\nfloat64 b\n";

/// CDR little-endian encapsulation header + the f64 fields.
fn cdr(values: &[f64]) -> Vec<u8> {
    let mut v = vec![0x00, 0x01, 0x00, 0x00];
    for x in values {
        v.extend_from_slice(&x.to_le_bytes());
    }
    v
}

struct Written {
    topic: &'static str,
    log_time: u64,
    publish_time: u64,
    values: Vec<f64>,
}

fn write_bag(dir: &Path, options: BagWriterOptions) -> Vec<Written> {
    let mut w = BagWriter::create_with(dir, options).unwrap();
    let a = w
        .add_topic(&TopicSpec::new(
            "/value_a",
            "forcemap_test/msg/Value",
            VALUE_SCHEMA,
        ))
        .unwrap();
    let mut spec_b = TopicSpec::new("/value_b", "forcemap_test/msg/Value", VALUE_SCHEMA);
    spec_b.offered_qos_profiles = QosProfile {
        depth: 1,
        reliable: false,
        transient_local: true,
    }
    .to_yaml_string();
    let b = w.add_topic(&spec_b).unwrap();
    let p = w
        .add_topic(&TopicSpec::new(
            "/pair",
            "forcemap_test/msg/Pair",
            PAIR_SCHEMA,
        ))
        .unwrap();
    let mut written = Vec::new();
    let t0 = 1_700_000_000_000_000_000u64;
    for i in 0..200u64 {
        // log times not strictly in write order on /value_b, to test log-time ordering
        let (id, topic, lt, vals) = match i % 3 {
            0 => (a, "/value_a", t0 + i * 1_000_000, vec![i as f64 * 0.5]),
            1 => (
                b,
                "/value_b",
                t0 + i * 1_000_000 - 1_500_000,
                vec![-(i as f64)],
            ),
            _ => (
                p,
                "/pair",
                t0 + i * 1_000_000,
                vec![i as f64, 1.0 / (i as f64 + 1.0)],
            ),
        };
        let pt = lt - 250_000;
        w.write(id, lt, pt, &cdr(&vals)).unwrap();
        written.push(Written {
            topic,
            log_time: lt,
            publish_time: pt,
            values: vals,
        });
        if i % 50 == 49 {
            w.flush_chunk().unwrap();
        }
    }
    assert!(w.partial_path().exists());
    let out = w.finish().unwrap();
    assert_eq!(out, dir);
    written
}

fn sorted(mut w: Vec<Written>) -> Vec<Written> {
    w.sort_by_key(|m| m.log_time); // stable: equal times keep write order
    w
}

fn check_read(path: &Path, expected: &[Written]) {
    let bag = BagReader::open(path).unwrap();
    let got: Vec<_> = bag.messages().unwrap().collect::<Result<_, _>>().unwrap();
    assert_eq!(got.len(), expected.len());
    for (g, e) in got.iter().zip(expected) {
        assert_eq!(g.topic.name, e.topic);
        assert_eq!(g.log_time, e.log_time);
        assert_eq!(g.publish_time, e.publish_time);
        assert_eq!(g.data, cdr(&e.values));
        let ty = if e.topic == "/pair" {
            "forcemap_test/msg/Pair"
        } else {
            "forcemap_test/msg/Value"
        };
        assert_eq!(g.topic.type_name, ty);
        let schema = if e.topic == "/pair" {
            PAIR_SCHEMA
        } else {
            VALUE_SCHEMA
        };
        assert_eq!(g.topic.schema_text, schema);
    }
    let s = bag.summary();
    assert_eq!(s.message_count, expected.len() as u64);
    assert_eq!(s.start_ns, expected.first().unwrap().log_time);
    assert_eq!(s.end_ns, expected.last().unwrap().log_time);
    assert_eq!(s.duration_ns, s.end_ns - s.start_ns);
    let names: Vec<_> = s.topics.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["/value_a", "/value_b", "/pair"]);
    let counts: Vec<_> = s.topics.iter().map(|t| t.message_count).collect();
    assert_eq!(counts, [67, 67, 66]);
    assert!(s.topics[1].offered_qos_profiles.contains("durability: 1"));

    let only: Vec<_> = bag
        .messages_on(&["/pair"])
        .unwrap()
        .collect::<Result<Vec<_>, _>>()
        .unwrap();
    assert_eq!(only.len(), 66);
    assert!(only.iter().all(|m| m.topic.name == "/pair"));
}

#[test]
fn round_trip_directory_and_bare_mcap() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run1");
    let written = sorted(write_bag(&dir, BagWriterOptions::default()));
    check_read(&dir, &written);
    check_read(&dir.join("run1_0.mcap"), &written);
    // nothing else left next to the bag
    let names: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(names, ["run1"]);

    let text = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    println!("{text}");
    assert!(text.starts_with("rosbag2_bagfile_information:\n  version: 8\n"));
    let m = BagMetadata::parse(&text).unwrap();
    assert_eq!(m.version, 8);
    assert_eq!(m.storage_identifier, "mcap");
    assert_eq!(m.message_count, 200);
    assert_eq!(m.relative_file_paths, ["run1_0.mcap"]);
    assert_eq!(m.starting_time_ns, written[0].log_time);
    assert_eq!(m.duration_ns, written[199].log_time - written[0].log_time);
    let counts: Vec<_> = m
        .topics
        .iter()
        .map(|t| (t.name.as_str(), t.message_count))
        .collect();
    assert_eq!(counts, [("/value_a", 67), ("/value_b", 67), ("/pair", 66)]);
    assert!(
        m.topics[0]
            .offered_qos_profiles
            .starts_with("- history: 1\n  depth: 10\n")
    );
    // the QoS string is itself a YAML list
    let qos: Vec<serde_json::Value> =
        serde_saphyr::from_str(&m.topics[1].offered_qos_profiles).unwrap();
    assert_eq!(qos[0]["reliability"], 2);
    assert_eq!(qos[0]["durability"], 1);
    assert_eq!(qos[0]["deadline"]["sec"], 9223372036u64);
}

#[test]
fn round_trip_uncompressed_small_chunks() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("plain");
    let opts = BagWriterOptions {
        zstd: false,
        chunk_size: 300,
        ..BagWriterOptions::default()
    };
    let written = sorted(write_bag(&dir, opts));
    check_read(&dir, &written);
}

#[test]
fn mcap_header_and_channels_are_ros2() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("hdr");
    write_bag(&dir, BagWriterOptions::default());
    let bytes = std::fs::read(dir.join("hdr_0.mcap")).unwrap();
    let mut header = None;
    for rec in mcap::read::LinearReader::new(&bytes).unwrap() {
        if let mcap::records::Record::Header(h) = rec.unwrap() {
            header = Some(h);
        }
    }
    let h = header.unwrap();
    assert_eq!(h.profile, "ros2");
    assert!(h.library.starts_with("forcemap "));
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert!(summary.chunk_indexes.len() >= 4);
    for c in summary.channels.values() {
        assert_eq!(c.message_encoding, "cdr");
        let s = c.schema.as_ref().unwrap();
        assert_eq!(s.encoding, "ros2msg");
        assert!(c.metadata["offered_qos_profiles"].starts_with("- history: 1"));
    }
}

#[test]
fn dropped_or_aborted_writer_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("gone");
    let mut w = BagWriter::create(&dir).unwrap();
    let a = w
        .add_topic(&TopicSpec::new(
            "/v",
            "forcemap_test/msg/Value",
            VALUE_SCHEMA,
        ))
        .unwrap();
    w.write(a, 1, 1, &cdr(&[1.0])).unwrap();
    w.abort();
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
    {
        let mut w = BagWriter::create(&dir).unwrap();
        w.write(a, 1, 1, &cdr(&[1.0])).unwrap_err(); // topic not added to this writer
    }
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
    // an existing output is refused
    std::fs::create_dir(&dir).unwrap();
    assert!(matches!(
        BagWriter::create(&dir),
        Err(forcemap_io::bag::BagError::OutputExists { .. })
    ));
}

/// Writes a bag and a JSON of the expected decoded values, and runs
/// `tests/python/bag_check.py` with `$FORCEMAP_PYTHON` (rosbags + mcap + mcap-ros2-support).
#[test]
fn python_readers_decode_the_bag() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("pycheck");
    let written = write_bag(&dir, BagWriterOptions::default());
    let expected: Vec<_> = sorted(written)
        .iter()
        .map(|m| {
            let fields = if m.topic == "/pair" {
                serde_json::json!({"a": m.values[0], "b": m.values[1]})
            } else {
                serde_json::json!({"data": m.values[0]})
            };
            serde_json::json!({"topic": m.topic, "log_time": m.log_time, "fields": fields})
        })
        .collect();
    common::python_bag_check(&dir, &serde_json::Value::Array(expected));
}
