//! Output-error refinement (`Method::OutputError`): fd-multi's estimate refined so that the
//! exact model's simulation (stick-slip included) reproduces the measured settled samples of
//! every measured channel, each weighted by its measured noise (maximum likelihood for white
//! noise).
//!
//! The harmonic balance of fd-multi has to leave the stick phase out (the element force is
//! set-valued there), so the information in the exact stick-slip timing is lost; output error
//! uses every settled sample. One Levenberg-Marquardt loop ([`lm`]) serves every setup; each
//! setup gives its residuals from its simulator:
//!
//! - the drive-point 3-DOF example ([`three_dof`]): x, x_d and F, with the far side of the
//!   element and each step's force amplitude fitted too;
//! - the base-excited rig ([`rig`]): base displacement, relative displacement and mass
//!   acceleration, the rig driven by a sine per step whose amplitude and phase are fitted too;
//! - the element test ([`element_test`]): x, F and the mass acceleration, the element driven by
//!   a fitted sine per step of its stroke (damper dyno) or of its force (shaker), whichever
//!   channel is the purer sine.
//! - element-test records of any excitation, with no steps ([`sampled_drive`]): the mass
//!   simulated under the measured force, each record from its fitted initial state.

mod element;
pub mod element_test;
mod lm;
pub mod rig;
pub mod sampled_drive;
mod sandwich;
mod three_dof;

use super::{Identification, IdentifyError, Parameter};
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::record::{Channel, Record};
use crate::sim::excitation::{Piece, PiecewiseSignal};

pub use element_test::{ElementOutputError, element_drive_of};
pub use rig::{RigDrive, RigMisfit, RigOutputError};
pub use sampled_drive::{
    HYSTERESIS_PARAMETERS, RecordsOutputError, RigChannelEffect, records_drive,
};

/// A misfit whose mean square exceeds this many noise variances is more than the noise: the
/// model's form may not describe the data.
pub const FORM_MISFIT_VARIANCE: f64 = 2.0;

/// What a fit's warning says when its misfit exceeds [`FORM_MISFIT_VARIANCE`] noise variances.
pub const FORM_MAY_BE_WRONG: &str = "the model's form may not describe these data (try diagnose)";

/// Floor of each channel's noise std, relative to its fundamental.
const NOISE_FLOOR: f64 = 1e-6;

fn unsupported(problem: String) -> IdentifyError {
    IdentifyError::Step { step: 0, problem }
}

/// Refines `first` (an fd-multi identification of the same data) by output error; see the
/// module docs. The returned covariance is the Gauss-Newton one (inverse Fisher information
/// of the fitted samples) for the element parameters.
pub fn refine_output_error(
    model: &Model,
    setup: &Setup,
    records: &[Record],
    analyses: &[HarmonicAnalysis],
    first: &Identification,
) -> Result<Identification, IdentifyError> {
    match setup {
        Setup::DrivePoint { .. } => three_dof::refine(model, setup, records, analyses, first),
        Setup::BaseExcited { mass_kg } => {
            RigOutputError::new(model, *mass_kg, records, analyses, RigDrive::FittedSine)?
                .refine(first)
        }
        Setup::Element { moving_mass_kg, .. } => element_test::ElementOutputError::new(
            model,
            *moving_mass_kg,
            records,
            analyses,
            element_test::element_drive_of(analyses),
        )?
        .refine(first),
    }
}

/// The sine records of a run and their analyses, checked to be records 0, 1, 2, ... of one
/// sample rate and contiguous in time (the simulators run the whole sequence).
fn sine_records<'a>(
    records: &'a [Record],
    analyses: &[HarmonicAnalysis],
) -> Result<Vec<&'a Record>, IdentifyError> {
    let recs: Vec<&Record> = records
        .iter()
        .filter(|r| matches!(r.excitation, crate::record::Excitation::Sine { .. }))
        .collect();
    if recs.is_empty() || analyses.len() != recs.len() {
        return Err(IdentifyError::NoSteps);
    }
    let fs = recs[0].sample_rate_hz;
    let mut next = recs[0].start_time_s;
    for (i, (r, an)) in recs.iter().zip(analyses).enumerate() {
        let contiguous = (r.start_time_s - next).abs() * fs < 0.5;
        if r.step != i || an.step != r.step || r.sample_rate_hz != fs || !contiguous {
            return Err(IdentifyError::Step {
                step: r.step,
                problem: "output-error refinement simulates the whole run: it needs sine records 0, 1, 2, ... back to back at one sample rate".into(),
            });
        }
        next = r.start_time_s + r.len() as f64 / fs;
    }
    Ok(recs)
}

