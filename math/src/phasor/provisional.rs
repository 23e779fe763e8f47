//! Provisional phasors of a step in progress: while a long step runs, its analysis so far
//! (the settled periods of the samples pushed) every `update_period_s` of its samples, so that
//! a tracking identifier follows a parameter that drifts within the step. The same schedule
//! serves the live harmonic node (on its [`PhasorStream`]) and `forcemap identify
//! --update-period-s` (on a record), so both give the same provisional phasors.

use super::{HarmonicAnalysis, PhasorError, PhasorOptions, PhasorStream};
use crate::record::{Excitation, Record};

/// When a step in progress gives provisional phasors: after every `update_period_s` of its
/// samples (a whole number of samples, at least one), never at its last sample (the final
/// phasors are due then).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProvisionalUpdates {
    samples_per_update: usize,
}

impl ProvisionalUpdates {
    /// Every `update_period_s` [s] at `sample_rate_hz` [Hz]; `update_period_s` must be finite
    /// and positive.
    pub fn new(
        update_period_s: f64,
        sample_rate_hz: f64,
    ) -> Result<ProvisionalUpdates, PhasorError> {
        if !(update_period_s.is_finite() && update_period_s > 0.0) {
            return Err(PhasorError::InvalidOptions {
                reason: format!("update_period_s = {update_period_s}: expected a period > 0 s"),
            });
        }
        let samples = (update_period_s * sample_rate_hz).round();
        if !samples.is_finite() {
            return Err(PhasorError::InvalidOptions {
                reason: format!(
                    "update_period_s = {update_period_s} at {sample_rate_hz} Hz: no whole number of samples"
                ),
            });
        }
        Ok(ProvisionalUpdates {
            samples_per_update: (samples as usize).max(1),
        })
    }

    pub fn samples_per_update(&self) -> usize {
        self.samples_per_update
    }

    /// Whether provisional phasors are due after `samples` samples of a step that will have
    /// `expected` (0: not known).
    pub fn due(&self, samples: usize, expected: usize) -> bool {
        samples > 0
            && samples.is_multiple_of(self.samples_per_update)
            && (expected == 0 || samples < expected)
    }
}

/// The provisional analysis of the samples pushed so far: `Some` only when they hold a settled
/// part of the required length (an unsettled analysis is not to be identified from).
/// The stream itself is left as it is.
pub fn provisional_analysis(stream: &PhasorStream) -> Option<HarmonicAnalysis> {
    stream.clone().finish().ok().filter(|a| a.settled)
}

/// The provisional analyses of a sine record, in order: those the live harmonic node publishes
/// while the record's samples arrive (streamed at the record's rate), one per due update with
/// a settled part. Empty for a record that is not a sine step.
pub fn provisional_analyses(
    record: &Record,
    options: &PhasorOptions,
    updates: ProvisionalUpdates,
) -> Result<Vec<HarmonicAnalysis>, PhasorError> {
    if !matches!(record.excitation, Excitation::Sine { .. }) {
        return Ok(Vec::new());
    }
    let mut stream = PhasorStream::new(
        record.step,
        &record.excitation,
        record.sample_rate_hz,
        record.start_time_s,
        record.channels.iter().map(|(c, _)| *c).collect(),
        options,
    )?;
    let len = record.len();
    stream.expect_samples(len);
    let mut values = vec![0.0; record.channels.len()];
    let mut out = Vec::new();
    for k in 0..len {
        for (v, (_, x)) in values.iter_mut().zip(&record.channels) {
            *v = x[k];
        }
        stream.push(&values);
        if updates.due(k + 1, len)
            && let Some(an) = provisional_analysis(&stream)
        {
            out.push(an);
        }
    }
    Ok(out)
}

impl HarmonicAnalysis {
    /// The end of the data the phasors fit [s since the start of the run]: the end of the last
    /// fitted whole period, `t_ref_s + periods_used / frequency_hz` (less than one sample
    /// interval after the last fitted sample). The time a theta from these phasors describes.
    pub fn data_end_s(&self) -> f64 {
        self.t_ref_s + self.periods_used as f64 / self.frequency_hz
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn updates_are_due_every_period_but_never_at_the_last_sample() {
        let u = ProvisionalUpdates::new(0.5, 1000.0).unwrap();
        assert_eq!(u.samples_per_update(), 500);
        assert!(!u.due(0, 2000));
        assert!(!u.due(499, 2000));
        assert!(u.due(500, 2000));
        assert!(u.due(1500, 2000));
        assert!(!u.due(2000, 2000));
        assert!(u.due(2000, 0));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = ProvisionalUpdates::new(bad, 1000.0)
                .unwrap_err()
                .to_string();
            assert!(e.contains("update_period_s"), "{e}");
        }
    }
}
