//! Equations per line of a periodic multisine record (eq. 11 generalised): frequency-domain
//! force-state mapping on one averaged period.
//!
//! The state of a nonlinear element is known over a whole period: x(t) and x'(t) are rebuilt
//! from every bin of the averaged period that carries signal (the excited lines, and the
//! distortion bins that stand out of their noise), each basis term h_i(x, x') is evaluated on a
//! fine grid over the period and transformed, and every excited line k gives one complex
//! equation `F_k = m A_k + sum_i theta_i H_{i,k}`, weighted by the inverse of the force's
//! noise at that line (the scatter between periods). The bins the multisine leaves out but
//! where the displacement stands out of its noise give equations too (by default): the force
//! there is zero up to noise, and the state's distortion there ties the nonlinear terms. With the moving mass unknown, `A_k` is
//! the column of the parameter `m`; known, `m A_k` moves to the right-hand side.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use super::fd::{grid_harmonics, harmonic_rms, rms, synthesize_grid};
use super::{
    EquationAccumulator, FdMultiOptions, HarmonicAnalysis, Identification, IdentifyError, Method,
    StepEquations, Weighting, step_equations,
};
use crate::model::Model;
use crate::phasor::MultisineAnalysis;
use crate::recipe::Setup;
use crate::record::Channel;

/// A distortion bin joins the rebuilt state when it stands out of its noise by this factor.
const SIGNIFICANT_NOISE_FACTOR: f64 = 3.0;
/// A distortion bin gives an equation when its displacement stands out of its noise by this
/// factor (20 dB): below it the noise in the regressors would bias the estimate.
const EQUATION_NOISE_FACTOR: f64 = 10.0;

/// The weighted equations of one multisine record (see the module docs). Only the element
/// setup is written this way (its force and displacement are measured across the element).
pub fn multisine_equations(
    model: &Model,
    setup: &Setup,
    an: &MultisineAnalysis,
    options: &FdMultiOptions,
) -> Result<StepEquations, IdentifyError> {
    multisine_block(model, setup, an, options, None, None)
}

/// A first-order lag on one term of the model: its force at bin `k` is the term's value on
/// the rebuilt state through `1 / (1 + i k w0 tau)`. A viscous damper `c x'` in series with a
/// spring `ks` is the damper term lagged by `tau = c / ks` (the diagnosis's series_compliance
/// candidate); the equations stay linear in every coefficient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TermLag {
    /// Index of the lagged term in the model's terms.
    pub term: usize,
    pub relaxation_s: f64,
}

/// [`multisine_equations`], each equation weighted by its whole noise about `prior` (a first
/// estimate of the parameters, the moving mass last where it is one): the block the second
/// pass of [`accumulate_multisines`] adds, for scoring a record the estimate was not fitted on
/// in the units of its noise (the diagnosis's cross-validation).
pub fn multisine_equations_about(
    model: &Model,
    setup: &Setup,
    an: &MultisineAnalysis,
    options: &FdMultiOptions,
    prior: &[f64],
) -> Result<StepEquations, IdentifyError> {
    multisine_block(model, setup, an, options, Some(prior), None)
}

/// [`multisine_equations_about`] with one term lagged ([`TermLag`]).
pub fn multisine_equations_about_lagged(
    model: &Model,
    setup: &Setup,
    an: &MultisineAnalysis,
    options: &FdMultiOptions,
    prior: &[f64],
    lag: Option<TermLag>,
) -> Result<StepEquations, IdentifyError> {
    multisine_block(model, setup, an, options, Some(prior), lag)
}

