//! The real-data suite: public measurements of other labs (committed under `data/real/`, each
//! with its licence and citation), read as they lie through their channel maps, identified by
//! `forcemap identify` with its defaults and scored on held-out tests (`--validate`) beside a
//! plain reference: the time-domain least squares of the same model's terms and moving mass on
//! every scored sample of the same fitted tests (`common/reference.rs`). The target is a mean
//! held-out force NMSE no worse than the reference's on every set and model. On every split
//! the model's form is not the damper's (the fit misses by far more than the noise), so
//! `identify` chooses between fd-multi and the time-domain least squares by leave-one-step-out
//! prediction (`pipeline::choose_estimator`): fd-multi on the first UTFSM split (better than
//! the reference), the least squares on the others (the reference's own estimate); the second
//! UTFSM split's three steps are too few to choose on (each left-out fit rests on two), and
//! the least squares is used. The ARTS friction damper's files are each one
//! record (ramped sines, an earthquake history: no stepped sines), which `identify` fits sample
//! by sample; with the displacement as the drive the force is the model's output along the
//! measured motion, so its output-error estimate is the least squares itself.
//!
//! `cargo test -p forcemap_cli --test real_data_suite -- --nocapture` prints the table of
//! docs/results.md.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;
#[path = "common/reference.rs"]
mod reference;

use std::path::{Path, PathBuf};

use forcemap_io::input::load_files;
use forcemap_io::steps::unlabelled::{DEFAULT_FREQUENCY_TOLERANCE, frequencies_from_data};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::record::{Channel, Record};
use forcemap_math::signal::bouc_wen::HysteresisLaw;

/// One real set and its split into fitted and held-out files.
struct Split {
    name: &'static str,
    /// The largest mean ratio of forcemap's held-out NMSE to the reference's, per model of
    /// [`MODELS`] (1: no worse; a bound above 1 would be a measured miss held so that it can
    /// only close).
    max_ratio: [f64; 2],
    dir: &'static str,
    fit: &'static [&'static str],
    held: &'static [&'static str],
}

const SPLITS: &[Split] = &[
    Split {
        name: "UTFSM MR damper, 0 A: the 200 Hz tests / the 1 kHz tests",
        max_ratio: [1.0, 1.0],
        dir: "mr_damper_utfsm",
        fit: &[
            "2mm5Hz0A.txt",
            "25mm0x1Hz0A.txt",
            "25mm0x25Hz0A.txt",
            "25mm0x5Hz0A.txt",
        ],
        held: &["5mm3Hz0A.txt", "10mm1Hz0A.txt"],
    },
    Split {
        name: "UTFSM MR damper, 0 A: 25 mm at 0.1 and 0.5 Hz, 5 mm at 3 Hz / the others",
        max_ratio: [1.0, 1.0],
        dir: "mr_damper_utfsm",
        fit: &["25mm0x1Hz0A.txt", "25mm0x5Hz0A.txt", "5mm3Hz0A.txt"],
        held: &["2mm5Hz0A.txt", "10mm1Hz0A.txt", "25mm0x25Hz0A.txt"],
    },
    Split {
        name: "Labcontrol MR damper, 0 V: odd tests / even tests",
        max_ratio: [1.0, 1.0],
        dir: "labcontrol_mr_shaketable",
        fit: &[
            "ensaio1.1.mat",
            "ensaio3.1.mat",
            "ensaio5.1.mat",
            "ensaio7.1.mat",
            "ensaio9.1.mat",
        ],
        held: &[
            "ensaio2.1.mat",
            "ensaio4.1.mat",
            "ensaio6.1.mat",
            "ensaio8.1.mat",
            "ensaio10.1.mat",
        ],
    },
    Split {
        name: "ARTS friction damper, 30 lb: 1 Hz 0.5 and 1.5 in, 2 Hz 0.5 in / 1 Hz 1 in, 0.5 Hz 1 in, an earthquake",
        max_ratio: [1.0, 1.0],
        dir: "friction_damper_arts",
        fit: &[
            "1Hz30lbtension0.5amplitude.json",
            "1Hz30lbtension1.5amplitude.json",
            "2Hz30lbtension0.5amplitude.json",
        ],
        held: &[
            "1Hz30lbtension1amplitude.json",
            "0.5Hz30lbtension1amplitude.json",
            "ImperialValleyDBE.json",
        ],
    },
];

