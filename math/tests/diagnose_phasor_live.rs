//! The live phasor-only diagnosis on the run of the committed bag `bags/rig_40db` (the paper's
//! Coulomb rig, stepped sine, 40 dB, seed 1), simulated here (math does no I/O): the true
//! model is adequate, the linear one is explained by Coulomb friction.

use forcemap_math::diagnose::{Effect, PhasorDiagnosis, Verdict};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::recipe::Setup;
use forcemap_math::record::Excitation;
use forcemap_math::sim::RunSpec;

#[test]
fn live_diagnosis_of_the_rig_bag_run() {
    let records = RunSpec::paper_rig_sine(Some(40.0), 1).simulate().unwrap();
    let popts = PhasorOptions::for_identification();
    let analyses: Vec<_> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        .map(|r| analyse_record(r, &popts).unwrap())
        .collect();
    assert!(analyses.len() >= 10, "{} sine steps", analyses.len());
    for (baseline, verdict, top) in [
        ("coulomb", Verdict::Adequate, None),
        ("linear", Verdict::Explained, Some(Effect::CoulombFriction)),
    ] {
        let model = Model::by_name(baseline, &ModelOptions::default()).unwrap();
        let mut live = PhasorDiagnosis::new(Setup::BaseExcited { mass_kg: 36.0 }, model);
        for a in &analyses {
            live.push(a.clone());
        }
        let f = live.findings().unwrap();
        println!(
            "{baseline}: {:?} {:?} ({:.2} % -> {:.2} %, floor {:.2} %); ranked: {}",
            f.findings.verdict,
            f.findings.top_effect,
            f.findings.gap_before_percent,
            f.findings.gap_after_percent,
            f.findings.floor_percent,
            f.ranked_effects
                .iter()
                .map(|r| format!("{} {:.2}", r.effect.name(), r.cv_percent))
                .collect::<Vec<_>>()
                .join(", ")
        );
        assert_eq!(
            (f.findings.verdict, f.findings.top_effect),
            (verdict, top),
            "{baseline}"
        );
    }
}
