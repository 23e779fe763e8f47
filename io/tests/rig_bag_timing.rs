//! forcemap's own bags timed as recordings go: a sample message lost in the middle of a step
//! (a recorder that dropped one) and steps recorded at different rates.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};

use forcemap_io::bag::{BagWriter, TopicSpec};
use forcemap_io::rig_bag::{DEFAULT_RUN_START, read_rig_bag, write_rig_bag};
use forcemap_io::rig_messages::{RigMessage, rig_messages};
use forcemap_io::topics::{RIG_EXCITATION, RIG_SAMPLES};
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::RunSpec;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::{ExcitationState, RigSample};

/// `records` as a rig bag without the sample messages `skip(step, index in the step)` says.
fn bag_without(dir: &Path, records: &[Record], skip: impl Fn(u32, usize) -> bool) -> PathBuf {
    let path = dir.join("bag");
    let mut w = BagWriter::create(&path).unwrap();
    let samples = w
        .add_topic(&TopicSpec::new(
            RIG_SAMPLES,
            RigSample::TYPE_NAME,
            &RigSample::schema(),
        ))
        .unwrap();
    let excitation = w
        .add_topic(&TopicSpec::new(
            RIG_EXCITATION,
            ExcitationState::TYPE_NAME,
            &ExcitationState::schema(),
        ))
        .unwrap();
    let mut index = (u32::MAX, 0usize);
    for m in rig_messages(
        records,
        Channel::BaseDisplacementM,
        None,
        DEFAULT_RUN_START,
        "rig",
    ) {
        match m {
            RigMessage::Excitation(s) if !s.is_idle() => {
                let t = s.start_time.as_nanos() as u64;
                w.write(excitation, t, t, &s.to_cdr()).unwrap();
            }
            RigMessage::Sample(s) => {
                index = if index.0 == s.step {
                    (s.step, index.1 + 1)
                } else {
                    (s.step, 0)
                };
                if !skip(index.0, index.1) {
                    let t = s.header.stamp.as_nanos() as u64;
                    w.write(samples, t, t, &s.to_cdr()).unwrap();
                }
            }
            _ => {}
        }
    }
    w.finish().unwrap()
}

/// A sample lost in step 3 (its plan counts 1300): a notice and two records, not the step
/// refused as 1299 of its 1300 samples.
#[test]
fn a_lost_sample_message_is_a_notice_and_two_records() {
    let dir = tempfile::tempdir().unwrap();
    let records = RunSpec::paper_rig(Some(40.0), 1).simulate().unwrap();
    let bag = bag_without(dir.path(), &records, |step, i| step == 3 && i == 600);
    let run = read_rig_bag(&bag).unwrap();
    assert_eq!(run.records.len(), records.len() + 1);
    let lens: Vec<usize> = run.records[2..6].iter().map(Record::len).collect();
    assert_eq!(lens, [1300, 600, 699, 1300]);
    assert_eq!(
        run.records[4].channels[0].1[..],
        records[3].channels[0].1[601..]
    );
    assert_eq!(run.records[5].channels, records[4].channels);
    assert_eq!(run.notices.len(), 1, "{:?}", run.notices);
    assert_eq!(
        run.notices[0],
        "step 3, sample 600: 1 sample lost (an interval of 0.020000 s where the samples around are 0.010000 s apart): the step goes on in another record from there"
    );
}

/// Steps recorded at 1 kHz and at 200 Hz (the damper dyno, steps 6-11 at every fifth sample):
/// each record read back at its own rate, with its samples.
#[test]
fn steps_at_two_rates_read_back_at_their_rates() {
    let dir = tempfile::tempdir().unwrap();
    let records: Vec<Record> = RunSpec::damper_dyno(Some(30.0), 1)
        .simulate()
        .unwrap()
        .into_iter()
        .map(|r| match r.step {
            0..6 => r,
            _ => Record {
                sample_rate_hz: 200.0,
                channels: r
                    .channels
                    .iter()
                    .map(|(c, x)| (*c, x.iter().step_by(5).copied().collect()))
                    .collect(),
                ..r
            },
        })
        .collect();
    let bag = write_rig_bag(
        &dir.path().join("two_rates"),
        &records,
        Channel::RelativeDisplacementM,
        &[],
        DEFAULT_RUN_START,
    )
    .unwrap();
    let run = read_rig_bag(&bag).unwrap();
    assert!(run.notices.is_empty(), "{:?}", run.notices);
    assert_eq!(run.records.len(), records.len());
    for (a, b) in records.iter().zip(&run.records) {
        assert_eq!(
            (a.step, a.sample_rate_hz, a.len()),
            (b.step, b.sample_rate_hz, b.len())
        );
        for (c, x) in &a.channels {
            assert!(b.channel(*c) == Some(&x[..]), "step {}: {c:?}", a.step);
        }
    }
}
