//! The phasor diagnosis on periodic multisine records against the truth of the element
//! simulator: a force-driven single DOF with cubic stiffness (the shaker of
//! `forcemap simulate --system shaker-sdof --excitation multisine`, three random-odd
//! realisations at 30 dB, its moving mass fitted with every model) diagnosed against a linear
//! baseline names cubic_stiffness and shrinks the cross-validated gap to near its floor; the
//! same system without the cubic spring is called adequate (no false alarm); and sine steps
//! beside the multisines are fitted with them.

use forcemap_math::diagnose::{Effect, PhasorDiagnosis, PhasorFindings, Verdict};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{MultisineOptions, PhasorOptions, analyse_multisine, analyse_record};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::{RunSpec, TruthElement};

const SNR_DB: f64 = 30.0;

/// The shaker's multisine run with a third realisation (the validation record dropped).
fn shaker_run(element: Option<TruthElement>, seed: u64) -> Vec<Record> {
    let mut spec = RunSpec::shaker_sdof_multisine(Some(SNR_DB), seed);
    spec.steps.truncate(2);
    spec.steps.push(spec.steps[0].clone());
    if let Some(e) = element {
        spec = spec.with_element(e);
    }
    spec.simulate().expect("the shaker run simulates")
}

fn diagnose(records: &[Record], baseline: &str) -> PhasorFindings {
    let model = Model::by_name(baseline, &ModelOptions::default()).expect("a model");
    let mut d = PhasorDiagnosis::new(
        Setup::Element {
            moving_mass_kg: None,
            drive: None,
        },
        model,
    );
    for r in records {
        match r.excitation {
            Excitation::Multisine { .. } => d.push_multisine(
                analyse_multisine(r, &MultisineOptions::default()).expect("a multisine"),
            ),
            Excitation::Sine { .. } => {
                d.push(analyse_record(r, &PhasorOptions::for_identification()).expect("a step"));
            }
            _ => {}
        }
    }
    d.findings().expect("findings")
}

fn print(f: &PhasorFindings) {
    println!(
        "{} ({} steps, {} multisine; gap {:.3} %, floor {:.3} %)",
        f.findings.headline(),
        f.steps,
        f.multisine_steps,
        f.findings.gap_before_percent,
        f.findings.floor_percent
    );
    for r in &f.ranked_effects {
        println!(
            "  {:<20} cv {:8.3} % score {:8.3} % {}",
            r.effect.name(),
            r.cv_percent,
            r.score_percent,
            r.significant
        );
    }
}

#[test]
fn a_cubic_spring_is_named_on_three_multisine_realisations() {
    let f = diagnose(&shaker_run(None, 1), "linear");
    print(&f);
    assert_eq!((f.steps, f.multisine_steps), (3, 3));
    assert_eq!(f.findings.verdict, Verdict::Explained);
    assert_eq!(f.findings.top_effect, Some(Effect::CubicStiffness));
    let top = &f.ranked_effects[0];
    // The planted 5e7 N/m^3, fitted on every realisation with the mass.
    let s = top
        .added_parameters
        .iter()
        .find(|p| p.name == "s")
        .expect("the cubic coefficient");
    assert!((s.value / 5.0e7 - 1.0).abs() < 0.02, "s = {}", s.value);
    // The truth leaves the noise: the gap shrinks to within 1.5 times its floor.
    assert!(
        top.cv_percent < 1.5 * f.findings.floor_percent,
        "{} % left, floor {} %",
        top.cv_percent,
        f.findings.floor_percent
    );
    assert!(f.findings.gap_before_percent > 5.0 * f.findings.floor_percent);
    // Candidates whose state the per-line equations do not hold are listed with the reason,
    // not silently dropped.
    assert!(
        f.dropped
            .iter()
            .any(|d| d.effect == Effect::Hysteresis && d.reason.contains("Bouc-Wen")),
        "{:?}",
        f.dropped
    );
    // A constant force has no equation here (the multisine equations start at the first bin).
    assert!(
        f.dropped
            .iter()
            .any(|d| d.effect == Effect::Preload && d.reason.contains("cannot identify")),
        "{:?}",
        f.dropped
    );
}

#[test]
fn the_linear_truth_is_adequate_on_multisines() {
    let linear = TruthElement::linear(2.0e4, 60.0);
    for seed in [1, 2] {
        let f = diagnose(&shaker_run(Some(linear.clone()), seed), "linear");
        print(&f);
        assert_eq!(f.findings.verdict, Verdict::Adequate, "seed {seed}");
        assert!(f.findings.gap_before_percent < 1.5 * f.findings.floor_percent);
    }
}

#[test]
fn the_true_model_is_adequate_and_two_realisations_suffice() {
    let mut records = shaker_run(None, 3);
    records.truncate(2);
    let f = diagnose(&records, "cubic");
    print(&f);
    assert_eq!(f.steps, 2);
    assert_eq!(f.findings.verdict, Verdict::Adequate);
    // One realisation alone cannot be cross-validated.
    let mut one = PhasorDiagnosis::new(
        Setup::Element {
            moving_mass_kg: None,
            drive: None,
        },
        Model::by_name("linear", &ModelOptions::default()).expect("a model"),
    );
    one.push_multisine(analyse_multisine(&records[0], &MultisineOptions::default()).unwrap());
    assert_eq!(one.min_steps(), 2);
    assert!(one.findings().is_err());
}

#[test]
fn sine_steps_beside_multisines_are_fitted_with_them() {
    // The shaker's stepped sine (12 steps) and its two multisine realisations, renumbered.
    let mut records = RunSpec::shaker_sdof(Some(SNR_DB), 4)
        .simulate()
        .expect("the stepped shaker run");
    records.truncate(6);
    let n = records.len();
    for (i, mut r) in shaker_run(None, 4).into_iter().take(2).enumerate() {
        r.step = n + i;
        records.push(r);
    }
    let f = diagnose(&records, "linear");
    print(&f);
    assert_eq!((f.steps, f.multisine_steps), (8, 2));
    assert_eq!(f.findings.top_effect, Some(Effect::CubicStiffness));
    assert_eq!(f.findings.verdict, Verdict::Explained);
}
