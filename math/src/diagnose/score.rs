//! Scoring on held-out records: the fitted model, with its channel transformation, simulated on
//! the measured base motion, against the measured mass acceleration (eq. 27); and the penalty
//! for extra parameters.

use super::effects::Transform;
use super::output_error::DIAGNOSIS_MAX_SUBSTEP_S;
use super::sensor::{apply_samples, undo_samples};
use crate::element::Element;
use crate::pipeline::{VALIDATION_BASE_LOWPASS_HZ, nmse_percent};
use crate::record::{Channel, Record};
use crate::signal::delay::delayed;
use crate::signal::differentiate::central_difference_at_rate;
use crate::signal::lowpass::zero_phase_lowpass;
use crate::sim::{ReplayOptions, RigInitial, SimError, SolverOptions, simulate_on_sampled_base};

/// The prediction of one held-out record.
#[derive(Debug, Clone)]
pub struct HeldOut {
    pub step: usize,
    pub nmse_percent: f64,
    pub measured_mps2: Vec<f64>,
    pub predicted_mps2: Vec<f64>,
    pub relative_displacement_m: Vec<f64>,
    /// Relative velocity of the measured data (central differences of the relative
    /// displacement) [m/s], for the state-plane residual.
    pub relative_velocity_mps: Vec<f64>,
}

impl HeldOut {
    /// RMS of the measured less the predicted mass acceleration [m/s^2].
    pub fn rms_error_mps2(&self) -> f64 {
        let sse: f64 = self
            .measured_mps2
            .iter()
            .zip(&self.predicted_mps2)
            .map(|(m, p)| (m - p).powi(2))
            .sum();
        (sse / self.measured_mps2.len().max(1) as f64).sqrt()
    }
}

/// Simulates `element` on the record's measured base motion and compares the mass
/// acceleration (eq. 27). The transform says what the candidate believes happened between the
/// element and the channels: a delay of the base motion the element sees, sensor dynamics on
/// some channels (undone on the base input and on the relative displacement that gives the
/// initial state, applied to the predicted mass acceleration), a mass factor.
pub fn predict_record(
    element: &dyn Element,
    nominal_mass_kg: f64,
    record: &Record,
    transform: &Transform,
) -> Result<HeldOut, SimError> {
    let missing = |c: Channel| {
        SimError::InvalidSpec(format!(
            "record {}: channel {} is missing",
            record.step,
            c.name()
        ))
    };
    let base = record
        .channel(Channel::BaseDisplacementM)
        .ok_or_else(|| missing(Channel::BaseDisplacementM))?;
    let measured_rel = record
        .channel(Channel::RelativeDisplacementM)
        .ok_or_else(|| missing(Channel::RelativeDisplacementM))?;
    let acc = record
        .channel(Channel::MassAccelerationMps2)
        .ok_or_else(|| missing(Channel::MassAccelerationMps2))?;
    let fs = record.sample_rate_hz;
    // The same zero-phase low-pass as `pipeline::validate_rig` before anything else.
    let mut input = zero_phase_lowpass(base, fs, VALIDATION_BASE_LOWPASS_HZ);
    let sensor = transform.sensor;
    let undone_rel;
    let mut rel: &[f64] = measured_rel;
    if let Some(f) = &sensor {
        if f.applies_to(Channel::BaseDisplacementM) {
            input = undo_samples(&input, fs, f);
        }
        // The relative displacement only gives the initial state, one sample of the undo: low-
        // passed as the base first, else the noise through the undo's derivatives at the
        // record's edge starts the model far off (a second-order undo near 3 Hz multiplies
        // the one-sided second difference's noise by some 200 at 100 Hz).
        if f.applies_to(Channel::RelativeDisplacementM) {
            let smooth = zero_phase_lowpass(measured_rel, fs, VALIDATION_BASE_LOWPASS_HZ);
            undone_rel = undo_samples(&smooth, fs, f);
            rel = &undone_rel;
        }
    }
    if transform.delay_s != 0.0 {
        input = delayed(&input, fs, transform.delay_s);
    }
    // With a delay the element still sees the previous motion for the first d seconds of the
    // record, which this record does not hold: the model starts after them, from the measured
    // relative displacement there, and the error is taken over the samples it predicts.
    let k0 = if transform.delay_s > 0.0 {
        ((transform.delay_s * fs).ceil() as usize + 1).min(input.len().saturating_sub(3))
    } else {
        0
    };
    // The mass moves with the base the element sees: its initial velocity comes from the
    // transformed input.
    let mass_velocity = if input.len() > k0 + 2 {
        ((input[k0 + 2] + rel[k0 + 2]) - (input[k0] + rel[k0])) * fs / 2.0
    } else {
        0.0
    };
    let opts = ReplayOptions {
        initial: RigInitial {
            relative_displacement_m: rel[k0],
            mass_velocity_mps: mass_velocity,
            first_internal_state: 0.0,
        },
        prefilter: None,
        solver: SolverOptions {
            max_substep_s: DIAGNOSIS_MAX_SUBSTEP_S,
            ..SolverOptions::default()
        },
        ..ReplayOptions::default()
    };
    let resp = simulate_on_sampled_base(
        element,
        nominal_mass_kg * transform.mass_factor,
        &input[k0..],
        fs,
        &opts,
    )?;
    let mut predicted = resp.mass_acceleration_mps2;
    if let Some(f) = &sensor
        && f.applies_to(Channel::MassAccelerationMps2)
    {
        predicted = apply_samples(&predicted, fs, f);
    }
    let acc = &acc[k0..];
    let rel = &measured_rel[k0..];
    Ok(HeldOut {
        step: record.step,
        nmse_percent: nmse_percent(acc, &predicted),
        measured_mps2: acc.to_vec(),
        predicted_mps2: predicted,
        relative_displacement_m: rel.to_vec(),
        relative_velocity_mps: central_difference_at_rate(rel, fs),
    })
}

/// Effective number of independent samples of held-out records: 2 B T per record (B the
/// excitation bandwidth, T the duration), at least 10. Band-limited samples are strongly
/// correlated, so counting every sample would make the penalty vanish.
pub fn effective_samples(records: &[&Record]) -> f64 {
    records
        .iter()
        .map(|r| {
            let t = r.len() as f64 / r.sample_rate_hz;
            let b = match r.excitation {
                crate::record::Excitation::Random {
                    band_hz: Some([lo, hi]),
                    ..
                } => hi - lo,
                // Unknown band or a sine step: a nominal 1 Hz.
                _ => 1.0,
            };
            (2.0 * b * t).max(10.0)
        })
        .sum()
}

/// BIC applied to the held-out error: comparing N ln(sigma^2) + p ln N between models is
/// comparing sigma^2 N^(p/N), so the score is the NMSE times N^(p/N) for `extra` added
/// parameters.
pub fn penalised(nmse_percent: f64, extra: usize, n_eff: f64) -> f64 {
    nmse_percent * n_eff.powf(extra as f64 / n_eff)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn delay_shifts_a_sine() {
        let fs = 100.0;
        let f = 2.0;
        let x: Vec<f64> = (0..400).map(|i| (TAU * f * i as f64 / fs).sin()).collect();
        let d = 0.013;
        let y = delayed(&x, fs, d);
        for (i, yi) in y.iter().enumerate().take(390).skip(10) {
            let t = i as f64 / fs - d;
            assert!((yi - (TAU * f * t).sin()).abs() < 2e-3, "{i}");
        }
    }
}
