//! Settled-part detection: decaying transients, a noise-free linear oscillator against its
//! closed-form steady state, and white noise against the theoretical standard error.

use forcemap_math::phasor::{PhasorOptions, analyse_record, synthesize};
use forcemap_math::record::{Channel, Excitation, Record};
use num_complex::Complex64;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use std::f64::consts::PI;

const FS: f64 = 100.0;
const F: f64 = 1.6; // 62.5 samples per period
const LEN: usize = 1300; // 20.8 periods

fn record(channels: Vec<(Channel, Vec<f64>)>, fs: f64, f: f64) -> Record {
    Record {
        step: 7,
        excitation: Excitation::Sine {
            frequency_hz: f,
            amplitude: 1.0,
        },
        sample_rate_hz: fs,
        start_time_s: 12.5,
        channels,
    }
}

fn periodic() -> Vec<Complex64> {
    vec![
        Complex64::new(0.3, 0.0),
        Complex64::from_polar(1.0, 0.2),
        Complex64::from_polar(0.2, -1.0),
        Complex64::from_polar(0.05, -PI / 2.0),
    ]
}

fn rel_err(got: &[Complex64], want: &[Complex64], scale: f64) -> f64 {
    let zero = Complex64::new(0.0, 0.0);
    (0..got.len().max(want.len()))
        .map(|n| (got.get(n).unwrap_or(&zero) - want.get(n).unwrap_or(&zero)).norm() / scale)
        .fold(0.0, f64::max)
}

/// Periodic signal + `amp e^{-t/tau} cos(w_d t)`, optionally with white noise.
fn transient_record(amp: f64, tau: f64, noise: f64, seed: u64) -> Record {
    let c = periodic();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let x: Vec<f64> = (0..LEN)
        .map(|k| {
            let t = k as f64 / FS;
            let e: f64 = rng.sample(StandardNormal);
            synthesize(&c, F, t) + amp * (-t / tau).exp() * (2.0 * PI * 2.3 * t).cos() + noise * e
        })
        .collect();
    // A second channel that is settled from the start: the step must wait for the first one.
    let y: Vec<f64> = (0..LEN)
        .map(|k| (2.0 * PI * F * k as f64 / FS).sin())
        .collect();
    record(
        vec![(Channel::ForceN, y), (Channel::RelativeDisplacementM, x)],
        FS,
        F,
    )
}

#[test]
fn decaying_transient_is_left_out() {
    let (amp, tau) = (2.0, 1.0);
    let opts = PhasorOptions::default();
    let tol = opts.settle_relative_tolerance;
    let a = analyse_record(&transient_record(amp, tau, 0.0, 0), &opts).unwrap();
    let c = periodic();
    let scale = c[1..].iter().map(Complex64::norm_sqr).sum::<f64>().sqrt();
    let t0 = a.first_settled_sample as f64 / FS;
    let env = |t: f64| amp * (-t / tau).exp() / scale;
    println!(
        "settled from sample {} (t = {t0:.3} s, {} of {} periods), envelope there {:.2e} of the AC amplitude",
        a.first_settled_sample,
        a.periods_used,
        a.periods_available,
        env(t0)
    );
    assert!(a.settled);
    // Started after the transient decayed to about the tolerance ...
    assert!(
        env(t0) < 3.0 * tol,
        "envelope {:e} at the start of the settled part",
        env(t0)
    );
    // ... but not much later (within two periods).
    assert!(
        env(t0 - 2.0 / F) > tol,
        "waited too long: envelope two periods earlier {:e}",
        env(t0 - 2.0 / F)
    );
    let ch = a.channel(Channel::RelativeDisplacementM).unwrap();
    let e = rel_err(&ch.phasors, &c, scale);
    println!("phasor error relative to the AC amplitude: {e:.2e}");
    assert!(e < 3e-5, "{e:e}");
    // The channel without a transient alone would be settled from period 0; jointly it is not.
    assert!(a.first_settled_sample > 0);
}

