//! Bad input gives the right error and never a panic.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::collections::BTreeMap;

use forcemap_io::bag::{BagError, BagReader, BagWriter, TopicSpec, recover};

fn small_bag(dir: &std::path::Path) {
    let mut w = BagWriter::create(dir).unwrap();
    let a = w
        .add_topic(&TopicSpec::new(
            "/a",
            "forcemap_test/msg/Value",
            "float64 data\n",
        ))
        .unwrap();
    let b = w
        .add_topic(&TopicSpec::new(
            "/b",
            "forcemap_test/msg/Value",
            "float64 data\n",
        ))
        .unwrap();
    for i in 0..20u64 {
        let mut d = vec![0, 1, 0, 0];
        d.extend_from_slice(&(i as f64).to_le_bytes());
        w.write(if i % 2 == 0 { a } else { b }, i, i, &d).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn missing_file_and_bad_magic() {
    let tmp = tempfile::tempdir().unwrap();
    let err = BagReader::open(tmp.path().join("nope")).unwrap_err();
    assert!(matches!(err, BagError::NotFound { .. }), "{err}");
    let f = tmp.path().join("x.mcap");
    std::fs::write(&f, b"hello, this is not mcap at all").unwrap();
    let err = BagReader::open(&f).unwrap_err();
    assert!(matches!(err, BagError::NotMcap { .. }), "{err}");
    println!("{err}");
    std::fs::write(&f, b"").unwrap();
    assert!(matches!(BagReader::open(&f), Err(BagError::NotMcap { .. })));
    let err = recover(&f, tmp.path().join("out")).unwrap_err();
    assert!(matches!(err, BagError::NotMcap { .. }), "{err}");
    assert!(!tmp.path().join("out").exists());
}

#[test]
fn truncated_file_names_offset_and_recover() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bag");
    small_bag(&dir);
    let mcap = dir.join("bag_0.mcap");
    let bytes = std::fs::read(&mcap).unwrap();
    std::fs::write(&mcap, &bytes[..bytes.len() / 2]).unwrap();
    let err = BagReader::open(&dir).unwrap_err();
    let text = err.to_string();
    println!("{text}");
    assert!(
        matches!(
            err,
            BagError::Corrupt {
                offset: Some(_),
                ..
            }
        ),
        "{text}"
    );
    assert!(text.contains("forcemap bag recover"));
}

#[test]
fn metadata_problems() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bag");
    small_bag(&dir);
    std::fs::write(
        dir.join("metadata.yaml"),
        "rosbag2_bagfile_information: [1, 2",
    )
    .unwrap();
    let err = BagReader::open(&dir).unwrap_err();
    assert!(matches!(err, BagError::Metadata { .. }), "{err}");
    std::fs::remove_file(dir.join("metadata.yaml")).unwrap();
    let err = BagReader::open(&dir).unwrap_err();
    assert!(matches!(err, BagError::Metadata { .. }), "{err}");
    println!("{err}");
}

#[test]
fn topic_not_found_lists_topics() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bag");
    small_bag(&dir);
    let bag = BagReader::open(&dir).unwrap();
    let err = bag.topic("/c").unwrap_err();
    match &err {
        BagError::TopicNotFound { topic, available } => {
            assert_eq!(topic, "/c");
            assert_eq!(available, &["/a", "/b"]);
        }
        other => panic!("{other}"),
    }
    assert!(err.to_string().contains("/a, /b"));
    assert!(bag.messages_on(&["/a", "/zzz"]).is_err());
}

#[test]
fn schema_encoding_not_ros2msg() {
    let tmp = tempfile::tempdir().unwrap();
    let f = tmp.path().join("idl.mcap");
    {
        let mut w =
            mcap::Writer::new(std::io::BufWriter::new(std::fs::File::create(&f).unwrap())).unwrap();
        let s = w
            .add_schema("pkg/msg/T", "ros2idl", b"module pkg {};")
            .unwrap();
        let c = w.add_channel(s, "/t", "cdr", &BTreeMap::new()).unwrap();
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id: c,
                sequence: 0,
                log_time: 1,
                publish_time: 1,
            },
            &[0, 1, 0, 0],
        )
        .unwrap();
        w.finish().unwrap();
    }
    let err = BagReader::open(&f).unwrap_err();
    assert!(
        matches!(&err, BagError::SchemaEncoding { encoding, .. } if encoding == "ros2idl"),
        "{err}"
    );
}

#[test]
fn invalid_topics_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let mut w = BagWriter::create(tmp.path().join("b")).unwrap();
    assert!(
        w.add_topic(&TopicSpec::new("a", "p/msg/T", "float64 x\n"))
            .is_err()
    );
    assert!(
        w.add_topic(&TopicSpec::new("/a", "T", "float64 x\n"))
            .is_err()
    );
    w.add_topic(&TopicSpec::new("/a", "p/msg/T", "float64 x\n"))
        .unwrap();
    assert!(
        w.add_topic(&TopicSpec::new("/a", "p/msg/U", "float64 x\n"))
            .is_err()
    );
}

/// Random bytes, with and without the magic, and random damage to a real file: errors, no panic.
#[test]
fn random_and_damaged_input_never_panics() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("bag");
    small_bag(&dir);
    let good = std::fs::read(dir.join("bag_0.mcap")).unwrap();
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let f = tmp.path().join("r.mcap");
    for k in 0..300 {
        let mut bytes: Vec<u8> = if k % 3 == 0 {
            (0..(next() % 4000)).map(|_| next() as u8).collect()
        } else {
            good.clone()
        };
        if k % 3 == 1 {
            let mut r: Vec<u8> = (0..(next() % 2000)).map(|_| next() as u8).collect();
            bytes.truncate(8);
            bytes.append(&mut r);
        } else if k % 3 == 2 {
            for _ in 0..(1 + next() % 8) {
                let i = (next() as usize) % bytes.len();
                bytes[i] = next() as u8;
            }
        }
        std::fs::write(&f, &bytes).unwrap();
        if let Ok(bag) = BagReader::open(&f)
            && let Ok(msgs) = bag.messages()
        {
            for m in msgs {
                let _ = m;
            }
        }
        let out = tmp.path().join(format!("out{k}"));
        let _ = recover(&f, &out);
    }
}

/// Found by fuzzing (fuzz/regressions/bag_read): a damaged QoS string with a DEL character made
/// `recover` write a metadata.yaml that no YAML reader accepts. The recovered bag must open.
#[test]
fn recovered_bag_with_control_characters_in_its_strings_opens_again() {
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/regressions/bag_read/recovered-metadata-yaml-unreadable-0x7f.mcap");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("recovered");
    let report = forcemap_io::bag::recover(&input, &out).expect("recovers");
    let reader = forcemap_io::bag::BagReader::open(&out).expect("the recovered bag opens");
    assert_eq!(reader.summary().message_count, report.messages);
    let qos: Vec<String> = reader
        .topics()
        .map(|t| t.offered_qos_profiles.clone())
        .collect();
    assert!(
        qos.iter().any(|q| q.contains('\u{7f}')),
        "the DEL survives the round trip: {qos:?}"
    );
}
