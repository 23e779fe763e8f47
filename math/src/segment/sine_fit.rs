//! The frequency of one sine in noise: the peak of a zero-padded DFT, refined by parabolic
//! interpolation, then a nonlinear least-squares fit of `c + a cos(w t) + b sin(w t)`
//! (Gauss-Newton in all four parameters). The least-squares fit is the maximum-likelihood
//! estimator for white Gaussian noise and reaches the Cramer-Rao bound
//! `var(w) = 12 sigma^2 / (A^2 n (n^2 - 1))` (rad/sample) at moderate SNR; the DFT peak alone
//! is only accurate to a fraction of a bin. The standard deviation reported is the fit's own
//! (residual variance times the inverse normal matrix), which matches the bound.

use std::f64::consts::PI;
use std::sync::Arc;

use nalgebra::{Matrix4, Vector4};
use num_complex::Complex64;
use rustfft::Fft;

/// Zero-padding factor of the initial DFT: the interpolated peak is then within a small
/// fraction of a bin of the true frequency, well inside Gauss-Newton's basin.
const ZERO_PAD: usize = 4;
/// Gauss-Newton stops when the frequency moves less than this (relative) in one iteration.
const CONVERGED_REL: f64 = 1e-13;

/// A sine fitted to a stretch of samples. Time `t` is in samples from `origin` (an absolute
/// sample index of the series the stretch came from), so [`SineFit::eval`] extrapolates the
/// fitted sine to any sample of the series.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineFit {
    /// Angular frequency [rad/sample].
    pub omega: f64,
    /// Its standard deviation [rad/sample] from the residual and the fit's normal matrix.
    pub omega_std: f64,
    /// `x ~ dc + cos_coef cos(omega (n - origin)) + sin_coef sin(omega (n - origin))`.
    pub dc: f64,
    pub cos_coef: f64,
    pub sin_coef: f64,
    pub origin: f64,
    /// RMS of the residual per sample.
    pub residual_rms: f64,
    /// RMS of the samples about their mean.
    pub total_rms: f64,
    /// Samples fitted.
    pub samples: usize,
}

impl SineFit {
    pub fn amplitude(&self) -> f64 {
        self.cos_coef.hypot(self.sin_coef)
    }

    /// Standard deviation of the amplitude (`sigma sqrt(2 / n)` for white noise).
    pub fn amplitude_std(&self) -> f64 {
        self.residual_rms * (2.0 / self.samples.max(1) as f64).sqrt()
    }

    /// The fitted sine at absolute sample index `n`.
    pub fn eval(&self, n: f64) -> f64 {
        let (s, c) = (self.omega * (n - self.origin)).sin_cos();
        self.dc + self.cos_coef * c + self.sin_coef * s
    }

    /// Fraction of the variance the sine leaves unexplained (0: a clean sine, ~1: no sine).
    pub fn unexplained(&self) -> f64 {
        if self.total_rms > 0.0 {
            (self.residual_rms / self.total_rms).powi(2)
        } else {
            1.0
        }
    }

    /// Frequency [Hz] at `sample_rate_hz`.
    pub fn frequency_hz(&self, sample_rate_hz: f64) -> f64 {
        self.omega * sample_rate_hz / (2.0 * PI)
    }
}

/// DFT plans by length, so that the many windows of a segmentation share them (kept here as
/// well as by `signal::fft`, which builds plans longer than its limit afresh: a segmentation's
/// padded windows can be longer).
pub struct SineFitter {
    plans: Vec<(usize, Arc<dyn Fft<f64>>)>,
}

impl Default for SineFitter {
    fn default() -> Self {
        SineFitter::new()
    }
}

impl SineFitter {
    pub fn new() -> SineFitter {
        SineFitter { plans: Vec::new() }
    }

    fn plan(&mut self, len: usize) -> Arc<dyn Fft<f64>> {
        if let Some((_, p)) = self.plans.iter().find(|(l, _)| *l == len) {
            return Arc::clone(p);
        }
        let p = crate::signal::fft::forward(len);
        self.plans.push((len, Arc::clone(&p)));
        p
    }

