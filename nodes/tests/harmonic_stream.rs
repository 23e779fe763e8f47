//! The harmonic node's state machine fed the committed bags message by message: every sine step
//! is analysed from its stream (no batch fallback at these whole-Hz rates), and the streamed
//! analysis is the batch analysis of the record `forcemap identify` reads from the same bag
//! up to rounding. Also a rate that is not a whole number of Hz: the stream's guess is wrong,
//! the record is analysed in batch, and the result is still the batch analysis.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::Path;
use std::time::Instant;

use forcemap_io::bag::BagReader;
use forcemap_io::rig_bag::read_rig_bag;
use forcemap_io::topics::{RIG_EXCITATION, RIG_SAMPLES};
use forcemap_math::phasor::{HarmonicAnalysis, PhasorOptions, analyse_record};
use forcemap_math::record::{Channel, Excitation};
use forcemap_msgs::RosMessage;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, RigSample};
use forcemap_msgs::std_msgs::Header;
use forcemap_nodes::node::harmonic::{Analysis, HarmonicState, Input, Outcome};

/// The analyses the state machine hands out for a bag (excitation states first, as a live
/// graph gets them before their step's samples), with whether each was streamed.
fn node_analyses(bag: &Path, options: &PhasorOptions) -> Vec<(bool, HarmonicAnalysis)> {
    let reader = BagReader::open(bag).unwrap();
    let mut h = HarmonicState::with_options(options.clone());
    let t = Instant::now();
    let mut out = Vec::new();
    for m in reader.messages_on(&[RIG_EXCITATION]).unwrap() {
        let s = ExcitationState::from_cdr(&m.unwrap().data).unwrap();
        out.extend(h.handle(Input::Excitation(s), t));
    }
    for m in reader.messages_on(&[RIG_SAMPLES]).unwrap() {
        let s = RigSample::from_cdr(&m.unwrap().data).unwrap();
        out.extend(h.handle(Input::Sample(s), t));
    }
    out.into_iter()
        .filter_map(|o| match o {
            Outcome::Analyse(a, _) => {
                let streamed = a.is_streamed();
                Some((streamed, a.run(options).unwrap()))
            }
            Outcome::Skipped(..) | Outcome::Provisional(..) | Outcome::Warning(..) => None,
            Outcome::Dropped(e) => panic!("{}: step dropped: {e}", bag.display()),
        })
        .collect()
}

#[test]
fn committed_bags_stream_to_the_batch_analysis() {
    let options = PhasorOptions::for_identification();
    for name in ["rig_40db", "three_dof_case_i", "three_dof_case_ii"] {
        let bag = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../bags")
            .join(name);
        let records = read_rig_bag(&bag).unwrap().records;
        let batch: Vec<HarmonicAnalysis> = records
            .iter()
            .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
            .map(|r| analyse_record(r, &options).unwrap())
            .collect();
        let node = node_analyses(&bag, &options);
        assert_eq!(node.len(), batch.len(), "{name}: sine steps");
        assert!(batch.len() >= 5, "{name}: {} sine steps", batch.len());
        let mut worst = 0.0f64;
        for ((streamed, n), b) in node.iter().zip(&batch) {
            assert!(streamed, "{name} step {}: analysed in batch", b.step);
            // Up to rounding (see math/tests/phasor_stream.rs): identical phasors, noise ~1e-14.
            let d = b.relative_difference(n);
            assert!(
                d.is_some_and(|d| d <= 1e-9),
                "{name} step {}: {d:?}\n{b:?}\n{n:?}",
                b.step
            );
            worst = worst.max(d.unwrap_or(f64::NAN));
        }
        println!(
            "{name}: {} steps streamed, largest relative difference to batch {worst:e}",
            node.len()
        );
    }
}

/// Stamps every 3 ms (333.33 Hz): the stream starts at the nearest whole rate (333 Hz), the
/// completed record's rate differs, and the record is analysed in batch.
#[test]
fn a_rate_that_is_not_whole_falls_back_to_the_batch_analysis() {
    let options = PhasorOptions::for_identification();
    let (n, f) = (1000usize, 2.0);
    let ex = Excitation::Sine {
        frequency_hz: f,
        amplitude: 1.0,
    };
    let start = Time::from_nanos(5_000_000_000);
    let state = ExcitationState::from_excitation(
        Header::default(),
        0,
        start,
        &ex,
        Channel::BaseDisplacementM,
        n,
    );
    let mut h = HarmonicState::with_options(options.clone());
    let t = Instant::now();
    let mut out = h.handle(Input::Excitation(state), t);
    for k in 0..n {
        let ts = k as f64 * 0.003;
        let s = RigSample::new(
            Header::new(
                Time::from_nanos(5_000_000_000 + k as i64 * 3_000_000),
                "rig",
            ),
            0,
        )
        .with(
            Channel::BaseDisplacementM,
            (2.0 * std::f64::consts::PI * f * ts).sin() + 0.1,
        );
        out.extend(h.handle(Input::Sample(s), t));
    }
    assert_eq!(out.len(), 1);
    let Some(Outcome::Analyse(Analysis::Batch(rec), _)) = out.pop() else {
        panic!("the step should be analysed in batch")
    };
    assert!((rec.sample_rate_hz - 1000.0 / 3.0).abs() < 1e-6);
    let want = analyse_record(&rec, &options).unwrap();
    let got = Analysis::Batch(rec).run(&options).unwrap();
    assert_eq!(got, want);
    assert!((got.channels[0].phasors[1].norm() - 1.0).abs() < 1e-6);
}

/// A periodic multisine bag (`ExcitationState` MULTISINE, lines not carried): the node analyses
/// each multisine step whole at its end, the lines it found are the simulator's design, and
/// its phasors are the averaged period of the record `forcemap identify` reads, bit for bit;
/// the band-random record gives none.
#[test]
fn multisine_steps_give_the_bins_of_their_averaged_period() {
    use forcemap_math::phasor::{MultisineOptions, analyse_multisine};
    use forcemap_math::sim::RunSpec;

    let bag = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bags/shaker_multisine_30db");
    let records = read_rig_bag(&bag).unwrap().records;
    // bags/regenerate.sh: the same run, its lines as designed.
    let designed = RunSpec::shaker_sdof_multisine(Some(30.0), 1)
        .simulate()
        .unwrap();
    let options = PhasorOptions::for_identification();
    let node = node_analyses(&bag, &options);
    assert_eq!(
        node.len(),
        2,
        "two multisine steps, the random record skipped"
    );
    for ((streamed, n), (r, d)) in node.iter().zip(records.iter().zip(&designed)) {
        assert!(!streamed);
        let (Excitation::Multisine { lines, rms, .. }, Excitation::Multisine { lines: want, .. }) =
            (&r.excitation, &d.excitation)
        else {
            panic!("step {}: not a multisine", r.step);
        };
        assert_eq!(lines, want, "step {}: lines found from the force", r.step);
        let batch = analyse_multisine(r, &MultisineOptions::default())
            .unwrap()
            .as_harmonic_analysis(*rms);
        assert_eq!(n, &batch, "step {}", r.step);
        assert_eq!((n.frequency_hz, n.harmonics), (0.5, 2000));
    }
}
