//! The simulators' fast paths give the generic path's results: a linear element between
//! stick-slip events stepped as a linear map (and a stuck rig left as it is) against the same
//! element hidden behind an `Element` that does not say it is linear (every sub-step through
//! the four RK4 stages), on the paper's rig run (stick-slip, sine and multisine pieces) and on
//! a replay of sampled base motion (spline pieces).
#![allow(clippy::unwrap_used, reason = "tests")]

use forcemap_math::element::{Element, Friction};
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::{
    ReplayOptions, RigEffects, RigInitial, RunSpec, SolverOptions, TruthElement,
    simulate_on_sampled_base, simulate_rig,
};

/// `inner` without its linear coefficients.
struct Opaque<'a>(&'a dyn Element);

impl Element for Opaque<'_> {
    fn smooth_force(&self, x: f64, v: f64, z: &[f64]) -> f64 {
        self.0.smooth_force(x, v, z)
    }
    fn friction(&self) -> Option<Friction> {
        self.0.friction()
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Largest |a - b| over a channel, relative to the channel's RMS in its record.
fn worst(a: &[Record], b: &[Record]) -> f64 {
    let mut w: f64 = 0.0;
    for (ra, rb) in a.iter().zip(b) {
        for ((ca, va), (cb, vb)) in ra.channels.iter().zip(&rb.channels) {
            assert_eq!(ca, cb);
            let scale = rms(vb).max(f64::MIN_POSITIVE);
            for (x, y) in va.iter().zip(vb) {
                w = w.max((x - y).abs() / scale);
            }
        }
    }
    w
}

#[test]
fn the_linear_map_is_the_rk4_run_with_stick_slip() {
    for element in [
        TruthElement::rig_coulomb(),
        TruthElement::linear(6000.0, 150.0),
    ] {
        let spec = RunSpec::paper_rig(None, 0).with_element(element.clone());
        let program = spec.program();
        let run = |e: &dyn Element| {
            simulate_rig(
                e,
                36.0,
                &program,
                &RigEffects::default(),
                RigInitial::default(),
                &SolverOptions::default(),
            )
            .unwrap()
        };
        let (fast, generic) = (run(&element), run(&Opaque(&element)));
        let w = worst(&fast.records, &generic.records);
        eprintln!("{element:?}: linear map vs RK4 stages, max difference / RMS = {w:.2e}");
        assert!(w < 1e-9, "{w:e}");
        let events = |o: &forcemap_math::sim::SimOutput| -> usize {
            o.traces.iter().map(|t| t.events).sum()
        };
        assert_eq!(events(&fast), events(&generic));
        if element.friction.is_some() {
            assert!(events(&fast) > 100, "the run sticks and slips");
        }
    }
}

#[test]
fn the_linear_map_replays_sampled_base_as_the_rk4_run() {
    let spec = RunSpec::paper_rig_random([1.5, 2.5], None, 3);
    let records = spec.simulate().unwrap();
    let base = records[0].channel(Channel::BaseDisplacementM).unwrap();
    let element = TruthElement::rig_coulomb();
    let opts = ReplayOptions::default();
    let fast = simulate_on_sampled_base(&element, 36.0, base, 100.0, &opts).unwrap();
    let generic = simulate_on_sampled_base(&Opaque(&element), 36.0, base, 100.0, &opts).unwrap();
    let scale = rms(&generic.mass_acceleration_mps2);
    let w = fast
        .mass_acceleration_mps2
        .iter()
        .zip(&generic.mass_acceleration_mps2)
        .map(|(a, b)| (a - b).abs() / scale)
        .fold(0.0, f64::max);
    eprintln!("replay: linear map vs RK4 stages, max difference / RMS = {w:.2e}");
    assert!(w < 1e-9, "{w:e}");
    assert!(fast.trace.iter().any(|s| s.stuck), "the replay sticks");
}
