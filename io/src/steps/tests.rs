//! The assembler's rules, for messages and for written samples.

use super::*;
use forcemap_msgs::std_msgs::Header;

fn sample(step: u32, t_ms: i64, x: f64) -> RigSample {
    let stamp = Time::from_nanos(1_000_000_000 + t_ms * 1_000_000);
    RigSample::new(Header::new(stamp, "rig"), step)
        .with(Channel::BaseDisplacementM, x)
        .with(Channel::MassAccelerationMps2, 2.0 * x)
}

fn plan(n: usize) -> StepPlan {
    StepPlan {
        excitation: Excitation::Sine {
            frequency_hz: 2.0,
            amplitude: 1e-3,
        },
        sample_count: n,
        driven: None,
        multisine_band_hz: None,
    }
}

#[test]
fn a_step_completes_at_its_planned_count_with_its_rate_and_values() {
    let mut a = StepAssembler::new();
    a.set_origin(Time::from_nanos(1_000_000_000));
    let p = plan(5);
    let mut out = Vec::new();
    for k in 0..5 {
        out.extend(a.push(&sample(0, 10 * k, k as f64), Some(&p)));
    }
    assert_eq!(out.len(), 1);
    let r = out.pop().unwrap().unwrap();
    assert_eq!(r.sample_rate_hz, 100.0);
    assert_eq!(r.start_time_s, 0.0);
    assert_eq!(
        r.channel(Channel::MassAccelerationMps2).unwrap(),
        &[0.0, 2.0, 4.0, 6.0, 8.0]
    );
    assert!(a.in_progress().is_none());
}

#[test]
fn a_lost_sample_ends_a_record_and_a_lost_tail_drops_the_step() {
    let mut a = StepAssembler::new();
    let p = plan(0);
    for k in [0, 1, 2, 3, 5, 6, 7] {
        assert!(a.push(&sample(0, 10 * k, k as f64), Some(&p)).is_empty());
    }
    // The step goes on in a second record after the lost sample (a break, not a refusal).
    let parts: Vec<AssembledStep> = a.finish_step().into_iter().map(Result::unwrap).collect();
    assert_eq!(parts.len(), 2);
    assert_eq!((parts[0].record.step, parts[1].record.step), (0, 1));
    assert_eq!((parts[0].label, parts[1].label), (0, 0));
    assert_eq!((parts[0].first_sample, parts[1].first_sample), (0, 4));
    assert_eq!(
        parts[1].record.channel(Channel::BaseDisplacementM).unwrap(),
        &[5.0, 6.0, 7.0]
    );
    assert_eq!(parts[1].record.start_time_s, 0.05);
    assert_eq!(parts[1].record.sample_rate_hz, 100.0);
    assert!(parts[0].notes.is_empty());
    match &parts[1].notes[..] {
        [timing::TimingNote::Break(b)] => {
            assert_eq!((b.sample, b.lost_samples()), (4, Some(1)));
        }
        n => panic!("{n:?}"),
    }

    // The next step's records are numbered after the split one's.
    let p = plan(6);
    let mut out = Vec::new();
    for k in 0..4 {
        out.extend(a.push(&sample(1, 100 + 10 * k, 0.0), Some(&p)));
    }
    // The next step begins: step 1 is complete with 4 of its 6 samples.
    out.extend(a.push(&sample(2, 200, 0.0), Some(&p)));
    let e = out.pop().unwrap().unwrap_err();
    assert_eq!(e.step, 1);
    assert!(e.problem.contains("4 of its 6 samples"), "{e}");
    assert!(e.truncated, "a short step is only truncated");
    for k in 1..6 {
        out.extend(a.push(&sample(2, 200 + 10 * k, 0.0), Some(&p)));
    }
    let r = out.pop().unwrap().unwrap();
    assert_eq!(r.step, 3, "step 2 is the fourth record");
}

