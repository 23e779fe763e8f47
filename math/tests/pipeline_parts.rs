//! Steps analysed and records validated on several cores are what one loop gives, bit for bit
//! and in order: `analyse_sine_steps` and `validate_rig_on_random_records` against the same
//! work record by record (`analyse_sine_step`, `validate_rig`), on a run long enough to be split.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_math::model::IdentifiedModel;
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline;
use forcemap_math::recipe::ModelSpec;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::RunSpec;

/// The paper's run at 40 dB, 16 times over (the steps numbered on): 250 000 samples.
fn long_run() -> Vec<Record> {
    let run = RunSpec::paper_rig(Some(40.0), 4).simulate().unwrap();
    let mut out = Vec::new();
    for k in 0..16 {
        out.extend(run.iter().map(|r| Record {
            step: r.step + k * run.len(),
            ..r.clone()
        }));
    }
    out
}

#[test]
fn analyses_and_validations_in_parts_are_those_of_one_loop() {
    let records = long_run();
    let options = PhasorOptions::for_identification();
    let (analyses, notes) = pipeline::analyse_sine_steps(&records, &options).unwrap();
    let mut one_by_one = Vec::new();
    let mut one_by_one_notes = Vec::new();
    for r in records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
    {
        let (an, note) = pipeline::analyse_sine_step(r, &options).unwrap();
        one_by_one.push(an);
        one_by_one_notes.extend(note);
    }
    assert_eq!(analyses.len(), 16 * 10);
    assert!(format!("{analyses:?}") == format!("{one_by_one:?}"));
    assert_eq!(notes, one_by_one_notes);

    let model = "coulomb".parse::<ModelSpec>().unwrap().build().unwrap();
    let fitted = IdentifiedModel::new(model, vec![6300.0, 185.0, 12.0]);
    let validations = pipeline::validate_rig_on_random_records(&fitted, 36.0, &records).unwrap();
    let one_by_one: Vec<_> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        .map(|r| pipeline::validate_rig(&fitted, 36.0, r).unwrap())
        .collect();
    assert_eq!(validations.len(), 16 * 2);
    assert!(format!("{validations:?}") == format!("{one_by_one:?}"));
}
