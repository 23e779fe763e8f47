//! The Levenberg-Marquardt loop of every output-error refinement: a setup's simulator gives the
//! noise-weighted residuals ([`Problem`]), the loop moves the parameters until the misfit stops
//! falling, and the Gauss-Newton information `J^T J` at the end gives the covariance.

use nalgebra::{DMatrix, DVector};

use crate::identify::IdentifyError;
use crate::parallel;

/// Gauss-Newton (Levenberg-Marquardt) iterations; the fd-multi start is close, so 2-3 suffice.
const ITERATIONS: usize = 10;
/// Largest change of a parameter per iteration, relative to its scale.
const MAX_STEP: f64 = 0.05;
/// Relative finite-difference step of the Jacobian.
const FD_STEP: f64 = 1e-5;

/// A setup's output-error problem: residuals `(measured - simulated) / noise std` of the
/// parameters `p`. Sync: the Jacobian's columns are simulated on the machine's cores.
pub(crate) trait Problem: Sync {
    fn residual(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError>;

    /// Groups of parameters whose finite differences may share one simulation because each
    /// moves residuals (`rows`) no other parameter of its group moves. Default: one each.
    fn column_groups(&self, np: usize) -> Vec<Vec<usize>> {
        (0..np).map(|j| vec![j]).collect()
    }

    /// The residual rows parameter `j` moves (all by default).
    fn rows(&self, _j: usize, n: usize) -> std::ops::Range<usize> {
        0..n
    }

    /// The size of each parameter at `p` (steps and finite differences are taken in
    /// `p / scale`): its magnitude by default, 1 where it is zero.
    fn scale(&self, p: &[f64]) -> Vec<f64> {
        p.iter()
            .map(|v| if v.abs() > 0.0 { v.abs() } else { 1.0 })
            .collect()
    }
}

/// The result of [`levenberg_marquardt`].
pub(crate) struct Fit {
    pub p: Vec<f64>,
    pub residual: Vec<f64>,
    /// Sum of squared residuals.
    pub cost: f64,
    /// `J^T J` in scaled parameters (`p_j / scale_j`) at the last Jacobian.
    pub information: DMatrix<f64>,
    pub scale: Vec<f64>,
}

impl Fit {
    /// Covariance of the parameters (inverse Gauss-Newton information, unscaled); NaN when
    /// the information is singular.
    pub fn covariance(&self) -> DMatrix<f64> {
        unscaled_inverse(self.information.clone(), &self.scale)
    }

    /// RMS of the weighted residuals (1 when the model misses the samples by the noise alone).
    pub fn rms(&self) -> f64 {
        (self.cost / self.residual.len().max(1) as f64).sqrt()
    }

    /// Condition number of the scaled Jacobian.
    pub fn condition_number(&self) -> f64 {
        let sv = self.information.singular_values();
        (sv.max() / sv.min()).sqrt()
    }
}

/// The inverse of `information` (in scaled parameters) in the parameters' own units; NaN when
/// it is singular.
fn unscaled_inverse(information: DMatrix<f64>, scale: &[f64]) -> DMatrix<f64> {
    let np = scale.len();
    let inv = information
        .try_inverse()
        .unwrap_or_else(|| DMatrix::from_element(np, np, f64::NAN));
    DMatrix::from_fn(np, np, |i, j| inv[(i, j)] * scale[i] * scale[j])
}

/// The covariance `(J^T W J)^-1` of every parameter of `problem` at `p`: the Cramer-Rao bound
/// when `p` is the truth and the residual is weighted by the true noise.
pub(crate) fn covariance_at(
    problem: &impl Problem,
    p: &[f64],
) -> Result<DMatrix<f64>, IdentifyError> {
    let scale = problem.scale(p);
    let r = problem.residual(p)?;
    let jac = jacobian(problem, p, &r, &scale)?;
    Ok(unscaled_inverse(jac.transpose() * &jac, &scale))
}

/// Jacobian of the model's output (`-d residual`) in scaled parameters, by forward differences.
pub(crate) fn jacobian(
    problem: &impl Problem,
    p: &[f64],
    r: &[f64],
    scale: &[f64],
) -> Result<DMatrix<f64>, IdentifyError> {
    let np = p.len();
    let mut jac = DMatrix::zeros(r.len(), np);
    let groups = problem.column_groups(np);
    // Each group's simulation is its own: a long problem's are run on the machine's cores
    // (the same residuals as one loop).
    let min_part = parallel::min_part_of(r.len() * groups.len(), groups.len());
    let shifted = parallel::try_in_parts(&groups, min_part, |part| {
        part.iter()
            .map(|group| {
                let mut pp = p.to_vec();
                for &j in group {
                    pp[j] += scale[j] * FD_STEP;
                }
                problem.residual(&pp)
            })
            .collect()
    })?;
    for (group, rp) in groups.iter().zip(shifted) {
        for &j in group {
            for i in problem.rows(j, r.len()) {
                jac[(i, j)] = -(rp[i] - r[i]) / FD_STEP;
            }
        }
    }
    Ok(jac)
}

/// How far a fit may go: iterations and the trust region per iteration.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Limits {
    pub iterations: usize,
    /// Largest change of a parameter per iteration, relative to its scale at the start.
    pub max_step: f64,
    /// The fit stops when an iteration lowers the cost by less than this fraction of it.
    pub relative_tolerance: f64,
}

