//! Identification throughput: samples of the rig's stepped-sine run (10 steps x 1300 samples at
//! 100 Hz) turned into theta per second, by method, from phasors and from raw records.
#![allow(
    clippy::unwrap_used,
    reason = "test and bench helpers outside #[test] fns: a panic is how they report failure"
)]

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use forcemap_math::identify::{FdMultiOptions, Method, identify};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::{analyse_sine_steps, identify_records};
use forcemap_math::recipe::Setup;
use forcemap_math::sim::RunSpec;

fn bench_identify(c: &mut Criterion) {
    let records = RunSpec::paper_rig_sine(Some(40.0), 1)
        .simulate()
        .expect("simulation runs");
    let samples: usize = records.iter().map(forcemap_math::record::Record::len).sum();
    // As many harmonics as the sample rate allows (what `forcemap reproduce` uses).
    let phasor_options = PhasorOptions {
        max_harmonic: usize::MAX,
        ..PhasorOptions::default()
    };
    let (analyses, _) = analyse_sine_steps(&records, &phasor_options).expect("analysis runs");
    let setup = Setup::BaseExcited { mass_kg: 36.0 };
    let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
    let options = FdMultiOptions::default();

    let mut g = c.benchmark_group("identify/rig_coulomb/from_phasors");
    g.throughput(Throughput::Elements(samples as u64));
    for method in [Method::Fd, Method::FdMulti] {
        g.bench_function(method.name(), |b| {
            b.iter(|| {
                identify(
                    black_box(&model),
                    &setup,
                    method,
                    &records,
                    black_box(&analyses),
                    &options,
                )
                .unwrap()
            });
        });
    }
    g.finish();

    let mut g = c.benchmark_group("identify/rig_coulomb/from_records");
    g.throughput(Throughput::Elements(samples as u64));
    for method in [
        Method::Fd,
        Method::FdMulti,
        Method::Td {
            points_per_step: None,
        },
    ] {
        g.bench_function(method.name(), |b| {
            b.iter(|| {
                identify_records(
                    black_box(&model),
                    &setup,
                    method,
                    black_box(&records),
                    &phasor_options,
                    &options,
                )
                .unwrap()
            });
        });
    }
    g.finish();
}

criterion_group!(benches, bench_identify);
criterion_main!(benches);
