//! Short-time harmonic analysis of a sine sweep: the record is cut into windows of whole
//! periods of the sweep's phase, and each window is fitted like a short stepped-sine step, with
//! the sweep's phase `phi(t)` in place of `w t` and harmonics whose amplitude may change
//! linearly across the window:
//! `s(t) = Re(sum_n (C_n + D_n tau) e^{j n (phi(t) - phi(t_a))})`, `tau = (t - t_c) / W`
//! (`t_a` the window's first sample, `t_c` its centre, `W` its duration). `C_n` is then the
//! signal's phasor at the window's centre, where the sweep's frequency is `f(t_c)`, and each
//! window gives the equations of a step at that frequency (eq. 11), so a sweep is identified by
//! the same machinery as steps.
//!
//! Why the `D_n` terms: a velocity `A w(t) cos(phi)` whose `w` grows across the window is not
//! a constant-amplitude harmonic; fitted as one, its growth leaks into the quadrature part
//! (the part in phase with the displacement) and biases the stiffness by about the damping
//! times the sweep rate (a 2.8 % error of k on the dyno damper swept 0.5-8 Hz in 60 s,
//! noise-free). With the linear amplitude terms the error left is second order in the rate.
//!
//! Why this rather than a time-domain fit: the state (velocity, acceleration) is rebuilt from
//! the measured harmonics as for steps, with no numerical differentiation of noisy samples, and
//! the noise per harmonic comes from each window's residual. A displacement-driven element (a
//! dyno) has no dynamics of its own to lag the sweep; a structure with a resonance needs a sweep
//! slow enough to stay settled, as any sweep test.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

use super::{ChannelPhasors, HarmonicAnalysis, PhasorError, checked_length};
use crate::record::Record;

/// How a sweep's frequency moves from start to end.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SweepKind {
    /// `f(t) = f0 + (f1 - f0) t / T`.
    Linear,
    /// `f(t) = f0 (f1 / f0)^(t / T)` (exponential in time; equal time per octave).
    Logarithmic,
}

/// A sine sweep `x(t) = A sin(phi(t))` from `start_frequency_hz` to `end_frequency_hz` over
/// `duration_s`, starting at phase 0 at `t = 0`; `amplitude` `A` in the driven quantity's unit.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SweepLaw {
    pub kind: SweepKind,
    pub amplitude: f64,
    pub start_frequency_hz: f64,
    pub end_frequency_hz: f64,
    pub duration_s: f64,
}

impl SweepLaw {
    /// Instantaneous frequency [Hz] at `t` [s from the sweep's start].
    pub fn frequency_hz(&self, t: f64) -> f64 {
        let (f0, f1, d) = (
            self.start_frequency_hz,
            self.end_frequency_hz,
            self.duration_s,
        );
        match self.kind {
            SweepKind::Linear => f0 + (f1 - f0) * t / d,
            SweepKind::Logarithmic => f0 * (f1 / f0).powf(t / d),
        }
    }

    /// Rate of change of the frequency [Hz/s] at `t`.
    pub fn frequency_rate_hz_per_s(&self, t: f64) -> f64 {
        let (f0, f1, d) = (
            self.start_frequency_hz,
            self.end_frequency_hz,
            self.duration_s,
        );
        match self.kind {
            SweepKind::Linear => (f1 - f0) / d,
            SweepKind::Logarithmic => self.frequency_hz(t) * (f1 / f0).ln() / d,
        }
    }

    /// Phase [rad] at `t`: the integral of `2 pi f`.
    pub fn phase_rad(&self, t: f64) -> f64 {
        let (f0, f1, d) = (
            self.start_frequency_hz,
            self.end_frequency_hz,
            self.duration_s,
        );
        match self.kind {
            SweepKind::Linear => 2.0 * PI * (f0 * t + 0.5 * (f1 - f0) * t * t / d),
            SweepKind::Logarithmic => {
                let l = (f1 / f0).ln();
                if l.abs() < 1e-12 {
                    2.0 * PI * f0 * t
                } else {
                    2.0 * PI * f0 * d / l * (l * t / d).exp_m1()
                }
            }
        }
    }

    /// The time at which the phase reaches `phase_rad` (the inverse of [`SweepLaw::phase_rad`]).
    pub fn time_at_phase(&self, phase_rad: f64) -> f64 {
        let (f0, f1, d) = (
            self.start_frequency_hz,
            self.end_frequency_hz,
            self.duration_s,
        );
        let cycles = phase_rad / (2.0 * PI);
        match self.kind {
            SweepKind::Linear => {
                let a = 0.5 * (f1 - f0) / d;
                if a.abs() < 1e-15 {
                    cycles / f0
                } else {
                    // a t^2 + f0 t - cycles = 0, the root that is 0 at phase 0 (stable form).
                    2.0 * cycles / (f0 + (f0 * f0 + 4.0 * a * cycles).sqrt())
                }
            }
            SweepKind::Logarithmic => {
                let l = (f1 / f0).ln();
                if l.abs() < 1e-12 {
                    cycles / f0
                } else {
                    d / l * (cycles * l / (f0 * d)).ln_1p()
                }
            }
        }
    }

