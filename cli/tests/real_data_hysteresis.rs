//! The real-data suite's models with a hysteresis state (`NAME+hysteresis`) on the sets whose
//! dampers have a loop, beside the plain references with a Bouc-Wen state: the least squares with
//! the law forcemap chose, and with a law of its own.
//!
//! `cargo test -p forcemap_cli --test real_data_hysteresis -- --nocapture` prints the table of
//! docs/results.md.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;
#[path = "common/real_sets.rs"]
mod real_sets;
// The reference's plain least squares without a state is the other suite's.
#[allow(dead_code)]
#[path = "common/reference.rs"]
mod reference;

use std::path::Path;

use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::record::Record;
use forcemap_math::signal::bouc_wen::HysteresisLaw;
use real_sets::*;

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
    // 112.04 against 73.47 %; not a worse law: `the_earthquake_is_not_ranked_by_laws_that_fit_
    // the_sines_alike`) and 0.970: held as the rows' bounds, so that they can only close.
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

/// The least squares of `model`'s terms, the moving mass and the state of `law` (forcemap's
/// integration of it, checked against its closed forms in `signal::bouc_wen`) on every scored
/// sample of the fitted records: its mean NMSE on them [%] and its NMSE on each held-out
/// record [%].
fn least_squares_with_law(
    model: &Model,
    law: HysteresisLaw,
    fit: &[Record],
    held: &[Record],
) -> (f64, Vec<f64>) {
    let state = |s: &forcemap_math::measured_state::MeasuredState| {
        law.integrate_record(&s.velocity_mps, 1.0 / s.sample_rate_hz)
    };
    let column: reference::StateColumn = &state;
    let theta = reference::least_squares_theta_with(model, true, Some(column), fit);
    (
        mean(&reference::nmse_on_with(model, &theta, Some(column), fit)),
        reference::nmse_on_with(model, &theta, Some(column), held),
    )
}

/// The largest displacement from the mean among `records`' scored samples [m].
fn largest_stroke_m(records: &[Record]) -> f64 {
    records
        .iter()
        .map(|r| {
            let s = forcemap_math::measured_state::MeasuredState::of(r).unwrap();
            let x = &s.displacement_m[s.scored.clone()];
            let mean = x.iter().sum::<f64>() / x.len() as f64;
            x.iter().fold(0.0f64, |m, v| m.max((v - mean).abs()))
        })
        .fold(0.0f64, f64::max)
}

/// The plain reference's own Bouc-Wen law: yields on a grid (eight, from 0.5 % to 80 % of the
/// largest displacement from the mean among the fitted tests, geometric) and the shapes n in
/// {1, 2}, r in {0.5, 0.85}, each fitted by [`least_squares_with_law`], the law whose fit
/// leaves the lowest mean NMSE on the fitted tests kept (no held-out data, no
/// cross-validation: what a few lines of least squares would do). Returns the law, described,
/// and its held-out NMSE per record [%].
fn reference_with_its_own_law(model: &Model, dir: &Path, split: &Split) -> (String, Vec<f64>) {
    let fit = records(dir, split.fit);
    let held = records(dir, split.held);
    let largest = largest_stroke_m(&fit);
    let mut best: Option<(f64, HysteresisLaw, Vec<f64>)> = None;
    for k in 0..8 {
        let yield_m = largest * 0.005 * (0.8f64 / 0.005).powf(k as f64 / 7.0);
        for (n, r) in SHAPES {
            let law = HysteresisLaw { yield_m, n, r };
            let (in_sample, held_out) = least_squares_with_law(model, law, &fit, &held);
            if best.as_ref().is_none_or(|(e, _, _)| in_sample < *e) {
                best = Some((in_sample, law, held_out));
            }
        }
    }
    let (_, law, held_out) = best.unwrap();
    (
        format!(
            "yield {:.3} mm, n {}, r {}",
            1e3 * law.yield_m,
            law.n,
            law.r
        ),
        held_out,
    )
}

/// The Bouc-Wen shapes (n, r) the plain references try.
const SHAPES: [(f64, f64); 4] = [(1.0, 0.5), (2.0, 0.5), (1.0, 0.85), (2.0, 0.85)];

/// Why forcemap's `damper+hysteresis` predicts the ARTS earthquake history worse than the
/// reference with its own law (1.46) without choosing a worse law: on a finer grid (yields
/// 1-8 mm, the four shapes) forcemap's law fits the three ramped sines better than every law,
/// and among the laws that fit them within 12 % of the best the sines are predicted alike
/// while the earthquake's error spans more than a factor 3 (measured 4.37-5.16 %, 3.18-4.16 %
/// on the sines; 50.57-177.31 % on the earthquake): the fitted tests cannot rank laws on a
/// slower, smaller record than theirs.
#[test]
fn the_earthquake_is_not_ranked_by_laws_that_fit_the_sines_alike() {
    let split = &SPLITS[3];
    let dir = data_dir(split.dir);
    let (fit, held) = (records(&dir, split.fit), records(&dir, split.held));
    let model = Model::by_name("damper", &ModelOptions::default()).unwrap();
    let v = run_on_split("identify", &dir, split, "damper+hysteresis");
    let value = |n: &str| common::parameter_value(&v["parameters"], n);
    let ours = HysteresisLaw {
        yield_m: value("yield_m"),
        n: value("bouc_wen_n"),
        r: value("bouc_wen_r"),
    };
    let (ours_in_sample, _) = least_squares_with_law(&model, ours, &fit, &held);
    let grid: Vec<(f64, Vec<f64>)> = [1.0, 1.5, 2.0, 2.5, 3.0, 3.4, 4.0, 4.75, 5.5, 6.5, 8.0]
        .iter()
        .flat_map(|yield_mm| {
            SHAPES.map(|(n, r)| HysteresisLaw {
                yield_m: 1e-3 * yield_mm,
                n,
                r,
            })
        })
        .map(|law| least_squares_with_law(&model, law, &fit, &held))
        .collect();
    let best = grid.iter().map(|(e, _)| *e).fold(f64::INFINITY, f64::min);
    assert!(
        ours_in_sample <= best * (1.0 + 1e-6),
        "forcemap's law leaves {ours_in_sample} % on the fitted tests, a grid law {best} %"
    );
    let alike: Vec<&Vec<f64>> = grid
        .iter()
        .filter(|(e, _)| *e <= 1.12 * best)
        .map(|(_, h)| h)
        .collect();
    let range = |i: usize| {
        let v = alike.iter().map(|h| h[i]);
        (
            v.clone().fold(f64::INFINITY, f64::min),
            v.fold(0.0f64, f64::max),
        )
    };
    let ((s0, s1), (t0, t1), (e0, e1)) = (range(0), range(1), range(2));
    println!(
        "{} laws within 12 % of the best fit ({best:.2} %; forcemap's law {ours_in_sample:.2} %): \
         sines {s0:.2}-{s1:.2} %, {t0:.2}-{t1:.2} %; earthquake {e0:.2}-{e1:.2} %",
        alike.len()
    );
    assert!(alike.len() >= 8, "{} laws", alike.len());
    assert!(
        s1 < 1.25 * s0 && t1 < 1.4 * t0,
        "the sines are not predicted alike"
    );
    assert!(e1 > 3.0 * e0, "the earthquake's error spans {e0}-{e1} %");
}