/// Whether each of the `n` samples of a simulated record is kept in a channel that jumps at
/// the simulation's stick/slip events (a rig's or a force-driven mass's acceleration, a
/// displacement-driven element's force): a sample within a sample interval of an event changes
/// by a jump when the event crosses it, so the misfit would have cliffs that stall the fit.
/// The drive of a sine-step run as the output-error fits model it: one sine per record
/// (`nuisance`: the amplitude and phase of each, in record order) at the record's frequency,
/// starting where the record starts, and at rest before the run at the first sine's starting
/// value (as `Program::from_steps`). The rig's base and the element test's drive.
fn sine_per_record_signal(records: &[&Record], nuisance: &[f64]) -> PiecewiseSignal {
    let fs = records[0].sample_rate_hz;
    let mut signal = PiecewiseSignal::new(0.0);
    let mut first = 0usize;
    for (k, r) in records.iter().enumerate() {
        let t0 = first as f64 / fs;
        let omega = 2.0 * std::f64::consts::PI * r.excitation.frequency_hz().unwrap_or(0.0);
        signal.push(
            t0,
            Piece::Sine {
                t0,
                amplitude: nuisance[2 * k],
                omega,
                phase: nuisance[2 * k + 1],
            },
        );
        first += r.len();
    }
    let v0 = signal.pieces[1].eval(0.0, 0.0).value;
    signal.pieces[0] = Piece::Const(v0);
    signal
}

/// The two samples around each sample interval with an event and one more on each side are
/// dropped (an event may move by a sample interval during a pass without reaching a kept
/// sample).
fn event_mask(trace: &crate::sim::RecordTrace, n: usize) -> Vec<bool> {
    let state: Vec<i8> = trace
        .samples
        .iter()
        .map(|t| {
            if t.stuck {
                0
            } else {
                t.relative_velocity_mps.signum() as i8
            }
        })
        .collect();
    let mut kept = vec![true; n];
    for i in 1..state.len().min(n) {
        if state[i] != state[i - 1] {
            for k in kept
                .iter_mut()
                .take((i + 2).min(n))
                .skip(i.saturating_sub(2))
            {
                *k = false;
            }
        }
    }
    kept
}

/// Noise std of each of `channels` per step: the residual of its harmonic fit, floored at
/// `NOISE_FLOOR` of the channel's largest fundamental over the steps, so that noise-free
/// data (or a step that only sticks) are not weighted by the round-off of the harmonic fit.
fn channel_noise<const N: usize>(
    analyses: &[HarmonicAnalysis],
    channels: &[Channel; N],
) -> Vec<[f64; N]> {
    let fundamental = channels.map(|c| {
        analyses
            .iter()
            .filter_map(|an| an.channel(c))
            .map(|p| p.phasors.get(1).map_or(0.0, |z| z.norm()))
            .fold(0.0f64, f64::max)
    });
    analyses
        .iter()
        .map(|an| {
            let mut s = [0.0; N];
            for (ci, c) in channels.iter().enumerate() {
                s[ci] = an.channel(*c).map_or(f64::NAN, |p| {
                    p.residual_rms
                        .max(NOISE_FLOOR * fundamental[ci])
                        .max(f64::MIN_POSITIVE)
                });
            }
            s
        })
        .collect()
}

/// The identification of the parameters of `first` (the first of the fit: the model's, then
/// the setup's, as an element test's moving mass), with the misfit warning and the r contributions of `first` rescaled to the refined values.
fn identification(
    model: &Model,
    first: &Identification,
    fit: &lm::Fit,
    steps_used: Vec<usize>,
    note: String,
) -> Identification {
    let p_model = first.parameters.len();
    let p = &fit.p;
    let cov = fit.covariance();
    let rms = fit.rms();
    let mut warnings = first.warnings.clone();
    if rms * rms > FORM_MISFIT_VARIANCE {
        warnings.push(format!(
            "output error: the simulated model misses the measured samples by {rms:.1} noise std (RMS); {FORM_MAY_BE_WRONG}"
        ));
    }
    let parameters: Vec<Parameter> = (0..p_model)
        .map(|i| Parameter {
            name: first.parameters[i].name.clone(),
            value: p[i],
            std: cov[(i, i)].sqrt(),
        })
        .collect();
    let covariance = (0..p_model)
        .map(|i| (0..p_model).map(|j| cov[(i, j)]).collect())
        .collect();
    warnings.push(format!(
        "output error: {note}; {} samples, RMS misfit {rms:.3} noise std",
        fit.residual.len()
    ));
    // r contributions: those of the first estimate's terms, rescaled by the refined theta.
    let scaled: Vec<(String, f64)> = first
        .r
        .iter()
        .zip(first.theta())
        .zip(p)
        .map(|(((n, r), t0), t)| {
            let v = if t0 != 0.0 { r * (t / t0).abs() } else { 0.0 };
            (n.clone(), v)
        })
        .collect();
    let total: f64 = scaled.iter().map(|(_, v)| v).sum();
    let r_out = scaled
        .into_iter()
        .map(|(n, v)| (n, 100.0 * v / total.max(f64::MIN_POSITIVE)))
        .collect();
    Identification {
        model: model.name.clone(),
        method: super::Method::OutputError.name(),
        parameters,
        covariance,
        condition_number: fit.condition_number(),
        equations: fit.residual.len(),
        r: r_out,
        residual_rms: rms,
        steps_used,
        // Against the noise in the time domain: the RMS misfit above.
        fit_quality: None,
        misfit_noise_std: Some(rms),
        warnings,
    }
}
