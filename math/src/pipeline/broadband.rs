//! Records that are not steps: sine sweeps (cut into windows by the short-time harmonic
//! analysis, each window then a step at the sweep's frequency there), and band-random records
//! (and an element test's multisines too short to average periods of) identified in the time
//! domain, or by output error on an element test, when a run has nothing else to identify
//! from.

use super::PipelineError;
use crate::diagnose::element_heldout::TermFit;
use crate::identify::{
    self, FORM_MAY_BE_WRONG, FORM_MISFIT_VARIANCE, IdentifyError, Method, RecordsOutputError,
    StepEquations, records_drive, td_range_equations,
};
use crate::measured_state::{CUTOFF_MULTIPLE, MeasuredState, white_noise_std_above};
use crate::model::Model;
use crate::phasor::{
    HarmonicAnalysis, MIN_MULTISINE_PERIODS, MultisineOptions, SweepOptions, analyse_sweep,
};
use crate::recipe::Setup;
use crate::record::{Excitation, Record};
use crate::signal::differentiate::derivative_noise_gain;
use crate::sim::ElementDrive;

/// What `identify` says when it runs output error without being told.
pub const OUTPUT_ERROR_CHOSEN: &str =
    "output error chosen: the records have no steps for the frequency-domain methods";

/// Leading windows of each sweep record left out of the equations: the first holds the
/// transient of the start (the drive starts at full amplitude from rest). On the paper's rig
/// swept 1.6-3.4 Hz the first window is 2.5 s, about 6 decay times of the rig's free response.
pub const SWEEP_TRANSIENT_WINDOWS: usize = 1;

/// The windows of every sweep record ([`analyse_sweep`] with its default options: 4 periods
/// per window, up to 20 harmonics), each numbered with its record's step so that equations
/// and the time-domain method find their record; the first [`SWEEP_TRANSIENT_WINDOWS`] of each
/// record are dropped.
pub fn analyse_sweep_records(records: &[Record]) -> Result<Vec<HarmonicAnalysis>, PipelineError> {
    let mut out = Vec::new();
    for r in records {
        let Excitation::Sweep { law } = &r.excitation else {
            continue;
        };
        let windows = analyse_sweep(r, law, &SweepOptions::default())?;
        if windows.len() <= SWEEP_TRANSIENT_WINDOWS {
            return Err(PipelineError::Identify(IdentifyError::Step {
                step: r.step,
                problem: format!(
                    "the sweep record holds {} window(s) of {} periods; it needs more than {} (the first is the start transient)",
                    windows.len(),
                    SweepOptions::default().periods_per_window,
                    SWEEP_TRANSIENT_WINDOWS
                ),
            }));
        }
        out.extend(
            windows
                .into_iter()
                .skip(SWEEP_TRANSIENT_WINDOWS)
                .map(|w| HarmonicAnalysis { step: r.step, ..w }),
        );
    }
    Ok(out)
}

/// Identifies `model` on the band-random records of `records`, the only way a random record
/// gives equations (it has no phasors): by time-domain FSM with `td-N` / `td-all` (one block
/// per record over all its samples, N evenly spaced samples per record); otherwise, on the
/// rig, by output error from `td-all`'s estimate (the rig simulated under each record's
/// measured base displacement, [`RecordsOutputError::rig`]).
pub fn identify_random_records(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
) -> Result<identify::Identification, PipelineError> {
    let random: Vec<&Record> = records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        .collect();
    let Some(first) = random.first() else {
        return Err(IdentifyError::NoSteps.into());
    };
    let td = Method::Td {
        points_per_step: None,
    };
    let (fit_method, points) = match method {
        Method::Td { points_per_step } => (method, points_per_step),
        _ => (td, None),
    };
    let Setup::BaseExcited { mass_kg } = setup else {
        return Err(IdentifyError::Step {
            step: first.step,
            problem: format!(
                "the data hold only random records, which have no phasors for {method}; the {} setup has no time-domain method for them",
                setup.kind()
            ),
        }
        .into());
    };
    let blocks = random
        .iter()
        .map(|r| td_range_equations(model, setup, r, 0, r.len(), points))
        .collect::<Result<Vec<StepEquations>, _>>()?;
    let start = identify::solve_blocks(model, setup, fit_method, &blocks)?;
    if matches!(method, Method::Td { .. }) {
        return Ok(start);
    }
    let mut id = RecordsOutputError::rig(model, *mass_kg, &random)?.fit(&start)?;
    if method != Method::OutputError {
        id.warnings.push(OUTPUT_ERROR_CHOSEN.into());
    }
    Ok(id)
}

