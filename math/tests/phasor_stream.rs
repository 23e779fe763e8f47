//! The streaming harmonic analysis against the batch one: fed the same samples one at a time,
//! [`PhasorStream`] must give [`analyse_record`]'s analysis (the same periods, settled part and
//! harmonics, the numbers up to rounding: the per-period sums are accumulated with the same
//! rotor and anchoring and the rest is the same code) on a simulated rig run with noise, on synthetic steps of random lengths,
//! frequencies, rates and harmonic counts, and the same errors where the batch analysis fails.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_math::phasor::{
    HarmonicAnalysis, PhasorError, PhasorOptions, PhasorStream, analyse_record, synthesize,
};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::sim::RunSpec;
use num_complex::Complex64;
use proptest::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

/// The record's samples pushed one at a time (all channels of a sample together), the stream
/// told the step's length (so that it prepares the joint fits of the end) or not.
fn stream_told(
    record: &Record,
    options: &PhasorOptions,
    told: bool,
) -> Result<HarmonicAnalysis, PhasorError> {
    stream_expecting(record, options, told.then_some(record.len()))
}

/// The record's samples pushed one at a time, the stream told to expect `expected` samples
/// (which may be wrong: a plan's count when samples were lost or added).
fn stream_expecting(
    record: &Record,
    options: &PhasorOptions,
    expected: Option<usize>,
) -> Result<HarmonicAnalysis, PhasorError> {
    let channels = record.channels.iter().map(|(c, _)| *c).collect();
    let mut s = PhasorStream::new(
        record.step,
        &record.excitation,
        record.sample_rate_hz,
        record.start_time_s,
        channels,
        options,
    )?;
    if let Some(n) = expected {
        s.expect_samples(n);
    }
    let mut values = vec![0.0; record.channels.len()];
    for k in 0..record.len() {
        for (v, (_, x)) in values.iter_mut().zip(&record.channels) {
            *v = x[k];
        }
        s.push(&values);
    }
    assert_eq!(s.samples(), record.len());
    // `analyse` (the stream kept) is `finish`, bit for bit, however often it runs; a stream
    // told the step's exact length has nothing left to do at its end.
    let kept = s.analyse();
    assert_eq!(s.analyse(), kept);
    if kept.is_ok() {
        if expected == Some(record.len()) {
            assert!(s.analysed_ahead(), "told {expected:?}");
        }
        if expected.is_none() {
            assert!(!s.analysed_ahead());
        }
    }
    let finished = s.finish();
    assert_eq!(finished, kept);
    finished
}

fn stream(record: &Record, options: &PhasorOptions) -> Result<HarmonicAnalysis, PhasorError> {
    stream_told(record, options, false)
}

/// The stream must be the batch analysis up to rounding: the per-period fits share Cholesky
/// factors between periods of the same length and phase (to 1e-12 of a cycle), and the batch
/// analysis meets the periods from the end where the stream meets them from the start, so a
/// period may be solved with a factor of a twin period whose normal matrix differs in its last
/// bits. The phasors of the joint fit come out identical; the noise at ~1e-14.
const TOLERANCE: f64 = 1e-9;

fn assert_same(batch: &HarmonicAnalysis, streamed: &HarmonicAnalysis, what: &str) -> f64 {
    let d = batch
        .relative_difference(streamed)
        .unwrap_or_else(|| panic!("{what}: not the same analysis:\n{batch:?}\n{streamed:?}"));
    assert!(d <= TOLERANCE, "{what}: differ by {d:e} (relative)");
    d
}

/// The paper's rig at 40 dB SNR, simulated at 100 Hz and at 2 kHz: every sine step, streamed
/// and in batch, with the identification's options (all harmonics up to 100).
#[test]
fn simulated_rig_run_streams_to_the_batch_analysis() {
    for rate_hz in [100.0, 2000.0] {
        let spec = RunSpec {
            sample_rate_hz: rate_hz,
            samples_per_record: (4.0 * rate_hz) as usize,
            ..RunSpec::paper_rig_sine(Some(40.0), 3)
        };
        let records = spec.simulate().unwrap();
        let options = PhasorOptions::for_identification();
        let (mut compared, mut worst) = (0, 0.0f64);
        for r in records
            .iter()
            .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        {
            let batch = analyse_record(r, &options).unwrap();
            for told in [false, true] {
                let streamed = stream_told(r, &options, told).unwrap();
                let what = format!("{rate_hz} Hz step {} (length told: {told})", r.step);
                worst = worst.max(assert_same(&batch, &streamed, &what));
            }
            compared += 1;
        }
        assert!(compared >= 5, "{rate_hz} Hz: only {compared} sine steps");
        println!("{rate_hz} Hz: {compared} steps, largest relative difference {worst:e}");
    }
}

