//! `forcemap diagnose` on a base-excited rig's records with no sine steps (band-random
//! drives): each record is fitted on its samples as the element between base and mass, its
//! force the one that holds the mass (-m a_o), and a held-out record is predicted the same way.
//! The paper's Coulomb rig (k 6380 N/m, c 184 N s/m, F_d 12.3 N) at 40 dB, three 130 s records
//! of 1.6-3.4 Hz fitted and a fourth held out, against `linear`: Coulomb friction is named
//! and explains the gap, and the held-out force NMSE falls to under half. The baseline and the
//! named model are then refitted by output error on the rig's records: F_d within 1 % of the
//! truth (the fit along the measured motion is biased low by the noisy velocity), and the
//! held-out record simulated with it leaves under a tenth of the baseline's acceleration NMSE,
//! and the verdict from the simulations agrees. A channel effect, which has no candidate along
//! the measured motion (a 4 Hz sensor low-pass on every channel of the Coulomb rig, against
//! `coulomb`), is named by simulation; so is a 10 ms exciter delay; and, against `linear`, the
//! friction and the low-pass together.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use forcemap_io::csv_export::write_csv;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::{RigEffects, RunSpec, RunSystem};

/// `forcemap diagnose` of the rig's band-random records of seeds 1 to `records` (40 dB), the
/// last held out, against `model`, each run changed by `change`. Its output, its JSON and its
/// HTML report.
fn diagnose_random_records(
    model: &str,
    records: u64,
    change: impl Fn(&mut RunSpec),
) -> (std::process::Output, serde_json::Value, String) {
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<String> = (1..=records)
        .map(|seed| {
            let path = dir.path().join(format!("random{seed}.csv"));
            let mut spec = RunSpec::rig_random(Some(40.0), seed);
            change(&mut spec);
            write_csv(&path, &spec.simulate().unwrap(), SetupKind::BaseExcited).unwrap();
            path.display().to_string()
        })
        .collect();
    let (validation, fitted) = files.split_last().unwrap();
    let mut args: Vec<&str> = vec!["diagnose"];
    args.extend(fitted.iter().map(String::as_str));
    args.extend([
        "--model",
        model,
        "--mass-kg",
        "36",
        "--validate",
        validation,
        "--json",
    ]);
    let report = dir.path().join("report");
    let report_arg = report.display().to_string();
    args.extend(["--report", &report_arg]);
    let o = common::forcemap(&args);
    assert!(o.status.success(), "{}", common::stderr(&o));
    let v = serde_json::from_slice(&o.stdout).unwrap();
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    (o, v, html)
}

/// The value of parameter `name` of the output-error refit of `model` in `refits` (the JSON's
/// `output_error_refits`).
fn refit_parameter(refits: &[serde_json::Value], model: &str, name: &str) -> f64 {
    let refit = refits.iter().find(|r| r["model"] == model).unwrap();
    let parameters = refit["parameters"].as_array().unwrap();
    parameters.iter().find(|p| p[0] == name).unwrap()[1]
        .as_f64()
        .unwrap()
}

/// `diagnose_random_records` of three records of 65 s (two fitted, one held out) with the
/// rig's channel `effects` planted: the JSON.
fn diagnose_half_records_with(model: &str, effects: RigEffects) -> serde_json::Value {
    let (_, v, _) = diagnose_random_records(model, 3, |spec| {
        spec.samples_per_record /= 2;
        if let RunSystem::Rig { effects: e, .. } = &mut spec.system {
            *e = effects;
        }
    });
    v
}

#[test]
fn a_rigs_random_records_are_diagnosed_on_their_samples() {
    let (o, v, html) = diagnose_random_records("linear", 4, |_| ());
    assert!(
        common::stderr(&o).contains("the rig's records have no sine steps"),
        "{}",
        common::stderr(&o)
    );
    println!("{} by {}; {}", v["verdict"], v["top_effect"], v["heldout"]);
    assert_eq!(v["sampled_records"], 3, "{v}");
    assert_eq!(v["verdict"], "explained", "{v}");
    assert_eq!(v["top_effect"], "coulomb_friction", "{v}");
    let held = &v["heldout"][0];
    let before = held["baseline_nmse_percent"].as_f64().unwrap();
    let after = held["effect_nmse_percent"].as_f64().unwrap();
    assert!(after < 0.5 * before, "{held}");
    let refits = v["output_error_refits"].as_array().unwrap();
    println!("output-error refits: {}", v["output_error_refits"]);
    // The named effect fits the records within their noise: no channel effect is refitted.
    let models: Vec<&str> = refits
        .iter()
        .map(|r| r["model"].as_str().unwrap())
        .collect();
    assert_eq!(models, ["linear", "linear + coulomb_friction"], "{v}");
    assert!(refits[1]["misfit_noise_std"].as_f64().unwrap() < 2f64.sqrt());
    let fd = refit_parameter(refits, "linear + coulomb_friction", "fd");
    assert!((fd / 12.3 - 1.0).abs() < 0.01, "fd {fd}");
    let nmse = |r: &serde_json::Value| r["heldout_nmse_percent"][0].as_f64().unwrap();
    assert!(nmse(&refits[1]) < 0.1 * nmse(&refits[0]), "{refits:?}");
    // The verdict from the simulations agrees with the one along the measured motion.
    let by_sim = &v["simulation_verdict"];
    println!("verdict by simulation: {by_sim}");
    assert_eq!(by_sim["verdict"], "explained", "{by_sim}");
    assert_eq!(by_sim["effect"], "coulomb_friction", "{by_sim}");
    // The report shows the refits and the verdict by simulation too.
    assert!(
        html.contains("verdict by simulation: explained by coulomb_friction: 4.23 %"),
        "{html}"
    );
    assert!(html.contains("linear + coulomb_friction: k "), "{html}");
}