/// Whether a multisine record is too short for the periodic analysis (its transient periods
/// and [`MIN_MULTISINE_PERIODS`] more): an element test identifies it as a record of any
/// excitation.
pub fn multisine_too_short(r: &Record, options: &MultisineOptions) -> bool {
    match &r.excitation {
        Excitation::Multisine {
            base_frequency_hz, ..
        } => {
            let periods = r.len() as f64 * base_frequency_hz / r.sample_rate_hz;
            periods + 1e-9 < (options.transient_periods + MIN_MULTISINE_PERIODS) as f64
        }
        _ => false,
    }
}

/// The records an element test identifies sample by sample: band-random records and
/// multisines too short for the periodic analysis.
pub fn sample_records<'a>(records: &'a [Record], options: &MultisineOptions) -> Vec<&'a Record> {
    records
        .iter()
        .filter(|r| {
            matches!(r.excitation, Excitation::Random { .. }) || multisine_too_short(r, options)
        })
        .collect()
}

/// Identifies an element test's `model` on `records` (none of them sine steps, sweeps or
/// periodic multisines) over all their samples: the time-domain fit of the force along the
/// measured motion, then, unless `method` is the time-domain one, output error
/// ([`RecordsOutputError`]) when the force was the drive (`drive`, as the user names it, else
/// as the records say, [`records_drive`]); with a displacement drive the time-domain fit is the output-error
/// estimate already (the force is the output, linear in theta).
pub fn identify_element_sample_records(
    model: &Model,
    moving_mass_kg: Option<f64>,
    drive: Option<ElementDrive>,
    method: Method,
    records: &[&Record],
) -> Result<identify::Identification, PipelineError> {
    let setup = Setup::Element {
        moving_mass_kg,
        drive,
    };
    let td = Method::Td {
        points_per_step: None,
    };
    let (fit_method, points) = match method {
        Method::Td { points_per_step } => (method, points_per_step),
        _ => (td, None),
    };
    let blocks = records
        .iter()
        .map(|r| td_range_equations(model, &setup, r, 0, r.len(), points))
        .collect::<Result<Vec<StepEquations>, _>>()?;
    let start = identify::solve_blocks(model, &setup, fit_method, &blocks)?;
    if matches!(method, Method::Td { .. }) {
        return Ok(start);
    }
    let mut id = match drive.unwrap_or_else(|| records_drive(records)) {
        ElementDrive::Displacement => {
            let mut id = start;
            id.method = Method::OutputError.name();
            let misfit = force_misfit(model, &setup, &id.theta(), records);
            id.misfit_noise_std = misfit.in_noise_std;
            id.warnings.push(format!(
                "output error: the displacement is the drive, so the model's output is the force along the measured motion, linear in theta: its least squares over every sample of {} record(s), {}",
                records.len(),
                misfit.text()
            ));
            if let Some(rms) = misfit.in_noise_std
                && rms * rms > FORM_MISFIT_VARIANCE
            {
                id.warnings.push(format!(
                    "output error: the model misses the measured force by {rms:.1} noise std (RMS); {FORM_MAY_BE_WRONG}"
                ));
            }
            id
        }
        ElementDrive::Force => {
            RecordsOutputError::forced(model, moving_mass_kg, records)?.fit(&start)?
        }
    };
    if method != Method::OutputError {
        id.warnings.push(OUTPUT_ERROR_CHOSEN.into());
    }
    Ok(id)
}

/// How far an element force fitted along the measured motion misses the measured force.
struct ForceMisfit {
    rms_n: f64,
    /// The RMS of the misfit in each record's force noise std; None where some record's noise
    /// cannot be measured (no band above [`CUTOFF_MULTIPLE`] times its excitation's top
    /// frequency below the Nyquist frequency).
    in_noise_std: Option<f64>,
}

