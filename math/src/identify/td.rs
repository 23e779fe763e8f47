//! Classical time-domain force-state mapping (paper section 4.3): one equation per time point,
//! m x_o''(t) = -g(x(t), x'(t)) on the rig, with the velocity integrated from the relative
//! acceleration; F(t) - m x''(t) = g(x(t), x'(t)) on an element test, along its measured state
//! ([`MeasuredState`]).

use nalgebra::{DMatrix, DVector};

use super::{IdentifyError, StepEquations};
use crate::measured_state::MeasuredState;
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::record::{Channel, Record};

/// Relative velocity over `range` of the record: the integral of the relative acceleration with
/// its linear drift removed, as in the paper; without a base accelerometer, the central
/// difference of the relative displacement.
fn relative_velocity(rec: &Record, start: usize, len: usize) -> Option<Vec<f64>> {
    let dt = 1.0 / rec.sample_rate_hz;
    if let (Some(ao), Some(ai)) = (
        rec.channel(Channel::MassAccelerationMps2),
        rec.channel(Channel::BaseAccelerationMps2),
    ) {
        let a: Vec<f64> = (start..start + len).map(|i| ao[i] - ai[i]).collect();
        let mut v = vec![0.0; len];
        for i in 1..len {
            v[i] = v[i - 1] + 0.5 * dt * (a[i] + a[i - 1]);
        }
        // Remove the best-fit line: over whole periods the true velocity has zero mean and no
        // drift, the integration constant and the accelerometer offset put both in.
        let n = len as f64;
        let tm = (n - 1.0) / 2.0;
        let vm = v.iter().sum::<f64>() / n;
        let sxx: f64 = (0..len).map(|i| (i as f64 - tm).powi(2)).sum();
        let sxy: f64 = (0..len).map(|i| (i as f64 - tm) * (v[i] - vm)).sum();
        let slope = sxy / sxx;
        Some(
            (0..len)
                .map(|i| v[i] - vm - slope * (i as f64 - tm))
                .collect(),
        )
    } else {
        let x = rec.channel(Channel::RelativeDisplacementM)?;
        Some(
            (start..start + len)
                .map(|i| {
                    let lo = i.saturating_sub(1);
                    let hi = (i + 1).min(x.len() - 1);
                    (x[hi] - x[lo]) / ((hi - lo) as f64 * dt)
                })
                .collect(),
        )
    }
}

/// Equations of one step for TD-FSM over the settled part found by the harmonic analysis (an
/// element test's sine step: its whole record), at `points` evenly spaced samples (None =
/// every sample of that part).
pub fn td_step_equations(
    model: &Model,
    setup: &Setup,
    rec: &Record,
    an: &HarmonicAnalysis,
    points: Option<usize>,
) -> Result<StepEquations, IdentifyError> {
    // An element's force law holds at every sample, settled or not, and its state is
    // measured: a sine step's whole record counts (a sweep's windows are its parts). The rig's
    // velocity is integrated over the settled part, whose mean and drift it removes.
    if matches!(setup, Setup::Element { .. })
        && matches!(rec.excitation, crate::record::Excitation::Sine { .. })
    {
        return td_range_equations(model, setup, rec, 0, rec.len(), points);
    }
    let start = an.first_settled_sample.min(rec.len());
    let len = an.samples_used.min(rec.len() - start);
    td_range_equations(model, setup, rec, start, len, points)
}

/// Evenly spaced sample indices `0..len`: `points` of them, or every one.
fn evenly_spaced(len: usize, points: Option<usize>) -> Vec<usize> {
    match points {
        Some(n) if n < len => (0..n).map(|k| k * len / n).collect(),
        _ => (0..len).collect(),
    }
}

/// Equations of TD-FSM for an element test over samples `start..start + len` of `rec`, the
/// scored samples of its [`MeasuredState`] only (the derivative rings at the record's ends):
/// `F - m x'' = sum theta_i h_i(x, x')` at each sample, the moving mass a column when it is
/// identified (`moving_mass_kg` None). Unweighted: every sample counts the same, the
/// time-domain least squares of the force waveform.
fn element_range_equations(
    model: &Model,
    moving_mass_kg: Option<f64>,
    rec: &Record,
    start: usize,
    len: usize,
    points: Option<usize>,
) -> Result<StepEquations, IdentifyError> {
    let state = MeasuredState::of(rec).map_err(|e| IdentifyError::Step {
        step: rec.step,
        problem: e.to_string(),
    })?;
    element_state_equations(model, moving_mass_kg, &state, start, len, points)
}

