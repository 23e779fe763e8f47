//! What `forcemap identify` gives an element-test user: the dynamic stiffness table in
//! `--json` and the summary, and its plots, checked against the closed forms of a damper
//! (preload + k x + rebound/compression damping + Coulomb friction) on a dyno's CSV export.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::f64::consts::PI;

use forcemap_io::csv_export::write_csv;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::{ElementDrive, RunSpec, StepSpec};

// The dyno damper's truth (`RunSpec::damper_dyno`), for the closed forms.
const PRELOAD_N: f64 = 150.0;
const K_N_PER_M: f64 = 2000.0;
const REBOUND_N_S_PER_M: f64 = 2500.0;
const COMPRESSION_N_S_PER_M: f64 = 1000.0;
const FRICTION_N: f64 = 40.0;

fn dyno_csv(dir: &std::path::Path, snr_db: Option<f64>) -> std::path::PathBuf {
    let element = RunSpec::damper_dyno(None, 0).element;
    let steps = [1.0, 2.0, 4.0]
        .iter()
        .flat_map(|&f| {
            [0.01, 0.02].map(|a| StepSpec::Sine {
                frequency_hz: f,
                amplitude: a,
            })
        })
        .collect();
    let records = RunSpec {
        snr_db,
        seed: 3,
        ..RunSpec::element_test(
            ElementDrive::Displacement,
            0.8,
            element,
            steps,
            1000.0,
            4000,
        )
    }
    .simulate()
    .expect("simulates");
    let path = dir.join("dyno.csv");
    write_csv(&path, &records, SetupKind::Element).expect("writes the export");
    path
}

fn num(v: &serde_json::Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

#[test]
fn the_dynamic_stiffness_table_is_the_dampers_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dyno_csv(dir.path(), None);
    let plots = dir.path().join("plots");
    let o = common::forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "damper",
        "--mass-kg",
        "0.8",
        "--json",
        "--plot",
        plots.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    // The closed forms' constants are the dyno's truth.
    let theta: std::collections::BTreeMap<_, _> = RunSpec::DAMPER_DYNO_THETA.into_iter().collect();
    assert_eq!(
        [
            theta["offset"],
            theta["k"],
            theta["c"] + theta["ca"],
            theta["c"] - theta["ca"],
            theta["fd"]
        ],
        [
            PRELOAD_N,
            K_N_PER_M,
            REBOUND_N_S_PER_M,
            COMPRESSION_N_S_PER_M,
            FRICTION_N
        ]
    );
    let rows = v["dynamic_stiffness"]
        .as_array()
        .expect("a dynamic_stiffness table");
    assert_eq!(rows.len(), 6);
    let c = 0.5 * (REBOUND_N_S_PER_M + COMPRESSION_N_S_PER_M);
    for r in rows {
        let (f, x) = (num(r, "frequency_hz"), num(r, "displacement_amplitude_m"));
        let w = 2.0 * PI * f;
        let vpk = w * x;
        // The fundamental: k in phase; c w and friction's describing function 4 fd / (pi X) in
        // quadrature; the even |x'| part and the preload have none.
        let loss = c * w + 4.0 * FRICTION_N / (PI * x);
        let close = |got: f64, want: f64, tol: f64, what: &str| {
            assert!(
                (got - want).abs() <= tol * want.abs(),
                "{what} at {f} Hz, {x} m: {got} vs {want}"
            );
        };
        close(
            num(r, "storage_stiffness_n_per_m"),
            K_N_PER_M,
            2e-3 * loss / K_N_PER_M,
            "K'",
        );
        close(num(r, "loss_stiffness_n_per_m"), loss, 2e-3, "K''");
        close(
            num(r, "loss_angle_deg"),
            loss.atan2(K_N_PER_M).to_degrees(),
            2e-3,
            "angle",
        );
        // The loop's area: viscous ellipse plus friction rectangle.
        close(
            num(r, "dissipated_energy_j"),
            PI * c * w * x * x + 4.0 * FRICTION_N * x,
            2e-3,
            "W",
        );
        close(num(r, "peak_velocity_mps"), vpk, 1e-3, "v_pk");
        // At mid-stroke: preload, the side's damping and the friction. The friction's square
        // wave, summed to the analysed 100 harmonics, is off there by at most the first term
        // left out of its alternating series, 4 fd / (pi n_max): 0.5 N.
        for (key, want) in [
            (
                "rebound_force_at_peak_velocity_n",
                PRELOAD_N + REBOUND_N_S_PER_M * vpk + FRICTION_N,
            ),
            (
                "compression_force_at_peak_velocity_n",
                PRELOAD_N - COMPRESSION_N_S_PER_M * vpk - FRICTION_N,
            ),
        ] {
            let got = num(r, key);
            assert!(
                (got - want).abs() < 4.0 * FRICTION_N / (PI * 100.0),
                "{key} at {f} Hz, {x} m: {got} vs {want}"
            );
        }
    }
    for file in [
        "force_state.svg",
        "dynamic_stiffness.svg",
        "peak_force_velocity.svg",
    ] {
        let svg = std::fs::read_to_string(plots.join(file)).expect(file);
        assert!(svg.contains("<svg"), "{file}");
    }
    let text = std::fs::read_to_string(plots.join("dynamic_stiffness.svg")).unwrap();
    // One line per amplitude level in each of the three panels' legends.
    assert_eq!(text.matches("amplitude 1.000e-2").count(), 3);
    assert_eq!(text.matches("amplitude 2.000e-2").count(), 3);
    let labels = text
        .match_indices("amplitude ")
        .filter(|(i, m)| text[i + m.len()..].starts_with(|c: char| c.is_ascii_digit()))
        .count();
    assert_eq!(labels, 6);
}

