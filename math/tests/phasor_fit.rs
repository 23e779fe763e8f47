//! Least-squares harmonic fit: exact recovery of band-limited signals, round trip with
//! `synthesize`, the harmonic cap.

use forcemap_math::phasor::{PhasorOptions, analyse_record, fit_harmonics, synthesize};
use forcemap_math::record::{Channel, Excitation, Record};
use num_complex::Complex64;
use proptest::prelude::*;

fn known_phasors() -> Vec<Complex64> {
    vec![
        Complex64::new(0.3, 0.0),
        Complex64::from_polar(1.0, 0.4),
        Complex64::from_polar(0.25, -1.2),
        Complex64::from_polar(0.1, 2.5),
        Complex64::new(0.0, 0.0),
        Complex64::from_polar(0.03, -0.7),
    ]
}

fn max_err(a: &[Complex64], b: &[Complex64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max)
}

fn sampled(c: &[Complex64], fs: f64, f: f64, len: usize) -> Vec<f64> {
    (0..len).map(|k| synthesize(c, f, k as f64 / fs)).collect()
}

#[test]
fn recovers_known_multi_harmonic_signal_non_integer_samples_per_period() {
    let c = known_phasors();
    // 62.5 samples per period over 3.7 periods, 37.3... samples per period, and an integer case.
    for &(fs, f, len) in &[
        (100.0, 1.6, 231usize),
        (100.0, 2.68, 150),
        (10_000.0, 1.7, 20_000),
        (100.0, 2.0, 200),
    ] {
        for n in [5usize, 7, 12] {
            let fit = fit_harmonics(&sampled(&c, fs, f, len), fs, f, n).unwrap();
            let mut want = c.clone();
            want.resize(n + 1, Complex64::new(0.0, 0.0));
            let e = max_err(&fit, &want);
            println!("fs {fs} f {f} len {len} N {n}: max |dC| = {e:.2e}");
            assert!(e < 1e-10, "fs {fs} f {f} len {len} N {n}: error {e:e}");
        }
    }
}

fn record_of(c: &[Complex64], fs: f64, f: f64, len: usize, start: f64) -> Record {
    let x = sampled(c, fs, f, len);
    let y: Vec<f64> = x.iter().map(|v| -2.0 * v + 1.0).collect();
    Record {
        step: 3,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 1.0,
        },
        sample_rate_hz: fs,
        start_time_s: start,
        channels: vec![(Channel::RelativeDisplacementM, x), (Channel::ForceN, y)],
    }
}

#[test]
fn analyse_record_recovers_periodic_signal() {
    let c = known_phasors();
    let r = record_of(&c, 100.0, 1.6, 1300, 5.0);
    let a = analyse_record(&r, &PhasorOptions::default()).unwrap();
    assert!(a.settled);
    assert_eq!(a.periods_available, 20);
    assert_eq!(
        a.periods_used, 20,
        "a periodic record is settled from the start"
    );
    assert_eq!(a.first_settled_sample, 0);
    assert_eq!(a.samples_used, 1250);
    assert_eq!(a.harmonics, 20);
    assert_eq!(a.harmonic_cap, 30);
    let mut want = c.clone();
    want.resize(21, Complex64::new(0.0, 0.0));
    let got = &a.channel(Channel::RelativeDisplacementM).unwrap().phasors;
    let e = max_err(got, &want);
    println!("analyse_record, 62.5 samples/period, N=20: max |dC| = {e:.2e}");
    assert!(e < 1e-10);
    let force: Vec<Complex64> = want
        .iter()
        .enumerate()
        .map(|(n, z)| if n == 0 { -2.0 * z + 1.0 } else { -2.0 * z })
        .collect();
    assert!(max_err(&a.channel(Channel::ForceN).unwrap().phasors, &force) < 1e-10);
    // t_ref is the start of the first used whole period: synthesize reproduces the samples.
    let ch = a.channel(Channel::RelativeDisplacementM).unwrap();
    for k in [0usize, 137, 1299] {
        let t = r.time_s(k) - a.t_ref_s;
        let x = r.channel(Channel::RelativeDisplacementM).unwrap()[k];
        assert!((synthesize(&ch.phasors, a.frequency_hz, t) - x).abs() < 1e-10);
    }
    // Noise-free: the standard errors and residual are at rounding level.
    assert!(
        ch.noise_std.iter().all(|s| *s < 1e-12),
        "{:?}",
        ch.noise_std
    );
    assert!(ch.residual_rms < 1e-10);
}

#[test]
fn harmonic_cap() {
    let c = known_phasors();
    let all = PhasorOptions {
        max_harmonic: usize::MAX,
        ..PhasorOptions::default()
    };
    // (fs, f, cap): floor((floor(fs/f) - 1) / 2)
    for &(fs, f, cap) in &[
        (100.0, 1.6, 30usize),
        (100.0, 1.5625, 31),
        (100.0, 12.5, 3),
        (100.0, 30.0, 1),
        (10_000.0, 1.7, 2940),
    ] {
        let len = (10.0 * fs / f) as usize;
        // Band-limited to the cap (harmonics above it would alias at 8 or 3.3 samples/period).
        let c: Vec<Complex64> = c[..c.len().min(cap + 1)].to_vec();
        if cap > 500 {
            // Only check the cap, without paying for a 2940-harmonic fit.
            let a =
                analyse_record(&record_of(&c, fs, f, len, 0.0), &PhasorOptions::default()).unwrap();
            assert_eq!(a.harmonic_cap, cap);
            assert_eq!(a.harmonics, 20);
            continue;
        }
        let a = analyse_record(&record_of(&c, fs, f, len, 0.0), &all).unwrap();
        assert_eq!(a.harmonic_cap, cap, "fs {fs} f {f}");
        assert_eq!(a.harmonics, cap);
        let got = &a.channels[0].phasors;
        let k = got.len().min(c.len());
        let e = max_err(&got[..k], &c[..k]);
        println!("fs {fs} f {f}: at the cap N = {cap}: max |dC| = {e:.2e}");
        // At the cap the periods are fitted with 2N+1 close to the samples per period; still exact.
        assert!(e < 1e-9, "fs {fs} f {f}: {e:e}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn fit_then_synthesize_round_trip(
        n in 0usize..8,
        extra in 1.0f64..120.0,
        periods in 1.0f64..6.0,
        seed in proptest::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 8),
    ) {
        let fs = 1000.0;
        let spp = (2 * n + 2) as f64 + extra; // samples per period, above the cap condition
        let f = fs / spp;
        let len = (periods * spp).ceil() as usize;
        let c: Vec<Complex64> = seed[..=n].iter().enumerate()
            .map(|(k, (re, im))| Complex64::new(*re, if k == 0 { 0.0 } else { *im })).collect();
        let x = sampled(&c, fs, f, len);
        let fit = fit_harmonics(&x, fs, f, n).unwrap();
        prop_assert!(max_err(&fit, &c) < 1e-9, "phasors {:e}", max_err(&fit, &c));
        for (k, xk) in x.iter().enumerate() {
            prop_assert!((synthesize(&fit, f, k as f64 / fs) - xk).abs() < 1e-9);
        }
    }
}
