//! Frequency-domain equations of one step: the paper's first-harmonic form and the improved
//! all-harmonic, slip-aware form.

use std::f64::consts::TAU;

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use super::stick::{circular_runs, legendre};
use super::weights::{RowNoise, StepRows, weigh};
use super::{FdMultiOptions, IdentifyError, Method, StepEquations};
use crate::model::Model;
use crate::phasor::{ChannelPhasors, HarmonicAnalysis, acceleration_phasors, velocity_phasors};
use crate::recipe::Setup;
use crate::record::Channel;

/// Harmonics n = 0..N of the element's state and force over one period of a settled step.
#[derive(Debug, Clone)]
pub struct ElementHarmonics {
    pub step: usize,
    pub omega_rad_s: f64,
    /// Relative displacement across the element, X_n [m].
    pub displacement: Vec<Complex64>,
    pub displacement_noise: Vec<f64>,
    /// Relative velocity across the element, V_n [m/s]: `j n w X_n` on a settled step, plus the
    /// displacement's rate of change in a sweep window ([`velocity_phasors`]).
    pub velocity: Vec<Complex64>,
    /// Element force, G_n [N], from the measurements and the known linear part.
    pub force: Vec<Complex64>,
    pub force_noise: Vec<f64>,
    /// The equation column of a parameter the setup adds (an element test's unknown moving
    /// mass: the acceleration harmonics A_n, so that G_n = F_n - m A_n = Y_n theta).
    pub extra_column: Option<Vec<Complex64>>,
    /// The noise std of `extra_column`'s harmonics.
    pub extra_column_noise: Option<Vec<f64>>,
}

impl ElementHarmonics {
    pub fn harmonics(&self) -> usize {
        self.displacement.len() - 1
    }
}

fn missing(step: usize, c: Channel, why: &str) -> IdentifyError {
    IdentifyError::Step {
        step,
        problem: format!("channel {} is missing ({why})", c.name()),
    }
}

