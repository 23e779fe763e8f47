//! How the improved method weighs a step's real equations, and what its rows say of the fit's
//! quality against the noise.
//!
//! A step's rows are the real and imaginary parts of harmonics 0..N of `G_n = Y_n theta +
//! Q_n q` (the stick-force columns `Q`, per step, projected out). Row `i` misses its right-hand
//! side by the measurement noise, of standard deviation `sigma_i` (from the scatter between
//! periods), and by what the model's form cannot describe. With [`Weighting::Robust`] (the
//! default) the latter is a variance `tau^2` of the step, the same on every row (a form error
//! is not known to favour any harmonic), estimated from the step's own fit:
//!
//! 1. The step's rows weighted by `1 / sigma_i` are fitted by least squares in every column
//!    (theta's and the stick force's, as if theta were the step's alone); the residual sum of
//!    squares `Q` has `d` degrees of freedom (rows less the columns' rank).
//! 2. While `Q <= FORM_FACTOR d` (a residual RMS up to 4 times the noise) the weights are the
//!    noise weights, bit for bit, and the method keeps its efficiency where the model's form is
//!    the element's. The margin is what such a fit misses by anyway: the stick phase's
//!    polynomials and jumps miss an exact Coulomb element's steps by up to 3.5 times their
//!    noise at 40 dB (Table 1's CASE II, `Q / d` up to 12), and a noise estimate from few
//!    periods scatters (its inverse has mean `nu / (nu - 2)` for `nu` degrees of freedom).
//! 3. Otherwise `tau^2` solves `sum_i e_i^2 / (sigma_i^2 + tau^2) = d`, `e_i` the step's residual
//!    refitted with the weights `1 / sqrt(sigma_i^2 + tau^2)` (a feasible generalised least
//!    squares, Paule-Mandel's estimator of a random-effects variance), iterated to a fixed
//!    point. The rows are then weighted by `1 / sqrt(sigma_i^2 + tau^2)`: where the form error
//!    dominates, every harmonic counts alike (the time-domain least squares of the waveform,
//!    by Parseval); where the noise does, each counts by its noise.
//!
//! The estimate is the step's own, so the live identifier (which adds each step's block as it
//! comes) and `forcemap identify` weigh every step alike.
//!
//! Whatever the weighting, each row also says how its residual compares with its noise
//! ([`RowNoise`]): the factor turning its weighted residual into units of its noise, and what
//! the noise alone leaves there after the projection. The accumulator sums them by band of
//! harmonics ([`super::quality`]).

use nalgebra::{DMatrix, DVector};

use super::Weighting;

/// A step's residual in units of its noise must exceed this many times its degrees of freedom
/// (residual RMS 4 times the noise) before a form error is estimated (module docs, step 2).
pub const FORM_FACTOR: f64 = 16.0;
/// Fewest degrees of freedom of a step's own fit for a form error to be estimated.
const MIN_FORM_DOF: usize = 4;
/// Singular values below this fraction of the largest are no direction of a step's own fit.
const RANK_TOLERANCE: f64 = 1e-9;
/// Fixed-point passes at most, and the relative change of `tau^2` that ends them.
const MAX_PASSES: usize = 20;
const CONVERGED_REL: f64 = 1e-6;

/// How one row of a block compares with the noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowNoise {
    /// The harmonic the row is of.
    pub harmonic: usize,
    /// The row's weighted residual times this is its residual in units of its noise.
    pub gain: f64,
    /// What the noise alone leaves of the row's squared residual in those units (1 for a row
    /// the projection did not touch).
    pub expected: f64,
}

/// A step's rows before weighting: `a theta + q s = b`, row `i` with noise `sigma[i]`
/// (infinite: not measured, left out) at harmonic `harmonic[i]`.
pub(super) struct StepRows {
    pub a: DMatrix<f64>,
    pub q: DMatrix<f64>,
    pub b: DVector<f64>,
    pub sigma: Vec<f64>,
    pub harmonic: Vec<usize>,
}

/// A step's weighted rows with `q` projected out.
pub(super) struct Weighed {
    pub a: DMatrix<f64>,
    pub b: DVector<f64>,
    /// Rows less the projected directions.
    pub independent: f64,
    pub row_noise: Vec<RowNoise>,
    /// The form-error variance the rows were weighted with [N^2 per real part] (0: none).
    pub form_variance: f64,
}

