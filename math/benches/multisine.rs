//! Throughput of `analyse_multisine` in samples per second (per-channel samples counted once:
//! `Throughput::Elements(record length)`, three channels each, the element test's), on
//! records of a random-odd multisine with a little distortion and a decaying transient.
//!
//! `cargo bench -p forcemap_math --bench multisine`
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use forcemap_math::phasor::{MultisineOptions, analyse_multisine};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::sim::MultisineDesign;
use forcemap_math::sim::periodic_multisine::{multisine_lines, periodic_multisine};
use std::hint::black_box;

/// `periods` periods of a random-odd multisine on `band_hz` of `f0` at `fs`, three channels.
fn record(fs: f64, f0: f64, band_hz: [f64; 2], periods: usize) -> Record {
    let lines = multisine_lines(f0, band_hz[0], band_hz[1], MultisineDesign::RandomOdd, 1);
    let ms = periodic_multisine(f0, &lines, 1.0, 2, fs);
    let len = periods * (fs / f0).round() as usize;
    let channels = [
        Channel::RelativeDisplacementM,
        Channel::ForceN,
        Channel::MassAccelerationMps2,
    ]
    .iter()
    .enumerate()
    .map(|(i, c)| {
        let g = 1.0 + i as f64;
        let x = (0..len)
            .map(|k| {
                let t = k as f64 / fs;
                let d = ms.eval(t);
                g * d.value + 0.1 * d.value.powi(3) + 0.5 * (-t).exp() * (7.0 * t).cos()
            })
            .collect();
        (*c, x)
    })
    .collect();
    Record {
        step: 0,
        excitation: Excitation::Multisine {
            base_frequency_hz: f0,
            lines,
            rms: 1.0,
        },
        sample_rate_hz: fs,
        start_time_s: 0.0,
        channels,
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("analyse_multisine");
    let cases = [
        // The acceptance test's record: 9 periods of 2 s at 2 kHz.
        (
            "2kHz_0.5Hz_9periods_3ch",
            record(2000.0, 0.5, [4.0, 25.0], 9),
        ),
        // A lab record: 1 Hz lines to 200 Hz, 10 periods at 10 kHz.
        (
            "10kHz_1Hz_10periods_3ch",
            record(10_000.0, 1.0, [1.0, 200.0], 10),
        ),
    ];
    let opts = MultisineOptions::default();
    for (name, rec) in &cases {
        let a = analyse_multisine(rec, &opts).unwrap();
        eprintln!(
            "{name}: {} samples, {} lines, periods used {} of {}",
            rec.len(),
            a.lines.len(),
            a.periods_used,
            a.periods_available
        );
        group.throughput(Throughput::Elements(rec.len() as u64));
        group.bench_function(*name, |b| {
            b.iter(|| analyse_multisine(black_box(rec), black_box(&opts)).unwrap());
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