/// Element state and force harmonics from a step's phasors. `paper_force` selects the paper's
/// displacement-only force (rig: m w^2 X_o); otherwise, where both the mass displacement and
/// the mass acceleration are measured, each harmonic combines them by inverse noise variance.
pub fn element_harmonics(
    setup: &Setup,
    an: &HarmonicAnalysis,
    paper_force: bool,
) -> Result<ElementHarmonics, IdentifyError> {
    let step = an.step;
    let omega = TAU * an.frequency_hz;
    let omega_rate = TAU * an.frequency_rate_hz_per_s;
    let rel = an.channel(Channel::RelativeDisplacementM).ok_or_else(|| {
        missing(
            step,
            Channel::RelativeDisplacementM,
            "it is the state of the element",
        )
    })?;
    let nh = rel.phasors.len();
    let mut extra_column = None;
    let mut extra_column_noise = None;
    let (force, force_noise) = match setup {
        Setup::BaseExcited { mass_kg } => {
            let m = *mass_kg;
            // Mass displacement (its phasors, their rates, noise): measured, or base + relative.
            type Disp = (Vec<Complex64>, Vec<Complex64>, Vec<f64>);
            let disp: Option<Disp> = if let Some(xo) = an.channel(Channel::MassDisplacementM) {
                Some((
                    xo.phasors.clone(),
                    xo.rate_per_s.clone(),
                    xo.noise_std.clone(),
                ))
            } else {
                an.channel(Channel::BaseDisplacementM).map(|xi| {
                    (
                        add(&xi.phasors, &rel.phasors),
                        add(&xi.rate_per_s, &rel.rate_per_s),
                        xi.noise_std
                            .iter()
                            .zip(&rel.noise_std)
                            .map(|(a, b)| a.hypot(*b))
                            .collect(),
                    )
                })
            };
            let from_disp = disp.map(|(xo, rate, s)| {
                let g: Vec<Complex64> = acceleration_phasors(&xo, &rate, omega, omega_rate)
                    .iter()
                    .map(|a| -a * m)
                    .collect();
                let gs: Vec<f64> = s
                    .iter()
                    .enumerate()
                    .map(|(n, x)| x * m * (n as f64 * omega).powi(2))
                    .collect();
                (g, gs)
            });
            let from_acc = an.channel(Channel::MassAccelerationMps2).map(|a| {
                (
                    a.phasors.iter().map(|v| -v * m).collect::<Vec<_>>(),
                    a.noise_std.iter().map(|v| v * m).collect::<Vec<_>>(),
                )
            });
            match (from_disp, from_acc) {
                (Some(d), _) if paper_force => d,
                (Some((gd, sd)), Some((ga, sa))) => {
                    let mut g = Vec::with_capacity(nh);
                    let mut s = Vec::with_capacity(nh);
                    for n in 0..nh {
                        let (vd, va) = (sd[n].powi(2), sa[n].powi(2));
                        if vd + va > 0.0 && vd.is_finite() && va.is_finite() {
                            g.push((gd[n] * va + ga[n] * vd) / (vd + va));
                            s.push((vd * va / (vd + va)).sqrt());
                        } else {
                            g.push((gd[n] + ga[n]) * 0.5);
                            s.push(0.0);
                        }
                    }
                    (g, s)
                }
                (Some(d), None) => d,
                (None, Some(a)) => a,
                (None, None) => {
                    return Err(IdentifyError::Step {
                        step,
                        problem: "neither the mass displacement (or the base displacement) nor the mass acceleration is measured: the element force is unknown".into(),
                    });
                }
            }
        }
        Setup::Element { moving_mass_kg, .. } => {
            let f = an.channel(Channel::ForceN).ok_or_else(|| {
                missing(step, Channel::ForceN, "the element test measures its force")
            })?;
            let (acc, acc_noise) = moving_acceleration(an, rel, omega, omega_rate);
            match moving_mass_kg {
                Some(m) => {
                    let g = (0..nh).map(|n| f.phasors[n] - acc[n] * *m).collect();
                    let s = (0..nh)
                        .map(|n| f.noise_std[n].hypot(acc_noise[n] * *m))
                        .collect();
                    (g, s)
                }
                None => {
                    let mut acc = acc;
                    if an.channel(Channel::MassAccelerationMps2).is_none() {
                        // The displacement's harmonics within their noise, differentiated
                        // twice, are noise amplified by (n w)^2: the acceleration is rebuilt
                        // from the harmonics the state is (the significant ones), as x and x'
                        // are (the rows carry the rest of its noise through the mass hint,
                        // `FdMultiOptions::moving_mass_hint_kg`).
                        let nx = significant_harmonics(&rel.phasors, &rel.noise_std);
                        for a in acc.iter_mut().skip(nx + 1) {
                            *a = Complex64::new(0.0, 0.0);
                        }
                    }
                    extra_column = Some(acc);
                    extra_column_noise = Some(acc_noise);
                    (f.phasors.clone(), f.noise_std.clone())
                }
            }
        }
        Setup::DrivePoint { substructure } => {
            let xd = an
                .channel(Channel::DrivePointDisplacementM)
                .ok_or_else(|| {
                    missing(
                        step,
                        Channel::DrivePointDisplacementM,
                        "eq. 22 needs the drive-point displacement",
                    )
                })?;
            let f = an
                .channel(Channel::ForceN)
                .ok_or_else(|| missing(step, Channel::ForceN, "eq. 22 needs the drive force"))?;
            let mut g = Vec::with_capacity(nh);
            let mut s = Vec::with_capacity(nh);
            for n in 0..nh {
                let alpha = substructure.drive_point_receptance(n as f64 * omega);
                g.push(f.phasors[n] - xd.phasors[n] / alpha);
                s.push(f.noise_std[n].hypot(xd.noise_std[n] / alpha.norm()));
            }
            (g, s)
        }
    };
    Ok(ElementHarmonics {
        step,
        omega_rad_s: omega,
        displacement: rel.phasors.clone(),
        displacement_noise: rel.noise_std.clone(),
        velocity: velocity_phasors(&rel.phasors, &rel.rate_per_s, omega),
        force,
        force_noise,
        extra_column,
        extra_column_noise,
    })
}