/// Weighs `rows` by `weighting` and projects the stick-force columns out (singular values of
/// the weighted `q` below `tolerance` of the largest are kept in).
pub(super) fn weigh(rows: &StepRows, weighting: Weighting, tolerance: f64) -> Weighed {
    let form_variance = match weighting {
        Weighting::Robust => form_variance(rows),
        Weighting::Noise | Weighting::Uniform => 0.0,
    };
    let w: Vec<f64> = rows
        .sigma
        .iter()
        .enumerate()
        .map(|(i, &s)| {
            if !s.is_finite() {
                0.0
            } else {
                match weighting {
                    Weighting::Uniform => 1.0 / form_share(rows.harmonic[i]).sqrt(),
                    // Exactly the noise weight when there is no form error.
                    _ if form_variance == 0.0 => 1.0 / s,
                    _ => 1.0 / (s * s + form_share(rows.harmonic[i]) * form_variance).sqrt(),
                }
            }
        })
        .collect();
    let m = rows.b.len();
    let mut a = rows.a.clone();
    let mut q = rows.q.clone();
    let mut b = rows.b.clone();
    for (r, wt) in w.iter().enumerate() {
        a.row_mut(r).iter_mut().for_each(|v| *v *= wt);
        q.row_mut(r).iter_mut().for_each(|v| *v *= wt);
        b[r] *= wt;
    }
    // Project the stick-force columns out.
    let mut kept: Vec<DVector<f64>> = Vec::new();
    if q.ncols() > 0 {
        let svd = q.svd(true, false);
        let u = svd.u.expect("U requested");
        let smax = svd.singular_values.max();
        for (k, sv) in svd.singular_values.iter().enumerate() {
            if *sv > tolerance * smax {
                let uk = u.column(k).into_owned();
                let ua = uk.transpose() * &a;
                a -= &uk * ua;
                let ub = uk.dot(&b);
                b -= &uk * ub;
                kept.push(uk);
            }
        }
    }
    // Each row's residual in units of its noise, and what the noise leaves there: the noise
    // of weighted row j is w_j sigma_j, mixed into row i by the projector P = I - U U^T.
    let scaled_noise: Vec<f64> = (0..m)
        .map(|j| {
            if w[j] > 0.0 {
                w[j] * rows.sigma[j]
            } else {
                0.0
            }
        })
        .collect();
    let row_noise = (0..m)
        .map(|i| {
            if w[i] == 0.0 || scaled_noise[i].is_nan() || scaled_noise[i] <= 0.0 {
                return RowNoise {
                    harmonic: rows.harmonic[i],
                    gain: 0.0,
                    expected: 0.0,
                };
            }
            let mut expected = 0.0;
            for (j, sj) in scaled_noise.iter().enumerate() {
                let pij =
                    f64::from(u8::from(i == j)) - kept.iter().map(|u| u[i] * u[j]).sum::<f64>();
                expected += pij * pij * sj * sj;
            }
            let gain = 1.0 / scaled_noise[i];
            RowNoise {
                harmonic: rows.harmonic[i],
                gain,
                expected: expected * gain * gain,
            }
        })
        .collect();
    Weighed {
        a,
        b,
        independent: (m - kept.len()) as f64,
        row_noise,
        form_variance,
    }
}

/// The step's form-error variance `tau^2` (module docs, steps 1-3); 0 while the noise explains
/// the step's own residual.
fn form_variance(rows: &StepRows) -> f64 {
    let measured: Vec<usize> = (0..rows.b.len())
        .filter(|&i| rows.sigma[i].is_finite() && rows.sigma[i] > 0.0)
        .collect();
    let m = measured.len();
    let cols = rows.a.ncols() + rows.q.ncols();
    // The rows' unweighted residual of the step's own fit with weights 1 / sqrt(sigma^2 + tau2),
    // and its degrees of freedom.
    let residual = |tau2: f64| -> Option<(Vec<f64>, usize)> {
        let mut z = DMatrix::zeros(m, cols);
        let mut y = DVector::zeros(m);
        let mut w = Vec::with_capacity(m);
        for (r, &i) in measured.iter().enumerate() {
            let s = rows.sigma[i];
            let wt = 1.0 / (s * s + form_share(rows.harmonic[i]) * tau2).sqrt();
            for c in 0..rows.a.ncols() {
                z[(r, c)] = rows.a[(i, c)] * wt;
            }
            for c in 0..rows.q.ncols() {
                z[(r, rows.a.ncols() + c)] = rows.q[(i, c)] * wt;
            }
            y[r] = rows.b[i] * wt;
            w.push(wt);
        }
        let svd = z.svd(true, false);
        let u = svd.u?;
        let smax = svd.singular_values.max();
        let mut e = y.clone();
        let mut rank = 0;
        for (k, sv) in svd.singular_values.iter().enumerate() {
            if *sv > RANK_TOLERANCE * smax {
                let uk = u.column(k);
                let c = uk.dot(&y);
                e -= uk * c;
                rank += 1;
            }
        }
        let dof = m.checked_sub(rank)?;
        Some((e.iter().zip(&w).map(|(v, wt)| v / wt).collect(), dof))
    };
    let sigma2: Vec<f64> = measured.iter().map(|&i| rows.sigma[i].powi(2)).collect();
    let share: Vec<f64> = measured
        .iter()
        .map(|&i| form_share(rows.harmonic[i]))
        .collect();
    let weighted = |e: &[f64], tau2: f64| -> f64 {
        e.iter()
            .zip(&sigma2)
            .zip(&share)
            .map(|((e, s2), f)| e * e / (s2 + f * tau2))
            .sum()
    };
    let Some((e, dof)) = residual(0.0) else {
        return 0.0;
    };
    if dof < MIN_FORM_DOF || weighted(&e, 0.0) <= FORM_FACTOR * dof as f64 {
        return 0.0;
    }
    let target = dof as f64;
    let mut tau2 = 0.0;
    let mut e = e;
    for _ in 0..MAX_PASSES {
        let next = solve_tau2(&e, &sigma2, &share, target);
        let done = (next - tau2).abs() <= CONVERGED_REL * next;
        tau2 = next;
        if done {
            break;
        }
        match residual(tau2) {
            Some((refit, _)) => e = refit,
            None => break,
        }
    }
    tau2
}

