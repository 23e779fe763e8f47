//! The harmonic node's state machine, without ROS.

use super::*;
use forcemap_math::record::{Channel, Excitation};

fn sample(step: u32, k: i64) -> RigSample {
    RigSample::new(
        Header::new(Time::from_nanos(5_000_000_000 + k * 10_000_000), "rig"),
        step,
    )
    .with(Channel::BaseDisplacementM, (k as f64 * 0.3).sin())
}

fn state(step: u32, n: u32, kind_sine: bool) -> ExcitationState {
    let ex = if kind_sine {
        Excitation::Sine {
            frequency_hz: 2.0,
            amplitude: 1.0,
        }
    } else {
        Excitation::Random {
            band_hz: None,
            rms: 1.0,
        }
    };
    ExcitationState::from_excitation(
        Header::default(),
        step as usize,
        Time::from_nanos(5_000_000_000 + (step as i64) * 1_000_000_000),
        &ex,
        Channel::BaseDisplacementM,
        n as usize,
    )
}

/// Samples that overtake their excitation state wait for it; the step completes at its
/// planned count; a random record is skipped; a step with a lost sample is dropped.
#[test]
fn steps_complete_in_order_whatever_the_topic_order() {
    let mut h = HarmonicState::new();
    let t = Instant::now();
    let mut out = Vec::new();
    for k in 0..3 {
        out.extend(h.handle(Input::Sample(sample(0, k)), t));
    }
    assert!(out.is_empty());
    out.extend(h.handle(Input::Excitation(state(0, 5, true)), t));
    for k in 3..5 {
        out.extend(h.handle(Input::Sample(sample(0, k)), t));
    }
    assert_eq!(out.len(), 1);
    let Outcome::Analyse(Analysis::Streamed(st), origin) = out.pop().unwrap() else {
        panic!("step 0 should be analysed from its stream")
    };
    assert_eq!(
        (st.step(), st.samples(), st.sample_rate_hz()),
        (0, 5, 100.0)
    );
    assert_eq!(origin, Time::from_nanos(5_000_000_000));
    // The step's record, which its stream made unnecessary, is the caller's to free.
    let spent = h.take_spent().expect("the streamed step's record");
    assert_eq!((spent.step, spent.len()), (0, 5));
    assert!(h.take_spent().is_none());

    out.extend(h.handle(Input::Excitation(state(1, 4, false)), t));
    for k in 100..104 {
        out.extend(h.handle(Input::Sample(sample(1, k)), t));
    }
    assert!(matches!(out.pop(), Some(Outcome::Skipped(1, _))));

    out.extend(h.handle(Input::Excitation(state(2, 4, true)), t));
    for k in [200, 201, 203] {
        out.extend(h.handle(Input::Sample(sample(2, k)), t));
    }
    assert!(out.is_empty());
    let idle = ExcitationState::idle(Header::default(), 3, Time::ZERO, Channel::ForceN);
    out.extend(h.handle(Input::Excitation(idle), t));
    // The idle state may overtake the last samples: the step stays open for the wait.
    out.extend(h.handle(Input::Tick, t + Duration::from_millis(500)));
    assert!(out.is_empty());
    out.extend(h.handle(Input::Tick, t + PLAN_WAIT + Duration::from_millis(1)));
    let Some(Outcome::Dropped(e)) = out.pop() else {
        panic!("step 2 should be dropped")
    };
    assert_eq!(e.step, 2);
}

/// The idle state overtaking the last samples of a step does not cut the step short.
#[test]
fn a_step_whose_idle_state_overtakes_its_last_samples_completes() {
    let mut h = HarmonicState::new();
    let t = Instant::now();
    let mut out = h.handle(Input::Excitation(state(0, 5, true)), t);
    for k in 0..3 {
        out.extend(h.handle(Input::Sample(sample(0, k)), t));
    }
    let idle = ExcitationState::idle(Header::default(), 1, Time::ZERO, Channel::ForceN);
    out.extend(h.handle(Input::Excitation(idle), t));
    out.extend(h.handle(Input::Tick, t + Duration::from_millis(300)));
    for k in 3..5 {
        out.extend(h.handle(Input::Sample(sample(0, k)), t + Duration::from_millis(400)));
    }
    assert_eq!(out.len(), 1);
    assert!(
        matches!(out.pop(), Some(Outcome::Analyse(Analysis::Streamed(s), _)) if s.samples() == 5)
    );
}

/// Samples whose excitation state never comes are dropped after the wait, not used.
#[test]
fn samples_without_an_excitation_state_are_dropped_after_the_wait() {
    let mut h = HarmonicState::new();
    let t = Instant::now();
    for k in 0..4 {
        assert!(h.handle(Input::Sample(sample(7, k)), t).is_empty());
    }
    assert!(
        h.handle(Input::Tick, t + Duration::from_millis(100))
            .is_empty()
    );
    let mut out = h.handle(Input::Tick, t + PLAN_WAIT + Duration::from_millis(1));
    out.extend(h.handle(
        Input::Excitation(ExcitationState::idle(
            Header::default(),
            8,
            Time::ZERO,
            Channel::ForceN,
        )),
        t + PLAN_WAIT,
    ));
    out.extend(h.handle(Input::Tick, t + 2 * PLAN_WAIT + Duration::from_millis(2)));
    let Some(Outcome::Dropped(e)) = out.pop() else {
        panic!("step 7 should be dropped")
    };
    assert!(e.problem.contains("no ExcitationState"), "{}", e.problem);
}

/// Finding steps, a silence ends the run; samples that then resume with no break in their
/// stamps were held by a stalled stream, not paused by the bench: a warning says the step in
/// progress was cut, and names the parameter that waits longer. A bench's pause says nothing.
#[test]
fn samples_resuming_after_a_stall_are_told_apart_from_a_pause() {
    let stalled = |h: &mut HarmonicState, from: i64, to: i64, at: Instant| -> Vec<String> {
        (from..to)
            .flat_map(|k| h.handle(Input::Sample(sample(0, k)), at))
            .filter_map(|o| match o {
                Outcome::Warning(w) if w.contains("stalled") => Some(w),
                _ => None,
            })
            .collect()
    };
    let t = Instant::now();
    let after = |s: f64| t + Duration::from_secs_f64(s);
    let mut h = HarmonicState::new().finding_steps().unwrap();
    assert!(stalled(&mut h, 0, 300, t).is_empty());
    // Within the silence: the run goes on.
    h.handle(Input::Tick, after(4.0));
    assert!(stalled(&mut h, 300, 310, after(4.5)).is_empty());
    h.handle(Input::Tick, after(10.6));
    let w = stalled(&mut h, 310, 320, after(11.0));
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("stopped for 6.1 s") && w[0].contains("run_end_silence_s"),
        "{}",
        w[0]
    );
    // A pause in the stamps (the next sample 2 s of stamps later) is the bench's.
    h.handle(Input::Tick, after(20.0));
    assert!(stalled(&mut h, 520, 530, after(21.0)).is_empty());
    // With a longer silence the stall does not end the run.
    let mut h = HarmonicState::new()
        .with_run_end_silence(30.0)
        .unwrap()
        .finding_steps()
        .unwrap();
    stalled(&mut h, 0, 300, t);
    h.handle(Input::Tick, after(10.0));
    assert!(stalled(&mut h, 300, 310, after(10.5)).is_empty());
    assert!(HarmonicState::new().with_run_end_silence(0.0).is_err());
}
