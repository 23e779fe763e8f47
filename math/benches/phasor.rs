//! Throughput of `analyse_record` in samples per second (per-channel samples counted once:
//! `Throughput::Elements(record length)`, six channels each).
//!
//! `cargo bench -p forcemap_math --bench phasor`
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::record::{Channel, Excitation, Record};
use std::f64::consts::PI;
use std::hint::black_box;

/// Six channels: a decaying transient on top of a periodic response with a few harmonics.
fn record(fs: f64, f: f64, len: usize, tau: f64) -> Record {
    let channels = Channel::ALL[..6]
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let g = 1.0 + i as f64;
            let x = (0..len)
                .map(|k| {
                    let t = k as f64 / fs;
                    let w = 2.0 * PI * f * t;
                    0.1 * g
                        + g * (w + 0.3 * g).cos()
                        + 0.2 * (2.0 * w).sin()
                        + 0.05 * (3.0 * w - g).cos()
                        + 0.5 * (-t / tau).exp() * (2.0 * PI * 2.3 * t).cos()
                })
                .collect();
            (*c, x)
        })
        .collect();
    Record {
        step: 0,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 1.0,
        },
        sample_rate_hz: fs,
        start_time_s: 0.0,
        channels,
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("analyse_record");
    let cases = [
        (
            "100Hz_1300samples_6ch_Nmax",
            record(100.0, 1.6, 1300, 0.8),
            PhasorOptions {
                max_harmonic: usize::MAX,
                ..PhasorOptions::default()
            },
        ),
        (
            "10kHz_20000samples_6ch_N20",
            record(10_000.0, 1.7, 20_000, 0.05),
            PhasorOptions {
                max_harmonic: 20,
                ..PhasorOptions::default()
            },
        ),
        (
            "10kHz_20000samples_6ch_N20_13Hz",
            record(10_000.0, 13.3, 20_000, 0.05),
            PhasorOptions {
                max_harmonic: 20,
                ..PhasorOptions::default()
            },
        ),
    ];
    for (name, rec, opts) in &cases {
        let a = analyse_record(rec, opts).unwrap();
        eprintln!(
            "{name}: N = {}, periods used {} of {}, settled {}",
            a.harmonics, a.periods_used, a.periods_available, a.settled
        );
        group.throughput(Throughput::Elements(rec.len() as u64));
        group.bench_function(*name, |b| {
            b.iter(|| analyse_record(black_box(rec), black_box(opts)).unwrap());
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