    fn check(&self, step: usize) -> Result<(), PhasorError> {
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if ok(self.start_frequency_hz) && ok(self.end_frequency_hz) && ok(self.duration_s) {
            Ok(())
        } else {
            Err(PhasorError::InvalidFit {
                reason: format!(
                    "step {step}: sweep {} -> {} Hz over {} s: frequencies and duration must be positive and finite",
                    self.start_frequency_hz, self.end_frequency_hz, self.duration_s
                ),
            })
        }
    }
}

/// Options of [`analyse_sweep`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SweepOptions {
    /// Whole periods of the sweep's phase per window.
    pub periods_per_window: usize,
    /// Highest harmonic wanted; capped per window below Nyquist at the window's highest
    /// frequency.
    pub max_harmonic: usize,
}

impl Default for SweepOptions {
    fn default() -> Self {
        SweepOptions {
            periods_per_window: 4,
            max_harmonic: 20,
        }
    }
}

/// Cuts a sweep record (its first sample at the sweep's start) into windows of
/// `periods_per_window` whole periods of the phase and analyses each: one
/// [`HarmonicAnalysis`] per window, numbered from 0 in `step`, with `frequency_hz` the sweep's
/// frequency at the window's centre, where its phasors are. Windows past the record's end are not made.
pub fn analyse_sweep(
    record: &Record,
    law: &SweepLaw,
    options: &SweepOptions,
) -> Result<Vec<HarmonicAnalysis>, PhasorError> {
    law.check(record.step)?;
    let len = checked_length(record)?;
    let fs = record.sample_rate_hz;
    let periods = options.periods_per_window.max(1);
    let per = periods as f64 * 2.0 * PI;
    let mut out = Vec::new();
    let mut k = 0usize;
    loop {
        let (pa, pb) = (k as f64 * per, (k + 1) as f64 * per);
        let (ta, tb) = (law.time_at_phase(pa), law.time_at_phase(pb));
        let first = (ta * fs).ceil() as usize;
        let end = (tb * fs).ceil() as usize;
        if end > len || tb > law.duration_s {
            break;
        }
        let f_top = law.frequency_hz(ta).max(law.frequency_hz(tb));
        let cap = ((fs / f_top - 1.0) / 2.0).floor().max(0.0) as usize;
        let harmonics = options.max_harmonic.min(cap);
        let samples = end - first;
        if harmonics == 0 || samples < 2 * (4 * harmonics + 2) {
            return Err(PhasorError::InvalidFit {
                reason: format!(
                    "step {}: sweep window {k} ({samples} samples at {f_top:.3} Hz) cannot carry harmonics at {fs} Hz sampling",
                    record.step
                ),
            });
        }
        let phase_a = law.phase_rad(first as f64 / fs);
        let t_centre = 0.5 * (first + end - 1) as f64 / fs;
        let basis = design(law, fs, first, end, phase_a, t_centre, harmonics);
        let width_s = samples as f64 / fs;
        let Some(chol) = (basis.transpose() * &basis).cholesky() else {
            return Err(PhasorError::InvalidFit {
                reason: format!("step {}: sweep window {k}: singular fit", record.step),
            });
        };
        let inverse_diag = chol.inverse().diagonal();
        let mut channels = Vec::with_capacity(record.channels.len());
        for (c, data) in &record.channels {
            let y = DVector::from_column_slice(&data[first..end]);
            let beta = chol.solve(&(basis.transpose() * &y));
            let residual = &y - &basis * &beta;
            let dof = (samples - basis.ncols()).max(1) as f64;
            let sigma2 = residual.norm_squared() / dof;
            let half = 2 * harmonics + 1;
            let mut phasors = vec![Complex64::new(beta[0], 0.0)];
            // D_n / W: the amplitude's slope per second (tau is time over the window's width).
            let mut rate_per_s = vec![Complex64::new(beta[half] / width_s, 0.0)];
            let mut noise_std = vec![(sigma2 * inverse_diag[0]).sqrt()];
            for n in 1..=harmonics {
                let (a, b) = (beta[2 * n - 1], beta[2 * n]);
                phasors.push(Complex64::new(a, -b));
                let (a, b) = (beta[half + 2 * n - 1], beta[half + 2 * n]);
                rate_per_s.push(Complex64::new(a, -b) / width_s);
                noise_std.push((sigma2 * (inverse_diag[2 * n - 1] + inverse_diag[2 * n])).sqrt());
            }
            channels.push(ChannelPhasors {
                channel: *c,
                phasors,
                noise_std,
                residual_rms: sigma2.sqrt(),
                rate_per_s,
            });
        }
        out.push(HarmonicAnalysis {
            step: k,
            frequency_hz: law.frequency_hz(t_centre),
            amplitude: law.amplitude,
            t_ref_s: record.start_time_s + first as f64 / fs,
            periods_used: periods,
            periods_available: periods,
            first_settled_sample: first,
            samples_used: samples,
            settled: true,
            harmonics,
            harmonic_cap: cap,
            channels,
            frequency_rate_hz_per_s: law.frequency_rate_hz_per_s(t_centre),
        });
        k += 1;
    }
    Ok(out)
}