#[test]
fn the_summary_prints_the_table_only_for_an_element_test() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dyno_csv(dir.path(), Some(30.0));
    let o = common::forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "damper",
        "--mass-kg",
        "0.8",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("dynamic stiffness K* = G_1 / X_1"), "{text}");
    // One row per step, its peak velocity the fundamental's w X within the noise.
    let rows: Vec<&str> = text
        .lines()
        .skip_while(|l| !l.starts_with("dynamic stiffness"))
        .skip(2)
        .collect();
    assert_eq!(rows.len(), 6, "{text}");
    for row in rows {
        let cols: Vec<f64> = row.split_whitespace().map(|c| c.parse().unwrap()).collect();
        let want = 2.0 * PI * cols[1] * cols[2];
        assert!((cols[7] / want - 1.0).abs() < 0.01, "{row}");
    }
    // A rig export has no such table.
    let rig = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/rig_40db");
    let o = common::forcemap(&["identify", rig.to_str().unwrap(), "--model", "coulomb"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!String::from_utf8_lossy(&o.stdout).contains("dynamic stiffness"));
}

/// `--method output-error` on element data: a dyno's CSV export (40 dB) and the committed dyno
/// bag are refined against the simulated stroke and force, every parameter within 1 % of the
/// truth, with the drive it found named in the warnings.
#[test]
fn output_error_on_a_dyno_csv_and_the_committed_bag() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dyno_csv(dir.path(), Some(40.0));
    let bag = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/damper_dyno_40db");
    for (data, extra) in [
        (csv.as_path(), vec!["--mass-kg", "0.8"]),
        (bag.as_path(), vec![]),
    ] {
        let mut args = vec![
            "identify",
            data.to_str().unwrap(),
            "--model",
            "damper",
            "--method",
            "output-error",
            "--json",
        ];
        args.extend(extra);
        let o = common::forcemap(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["method"], "output-error");
        let warnings = v["warnings"].to_string();
        assert!(
            warnings.contains("driven by its displacement"),
            "{warnings}"
        );
        let params = v["parameters"].as_array().unwrap();
        assert_eq!(params.len(), RunSpec::DAMPER_DYNO_THETA.len());
        for (p, (name, t)) in params.iter().zip(RunSpec::DAMPER_DYNO_THETA) {
            assert_eq!(p["name"], name);
            let value = num(p, "value");
            assert!(
                (value / t - 1.0).abs() < 0.01,
                "{}: {name} = {value} (truth {t})",
                data.display()
            );
        }
    }
}