/// Harmonics of the moving mass's acceleration in an element test, with their noise: the
/// measured fixture acceleration (`mass_acceleration_mps2`) where there is one, else the
/// displacement's second derivative ([`acceleration_phasors`]).
fn moving_acceleration(
    an: &HarmonicAnalysis,
    displacement: &ChannelPhasors,
    omega: f64,
    omega_rate: f64,
) -> (Vec<Complex64>, Vec<f64>) {
    if let Some(a) = an.channel(Channel::MassAccelerationMps2) {
        return (a.phasors.clone(), a.noise_std.clone());
    }
    let w2 = |n: usize| (n as f64 * omega).powi(2);
    (
        acceleration_phasors(
            &displacement.phasors,
            &displacement.rate_per_s,
            omega,
            omega_rate,
        ),
        displacement
            .noise_std
            .iter()
            .enumerate()
            .map(|(n, s)| s * w2(n))
            .collect(),
    )
}

/// Element-wise sum of two phasor lists (a missing entry is 0: an empty list of rates).
fn add(a: &[Complex64], b: &[Complex64]) -> Vec<Complex64> {
    let zero = Complex64::new(0.0, 0.0);
    (0..a.len().max(b.len()))
        .map(|n| a.get(n).copied().unwrap_or(zero) + b.get(n).copied().unwrap_or(zero))
        .collect()
}

/// RMS over the cycle of the signal with one-sided harmonics `c`.
pub(crate) fn harmonic_rms(c: &[Complex64]) -> f64 {
    c.iter()
        .enumerate()
        .map(|(n, v)| {
            if n == 0 {
                v.norm_sqr()
            } else {
                v.norm_sqr() / 2.0
            }
        })
        .sum::<f64>()
        .sqrt()
}

/// Values over one period on `l` grid points of the signal with one-sided phasors `c` at
/// harmonic multiplier `scale(n)` (1 for the signal, j n w for its derivative).
pub(crate) fn synthesize_grid(
    c: &[Complex64],
    l: usize,
    scale: impl Fn(usize) -> Complex64,
) -> Vec<f64> {
    assert!(
        c.len() <= l / 2 + 1,
        "{} harmonics do not fit a grid of {l} points",
        c.len()
    );
    // s(theta_i) = Re sum_n C_n scale(n) e^{j n theta_i}: one inverse FFT (e^{+j}, unnormalised).
    let mut buf = vec![Complex64::new(0.0, 0.0); l];
    for (n, cn) in c.iter().enumerate() {
        buf[n] = cn * scale(n);
    }
    crate::signal::fft::inverse(l).process(&mut buf);
    buf.iter().map(|b| b.re).collect()
}

/// One-sided first-harmonic phasor of `h` sampled on a uniform grid over one period.
fn first_harmonic(h: &[f64]) -> Complex64 {
    let l = h.len() as f64;
    h.iter()
        .enumerate()
        .map(|(i, v)| v * Complex64::from_polar(1.0, -TAU * i as f64 / l))
        .sum::<Complex64>()
        * (2.0 / l)
}

pub(crate) fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Highest harmonic of `c` that stands out of its noise (3 sigma): above it a rebuilt waveform
/// would carry noise amplified by n w (velocity) or n^2 w^2 (force from displacement) and no
/// information.
fn significant_harmonics(c: &[Complex64], noise: &[f64]) -> usize {
    (1..c.len())
        .rev()
        .find(|&n| c[n].norm() > 3.0 * noise[n])
        .unwrap_or(1)
}

/// One-sided harmonics 0..=n of a real periodic signal sampled on a uniform grid over one period
/// (the inverse of `synthesize_grid`).
pub(crate) fn grid_harmonics(h: &[f64], n: usize, fft: &dyn rustfft::Fft<f64>) -> Vec<Complex64> {
    let l = h.len();
    let mut buf: Vec<Complex64> = h.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    fft.process(&mut buf);
    (0..=n)
        .map(|k| {
            buf[k]
                * if k == 0 {
                    1.0 / l as f64
                } else {
                    2.0 / l as f64
                }
        })
        .collect()
}

