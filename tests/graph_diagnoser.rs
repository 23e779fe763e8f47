//! The diagnoser node live in the graph: the rig bag (a Coulomb damper) replayed against the
//! linear "sim" names coulomb_friction, on /diagnostics and in its GapDiagnosis message (read
//! back from a bag the recorder wrote).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::time::Duration;

use common::*;
use forcemap_msgs::RosMessage;
use forcemap_msgs::msg::GapDiagnosis;

#[test]
fn linear_sim_against_the_coulomb_rig_is_diagnosed_live_as_coulomb_friction() {
    let d = domain(8);
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("diagnosis");
    let mut recorder = NodeProcess::start(
        "recorder",
        d,
        &[
            format!("bag:={}", bag.display()),
            "topics:=[diagnosis, /diagnostics]".into(),
        ],
    );
    recorder.wait_for("recording 2 topics", Duration::from_secs(30));
    let _harmonic = NodeProcess::start("harmonic", d, &[]);
    let diagnoser = NodeProcess::start("diagnoser", d, &["baseline:=linear".into()]);
    let mut sensor = play_bag(d, &repo().join("bags/rig_40db"), 0.0);
    let line = diagnoser.wait_for("after 10 steps:", Duration::from_secs(120));
    assert!(line.contains("explained by coulomb_friction"), "{line}");
    assert!(sensor.wait_exit(Duration::from_secs(60)).success());
    std::thread::sleep(Duration::from_millis(500));
    assert!(recorder.stop().success());

    let reader = forcemap_io::bag::BagReader::open(&bag).unwrap();
    let last: GapDiagnosis = reader
        .messages_on(&["/rig/diagnosis"])
        .unwrap()
        .map(|m| GapDiagnosis::from_cdr(&m.unwrap().data).unwrap())
        .last()
        .expect("a GapDiagnosis message");
    assert_eq!(last.steps, 10);
    assert_eq!(last.baseline_model, "linear");
    assert_eq!(last.verdict, "explained");
    assert_eq!(last.top_effect, "coulomb_friction");
    assert_eq!(last.ranked_effects[0], "coulomb_friction");
    // The friction term removes most of the gap (the paper: 11 -> 4 % on its rig).
    assert!(
        last.gap_after_percent < 0.25 * last.gap_before_percent,
        "{} -> {}",
        last.gap_before_percent,
        last.gap_after_percent
    );
    // The same finding on /diagnostics, as a WARN naming the effect.
    let warned = reader
        .messages_on(&["/diagnostics"])
        .unwrap()
        .map(|m| {
            forcemap_msgs::diagnostic_msgs::DiagnosticArray::from_cdr(&m.unwrap().data).unwrap()
        })
        .flat_map(|a| a.status)
        .any(|s| {
            s.name.ends_with("gap diagnosis")
                && s.level == 1
                && s.message.contains("coulomb_friction")
        });
    assert!(warned, "no WARN naming coulomb_friction on /diagnostics");
}

/// The true model (the rig bag is a Coulomb damper) is not flagged: the live verdict is
/// "adequate" and /diagnostics says OK.
#[test]
fn the_true_model_is_adequate_live() {
    let d = domain(9);
    let _harmonic = NodeProcess::start("harmonic", d, &[]);
    let diagnoser = NodeProcess::start("diagnoser", d, &["baseline:=coulomb".into()]);
    let mut sensor = play_bag(d, &repo().join("bags/rig_40db"), 0.0);
    let line = diagnoser.wait_for("after 10 steps:", Duration::from_secs(120));
    assert!(line.contains("after 10 steps: adequate"), "{line}");
    assert!(sensor.wait_exit(Duration::from_secs(60)).success());
}