/// [`multisine_equations`], each equation weighted by its whole noise when `prior` (a first
/// estimate of the parameters, the moving mass last where it is one) is given: the force's,
/// and the displacement's and acceleration's propagated through the element linearised
/// about the rebuilt state (errors in the regressors weigh as much as in the force at 30 dB).
/// `lag` lags one term's column ([`TermLag`]).
fn multisine_block(
    model: &Model,
    setup: &Setup,
    an: &MultisineAnalysis,
    options: &FdMultiOptions,
    prior: Option<&[f64]>,
    lag: Option<TermLag>,
) -> Result<StepEquations, IdentifyError> {
    let step = an.step;
    let fail = |problem: String| IdentifyError::Step { step, problem };
    let Setup::Element { moving_mass_kg, .. } = setup else {
        return Err(fail(
            "multisine equations are written for the element setup only (force and displacement measured across the element)".into(),
        ));
    };
    let spectrum = |c: Channel, why: &str| {
        an.channel(c)
            .ok_or_else(|| fail(format!("channel {} is missing ({why})", c.name())))
    };
    let x = spectrum(
        Channel::RelativeDisplacementM,
        "it is the state of the element",
    )?;
    let f = spectrum(Channel::ForceN, "the element test measures its force")?;
    let w0 = std::f64::consts::TAU * an.base_frequency_hz;
    let acc: Vec<Complex64> = match an.channel(Channel::MassAccelerationMps2) {
        Some(a) => a.phasors.clone(),
        None => x
            .phasors
            .iter()
            .enumerate()
            .map(|(k, v)| -v * (k as f64 * w0).powi(2))
            .collect(),
    };
    // Bins of the rebuilt state: DC, the excited lines, and what stands out of the noise.
    let bins = x.phasors.len();
    let keep: Vec<bool> = (0..bins)
        .map(|k| {
            k == 0
                || an.lines.binary_search(&k).is_ok()
                || x.phasors[k].norm() > SIGNIFICANT_NOISE_FACTOR * x.noise_std[k]
        })
        .collect();
    let kmax = keep.iter().rposition(|k| *k).unwrap_or(0);
    let c: Vec<Complex64> = (0..=kmax)
        .map(|k| {
            if keep[k] {
                x.phasors[k]
            } else {
                Complex64::new(0.0, 0.0)
            }
        })
        .collect();
    // Cubic terms reach 3 kmax: 8 points per highest bin keep their aliases off the lines.
    let l = options.grid_points.max(8 * (kmax + 1)).next_power_of_two();
    let xs = synthesize_grid(&c, l, |_| Complex64::new(1.0, 0.0));
    let vs = synthesize_grid(&c, l, |k| Complex64::new(0.0, k as f64 * w0));
    // Equations at the excited lines, and where asked at the other bins with signal.
    let eq_bins: Vec<usize> = if options.multisine_distortion_lines {
        (1..=kmax)
            .filter(|&k| {
                an.lines.binary_search(&k).is_ok()
                    || x.phasors[k].norm() > EQUATION_NOISE_FACTOR * x.noise_std[k]
            })
            .collect()
    } else {
        an.lines.clone()
    };
    let top = eq_bins[eq_bins.len() - 1];
    let fft = crate::signal::fft::forward(l);
    let mut term_rms = Vec::with_capacity(model.terms.len() + 1);
    let mut columns: Vec<Vec<Complex64>> = Vec::with_capacity(model.terms.len() + 1);
    for t in &model.terms {
        let h: Vec<f64> = xs.iter().zip(&vs).map(|(x, v)| t.eval(*x, *v)).collect();
        term_rms.push(rms(&h));
        columns.push(grid_harmonics(&h, top, fft.as_ref()));
    }
    if let Some(lag) = lag {
        let col = columns.get_mut(lag.term).ok_or_else(|| {
            fail(format!(
                "the lagged term {} is not one of the model's {} terms",
                lag.term,
                model.terms.len()
            ))
        })?;
        for (k, c) in col.iter_mut().enumerate() {
            *c /= Complex64::new(1.0, k as f64 * w0 * lag.relaxation_s);
        }
    }
    let used_acc: Vec<Complex64> = (0..=kmax)
        .map(|k| {
            if keep[k] {
                acc[k]
            } else {
                Complex64::new(0.0, 0.0)
            }
        })
        .collect();
    let known_mass = *moving_mass_kg;
    if known_mass.is_none() {
        term_rms.push(harmonic_rms(&used_acc));
        columns.push(acc[..=top].to_vec());
    }
    let p = columns.len();
    let force_peak = an
        .lines
        .iter()
        .map(|&k| f.phasors[k].norm())
        .fold(0.0, f64::max);
    let floor = options.noise_floor * force_peak;
    let measured_acc = an.channel(Channel::MassAccelerationMps2);
    // The linearised element (k_eq, c_eq) and the mass of the prior, for the equation noise.
    let linear = prior.map(|theta| {
        let (k_eq, c_eq) = linearisation(model, theta, &xs, &vs);
        let m = known_mass.unwrap_or_else(|| theta.get(model.terms.len()).copied().unwrap_or(0.0));
        (k_eq, c_eq, m)
    });
    let equation_noise = |k: usize| {
        let sf = f.noise_std[k];
        let Some((k_eq, c_eq, m)) = linear else {
            return sf;
        };
        let w = k as f64 * w0;
        let sx = x.noise_std[k];
        match measured_acc {
            Some(a) => {
                let sx_force = Complex64::new(k_eq, w * c_eq).norm() * sx;
                (sf * sf + (m * a.noise_std[k]).powi(2) + sx_force * sx_force).sqrt()
            }
            None => sf.hypot(Complex64::new(k_eq - m * w * w, w * c_eq).norm() * sx),
        }
    };
    let rows = 2 * eq_bins.len();
    let mut a = DMatrix::zeros(rows, p);
    let mut b = DVector::zeros(rows);
    for (r, &k) in eq_bins.iter().enumerate() {
        // The robust weighting weighs a multisine's lines by their noise, as the noise
        // weighting does: no form error is estimated for a multisine record.
        let weight = match options.weighting {
            Weighting::Noise | Weighting::Robust => {
                1.0 / equation_noise(k).max(floor).max(f64::MIN_POSITIVE)
            }
            Weighting::Uniform => 1.0,
        };
        let rhs = f.phasors[k] - known_mass.map_or(Complex64::new(0.0, 0.0), |m| acc[k] * m);
        for (i, col) in columns.iter().enumerate() {
            a[(2 * r, i)] = weight * col[k].re;
            a[(2 * r + 1, i)] = weight * col[k].im;
        }
        b[2 * r] = weight * rhs.re;
        b[2 * r + 1] = weight * rhs.im;
    }
    let mut notes = Vec::new();
    if model.has_friction() {
        notes.push(format!(
            "step {step}: multisine equations evaluate the friction terms on the rebuilt state without a stick phase"
        ));
    }
    Ok(StepEquations {
        step,
        a,
        b,
        independent_equations: rows as f64,
        term_rms,
        notes,
        row_noise: Vec::new(),
        form_variance: 0.0,
    })
}

