//! From records to an identification and its validation: the steps every front end (the
//! `forcemap` command, the nodes, the table reproduction) runs in the same way.

use serde::Serialize;
use thiserror::Error;

use crate::identify::{self, FdMultiOptions, Identification, IdentifyError, Method};
use crate::model::{IdentifiedModel, Model};
use crate::parallel;
use crate::phasor::{
    HarmonicAnalysis, MultisineAnalysis, MultisineError, MultisineOptions, PhasorError,
    PhasorOptions, analyse_multisine, analyse_record,
};
use crate::recipe::Setup;
use crate::record::{Channel, Excitation, Record};
use crate::sim::{ReplayOptions, RigInitial, SimError, ZeroPhaseLowpass, simulate_on_sampled_base};

mod broadband;
mod element;
mod estimator_choice;
mod hysteresis_records;
mod sine_stream;
pub use broadband::{
    SWEEP_TRANSIENT_WINDOWS, analyse_sweep_records, identify_element_sample_records,
    identify_random_records, multisine_too_short, sample_records,
};
pub use element::{
    ElementValidation, ForcedValidation, validate_element, validate_element_fit,
    validate_forced_element,
};
pub use estimator_choice::{CHOICE_MARGIN, MIN_CROSS_VALIDATION_STEPS, choose_estimator};
pub use hysteresis_records::{
    HysteresisRefit, refine_hysteresis_on_records, validate_forced_hysteresis,
};
pub use sine_stream::{Analysed, SineStepStream};