#[test]
fn decaying_transient_in_noise_settles_at_the_noise_level() {
    let (amp, tau, sigma) = (2.0, 1.0, 1e-3);
    let opts = PhasorOptions::default();
    let c = periodic();
    // Per-period phasor noise 2 sigma / sqrt(62.5) = 2.5e-4; k = 4 puts the threshold near 1e-3.
    let per_period = 2.0 * sigma / (FS / F).sqrt();
    let (mut worst, mut worst_env) = (0.0f64, 0.0f64);
    for seed in 0..20 {
        let a = analyse_record(&transient_record(amp, tau, sigma, seed), &opts).unwrap();
        assert!(a.settled);
        let t0 = a.first_settled_sample as f64 / FS;
        let env = amp * (-t0 / tau).exp();
        worst_env = worst_env.max(env / per_period);
        // Transient below a few per-period noise deviations where the settled part starts (the
        // envelope at the period start is ~2x the transient's per-period phasor; k = 4 plus the
        // noise of the tested period allow ~5 deviations of that).
        assert!(
            env < 12.0 * per_period,
            "seed {seed}: envelope {env:e} at t0 = {t0}"
        );
        assert!(
            amp * (-(t0 - 3.0 / F) / tau).exp() > per_period,
            "seed {seed}: waited too long (t0 = {t0})"
        );
        let ch = a.channel(Channel::RelativeDisplacementM).unwrap();
        // Error within 4 standard errors of the noise estimate (+ transient left in).
        let e1 = (ch.phasors[1] - c[1]).norm();
        worst = worst.max(e1 / ch.noise_std[1]);
        assert!(
            e1 < 4.0 * ch.noise_std[1] + 2e-4,
            "seed {seed}: |dC1| = {e1:e}, noise_std {:e}",
            ch.noise_std[1]
        );
    }
    println!(
        "noisy transient: worst |dC1| / noise_std[1] = {worst:.2}; worst envelope at t0 / per-period noise = {worst_env:.2}"
    );
}

/// m x'' + c x' + k x = F cos(w t), x(0) = x'(0) = 0, exact solution sampled.
fn oscillator(fs: f64, f: f64, len: usize, zeta: f64, fn_hz: f64) -> (Record, Complex64) {
    let (m, force) = (2.0, 3.0);
    let wn = 2.0 * PI * fn_hz;
    let (k, c) = (m * wn * wn, 2.0 * zeta * m * wn);
    let w = 2.0 * PI * f;
    let x_ss = force / Complex64::new(k - m * w * w, c * w);
    let sigma = c / (2.0 * m);
    let wd = (k / m - sigma * sigma).sqrt();
    let a0 = -x_ss.re;
    let b0 = (w * x_ss.im + sigma * a0) / wd;
    let (mut x, mut acc, mut fch) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..len {
        let t = i as f64 / fs;
        let e = (-sigma * t).exp();
        let (s, co) = (wd * t).sin_cos();
        let xh = e * (a0 * co + b0 * s);
        let vh = e * (-sigma * (a0 * co + b0 * s) + wd * (-a0 * s + b0 * co));
        let z = Complex64::from_polar(1.0, w * t);
        let xt = xh + (x_ss * z).re;
        let vt = vh + (Complex64::new(0.0, w) * x_ss * z).re;
        let ft = force * (w * t).cos();
        x.push(xt);
        acc.push((ft - c * vt - k * xt) / m);
        fch.push(ft);
    }
    let r = record(
        vec![
            (Channel::ForceN, fch),
            (Channel::MassDisplacementM, x),
            (Channel::MassAccelerationMps2, acc),
        ],
        fs,
        f,
    );
    (r, x_ss)
}

#[test]
fn linear_oscillator_matches_closed_form_steady_state() {
    // f_n = 2 Hz, zeta = 0.1, driven at 1.6 Hz: the transient decays by e^{-1.26 t}.
    let opts = PhasorOptions::default();
    for (fs, f, len, zeta) in [
        (FS, F, LEN, 0.1),
        (FS, F, LEN, 0.2),
        (10_000.0, 1.7, 130_000, 0.1),
        (FS, 2.6, LEN, 0.1),
    ] {
        let (r, x_ss) = oscillator(fs, f, len, zeta, 2.0);
        let a = analyse_record(&r, &opts).unwrap();
        assert!(a.settled);
        let w = 2.0 * PI * f;
        let disp = &a.channel(Channel::MassDisplacementM).unwrap().phasors;
        let acc = &a.channel(Channel::MassAccelerationMps2).unwrap().phasors;
        let e_x = rel_err(disp, &[Complex64::new(0.0, 0.0), x_ss], x_ss.norm());
        let e_a = rel_err(
            acc,
            &[Complex64::new(0.0, 0.0), -w * w * x_ss],
            w * w * x_ss.norm(),
        );
        println!(
            "oscillator fs {fs} f {f} zeta {zeta}: settled from period {} ({} used), max rel error displacement {e_x:.2e}, acceleration {e_a:.2e}",
            a.periods_available - a.periods_used,
            a.periods_used,
        );
        assert!(e_x < 1e-4 && e_a < 1e-4, "{e_x:e} {e_a:e}");
        assert!(a.periods_used >= 4);
        // A looser settling tolerance leaves proportionally more transient in.
        let loose = PhasorOptions {
            settle_relative_tolerance: 1e-3,
            ..opts.clone()
        };
        let b = analyse_record(&r, &loose).unwrap();
        let e_loose = rel_err(
            &b.channel(Channel::MassDisplacementM).unwrap().phasors,
            &[Complex64::new(0.0, 0.0), x_ss],
            x_ss.norm(),
        );
        println!(
            "    with settle_relative_tolerance 1e-3: {} periods used, displacement error {e_loose:.2e}",
            b.periods_used
        );
        assert!(e_loose < 1e-3);
    }
}