    /// The initial frequency [rad/sample]: the interpolated peak of the zero-padded DFT of
    /// `x` minus its mean (DC bin excluded). `None` for fewer than 4 samples or a constant.
    pub fn dft_peak(&mut self, x: &[f64]) -> Option<f64> {
        let n = x.len();
        if n < 4 {
            return None;
        }
        let mean = x.iter().sum::<f64>() / n as f64;
        let m = (ZERO_PAD * n).next_power_of_two();
        let mut buf: Vec<Complex64> = x
            .iter()
            .map(|v| Complex64::new(v - mean, 0.0))
            .chain(std::iter::repeat(Complex64::new(0.0, 0.0)))
            .take(m)
            .collect();
        self.plan(m).process(&mut buf);
        let power: Vec<f64> = buf[..=m / 2].iter().map(Complex64::norm_sqr).collect();
        // Skip the main lobe of DC (what is left of a trend after removing the mean).
        let first = ZERO_PAD.min(m / 2);
        let (k, &peak) = power
            .iter()
            .enumerate()
            .skip(first)
            .max_by(|a, b| a.1.total_cmp(b.1))?;
        if peak <= 0.0 {
            return None;
        }
        let mut delta = 0.0;
        if k > first && k < m / 2 {
            // Parabola through the magnitudes of the peak bin and its neighbours.
            let (a, b, c) = (power[k - 1].sqrt(), peak.sqrt(), power[k + 1].sqrt());
            let den = a - 2.0 * b + c;
            if den < 0.0 {
                delta = (0.5 * (a - c) / den).clamp(-0.5, 0.5);
            }
        }
        Some(2.0 * PI * (k as f64 + delta) / m as f64)
    }

    /// Fits one sine to `x`, whose first sample is sample `first_index` of its series, with
    /// at most `max_iterations` Gauss-Newton steps. `None` when there is no sine to fit
    /// (fewer than 8 samples, a constant, or a singular fit).
    pub fn fit(&mut self, x: &[f64], first_index: usize, max_iterations: usize) -> Option<SineFit> {
        let n = x.len();
        if n < 8 {
            return None;
        }
        let omega0 = self.dft_peak(x)?;
        fit_from(x, first_index, omega0, max_iterations)
    }
}

/// Gauss-Newton from `omega0` (time centred on the stretch for conditioning).
///
/// The sines and cosines of a frequency are computed once and shared by the linear fit, the
/// cost and the normal equations at that frequency (the accepted trial's are the next
/// iteration's): the same operations as evaluating them in each, half the phases.
pub(crate) fn fit_from(
    x: &[f64],
    first_index: usize,
    omega0: f64,
    max_iterations: usize,
) -> Option<SineFit> {
    let n = x.len();
    let centre = (n as f64 - 1.0) / 2.0;
    let mut omega = omega0;
    let mut phases = Vec::with_capacity(n);
    let mut trial_phases = Vec::with_capacity(n);
    fill_phases(n, centre, omega, &mut phases);
    let (mut dc, mut a, mut b) = linear_fit(x, &phases)?;
    let mut cost = cost_of(x, &phases, [dc, a, b]);
    let mut normal = Matrix4::zeros();
    for _ in 0..max_iterations {
        // The upper triangle of `sum g g^T` and `sum g r`, each entry summed in sample order
        // as `normal += g * g.transpose()` sums it (the lower triangle is the same products).
        let mut upper = [0.0; 10];
        let mut rhs_sum = [0.0; 4];
        for (j, (&v, &(s, c))) in x.iter().zip(&phases).enumerate() {
            let t = j as f64 - centre;
            let r = v - (dc + a * c + b * s);
            let g = [1.0, c, s, t * (b * c - a * s)];
            let mut k = 0;
            for p in 0..4 {
                for q in p..4 {
                    upper[k] += g[p] * g[q];
                    k += 1;
                }
                rhs_sum[p] += g[p] * r;
            }
        }
        let mut k = 0;
        for p in 0..4 {
            for q in p..4 {
                normal[(p, q)] = upper[k];
                normal[(q, p)] = upper[k];
                k += 1;
            }
        }
        let rhs = Vector4::from(rhs_sum);
        let step = normal.cholesky()?.solve(&rhs);
        // Halve the step until the cost does not grow (Gauss-Newton is undamped otherwise).
        let mut scale = 1.0;
        let mut accepted = false;
        for _ in 0..20 {
            let trial = [
                dc + scale * step[0],
                a + scale * step[1],
                b + scale * step[2],
                omega + scale * step[3],
            ];
            fill_phases(n, centre, trial[3], &mut trial_phases);
            let c = cost_of(x, &trial_phases, [trial[0], trial[1], trial[2]]);
            if c <= cost {
                [dc, a, b, omega] = trial;
                cost = c;
                std::mem::swap(&mut phases, &mut trial_phases);
                accepted = true;
                break;
            }
            scale *= 0.5;
        }
        if !accepted || (scale * step[3]).abs() <= CONVERGED_REL * omega.abs() {
            break;
        }
    }
    if omega < 0.0 {
        // The same sine with a positive frequency.
        omega = -omega;
        b = -b;
    }
    let dof = n.saturating_sub(4).max(1) as f64;
    let residual_var = cost / dof;
    let omega_var = normal
        .try_inverse()
        .map_or(f64::INFINITY, |inv| (inv[(3, 3)] * residual_var).max(0.0));
    let mean = x.iter().sum::<f64>() / n as f64;
    let total_var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
    Some(SineFit {
        omega,
        omega_std: omega_var.sqrt(),
        dc,
        cos_coef: a,
        sin_coef: b,
        origin: first_index as f64 + centre,
        residual_rms: (cost / n as f64).sqrt(),
        total_rms: total_var.sqrt(),
        samples: n,
    })
}

