//! Throughput of `detect_steps` in samples per second: the paper's rig drive (10 stepped-sine
//! steps of 1300 samples at 100 Hz, 30 dB) and the 3-DOF force (5 steps of 8000 samples at
//! 1 kHz, 30 dB).
//!
//! `cargo bench -p forcemap_math --bench segment`
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use forcemap_math::segment::{SegmentOptions, detect_steps};
use forcemap_math::sim::{RunSpec, ThreeDofCase};
use std::hint::black_box;

fn drive(spec: &RunSpec) -> Vec<f64> {
    let driven = spec.driven_channel();
    spec.simulate()
        .unwrap()
        .iter()
        .flat_map(|r| r.channel(driven).unwrap().to_vec())
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("detect_steps");
    for (name, spec) in [
        (
            "rig_10x1300_at_100hz",
            RunSpec::paper_rig_sine(Some(30.0), 0),
        ),
        (
            "three_dof_5x8000_at_1khz",
            RunSpec::three_dof(ThreeDofCase::I, Some(30.0), 0),
        ),
    ] {
        let x = drive(&spec);
        let options = SegmentOptions::default();
        group.throughput(Throughput::Elements(x.len() as u64));
        group.bench_function(name, |b| {
            b.iter(|| detect_steps(black_box(&x), spec.sample_rate_hz, 0.0, &options).unwrap());
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
