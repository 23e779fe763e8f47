//! The names `series_compliance` and `drift` on the wide forms' world: a damper in series with a spring is named
//! series_compliance with its spring and damper, a damper whose damping fades with the energy it
//! dissipated is named drift with its rate per minute and per kJ, and a run without either is
//! given neither name.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how they report failure"
)]

mod common;

use forcemap_eval::diagnose_eval::world::{Term, WorldEffect, WorldKind};
use forcemap_math::diagnose::{Diagnosis, Effect, Verdict, drift};
use forcemap_math::record::{Channel, Record};
use forcemap_math::signal::differentiate::central_difference_at_rate;
use forcemap_math::sim::rig::PAPER_RIG_MASS_KG;

/// The paper's rig damping [N s/m] (the base damper both new effects act on).
const RIG_C: f64 = 184.0;

/// The world with `term` (none: the paper's rig alone) at 30 dB against the Coulomb baseline:
/// its diagnosis and records.
fn diagnosed(name: &'static str, term: Option<Term>, seed: u64) -> (Diagnosis, Vec<Record>) {
    let effects: Vec<WorldEffect> = term
        .map(|t| WorldEffect::of_terms(name, WorldKind::NewName, [Some(t), None]))
        .into_iter()
        .collect();
    let (d, run) = common::diagnose_world(name, &effects, 30.0, seed);
    (d, run.records)
}

fn parameter(d: &Diagnosis, name: &str) -> f64 {
    d.ranked_effects[0]
        .added_parameters
        .iter()
        .find(|p| p.name == name)
        .map(|p| p.value)
        .unwrap()
}

#[test]
fn a_damper_in_series_with_a_spring_is_named_series_compliance_with_its_spring() {
    let ks = 3000.0;
    let (d, _) = diagnosed(
        "series_compliance",
        Some(Term::SeriesCompliance {
            damping_n_s_per_m: RIG_C,
            stiffness_n_per_m: ks,
        }),
        61,
    );
    assert_eq!(d.findings.verdict, Verdict::Explained, "{d:#?}");
    assert_eq!(d.findings.top_effect, Some(Effect::SeriesCompliance));
    let member = d.findings.top_member.clone().unwrap();
    assert!(d.findings.headline().ends_with(&format!("({member})")));
    // The series spring within 10 % and the damper within 5 % of the world's.
    let tau = parameter(&d, "relaxation_s");
    let fitted_ks = parameter(&d, "series_stiffness_n_per_m");
    let c = fitted_ks * tau;
    assert!((c / RIG_C - 1.0).abs() < 0.05, "c {c} ({member})");
    assert!(
        (fitted_ks / ks - 1.0).abs() < 0.1,
        "ks {fitted_ks} ({member})"
    );
}

/// The integral of the squared relative velocity over the run's records [m^2/s].
fn v2_integral(records: &[Record]) -> f64 {
    records
        .iter()
        .map(|r| {
            let fs = r.sample_rate_hz;
            let x = r.channel(Channel::RelativeDisplacementM).unwrap();
            central_difference_at_rate(x, fs)
                .iter()
                .map(|v| v * v / fs)
                .sum::<f64>()
        })
        .sum()
}

#[test]
fn a_damper_that_fades_as_it_dissipates_is_named_drift_with_its_rate() {
    // 20 % fade over a run that dissipates about 150 J in the damper.
    let fade_per_j = 0.2 / 150.0;
    let (d, records) = diagnosed(
        "drift",
        Some(Term::Drift {
            damping_n_s_per_m: RIG_C,
            fade_per_j,
            energy_at_start_j: 0.0,
        }),
        62,
    );
    assert_eq!(d.findings.verdict, Verdict::Explained, "{d:#?}");
    assert_eq!(d.findings.top_effect, Some(Effect::Drift));
    let member = d.findings.top_member.clone().unwrap();
    assert!(
        member.contains("%/min") && member.contains("%/kJ"),
        "{member}"
    );
    assert!(d.findings.headline().ends_with(&format!("({member})")));
    // The world's damping at the end of the run is c0 exp(-fade c0 I) (I the integral of the
    // squared relative velocity); the fitted line's change over the run within 30 % of it
    // (a fade with energy is not linear in time: the later, faster steps dissipate more).
    let truth = -(-(fade_per_j * RIG_C * v2_integral(&records))).exp_m1();
    let run = drift::run_dissipation(&records, PAPER_RIG_MASS_KG).unwrap();
    let rate = parameter(&d, "drift_per_s");
    let end_s = records
        .iter()
        .map(|r| r.start_time_s + r.len() as f64 / r.sample_rate_hz)
        .fold(0.0, f64::max);
    let fitted = -rate * end_s;
    println!("fade over the run: fitted {fitted:.3}, world {truth:.3}; {run:?}");
    assert!((fitted / truth - 1.0).abs() < 0.3, "{fitted} vs {truth}");
}

#[test]
fn a_run_without_either_is_given_neither_name() {
    for seed in [63, 64] {
        let (d, _) = diagnosed("none", None, seed);
        assert!(
            !matches!(
                d.findings.top_effect,
                Some(Effect::SeriesCompliance | Effect::Drift)
            ) || d.findings.verdict != Verdict::Explained,
            "{d:#?}"
        );
        assert_ne!(d.findings.verdict, Verdict::Explained, "{d:#?}");
    }
}