/// A settled periodic response with a decaying transient and white noise on three channels.
fn synthetic(fs: f64, f: f64, len: usize, noise: f64, seed: u64) -> Record {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let channels = [
        Channel::ForceN,
        Channel::RelativeDisplacementM,
        Channel::BaseDisplacementM,
    ]
    .iter()
    .enumerate()
    .map(|(i, c)| {
        let g = 1.0 + i as f64;
        let periodic = [
            Complex64::new(0.1 * g, 0.0),
            Complex64::from_polar(g, 0.3 * g),
            Complex64::from_polar(0.2, -1.0),
            Complex64::from_polar(0.05, g),
        ];
        let x = (0..len)
            .map(|k| {
                let t = k as f64 / fs;
                let e: f64 = rng.sample(StandardNormal);
                synthesize(&periodic, f, t)
                    + 0.5 * g * (-t * f / 3.0).exp() * (2.0 * PI * 2.3 * f * t).cos()
                    + noise * e
            })
            .collect();
        (*c, x)
    })
    .collect();
    Record {
        step: 4,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 1.0,
        },
        sample_rate_hz: fs,
        start_time_s: 3.25,
        channels,
    }
}

/// A step too short for two whole periods and an excitation the analysis refuses fail in the
/// stream as in batch, with the same error.
#[test]
fn stream_fails_where_the_batch_analysis_fails() {
    let options = PhasorOptions::default();
    let short = synthetic(100.0, 1.6, 100, 0.0, 1); // 1.6 periods
    let want = analyse_record(&short, &options).unwrap_err();
    assert!(matches!(want, PhasorError::TooShort { .. }), "{want}");
    assert_eq!(stream(&short, &options).unwrap_err(), want);

    let mut fast = synthetic(100.0, 1.6, 1000, 0.0, 1);
    fast.excitation = Excitation::Sine {
        frequency_hz: 40.0,
        amplitude: 1.0,
    };
    let want = analyse_record(&fast, &options).unwrap_err();
    assert!(
        matches!(want, PhasorError::TooFewSamplesPerPeriod { .. }),
        "{want}"
    );
    assert_eq!(stream(&fast, &options).unwrap_err(), want);

    let mut s = PhasorStream::new(
        0,
        &short.excitation,
        100.0,
        0.0,
        vec![Channel::ForceN, Channel::BaseDisplacementM],
        &options,
    )
    .unwrap();
    s.push(&[1.0, 2.0]);
    s.push(&[1.0]);
    s.push(&[f64::NAN, 2.0]);
    assert!(matches!(
        s.finish(),
        Err(PhasorError::SampleWidth {
            sample: 1,
            values: 1,
            channels: 2,
            ..
        })
    ));
}

/// A stream told the step's length analyses it when the last whole period completes (before
/// the step's last sample); that analysis must be the one `finish` would compute, to the bit,
/// whether the step ends within a period or on its last sample, and a wrong count (samples
/// lost or added against the plan) must give the analysis of the samples actually pushed.
#[test]
fn analysis_ahead_of_the_step_end_is_the_finish_analysis() {
    let options = PhasorOptions::for_identification();
    // 1000 / 2.2 = 454.5 samples per period: 2500 samples end 0.5 period after the 5th.
    for len in [2500, 2273, 2272] {
        let r = synthetic(1000.0, 2.2, len, 1e-3, 7);
        let untold = stream_expecting(&r, &options, None).unwrap();
        let batch = analyse_record(&r, &options).unwrap();
        assert_same(&batch, &untold, &format!("{len} samples"));
        for expected in [len, len - 300, len + 300, len - 1000, len + 1000] {
            let told = stream_expecting(&r, &options, Some(expected)).unwrap();
            assert_eq!(told, untold, "{len} samples, {expected} expected");
        }
    }
}

/// A transient that never settles within the step (`settled = false`) streams the same too.
#[test]
fn unsettled_step_streams_to_the_batch_analysis() {
    let mut r = synthetic(1000.0, 2.2, 2000, 0.0, 2);
    for (_, x) in &mut r.channels {
        for (k, v) in x.iter_mut().enumerate() {
            *v += 1e-3 * k as f64; // a drift: no two periods agree
        }
    }
    let options = PhasorOptions::default();
    let batch = analyse_record(&r, &options).unwrap();
    assert!(!batch.settled);
    assert_same(&batch, &stream(&r, &options).unwrap(), "drifting step");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Random rates, frequencies (integer and non-integer samples per period), step lengths
    /// (whole periods or not), harmonic limits and noise: the stream is the batch analysis.
    #[test]
    fn stream_equals_batch_for_random_steps(
        fs in prop::sample::select(vec![100.0, 250.0, 1000.0, 10_000.0]),
        periods_per_step in 2.0f64..14.0,
        spp in 4.0f64..400.0,
        max_harmonic in prop::sample::select(vec![1usize, 3, 20, 100, usize::MAX]),
        noise in prop::sample::select(vec![0.0, 1e-3, 0.1]),
        seed in 0u64..1000,
        told in any::<bool>(),
    ) {
        let f = fs / spp;
        let len = (periods_per_step * spp).ceil() as usize;
        let r = synthetic(fs, f, len, noise, seed);
        let options = PhasorOptions { max_harmonic, ..PhasorOptions::default() };
        match (analyse_record(&r, &options), stream_told(&r, &options, told)) {
            (Ok(batch), Ok(streamed)) => {
                let d = batch.relative_difference(&streamed);
                prop_assert!(d.is_some_and(|d| d <= TOLERANCE), "{d:?}");
            }
            (batch, streamed) => prop_assert_eq!(batch, streamed),
        }
    }
}