/// Samples between exact `sin_cos` evaluations of a stretch's phases. In between, each phase is
/// the one before turned by `omega` (a complex product, a few multiplications instead of a
/// `sin_cos`): the phases differ from `sin_cos` of `omega (j - centre)` by less than 1e-14 plus
/// the rounding of that argument itself (a few of its ulps; the test checks it), far below the
/// noise of any drive.
const RESYNC_SAMPLES: usize = 32;

/// `(sin, cos)` of `omega (j - centre)` for the samples `j` of a stretch of `n`: exact every
/// [`RESYNC_SAMPLES`] samples, turned by `omega` between. The times are symmetric about the
/// centre (`j - centre` is exactly `-(n - 1 - j - centre)`), so the first half is the second's
/// with the sine negated (sine is odd and cosine even).
fn fill_phases(n: usize, centre: f64, omega: f64, out: &mut Vec<(f64, f64)>) {
    out.clear();
    out.resize(n, (0.0, 0.0));
    let half = n / 2;
    let (turn_sin, turn_cos) = omega.sin_cos();
    for (k, part) in out[half..].chunks_mut(RESYNC_SAMPLES).enumerate() {
        let j = half + k * RESYNC_SAMPLES;
        let (mut s, mut c) = (omega * (j as f64 - centre)).sin_cos();
        for p in part {
            *p = (s, c);
            (s, c) = (s * turn_cos + c * turn_sin, c * turn_cos - s * turn_sin);
        }
    }
    for j in 0..half {
        let (s, c) = out[n - 1 - j];
        out[j] = (-s, c);
    }
}

/// The DC, cosine and sine coefficients at the frequency of `phases`.
fn linear_fit(x: &[f64], phases: &[(f64, f64)]) -> Option<(f64, f64, f64)> {
    let mut normal = nalgebra::Matrix3::zeros();
    let mut rhs = nalgebra::Vector3::zeros();
    for (&v, &(s, c)) in x.iter().zip(phases) {
        let g = nalgebra::Vector3::new(1.0, c, s);
        normal += g * g.transpose();
        rhs += g * v;
    }
    let p = normal.cholesky()?.solve(&rhs);
    Some((p[0], p[1], p[2]))
}

