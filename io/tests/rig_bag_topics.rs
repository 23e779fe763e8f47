//! The rule that finds a bag's rig topics (`rig_bag::RigBagReader`), shared by the analysis
//! and the sensor's playback: forcemap's type under forcemap's last name component, in any
//! namespace; two rigs in one bag are ambiguous.

use std::path::{Path, PathBuf};

use forcemap_io::bag::{BagReader, BagWriter, TopicSpec};
use forcemap_io::rig_bag::{RigBagError, read_rig_bag, read_rig_messages};

fn committed_bag() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db")
}

/// The committed rig bag copied with its topics renamed by `rename` (several names: one copy
/// of each topic per name).
fn copy_renamed(out: &Path, rename: &dyn Fn(&str) -> Vec<String>) {
    let reader = BagReader::open(committed_bag()).expect("copying the committed bag");
    let mut w = BagWriter::create(out).expect("copying the committed bag");
    let mut ids = std::collections::BTreeMap::new();
    for t in reader.topics() {
        let mut list = Vec::new();
        for name in rename(&t.name) {
            let mut spec = TopicSpec::new(&name, &t.type_name, &t.schema_text);
            spec.offered_qos_profiles = t.offered_qos_profiles.clone();
            list.push(w.add_topic(&spec).expect("copying the committed bag"));
        }
        ids.insert(t.name.clone(), list);
    }
    for m in reader.messages().expect("copying the committed bag") {
        let m = m.expect("copying the committed bag");
        for id in &ids[&m.topic.name] {
            w.write(*id, m.log_time, m.publish_time, &m.data)
                .expect("copying the committed bag");
        }
    }
    w.finish().expect("copying the committed bag");
}

#[test]
fn a_rig_under_another_namespace_reads_as_under_rig() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bench2");
    copy_renamed(&out, &|name| {
        vec![name.replacen("/rig/", "/bench2/rig/", 1)]
    });
    let ours = read_rig_bag(&committed_bag()).unwrap();
    let theirs = read_rig_bag(&out).unwrap();
    assert_eq!(theirs.records.len(), ours.records.len());
    for (a, b) in theirs.records.iter().zip(&ours.records) {
        assert_eq!(a.step, b.step);
        assert_eq!(a.channels, b.channels);
    }
    assert_eq!(theirs.parameters, ours.parameters);
    let (a, b) = (
        read_rig_messages(&out).unwrap(),
        read_rig_messages(&committed_bag()).unwrap(),
    );
    // Compared as text: the states' unused band fields are NaN, never equal to themselves.
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(format!("{x:?}"), format!("{y:?}"));
    }
}

#[test]
fn two_rigs_in_one_bag_are_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("two");
    copy_renamed(&out, &|name| {
        vec![name.to_string(), name.replacen("/rig/", "/rig2/rig/", 1)]
    });
    for err in [
        read_rig_bag(&out).unwrap_err(),
        read_rig_messages(&out).unwrap_err(),
    ] {
        assert!(matches!(err, RigBagError::Ambiguous { .. }), "{err}");
        let text = err.to_string();
        assert!(
            text.contains("/rig/samples") && text.contains("/rig2/rig/samples"),
            "{text}"
        );
    }
}

#[test]
fn asking_for_no_topics_gives_no_messages() {
    let reader = BagReader::open(committed_bag()).unwrap();
    assert_eq!(reader.messages_on(&[]).unwrap().count(), 0);
    assert!(reader.messages().unwrap().count() > 0);
}

#[test]
fn streamed_playback_is_the_playback_and_stops_when_asked() {
    use forcemap_io::rig_bag::RigBagReader;
    let reader = RigBagReader::open(&committed_bag()).unwrap();
    let whole = reader.playback().unwrap();
    let mut streamed = Vec::new();
    reader
        .stream_playback(|m| {
            streamed.push(m);
            true
        })
        .unwrap();
    assert_eq!(streamed.len(), whole.len());
    for (a, b) in streamed.iter().zip(&whole) {
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
    }
    let mut first = 0;
    reader
        .stream_playback(|_| {
            first += 1;
            first < 5
        })
        .unwrap();
    assert_eq!(first, 5);
    // The summary's count of samples, which the sensor reports progress against.
    let samples = whole
        .iter()
        .filter(|m| matches!(m, forcemap_io::rig_messages::RigMessage::Sample(_)))
        .count();
    assert_eq!(
        reader.message_count(forcemap_io::rig_bag::RigTopic::Samples),
        samples as u64
    );
}