/// The element linearised about the rebuilt state: the mean over the period of
/// `sum_i theta_i dh_i/dx` and of `sum_i theta_i dh_i/dx'` (central differences; terms that
/// jump at zero velocity are left out, their derivative is no noise gain).
fn linearisation(model: &Model, theta: &[f64], xs: &[f64], vs: &[f64]) -> (f64, f64) {
    let peak = |s: &[f64]| s.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    let (dx, dv) = (1e-6 * peak(xs), 1e-6 * peak(vs));
    let n = xs.len().max(1) as f64;
    let mut kc = (0.0, 0.0);
    for (t, th) in model.terms.iter().zip(theta) {
        if t.jumps_at_zero_velocity() {
            continue;
        }
        for (x, v) in xs.iter().zip(vs) {
            kc.0 += th * (t.eval(x + dx, *v) - t.eval(x - dx, *v)) / (2.0 * dx * n);
            kc.1 += th * (t.eval(*x, v + dv) - t.eval(*x, v - dv)) / (2.0 * dv * n);
        }
    }
    kc
}

/// Identifies `model` from stepped-sine analyses and multisine analyses together: every sine
/// step's block (`Fd` or `FdMulti`) and every multisine record's per-line block, solved as one
/// ([`accumulate_multisines`] on the sine steps' accumulated equations).
pub fn identify_with_multisines(
    model: &Model,
    setup: &Setup,
    method: Method,
    analyses: &[HarmonicAnalysis],
    multisines: &[MultisineAnalysis],
    options: &FdMultiOptions,
) -> Result<Identification, IdentifyError> {
    if !matches!(method, Method::Fd | Method::FdMulti) {
        let step = multisines.first().map_or(0, |m| m.step);
        return Err(IdentifyError::Step {
            step,
            problem: format!(
                "a periodic multisine record is identified by its per-line equations (fd or fd-multi), not by {method}"
            ),
        });
    }
    let mut sines = EquationAccumulator::new(model, setup, method);
    for an in analyses {
        sines.add(&step_equations(model, setup, method, an, options)?)?;
    }
    accumulate_multisines(&sines, model, setup, multisines, options)?.solve()
}

/// The equations of `sines` (the sine steps' blocks, accumulated) with every multisine
/// record's per-line block added after them, in two passes: first weighted by the force noise,
/// then, unless the weighting is uniform, each multisine equation weighted by its whole noise
/// about the first pass's estimate. `sines` is left as it is. What `forcemap identify` and the
/// live identifier (which keeps its sine steps accumulated and the multisine records' phasors)
/// both solve, so that their theta agree exactly.
pub fn accumulate_multisines(
    sines: &EquationAccumulator,
    model: &Model,
    setup: &Setup,
    multisines: &[MultisineAnalysis],
    options: &FdMultiOptions,
) -> Result<EquationAccumulator, IdentifyError> {
    accumulate_multisines_lagged(sines, model, setup, multisines, options, None)
}

/// [`accumulate_multisines`] with one term lagged on every multisine record ([`TermLag`]; the
/// sine steps' blocks in `sines` are as given).
pub fn accumulate_multisines_lagged(
    sines: &EquationAccumulator,
    model: &Model,
    setup: &Setup,
    multisines: &[MultisineAnalysis],
    options: &FdMultiOptions,
    lag: Option<TermLag>,
) -> Result<EquationAccumulator, IdentifyError> {
    let pass = |prior: Option<&[f64]>| -> Result<EquationAccumulator, IdentifyError> {
        let mut acc = sines.clone();
        for ms in multisines {
            acc.add(&multisine_block(model, setup, ms, options, prior, lag)?)?;
        }
        Ok(acc)
    };
    let first = pass(None)?;
    if options.weighting == Weighting::Uniform || multisines.is_empty() {
        return Ok(first);
    }
    // Again, each multisine equation weighted by its whole noise about the first estimate.
    let theta = first.solve()?.theta();
    pass(Some(&theta))
}