fn cost_of(x: &[f64], phases: &[(f64, f64)], [dc, a, b]: [f64; 3]) -> f64 {
    x.iter()
        .zip(phases)
        .map(|(&v, &(s, c))| (v - (dc + a * c + b * s)).powi(2))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit without shared phases, the reference the shared ones are checked against: every
    /// linear fit, cost and normal matrix computes its own phases of every sample.
    fn reference_fit(x: &[f64], omega0: f64, max_iterations: usize) -> Option<[f64; 6]> {
        let n = x.len();
        let centre = (n as f64 - 1.0) / 2.0;
        let phases = |omega: f64| -> Vec<(f64, f64)> {
            let mut p = Vec::new();
            fill_phases(n, centre, omega, &mut p);
            p
        };
        let mut omega = omega0;
        let (mut dc, mut a, mut b) = linear_fit(x, &phases(omega))?;
        let mut cost = cost_of(x, &phases(omega), [dc, a, b]);
        for _ in 0..max_iterations {
            let mut rhs = Vector4::zeros();
            let mut normal = Matrix4::zeros();
            for (j, (&v, &(s, c))) in x.iter().zip(&phases(omega)).enumerate() {
                let t = j as f64 - centre;
                let r = v - (dc + a * c + b * s);
                let g = Vector4::new(1.0, c, s, t * (b * c - a * s));
                normal += g * g.transpose();
                rhs += g * r;
            }
            let step = normal.cholesky()?.solve(&rhs);
            let mut scale = 1.0;
            let mut accepted = false;
            for _ in 0..20 {
                let trial = [
                    dc + scale * step[0],
                    a + scale * step[1],
                    b + scale * step[2],
                    omega + scale * step[3],
                ];
                let c = cost_of(x, &phases(trial[3]), [trial[0], trial[1], trial[2]]);
                if c <= cost {
                    [dc, a, b, omega] = trial;
                    cost = c;
                    accepted = true;
                    break;
                }
                scale *= 0.5;
            }
            if !accepted || (scale * step[3]).abs() <= CONVERGED_REL * omega.abs() {
                break;
            }
        }
        Some([omega, dc, a, b, cost, 0.0])
    }

    #[test]
    fn shared_phases_give_the_fit_bit_for_bit() {
        // Noisy sines (a deterministic pseudo-random sequence), started off the true frequency.
        let mut state = 12345u64;
        let mut noise = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for (n, omega, offset) in [
            (200, 0.31, 0.01),
            (651, 0.0503, -0.002),
            (1300, 1.7, 0.004),
            (97, 2.9, -0.02),
        ] {
            let x: Vec<f64> = (0..n)
                .map(|j| 0.3 + 2.0 * (omega * j as f64 + 0.7).sin() + 0.05 * noise())
                .collect();
            let fit = fit_from(&x, 17, omega + offset, 50).expect("a sine");
            let [w, dc, a, b, cost, _] = reference_fit(&x, omega + offset, 50).expect("a sine");
            assert_eq!(fit.omega.to_bits(), w.abs().to_bits(), "n {n}");
            assert_eq!(fit.dc.to_bits(), dc.to_bits());
            assert_eq!(fit.cos_coef.to_bits(), a.to_bits());
            assert_eq!(
                fit.sin_coef.to_bits(),
                (if w < 0.0 { -b } else { b }).to_bits()
            );
            assert_eq!(
                fit.residual_rms.to_bits(),
                (cost / n as f64).sqrt().to_bits()
            );
        }
    }

    /// Largest difference between a phase of [`fill_phases`] and `sin_cos` of its argument,
    /// less the argument's own rounding (`ARGUMENT_ULPS` of its ulps).
    const PHASE_ERROR_BOUND: f64 = 1e-14;
    const ARGUMENT_ULPS: f64 = 4.0;

    #[test]
    fn phases_are_sin_cos_within_the_bound() {
        let mut phases = Vec::new();
        for n in [8, 9, 33, 97, 200, 651, 1300, 4001, 20_000] {
            let centre = (n as f64 - 1.0) / 2.0;
            for omega in [1e-4, 0.0503, 0.31, 1.0, 1.7, 2.9, 3.1, -0.7] {
                fill_phases(n, centre, omega, &mut phases);
                for (j, &(s, c)) in phases.iter().enumerate() {
                    let arg = omega * (j as f64 - centre);
                    let (es, ec) = arg.sin_cos();
                    let err = (s - es).abs().max((c - ec).abs());
                    assert!(
                        err <= PHASE_ERROR_BOUND + ARGUMENT_ULPS * f64::EPSILON * arg.abs(),
                        "n {n}, omega {omega}, sample {j}: {err:e}"
                    );
                }
            }
        }
    }
}