/// A 4 Hz first-order low-pass on every measured channel of the Coulomb rig (records of
/// 1.6-3.4 Hz, 65 s each), diagnosed against `coulomb`: the baseline's simulation misses the
/// records beyond their noise, the channel effects are refitted by simulation beside the
/// best-ranked element candidate, and the low-pass is named with its cutoff.
#[test]
fn a_channel_filter_is_named_by_simulation() {
    let v = diagnose_half_records_with(
        "coulomb",
        RigEffects {
            sensor_lowpass_hz: Some(4.0),
            ..RigEffects::default()
        },
    );
    let by_sim = &v["simulation_verdict"];
    let refits = v["output_error_refits"].as_array().unwrap();
    println!("along the motion {}; by simulation {by_sim}", v["verdict"]);
    println!("output-error refits: {}", v["output_error_refits"]);
    let misfit = refits[0]["misfit_noise_std"].as_f64().unwrap();
    assert!(misfit > 2f64.sqrt(), "{refits:?}");
    assert_eq!(by_sim["verdict"], "explained", "{by_sim}");
    assert_eq!(by_sim["effect"], "sensor_lowpass", "{by_sim}");
    let tau = refit_parameter(refits, "coulomb + sensor_lowpass", "sensor_time_constant_s");
    // 4.13 Hz at 40 dB (3.999 Hz at 70 dB): the noisy measured base is the input, its noise
    // amplified by the undo (x + tau x') before the friction's stick-slip sees it, so the
    // cutoff is a few percent off, several of its standard deviations.
    let cutoff_hz = 1.0 / (std::f64::consts::TAU * tau);
    assert!(
        (cutoff_hz / 4.0 - 1.0).abs() < 0.06,
        "cutoff {cutoff_hz} Hz"
    );
}

/// An exciter delay of 10 ms (the element sees the measured base motion a sample later) on the
/// Coulomb rig, records as above, diagnosed against `coulomb`: named by simulation, its delay
/// refitted.
#[test]
fn an_exciter_delay_is_named_by_simulation() {
    let v = diagnose_half_records_with(
        "coulomb",
        RigEffects {
            exciter_delay_s: 0.010,
            ..RigEffects::default()
        },
    );
    let by_sim = &v["simulation_verdict"];
    let refits = v["output_error_refits"].as_array().unwrap();
    println!("along the motion {}; by simulation {by_sim}", v["verdict"]);
    println!("output-error refits: {}", v["output_error_refits"]);
    assert_eq!(by_sim["verdict"], "explained", "{by_sim}");
    assert_eq!(by_sim["effect"], "exciter_delay", "{by_sim}");
    let delay_s = refit_parameter(refits, "coulomb + exciter_delay", "exciter_delay_s");
    assert!((delay_s / 0.010 - 1.0).abs() < 0.05, "delay {delay_s} s");
}

/// The Coulomb rig through the 4 Hz sensor low-pass, as above, diagnosed against `linear`: two
/// effects share the gap. Each alone, refitted by simulation, still misses the records beyond
/// their noise; refitted together they are named together.
#[test]
fn a_friction_seen_through_a_channel_filter_is_named_as_a_pair() {
    let v = diagnose_half_records_with(
        "linear",
        RigEffects {
            sensor_lowpass_hz: Some(4.0),
            ..RigEffects::default()
        },
    );
    let by_sim = &v["simulation_verdict"];
    println!(
        "along the motion {} {}; by simulation {by_sim}",
        v["verdict"], v["top_effect"]
    );
    println!("output-error refits: {}", v["output_error_refits"]);
    assert_eq!(by_sim["verdict"], "explained", "{by_sim}");
    let mut named = [
        by_sim["effect"].as_str().unwrap_or_default(),
        by_sim["second_effect"].as_str().unwrap_or_default(),
    ];
    named.sort_unstable();
    assert_eq!(named, ["coulomb_friction", "sensor_lowpass"], "{by_sim}");
}