/// A planned step that loses a sample is two records, not a count short: the plan's count
/// holds for the whole step.
#[test]
fn a_break_in_a_planned_step_is_no_lost_count() {
    let mut a = StepAssembler::new();
    let p = plan(10);
    let mut out = Vec::new();
    for k in (0..10).filter(|k| *k != 4) {
        out.extend(a.push(&sample(0, 10 * k, 0.0), Some(&p)));
    }
    assert!(out.is_empty());
    out.extend(a.push(&sample(1, 100, 0.0), Some(&p)));
    assert_eq!(out.len(), 2);
    let lens: Vec<usize> = out.into_iter().map(|r| r.unwrap().len()).collect();
    assert_eq!(lens, [4, 5]);
}

/// A lone sample between two breaks is left out, with a note; so is a first sample before a
/// break.
#[test]
fn pieces_too_short_for_a_record_are_left_out_with_a_note() {
    let mut a = StepAssembler::with_rules(StepRules::WRITTEN);
    let p = plan(0);
    // 0 | 2 3 4 5 | 7 | 9 10 11
    for k in [0, 2, 3, 4, 5, 7, 9, 10, 11] {
        a.push_sample(&row(0, 0.01 * k as f64, 0.0), Some(&p));
    }
    let parts: Vec<AssembledStep> = a.finish_step().into_iter().map(Result::unwrap).collect();
    assert_eq!(parts.len(), 2);
    assert_eq!((parts[0].first_sample, parts[1].first_sample), (1, 6));
    use timing::TimingNote::{Break, LeftOut};
    assert!(matches!(
        parts[0].notes[..],
        [LeftOut { first: 0, count: 1 }, Break(_)]
    ));
    assert!(
        matches!(
            parts[1].notes[..],
            [Break(_), LeftOut { first: 5, count: 1 }, Break(_)]
        ),
        "{:?}",
        parts[1].notes
    );
    assert_eq!(
        parts[1].notes[1].describe(Some(0)),
        "step 0, samples 5-5: 1 sample between breaks of the sampling, too few for a record: left out"
    );
}

/// One step (an unlabelled run) at 1 kHz, a pause, then at 200 Hz: two records, each at its
/// own rate.
#[test]
fn a_pause_between_rates_gives_a_record_at_each() {
    let mut a = StepAssembler::with_rules(StepRules::WRITTEN);
    let p = plan(0);
    let mut t: Vec<f64> = (0..50).map(|k| k as f64 * 0.001).collect();
    t.extend((0..50).map(|k| 0.549 + k as f64 * 0.005));
    for &t in &t {
        a.push_sample(&row(0, t, 0.0), Some(&p));
    }
    let parts: Vec<AssembledStep> = a.finish_step().into_iter().map(Result::unwrap).collect();
    let rates: Vec<f64> = parts.iter().map(|p| p.record.sample_rate_hz).collect();
    assert_eq!(rates, [1000.0, 200.0]);
    assert!(parts.iter().all(|p| p.timing.jitter.is_none()));
    match &parts[1].notes[..] {
        [timing::TimingNote::Break(b)] => {
            assert_eq!(b.lost_samples(), None);
            assert!((b.interval_s - 0.5).abs() < 1e-12, "{b:?}");
        }
        n => panic!("{n:?}"),
    }
}

/// Stamps 5 % of an interval off their grid (a PC clock): one record, read as uniform, its rate
/// the whole number it scatters about, its jitter measured.
#[test]
fn jittered_stamps_are_one_uniform_record() {
    let mut a = StepAssembler::new();
    let p = plan(0);
    let mut state = 3u64;
    for k in 0..2000i64 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
        let stamp = Time::from_nanos(1_000_000_000 + k * 1_000_000 + (u * 50_000.0) as i64);
        let s = RigSample::new(Header::new(stamp, "rig"), 0).with(Channel::ForceN, 1.0);
        a.push(&s, Some(&p));
    }
    let parts: Vec<AssembledStep> = a.finish_step().into_iter().map(Result::unwrap).collect();
    assert_eq!(parts.len(), 1);
    let r = &parts[0];
    assert_eq!(r.record.sample_rate_hz, 1000.0);
    assert_eq!(r.record.len(), 2000);
    let j = r.timing.jitter.unwrap();
    // Uniform in +-50 us: an RMS of 50/sqrt(3) = 28.9 us, at most 50 us.
    assert!(
        (j.rms_s - 28.9e-6).abs() < 2e-6 && j.max_s <= 52e-6,
        "{j:?}"
    );
}

