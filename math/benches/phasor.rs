//! Throughput of `analyse_record` in samples per second (per-channel samples counted once:
//! `Throughput::Elements(record length)`, six channels each), and of the stream: the cost of
//! pushing a sample (six channels) and of `PhasorStream::finish` after a step's last sample
//! (the stream told the step's length, as the harmonic node is, or not), against `analyse_record` of the same 13 s step at 10 kHz (what the harmonic node did then).
//!
//! `cargo bench -p forcemap_math --bench phasor`
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use criterion::BatchSize;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use forcemap_math::phasor::{PhasorOptions, PhasorStream, analyse_record};
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

/// A stream of `rec` fed `samples` of its samples.
fn fed(rec: &Record, opts: &PhasorOptions, samples: usize) -> PhasorStream {
    fed_told(rec, opts, samples, None)
}

/// A stream of `rec` told to expect `expected` samples (as the harmonic node is, from the
/// plan) and fed `samples` of them.
fn fed_told(
    rec: &Record,
    opts: &PhasorOptions,
    samples: usize,
    expected: Option<usize>,
) -> PhasorStream {
    let channels = rec.channels.iter().map(|(c, _)| *c).collect();
    let mut s = PhasorStream::new(
        rec.step,
        &rec.excitation,
        rec.sample_rate_hz,
        rec.start_time_s,
        channels,
        opts,
    )
    .unwrap();
    if let Some(n) = expected {
        s.expect_samples(n);
    }
    let mut values = vec![0.0; rec.channels.len()];
    for k in 0..samples {
        for (v, (_, x)) in values.iter_mut().zip(&rec.channels) {
            *v = x[k];
        }
        s.push(black_box(&values));
    }
    s
}

fn bench_stream(c: &mut Criterion) {
    let opts = PhasorOptions::for_identification(); // N = 100, as the harmonic node
    // The `forcemap bench graph --sample-rate-hz 10000` step: 13 s at 10 kHz, 1.6 Hz.
    let step = record(10_000.0, 1.6, 130_000, 0.8);
    let small = record(100.0, 1.6, 1300, 0.8);

    let mut group = c.benchmark_group("phasor_stream_push");
    for (name, rec) in [
        ("10kHz_6ch_N100_20000samples", &step),
        ("100Hz_6ch_N30_1300samples", &small),
    ] {
        let n = rec.len().min(20_000);
        group.throughput(Throughput::Elements(n as u64));
        group.bench_function(name, |b| b.iter(|| fed(rec, &opts, n).samples()));
    }
    group.finish();

    // After the last sample: what remains of the stream against the whole batch analysis.
    let mut group = c.benchmark_group("phasor_step_end_10kHz_130000samples_6ch_N100");
    group.sample_size(20);
    let full = fed(&step, &opts, step.len());
    let a = full.clone().finish().unwrap();
    eprintln!(
        "13 s step at 10 kHz: N = {}, periods used {} of {}, settled {}",
        a.harmonics, a.periods_used, a.periods_available, a.settled
    );
    group.bench_function("stream_finish", |b| {
        b.iter_batched(
            || full.clone(),
            |s| s.finish().unwrap(),
            BatchSize::SmallInput,
        );
    });
    // Told the step's length, the stream analyses it when its last whole period completes.
    let told = fed_told(&step, &opts, step.len(), Some(step.len()));
    group.bench_function("stream_finish_length_told", |b| {
        b.iter_batched(
            || told.clone(),
            |s| s.finish().unwrap(),
            BatchSize::SmallInput,
        );
    });
    group.bench_function("batch_analyse_record", |b| {
        b.iter(|| analyse_record(black_box(&step), black_box(&opts)).unwrap());
    });
    group.finish();
}

criterion_group!(benches, bench, bench_stream);
criterion_main!(benches);