const MODELS: &[&str] = &["damper", "linear"];

fn data_dir(dir: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../data/real")
        .join(dir)
}

fn paths(dir: &Path, files: &[&str]) -> Vec<PathBuf> {
    files.iter().map(|f| dir.join(f)).collect()
}

/// The records of `files` as `identify` reads them: through the map, each sine step at the
/// frequency its driven channel shows.
fn records(dir: &Path, files: &[&str]) -> Vec<Record> {
    let loaded = load_files(&paths(dir, files), Some(&dir.join("map.yaml")))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let mut records = loaded.records;
    frequencies_from_data(
        &mut records,
        Channel::RelativeDisplacementM,
        DEFAULT_FREQUENCY_TOLERANCE,
    );
    records
}

/// `forcemap COMMAND FIT... --channels MAP --model MODEL --validate HELD...` on a split, with
/// `extra` arguments: its output.
fn run_split(
    command: &str,
    dir: &Path,
    split: &Split,
    model: &str,
    extra: &[&str],
) -> std::process::Output {
    let map = dir.join("map.yaml");
    let mut args: Vec<String> = vec![command.into()];
    args.extend(
        paths(dir, split.fit)
            .iter()
            .map(|p| p.display().to_string()),
    );
    args.extend([
        "--channels".into(),
        map.display().to_string(),
        "--model".into(),
        model.into(),
    ]);
    args.extend(extra.iter().map(ToString::to_string));
    for h in paths(dir, split.held) {
        args.extend(["--validate".into(), h.display().to_string()]);
    }
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = common::forcemap(&refs);
    assert!(
        o.status.success(),
        "{} {command} {model}: {}",
        split.name,
        common::stderr(&o)
    );
    o
}

/// [`run_split`] with `--json`: its JSON output.
fn run_on_split(command: &str, dir: &Path, split: &Split, model: &str) -> serde_json::Value {
    serde_json::from_slice(&run_split(command, dir, split, model, &["--json"]).stdout)
        .expect("JSON")
}

/// `forcemap identify` on a split: the held-out force NMSE of each held-out record [%].
fn forcemap_held_out_nmse(dir: &Path, split: &Split, model: &str) -> Vec<f64> {
    run_on_split("identify", dir, split, model)["held_out"]
        .as_array()
        .expect("held_out in the JSON")
        .iter()
        .map(|h| h["nmse_percent"].as_f64().expect("nmse_percent"))
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn fmt(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.2}"))
        .collect::<Vec<_>>()
        .join(", ")
}

#[test]
fn forcemap_predicts_real_held_out_tests_beside_least_squares() {
    let mut worse = Vec::new();
    println!(
        "| set: fitted / held out | model | forcemap (default) | least squares | mean ratio |"
    );
    println!("|---|---|---|---|---|");
    for split in SPLITS {
        let dir = data_dir(split.dir);
        let fit = records(&dir, split.fit);
        let held = records(&dir, split.held);
        for (name, max_ratio) in MODELS.iter().zip(split.max_ratio) {
            let model = Model::by_name(name, &ModelOptions::default()).expect("a built-in model");
            let ours = forcemap_held_out_nmse(&dir, split, name);
            let theta = reference::least_squares_theta(&model, true, &fit);
            let reference = reference::nmse_on(&model, &theta, &held);
            assert_eq!(
                ours.len(),
                reference.len(),
                "{}: held-out records",
                split.name
            );
            let ratio = mean(&ours) / mean(&reference);
            println!(
                "| {} | `{name}` | {} | {} | {ratio:.2} |",
                split.name,
                fmt(&ours),
                fmt(&reference)
            );
            // The least squares, where chosen, is the reference's estimate to round-off.
            if ratio > max_ratio * (1.0 + 1e-9) {
                worse.push(format!(
                    "{} `{name}`: {ratio:.3} (at most {max_ratio})",
                    split.name
                ));
            }
        }
    }
    assert!(
        worse.is_empty(),
        "forcemap's default predicts worse than its bound against least squares: {worse:#?}"
    );
}