impl ForceMisfit {
    fn text(&self) -> String {
        match self.in_noise_std {
            Some(r) => format!("RMS misfit {:.4e} N, {r:.3} noise std", self.rms_n),
            None => format!(
                "RMS misfit {:.4e} N: the force noise cannot be measured (no band above {CUTOFF_MULTIPLE} times the excitation's top frequency), so the misfit is not compared with noise",
                self.rms_n
            ),
        }
    }
}

/// The misfit of `model` at `theta` on `records`' forces, each predicted along its measured
/// motion over its scored samples (the prediction of `identify --validate`), and the same in
/// noise std: each sample's residual over what the noise alone would leave there, the force's
/// noise and the measured motion's carried through the model (its terms moved by the noise
/// std of the displacement and of the velocity differentiated from it, the mass by the
/// acceleration's), so that a model of the element's form misses by about 1.
fn force_misfit(model: &Model, setup: &Setup, theta: &[f64], records: &[&Record]) -> ForceMisfit {
    let fit = TermFit::of_model(model, setup, theta);
    let (mut squares_n, mut squares_noise, mut samples) = (0.0, Some(0.0), 0usize);
    for r in records {
        let Ok(state) = MeasuredState::of(r) else {
            squares_noise = None;
            continue;
        };
        let measured = &state.force_n[state.scored.clone()];
        let residual: Vec<f64> = measured
            .iter()
            .zip(state.predicted_force(&fit))
            .map(|(m, p)| m - p)
            .collect();
        squares_n += residual.iter().map(|e| e * e).sum::<f64>();
        samples += measured.len();
        squares_noise = squares_noise
            .zip(noise_variances(&state, &fit))
            .map(|(sum, variances)| {
                sum + residual
                    .iter()
                    .zip(variances)
                    .map(|(e, v)| e * e / v)
                    .sum::<f64>()
            });
    }
    let n = samples.max(1) as f64;
    ForceMisfit {
        rms_n: (squares_n / n).sqrt(),
        in_noise_std: squares_noise.map(|s| (s / n).sqrt()),
    }
}

/// The variance the noise alone leaves in each scored sample's force residual: the measured
/// force's noise plus the prediction's, from the noise of the displacement (white above the
/// band, [`white_noise_std_above`]), of the velocity and acceleration differentiated from it
/// ([`derivative_noise_gain`]; the acceleration's own where it is measured) and their
/// correlation (a displacement's noise and its second derivative's: minus the velocity
/// noise's variance). None where a noise cannot be measured.
fn noise_variances(state: &MeasuredState, fit: &TermFit) -> Option<Vec<f64>> {
    let (fs, n) = (state.sample_rate_hz, state.displacement_m.len());
    let cutoff = CUTOFF_MULTIPLE * state.top_frequency_hz;
    let noise = |y: &[f64]| white_noise_std_above(y, fs, cutoff);
    let force = noise(&state.force_n).filter(|s| *s > 0.0)?;
    let sx = noise(&state.displacement_m)?;
    let sv = sx * derivative_noise_gain(n, fs, cutoff, 1);
    let (sa, cross) = if state.acceleration_measured {
        (noise(&state.acceleration_mps2)?, 0.0)
    } else {
        (sx * derivative_noise_gain(n, fs, cutoff, 2), -sv * sv)
    };
    let moved = |x: f64, v: f64, dx: f64, dv: f64| -> f64 {
        fit.terms
            .iter()
            .zip(&fit.theta)
            .map(|(t, th)| th * (t.eval(x + dx, v + dv) - t.eval(x - dx, v - dv)) / 2.0)
            .sum()
    };
    Some(
        state
            .scored
            .clone()
            .map(|i| {
                let (x, v) = (state.displacement_m[i], state.velocity_mps[i]);
                let by_x = moved(x, v, sx, 0.0);
                let by_v = moved(x, v, 0.0, sv);
                let by_a = fit.mass_kg * sa;
                // d(force)/dx times m times the covariance of the two noises.
                let covariance = if sx > 0.0 {
                    2.0 * (by_x / sx) * fit.mass_kg * cross
                } else {
                    0.0
                };
                (force * force + by_x * by_x + by_v * by_v + by_a * by_a + covariance)
                    .max(force * force)
            })
            .collect(),
    )
}
