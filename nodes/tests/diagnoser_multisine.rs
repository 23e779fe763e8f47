//! The diagnoser's state machine on periodic multisine steps, without DDS: the force-driven
//! cubic single DOF's sine steps and multisine realisations (each multisine's lines found on
//! the driven channel its ExcitationState names, as the identifier finds them) give live the
//! findings of the offline phasor diagnosis on the same records (`forcemap diagnose`'s
//! element path): the same ranking, errors and verdict, cubic_stiffness named against a linear
//! baseline.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::params::ParamValue;
use forcemap_math::diagnose::{Effect, PhasorDiagnosis, PhasorFindings};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{MultisineOptions, PhasorOptions, analyse_multisine, analyse_record};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::RunSpec;
use forcemap_msgs::msg::GapDiagnosis;
use forcemap_nodes::node::diagnoser::{DiagnoserCore, Output};
use forcemap_nodes::node::setup_gate::Input;

mod common;

use common::*;

/// Sine steps 0-3 of the shaker's grid, then its two multisine realisations (30 dB),
/// renumbered and placed one after the other in time.
fn run() -> Vec<Record> {
    let sines = RunSpec::shaker_sdof(Some(30.0), 5).simulate().unwrap();
    let multisines = RunSpec::shaker_sdof_multisine(Some(30.0), 5)
        .simulate()
        .unwrap();
    one_run(sines[..4].iter().chain(&multisines[..2]))
}

fn offline(records: &[Record]) -> PhasorFindings {
    let mut d = PhasorDiagnosis::new(
        Setup::Element {
            moving_mass_kg: None,
            drive: None,
        },
        Model::by_name("linear", &ModelOptions::default()).unwrap(),
    );
    for r in records {
        match r.excitation {
            Excitation::Multisine { .. } => {
                d.push_multisine(analyse_multisine(r, &MultisineOptions::default()).unwrap());
            }
            _ => d.push(analyse_record(r, &PhasorOptions::for_identification()).unwrap()),
        }
    }
    d.findings().unwrap()
}

fn live(records: &[Record]) -> (Vec<GapDiagnosis>, Vec<String>) {
    let p = params(&[("baseline", ParamValue::String("linear".into()))]);
    let mut core = DiagnoserCore::from_params(&p, "/shaker/diagnoser: gap diagnosis").unwrap();
    let mut out = Vec::new();
    for r in records {
        let (state, ph) = step_messages(r);
        if let Some(s) = state {
            out.extend(
                core.handle(Input::Excitation(Box::new(s)), RUN_START)
                    .unwrap(),
            );
        }
        out.extend(
            core.handle(Input::Phasors(Box::new(ph)), RUN_START)
                .unwrap(),
        );
    }
    let mut diagnoses = Vec::new();
    let mut logs = Vec::new();
    for o in out {
        match o {
            Output::Diagnosis(d) => diagnoses.push(d),
            Output::Log(l) => logs.push(l),
            Output::Status(_) => {}
        }
    }
    (diagnoses, logs)
}

#[test]
fn multisine_steps_live_give_the_offline_findings() {
    let records = run();
    let (diagnoses, logs) = live(&records);
    // A diagnosis after sine steps 3 and 4 (three sine steps and more), then after each
    // multisine: nothing skipped.
    assert!(
        !logs
            .iter()
            .any(|l| l.contains("skipped") || l.contains("refused")),
        "{logs:?}"
    );
    let last = diagnoses.last().unwrap();
    assert_eq!(last.steps, 6);
    let want = offline(&records);
    assert_eq!(want.multisine_steps, 2);
    assert_eq!(want.findings.top_effect, Some(Effect::CubicStiffness));
    assert_eq!(last.verdict, want.findings.verdict.name());
    assert_eq!(last.top_effect, "cubic_stiffness");
    let names: Vec<&str> = want
        .ranked_effects
        .iter()
        .map(|e| e.effect.name())
        .collect();
    assert_eq!(last.ranked_effects, names);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-12);
    assert!(close(
        last.gap_before_percent,
        want.findings.gap_before_percent
    ));
    assert!(close(last.noise_floor_percent, want.findings.floor_percent));
    for (a, e) in last
        .ranked_gap_after_percent
        .iter()
        .zip(&want.ranked_effects)
    {
        assert!(
            close(*a, e.cv_percent),
            "{}: live {a} offline {}",
            e.effect.name(),
            e.cv_percent
        );
    }
    // The one diagnosis before the first multisine is the sine steps' own.
    let before = &diagnoses[diagnoses.len() - 3];
    assert_eq!(before.steps, 4);
    assert!(!close(before.gap_before_percent, last.gap_before_percent));
}