/// The improved equations, a weighted harmonic balance of every measured harmonic (eq. 11 for
/// n = 0..N). One period of the state is rebuilt from the displacement's significant harmonics;
/// for models with a friction term the cycle is split into slip samples (where g = theta^T h holds) and
/// stick samples (|x'| small, plus a guard), where the element force is set-valued and is
/// represented instead by an unknown smooth function: a low-order polynomial per stick interval.
/// The harmonics of both parts are balanced against the measured force harmonics, each weighted
/// by its own noise, and the polynomial coefficients are projected out (they are per step, theta
/// is shared). Noisy high harmonics thus get little weight instead of a hard cut, and no
/// truncated waveform is compared sample by sample (no Gibbs ringing to guard against).
fn fd_multi_equations(
    model: &Model,
    eh: &ElementHarmonics,
    step: usize,
    options: &FdMultiOptions,
    term_rms: Vec<f64>,
    mut notes: Vec<String>,
) -> Result<StepEquations, IdentifyError> {
    let p = model.terms.len() + usize::from(eh.extra_column.is_some());
    let empty = |notes: Vec<String>, term_rms: Vec<f64>| StepEquations {
        step,
        a: DMatrix::zeros(0, p),
        b: DVector::zeros(0),
        independent_equations: 0.0,
        term_rms,
        notes,
        row_noise: Vec::new(),
        form_variance: 0.0,
    };
    let amp = eh.displacement.get(1).map_or(0.0, |c| c.norm());
    let amp_noise = eh.displacement_noise.get(1).copied().unwrap_or(0.0);
    if model.has_friction() && (amp < 1e-9 || amp < 5.0 * amp_noise) {
        notes.push(format!(
            "step {step}: the element did not slip (relative displacement amplitude {amp:.3e} m); left out, as no friction model can describe a step that only sticks"
        ));
        return Ok(empty(notes, term_rms));
    }
    let nh = eh.harmonics();
    let nx = significant_harmonics(&eh.displacement, &eh.displacement_noise);
    let l = options.grid_points.max(16 * (nh + 1)).next_power_of_two();
    let w = eh.omega_rad_s;
    let x = synthesize_grid(&eh.displacement[..=nx], l, |_| Complex64::new(1.0, 0.0));
    let v = synthesize_grid(&eh.velocity[..=nx], l, |_| Complex64::new(1.0, 0.0));
    let mut keep = vec![true; l];
    let vmax = v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let v_noise = (1..=nx)
        .map(|n| (n as f64 * w * eh.displacement_noise[n]).powi(2) / 2.0)
        .sum::<f64>()
        .sqrt();
    let threshold = (options.stick_velocity_fraction * vmax).max(3.0 * v_noise);
    let jump_stride = (l / (8 * nh.max(1))).max(1);
    if model.has_friction() {
        let guard = (options.guard_harmonic_periods * l as f64 / nx as f64).ceil() as isize;
        for i in 0..l {
            if v[i].abs() < threshold {
                for d in -guard..=guard {
                    keep[(i as isize + d).rem_euclid(l as isize) as usize] = false;
                }
            }
        }
    }
    let kept = keep.iter().filter(|k| **k).count();
    if kept == 0 {
        notes.push(format!("step {step}: no slip samples; left out"));
        return Ok(empty(notes, term_rms));
    }
    let fft = crate::signal::fft::forward(l);
    // Harmonics of the basis functions over the slip samples.
    let mut hh: Vec<Vec<Complex64>> = model
        .terms
        .iter()
        .map(|t| {
            let hi: Vec<f64> = x
                .iter()
                .zip(&v)
                .zip(&keep)
                .map(|((x, v), k)| if *k { t.eval(*x, *v) } else { 0.0 })
                .collect();
            grid_harmonics(&hi, nh, fft.as_ref())
        })
        .collect();
    // The inertia of an unknown moving mass acts over the whole cycle, stuck or slipping.
    hh.extend(eh.extra_column.iter().cloned());
    // Harmonics of the stick-force polynomials.
    let mut qq: Vec<Vec<Complex64>> = Vec::new();
    for (start, len) in circular_runs(&keep) {
        let d = options.stick_force_degree.min(len.saturating_sub(1));
        let mut cols = vec![vec![0.0; l]; d + 1];
        for j in 0..len {
            let t = 2.0 * (j as f64 + 0.5) / len as f64 - 1.0;
            for (k, pk) in legendre(t, d).into_iter().enumerate() {
                cols[k][(start + j) % l] = pk;
            }
        }
        // Where the force may jump: at the stick onset (the true force jumps from the slip
        // value to the static one) or, if the element only reverses, at the sign change of x'.
        // Both lie between the run's first sample with |x'| below the threshold and the first
        // sign change of x' after it, give or take the resolution of the rebuilt velocity.
        let at = |j: usize| v[(start + j) % l];
        let first_low = (0..len).find(|&j| at(j).abs() < threshold).unwrap_or(0);
        let first_flip = (first_low + 1..len)
            .find(|&j| at(j).signum() != at(first_low).signum())
            .unwrap_or(first_low);
        let margin = (options.jump_margin_harmonic_periods * l as f64 / nx as f64).ceil() as usize;
        let lo = first_low.saturating_sub(margin).max(1);
        let hi = (first_flip + margin).min(len - 1);
        for j in (lo..=hi).step_by(jump_stride) {
            let mut c = vec![0.0; l];
            for jj in j..len {
                c[(start + jj) % l] = 1.0;
            }
            cols.push(c);
        }
        qq.extend(cols.iter().map(|c| grid_harmonics(c, nh, fft.as_ref())));
    }
    // Real equations: DC, then real and imaginary part of each harmonic, with their noise. The
    // per-part noise std of harmonic n >= 1 is |noise| / sqrt 2; a floor keeps noise-free data
    // from being weighted by round-off.
    let floor = options.noise_floor
        * eh.force
            .get(1)
            .map_or(0.0, |g| g.norm())
            .max(f64::MIN_POSITIVE);
    let rows = 2 * nh + 1;
    let mut step_rows = StepRows {
        a: DMatrix::zeros(rows, p),
        q: DMatrix::zeros(rows, qq.len()),
        b: DVector::zeros(rows),
        sigma: vec![f64::INFINITY; rows],
        harmonic: vec![0; rows],
    };
    for n in 0..=nh {
        let s = if n == 0 {
            eh.force_noise[0]
        } else {
            eh.force_noise[n] / 2f64.sqrt()
        };
        let s = if s.is_finite() {
            s.max(floor)
        } else {
            f64::INFINITY
        };
        let parts: &[(usize, bool)] = if n == 0 {
            &[(0, false)]
        } else {
            &[(2 * n - 1, false), (2 * n, true)]
        };
        for &(r, im) in parts {
            let pick = |c: Complex64| if im { c.im } else { c.re };
            step_rows.b[r] = pick(eh.force[n]);
            for (i, h) in hh.iter().enumerate() {
                step_rows.a[(r, i)] = pick(h[n]);
            }
            for (k, qk) in qq.iter().enumerate() {
                step_rows.q[(r, k)] = pick(qk[n]);
            }
            step_rows.sigma[r] = s;
            step_rows.harmonic[r] = n;
        }
    }
    let weighed = weigh(&step_rows, options.weighting, options.stick_force_tolerance);
    Ok(StepEquations {
        step,
        a: weighed.a,
        b: weighed.b,
        independent_equations: weighed.independent,
        term_rms,
        notes,
        row_noise: weighed.row_noise,
        form_variance: weighed.form_variance,
    })
}

