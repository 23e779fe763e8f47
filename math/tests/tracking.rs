//! Tracking a drifting parameter by exponential forgetting (`EquationAccumulator::forget`): a
//! damper whose damping fades by 30 % over a run of 40 steps (a damper heating up on a dyno),
//! identified step by step as the live identifier does. The trade-off between lag and scatter
//! is measured over forgetting factors; the converged mode (factor 1) averages the whole run.

use forcemap_math::identify::{EquationAccumulator, FdMultiOptions, Method, step_equations};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::recipe::Setup;
use forcemap_math::sim::{AsymmetricDamping, ElementDrive, RunSpec, StepSpec};

const STEPS: usize = 40;
const FADE: f64 = 0.30;

/// The dyno damper's viscous damping c (mean of rebound and compression) at step `j`.
fn true_c(j: usize) -> f64 {
    1750.0 * (1.0 - FADE * j as f64 / (STEPS - 1) as f64)
}

/// The tracked c after each step, for one forgetting factor.
fn tracked_c(factor: f64, snr_db: f64) -> Vec<f64> {
    let base = RunSpec::damper_dyno(None, 0).element;
    let model = Model::by_name("damper", &ModelOptions::default()).expect("model");
    let setup = Setup::Element {
        moving_mass_kg: Some(0.8),
        drive: None,
    };
    let mut acc = EquationAccumulator::new(&model, &setup, Method::FdMulti);
    let frequencies_hz = [1.0, 2.0, 4.0, 8.0];
    let mut out = Vec::new();
    for j in 0..STEPS {
        // The fade scales both sides' damping; the damper is otherwise the dyno's.
        let scale = true_c(j) / 1750.0;
        let mut element = base.clone();
        element.asymmetric_damping = Some(AsymmetricDamping {
            rebound_n_s_per_m: 2500.0 * scale,
            compression_n_s_per_m: 1000.0 * scale,
        });
        let run = RunSpec {
            snr_db: Some(snr_db),
            seed: 100 + j as u64,
            ..RunSpec::element_test(
                ElementDrive::Displacement,
                0.8,
                element,
                vec![StepSpec::Sine {
                    frequency_hz: frequencies_hz[j % 4],
                    amplitude: 0.01,
                }],
                1000.0,
                4000,
            )
        };
        let mut record = run.simulate().expect("simulates").remove(0);
        record.step = j;
        let an = analyse_record(&record, &PhasorOptions::for_identification()).expect("phasors");
        let blk = step_equations(
            &model,
            &setup,
            Method::FdMulti,
            &an,
            &FdMultiOptions::default(),
        )
        .expect("equations");
        acc.forget(factor);
        acc.add(&blk).expect("added");
        let c = acc
            .solve()
            .ok()
            .and_then(|id| {
                id.parameters
                    .iter()
                    .find(|p| p.name == "c")
                    .map(|p| p.value)
            })
            .unwrap_or(f64::NAN);
        out.push(c);
    }
    out
}

/// (largest error of the tracked c against the truth `lag` steps back, after a warm-up of
/// twice the window, relative; the lag used).
fn error_after_lag(c: &[f64], factor: f64) -> (f64, f64) {
    let lag = factor / (1.0 - factor);
    let start = (2.0 * lag).ceil() as usize + 4;
    let err = (start..STEPS)
        .map(|j| {
            // The truth is linear in the step: its value lag steps back.
            let t = 1750.0 * (1.0 - FADE * (j as f64 - lag) / (STEPS - 1) as f64);
            (c[j] / t - 1.0).abs()
        })
        .fold(0.0, f64::max);
    (err, lag)
}

#[test]
fn forgetting_follows_a_fading_damper_within_three_percent_after_its_lag() {
    println!(
        "factor  lag [steps]  max |error| after the lag  error at the end against the truth then"
    );
    let mut errors = Vec::new();
    for factor in [0.9, 0.8, 0.7] {
        let c = tracked_c(factor, 30.0);
        let (err, lag) = error_after_lag(&c, factor);
        let end = (c[STEPS - 1] / true_c(STEPS - 1) - 1.0) * 100.0;
        println!(
            "{factor:>6} {lag:>12.2} {:>26.2} % {end:>+22.2} %",
            100.0 * err
        );
        errors.push((factor, err));
    }
    // A window of 9 steps' mean age is too long for a 40-step run: it has not reached its
    // asymptotic lag when the run ends. Windows of 2-4 steps follow within 3 %.
    for (factor, err) in &errors {
        if *factor <= 0.8 {
            assert!(*err < 0.03, "{errors:?}");
        }
    }
    // The converged mode averages the run: at its end it is far from the faded truth.
    let c = tracked_c(1.0, 30.0);
    let end = c[STEPS - 1] / true_c(STEPS - 1) - 1.0;
    println!(
        "   1.0 (converged): at the end {:+.2} % against the truth then",
        100.0 * end
    );
    assert!(end > 0.1, "{end}");
}