/// The share of a step's form-error variance `tau^2` (that of a real or imaginary part of a
/// harmonic) on a row of `harmonic`: a period's mean square is `C_0^2 + sum |C_n|^2 / 2`
/// (Parseval, one-sided phasors), so the time-domain least squares of the waveform counts the
/// mean's row once and each real part of the others by half; the mean's row carries half the
/// variance. With it, rows weighted by the form error alone are that least squares.
fn form_share(harmonic: usize) -> f64 {
    if harmonic == 0 { 0.5 } else { 1.0 }
}

/// The `tau^2 >= 0` with `sum_i e_i^2 / (s2_i + f_i tau^2) = target` (0 when even `tau^2 = 0`
/// gives less), by bisection on a bracket (the sum falls with `tau^2`).
fn solve_tau2(e: &[f64], s2: &[f64], share: &[f64], target: f64) -> f64 {
    let q = |t: f64| -> f64 {
        e.iter()
            .zip(s2)
            .zip(share)
            .map(|((e, s), f)| e * e / (s + f * t))
            .sum()
    };
    if q(0.0) <= target {
        return 0.0;
    }
    let mean_square = e.iter().map(|v| v * v).sum::<f64>() / e.len().max(1) as f64;
    let mut hi = mean_square.max(f64::MIN_POSITIVE);
    while q(hi) > target && hi < f64::MAX / 4.0 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if q(mid) > target {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of a straight line through harmonics with a known misfit: the estimate recovers
    /// the misfit's variance, and exact rows give none.
    #[test]
    fn the_form_variance_is_the_misfit_the_noise_does_not_explain() {
        let m = 61;
        let a = DMatrix::from_fn(
            m,
            2,
            |r, c| if c == 0 { 1.0 } else { (r as f64 * 0.3).sin() },
        );
        let q = DMatrix::zeros(m, 0);
        let sigma = vec![0.01; m];
        // A misfit of +-0.5 that no combination of the columns takes away, and no noise.
        let misfit: Vec<f64> = (0..m)
            .map(|r| if (r / 3) % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let b = DVector::from_fn(m, |r, _| 2.0 + 3.0 * a[(r, 1)] + misfit[r]);
        let rows = StepRows {
            a: a.clone(),
            q: q.clone(),
            b,
            sigma: sigma.clone(),
            harmonic: (0..m).map(|r| r.div_ceil(2)).collect(),
        };
        let tau2 = form_variance(&rows);
        // The misfit's variance after the fit, per degree of freedom: near 0.25.
        assert!((tau2 / 0.25 - 1.0).abs() < 0.1, "{tau2}");
        let exact = StepRows {
            b: DVector::from_fn(m, |r, _| 2.0 + 3.0 * a[(r, 1)]),
            ..rows
        };
        assert_eq!(form_variance(&exact), 0.0);
        // Noise weighting with no form error is the noise weighting.
        let robust = weigh(&exact, Weighting::Robust, 1e-6);
        let noise = weigh(&exact, Weighting::Noise, 1e-6);
        assert_eq!(robust.a, noise.a);
        assert_eq!(robust.b, noise.b);
        assert!(
            noise
                .row_noise
                .iter()
                .all(|r| (r.expected - 1.0).abs() < 1e-12)
        );
    }
}