/// The equations of one step for the FD methods.
pub fn step_equations(
    model: &Model,
    setup: &Setup,
    method: Method,
    an: &HarmonicAnalysis,
    options: &FdMultiOptions,
) -> Result<StepEquations, IdentifyError> {
    let mut eh = element_harmonics(setup, an, method == Method::Fd)?;
    if let (Method::FdMulti, Some(m), Some(noise)) = (
        method,
        options.moving_mass_hint_kg,
        eh.extra_column_noise.as_ref(),
    ) {
        for (s, a) in eh.force_noise.iter_mut().zip(noise) {
            *s = s.hypot(m * a);
        }
    }
    let nh = eh.harmonics();
    let l = options.grid_points.max(16 * (nh + 1)).next_power_of_two();
    let x = synthesize_grid(&eh.displacement, l, |_| Complex64::new(1.0, 0.0));
    let v = synthesize_grid(&eh.velocity, l, |_| Complex64::new(1.0, 0.0));
    let p = model.terms.len() + usize::from(eh.extra_column.is_some());
    let h: Vec<Vec<f64>> = model
        .terms
        .iter()
        .map(|t| x.iter().zip(&v).map(|(x, v)| t.eval(*x, *v)).collect())
        .collect();
    let mut term_rms: Vec<f64> = h.iter().map(|hi| rms(hi)).collect();
    term_rms.extend(eh.extra_column.iter().map(|c| harmonic_rms(c)));
    let notes = Vec::new();
    match method {
        Method::Fd => {
            // a = Y_1, b = G_1 (eqs. 13, 22, 23), split into real and imaginary parts. A term
            // with no first harmonic over the cycle (a constant, |x'| of a sine) is no column
            // of these equations: its column is zero (the solver then names it) rather than
            // round-off that column scaling would blow up.
            let mut y1: Vec<Complex64> = h.iter().map(|hi| first_harmonic(hi)).collect();
            y1.extend(eh.extra_column.iter().map(|c| c[1]));
            for (y, rms) in y1.iter_mut().zip(&term_rms) {
                if y.norm() <= 1e-12 * rms {
                    *y = Complex64::new(0.0, 0.0);
                }
            }
            let a = DMatrix::from_fn(2, p, |r, i| if r == 0 { y1[i].re } else { y1[i].im });
            let b = DVector::from_vec(vec![eh.force[1].re, eh.force[1].im]);
            let floor = options.noise_floor * eh.force[1].norm();
            let s = (eh.force_noise[1] / 2f64.sqrt()).max(floor);
            let row = RowNoise {
                harmonic: 1,
                gain: if s.is_finite() && s > 0.0 { 1.0 / s } else { 0.0 },
                expected: if s.is_finite() && s > 0.0 { 1.0 } else { 0.0 },
            };
            Ok(StepEquations {
                step: an.step,
                a,
                b,
                independent_equations: 2.0,
                term_rms,
                notes,
                row_noise: vec![row; 2],
                form_variance: 0.0,
            })
        }
        Method::FdMulti => fd_multi_equations(model, &eh, an.step, options, term_rms, notes),
        Method::Td { .. } => unreachable!("time-domain equations come from td_step_equations"),
        Method::OutputError => Err(IdentifyError::Step {
            step: an.step,
            problem: "output-error refinement has no per-step equations (it is a post-step on fd-multi's estimate)".into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_synthesis_and_first_harmonic_are_inverse() {
        let c = vec![
            Complex64::new(0.1, 0.0),
            Complex64::new(0.3, -0.2),
            Complex64::new(0.0, 0.05),
        ];
        let g = synthesize_grid(&c, 64, |_| Complex64::new(1.0, 0.0));
        assert!((first_harmonic(&g) - c[1]).norm() < 1e-14);
        // derivative of cos(th) at th = pi/2 with w = 2: -2
        let c = vec![Complex64::new(0.0, 0.0), Complex64::new(1.0, 0.0)];
        let v = synthesize_grid(&c, 64, |n| Complex64::new(0.0, n as f64 * 2.0));
        assert!((v[16] + 2.0).abs() < 1e-13);
    }
}
