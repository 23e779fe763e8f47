//! Output error on the element setup against the truth of its simulator: the damper on a
//! displacement-driven dyno (`RunSpec::damper_dyno`, moving mass known) and the force-driven
//! single-DOF system with cubic stiffness (`RunSpec::shaker_sdof`, moving mass identified).
//!
//! The noise study (ten seeds at 30 and 40 dB, scatter against the reported std and the
//! Cramer-Rao bound) is ignored for its run time; run it with
//! `cargo test --release -p forcemap_math --test identify_element_output_error -- --ignored --nocapture`.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

use std::sync::Arc;

use forcemap_math::basis::{StribeckVelocity, Term};
use forcemap_math::element::Friction;
use forcemap_math::identify::{FdMultiOptions, Identification, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::record::Record;
use forcemap_math::sim::{RunSpec, TruthElement};

const DYNO_MASS_KG: f64 = 0.8;

/// The shaker system's truth: the `cubic` model's k, c, s, then the identified mass m.
const SDOF_THETA: [f64; 4] = [2.0e4, 60.0, 5.0e7, 2.0];

fn model(name: &str) -> Model {
    Model::by_name(name, &ModelOptions::default()).unwrap()
}

fn identify(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
) -> Result<Identification, forcemap_math::pipeline::PipelineError> {
    identify_records(
        model,
        setup,
        method,
        records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
}

fn dyno_setup() -> Setup {
    Setup::Element {
        moving_mass_kg: Some(DYNO_MASS_KG),
    }
}

fn sdof_setup() -> Setup {
    Setup::Element {
        moving_mass_kg: None,
    }
}

fn dyno_truth() -> Vec<f64> {
    RunSpec::DAMPER_DYNO_THETA.iter().map(|(_, v)| *v).collect()
}

fn relative_errors(id: &Identification, truth: &[f64]) -> Vec<f64> {
    assert_eq!(id.parameters.len(), truth.len(), "{:?}", id.parameters);
    id.theta()
        .iter()
        .zip(truth)
        .map(|(v, t)| v / t - 1.0)
        .collect()
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, e| a.max(e.abs()))
}

#[test]
fn noise_free_damper_dyno_is_recovered_to_round_off() {
    let rec = RunSpec::damper_dyno(None, 0).simulate().unwrap();
    let oe = identify(&model("damper"), &dyno_setup(), Method::OutputError, &rec).unwrap();
    assert_eq!(oe.method, "output-error");
    assert!(
        oe.warnings
            .iter()
            .any(|w| w.contains("driven by its displacement")),
        "{:?}",
        oe.warnings
    );
    let e = relative_errors(&oe, &dyno_truth());
    println!("damper dyno, noise-free output error: relative errors {e:?}");
    assert!(max_abs(&e) < 1e-9, "{e:?}");
}

#[test]
fn noise_free_shaker_sdof_with_its_mass_is_recovered_to_round_off() {
    let rec = RunSpec::shaker_sdof(None, 0).simulate().unwrap();
    let oe = identify(&model("cubic"), &sdof_setup(), Method::OutputError, &rec).unwrap();
    assert!(
        oe.warnings
            .iter()
            .any(|w| w.contains("driven by its force")),
        "{:?}",
        oe.warnings
    );
    assert_eq!(oe.parameters.last().unwrap().name, "m");
    let e = relative_errors(&oe, &SDOF_THETA);
    println!("shaker sdof, noise-free output error: relative errors {e:?}");
    assert!(max_abs(&e) < 1e-9, "{e:?}");
}

/// Stick-slip under a force drive: the shaker's system with Stribeck friction (breakaway 6 N,
/// kinetic 4 N at 0.02 m/s) and the model `cubic` plus sgn and the Stribeck excess; the mass
/// sticks at every reversal, so the acceleration jumps and is masked next to the events.
#[test]
fn stick_slip_under_a_force_drive_is_recovered_noise_free() {
    let vs = 0.02;
    let truth = TruthElement {
        friction: Some(Friction {
            breakaway_n: 6.0,
            kinetic_n: 4.0,
            stribeck_velocity_mps: vs,
            asymmetry: 0.0,
        }),
        ..RunSpec::shaker_sdof(None, 0).element
    };
    let rec = RunSpec::shaker_sdof(None, 0)
        .with_element(truth)
        .simulate()
        .unwrap();
    let m = model("cubic").with_terms(
        "cubic-stribeck",
        &[
            Arc::new(forcemap_math::basis::SignVelocity) as Arc<dyn Term>,
            Arc::new(StribeckVelocity { velocity_mps: vs }) as Arc<dyn Term>,
        ],
    );
    let oe = identify(&m, &sdof_setup(), Method::OutputError, &rec).unwrap();
    let fdm = identify(&m, &sdof_setup(), Method::FdMulti, &rec).unwrap();
    let want = [2.0e4, 60.0, 5.0e7, 4.0, 2.0, 2.0];
    println!(
        "fd-multi {:?}\noutput-error {:?}",
        relative_errors(&fdm, &want),
        relative_errors(&oe, &want)
    );
    assert!(max_abs(&relative_errors(&oe, &want)) < 1e-6);
}

/// The friction law of the simulators has one Stribeck velocity: a model with excesses at two
/// is refused, with the reason, not simulated with one of them.
#[test]
fn a_model_the_simulator_cannot_run_is_refused_with_the_reason() {
    let rec = RunSpec::damper_dyno(None, 0).simulate().unwrap();
    let two = model("damper").with_terms(
        "damper-two-stribeck",
        &[
            Arc::new(StribeckVelocity { velocity_mps: 0.01 }) as Arc<dyn Term>,
            Arc::new(StribeckVelocity { velocity_mps: 0.05 }) as Arc<dyn Term>,
        ],
    );
    let e = identify(&two, &dyno_setup(), Method::OutputError, &rec)
        .unwrap_err()
        .to_string();
    assert!(e.contains("one Stribeck velocity"), "{e}");
    assert!(e.contains("0.01") && e.contains("0.05"), "{e}");
}