/// Columns: DC, `cos(n psi)`, `sin(n psi)` (n = 1..=N), then the same times `tau`, with
/// `psi = phi(t) - phase_a` and `tau = (t - t_centre) / W`, for samples `first..end`. The
/// first `2N + 1` columns are the ones [`analyse_sweep`] reads the phasors from.
fn design(
    law: &SweepLaw,
    fs: f64,
    first: usize,
    end: usize,
    phase_a: f64,
    t_centre: f64,
    harmonics: usize,
) -> DMatrix<f64> {
    let rows = end - first;
    let half = 2 * harmonics + 1;
    let width = rows as f64 / fs;
    let mut m = DMatrix::<f64>::zeros(rows, 2 * half);
    for (r, i) in (first..end).enumerate() {
        let t = i as f64 / fs;
        let psi = law.phase_rad(t) - phase_a;
        let tau = (t - t_centre) / width;
        m[(r, 0)] = 1.0;
        let z = Complex64::from_polar(1.0, psi);
        let mut w = z;
        for n in 1..=harmonics {
            m[(r, 2 * n - 1)] = w.re;
            m[(r, 2 * n)] = w.im;
            w *= z;
        }
        for c in 0..half {
            m[(r, half + c)] = tau * m[(r, c)];
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_inverts_and_its_derivative_is_the_frequency() {
        for kind in [SweepKind::Linear, SweepKind::Logarithmic] {
            let law = SweepLaw {
                kind,
                amplitude: 0.01,
                start_frequency_hz: 1.0,
                end_frequency_hz: 12.0,
                duration_s: 60.0,
            };
            for t in [0.0, 0.3, 7.0, 31.5, 59.9] {
                let back = law.time_at_phase(law.phase_rad(t));
                assert!((back - t).abs() < 1e-9, "{kind:?}: {t} -> {back}");
                let h = 1e-5;
                let d = (law.phase_rad(t + h) - law.phase_rad((t - h).max(0.0)))
                    / (t + h - (t - h).max(0.0));
                let f = law.frequency_hz(t);
                assert!((d / (2.0 * PI) / f - 1.0).abs() < 1e-6, "{kind:?} at {t}");
            }
            assert!((law.frequency_hz(60.0) - 12.0).abs() < 1e-12);
        }
    }

    /// The sweep itself, `A sin(phi)`, is the fundamental `-j A` of every window, with nothing
    /// at DC or above and no residual.
    #[test]
    fn a_pure_sweep_is_its_own_fundamental_in_every_window() {
        let law = SweepLaw {
            kind: SweepKind::Logarithmic,
            amplitude: 0.01,
            start_frequency_hz: 0.5,
            end_frequency_hz: 8.0,
            duration_s: 30.0,
        };
        let fs = 1000.0;
        let x: Vec<f64> = (0..30_000)
            .map(|i| law.amplitude * law.phase_rad(i as f64 / fs).sin())
            .collect();
        let record = Record {
            step: 3,
            excitation: crate::record::Excitation::Random {
                band_hz: None,
                rms: 0.0,
            },
            sample_rate_hz: fs,
            start_time_s: 0.0,
            channels: vec![(crate::record::Channel::RelativeDisplacementM, x)],
        };
        let windows = analyse_sweep(&record, &law, &SweepOptions::default()).unwrap();
        assert!(windows.len() > 10);
        for w in &windows {
            let c = &w.channels[0];
            // Referenced to the phase of the window's first sample.
            let expected = Complex64::new(0.0, -law.amplitude)
                * Complex64::from_polar(1.0, law.phase_rad(w.t_ref_s));
            assert!((c.phasors[1] - expected).norm() < 1e-9 * law.amplitude);
            for (n, p) in c.phasors.iter().enumerate().filter(|(n, _)| *n != 1) {
                assert!(
                    p.norm() < 1e-9 * law.amplitude,
                    "window {} harmonic {n}: {p}",
                    w.step
                );
            }
            assert!(c.residual_rms < 1e-9 * law.amplitude);
        }
        // Windows follow the sweep upwards, each at the frequency of its centre.
        assert!(
            windows
                .windows(2)
                .all(|p| p[1].frequency_hz > p[0].frequency_hz)
        );
    }
}
