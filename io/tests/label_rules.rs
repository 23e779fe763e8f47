//! A label is a hint: a sine step is analysed at the frequency its driven channel shows where
//! the label is off beyond the estimate's uncertainty and the tolerance, with one warning
//! naming both; exact labels stand bit for bit. Label checks run only where they can apply,
//! with at most one line per record and kind.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::steps::label_check::check_labels;
use forcemap_io::steps::unlabelled::{
    DEFAULT_FREQUENCY_TOLERANCE, StepWithFrequency, frequencies_from_data, frequency_from_data,
};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::segment::SegmentOptions;

/// Unit Gaussian samples from `seed` (a 64-bit LCG through Box-Muller): reproducible noise.
fn gaussian(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    move || {
        let (u, v) = (uniform(), uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

const FS: f64 = 200.0;

/// A step of `seconds` of a sine at `drive_hz` (amplitude 25 mm, 30 dB noise) labelled
/// `label` (`None`: random), with a force channel.
fn step(
    step: usize,
    start_s: f64,
    seconds: f64,
    drive_hz: f64,
    label: Option<f64>,
    seed: u64,
) -> Record {
    let n = (seconds * FS) as usize;
    let sigma = 0.025 / 2f64.sqrt() * 10f64.powf(-1.5);
    let mut noise = gaussian(seed);
    let x: Vec<f64> = (0..n)
        .map(|i| 0.025 * (std::f64::consts::TAU * drive_hz * i as f64 / FS).sin() + sigma * noise())
        .collect();
    Record {
        step,
        excitation: match label {
            Some(frequency_hz) => Excitation::Sine {
                frequency_hz,
                amplitude: 0.025,
            },
            None => Excitation::Random {
                band_hz: None,
                rms: 0.0177,
            },
        },
        sample_rate_hz: FS,
        start_time_s: start_s,
        channels: vec![
            (Channel::RelativeDisplacementM, x.clone()),
            (Channel::ForceN, x.iter().map(|v| 4000.0 * v).collect()),
        ],
    }
}

#[test]
fn a_label_off_by_percent_gives_way_to_the_drive_with_one_warning() {
    // The UTFSM machine's 0.5 Hz step ran at 0.5086 Hz.
    let mut r = step(2, 0.0, 24.0, 0.5086, Some(0.5), 1);
    let w = frequency_from_data(
        &mut r,
        Channel::RelativeDisplacementM,
        DEFAULT_FREQUENCY_TOLERANCE,
    )
    .unwrap();
    let f = r.excitation.frequency_hz().unwrap();
    assert!((f / 0.5086 - 1.0).abs() < 1e-4, "{f}");
    assert!(
        w.starts_with("step 2 is labelled 0.5 Hz, but relative_displacement_m is at 0.508"),
        "{w}"
    );
    assert!(w.contains(&format!("analysed at {f:.7} Hz")), "{w}");
    // Within a tolerance of 2 % the label stands.
    let mut r = step(2, 0.0, 24.0, 0.5086, Some(0.5), 1);
    assert!(frequency_from_data(&mut r, Channel::RelativeDisplacementM, 0.02).is_none());
    assert_eq!(r.excitation.frequency_hz(), Some(0.5));
}

#[test]
fn exact_labels_stand_bit_for_bit_and_records_that_are_no_sine_step_are_left() {
    let mut records: Vec<Record> = (0..40)
        .map(|k| {
            let f = 0.5 + 0.1 * k as f64;
            step(k, 0.0, 12.0 / f + 1.0, f, Some(f), 10 + k as u64)
        })
        .collect();
    let before = records.clone();
    let w = frequencies_from_data(
        &mut records,
        Channel::RelativeDisplacementM,
        DEFAULT_FREQUENCY_TOLERANCE,
    );
    assert!(w.is_empty(), "{w:?}");
    assert_eq!(records, before);
    // A random record, and a step without the driven channel, are no sine steps to check.
    let mut random = step(0, 0.0, 10.0, 1.0, None, 3);
    assert!(frequency_from_data(&mut random, Channel::RelativeDisplacementM, 0.0).is_none());
    let mut other = step(0, 0.0, 10.0, 1.0, Some(1.1), 3);
    assert!(frequency_from_data(&mut other, Channel::BaseDisplacementM, 0.0).is_none());
}

#[test]
fn a_step_labelled_a_sine_that_is_none_keeps_its_label_with_a_warning() {
    let mut r = step(4, 0.0, 20.0, 1.0, Some(1.0), 5);
    let mut noise = gaussian(9);
    for v in r.channel_mut(Channel::RelativeDisplacementM).unwrap() {
        *v = 0.02 * noise();
    }
    let w = frequency_from_data(&mut r, Channel::RelativeDisplacementM, 0.0).unwrap();
    assert!(
        w.starts_with(
            "step 4 is labelled a sine of 1 Hz, but relative_displacement_m is no sine near it"
        ),
        "{w}"
    );
    assert_eq!(r.excitation.frequency_hz(), Some(1.0));
}

/// Ten random records whose level changes every second (a drive the segmentation cuts into
/// many steps): a random record's drive has no change to report. One sine step into which the
/// drive changes three times gets one line.
#[test]
fn label_checks_run_where_they_apply_once_per_record_and_kind() {
    let mut noise = gaussian(11);
    let mut t = 0.0;
    let mut steps: Vec<StepWithFrequency> = Vec::new();
    for k in 0..10 {
        let n = 20 * FS as usize;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let level = if (i / FS as usize).is_multiple_of(2) {
                    0.02
                } else {
                    0.002
                };
                level * noise()
            })
            .collect();
        steps.push((
            Record {
                step: k,
                excitation: Excitation::Random {
                    band_hz: None,
                    rms: 0.01,
                },
                sample_rate_hz: FS,
                start_time_s: t,
                channels: vec![(Channel::RelativeDisplacementM, x)],
            },
            None,
        ));
        t += 20.0;
    }
    let w = check_labels(
        &steps,
        Channel::RelativeDisplacementM,
        &SegmentOptions::default(),
    );
    assert!(
        w.iter().all(|l| !l.contains("inside labelled step")),
        "{} lines: {w:#?}",
        w.len()
    );
    assert!(w.len() <= steps.len(), "{w:#?}");

    // A sine step at 2 Hz whose drive goes 3 Hz, 2 Hz, 3 Hz, 2 Hz for 20 s each.
    let parts: Vec<Record> = [2.0, 3.0, 2.0, 3.0]
        .iter()
        .enumerate()
        .map(|(k, f)| step(0, 20.0 * k as f64, 20.0, *f, Some(2.0), 20 + k as u64))
        .collect();
    let mut x = Vec::new();
    for p in &parts {
        x.extend_from_slice(p.channel(Channel::RelativeDisplacementM).unwrap());
    }
    let one = Record {
        channels: vec![(Channel::RelativeDisplacementM, x)],
        ..parts[0].clone()
    };
    let w = check_labels(
        &[(one, Some(2.0))],
        Channel::RelativeDisplacementM,
        &SegmentOptions::default(),
    );
    assert_eq!(w.len(), 1, "{w:#?}");
    assert!(
        w[0].contains("inside labelled step 0") && w[0].ends_with("(and 2 more times)"),
        "{w:#?}"
    );
}

/// Steps much shorter than the segmentation's windows (set by the run's lowest frequency) are
/// not checked against it: the UTFSM program's 5 Hz step of 2.2 s beside its 0.1 Hz one gave
/// lines saying its sine was broadband and its start no change.
#[test]
fn steps_too_short_for_the_segmentation_are_not_checked() {
    let steps: Vec<StepWithFrequency> = [(5.0, 2.245), (0.5, 24.7), (0.25, 22.43), (0.1, 95.2)]
        .iter()
        .enumerate()
        .scan(0.0, |t, (k, (f, seconds))| {
            let r = step(k, *t, *seconds, *f, Some(*f), 30 + k as u64);
            *t += seconds;
            Some((r, Some(*f)))
        })
        .collect();
    let w = check_labels(
        &steps,
        Channel::RelativeDisplacementM,
        &SegmentOptions::default(),
    );
    assert!(
        w.iter()
            .all(|l| !l.contains("step 0") && !l.contains("step 1 ")),
        "{w:#?}"
    );
}

/// The records of `pieces` (drive frequency, seconds) joined into one step labelled `label`.
fn step_of_pieces(step_no: usize, start_s: f64, label: f64, pieces: &[(f64, f64)]) -> Record {
    let mut t = start_s;
    let mut joined = step(step_no, start_s, 0.0, label, Some(label), 0);
    for (k, (f, seconds)) in pieces.iter().enumerate() {
        let piece = step(
            step_no,
            t,
            *seconds,
            *f,
            Some(label),
            100 + 10 * step_no as u64 + k as u64,
        );
        for ((_, x), (_, y)) in joined.channels.iter_mut().zip(piece.channels) {
            x.extend(y);
        }
        t += seconds;
    }
    joined
}

/// A slow step (0.1 Hz, 120 s) before five fast ones (5-9 Hz, 6 s each): each pair of steps is
/// segmented with windows of its own lowest frequency, so the fast steps are checked (with
/// windows of the run's lowest frequency, 40 s, none of them was). The drive goes to step 3's
/// 7 Hz a second before step 3's labelled start; the last step's drive goes to 10 Hz for its
/// middle 2 s. Each change is one line, whichever pair of steps sees it.
#[test]
fn each_pair_of_steps_is_checked_with_windows_of_its_own_frequencies() {
    let mut steps: Vec<StepWithFrequency> = Vec::new();
    let mut t = 0.0;
    let plan: [(f64, Vec<(f64, f64)>); 6] = [
        (0.1, vec![(0.1, 120.0)]),
        (5.0, vec![(5.0, 6.0)]),
        (6.0, vec![(6.0, 5.0), (7.0, 1.0)]),
        (7.0, vec![(7.0, 6.0)]),
        (8.0, vec![(8.0, 6.0)]),
        (9.0, vec![(9.0, 2.0), (10.0, 2.0), (9.0, 2.0)]),
    ];
    for (k, (label, pieces)) in plan.iter().enumerate() {
        let r = step_of_pieces(k, t, *label, pieces);
        t += r.len() as f64 / FS;
        steps.push((r, Some(*label)));
    }
    let w = check_labels(
        &steps,
        Channel::RelativeDisplacementM,
        &SegmentOptions::default(),
    );
    assert_eq!(w.len(), 3, "{w:#?}");
    assert!(
        w[0].starts_with("relative_displacement_m changes at 131.000 s")
            && w[0].ends_with("(to sine) inside labelled step 2"),
        "{w:#?}"
    );
    assert!(
        w[1].starts_with("step 3 is labelled to start at 132.000 s")
            && w[1].ends_with("does not change there"),
        "{w:#?}"
    );
    assert!(
        w[2].starts_with("relative_displacement_m changes at 146.000 s")
            && w[2].ends_with("inside labelled step 5 (and once more)"),
        "{w:#?}"
    );
}
