//! Held-out records of an element test (a sine step, a sweep or a band-random record the
//! diagnosis, or an identification, was not fitted on): the measured force predicted from the
//! measured motion by the baseline and by the model with the top effect, F = m x'' + f(x, x'),
//! and the NMSE of the force before and after.
//!
//! No simulation: the element sits between the measured displacement and the measured force
//! whatever drives it (a displacement-controlled dyno or a force-driven shaker), so the force
//! follows from the measured state. The velocity is the measured displacement differentiated
//! in the frequency domain up to [`CUTOFF_MULTIPLE`] times the record's highest excitation
//! frequency (above it the derivative would be noise amplified by w); the acceleration is the
//! measured one where the record has it, else the displacement differentiated twice in the
//! same band. The record's first and last [`GUARD_FRACTION`] are left out of the NMSE: the
//! derivative of a record that is not periodic rings at its ends.

use std::sync::Arc;

use thiserror::Error;

use crate::basis::Term;
use crate::pipeline::nmse_percent;
use crate::record::{Channel, Excitation, Record};
use crate::signal::differentiate::band_limited_derivative;

/// The velocity keeps the displacement's content up to this multiple of the record's highest
/// excitation frequency (a cubic term's third harmonic, with margin).
pub const CUTOFF_MULTIPLE: f64 = 4.0;
/// Fraction of the record at each end left out of the NMSE.
pub const GUARD_FRACTION: f64 = 0.05;

#[derive(Debug, Error)]
pub enum HeldOutError {
    #[error(
        "held-out record {step}: channel {channel} is missing (the force is predicted from the measured displacement and compared with the measured force)"
    )]
    MissingChannel { step: usize, channel: &'static str },
    #[error(
        "held-out record {step}: a {kind} record has no band to differentiate the displacement in; give a sine, a sweep or a band-random record with its band"
    )]
    NoBand { step: usize, kind: &'static str },
    #[error("held-out record {step}: too short ({samples} samples)")]
    TooShort { step: usize, samples: usize },
}

/// A model of the element force with its fitted coefficients (extra element terms only), and
/// the moving mass it was fitted with.
#[derive(Debug, Clone)]
pub struct TermFit {
    pub terms: Vec<Arc<dyn Term>>,
    pub theta: Vec<f64>,
    pub mass_kg: f64,
}

impl TermFit {
    /// The measured force's prediction at (x, x', x'').
    pub fn force(&self, x: f64, v: f64, a: f64) -> f64 {
        self.mass_kg * a
            + self
                .terms
                .iter()
                .zip(&self.theta)
                .map(|(t, th)| th * t.eval(x, v))
                .sum::<f64>()
    }
}

/// The measured state of a held-out record and the samples scored.
#[derive(Debug, Clone)]
pub struct HeldOutState {
    pub step: usize,
    pub displacement_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    pub acceleration_mps2: Vec<f64>,
    pub force_n: Vec<f64>,
    /// Samples scored (the guard at each end left out).
    pub scored: std::ops::Range<usize>,
    /// Whether the acceleration is the measured one (else the displacement's second
    /// derivative).
    pub acceleration_measured: bool,
}

/// The kind of excitation, as the messages name it.
pub fn excitation_kind(e: &Excitation) -> &'static str {
    match e {
        Excitation::Sine { .. } => "sine",
        Excitation::Random { .. } => "band-random",
        Excitation::Multisine { .. } => "multisine",
        Excitation::Sweep { .. } => "sweep",
    }
}

/// Highest excitation frequency of a held-out record [Hz].
fn top_frequency_hz(r: &Record) -> Result<f64, HeldOutError> {
    match &r.excitation {
        Excitation::Sine { frequency_hz, .. } => Ok(*frequency_hz),
        Excitation::Random {
            band_hz: Some([_, hi]),
            ..
        } => Ok(*hi),
        Excitation::Sweep { law } => Ok(law.start_frequency_hz.max(law.end_frequency_hz)),
        e => Err(HeldOutError::NoBand {
            step: r.step,
            kind: excitation_kind(e),
        }),
    }
}

impl HeldOutState {
    pub fn of(r: &Record) -> Result<HeldOutState, HeldOutError> {
        let step = r.step;
        let channel = |c: Channel| {
            r.channel(c).ok_or(HeldOutError::MissingChannel {
                step,
                channel: c.name(),
            })
        };
        let x = channel(Channel::RelativeDisplacementM)?;
        let f = channel(Channel::ForceN)?;
        let cutoff = CUTOFF_MULTIPLE * top_frequency_hz(r)?;
        let n = x.len();
        let guard = (GUARD_FRACTION * n as f64).ceil() as usize;
        if n < 16 || 2 * guard >= n {
            return Err(HeldOutError::TooShort { step, samples: n });
        }
        let fs = r.sample_rate_hz;
        let measured_a = r.channel(Channel::MassAccelerationMps2);
        Ok(HeldOutState {
            step,
            displacement_m: x.to_vec(),
            velocity_mps: band_limited_derivative(x, fs, cutoff, 1),
            acceleration_mps2: match measured_a {
                Some(a) => a.to_vec(),
                None => band_limited_derivative(x, fs, cutoff, 2),
            },
            force_n: f.to_vec(),
            scored: guard..n - guard,
            acceleration_measured: measured_a.is_some(),
        })
    }

    /// NMSE of the measured force against `fit`'s prediction over the scored samples [%].
    pub fn force_nmse_percent(&self, fit: &TermFit) -> f64 {
        let s = self.scored.clone();
        let predicted: Vec<f64> = s
            .clone()
            .map(|i| {
                fit.force(
                    self.displacement_m[i],
                    self.velocity_mps[i],
                    self.acceleration_mps2[i],
                )
            })
            .collect();
        nmse_percent(&self.force_n[s], &predicted)
    }
}
