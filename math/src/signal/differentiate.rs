//! Derivatives of sampled signals: central differences, one-sided at the ends, and the
//! band-limited derivative in the frequency domain (held-out element records).
//!
//! Two roundings of the same derivative exist because each user's results were computed with
//! one of them: they differ in the last bits only, which would still change the EMPS figures
//! or the rig diagnosis if one replaced the other.

/// Central differences, one-sided at the ends, dividing by the step: `(x[i+1] - x[i-1]) /
/// (2 dt)`. Fewer than two samples give zeros. The time-domain path's (the EMPS
/// identification script's `diffcent`).
pub fn central_difference(x: &[f64], dt: f64) -> Vec<f64> {
    let n = x.len();
    if n < 2 {
        return vec![0.0; n];
    }
    (0..n)
        .map(|i| {
            let (lo, hi) = (i.saturating_sub(1), (i + 1).min(n - 1));
            (x[hi] - x[lo]) / ((hi - lo) as f64 * dt)
        })
        .collect()
}

/// Central differences, one-sided at the ends, multiplying by the rate: `(x[i+1] - x[i-1]) *
/// fs / 2`. One sample gives zero. The rig diagnosis's scoring (`diagnose::score`: undoing a
/// sensor low-pass on the base input).
pub fn central_difference_at_rate(x: &[f64], sample_rate_hz: f64) -> Vec<f64> {
    let n = x.len();
    (0..n)
        .map(|i| {
            let lo = i.saturating_sub(1);
            let hi = (i + 1).min(n - 1);
            (x[hi] - x[lo]) * sample_rate_hz / (hi - lo).max(1) as f64
        })
        .collect()
}

/// First and second derivatives by sixth-order central stencils, multiplying by the rate
/// (fourth and second order one and two samples from the ends, one-sided second order at the
/// first and last sample). On a sine the stencils fall short by about (w h)^6 / 140 and
/// (w h)^6 / 560 (h the sample step): 0.04 % and 0.01 % at 10 Hz sampled at 100 Hz, where two
/// central differences in a row fall 12.5 % short. Local, unlike the frequency domain's
/// derivative, which wraps the record. The rig diagnosis's held-out sensor undo
/// (`diagnose::sensor::undo_samples`).
pub fn sixth_order_derivatives(x: &[f64], sample_rate_hz: f64) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let (fs, fs2) = (sample_rate_hz, sample_rate_hz * sample_rate_hz);
    if n < 4 {
        let d1 = central_difference_at_rate(x, fs);
        let d2 = central_difference_at_rate(&d1, fs);
        return (d1, d2);
    }
    // The k-th sample inward from sample i's nearer end (i itself at k = 0).
    let inward = |i: usize, k: usize| if i == 0 { x[k] } else { x[n - 1 - k] };
    let d1 = |i: usize| {
        let a = |k: usize| x[i + k] - x[i - k];
        match i.min(n - 1 - i) {
            0 => {
                let sign = if i == 0 { 1.0 } else { -1.0 };
                sign * (-3.0 * inward(i, 0) + 4.0 * inward(i, 1) - inward(i, 2)) * fs / 2.0
            }
            1 => a(1) * fs / 2.0,
            2 => (8.0 * a(1) - a(2)) * fs / 12.0,
            _ => (45.0 * a(1) - 9.0 * a(2) + a(3)) * fs / 60.0,
        }
    };
    let d2 = |i: usize| {
        let s = |k: usize| x[i + k] + x[i - k] - 2.0 * x[i];
        match i.min(n - 1 - i) {
            0 => {
                (2.0 * inward(i, 0) - 5.0 * inward(i, 1) + 4.0 * inward(i, 2) - inward(i, 3)) * fs2
            }
            1 => s(1) * fs2,
            2 => (16.0 * s(1) - s(2)) * fs2 / 12.0,
            _ => (270.0 * s(1) - 27.0 * s(2) + 2.0 * s(3)) * fs2 / 180.0,
        }
    };
    ((0..n).map(d1).collect(), (0..n).map(d2).collect())
}

