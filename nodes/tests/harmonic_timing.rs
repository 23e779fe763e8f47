//! The harmonic node reads times by the rule files are read by (`forcemap_io::steps::timing`):
//! finding steps, a run that pauses between steps is cut at its pauses; with excitation
//! states, a sample lost in the middle of a step makes it two records, analysed, with a
//! warning, not a step dropped.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::time::{Duration, Instant};

use forcemap_io::rig_bag::DEFAULT_RUN_START;
use forcemap_io::rig_messages::{RigMessage, rig_messages};
use forcemap_math::phasor::{HarmonicAnalysis, PhasorOptions, analyse_record};
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::RunSpec;
use forcemap_nodes::node::harmonic::{HarmonicState, Input, Outcome};

/// The outcomes' analyses, and their warnings; a dropped step fails the test.
fn analyses(out: Vec<Outcome>, options: &PhasorOptions) -> (Vec<HarmonicAnalysis>, Vec<String>) {
    let (mut done, mut warnings) = (Vec::new(), Vec::new());
    for o in out {
        match o {
            Outcome::Analyse(a, _) => done.push(a.run(options).unwrap()),
            Outcome::Warning(w) => warnings.push(w),
            Outcome::Dropped(e) => panic!("step dropped: {e}"),
            Outcome::Skipped(..) | Outcome::Provisional(..) => {}
        }
    }
    (done, warnings)
}

/// The phasors of `got` are those of `want` (the amplitude and step number aside; the stamps'
/// nanoseconds move the phase reference by about 1e-8 relative).
fn assert_same(want: &HarmonicAnalysis, got: &HarmonicAnalysis) {
    assert_eq!(got.frequency_hz, want.frequency_hz);
    let got = HarmonicAnalysis {
        step: want.step,
        amplitude: want.amplitude,
        ..got.clone()
    };
    let d = want.relative_difference(&got);
    assert!(d.is_some_and(|d| d < 1e-6), "step {}: {d:?}", want.step);
}

/// The paper rig's ten sine steps (40 dB) sent with no excitation state, each step 0.5 s after
/// the last (a bench that pauses between steps): each step is found, with the phasors of its
/// record.
#[test]
fn finding_steps_a_run_is_cut_at_its_pauses() {
    let options = PhasorOptions::for_identification();
    let records = RunSpec::paper_rig_sine(Some(40.0), 1).simulate().unwrap();
    let paused: Vec<Record> = records
        .iter()
        .map(|r| Record {
            start_time_s: r.start_time_s + 0.5 * r.step as f64,
            ..r.clone()
        })
        .collect();
    let mut state = HarmonicState::with_options(options.clone())
        .finding_steps()
        .unwrap();
    let t = Instant::now();
    let mut out = Vec::new();
    for m in rig_messages(
        &paused,
        Channel::BaseDisplacementM,
        None,
        DEFAULT_RUN_START,
        "rig",
    ) {
        if let RigMessage::Sample(s) = m {
            out.extend(state.handle(Input::Sample(s), t));
        }
    }
    out.extend(state.handle(Input::Tick, t + Duration::from_secs(10)));
    let (got, warnings) = analyses(out, &options);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(got.len(), records.len());
    for (r, g) in paused.iter().zip(&got) {
        assert_same(&analyse_record(r, &options).unwrap(), g);
    }
}

/// The paper rig with its excitation states (each counting 1300 samples), one sample of step 3
/// lost: step 3 is two records, each analysed, with a warning naming the lost sample; the other
/// steps are analysed as their records.
#[test]
fn with_states_a_lost_sample_makes_two_records() {
    let options = PhasorOptions::for_identification();
    let records = RunSpec::paper_rig_sine(Some(40.0), 1).simulate().unwrap();
    let mut state = HarmonicState::with_options(options.clone());
    let t = Instant::now();
    let mut out = Vec::new();
    let mut index = 0usize;
    for m in rig_messages(
        &records,
        Channel::BaseDisplacementM,
        None,
        DEFAULT_RUN_START,
        "rig",
    ) {
        match m {
            RigMessage::Excitation(e) => {
                index = 0;
                out.extend(state.handle(Input::Excitation(e), t));
            }
            RigMessage::Sample(s) => {
                index += 1;
                if !(s.step == 3 && index == 601) {
                    out.extend(state.handle(Input::Sample(s), t));
                }
            }
            RigMessage::Parameters(_) => {}
        }
    }
    out.extend(state.handle(Input::Tick, t + Duration::from_secs(10)));
    let (got, warnings) = analyses(out, &options);
    assert_eq!(
        warnings,
        [
            "step 3, sample 600: 1 sample lost (an interval of 0.020000 s where the samples around are 0.010000 s apart): the step goes on in another record from there"
        ]
    );
    assert_eq!(got.len(), records.len() + 1);
    let split = |r: &Record, range: std::ops::Range<usize>, step: usize| Record {
        step,
        start_time_s: r.time_s(range.start),
        channels: r
            .channels
            .iter()
            .map(|(c, x)| (*c, x[range.clone()].to_vec()))
            .collect(),
        ..r.clone()
    };
    let mut want: Vec<Record> = records[..3].to_vec();
    want.push(split(&records[3], 0..600, 3));
    want.push(split(&records[3], 601..1300, 4));
    want.extend(records[4..].iter().cloned());
    for (r, g) in want.iter().zip(&got) {
        assert_same(&analyse_record(r, &options).unwrap(), g);
    }
}
