//! Bag playback through the real node graph (separate processes, DDS over loopback): the theta
//! the identifier publishes live equals `forcemap identify` on the same bag, and is close to the
//! truth the bag was simulated from.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::time::Duration;

use common::*;

/// Plays `bag` through harmonic + identifier + monitor, returns (live, offline) theta.
fn replay(
    bag: &str,
    domain_id: u16,
    identifier_params: &[String],
    offline_args: &[&str],
) -> (Theta, Theta) {
    replay_with(bag, domain_id, &[], identifier_params, offline_args).0
}

/// [`replay`] with parameters for the harmonic node too; also returns the identifier's log.
fn replay_with(
    bag: &str,
    domain_id: u16,
    harmonic_params: &[String],
    identifier_params: &[String],
    offline_args: &[&str],
) -> ((Theta, Theta), Vec<String>) {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let bag = repo().join(bag);
    let mut monitor = NodeProcess::start(
        "monitor",
        domain_id,
        &[
            format!("summary_json:={}", summary.display()),
            "quiet_s:=2.0".into(),
            "timeout_s:=120.0".into(),
        ],
    );
    let _harmonic = NodeProcess::start("harmonic", domain_id, harmonic_params);
    let identifier = NodeProcess::start("identifier", domain_id, identifier_params);
    let mut sensor = play_bag(domain_id, &bag, 0.0);
    assert!(sensor.wait_exit(Duration::from_secs(120)).success());
    assert!(monitor.wait_exit(Duration::from_secs(60)).success());
    (
        (summary_theta(&summary), offline_theta(&bag, offline_args)),
        identifier.lines(),
    )
}

#[test]
fn rig_bag_replayed_live_gives_the_offline_theta_and_the_truth() {
    let (live, offline) = replay(
        "bags/rig_40db",
        domain(0),
        &["model:=coulomb".into(), "method:=fd-multi".into()],
        &["--model", "coulomb", "--method", "fd-multi"],
    );
    assert_same_theta(&live, &offline, 1e-9);
    // The stand-in rig's truth (k 6380 N/m, c 184 N s/m, F_d 12.3 N) at 40 dB SNR.
    for ((n, v), truth) in live.iter().zip([6380.0, 184.0, 12.3]) {
        let err = (v - truth).abs() / truth;
        assert!(err < 0.01, "{n} = {v}, truth {truth}: {:.2} %", 100.0 * err);
    }
}

#[test]
fn three_dof_case_i_replayed_live_gives_the_offline_theta_and_the_truth() {
    let params = repo().join("launch_configs/three_dof.params.yaml");
    let (live, offline) = replay(
        "bags/three_dof_case_i",
        domain(1),
        &[
            format!("--params-file={}", params.display()),
            "model:=coulomb-cubic".into(),
        ],
        &[
            "--model",
            "coulomb-cubic",
            "--params",
            params.to_str().unwrap(),
        ],
    );
    assert_same_theta(&live, &offline, 1e-9);
    // Table 1 truth (k, c, F_d, S); noise-free CASE I.
    let (k, c, fd, s) = forcemap_eval::paper::TABLE1_TRUTH;
    for (n, v) in &live {
        let t = match n.as_str() {
            "k" => k,
            "c" => c,
            "fd" => fd,
            "s" => s,
            other => panic!("unexpected parameter {other}"),
        };
        let err = (v - t).abs() / t;
        assert!(err < 0.01, "{n} = {v}, truth {t}: {:.2} %", 100.0 * err);
    }
}

#[test]
fn damper_dyno_bag_replayed_live_gives_the_offline_theta_and_the_truth() {
    // An element test: the bag carries the 0.8 kg fixture mass; the identifier takes the
    // element setup from the channels the phasors hold.
    let (live, offline) = replay(
        "bags/damper_dyno_40db",
        domain(10),
        &["model:=damper".into()],
        &["--model", "damper"],
    );
    assert_same_theta(&live, &offline, 1e-9);
    for ((n, v), (name, truth)) in live
        .iter()
        .zip(forcemap_math::sim::RunSpec::DAMPER_DYNO_THETA)
    {
        assert_eq!(n, name);
        let err = (v - truth).abs() / truth;
        assert!(err < 0.01, "{n} = {v}, truth {truth}: {:.2} %", 100.0 * err);
    }
}

/// Tracking within the steps live: the harmonic node publishes provisional phasors every
/// second, the identifier solves with them in place and ends on the theta `forcemap identify
/// --forgetting-per-step 0.8 --update-period-s 1` ends on.
#[test]
fn damper_dyno_bag_tracked_within_steps_live_gives_the_offline_track_end() {
    let ((live, offline), log) = replay_with(
        "bags/damper_dyno_40db",
        domain(57),
        &["update_period_s:=1.0".into()],
        &["model:=damper".into(), "forgetting_per_step:=0.8".into()],
        &[
            "--model",
            "damper",
            "--forgetting-per-step",
            "0.8",
            "--update-period-s",
            "1",
        ],
    );
    assert_same_theta(&live, &offline, 1e-9);
    let provisional = log.iter().filter(|l| l.contains("(provisional,")).count();
    assert!(
        provisional > 0,
        "no provisional theta in the log:\n{}",
        log.join("\n")
    );
    println!("{provisional} provisional thetas live");
}

