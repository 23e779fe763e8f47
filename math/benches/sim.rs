//! Simulator speed: simulated seconds per wall second (criterion's "elem/s", one element per
//! simulated second) of the paper's rig run at 100 Hz (10 stepped-sine steps and two
//! band-random records, stick-slip with event location), of a 10 kHz rig run (three
//! stepped-sine steps of 2 s), of the same run at 100 Hz and of the paper's 3-DOF example
//! (CASE II, 1 kHz, cubic stiffness and friction).
#![allow(
    clippy::unwrap_used,
    reason = "test and bench helpers outside #[test] fns: a panic is how they report failure"
)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use forcemap_math::sim::excitation::{PAPER_RIG_SINE_AMPLITUDE_M, sine_steps};
use forcemap_math::sim::{RunSpec, ThreeDofCase};

/// Simulated seconds of a run.
fn simulated_s(spec: &RunSpec) -> f64 {
    (spec.steps.len() * spec.samples_per_record) as f64 / spec.sample_rate_hz
}

fn bench_sim(c: &mut Criterion) {
    let rig_10khz = RunSpec {
        sample_rate_hz: 10_000.0,
        samples_per_record: 20_000,
        steps: sine_steps(&[1.6, 2.4, 3.4], PAPER_RIG_SINE_AMPLITUDE_M),
        ..RunSpec::paper_rig(None, 0)
    };
    // The same three steps at 100 Hz: the 10 kHz run's cost per simulated second against
    // the same run's at the paper's rate (the target: no slower).
    let rig_100hz = RunSpec {
        sample_rate_hz: 100.0,
        samples_per_record: 200,
        ..rig_10khz.clone()
    };
    let runs = [
        ("paper_rig_100Hz", RunSpec::paper_rig(Some(40.0), 1)),
        ("rig_10kHz_sine", rig_10khz),
        ("rig_100Hz_sine", rig_100hz),
        (
            "three_dof_case_ii_1kHz",
            RunSpec::three_dof(ThreeDofCase::Ii, None, 0),
        ),
    ];
    let mut g = c.benchmark_group("sim");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    for (name, spec) in runs {
        // Whole simulated seconds (criterion counts elements as integers).
        g.throughput(Throughput::Elements(simulated_s(&spec).round() as u64));
        g.bench_function(name, |b| b.iter(|| black_box(spec.simulate().unwrap())));
    }
    g.finish();
}

criterion_group!(benches, bench_sim);
criterion_main!(benches);