/// [`element_range_equations`] on a record's measured state already taken (its derivatives
/// are the costly part: a caller that writes the rows of several models keeps the state).
pub fn element_state_equations(
    model: &Model,
    moving_mass_kg: Option<f64>,
    state: &MeasuredState,
    start: usize,
    len: usize,
    points: Option<usize>,
) -> Result<StepEquations, IdentifyError> {
    let step = state.step;
    let lo = start.max(state.scored.start);
    let hi = (start + len).min(state.scored.end);
    if hi < lo + 2 {
        return Err(IdentifyError::Step {
            step,
            problem: format!(
                "samples {start}..{} leave fewer than 2 samples inside the record's scored part {}..{}",
                start + len,
                state.scored.start,
                state.scored.end
            ),
        });
    }
    let idx: Vec<usize> = evenly_spaced(hi - lo, points)
        .into_iter()
        .map(|k| lo + k)
        .collect();
    let (x, v, a) = (
        &state.displacement_m,
        &state.velocity_mps,
        &state.acceleration_mps2,
    );
    let p = model.terms.len();
    let cols = p + usize::from(moving_mass_kg.is_none());
    let rows = DMatrix::from_fn(idx.len(), cols, |r, i| {
        let k = idx[r];
        match model.terms.get(i) {
            Some(t) => t.eval(x[k], v[k]),
            None => a[k],
        }
    });
    let b = DVector::from_fn(idx.len(), |r, _| {
        let k = idx[r];
        state.force_n[k] - moving_mass_kg.unwrap_or(0.0) * a[k]
    });
    let rms = |f: &dyn Fn(usize) -> f64| {
        ((lo..hi).map(|k| f(k).powi(2)).sum::<f64>() / (hi - lo) as f64).sqrt()
    };
    let mut term_rms: Vec<f64> = model
        .terms
        .iter()
        .map(|t| rms(&|k| t.eval(x[k], v[k])))
        .collect();
    if moving_mass_kg.is_none() {
        term_rms.push(rms(&|k| a[k]));
    }
    Ok(StepEquations {
        step,
        a: rows,
        b,
        independent_equations: idx.len() as f64,
        term_rms,
        notes: vec![],
        row_noise: Vec::new(),
        form_variance: 0.0,
    })
}

/// Equations of TD-FSM over samples `start..start + len` of `rec` (any excitation: the
/// equation of motion holds at every sample, transient or not), at `points` evenly spaced
/// samples (None = every sample of the range).
pub fn td_range_equations(
    model: &Model,
    setup: &Setup,
    rec: &Record,
    start: usize,
    len: usize,
    points: Option<usize>,
) -> Result<StepEquations, IdentifyError> {
    let step = rec.step;
    let mass_kg = match setup {
        Setup::BaseExcited { mass_kg } => mass_kg,
        Setup::Element { moving_mass_kg, .. } => {
            return element_range_equations(model, *moving_mass_kg, rec, start, len, points);
        }
        Setup::DrivePoint { .. } => {
            return Err(IdentifyError::Step {
                step,
                problem: "time-domain FSM is implemented for the base-excited rig and the element test (the drive-point setup's element force needs the substructure's dynamics)".into(),
            });
        }
    };
    let need = |c: Channel| {
        rec.channel(c).ok_or_else(|| IdentifyError::Step {
            step,
            problem: format!("channel {} is missing (time-domain FSM needs it)", c.name()),
        })
    };
    let x = need(Channel::RelativeDisplacementM)?;
    let ao = need(Channel::MassAccelerationMps2)?;
    if len < 2 || start + len > rec.len() {
        return Err(IdentifyError::Step {
            step,
            problem: format!(
                "samples {start}..{} are not a range of the record's {} samples",
                start + len,
                rec.len()
            ),
        });
    }
    let v = relative_velocity(rec, start, len).ok_or_else(|| IdentifyError::Step {
        step,
        problem: "no way to get the relative velocity: need base_acceleration_mps2 or relative_displacement_m".into(),
    })?;
    let idx = evenly_spaced(len, points);
    let p = model.terms.len();
    let a = DMatrix::from_fn(idx.len(), p, |r, i| {
        model.terms[i].eval(x[start + idx[r]], v[idx[r]])
    });
    let b = DVector::from_fn(idx.len(), |r, _| -mass_kg * ao[start + idx[r]]);
    let term_rms = model
        .terms
        .iter()
        .map(|t| {
            ((0..len)
                .map(|k| t.eval(x[start + k], v[k]).powi(2))
                .sum::<f64>()
                / len as f64)
                .sqrt()
        })
        .collect();
    Ok(StepEquations {
        step,
        a,
        b,
        independent_equations: idx.len() as f64,
        term_rms,
        notes: vec![],
        row_noise: Vec::new(),
        form_variance: 0.0,
    })
}