#[test]
fn unsettled_record_is_flagged_and_still_analysed() {
    // Transient that never decays within the record.
    let (r, _) = oscillator(FS, F, LEN, 0.005, 2.0);
    let a = analyse_record(&r, &PhasorOptions::default()).unwrap();
    assert!(!a.settled);
    assert_eq!(a.periods_used, 2);
    assert_eq!(a.first_settled_sample, 1125); // ceil(18 * 62.5)
    assert!((a.t_ref_s - (12.5 + 18.0 / F)).abs() < 1e-12);
}

#[test]
fn noise_std_matches_theoretical_standard_error() {
    // White noise sigma on a sine, no transient: 20 whole periods, S = 1250 samples used.
    let sigma = 0.01;
    let c = [Complex64::new(0.5, 0.0), Complex64::from_polar(1.0, 0.7)];
    let opts = PhasorOptions {
        max_harmonic: 5,
        ..PhasorOptions::default()
    };
    let seeds = 300;
    let (mut ms_reported, mut ms_error, mut ms_reported_dc, mut ms_error_dc, mut ms_h3) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut full = 0;
    for seed in 0..seeds {
        let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
        let x: Vec<f64> = (0..LEN)
            .map(|k| {
                let e: f64 = rng.sample(StandardNormal);
                synthesize(&c, F, k as f64 / FS) + sigma * e
            })
            .collect();
        let a = analyse_record(
            &record(vec![(Channel::RelativeDisplacementM, x)], FS, F),
            &opts,
        )
        .unwrap();
        assert!(a.settled);
        let s = a.samples_used as f64;
        let ch = &a.channels[0];
        // Normalise by the theory for the number of samples actually used.
        let th1 = 2.0 * sigma / s.sqrt();
        let th0 = sigma / s.sqrt();
        ms_reported += (ch.noise_std[1] / th1).powi(2);
        ms_error += ((ch.phasors[1] - c[1]).norm() / th1).powi(2);
        ms_reported_dc += (ch.noise_std[0] / th0).powi(2);
        ms_error_dc += ((ch.phasors[0] - c[0]).norm() / th0).powi(2);
        ms_h3 += (ch.noise_std[3] / th1).powi(2);
        if a.periods_used == a.periods_available {
            full += 1;
        }
    }
    let n = seeds as f64;
    let (r1, e1, r0, e0, r3) = (
        (ms_reported / n).sqrt(),
        (ms_error / n).sqrt(),
        (ms_reported_dc / n).sqrt(),
        (ms_error_dc / n).sqrt(),
        (ms_h3 / n).sqrt(),
    );
    println!(
        "RMS over {seeds} seeds / theory: noise_std[1] {r1:.3}, actual |dC1| {e1:.3}, noise_std[0] {r0:.3}, |dC0| {e0:.3}, noise_std[3] {r3:.3}; all periods used in {full}/{seeds}"
    );
    for (name, v) in [
        ("noise_std[1]", r1),
        ("|dC1|", e1),
        ("noise_std[0]", r0),
        ("|dC0|", e0),
        ("noise_std[3]", r3),
    ] {
        assert!((v - 1.0).abs() < 0.2, "{name}: {v}");
    }
    assert!(
        full as f64 >= 0.95 * n,
        "a settled noisy record was truncated in {} of {seeds} seeds",
        seeds - full
    );
}