/// The limits of a refinement from fd-multi's estimate, which is within a few %.
pub(crate) const REFINE: Limits = Limits {
    iterations: ITERATIONS,
    max_step: MAX_STEP,
    relative_tolerance: 1e-9,
};

/// Minimises the sum of squared residuals from `start` (steps in `p / Problem::scale`).
pub(crate) fn levenberg_marquardt(
    problem: &impl Problem,
    start: Vec<f64>,
) -> Result<Fit, IdentifyError> {
    levenberg_marquardt_within(problem, start, REFINE)
}

/// [`levenberg_marquardt`] within `limits`.
pub(crate) fn levenberg_marquardt_within(
    problem: &impl Problem,
    start: Vec<f64>,
    limits: Limits,
) -> Result<Fit, IdentifyError> {
    let np = start.len();
    let scale = problem.scale(&start);
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let mut p = start;
    let mut r = problem.residual(&p)?;
    let mut c = cost(&r);
    let mut lambda = 1e-3;
    let mut jtj = DMatrix::zeros(np, np);
    for _ in 0..limits.iterations {
        let jac = jacobian(problem, &p, &r, &scale)?;
        jtj = jac.transpose() * &jac;
        let jtr = jac.transpose() * DVector::from_column_slice(&r);
        let mut improved = false;
        while lambda < 1e8 {
            let mut m = jtj.clone();
            for d in 0..np {
                m[(d, d)] *= 1.0 + lambda;
            }
            let Some(step) = m.lu().solve(&jtr) else {
                lambda *= 10.0;
                continue;
            };
            // Trust region: the start is within a few % (fd-multi), so no parameter moves by
            // more than `max_step` of its scale per iteration.
            if step.amax() > limits.max_step {
                lambda *= 10.0;
                continue;
            }
            let pn: Vec<f64> = (0..np).map(|j| p[j] + step[j] * scale[j]).collect();
            let rn = problem.residual(&pn)?;
            let cn = cost(&rn);
            if cn < c {
                improved = c - cn > limits.relative_tolerance * c && step.amax() > 1e-9;
                (p, r, c) = (pn, rn, cn);
                lambda = (lambda * 0.1).max(1e-9);
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    Ok(Fit {
        p,
        residual: r,
        cost: c,
        information: jtj,
        scale,
    })
}

/// `inner` with only the parameters `free` fitted, the others held at their values in `full`
/// (e.g. a rig's fitted-sine base parameters, known from the phasor fit far better than the
/// model's, when output error only compares models).
pub(crate) struct Partial<'a, P> {
    pub inner: &'a P,
    pub full: Vec<f64>,
    pub free: Vec<usize>,
}

impl<P: Problem> Partial<'_, P> {
    /// The inner problem's parameters with the free ones at `p`.
    pub fn expand(&self, p: &[f64]) -> Vec<f64> {
        let mut full = self.full.clone();
        for (k, &j) in self.free.iter().enumerate() {
            full[j] = p[k];
        }
        full
    }
}

impl<P: Problem> Problem for Partial<'_, P> {
    fn residual(&self, p: &[f64]) -> Result<Vec<f64>, IdentifyError> {
        self.inner.residual(&self.expand(p))
    }

    fn column_groups(&self, _np: usize) -> Vec<Vec<usize>> {
        self.inner
            .column_groups(self.full.len())
            .into_iter()
            .map(|g| {
                g.iter()
                    .filter_map(|j| self.free.iter().position(|f| f == j))
                    .collect::<Vec<usize>>()
            })
            .filter(|g| !g.is_empty())
            .collect()
    }

    fn rows(&self, j: usize, n: usize) -> std::ops::Range<usize> {
        self.inner.rows(self.free[j], n)
    }

    fn scale(&self, p: &[f64]) -> Vec<f64> {
        let s = self.inner.scale(&self.expand(p));
        self.free.iter().map(|&j| s[j]).collect()
    }
}
