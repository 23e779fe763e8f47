//! The harmonic node without `ExcitationState` (`find_steps`): the committed paper-rig bag
//! (the simulated rig, 10 stepped-sine steps then two random records, 40 dB) fed sample by
//! sample with no excitation state and no step numbers gives the phasors the node gives with
//! the excitation states, and holds a bounded number of samples.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::PathBuf;
use std::time::{Duration, Instant};

use forcemap_io::bag::BagReader;
use forcemap_io::rig_messages::{RigMessage, rig_messages};
use forcemap_io::topics::{RIG_EXCITATION, RIG_SAMPLES};
use forcemap_math::phasor::{
    HarmonicAnalysis, PhasorOptions, PhasorStream, ProvisionalUpdates, provisional_analyses,
    provisional_analysis,
};
use forcemap_math::record::{Channel, Record};
use forcemap_math::segment::SegmentOptions;
use forcemap_math::sim::{ElementDrive, RunSpec, StepSpec};
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::node::harmonic::find_steps::StepFinder;
use forcemap_nodes::node::harmonic::{Analysis, HarmonicState, Input, Outcome, RUN_END_SILENCE};

fn bag(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../bags")
        .join(name)
}

fn samples(name: &str) -> Vec<RigSample> {
    let reader = BagReader::open(bag(name)).unwrap();
    reader
        .messages_on(&[RIG_SAMPLES])
        .unwrap()
        .map(|m| RigSample::from_cdr(&m.unwrap().data).unwrap())
        .collect()
}

/// The analyses an outcome list holds (a dropped step fails the test), and how many records
/// were skipped (random).
fn analyses(out: Vec<Outcome>, options: &PhasorOptions) -> (Vec<HarmonicAnalysis>, Vec<String>) {
    let mut skipped = Vec::new();
    let mut done = Vec::new();
    for o in out {
        match o {
            Outcome::Analyse(a, _) => done.push(a.run(options).unwrap()),
            Outcome::Skipped(step, why) => skipped.push(format!("{step}: {why}")),
            Outcome::Dropped(e) => panic!("step dropped: {e}"),
            Outcome::Warning(w) => panic!("{w}"),
            Outcome::Provisional(..) => panic!("no provisional phasors were asked for"),
        }
    }
    (done, skipped)
}

/// The analyses with the bag's excitation states, and without them (no step numbers either):
/// (with, without, skipped with, skipped without, steps out before the run ended, most samples
/// held).
type Compared = (
    Vec<HarmonicAnalysis>,
    Vec<HarmonicAnalysis>,
    Vec<String>,
    Vec<String>,
    usize,
    usize,
);

fn with_and_without_states(name: &str, options: &PhasorOptions) -> Compared {
    let t = Instant::now();
    let samples = samples(name);

    let mut labelled = HarmonicState::with_options(options.clone());
    let mut out = Vec::new();
    let reader = BagReader::open(bag(name)).unwrap();
    for m in reader.messages_on(&[RIG_EXCITATION]).unwrap() {
        let s = ExcitationState::from_cdr(&m.unwrap().data).unwrap();
        out.extend(labelled.handle(Input::Excitation(s), t));
    }
    for s in &samples {
        out.extend(labelled.handle(Input::Sample(s.clone()), t));
    }
    let (want, want_skipped) = analyses(out, options);

    let mut found = HarmonicState::with_options(options.clone())
        .finding_steps()
        .unwrap();
    let mut out = Vec::new();
    let mut most_held = 0;
    for s in &samples {
        // A bench without forcemap's step counter.
        let s = RigSample {
            step: 0,
            ..s.clone()
        };
        out.extend(found.handle(Input::Sample(s), t));
        most_held = most_held.max(found.buffered_samples().unwrap());
    }
    // Each sine step is out once the next has begun, before the run ends.
    let before_end = out.len();
    // The run ends: no sample for a while, and the last step completes. A pause of 4 s (a
    // reliable writer repairing a lost sample) is not yet the end.
    out.extend(found.handle(Input::Tick, t + Duration::from_secs(1)));
    out.extend(found.handle(Input::Tick, t + RUN_END_SILENCE - Duration::from_secs(1)));
    assert_eq!(out.len(), before_end, "the run has not ended yet");
    out.extend(found.handle(Input::Tick, t + Duration::from_secs(10)));
    assert_eq!(found.buffered_samples(), Some(0));
    let (got, got_skipped) = analyses(out, options);
    (want, got, want_skipped, got_skipped, before_end, most_held)
}

