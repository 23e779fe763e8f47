//! Classical time-domain force-state mapping (paper section 4.3): one equation per time point,
//! m x_o''(t) = -g(x(t), x'(t)), with the velocity integrated from the relative acceleration.

use nalgebra::{DMatrix, DVector};

use super::{IdentifyError, StepEquations};
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

/// Equations of one step for TD-FSM over the settled part found by the harmonic analysis,
/// at `points` evenly spaced samples (None = every settled sample).
pub fn td_step_equations(
    model: &Model,
    setup: &Setup,
    rec: &Record,
    an: &HarmonicAnalysis,
    points: Option<usize>,
) -> Result<StepEquations, IdentifyError> {
    let start = an.first_settled_sample.min(rec.len());
    let len = an.samples_used.min(rec.len() - start);
    td_range_equations(model, setup, rec, start, len, points)
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
    let Setup::BaseExcited { mass_kg } = setup else {
        return Err(IdentifyError::Step {
            step,
            problem: "time-domain FSM is implemented for the base-excited rig (it needs the mass acceleration)".into(),
        });
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
    let idx: Vec<usize> = match points {
        Some(n) if n < len => (0..n).map(|k| k * len / n).collect(),
        _ => (0..len).collect(),
    };
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