/// The DFT of `y` (at least two samples) with the straight line through its end points taken
/// out, so that a record that does not wrap leaks no step into the spectrum.
pub fn detrended_spectrum(y: &[f64]) -> Vec<num_complex::Complex64> {
    let n = y.len();
    let slope = (y[n - 1] - y[0]) / (n - 1) as f64;
    let mut buf: Vec<num_complex::Complex64> = y
        .iter()
        .enumerate()
        .map(|(i, v)| num_complex::Complex64::new(v - y[0] - slope * i as f64, 0.0))
        .collect();
    super::fft::forward(n).process(&mut buf);
    buf
}

/// `order`-th derivative of `y` (sampled at `fs`) in the frequency domain, bins above
/// `cutoff_hz` dropped; the straight line through the end points is taken out first (and given
/// back to `y` itself at order 0, its slope to the first derivative) so the record wraps
/// without a jump. Order 0 is a zero-phase low-pass with no loss in its pass band.
pub fn band_limited_derivative(y: &[f64], fs: f64, cutoff_hz: f64, order: u32) -> Vec<f64> {
    let n = y.len();
    let slope = (y[n - 1] - y[0]) / (n - 1) as f64;
    let mut buf = detrended_spectrum(y);
    for (k, b) in buf.iter_mut().enumerate() {
        // Signed bin frequency.
        let kk = if k <= n / 2 {
            k as f64
        } else {
            k as f64 - n as f64
        };
        let f = kk * fs / n as f64;
        if f.abs() > cutoff_hz || (n.is_multiple_of(2) && k == n / 2) {
            *b = num_complex::Complex64::new(0.0, 0.0);
        } else {
            *b *=
                num_complex::Complex64::new(0.0, std::f64::consts::TAU * f).powu(order) / n as f64;
        }
    }
    super::fft::inverse(n).process(&mut buf);
    buf.iter()
        .enumerate()
        .map(|(i, b)| {
            b.re + match order {
                0 => y[0] + slope * i as f64,
                1 => slope * fs,
                _ => 0.0,
            }
        })
        .collect()
}