/// The phasors of every sine step without states are those with them (the step number and the
/// programmed amplitude aside); the largest relative difference.
fn assert_same_phasors(name: &str, want: &[HarmonicAnalysis], got: &[HarmonicAnalysis]) -> f64 {
    assert_eq!(got.len(), want.len(), "{name}");
    let mut worst = 0.0_f64;
    for (w, g) in want.iter().zip(got) {
        assert_eq!(g.frequency_hz, w.frequency_hz, "{name} step {}", w.step);
        // The programmed amplitude and the step number are the excitation state's; without it
        // the amplitude is estimated (sqrt 2 times the RMS) and the steps counted from 0.
        let g = HarmonicAnalysis {
            step: w.step,
            amplitude: w.amplitude,
            ..g.clone()
        };
        let d = w.relative_difference(&g);
        assert!(
            d.is_some_and(|d| d < 1e-6),
            "{name} step {}: {d:?}\n{w:?}\n{g:?}",
            w.step
        );
        worst = worst.max(d.unwrap_or(f64::NAN));
    }
    worst
}

#[test]
fn without_excitation_states_the_phasors_are_those_with_them() {
    let options = PhasorOptions::for_identification();
    let (want, got, want_skipped, got_skipped, before_end, most_held) =
        with_and_without_states("rig_40db", &options);
    assert_eq!(want.len(), 10);
    assert!(before_end >= 10, "{before_end} steps out before the end");
    println!("skipped with states: {want_skipped:?}; without: {got_skipped:?}");
    // The random records give no phasors either way; without states they are cut where the
    // live segmentation sees a change (not at their labelled boundary), but cover the same
    // 2 x 1300 samples.
    let random_samples = |skipped: &[String]| -> usize {
        skipped
            .iter()
            .map(|w| {
                let n = w.split("random record of ").nth(1).unwrap();
                n.split(' ').next().unwrap().parse::<usize>().unwrap()
            })
            .sum()
    };
    assert_eq!(random_samples(&want_skipped), 2600);
    assert_eq!(random_samples(&got_skipped), 2600);
    let worst = assert_same_phasors("rig_40db", &want, &got);
    // Memory: about two steps' samples (1300 each) plus the search's growth, never the run.
    assert!(most_held < 4000, "held {most_held} of 15600 samples");
    println!(
        "rig_40db: {} steps, largest relative difference {worst:e}, at most {most_held} samples held",
        got.len(),
    );
}

/// The 3-DOF example (noise-free, steps of force amplitude at one frequency): the driven
/// channel is the force.
#[test]
fn three_dof_bags_without_excitation_states() {
    let options = PhasorOptions::for_identification();
    for name in ["three_dof_case_i", "three_dof_case_ii"] {
        let (want, got, want_skipped, got_skipped, before_end, most_held) =
            with_and_without_states(name, &options);
        assert!(want.len() >= 5, "{name}: {} steps", want.len());
        assert!(want_skipped.is_empty() && got_skipped.is_empty(), "{name}");
        // Every step but the last is out before the run ends.
        assert!(
            before_end + 1 >= want.len(),
            "{name}: {before_end} before the end"
        );
        let worst = assert_same_phasors(name, &want, &got);
        println!(
            "{name}: {} steps, largest relative difference {worst:e}, at most {most_held} samples held",
            got.len()
        );
    }
}

/// A drive that never changes fills the buffer: it is dropped as one step at the limit, with
/// a message saying why, and the finder starts again.
#[test]
fn a_buffer_without_a_boundary_is_dropped_at_its_limit() {
    let mut f = StepFinder::new(SegmentOptions::default(), 1000);
    let mut errors = Vec::new();
    for k in 0..2500i64 {
        let s = RigSample::new(Header::new(Time::from_nanos(k * 10_000_000), "rig"), 0)
            .with(Channel::BaseDisplacementM, (k as f64 * 0.2).sin())
            .with(Channel::RelativeDisplacementM, 0.1 * (k as f64 * 0.2).cos())
            .with(Channel::MassAccelerationMps2, (k as f64 * 0.2).sin());
        for r in f.push(&s) {
            errors.push(r.into_step().unwrap().unwrap_err());
        }
        assert!(f.buffered() < 1000);
    }
    assert_eq!(errors.len(), 2);
    assert!(
        errors[0]
            .problem
            .contains("no step boundary found in 1000 samples"),
        "{}",
        errors[0].problem
    );
    // What is left is one sine step.
    let rest: Vec<_> = f
        .finish()
        .into_iter()
        .map(|r| r.into_step().unwrap())
        .collect();
    assert_eq!(rest.len(), 1);
    assert_eq!(rest[0].as_ref().unwrap().len(), 500);
}

