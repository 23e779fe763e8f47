//! A run simulated record by record (`RunSpec::simulate_streamed`, what the sensor node
//! publishes while it simulates) gives the whole-run simulation's records bit for bit: the
//! paper's rig run at 40 dB (the committed bag `bags/rig_40db`), a rig with an exciter delay
//! and a sensor low-pass (breakpoints between samples, filter states), a noise-free run, and
//! the 3-DOF example (simulated whole, handed out by record).
#![allow(clippy::unwrap_used, reason = "tests")]

use forcemap_math::record::Record;
use forcemap_math::sim::{RigEffects, RunSpec, ThreeDofCase};

fn streamed(spec: &RunSpec) -> Vec<Record> {
    let mut out = Vec::new();
    spec.simulate_streamed(|r| {
        out.push(r);
        true
    })
    .unwrap();
    out
}

fn assert_bitwise_equal(a: &[Record], b: &[Record]) {
    assert_eq!(a.len(), b.len(), "record count");
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.step, y.step);
        assert_eq!(x.excitation, y.excitation, "step {}", x.step);
        assert_eq!(x.start_time_s.to_bits(), y.start_time_s.to_bits());
        assert_eq!(x.channels.len(), y.channels.len());
        for ((cx, vx), (cy, vy)) in x.channels.iter().zip(&y.channels) {
            assert_eq!(cx, cy);
            let bx: Vec<u64> = vx.iter().map(|v| v.to_bits()).collect();
            let by: Vec<u64> = vy.iter().map(|v| v.to_bits()).collect();
            assert!(bx == by, "step {}, {cx:?} differs", x.step);
        }
    }
}

#[test]
fn the_paper_rig_run_streamed_is_the_whole_run() {
    let spec = RunSpec::paper_rig(Some(40.0), 1);
    assert_bitwise_equal(&streamed(&spec), &spec.simulate().unwrap());
}

#[test]
fn a_rig_with_delay_and_sensor_lowpass_streamed_is_the_whole_run() {
    let spec = RunSpec {
        sample_rate_hz: 1000.0,
        samples_per_record: 2300,
        ..RunSpec::paper_rig(Some(30.0), 7)
    }
    .with_effects(RigEffects {
        exciter_delay_s: 0.0123,
        sensor_lowpass_hz: Some(80.0),
        mass_factor: 1.05,
    });
    assert_bitwise_equal(&streamed(&spec), &spec.simulate().unwrap());
}

#[test]
fn a_noise_free_run_and_the_three_dof_example_streamed_are_their_whole_runs() {
    for spec in [
        RunSpec::paper_rig(None, 3),
        RunSpec::three_dof(ThreeDofCase::I, Some(40.0), 2),
    ] {
        assert_bitwise_equal(&streamed(&spec), &spec.simulate().unwrap());
    }
}

#[test]
fn the_consumer_stops_a_streamed_run() {
    let spec = RunSpec::paper_rig(Some(40.0), 1);
    let mut steps = Vec::new();
    spec.simulate_streamed(|r| {
        steps.push(r.step);
        steps.len() < 3
    })
    .unwrap();
    assert_eq!(steps, [0, 1, 2]);
}
