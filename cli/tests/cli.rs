//! The `forcemap` command at the process boundary: the outputs a user or a script relies on.
//! (Bad input is tested in `bad_input_cli.rs`.)
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use common::{forcemap, stderr};

use std::path::{Path, PathBuf};
use std::process::Output;

fn params(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../launch_configs")
        .join(name)
        .display()
        .to_string()
}

/// A simulated rig export at 40 dB SNR (written once per test that needs it).
fn rig_csv(dir: &Path) -> PathBuf {
    let p = dir.join("rig.csv");
    let o = forcemap(&[
        "simulate",
        "--system",
        "rig",
        "--snr-db",
        "40",
        "--seed",
        "3",
        "--csv",
        p.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    p
}

#[test]
fn identify_json_has_the_documented_shape_and_values_near_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path());
    let o = forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "coulomb",
        "--params",
        &params("rig.params.yaml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(v["model"], "coulomb");
    assert_eq!(v["method"], "fd-multi");
    let p = v["parameters"].as_array().unwrap();
    let names: Vec<&str> = p.iter().map(|x| x["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["k", "c", "fd"]);
    for (x, truth) in p.iter().zip([6380.0, 184.0, 12.3]) {
        let value = x["value"].as_f64().unwrap();
        let std = x["std"].as_f64().unwrap();
        assert!((value / truth - 1.0).abs() < 0.02, "{x}");
        assert!(std > 0.0 && std < 0.05 * truth, "{x}");
    }
    assert!(v["condition_number"].as_f64().unwrap() >= 1.0);
    assert!(v["equations"].as_u64().unwrap() > 20);
    let r_sum: f64 = v["r"]
        .as_object()
        .unwrap()
        .values()
        .map(|x| x.as_f64().unwrap())
        .sum();
    assert!((r_sum - 100.0).abs() < 1e-9);
    // the two band-random records validate the model
    assert_eq!(v["validation"].as_array().unwrap().len(), 2);
}

#[test]
fn identify_by_each_method_and_flag_overrides_params() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path());
    for method in ["fd", "fd-multi", "td"] {
        let o = forcemap(&[
            "identify",
            csv.to_str().unwrap(),
            "--model",
            "linear",
            "--mass-kg",
            "36",
            "--method",
            method,
            "--json",
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(
            v["method"].as_str().unwrap().split('-').next().unwrap(),
            method.split('-').next().unwrap()
        );
        // the linear model absorbs the friction into c
        assert!(
            v["parameters"][1]["value"].as_f64().unwrap() > 250.0,
            "{method}: {v}"
        );
    }
    // --mass-kg beats the params file: a wrong mass scales the force, hence k
    let o = forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "coulomb",
        "--params",
        &params("rig.params.yaml"),
        "--mass-kg",
        "72",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        (v["parameters"][0]["value"].as_f64().unwrap() / (2.0 * 6380.0) - 1.0).abs() < 0.03,
        "{v}"
    );
}

/// Output error on a rig export: the exact stick-slip simulation fitted to the samples moves
/// fd-multi's estimate to within 1 % of the truth with a smaller reported std.
#[test]
fn identify_output_error_on_a_rig_export() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path());
    let run = |method: &str| {
        let o = forcemap(&[
            "identify",
            csv.to_str().unwrap(),
            "--model",
            "coulomb",
            "--mass-kg",
            "36",
            "--method",
            method,
            "--json",
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    let oe = run("output-error");
    let fdm = run("fd-multi");
    assert_eq!(oe["method"], "output-error");
    for (j, truth) in [6380.0, 184.0, 12.3].into_iter().enumerate() {
        let (p, q) = (&oe["parameters"][j], &fdm["parameters"][j]);
        let value = p["value"].as_f64().unwrap();
        assert!((value / truth - 1.0).abs() < 0.01, "{p}");
        assert!(
            p["std"].as_f64().unwrap() < q["std"].as_f64().unwrap(),
            "{p} against fd-multi {q}"
        );
    }
}

/// Tracking offline: theta after every sine step. Without forgetting (factor 1) the last theta
/// is the converged one (the same equations, the same solve); with forgetting the track has
/// one theta per step and its last is the reported one.
#[test]
fn identify_tracking_reports_theta_after_every_step() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path());
    let run = |extra: &[&str]| {
        let mut args = vec![
            "identify",
            csv.to_str().unwrap(),
            "--model",
            "coulomb",
            "--mass-kg",
            "36",
            "--json",
        ];
        args.extend_from_slice(extra);
        let o = forcemap(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    let converged = run(&[]);
    let unforgetting = run(&["--forgetting-per-step", "1"]);
    let forgetting = run(&["--forgetting-per-step", "0.8"]);
    let values = |j: &serde_json::Value| -> Vec<f64> {
        j["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["value"].as_f64().unwrap())
            .collect()
    };
    for (a, b) in values(&converged).iter().zip(values(&unforgetting)) {
        assert!((a / b - 1.0).abs() < 1e-12, "{a} against {b}");
    }
    let steps = converged["steps_used"].as_array().unwrap().len();
    let track = forgetting["track"].as_array().unwrap();
    assert!(
        track.len() >= steps - 2 && track.len() <= steps,
        "{} of {steps}",
        track.len()
    );
    let last: Vec<f64> = track.last().unwrap()["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["value"].as_f64().unwrap())
        .collect();
    assert_eq!(last, values(&forgetting));
    // Forgetting weighs the steps unequally: not the converged theta.
    assert_ne!(values(&forgetting), values(&converged));
}

/// Tracking within each step (`--update-period-s`): provisional rows between the steps' rows,
/// which are the per-step track's exactly (provisional phasors never enter the equations);
/// every row says when its data end. A period that is not positive is refused by name.
#[test]
fn identify_tracking_within_steps_adds_provisional_rows() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path());
    let run = |extra: &[&str]| {
        let mut args = vec![
            "identify",
            csv.to_str().unwrap(),
            "--model",
            "coulomb",
            "--mass-kg",
            "36",
            "--forgetting-per-step",
            "0.8",
            "--json",
        ];
        args.extend_from_slice(extra);
        forcemap(&args)
    };
    let track = |o: &Output| {
        assert!(o.status.success(), "{}", stderr(o));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        j["track"].as_array().unwrap().clone()
    };
    let per_step = track(&run(&[]));
    let within = track(&run(&["--update-period-s", "1"]));
    let finals: Vec<_> = within
        .iter()
        .filter(|r| !r["provisional"].as_bool().unwrap())
        .collect();
    assert!(within.len() > per_step.len(), "{} rows", within.len());
    assert_eq!(finals.len(), per_step.len());
    for (a, b) in finals.iter().zip(&per_step) {
        assert_eq!(a["parameters"], b["parameters"]);
        assert_eq!(a["data_end_s"], b["data_end_s"]);
    }
    let ends: Vec<f64> = within
        .iter()
        .map(|r| r["data_end_s"].as_f64().unwrap())
        .collect();
    assert!(ends.windows(2).all(|w| w[0] < w[1]), "{ends:?}");
    let o = run(&["--update-period-s", "0"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("update_period_s = 0"), "{}", stderr(&o));
}

#[test]
fn three_dof_export_needs_its_substructure_and_is_identified_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("case2.csv");
    let o = forcemap(&[
        "simulate",
        "--system",
        "three-dof",
        "--case",
        "ii",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "coulomb-cubic",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("substructure"), "{}", stderr(&o));
    let o = forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "coulomb-cubic",
        "--params",
        &params("three_dof.params.yaml"),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for (x, truth) in v["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .zip([8000.0, 20.0, 5.0, 3e8])
    {
        assert!(
            (x["value"].as_f64().unwrap() / truth - 1.0).abs() < 0.02,
            "{x}"
        );
    }
}

#[test]
fn reproduce_json_rows_have_the_documented_keys() {
    let o = forcemap(&["reproduce", "--json", "--tables", "4"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rows: Vec<serde_json::Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    assert!(rows.len() >= 4);
    for r in &rows {
        for key in [
            "table", "case", "model", "method", "k", "c", "fd", "s", "nmse1", "nmse2",
        ] {
            assert!(r.get(key).is_some(), "row lacks {key}: {r}");
        }
        assert_eq!(r["table"], 4);
        assert!(r["s"].is_null() && r["case"].is_null());
    }
    let paper = rows.iter().find(|r| r["source"] == "paper").unwrap();
    assert_eq!(paper["fd"], 4.1);
    assert!(
        rows.iter()
            .any(|r| r["source"] == "forcemap" && r["method"] == "td-20")
    );
    let o = forcemap(&["reproduce", "--tables", "7"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("Table 7"));
}

#[test]
fn plots_are_written_as_svg_with_one_series_per_step() {
    let dir = tempfile::tempdir().unwrap();
    let csv = rig_csv(dir.path());
    let plots = dir.path().join("plots");
    let o = forcemap(&[
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "coulomb",
        "--mass-kg",
        "36",
        "--plot",
        plots.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fs = std::fs::read_to_string(plots.join("force_state.svg")).unwrap();
    assert!(
        fs.starts_with("<svg") && fs.contains("step 9 (3.40 Hz) measured"),
        "force-state map lacks the steps"
    );
    for step in [10, 11] {
        let v = std::fs::read_to_string(plots.join(format!("validation_step{step}.svg"))).unwrap();
        assert!(v.contains("NMSE") && v.contains("predicted"));
    }
    // nothing temporary left behind
    assert!(
        std::fs::read_dir(&plots).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .ends_with(".tmp"))
    );
}

#[test]
fn planted_mass_error_scales_every_parameter_by_the_nominal_over_the_true_mass() {
    // m_true x_o'' = -g, analysed with m = 36 kg: the force seen is g * 36 / m_true
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("heavy.csv");
    let o = forcemap(&[
        "simulate",
        "--mass-factor",
        "1.1",
        "--no-random",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let theta = common::identified_values(&csv, &["--model", "coulomb", "--mass-kg", "36"]);
    for (v, truth) in theta.iter().zip([6380.0, 184.0, 12.3]) {
        assert!((v * 1.1 / truth - 1.0).abs() < 0.005, "{theta:?}");
    }
}

#[test]
fn planted_cubic_stiffness_is_recovered_and_rig_effects_are_refused_on_the_three_dof() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("cubic.csv");
    let o = forcemap(&[
        "simulate",
        "--cubic-stiffness-n-per-m3",
        "3e6",
        "--no-random",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let theta = common::identified_values(&csv, &["--model", "coulomb-cubic", "--mass-kg", "36"]);
    for (v, truth) in theta.iter().zip([6380.0, 184.0, 12.3, 3e6]) {
        assert!((v / truth - 1.0).abs() < 0.03, "{theta:?}");
    }
    let o = forcemap(&[
        "simulate",
        "--system",
        "three-dof",
        "--mass-factor",
        "1.1",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--mass-factor"), "{}", stderr(&o));
}

#[test]
fn a_closed_output_pipe_ends_the_command_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_forcemap"))
        .arg("identify")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/damper_dyno_40db"))
        .args(["--model", "damper"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader is gone before anything is written
    let o = child.wait_with_output().unwrap();
    let e = stderr(&o);
    assert!(!e.contains("panicked"), "{e}");
    // Killed by SIGPIPE, as `head` leaves any filter.
    assert_eq!(o.status.signal(), Some(13), "{:?}: {e}", o.status);
}

/// The completion script and the manual pages come from the argument parser: they name the
/// subcommands and options `--help` names, and `man` writes a new directory whole.
#[test]
fn completions_and_manual_pages_name_the_subcommands() {
    let o = forcemap(&["completions", "bash"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let script = String::from_utf8_lossy(&o.stdout);
    for word in ["_forcemap", "identify", "--channels", "--validate", "info"] {
        assert!(script.contains(word), "{word} missing from the bash script");
    }
    let dir = tempfile::tempdir().unwrap();
    let man = dir.path().join("man");
    let o = forcemap(&["man", man.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let page = std::fs::read_to_string(man.join("forcemap-identify.1")).unwrap();
    assert!(page.starts_with(".ie") || page.contains(".TH"), "{page}");
    assert!(page.contains("frequency\\-tolerance"), "{page}");
    assert!(man.join("forcemap.1").is_file());
    // An existing directory is refused, and left as it was.
    let o = forcemap(&["man", man.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("exists already"), "{}", stderr(&o));
}
