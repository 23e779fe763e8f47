//! An identified element model on held-out element-test records: its force predicted along
//! each record's measured motion (the force law on the measured displacement and its
//! zero-phase velocity, plus the moving mass times the acceleration), as the diagnosis predicts
//! its held-out records ([`MeasuredState`]), scored by the NMSE of eq. 27 and the RMS error.

use serde::Serialize;

use super::{PipelineError, nmse_percent};
use crate::diagnose::element_heldout::TermFit;
use crate::identify::RecordsOutputError;
use crate::measured_state::MeasuredState;
use crate::model::{IdentifiedModel, Model};
use crate::record::{Channel, Record};
use crate::signal::bouc_wen::HysteresisLaw;

/// The prediction of an element model on one held-out record.
#[derive(Debug, Clone, Serialize)]
pub struct ElementValidation {
    pub step: usize,
    /// 100 % * sum (F - F^)^2 / (N var(F)) of the measured force over the scored samples.
    pub nmse_percent: f64,
    /// RMS of F - F^ over the scored samples [N].
    pub rms_error_n: f64,
    /// Samples scored (the record less a guard at each end, where the derivative rings).
    pub samples: usize,
}

/// Predicts the force of `record` (an element test's: relative displacement and force) with
/// `model` behind a moving mass of `moving_mass_kg` ([`MeasuredState`]: the velocity and, where
/// the record measures none, the acceleration from the displacement differentiated in the
/// frequency domain up to 4 times its highest excitation frequency; the first and last 5 %
/// left out).
pub fn validate_element(
    model: &IdentifiedModel,
    moving_mass_kg: f64,
    record: &Record,
) -> Result<ElementValidation, PipelineError> {
    let fit = TermFit {
        terms: model.model.terms.clone(),
        theta: model.theta.clone(),
        mass_kg: moving_mass_kg,
        hysteresis: None,
    };
    validate_element_fit(&fit, record)
}

/// [`validate_element`] of an element force as fitted ([`TermFit`]: terms, moving mass and a
/// hysteresis state where it has one).
pub fn validate_element_fit(
    fit: &TermFit,
    record: &Record,
) -> Result<ElementValidation, PipelineError> {
    let state = MeasuredState::of(record)?;
    let predicted = state.predicted_force(fit);
    let measured = &state.force_n[state.scored.clone()];
    let sse: f64 = measured
        .iter()
        .zip(&predicted)
        .map(|(f, p)| (f - p).powi(2))
        .sum();
    Ok(ElementValidation {
        step: record.step,
        nmse_percent: nmse_percent(measured, &predicted),
        rms_error_n: (sse / measured.len() as f64).sqrt(),
        samples: measured.len(),
    })
}

/// The simulated displacement of an element model on one held-out force-driven record.
#[derive(Debug, Clone, Serialize)]
pub struct ForcedValidation {
    pub step: usize,
    /// 100 % * sum (x - x^)^2 / (N var(x)) of the measured displacement.
    pub nmse_percent: f64,
    /// RMS of x - x^ [m].
    pub rms_error_m: f64,
    /// The record's sample rate [Hz] and its displacement, measured and simulated [m] (for
    /// the time-trace plot).
    #[serde(skip)]
    pub sample_rate_hz: f64,
    #[serde(skip)]
    pub measured_m: Vec<f64>,
    #[serde(skip)]
    pub simulated_m: Vec<f64>,
}

/// Simulates the mass of a force-driven element test (`moving_mass_kg`, or the identified
/// mass after theta in `element` when None; with a `hysteresis` law's shape, its alpha and
/// yield after those) under `record`'s measured force from the initial
/// state that fits the record best with the parameters held
/// ([`RecordsOutputError::predict_forced`]), and scores its displacement.
pub fn validate_forced_element(
    model: &Model,
    moving_mass_kg: Option<f64>,
    hysteresis: Option<HysteresisLaw>,
    element: &[f64],
    record: &Record,
) -> Result<ForcedValidation, PipelineError> {
    let predicted =
        RecordsOutputError::predict_forced(model, moving_mass_kg, hysteresis, element, record)?;
    let measured =
        record
            .channel(Channel::RelativeDisplacementM)
            .ok_or(PipelineError::MissingChannel {
                step: record.step,
                channel: Channel::RelativeDisplacementM.name(),
            })?;
    let sse: f64 = measured
        .iter()
        .zip(&predicted)
        .map(|(x, p)| (x - p).powi(2))
        .sum();
    Ok(ForcedValidation {
        step: record.step,
        nmse_percent: nmse_percent(measured, &predicted),
        rms_error_m: (sse / measured.len() as f64).sqrt(),
        sample_rate_hz: record.sample_rate_hz,
        measured_m: measured.to_vec(),
        simulated_m: predicted,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Model, ModelOptions};
    use crate::record::{Channel, Excitation};

    /// A sine step whose force is the model's law plus the moving mass's inertia is predicted
    /// to the derivative's accuracy; where the measured law is twice the model's, the RMS
    /// error is the law's RMS force.
    #[test]
    fn a_sine_step_is_predicted_along_its_measured_motion() {
        let (fs, f, n) = (1000.0, 2.0, 4000);
        let w = std::f64::consts::TAU * f;
        let x: Vec<f64> = (0..n).map(|i| 0.01 * (w * i as f64 / fs).sin()).collect();
        let model = Model::by_name("linear", &ModelOptions::default()).unwrap();
        let fitted = IdentifiedModel::new(model, vec![2000.0, 500.0]);
        let force = |scale: f64| -> Vec<f64> {
            (0..n)
                .map(|i| {
                    let t = i as f64 / fs;
                    let (v, a) = (0.01 * w * (w * t).cos(), -0.01 * w * w * (w * t).sin());
                    scale * (2000.0 * x[i] + 500.0 * v) + 0.8 * a
                })
                .collect()
        };
        let record = |f_n: Vec<f64>| Record {
            step: 3,
            excitation: Excitation::Sine {
                frequency_hz: f,
                amplitude: 0.01,
            },
            sample_rate_hz: fs,
            start_time_s: 0.0,
            channels: vec![
                (Channel::RelativeDisplacementM, x.clone()),
                (Channel::ForceN, f_n),
            ],
        };
        let v = validate_element(&fitted, 0.8, &record(force(1.0))).unwrap();
        assert_eq!(v.step, 3);
        assert!(v.nmse_percent < 1e-3, "{v:?}");
        assert_eq!(v.samples, n - 2 * 200);
        // The measured force twice the law's: the error is the law's force.
        let v = validate_element(&fitted, 0.8, &record(force(2.0))).unwrap();
        let law: Vec<f64> = force(1.0)
            .iter()
            .zip(&force(0.0))
            .map(|(a, b)| a - b)
            .collect();
        let scored = &law[200..n - 200];
        let law_rms = (scored.iter().map(|f| f * f).sum::<f64>() / scored.len() as f64).sqrt();
        assert!(
            (v.rms_error_n / law_rms - 1.0).abs() < 1e-4,
            "{v:?} {law_rms}"
        );
    }
}
