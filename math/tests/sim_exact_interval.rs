//! A replay of sampled base motion steps each sample interval exactly when it can (a linear
//! element, friction of constant level, no stick-slip event possible inside: `exact_step.rs`)
//! and gives the sub-stepped RK4 run's response: the same element hidden behind an `Element`
//! that does not say it is linear takes the four RK4 stages of every 0.1 ms sub-step.
#![allow(clippy::unwrap_used, reason = "tests")]

use forcemap_math::element::{Element, Friction};
use forcemap_math::record::Channel;
use forcemap_math::sim::{ReplayOptions, RunSpec, TruthElement, simulate_on_sampled_base};

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

/// Largest |a - b| relative to the RMS of `b`.
fn worst(a: &[f64], b: &[f64]) -> f64 {
    let rms = (b.iter().map(|x| x * x).sum::<f64>() / b.len() as f64).sqrt();
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / rms)
        .fold(0.0, f64::max)
}

#[test]
fn exact_intervals_replay_as_the_substepped_rk4_run() {
    let spec = RunSpec::paper_rig_random([1.5, 2.5], None, 3);
    let records = spec.simulate().unwrap();
    let base = records[0].channel(Channel::BaseDisplacementM).unwrap();
    let opts = ReplayOptions::default();
    for element in [
        TruthElement::linear(6380.0, 184.0),
        TruthElement::rig_coulomb(),
    ] {
        let fast = simulate_on_sampled_base(&element, 36.0, base, 100.0, &opts).unwrap();
        let generic =
            simulate_on_sampled_base(&Opaque(&element), 36.0, base, 100.0, &opts).unwrap();
        let wa = worst(
            &fast.mass_acceleration_mps2,
            &generic.mass_acceleration_mps2,
        );
        let wx = worst(
            &fast.relative_displacement_m,
            &generic.relative_displacement_m,
        );
        eprintln!(
            "{element:?}: exact intervals vs RK4 stages, max difference / RMS: acceleration {wa:.2e}, relative displacement {wx:.2e}"
        );
        // RK4 with 0.1 ms sub-steps is itself within about 1e-13 of the exact solution.
        assert!(wa < 1e-9 && wx < 1e-9, "{wa:e} {wx:e}");
        let stuck = |o: &forcemap_math::sim::RigResponse| -> Vec<bool> {
            o.trace.iter().map(|s| s.stuck).collect()
        };
        assert_eq!(stuck(&fast), stuck(&generic), "the same samples stuck");
        if element.friction.is_some() {
            assert!(fast.trace.iter().any(|s| s.stuck), "the replay sticks");
        }
    }
}