/// Tracking within the steps live without excitation states: the harmonic node
/// ignores the bag's states and finds the steps in the samples (`find_steps:=true`), with
/// provisional phasors every 2 s of a step's samples; the identifier (forgetting 0.7) ends on
/// the theta `forcemap identify --forgetting-per-step 0.7 --update-period-s 2` ends on with
/// the bag's labels (the finder cuts the rig bag's sine steps where its states do), and
/// publishes provisional thetas, each before its step's final theta.
#[test]
fn rig_bag_without_states_tracked_within_steps_live_gives_the_labelled_track_end() {
    let ((live, offline), log) = replay_with(
        "bags/rig_40db",
        domain(59),
        &["find_steps:=true".into(), "update_period_s:=2.0".into()],
        &[
            "model:=coulomb".into(),
            "method:=fd-multi".into(),
            "forgetting_per_step:=0.7".into(),
        ],
        &[
            "--model",
            "coulomb",
            "--method",
            "fd-multi",
            "--forgetting-per-step",
            "0.7",
            "--update-period-s",
            "2",
        ],
    );
    assert_same_theta(&live, &offline, 1e-9);
    let position = |needle: &str| log.iter().position(|l| l.contains(needle));
    let mut provisional = 0;
    for step in 0..10 {
        let last_final = position(&format!("step {step}: "))
            .unwrap_or_else(|| panic!("no final theta of step {step}:\n{}", log.join("\n")));
        for (i, l) in log.iter().enumerate() {
            if l.contains(&format!("step {step} (provisional,")) {
                assert!(i < last_final, "step {step}:\n{}", log.join("\n"));
                provisional += usize::from(!l.contains("no theta"));
            }
        }
    }
    assert!(provisional > 0, "no provisional theta:\n{}", log.join("\n"));
    println!("{provisional} provisional thetas live, the final theta {live:?}");
}

/// A periodic multisine run live: the committed bag of the force-driven cubic single DOF (two
/// multisine realisations, then a band-random record) through harmonic node, identifier and
/// monitor. The identifier finds each step's lines on the driven channel its ExcitationState
/// names and solves them with the two passes of `forcemap identify`: theta and its standard
/// deviations equal the offline ones, and theta is within 1 % of the simulation's truth.
#[test]
fn shaker_multisine_bag_replayed_live_gives_the_offline_theta_and_its_std() {
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let bag = repo().join("bags/shaker_multisine_30db");
    let params = repo().join("launch_configs/shaker.params.yaml");
    let mut monitor = NodeProcess::start(
        "monitor",
        domain(58),
        &[
            format!("summary_json:={}", summary.display()),
            "quiet_s:=2.0".into(),
            "timeout_s:=120.0".into(),
        ],
    );
    let _harmonic = NodeProcess::start("harmonic", domain(58), &[]);
    let identifier = NodeProcess::start(
        "identifier",
        domain(58),
        &[
            format!("--params-file={}", params.display()),
            "model:=cubic".into(),
        ],
    );
    let mut sensor = play_bag(domain(58), &bag, 0.0);
    assert!(sensor.wait_exit(Duration::from_secs(120)).success());
    assert!(monitor.wait_exit(Duration::from_secs(60)).success());
    let live = summary_json(&summary);
    let offline = offline_json(&bag, &["--model", "cubic"]);
    let log = identifier.lines().join("\n");
    assert_same_theta(&theta_of_json(&live), &theta_of_json(&offline), 1e-9);
    assert_same_theta(&stds_of_json(&live), &stds_of_json(&offline), 1e-9);
    assert_eq!(live["steps_used"], serde_json::json!([0, 1]), "{log}");
    assert_eq!(live["equations"], offline["equations"]);
    assert_eq!(live["multisine_steps"], 2);
    // The truth of RunSpec::shaker_sdof (k, c, s; the moving mass m last).
    let truth = [("k", 2.0e4), ("c", 60.0), ("s", 5.0e7), ("m", 2.0)];
    let theta = theta_of_json(&live);
    assert_eq!(theta.len(), truth.len(), "{theta:?}");
    for ((n, v), (name, t)) in theta.iter().zip(truth) {
        assert_eq!(n, name);
        let err = (v - t).abs() / t;
        assert!(err < 0.01, "{n} = {v}, truth {t}: {:.2} %", 100.0 * err);
    }
}