/// A duplicated stamp is no break and no jitter: refused, naming the sample.
#[test]
fn a_duplicate_stamp_is_refused() {
    let mut a = StepAssembler::new();
    let p = plan(0);
    for k in [0, 1, 2, 3, 3, 4, 5, 6] {
        a.push(&sample(0, 10 * k, 0.0), Some(&p));
    }
    let e = a.finish_step().pop().unwrap().unwrap_err();
    assert!(
        matches!(e.fault, StepFault::NotUniform { sample: 4, .. }),
        "{:?}",
        e.fault
    );
    assert!(e.problem.contains("a duplicate"), "{e}");
}

/// A sweep runs from its first sample: split, its second part would be another sweep.
#[test]
fn a_broken_sweep_is_refused() {
    let law = forcemap_math::phasor::SweepLaw {
        kind: forcemap_math::phasor::SweepKind::Linear,
        amplitude: 1.0,
        start_frequency_hz: 1.0,
        end_frequency_hz: 2.0,
        duration_s: f64::NAN,
    };
    let p = StepPlan {
        excitation: Excitation::Sweep { law },
        ..plan(0)
    };
    let mut a = StepAssembler::new();
    for k in (0..20).filter(|k| *k != 9) {
        a.push(&sample(0, 10 * k, 0.0), Some(&p));
    }
    let e = a.finish_step().pop().unwrap().unwrap_err();
    assert!(
        e.problem
            .starts_with("a sweep's samples break at sample 9: 1 sample lost"),
        "{e}"
    );
}

#[test]
fn non_finite_values_and_unknown_steps_are_refused() {
    let mut a = StepAssembler::new();
    let p = plan(3);
    let mut out = a.push(&sample(0, 0, 0.0), Some(&p));
    out.extend(a.push(&sample(0, 10, f64::NAN), Some(&p)));
    out.extend(a.push(&sample(0, 20, 0.0), Some(&p)));
    let e = out.pop().unwrap().unwrap_err();
    assert!(e.problem.contains("sample 1: channel"), "{e}");
    let mut out = Vec::new();
    for k in 0..3 {
        out.extend(a.push(&sample(1, 100 + 10 * k, 0.0), None));
    }
    let e = a.finish().pop().unwrap().unwrap_err();
    assert!(e.problem.contains("no ExcitationState"), "{e}");
    // a step cannot come back after a later one
    out.extend(a.push(&sample(0, 300, 0.0), Some(&p)));
    let e = a.finish().pop().unwrap().unwrap_err();
    assert!(e.problem.contains("not contiguous"), "{e}");
}

fn row(step: usize, t_s: f64, resolution: f64) -> StepSample {
    StepSample {
        t_s,
        t_resolution_s: resolution,
        step,
        values: vec![(Channel::ForceN, t_s)],
    }
}

#[test]
fn rig_samples_become_step_samples_with_their_present_channels() {
    let s = StepSample::of_rig(&sample(3, 0, 1.5), 0.25);
    assert_eq!(s.step, 3);
    assert_eq!(s.t_s, 0.25);
    assert_eq!(s.t_resolution_s, 0.0);
    assert_eq!(
        s.values,
        [
            (Channel::BaseDisplacementM, 1.5),
            (Channel::MassAccelerationMps2, 3.0)
        ]
    );
}

#[test]
fn written_steps_must_be_consecutive_and_messages_only_increasing() {
    let p = plan(0);
    let mut written = StepAssembler::with_rules(StepRules::WRITTEN);
    let mut messages = StepAssembler::new();
    for k in 0..3 {
        written.push_sample(&row(4, 0.01 * k as f64, 0.0), Some(&p));
        messages.push_sample(&row(4, 0.01 * k as f64, 0.0), Some(&p));
    }
    // The step in progress may continue, the first step may be any.
    assert_eq!(written.order_fault(4), None);
    assert_eq!(
        StepAssembler::with_rules(StepRules::WRITTEN).order_fault(9),
        None
    );
    assert_eq!(written.order_fault(5), None);
    assert_eq!(
        written.order_fault(6),
        Some(StepFault::OutOfOrder { previous: 4 })
    );
    assert_eq!(messages.order_fault(6), None);
    assert_eq!(
        messages.order_fault(3),
        Some(StepFault::OutOfOrder { previous: 4 })
    );
}