#[derive(Debug, Error)]
pub enum PipelineError {
    #[error(transparent)]
    Phasor(#[from] PhasorError),
    #[error(transparent)]
    Multisine(#[from] MultisineError),
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    #[error("validation of record {step}: {source}")]
    Simulation { step: usize, source: SimError },
    #[error("validation of record {step}: channel {channel} is missing")]
    MissingChannel { step: usize, channel: &'static str },
    #[error(transparent)]
    HeldOut(#[from] crate::measured_state::MeasuredStateError),
}

/// Harmonic analyses of the sine steps; steps that never settled are kept but noted.
pub fn analyse_sine_steps(
    records: &[Record],
    options: &PhasorOptions,
) -> Result<(Vec<HarmonicAnalysis>, Vec<String>), PhasorError> {
    let sines: Vec<&Record> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        .collect();
    // Each step's analysis is its own: many steps are analysed on the machine's cores.
    let samples = sines.iter().map(|r| r.len()).sum();
    let min_part = parallel::min_part_of(samples, sines.len());
    let analysed = parallel::try_in_parts(&sines, min_part, |part| {
        part.iter().map(|r| analyse_sine_step(r, options)).collect()
    })?;
    let mut out = Vec::with_capacity(analysed.len());
    let mut notes = Vec::new();
    for (an, note) in analysed {
        notes.extend(note);
        out.push(an);
    }
    Ok((out, notes))
}

/// The harmonic analysis of one sine step and the note of [`analyse_sine_steps`] when it never
/// settled (for records analysed as they arrive).
pub fn analyse_sine_step(
    record: &Record,
    options: &PhasorOptions,
) -> Result<(HarmonicAnalysis, Option<String>), PhasorError> {
    let an = analyse_record(record, options)?;
    let note = (!an.settled).then(|| {
        format!(
            "step {}: no settled part of {} periods found; phasors from {} periods anyway",
            an.step,
            options.min_periods.max(2),
            an.periods_used
        )
    });
    Ok((an, note))
}

/// Analyses of the periodic multisine records (the default transient of one period).
pub fn analyse_multisine_records(
    records: &[Record],
    options: &MultisineOptions,
) -> Result<Vec<MultisineAnalysis>, MultisineError> {
    records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Multisine { .. }))
        .map(|r| analyse_multisine(r, options))
        .collect()
}

/// Identifies `model` on the sine steps, the sweep records (their windows) and the periodic
/// multisine records of `records`; when there are none of these, on the band-random records by
/// time-domain FSM (the random records are otherwise left for validation).
pub fn identify_records(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    phasor_options: &PhasorOptions,
    fd_options: &FdMultiOptions,
) -> Result<Identification, PipelineError> {
    identify_records_with_analyses(model, setup, method, records, phasor_options, fd_options)
        .map(|(id, _)| id)
}

/// [`identify_records`], also returning the harmonic analyses of the sine steps and the sweep
/// windows.
pub fn identify_records_with_analyses(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    phasor_options: &PhasorOptions,
    fd_options: &FdMultiOptions,
) -> Result<(Identification, Vec<HarmonicAnalysis>), PipelineError> {
    let (analyses, notes) = analyse_sine_steps(records, phasor_options)?;
    identify_analysed(model, setup, method, records, analyses, notes, fd_options)
}

/// [`identify_records_with_analyses`] with the sine steps already analysed (`analyses` and
/// their `notes`, [`analyse_sine_step`] in record order): `records` need not hold the sine
/// steps for the frequency-domain methods (fd, fd-multi); time-domain FSM and output error
/// need them.
pub fn identify_analysed(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    mut analyses: Vec<HarmonicAnalysis>,
    notes: Vec<String>,
    fd_options: &FdMultiOptions,
) -> Result<(Identification, Vec<HarmonicAnalysis>), PipelineError> {
    let sweeps = analyse_sweep_records(records)?;
    if let (Some(w), Method::OutputError) = (sweeps.first(), method) {
        return Err(PipelineError::Identify(identify::IdentifyError::Step {
            step: w.step,
            problem: "output-error refinement simulates sine steps; a sweep record is identified by fd, fd-multi or td".into(),
        }));
    }
    analyses.extend(sweeps);
    let multisine_options = MultisineOptions::default();
    if let Setup::Element {
        moving_mass_kg,
        drive,
    } = setup
        && analyses.is_empty()
    {
        let sampled = sample_records(records, &multisine_options);
        let periodic = records.iter().any(|r| {
            matches!(r.excitation, Excitation::Multisine { .. })
                && !multisine_too_short(r, &multisine_options)
        });
        if !sampled.is_empty() && !periodic {
            let mut id =
                identify_element_sample_records(model, *moving_mass_kg, *drive, method, &sampled)?;
            id.warnings.splice(0..0, notes);
            return Ok((id, analyses));
        }
    }
    let multisines = analyse_multisine_records(records, &multisine_options)?;
    if analyses.is_empty()
        && multisines.is_empty()
        && records
            .iter()
            .any(|r| matches!(r.excitation, Excitation::Random { .. }))
    {
        let mut id = identify_random_records(model, setup, method, records)?;
        id.warnings.splice(0..0, notes);
        return Ok((id, analyses));
    }
    let mut id = if multisines.is_empty() {
        let id = identify::identify(model, setup, method, records, &analyses, fd_options)?;
        choose_estimator(model, setup, method, records, &analyses, fd_options, id)?
    } else {
        identify::identify_with_multisines(
            model,
            setup,
            method,
            &analyses,
            &multisines,
            fd_options,
        )?
    };
    id.warnings.splice(0..0, notes);
    Ok((id, analyses))
}

/// Tracks `model` on the sine steps of `records`: theta after every step, the steps before it
/// weighed by `factor_per_step` each time a step is added ([`identify::track_steps_within`]),
/// and the harmonic analyses. With `update_period_s`, also theta within each step, every that
/// many seconds of its samples once they have settled periods (the provisional phasors the
/// live harmonic node publishes with the same period). The last theta is the current one and
/// carries the analysis notes. The periodic multisine records are refused: forgetting is per
/// step.
#[allow(clippy::too_many_arguments)]
pub fn track_records_with_analyses(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    phasor_options: &PhasorOptions,
    fd_options: &FdMultiOptions,
    factor_per_step: f64,
    update_period_s: Option<f64>,
) -> Result<(Vec<identify::TrackPoint>, Vec<HarmonicAnalysis>), PipelineError> {
    if let Some(r) = records.iter().find(|r| {
        matches!(
            r.excitation,
            Excitation::Multisine { .. } | Excitation::Sweep { .. }
        )
    }) {
        return Err(PipelineError::Identify(identify::IdentifyError::Step {
            step: r.step,
            problem:
                "tracking forgets per sine step; a periodic multisine or sweep record cannot be tracked"
                    .into(),
        }));
    }
    let (analyses, notes) = analyse_sine_steps(records, phasor_options)?;
    let mut provisional = Vec::with_capacity(analyses.len());
    for r in records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
    {
        provisional.push(match update_period_s {
            Some(t) => crate::phasor::provisional_analyses(
                r,
                phasor_options,
                crate::phasor::ProvisionalUpdates::new(t, r.sample_rate_hz)?,
            )?,
            None => Vec::new(),
        });
    }
    let steps: Vec<identify::TrackedStep> = provisional
        .iter()
        .zip(&analyses)
        .map(|(p, an)| identify::TrackedStep {
            provisional: p,
            last: an,
        })
        .collect();
    let mut track =
        identify::track_steps_within(model, setup, method, &steps, fd_options, factor_per_step)?;
    if track.is_empty() {
        // No step determined theta; forgetting does not change which parameters the equations
        // determine, so the converged solve gives the reason (or, equally, the one theta).
        let id = identify::identify(model, setup, method, records, &analyses, fd_options)?;
        let last = analyses.last();
        track.push(identify::TrackPoint {
            identification: id,
            step: last.map_or(0, |a| a.step),
            provisional: false,
            data_end_s: last.map_or(f64::NAN, HarmonicAnalysis::data_end_s),
        });
    }
    if let Some(last) = track.last_mut() {
        last.identification.warnings.splice(0..0, notes);
    }
    Ok((track, analyses))
}

/// The prediction of a base-excited rig model on one record.
#[derive(Debug, Clone, Serialize)]
pub struct Validation {
    pub step: usize,
    /// Eq. 27: 100 % * sum (y - y^)^2 / (N var(y)) of the mass acceleration.
    pub nmse_percent: f64,
    /// RMS of y - y^ [m/s^2].
    pub rms_error_mps2: f64,
    #[serde(skip)]
    pub predicted_mass_acceleration_mps2: Vec<f64>,
    #[serde(skip)]
    pub measured_mass_acceleration_mps2: Vec<f64>,
}

impl Validation {
    /// The figures without the two traces (all a report without plots reads of it).
    pub fn without_traces(self) -> Validation {
        Validation {
            predicted_mass_acceleration_mps2: Vec::new(),
            measured_mass_acceleration_mps2: Vec::new(),
            ..self
        }
    }
}

/// Eq. 27, in percent.
pub fn nmse_percent(measured: &[f64], predicted: &[f64]) -> f64 {
    let n = measured.len().min(predicted.len());
    if n == 0 {
        return f64::NAN;
    }
    let mean = measured[..n].iter().sum::<f64>() / n as f64;
    let var = measured[..n]
        .iter()
        .map(|y| (y - mean).powi(2))
        .sum::<f64>()
        / n as f64;
    let sse: f64 = measured[..n]
        .iter()
        .zip(predicted)
        .map(|(y, p)| (y - p).powi(2))
        .sum();
    100.0 * sse / (n as f64 * var)
}

/// Simulates the identified rig model under the record's measured base displacement and
/// compares the predicted mass acceleration with the measured one (eq. 27). The model starts
/// from the measured relative displacement and the mass velocity estimated from the first
/// samples.
/// Default zero-phase low-pass [Hz] on the measured base displacement before it drives the
/// model: the paper's rig has a 10 Hz anti-alias filter, and without one the spline's velocity
/// and acceleration amplify the sensor noise (at 40 dB SNR the true model's NMSE rises from
/// 0.003 % to 1.3 % on the rig stand-in).
pub const VALIDATION_BASE_LOWPASS_HZ: f64 = 10.0;

pub fn validate_rig(
    model: &IdentifiedModel,
    mass_kg: f64,
    record: &Record,
) -> Result<Validation, PipelineError> {
    validate_rig_with(model, mass_kg, record, Some(VALIDATION_BASE_LOWPASS_HZ))
}

/// [`validate_rig`] on every band-random record of `records` in their order: the records that
/// identification leaves for validation.
pub fn validate_rig_on_random_records(
    model: &IdentifiedModel,
    mass_kg: f64,
    records: &[Record],
) -> Result<Vec<Validation>, PipelineError> {
    let random: Vec<&Record> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        .collect();
    // Each record's simulation is its own: many records are simulated on the machine's cores.
    let samples = random.iter().map(|r| r.len()).sum();
    let min_part = parallel::min_part_of(samples, random.len());
    parallel::try_in_parts(&random, min_part, |part| {
        part.iter()
            .map(|r| validate_rig(model, mass_kg, r))
            .collect()
    })
}

/// [`validate_rig`] with a chosen base low-pass (None: the raw samples).
pub fn validate_rig_with(
    model: &IdentifiedModel,
    mass_kg: f64,
    record: &Record,
    base_lowpass_hz: Option<f64>,
) -> Result<Validation, PipelineError> {
    let step = record.step;
    let get = |c: Channel| {
        record.channel(c).ok_or(PipelineError::MissingChannel {
            step,
            channel: c.name(),
        })
    };
    let base = get(Channel::BaseDisplacementM)?;
    let rel = get(Channel::RelativeDisplacementM)?;
    let acc = get(Channel::MassAccelerationMps2)?;
    let fs = record.sample_rate_hz;
    let mass_velocity = if base.len() > 2 {
        ((base[2] + rel[2]) - (base[0] + rel[0])) * fs / 2.0
    } else {
        0.0
    };
    let opts = ReplayOptions {
        initial: RigInitial {
            relative_displacement_m: rel[0],
            mass_velocity_mps: mass_velocity,
            first_internal_state: 0.0,
        },
        prefilter: base_lowpass_hz.map(|cutoff_hz| ZeroPhaseLowpass { cutoff_hz }),
        ..ReplayOptions::default()
    };
    let resp = simulate_on_sampled_base(model, mass_kg, base, fs, &opts)
        .map_err(|source| PipelineError::Simulation { step, source })?;
    let n = acc.len().min(resp.mass_acceleration_mps2.len()).max(1);
    let sse: f64 = acc
        .iter()
        .zip(&resp.mass_acceleration_mps2)
        .map(|(y, p)| (y - p).powi(2))
        .sum();
    Ok(Validation {
        step,
        nmse_percent: nmse_percent(acc, &resp.mass_acceleration_mps2),
        rms_error_mps2: (sse / n as f64).sqrt(),
        predicted_mass_acceleration_mps2: resp.mass_acceleration_mps2,
        measured_mass_acceleration_mps2: acc.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nmse_is_eq_27() {
        let y = [1.0, -1.0, 1.0, -1.0];
        assert_eq!(nmse_percent(&y, &y), 0.0);
        // predicting zero leaves the whole variance: 100 %
        assert!((nmse_percent(&y, &[0.0; 4]) - 100.0).abs() < 1e-12);
        // an error of half the amplitude everywhere: 25 %
        assert!((nmse_percent(&y, &[0.5, -0.5, 0.5, -0.5]) - 25.0).abs() < 1e-12);
    }
}