/// Provisional phasors while the steps are found (`find_steps` with `update_period_s`): a dyno
/// run whose drive changes a little (amplitude 3 %, frequency 1 %) or a lot, at sample counts
/// that are not multiples of the update period, 30 dB. No provisional phasors hold a sample
/// of another step (each holds fewer samples than its step turns out to have), some come
/// before their step ends, and they are those the offline path gives on each found step's
/// record ([`provisional_analyses`], what `forcemap identify --update-period-s` runs).
#[test]
fn provisional_phasors_hold_only_samples_of_their_step() {
    let sine = |frequency_hz: f64, amplitude: f64| StepSpec::Sine {
        frequency_hz,
        amplitude,
    };
    let steps = vec![
        sine(2.0, 0.010),
        sine(2.0, 0.0103),
        sine(2.02, 0.0103),
        sine(5.0, 0.004),
        sine(1.3, 0.010),
        sine(1.3, 0.0097),
        sine(8.0, 0.002),
    ];
    let spec = RunSpec {
        snr_db: Some(30.0),
        seed: 12,
        ..RunSpec::element_test(
            ElementDrive::Displacement,
            0.8,
            RunSpec::damper_dyno(None, 0).element,
            steps.clone(),
            1000.0,
            9_137,
        )
    };
    let records = spec.simulate().unwrap();
    let options = PhasorOptions::for_identification();
    let update_period_s = 0.7;
    let mut state = HarmonicState::with_options(options.clone())
        .with_updates(update_period_s)
        .unwrap()
        .finding_steps()
        .unwrap();
    let t = Instant::now();
    let mut inputs: Vec<(Input, Instant)> = Vec::new();
    for m in rig_messages(&records, spec.driven_channel(), None, Time::ZERO, "rig") {
        if let RigMessage::Sample(s) = m {
            inputs.push((Input::Sample(RigSample { step: 0, ..s }), t));
        }
    }
    inputs.push((Input::Tick, t + Duration::from_secs(10)));
    // Per step: the provisional streams (and whether they came before the step closed), then
    // its record.
    let mut provisional: Vec<(PhasorStream, bool)> = Vec::new();
    let mut found: Vec<(Record, Vec<(PhasorStream, bool)>)> = Vec::new();
    for (input, at) in inputs {
        let out = state.handle(input, at);
        let closes = out.iter().any(|o| matches!(o, Outcome::Analyse(..)));
        for o in out {
            match o {
                Outcome::Provisional(s, _) => provisional.push((*s, !closes)),
                Outcome::Analyse(Analysis::Batch(r), _) => {
                    found.push((r, std::mem::take(&mut provisional)));
                }
                Outcome::Analyse(..) => panic!("found steps are analysed in batch"),
                Outcome::Warning(w) => panic!("{w}"),
                Outcome::Skipped(..) | Outcome::Dropped(_) => panic!("every step is a sine step"),
            }
        }
    }
    assert!(provisional.is_empty(), "provisional phasors of no step");
    assert_eq!(found.len(), steps.len(), "every change found");
    let mut early = 0;
    let mut closest = usize::MAX;
    // Where each found step starts in the run, and where the true steps end.
    let mut start = 0;
    let true_ends: Vec<usize> = (1..=steps.len())
        .map(|k| k * spec.samples_per_record)
        .collect();
    for (record, streams) in &found {
        // A copy given before its step closed holds no sample of the next true step (every
        // change is found: found step k is true step k, its ends within a few samples).
        let true_end = true_ends[record.step];
        for (s, before) in streams {
            assert!(
                !before || start + s.samples() <= true_end,
                "step {}: provisional phasors up to sample {} of the run, the true step ends at {true_end}",
                record.step,
                start + s.samples()
            );
            if *before {
                closest = closest.min(true_end - (start + s.samples()));
            }
        }
        start += record.len();
        let updates = ProvisionalUpdates::new(update_period_s, record.sample_rate_hz).unwrap();
        let offline = provisional_analyses(record, &options, updates).unwrap();
        let live: Vec<HarmonicAnalysis> = streams
            .iter()
            .filter_map(|(s, _)| provisional_analysis(s))
            .collect();
        for (s, before) in streams {
            assert_eq!(s.step(), record.step);
            assert!(
                s.samples() < record.len(),
                "step {}: provisional phasors of {} samples, the step has {}",
                record.step,
                s.samples(),
                record.len()
            );
            early += usize::from(*before);
        }
        assert_eq!(live.len(), offline.len(), "step {}", record.step);
        for (l, o) in live.iter().zip(&offline) {
            let l = HarmonicAnalysis {
                amplitude: o.amplitude,
                ..l.clone()
            };
            let d = o.relative_difference(&l);
            assert!(d.is_some_and(|d| d < 1e-12), "step {}: {d:?}", record.step);
        }
        println!(
            "step {}: {} samples, {:?} Hz; provisional at {:?} samples ({} before the step closed)",
            record.step,
            record.len(),
            record.excitation.frequency_hz(),
            streams.iter().map(|(s, _)| s.samples()).collect::<Vec<_>>(),
            streams.iter().filter(|(_, b)| *b).count()
        );
    }
    assert!(early > 0);
    println!(
        "{early} provisional updates before their step closed, the closest {closest} samples before the true step's end"
    );
}