#[test]
fn written_times_are_checked_against_the_median_interval_within_their_rounding() {
    let p = plan(0);
    // Times written with 4 decimals at 300 Hz: rounded intervals of 3.3 or 3.4 ms pass.
    let mut a = StepAssembler::with_rules(StepRules::WRITTEN);
    for k in 0..30 {
        let t = ((k as f64 / 300.0) * 1e4).round() / 1e4;
        a.push_sample(&row(0, t, 1e-4), Some(&p));
    }
    let done = a.finish_step().pop().unwrap().unwrap();
    assert_eq!(done.timing.samples, 30);
    assert_eq!(done.timing.resolution_s, 1e-4);
    assert_eq!(done.timing.jitter, None, "rounded times are exact");
    assert_eq!(done.record.sample_rate_hz, 300.0);
    assert_eq!(done.record.channel(Channel::ForceN).unwrap().len(), 30);
    // A dropped row ends a record at the interval after it: two records of the step.
    let mut a = StepAssembler::with_rules(StepRules::WRITTEN);
    for k in [0, 1, 2, 3, 5, 6, 7] {
        a.push_sample(&row(1, 0.01 * k as f64, 0.0), Some(&p));
    }
    let parts: Vec<AssembledStep> = a.finish_step().into_iter().map(Result::unwrap).collect();
    let lens: Vec<(usize, usize, usize)> = parts
        .iter()
        .map(|p| (p.record.step, p.first_sample, p.record.len()))
        .collect();
    assert_eq!(lens, [(1, 0, 4), (2, 4, 3)]);
}

/// A multisine's lines found on its driven channel are checked against the band its state
/// labels it with: a right label says nothing, a wrong one gives a warning naming the step.
#[test]
fn a_mislabelled_multisine_band_gives_a_warning_naming_the_step() {
    let records = forcemap_math::sim::RunSpec::shaker_sdof_multisine(Some(30.0), 1)
        .simulate()
        .unwrap();
    let r = &records[0];
    let Excitation::Multisine {
        base_frequency_hz: f0,
        lines,
        rms,
    } = r.excitation.clone()
    else {
        panic!("step 0 is a multisine")
    };
    let designed = [lines[0] as f64 * f0, lines[lines.len() - 1] as f64 * f0];
    let assemble = |band: [f64; 2]| {
        let plan = StepPlan {
            excitation: Excitation::Multisine {
                base_frequency_hz: f0,
                lines: Vec::new(),
                rms,
            },
            sample_count: r.len(),
            driven: Some(Channel::ForceN),
            multisine_band_hz: Some(band),
        };
        let mut a = StepAssembler::new();
        let mut done = Vec::new();
        for i in 0..r.len() {
            let s = StepSample {
                t_s: r.time_s(i),
                t_resolution_s: 0.0,
                step: 3,
                values: r.channels.iter().map(|(c, x)| (*c, x[i])).collect(),
            };
            done.extend(a.push_sample(&s, Some(&plan)));
        }
        assert_eq!(done.len(), 1);
        done.pop().unwrap().unwrap()
    };
    let right = assemble(designed);
    assert!(right.warnings.is_empty(), "{:?}", right.warnings);
    let Excitation::Multisine { lines: found, .. } = &right.record.excitation else {
        panic!("still a multisine")
    };
    assert_eq!(found, &lines);
    // Labelled up to 40 Hz where the lines end at the designed edge.
    let wrong = assemble([designed[0], 40.0]);
    assert_eq!(
        wrong.record, right.record,
        "the label does not change the record"
    );
    assert_eq!(wrong.warnings.len(), 1);
    let w = &wrong.warnings[0];
    assert!(
        w.starts_with("step 3: multisine lines on force_n: ")
            && w.contains(&format!("span {} to {} Hz", designed[0], designed[1]))
            && w.contains(&format!(
                "labelled with lines from {} to 40 Hz",
                designed[0]
            )),
        "{w}"
    );
}
