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
use forcemap_math::identify::{
    ElementOutputError, FdMultiOptions, Identification, Method, element_drive_of,
};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::{analyse_sine_steps, identify_records};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::excitation::Piece;
use forcemap_math::sim::noise::run_rms;
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
        drive: None,
    }
}

fn sdof_setup() -> Setup {
    Setup::Element {
        moving_mass_kg: None,
        drive: None,
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
            stribeck_exponent: 2.0,
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
            Arc::new(StribeckVelocity::gaussian(vs)) as Arc<dyn Term>,
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

/// The friction law of the simulators has one Stribeck curve: a model with excesses at two velocities
/// is refused, with the reason, not simulated with one of them.
#[test]
fn a_model_the_simulator_cannot_run_is_refused_with_the_reason() {
    let rec = RunSpec::damper_dyno(None, 0).simulate().unwrap();
    let two = model("damper").with_terms(
        "damper-two-stribeck",
        &[
            Arc::new(StribeckVelocity::gaussian(0.01)) as Arc<dyn Term>,
            Arc::new(StribeckVelocity::gaussian(0.05)) as Arc<dyn Term>,
        ],
    );
    let e = identify(&two, &dyno_setup(), Method::OutputError, &rec)
        .unwrap_err()
        .to_string();
    assert!(e.contains("one Stribeck curve"), "{e}");
    assert!(e.contains("0.01") && e.contains("0.05"), "{e}");
}

/// The two benches of the study: name, run, model, setup, truth of the identified parameters.
struct Bench {
    name: &'static str,
    run: fn(Option<f64>, u64) -> RunSpec,
    model: &'static str,
    setup: fn() -> Setup,
    truth: Vec<f64>,
    names: Vec<&'static str>,
}

fn benches() -> [Bench; 2] {
    [
        Bench {
            name: "damper dyno",
            run: RunSpec::damper_dyno,
            model: "damper",
            setup: dyno_setup,
            truth: dyno_truth(),
            names: RunSpec::DAMPER_DYNO_THETA.iter().map(|(n, _)| *n).collect(),
        },
        Bench {
            name: "shaker sdof",
            run: RunSpec::shaker_sdof,
            model: "cubic",
            setup: sdof_setup,
            truth: SDOF_THETA.to_vec(),
            names: vec!["k", "c", "s", "m"],
        },
    ]
}

#[test]
fn damper_dyno_and_shaker_sdof_at_30_db_every_parameter_within_1_percent() {
    for b in benches() {
        let rec = (b.run)(Some(30.0), 1).simulate().unwrap();
        let oe = identify(&model(b.model), &(b.setup)(), Method::OutputError, &rec).unwrap();
        let e = relative_errors(&oe, &b.truth);
        println!("{} at 30 dB: relative errors {e:?}", b.name);
        assert!(max_abs(&e) < 0.01, "{}: {e:?}", b.name);
        assert!(
            (0.9..1.1).contains(&oe.residual_rms),
            "{}: RMS misfit {} noise std",
            b.name,
            oe.residual_rms
        );
        for (p, t) in oe.parameters.iter().zip(&b.truth) {
            assert!(
                (p.value - t).abs() < 4.0 * p.std,
                "{}: {} = {} +- {}",
                b.name,
                p.name,
                p.value,
                p.std
            );
        }
    }
}

/// The true parameters of the fitted problem: the bench's truth, each step's drive amplitude
/// and phase at its record's start as the run's program has them, and the offset (none).
fn true_parameters(spec: &RunSpec, truth: &[f64]) -> Vec<f64> {
    let mut p = truth.to_vec();
    for piece in &spec.program().signal.pieces[1..] {
        let Piece::Sine {
            amplitude, phase, ..
        } = piece
        else {
            panic!("sine steps only")
        };
        p.extend([*amplitude, *phase]);
    }
    p.push(0.0);
    p
}

/// Runs `f` on the output-error problem of `noisy` weighted by the true noise std of each
/// channel (as `noise::add_noise` draws it), with the true parameters.
fn at_truth_with_true_noise<T>(
    b: &Bench,
    noisy: &[Record],
    snr_db: f64,
    f: impl FnOnce(&ElementOutputError, &[f64]) -> T,
) -> T {
    let spec = (b.run)(None, 0);
    let clean = spec.simulate().unwrap();
    let (analyses, _) = analyse_sine_steps(noisy, &PhasorOptions::for_identification()).unwrap();
    let sigma = [
        Channel::RelativeDisplacementM,
        Channel::ForceN,
        Channel::MassAccelerationMps2,
    ]
    .map(|c| run_rms(&clean, c).unwrap() / 10f64.powf(snr_db / 20.0));
    let Setup::Element { moving_mass_kg, .. } = (b.setup)() else {
        panic!("element setup")
    };
    let problem = ElementOutputError::new(
        &model(b.model),
        moving_mass_kg,
        noisy,
        &analyses,
        element_drive_of(&analyses),
    )
    .unwrap()
    .with_noise(&sigma);
    f(&problem, &true_parameters(&spec, &b.truth))
}

/// Cramer-Rao bound of the bench's parameters on the settled samples the fit of `noisy` used:
/// the output-error Jacobian at the truth, the true noise std of each channel.
fn crb(b: &Bench, noisy: &[Record], snr_db: f64) -> Vec<f64> {
    let cov = at_truth_with_true_noise(b, noisy, snr_db, |problem, truth| {
        problem.covariance_at(truth).unwrap()
    });
    (0..b.truth.len()).map(|i| cov[(i, i)].sqrt()).collect()
}

/// The error of the linearised estimate for the noise draw of `noisy`: the Gauss-Newton step
/// from the truth with the true noise std (see [`crb`]).
fn linearised_error(b: &Bench, noisy: &[Record], snr_db: f64) -> Vec<f64> {
    let mut d = at_truth_with_true_noise(b, noisy, snr_db, |problem, truth| {
        problem.gauss_newton_step_at(truth).unwrap()
    });
    d.truncate(b.truth.len());
    d
}

/// Whether the scatter above the bound is the noise draws' or the fit's: each seed's error
/// against the linearised estimate's for the same draw (`BENCH`, `SEEDS` as the study).
#[test]
#[ignore]
fn errors_against_the_linearised_estimate() {
    let only = std::env::var("BENCH").unwrap_or_default();
    for b in benches()
        .into_iter()
        .filter(|b| b.name.contains(only.as_str()))
    {
        let np = b.truth.len();
        let (mut fit, mut lin) = (vec![0.0; np], vec![0.0; np]);
        for seed in 0..seeds() {
            let rec = (b.run)(Some(30.0), seed).simulate().unwrap();
            let d = linearised_error(&b, &rec, 30.0);
            let id = identify(&model(b.model), &(b.setup)(), Method::OutputError, &rec).unwrap();
            let e: Vec<f64> = id
                .theta()
                .iter()
                .zip(&b.truth)
                .map(|(v, t)| v - t)
                .collect();
            println!(
                "{} seed {seed}: error / linearised error {:.3?}",
                b.name,
                e.iter().zip(&d).map(|(a, l)| a / l).collect::<Vec<_>>()
            );
            for j in 0..np {
                fit[j] += e[j] * e[j];
                lin[j] += d[j] * d[j];
            }
        }
        println!(
            "{}: RMS error / RMS linearised error {:.3?}",
            b.name,
            fit.iter()
                .zip(&lin)
                .map(|(a, l)| (a / l).sqrt())
                .collect::<Vec<_>>()
        );
    }
}

/// Seeds of the noise study: `SEEDS` (default 10).
fn seeds() -> u64 {
    std::env::var("SEEDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10)
}

/// The acceptance on the element setup: over the seeds (`SEEDS`, default 10) at 30 and
/// 40 dB, the scatter (RMS error about the truth) against the reported std and the Cramer-Rao
/// bound, for both benches. Prints the table. Asserts every error within 1 % at 30 dB, the
/// reported std within 20 % of the bound, and the scatter within the 99 % interval of an RMS
/// of `SEEDS` normal errors with the reported std (as the rig's study). An error above 1 % is
/// accepted where the bound itself is above a third of 1 % (no unbiased fit can do better;
/// the dyno's k, see docs/results.md) if it is within 3 bounds.
#[test]
#[ignore]
fn noise_study_scatter_matches_reported_std_and_crb() {
    let n = seeds();
    let chi2 = |z: f64| {
        let n = n as f64;
        n * (1.0 - 2.0 / (9.0 * n) + z * (2.0 / (9.0 * n)).sqrt()).powi(3)
    };
    let (lo, hi) = (
        (chi2(-2.576) / n as f64).sqrt(),
        (chi2(2.576) / n as f64).sqrt(),
    );
    println!("{n} seeds; 99 % interval of rms/std: {lo:.2} to {hi:.2}");
    println!(
        "bench  snr  param  mean error %  rms error %  max error %  reported std %  CRB %  rms/std  rms/CRB  std/CRB"
    );
    let mut failures = Vec::new();
    // `BENCH=dyno` or `BENCH=shaker` runs one of the two.
    let only = std::env::var("BENCH").unwrap_or_default();
    for b in benches()
        .into_iter()
        .filter(|b| b.name.contains(only.as_str()))
    {
        for snr in [30.0, 40.0] {
            let np = b.truth.len();
            let (mut err, mut std, mut bound) = (
                vec![Vec::new(); np],
                vec![Vec::new(); np],
                vec![Vec::new(); np],
            );
            for seed in 0..n {
                let rec = (b.run)(Some(snr), seed).simulate().unwrap();
                for (j, v) in crb(&b, &rec, snr).into_iter().enumerate() {
                    bound[j].push(v);
                }
                let id =
                    identify(&model(b.model), &(b.setup)(), Method::OutputError, &rec).unwrap();
                for (j, (p, t)) in id.parameters.iter().zip(&b.truth).enumerate() {
                    err[j].push(p.value - t);
                    std[j].push(p.std);
                }
            }
            let rms = |v: &Vec<f64>| (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt();
            let mean = |v: &Vec<f64>| v.iter().sum::<f64>() / v.len() as f64;
            for j in 0..np {
                let t = b.truth[j];
                let (e, sd, cr) = (rms(&err[j]), mean(&std[j]), mean(&bound[j]));
                let worst = err[j].iter().fold(0.0f64, |a, v| a.max(v.abs()));
                println!(
                    "{:<11}  {snr:>3}  {:<5}  {:>12.4}  {:>11.4}  {:>11.4}  {:>14.4}  {:>5.4}  {:>7.3}  {:>7.3}  {:>7.3}",
                    b.name,
                    b.names[j],
                    100.0 * mean(&err[j]) / t,
                    100.0 * e / t,
                    100.0 * worst / t,
                    100.0 * sd / t,
                    100.0 * cr / t,
                    e / sd,
                    e / cr,
                    sd / cr
                );
                if snr == 30.0
                    && worst / t.abs() >= 0.01
                    && (cr / t.abs() < 0.01 / 3.0 || worst > 3.0 * cr)
                {
                    failures.push(format!("{} {}: error {worst}", b.name, b.names[j]));
                }
                if (sd / cr - 1.0).abs() >= 0.2 {
                    failures.push(format!(
                        "{} {snr} dB {}: std/CRB {}",
                        b.name,
                        b.names[j],
                        sd / cr
                    ));
                }
                if !(lo..hi).contains(&(e / sd)) {
                    failures.push(format!(
                        "{} {snr} dB {}: rms/std {}",
                        b.name,
                        b.names[j],
                        e / sd
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A friction variant under a displacement drive: the dyno's damper with Stribeck seal
/// friction (breakaway 60 N, kinetic 40 N at 0.01 m/s) and the model `damper` plus the Stribeck
/// excess. fd-multi leaves out the slow part of each reversal, where the excess acts; output
/// error fits the force along the whole stroke and returns the truth noise-free.
#[test]
fn stribeck_friction_on_the_dyno_is_recovered_noise_free() {
    let vs = 0.01;
    let base = RunSpec::damper_dyno(None, 0);
    let truth = TruthElement {
        friction: Some(Friction {
            breakaway_n: 60.0,
            kinetic_n: 40.0,
            stribeck_velocity_mps: vs,
            stribeck_exponent: 2.0,
            asymmetry: 0.0,
        }),
        ..base.element.clone()
    };
    let rec = base.with_element(truth).simulate().unwrap();
    let m = model("damper").with_terms(
        "damper-stribeck",
        &[Arc::new(StribeckVelocity::gaussian(vs)) as Arc<dyn Term>],
    );
    let mut want = dyno_truth();
    want.push(20.0);
    let oe = identify(&m, &dyno_setup(), Method::OutputError, &rec).unwrap();
    let fdm = identify(&m, &dyno_setup(), Method::FdMulti, &rec).unwrap();
    println!(
        "fd-multi {:?}\noutput-error {:?}",
        relative_errors(&fdm, &want),
        relative_errors(&oe, &want)
    );
    assert!(max_abs(&relative_errors(&oe, &want)) < 1e-6);
}