/// `forcemap diagnose ... --model linear` on a split.
fn diagnose_linear(dir: &Path, split: &Split) -> serde_json::Value {
    run_on_split("diagnose", dir, split, "linear")
}

/// The diagnosis of a `linear` model names what the hardware is known for. The UTFSM MR damper
/// at 0 A: the MR fluid's yield (Coulomb friction, about 108 N) explains the gap, the pre-yield
/// hysteresis (Bouc-Wen) second, and both held-out tests shrink by a third (7.24 -> 4.93 %,
/// 5.73 -> 4.00 %). The Labcontrol damper: its gas preload (about 80 N) explains the gap in
/// part, and every held-out test shrinks to under 40 % of its baseline NMSE (measured 28-38 %).
/// The ARTS friction damper (each file one record, fitted on its samples): the friction's
/// hysteresis loop (Bouc-Wen, yield 4.5 mm, saturated at about 11.3 kN) explains the gap, and
/// the held-out tests, the earthquake history among them, shrink to under 40 % (measured
/// 16-37 %: 18.89 -> 6.31 %, 37.57 -> 5.92 %, 80.91 -> 29.97 %).
#[test]
fn the_diagnosis_names_what_the_dampers_are_known_for() {
    let utfsm = &SPLITS[0];
    let v = diagnose_linear(&data_dir(utfsm.dir), utfsm);
    let ranked: Vec<&str> = v["ranked_effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["effect"].as_str().unwrap())
        .collect();
    println!(
        "UTFSM: {} by {}; ranked {:?}",
        v["verdict"],
        v["top_effect"],
        &ranked[..3]
    );
    assert_eq!(v["verdict"], "explained", "{v}");
    assert_eq!(v["top_effect"], "coulomb_friction", "{v}");
    assert_eq!(ranked[1], "hysteresis", "{ranked:?}");
    let labcontrol = &SPLITS[2];
    let w = diagnose_linear(&data_dir(labcontrol.dir), labcontrol);
    println!("Labcontrol: {} by {}", w["verdict"], w["top_effect"]);
    assert_eq!(w["verdict"], "explained_in_part", "{w}");
    assert_eq!(w["top_effect"], "preload", "{w}");
    let arts = &SPLITS[3];
    let a = diagnose_linear(&data_dir(arts.dir), arts);
    println!("ARTS: {} by {}", a["verdict"], a["top_effect"]);
    assert_eq!(a["verdict"], "explained", "{a}");
    assert_eq!(a["top_effect"], "hysteresis", "{a}");
    assert_eq!(a["sampled_records"], 3, "{a}");
    for (name, d, shrink) in [
        ("UTFSM", &v, 0.75),
        ("Labcontrol", &w, 0.4),
        ("ARTS", &a, 0.4),
    ] {
        for h in d["heldout"].as_array().unwrap() {
            let before = h["baseline_nmse_percent"].as_f64().unwrap();
            let after = h["effect_nmse_percent"].as_f64().unwrap();
            println!(
                "{name} held-out record {}: {before:.2} -> {after:.2} %",
                h["step"]
            );
            assert!(after < shrink * before, "{name}: {h}");
        }
    }
}

/// The Bouc-Wen state of the diagnoses' family (a = 1, yield `zy`, exponent `n`, share
/// `r = beta / (beta + gamma)`) along a sampled velocity from z = 0, written here from its
/// rate equation: RK4 in time, [`REFERENCE_SUB_STEPS`] sub-steps per sample interval with the
/// velocity linear in between (forcemap integrates the same law in the distance travelled).
fn bouc_wen_state(v: &[f64], dt: f64, zy: f64, n: f64, r: f64) -> Vec<f64> {
    let rate = |z: f64, v: f64| {
        let un = (z.abs() / zy).powf(n);
        v - (r * v.abs() * z.signum() + (1.0 - r) * v) * un
    };
    let h = dt / REFERENCE_SUB_STEPS as f64;
    let mut z = 0.0;
    let mut out = vec![0.0];
    for w in v.windows(2) {
        let at = |k: f64| w[0] + (w[1] - w[0]) * k / REFERENCE_SUB_STEPS as f64;
        for k in 0..REFERENCE_SUB_STEPS {
            let k = k as f64;
            let (v0, vm, v1) = (at(k), at(k + 0.5), at(k + 1.0));
            let k1 = rate(z, v0);
            let k2 = rate(z + 0.5 * h * k1, vm);
            let k3 = rate(z + 0.5 * h * k2, vm);
            let k4 = rate(z + h * k3, v1);
            z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        out.push(z);
    }
    out
}

/// The ratio of a row where forcemap's estimate is the reference's, within what the two
/// integrations of the Bouc-Wen state leave (measured within 1.6e-7 of 1).
const SAME_ESTIMATE: f64 = 1.0 + 1e-5;

/// RK4 sub-steps per sample interval of the reference's Bouc-Wen state: at the UTFSM damper's
/// 200 Hz a 5 Hz stroke moves more than the fitted yield (0.24 mm) between two samples.
const REFERENCE_SUB_STEPS: usize = 32;

/// The whole model `diagnose` prints with the effect it names is the one its held-out figures
/// come from: on the ARTS friction damper, the `linear` baseline refitted beside the hysteresis
/// (k, c and the moving mass m, then alpha, the yield and the shape) predicts each held-out
/// record's force along its measured motion, computed here from those printed values alone,
/// within 2 % of the NMSE the diagnosis reports with the effect (its state integrated here by
/// RK4 in time, there in the distance travelled).
#[test]
fn the_model_printed_with_the_named_effect_predicts_the_held_out_records() {
    let arts = &SPLITS[3];
    let dir = data_dir(arts.dir);
    let d = diagnose_linear(&dir, arts);
    assert_eq!(d["top_effect"], "hysteresis", "{d}");
    let top = &d["ranked_effects"][0];
    let value = |list: &str, name: &str| common::parameter_value(&top[list], name);
    let (k, c, m) = (
        value("refitted_baseline", "k"),
        value("refitted_baseline", "c"),
        value("refitted_baseline", "m"),
    );
    let alpha = value("added_parameters", "alpha");
    let (zy, n, r) = (
        value("added_parameters", "yield_m"),
        value("added_parameters", "bouc_wen_n"),
        value("added_parameters", "bouc_wen_r"),
    );
    for (record, h) in records(&dir, arts.held)
        .iter()
        .zip(d["heldout"].as_array().unwrap())
    {
        let s = forcemap_math::measured_state::MeasuredState::of(record).unwrap();
        let z = bouc_wen_state(&s.velocity_mps, 1.0 / s.sample_rate_hz, zy, n, r);
        let (measured, predicted): (Vec<f64>, Vec<f64>) = s
            .scored
            .clone()
            .map(|i| {
                let f = k * s.displacement_m[i]
                    + c * s.velocity_mps[i]
                    + m * s.acceleration_mps2[i]
                    + alpha * z[i];
                (s.force_n[i], f)
            })
            .unzip();
        let nmse = forcemap_math::pipeline::nmse_percent(&measured, &predicted);
        let reported = h["effect_nmse_percent"].as_f64().unwrap();
        println!(
            "held-out record {}: {nmse:.2} % from the printed model, {reported:.2} % reported",
            h["step"]
        );
        assert!((nmse / reported - 1.0).abs() < 0.02, "{nmse} {reported}");
    }
}

/// Where the model's form fails, `identify` says so on real data: the `damper` model of the
/// ARTS friction damper (fitted on the samples of three ramped sines) misses their force by far
/// more than what the noise of the force and of the measured motion leaves (37 noise std
/// measured), with the warning that the form may not describe the data; and the earthquake
/// history, predicted worse than by zero (249.57 %), is marked so, while the held-out sines
/// (16.62, 28.02 %) are not.
#[test]
fn identify_says_where_the_damper_model_fails_on_the_friction_damper() {
    let arts = &SPLITS[3];
    let o = run_split("identify", &data_dir(arts.dir), arts, "damper", &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    let misfit: f64 = text
        .lines()
        .find(|l| l.contains("the displacement is the drive"))
        .and_then(|l| l.strip_suffix(" noise std"))
        .and_then(|l| l.rsplit_once(", "))
        .and_then(|(_, v)| v.parse().ok())
        .unwrap_or_else(|| panic!("no misfit line: {text}"));
    println!("ARTS damper: RMS misfit {misfit} noise std");
    assert!(misfit > 10.0, "{text}");
    assert!(
        text.contains("the model's form may not describe these data"),
        "{text}"
    );
    let held: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("held out:"))
        .collect();
    assert_eq!(held.len(), 3, "{text}");
    let zero = "no better than predicting zero";
    assert!(
        !held[0].contains(zero) && !held[1].contains(zero),
        "{held:?}"
    );
    assert!(
        held[2].contains("ImperialValleyDBE") && held[2].contains(zero),
        "{held:?}"
    );
}

/// Models with a hysteresis state (`NAME+hysteresis`: the terms and a Bouc-Wen state, fitted as
/// `diagnose` refits NAME with its hysteresis), on the sets whose dampers have a loop, beside the
/// plain reference with the same state: the least squares of the terms, the moving mass and
/// the state of the Bouc-Wen law forcemap chose (integrated here by RK4 along each record's
/// measured velocity), on every scored sample of the same fitted tests. Held-out force NMSE
/// [%] per record and the ratio of the means, at most 1 on every row: forcemap's choice
/// between the rebuilt periods and the samples must not lose to the samples' least squares.
#[test]
fn hysteresis_models_against_the_least_squares_with_the_same_state() {
    // Measured: 1 on every row within 1.6e-7: where the sine steps' samples are fitted (both
    // dampers' steps; the ARTS records have none), forcemap's coefficients are this least
    // squares' (every sample alike), and the two integrations of the state differ by less
    // than the bound's slack.
    // Beside the reference with its own law (`reference_with_its_own_law`), measured 1.004,
    // 1.009, 1.458 (the earthquake history, which forcemap's fit predicts worse than zero:
    // 112.04 against 73.47 %) and 0.970: held as the rows' bounds, so that they can only close.
    let cases: [(usize, &str, f64, f64); 4] = [
        (0, "damper", SAME_ESTIMATE, 1.004),
        (2, "damper", SAME_ESTIMATE, 1.009),
        (3, "damper", SAME_ESTIMATE, 1.459),
        (3, "linear", SAME_ESTIMATE, 0.971),
    ];
    for (split, base, bound, own_bound) in cases {
        let split = &SPLITS[split];
        let dir = data_dir(split.dir);
        let name = format!("{base}+hysteresis");
        let v = run_on_split("identify", &dir, split, &name);
        let value = |n: &str| common::parameter_value(&v["parameters"], n);
        let (zy, n, r) = (value("yield_m"), value("bouc_wen_n"), value("bouc_wen_r"));
        // Both MR dampers' sine steps: their samples predict left-out steps best (1.84 %
        // against the periods' 6.51 % on the Labcontrol damper, 10.38 % against 272.90 % on
        // the UTFSM one), and the choice says so with both scores. The ARTS records have no
        // steps: no choice.
        let choice = v["fit_choice"].as_str().unwrap_or("");
        if split.dir == "friction_damper_arts" {
            assert!(v["fit_choice"].is_null(), "{v}");
        } else {
            assert_eq!(v["fitted_on"], "samples", "{v}");
            assert!(
                choice.contains("periods ") && choice.contains("samples "),
                "{choice}"
            );
        }
        let ours: Vec<f64> = v["held_out"]
            .as_array()
            .unwrap()
            .iter()
            .map(|h| h["nmse_percent"].as_f64().unwrap())
            .collect();
        let model = Model::by_name(base, &ModelOptions::default()).unwrap();
        let state = |s: &forcemap_math::measured_state::MeasuredState| {
            bouc_wen_state(&s.velocity_mps, 1.0 / s.sample_rate_hz, zy, n, r)
        };
        let column: reference::StateColumn = &state;
        let theta = reference::least_squares_theta_with(
            &model,
            true,
            Some(column),
            &records(&dir, split.fit),
        );
        let reference =
            reference::nmse_on_with(&model, &theta, Some(column), &records(&dir, split.held));
        let ratio = mean(&ours) / mean(&reference);
        let (own_law, own) = reference_with_its_own_law(&model, &dir, split);
        let own_ratio = mean(&ours) / mean(&own);
        let list = |v: &[f64]| {
            v.iter()
                .map(|e| format!("{e:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        println!(
            "| {} | `{name}` | {} | {} | **{ratio:.2}** | {} ({own_law}) | **{own_ratio:.2}** |",
            split.name,
            list(&ours),
            list(&reference),
            list(&own),
        );
        assert!(ratio <= bound, "{name} on {}: {ratio}", split.name);
        assert!(
            own_ratio <= own_bound,
            "{name} on {} against the reference's own law: {own_ratio}",
            split.name
        );
    }
}

/// The plain reference's own Bouc-Wen law: yields on a grid (eight, from 0.5 % to 80 % of the
/// largest displacement from the mean among the fitted tests, geometric) and the shapes n in
/// {1, 2}, r in {0.5, 0.85}, each fitted by the least squares of the terms, the moving mass and
/// the state, the law whose fit leaves the lowest mean NMSE on the fitted tests kept (no
/// held-out data, no cross-validation: what a few lines of least squares would do). The state
/// is forcemap's integration of the law (checked against its closed forms in
/// `signal::bouc_wen`). Returns the law, described, and its held-out NMSE per record [%].
fn reference_with_its_own_law(model: &Model, dir: &Path, split: &Split) -> (String, Vec<f64>) {
    let fit = records(dir, split.fit);
    let held = records(dir, split.held);
    let largest = fit
        .iter()
        .map(|r| {
            let s = forcemap_math::measured_state::MeasuredState::of(r).unwrap();
            let x = &s.displacement_m[s.scored.clone()];
            let mean = x.iter().sum::<f64>() / x.len() as f64;
            x.iter().fold(0.0f64, |m, v| m.max((v - mean).abs()))
        })
        .fold(0.0f64, f64::max);
    let mut best: Option<(f64, HysteresisLaw)> = None;
    for k in 0..8 {
        let yield_m = largest * 0.005 * (0.8f64 / 0.005).powf(k as f64 / 7.0);
        for (n, r) in [(1.0, 0.5), (2.0, 0.5), (1.0, 0.85), (2.0, 0.85)] {
            let law = HysteresisLaw { yield_m, n, r };
            let state = |s: &forcemap_math::measured_state::MeasuredState| {
                law.integrate_record(&s.velocity_mps, 1.0 / s.sample_rate_hz)
            };
            let column: reference::StateColumn = &state;
            let theta = reference::least_squares_theta_with(model, true, Some(column), &fit);
            let in_sample = mean(&reference::nmse_on_with(model, &theta, Some(column), &fit));
            if best.is_none_or(|(e, _)| in_sample < e) {
                best = Some((in_sample, law));
            }
        }
    }
    let (_, law) = best.unwrap();
    let state = |s: &forcemap_math::measured_state::MeasuredState| {
        law.integrate_record(&s.velocity_mps, 1.0 / s.sample_rate_hz)
    };
    let column: reference::StateColumn = &state;
    let theta = reference::least_squares_theta_with(model, true, Some(column), &fit);
    (
        format!(
            "yield {:.3} mm, n {}, r {}",
            1e3 * law.yield_m,
            law.n,
            law.r
        ),
        reference::nmse_on_with(model, &theta, Some(column), &held),
    )
}
