//! Preprocessing of a record (steps 1 to 4 of the module docs of [`super`]): the position
//! low-passed without phase shift, velocity and acceleration by central differences, the
//! border cut, and the decimation of every column.

use super::AxisError;
use crate::signal::decimate::Decimator;
use crate::signal::differentiate::central_difference;
use crate::signal::iir::LowPass;

/// A record of a force-driven axis.
#[derive(Debug, Clone)]
pub struct AxisRecord {
    pub sample_rate_hz: f64,
    pub position_m: Vec<f64>,
    pub force_n: Vec<f64>,
}

/// Preparation of the regressors (see the docs of [`super`], "Preprocessing").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeDomainOptions {
    /// Cut-off of the zero-phase 4th-order Butterworth low-pass of the position [Hz] (the
    /// published script: 100 Hz at 1 kHz).
    pub position_cutoff_hz: f64,
    /// Keep one sample in this many after the anti-alias low-pass (its pass band ends at
    /// 0.8 Nyquist / decimation).
    pub decimation: usize,
}

impl Default for TimeDomainOptions {
    fn default() -> Self {
        TimeDomainOptions {
            position_cutoff_hz: 100.0,
            decimation: 10,
        }
    }
}

/// Time dropped at each end after differentiating: the published script drops 49 samples at
/// 1 kHz from the start (`n_border = 50`); the end is dropped too, where the differences are
/// one-sided.
pub const BORDER_S: f64 = 0.049;

/// Order of the position filter (the published script's `butter(4, ...)`).
const POSITION_FILTER_ORDER: usize = 4;

/// A record after differentiation and the border cut, at the full rate, with what the
/// decimation needs.
pub(super) struct Motion {
    pub(super) q: Vec<f64>,
    pub(super) qd: Vec<f64>,
    pub(super) qdd: Vec<f64>,
    pub(super) force: Vec<f64>,
    pub(super) fs: f64,
    /// Index in the original record of `q[0]`.
    pub(super) first_index: usize,
    pub(super) q_mean: f64,
    pub(super) decimator: Decimator,
}

impl Motion {
    /// Sample rate of the decimated columns [Hz].
    pub(super) fn decimated_rate_hz(&self) -> f64 {
        self.fs / self.decimator.factor() as f64
    }

    pub(super) fn new(
        r: &AxisRecord,
        o: &TimeDomainOptions,
        record: &'static str,
    ) -> Result<Motion, AxisError> {
        let bad = |detail: String| AxisError::BadRecord { record, detail };
        if o.decimation == 0 || o.position_cutoff_hz.is_nan() || o.position_cutoff_hz <= 0.0 {
            return Err(AxisError::BadOptions(format!("{o:?}")));
        }
        let fs = r.sample_rate_hz;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(bad(format!("sample rate {fs} Hz")));
        }
        if r.position_m.len() != r.force_n.len() {
            return Err(bad(format!(
                "{} positions but {} forces",
                r.position_m.len(),
                r.force_n.len()
            )));
        }
        if let Some(i) = r
            .position_m
            .iter()
            .chain(&r.force_n)
            .position(|v| !v.is_finite())
        {
            return Err(bad(format!(
                "non-finite {} at sample {}",
                if i < r.position_m.len() {
                    "position"
                } else {
                    "force"
                },
                i % r.position_m.len().max(1)
            )));
        }
        let dt = 1.0 / fs;
        let q = LowPass::butterworth(POSITION_FILTER_ORDER, o.position_cutoff_hz, fs)
            .filtfilt(&r.position_m);
        let qd = central_difference(&q, dt);
        let qdd = central_difference(&qd, dt);
        let border = (BORDER_S * fs).round() as usize;
        let n = q.len();
        let keep = border..n.saturating_sub(border).max(border);
        let q: Vec<f64> = q[keep.clone()].to_vec();
        let q_mean = q.iter().sum::<f64>() / q.len().max(1) as f64;
        Ok(Motion {
            qd: qd[keep.clone()].to_vec(),
            qdd: qdd[keep.clone()].to_vec(),
            force: r.force_n[keep].to_vec(),
            q,
            fs,
            first_index: border,
            q_mean,
            decimator: Decimator::new(o.decimation, fs),
        })
    }

    /// Indices kept by the decimation ([`Decimator::kept`]).
    pub(super) fn kept(&self) -> impl Iterator<Item = usize> + use<> {
        self.decimator.kept(self.q.len())
    }

    /// A full-rate column, anti-alias filtered and decimated.
    pub(super) fn decimate(&self, full: &[f64]) -> Vec<f64> {
        self.decimator.decimate(full)
    }

    /// The decimated samples' times from the start of the record [s].
    pub(super) fn kept_times_s(&self) -> Vec<f64> {
        self.kept()
            .map(|i| (i + self.first_index) as f64 / self.fs)
            .collect()
    }

    /// The motion at the kept samples, without the anti-alias filter (for plots and bins).
    pub(super) fn kept_values(&self, full: &[f64]) -> Vec<f64> {
        self.kept().map(|i| full[i]).collect()
    }
}

pub(super) fn check_equations(
    m: &Motion,
    record: &'static str,
    parameters: usize,
) -> Result<(), AxisError> {
    let equations = m.kept().count();
    if equations < 2 * parameters {
        return Err(AxisError::TooShort {
            record,
            samples: m.q.len() + 2 * m.first_index,
            decimation: m.decimator.factor(),
            equations,
            parameters: 2 * parameters,
        });
    }
    Ok(())
}

/// A record prepared for fitting: the motion and the decimated force.
pub(super) struct Prepared {
    pub(super) motion: Motion,
    pub(super) force: Vec<f64>,
}

impl Prepared {
    pub(super) fn new(
        r: &AxisRecord,
        o: &TimeDomainOptions,
        record: &'static str,
    ) -> Result<Prepared, AxisError> {
        let motion = Motion::new(r, o, record)?;
        let force = motion.decimate(&motion.force);
        Ok(Prepared { motion, force })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_the_last_sample() {
        let r = AxisRecord {
            sample_rate_hz: 1000.0,
            position_m: vec![0.0; 1000],
            force_n: vec![0.0; 1000],
        };
        let m = Motion::new(&r, &TimeDomainOptions::default(), "fitting").unwrap();
        let kept: Vec<usize> = m.kept().collect();
        assert_eq!(*kept.last().unwrap(), m.q.len() - 1);
        assert!(kept.windows(2).all(|w| w[1] - w[0] == 10));
    }
}