/// The std of [`band_limited_derivative`] of white noise of unit std over `n` samples: the
/// root of the mean over the bins it keeps of `(2 pi f)^(2 order)`. The same bins as the
/// derivative keeps, so a record's derivative noise is its own noise std times this.
pub fn derivative_noise_gain(n: usize, fs: f64, cutoff_hz: f64, order: u32) -> f64 {
    let kept: f64 = (0..n)
        .filter(|&k| !(n.is_multiple_of(2) && k == n / 2))
        .map(|k| {
            let kk = if k <= n / 2 {
                k as f64
            } else {
                k as f64 - n as f64
            };
            kk * fs / n as f64
        })
        .filter(|f| f.abs() <= cutoff_hz)
        .map(|f| (std::f64::consts::TAU * f).powi(2 * order as i32))
        .sum();
    (kept / n as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// White noise of std 0.01 at 1 kHz differentiated in a 40 Hz band: the velocity's and
    /// the acceleration's std within 5 % of the gain's (the estimate's own scatter over 20 000
    /// samples is about 1 %; the line taken out through the two noisy end points leaves a
    /// sawtooth whose spectrum, weighted by f^4, adds to the acceleration's: 3.1 % here).
    #[test]
    fn the_noise_gain_is_the_std_of_differentiated_white_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let normal = Normal::new(0.0, 0.01).unwrap();
        let (n, fs, cutoff) = (20_000, 1000.0, 40.0);
        let y: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        for order in [1, 2] {
            let d = band_limited_derivative(&y, fs, cutoff, order);
            let std = (d.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
            let gain = derivative_noise_gain(n, fs, cutoff, order);
            assert!(
                (std / (0.01 * gain) - 1.0).abs() < 0.05,
                "{order}: {std} {gain}"
            );
        }
    }

    #[test]
    fn both_roundings_differentiate_a_parabola_exactly_inside_and_one_sided_at_the_ends() {
        let x: Vec<f64> = (0..6).map(|i| (i * i) as f64).collect();
        for d in [
            central_difference(&x, 0.5),
            central_difference_at_rate(&x, 2.0),
        ] {
            assert_eq!(d, vec![2.0, 4.0, 8.0, 12.0, 16.0, 18.0]);
        }
        assert_eq!(central_difference(&[1.0], 0.1), vec![0.0]);
        assert_eq!(central_difference_at_rate(&[1.0], 10.0), vec![0.0]);
    }

    #[test]
    fn the_sixth_order_derivatives_of_a_sine_are_its_derivatives_times_the_stencils_gains() {
        // 10 Hz at 100 Hz (wh = w h = 0.63): inside, the derivatives times the stencils' gains
        // in closed form, each within 0.05 % of 1; a cubic's second derivative exact everywhere,
        // its first two samples or more from the ends (nearer, the stencils are second order).
        let (fs, f) = (100.0, 10.0);
        let w = std::f64::consts::TAU * f;
        let wh = w / fs;
        let g1 = (45.0 * wh.sin() - 9.0 * (2.0 * wh).sin() + (3.0 * wh).sin()) / (30.0 * wh);
        let g2 = -(270.0 * (2.0 * wh.cos() - 2.0) - 27.0 * (2.0 * (2.0 * wh).cos() - 2.0)
            + 2.0 * (2.0 * (3.0 * wh).cos() - 2.0))
            / (180.0 * wh * wh);
        assert!(
            (1.0 - g1).abs() < 5e-4 && (1.0 - g2).abs() < 5e-4,
            "{g1} {g2}"
        );
        let x: Vec<f64> = (0..200).map(|i| (w * i as f64 / fs + 0.3).sin()).collect();
        let (v, a) = sixth_order_derivatives(&x, fs);
        for i in 3..197 {
            let t = i as f64 / fs;
            let want = g1 * w * (w * t + 0.3).cos();
            assert!((v[i] - want).abs() < 1e-9 * w, "{i}: {} vs {want}", v[i]);
            let want = -g2 * w * w * (w * t + 0.3).sin();
            assert!(
                (a[i] - want).abs() < 1e-9 * w * w,
                "{i}: {} vs {want}",
                a[i]
            );
        }
        let p: Vec<f64> = (0..8)
            .map(|i| {
                let t = i as f64 / 2.0;
                1.0 + 2.0 * t - 0.5 * t * t + 0.1 * t * t * t
            })
            .collect();
        let (v, a) = sixth_order_derivatives(&p, 2.0);
        for i in 0..8 {
            let t = i as f64 / 2.0;
            let (dv, da) = (2.0 - t + 0.3 * t * t, -1.0 + 0.6 * t);
            if (2..6).contains(&i) {
                assert!((v[i] - dv).abs() < 1e-12, "{i}: {} vs {dv}", v[i]);
            }
            assert!((a[i] - da).abs() < 1e-12, "{i}: {} vs {da}", a[i]);
        }
        // The ends' one-sided first derivative is exact on a parabola.
        let q: Vec<f64> = (0..6).map(|i| (i * i) as f64).collect();
        let (v, _) = sixth_order_derivatives(&q, 1.0);
        assert!(
            (v[0] - 0.0).abs() < 1e-12 && (v[5] - 10.0).abs() < 1e-12,
            "{v:?}"
        );
    }

    #[test]
    fn the_band_limited_derivative_of_a_non_periodic_sine_is_its_cosine() {
        // 7.3 Hz over 10 s at 1 kHz plus an offset and a ramp: not periodic.
        let fs = 1000.0;
        let w = std::f64::consts::TAU * 7.3;
        let y: Vec<f64> = (0..10_000)
            .map(|i| {
                let t = i as f64 / fs;
                0.2 + 0.05 * t + (w * t).sin()
            })
            .collect();
        let (v, a) = (
            band_limited_derivative(&y, fs, 30.0, 1),
            band_limited_derivative(&y, fs, 30.0, 2),
        );
        for i in 500..9500 {
            let t = i as f64 / fs;
            let want = 0.05 + w * (w * t).cos();
            assert!((v[i] - want).abs() < 0.01 * w, "{i}: {} vs {want}", v[i]);
            let want = -w * w * (w * t).sin();
            assert!(
                (a[i] - want).abs() < 0.01 * w * w,
                "{i}: {} vs {want}",
                a[i]
            );
        }
    }
}
