//! Frequency-domain equations of one step: the paper's first-harmonic form and the improved
//! all-harmonic, slip-aware form.

use std::f64::consts::TAU;

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use super::{FdMultiOptions, IdentifyError, Method, Setup, StepEquations};
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::record::Channel;

/// Harmonics n = 0..N of the element's state and force over one period of a settled step.
#[derive(Debug, Clone)]
pub struct ElementHarmonics {
    pub step: usize,
    pub omega_rad_s: f64,
    /// Relative displacement across the element, X_n [m].
    pub displacement: Vec<Complex64>,
    pub displacement_noise: Vec<f64>,
    /// Element force, G_n [N], from the measurements and the known linear part.
    pub force: Vec<Complex64>,
    pub force_noise: Vec<f64>,
}

impl ElementHarmonics {
    pub fn harmonics(&self) -> usize {
        self.displacement.len() - 1
    }
}

fn missing(step: usize, c: Channel, why: &str) -> IdentifyError {
    IdentifyError::Step { step, problem: format!("channel {} is missing ({why})", c.name()) }
}

/// Element state and force harmonics from a step's phasors. `paper_force` selects the paper's
/// displacement-only force (rig: m w^2 X_o); otherwise, where both the mass displacement and
/// the mass acceleration are measured, each harmonic combines them by inverse noise variance.
pub fn element_harmonics(setup: &Setup, an: &HarmonicAnalysis, paper_force: bool) -> Result<ElementHarmonics, IdentifyError> {
    let step = an.step;
    let omega = TAU * an.frequency_hz;
    let rel = an
        .channel(Channel::RelativeDisplacementM)
        .ok_or_else(|| missing(step, Channel::RelativeDisplacementM, "it is the state of the element"))?;
    let nh = rel.phasors.len();
    let (force, force_noise) = match setup {
        Setup::BaseExcited { mass_kg } => {
            let m = *mass_kg;
            // Mass displacement: measured, or base + relative.
            let disp: Option<(Vec<Complex64>, Vec<f64>)> = if let Some(xo) = an.channel(Channel::MassDisplacementM) {
                Some((xo.phasors.clone(), xo.noise_std.clone()))
            } else {
                an.channel(Channel::BaseDisplacementM).map(|xi| {
                    (
                        xi.phasors.iter().zip(&rel.phasors).map(|(a, b)| a + b).collect(),
                        xi.noise_std.iter().zip(&rel.noise_std).map(|(a, b)| a.hypot(*b)).collect(),
                    )
                })
            };
            let from_disp = disp.map(|(xo, s)| {
                let g: Vec<Complex64> =
                    xo.iter().enumerate().map(|(n, x)| x * m * (n as f64 * omega).powi(2)).collect();
                let gs: Vec<f64> = s.iter().enumerate().map(|(n, x)| x * m * (n as f64 * omega).powi(2)).collect();
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
        Setup::DrivePoint { substructure } => {
            let xd = an.channel(Channel::DrivePointDisplacementM).ok_or_else(|| {
                missing(step, Channel::DrivePointDisplacementM, "eq. 22 needs the drive-point displacement")
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
        force,
        force_noise,
    })
}

/// Values over one period on `l` grid points of the signal with one-sided phasors `c` at
/// harmonic multiplier `scale(n)` (1 for the signal, j n w for its derivative).
fn synthesize_grid(c: &[Complex64], l: usize, scale: impl Fn(usize) -> Complex64) -> Vec<f64> {
    (0..l)
        .map(|i| {
            let th = TAU * i as f64 / l as f64;
            c.iter()
                .enumerate()
                .map(|(n, cn)| (cn * scale(n) * Complex64::from_polar(1.0, n as f64 * th)).re)
                .sum()
        })
        .collect()
}

/// One-sided first-harmonic phasor of `h` sampled on a uniform grid over one period.
fn first_harmonic(h: &[f64]) -> Complex64 {
    let l = h.len() as f64;
    h.iter().enumerate().map(|(i, v)| v * Complex64::from_polar(1.0, -TAU * i as f64 / l)).sum::<Complex64>() * (2.0 / l)
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// Highest harmonic of `c` that stands out of its noise (3 sigma): above it a rebuilt waveform
/// would carry noise amplified by n w (velocity) or n^2 w^2 (force from displacement) and no
/// information.
fn significant_harmonics(c: &[Complex64], noise: &[f64]) -> usize {
    (1..c.len()).rev().find(|&n| c[n].norm() > 3.0 * noise[n]).unwrap_or(1)
}

/// Keeps harmonics 0..=n of a real periodic signal sampled on a uniform grid over one period.
fn band_limit(h: &mut [f64], n: usize, fft: &FftPair) {
    let l = h.len();
    if n >= l / 2 {
        return;
    }
    let mut buf: Vec<Complex64> = h.iter().map(|v| Complex64::new(*v, 0.0)).collect();
    fft.forward.process(&mut buf);
    for (k, b) in buf.iter_mut().enumerate() {
        let order = k.min(l - k);
        if order > n {
            *b = Complex64::new(0.0, 0.0);
        }
    }
    fft.inverse.process(&mut buf);
    for (v, b) in h.iter_mut().zip(&buf) {
        *v = b.re / l as f64;
    }
}

struct FftPair {
    forward: std::sync::Arc<dyn rustfft::Fft<f64>>,
    inverse: std::sync::Arc<dyn rustfft::Fft<f64>>,
}

/// The improved equations: one period of the element force and state rebuilt from the
/// significant harmonics, every basis function band-limited to the same harmonics (so each
/// side holds exactly harmonics 0..=n, as eq. 11 balances them), and the samples where the
/// element sticks or reverses left out for models with a sgn term.
fn fd_multi_equations(
    model: &Model,
    eh: &ElementHarmonics,
    step: usize,
    options: &FdMultiOptions,
    term_rms: Vec<f64>,
    mut notes: Vec<String>,
) -> Result<StepEquations, IdentifyError> {
    let p = model.terms.len();
    let amp = eh.displacement.get(1).map_or(0.0, |c| c.norm());
    let amp_noise = eh.displacement_noise.get(1).copied().unwrap_or(0.0);
    if model.has_velocity_jump() && (amp < 1e-9 || amp < 5.0 * amp_noise) {
        notes.push(format!(
            "step {step}: the element did not slip (relative displacement amplitude {amp:.3e} m); left out, as no sgn model can describe a step that only sticks"
        ));
        return Ok(StepEquations { step, a: DMatrix::zeros(0, p), b: DVector::zeros(0), independent_equations: 0.0, term_rms, notes });
    }
    // The state comes from the displacement's significant harmonics, the force from its own;
    // where the force has fewer, the basis functions are band-limited to the same harmonics
    // so that both sides of each equation hold the same harmonics (eq. 11).
    let nx = significant_harmonics(&eh.displacement, &eh.displacement_noise);
    let ng = significant_harmonics(&eh.force, &eh.force_noise);
    if std::env::var("FM_DEBUG").is_ok() { eprintln!("step {step} N {} nx {nx} ng {ng}", eh.harmonics()); }
    let l = options.grid_points.max(16 * (eh.harmonics() + 1)).next_power_of_two();
    let w = eh.omega_rad_s;
    let x = synthesize_grid(&eh.displacement[..=nx], l, |_| Complex64::new(1.0, 0.0));
    let v = synthesize_grid(&eh.displacement[..=nx], l, |n| Complex64::new(0.0, n as f64 * w));
    let g = synthesize_grid(&eh.force[..=ng], l, |_| Complex64::new(1.0, 0.0));
    let mut planner = rustfft::FftPlanner::new();
    let fft = FftPair { forward: planner.plan_fft_forward(l), inverse: planner.plan_fft_inverse(l) };
    let h: Vec<Vec<f64>> = model
        .terms
        .iter()
        .map(|t| {
            let mut hi: Vec<f64> = x.iter().zip(&v).map(|(x, v)| t.eval(*x, *v)).collect();
            if ng < eh.harmonics() {
                band_limit(&mut hi, ng, &fft);
            }
            hi
        })
        .collect();
    let mut keep = vec![true; l];
    if model.has_velocity_jump() {
        let vmax = v.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let v_noise = (1..=nx).map(|n| (n as f64 * w * eh.displacement_noise[n]).powi(2) / 2.0).sum::<f64>().sqrt();
        let threshold = (options.stick_velocity_fraction * vmax).max(3.0 * v_noise);
        let guard = (options.guard_harmonic_periods * l as f64 / ng.min(nx) as f64).ceil() as isize;
        for i in 0..l {
            if v[i].abs() < threshold {
                for d in -guard..=guard {
                    keep[(i as isize + d).rem_euclid(l as isize) as usize] = false;
                }
            }
        }
    }
    let kept: Vec<usize> = (0..l).filter(|i| keep[*i]).collect();
    // Weight by the step's force noise (floor: 1e-3 of its RMS, so noise-free steps are
    // weighted by their size, not by round-off).
    let g_noise = (eh.force_noise[0].powi(2) + eh.force_noise[1..=ng].iter().map(|s| s * s / 2.0).sum::<f64>()).sqrt();
    let g_rms = rms(&g);
    let sigma = if g_noise.is_finite() { g_noise.max(1e-3 * g_rms) } else { g_rms };
    let weight = 1.0 / sigma.max(f64::MIN_POSITIVE);
    let a = DMatrix::from_fn(kept.len(), p, |r, i| h[i][kept[r]] * weight);
    let b = DVector::from_fn(kept.len(), |r, _| g[kept[r]] * weight);
    let independent = (2 * ng + 1) as f64 * kept.len() as f64 / l as f64;
    Ok(StepEquations { step, a, b, independent_equations: independent, term_rms, notes })
}

/// The equations of one step for the FD methods.
pub fn step_equations(
    model: &Model,
    setup: &Setup,
    method: Method,
    an: &HarmonicAnalysis,
    options: &FdMultiOptions,
) -> Result<StepEquations, IdentifyError> {
    let eh = element_harmonics(setup, an, method == Method::Fd)?;
    let nh = eh.harmonics();
    let l = options.grid_points.max(16 * (nh + 1)).next_power_of_two();
    let w = eh.omega_rad_s;
    let x = synthesize_grid(&eh.displacement, l, |_| Complex64::new(1.0, 0.0));
    let v = synthesize_grid(&eh.displacement, l, |n| Complex64::new(0.0, n as f64 * w));
    let p = model.terms.len();
    let h: Vec<Vec<f64>> = model.terms.iter().map(|t| x.iter().zip(&v).map(|(x, v)| t.eval(*x, *v)).collect()).collect();
    let term_rms: Vec<f64> = h.iter().map(|hi| rms(hi)).collect();
    let notes = Vec::new();
    match method {
        Method::Fd => {
            // a = Y_1, b = G_1 (eqs. 13, 22, 23), split into real and imaginary parts.
            let y1: Vec<Complex64> = h.iter().map(|hi| first_harmonic(hi)).collect();
            let a = DMatrix::from_fn(2, p, |r, i| if r == 0 { y1[i].re } else { y1[i].im });
            let b = DVector::from_vec(vec![eh.force[1].re, eh.force[1].im]);
            Ok(StepEquations { step: an.step, a, b, independent_equations: 2.0, term_rms, notes })
        }
        Method::FdMulti => fd_multi_equations(model, &eh, an.step, options, term_rms, notes),
        Method::Td { .. } => unreachable!("time-domain equations come from td_step_equations"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_synthesis_and_first_harmonic_are_inverse() {
        let c = vec![Complex64::new(0.1, 0.0), Complex64::new(0.3, -0.2), Complex64::new(0.0, 0.05)];
        let g = synthesize_grid(&c, 64, |_| Complex64::new(1.0, 0.0));
        assert!((first_harmonic(&g) - c[1]).norm() < 1e-14);
        // derivative of cos(th) at th = pi/2 with w = 2: -2
        let c = vec![Complex64::new(0.0, 0.0), Complex64::new(1.0, 0.0)];
        let v = synthesize_grid(&c, 64, |n| Complex64::new(0.0, n as f64 * 2.0));
        assert!((v[16] + 2.0).abs() < 1e-13);
    }
}
