//! A transformation between the rig and its measured channels, fitted by output error beside
//! the element on records with no steps: the candidates of the rig's channels (`diagnose`'s
//! exciter_delay and sensor_lowpass) where no phasors are there to undo them on.
//!
//! Each adds one parameter after the element's. The base input is the band-limited measured
//! base displacement ([`RecordsOutputError::rig`]), so both transformations are exact there:
//! - a first-order low-pass `y' = (u - y) / tau` on every measured channel: the input undone
//!   (`x + tau x'`, the band-limited derivative), the simulated channels passed through the
//!   filter, integrated with the mechanics from each channel's first value (a filter applied
//!   to the samples afterwards misses where a stick-slip kink falls between them:
//!   `ReplayOptions::sensor_lowpass_hz`);
//! - an exciter delay d: the element sees the measured base motion d later
//!   ([`delayed`]; the compared channels are the physical ones, as the simulator's).

use std::f64::consts::TAU;

use super::{RecordsOutputError, SampledDrive, step_error};
use crate::identify::output_error::lm::Problem as _;
use crate::identify::{Identification, IdentifyError, Parameter};
use crate::signal::delay::delayed;

/// Starting cutoffs of the low-pass, in multiples of the records' top excitation frequency:
/// the filter's phase there runs from 45 degrees down to 4.
const LOWPASS_START_MULTIPLES: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

/// Time constants of the slowest starting low-pass over which a filter started on its
/// channel's first value is left to settle ([`RecordsOutputError::filter_transient_samples`]):
/// its start's error falls to e^-5, under 1 %.
const LOWPASS_TRANSIENT_TIME_CONSTANTS: f64 = 5.0;

/// Starting delays, in fractions of the records' top excitation period: the phase there runs
/// from -45 to +45 degrees.
const DELAY_START_PERIODS: [f64; 9] = [
    -0.125, -0.0625, -0.03125, -0.015625, 0.0, 0.015625, 0.03125, 0.0625, 0.125,
];

/// A transformation of the rig's channels, its one parameter fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RigChannelEffect {
    /// A first-order low-pass on every measured channel; parameter: its time constant tau [s]
    /// (the cutoff is 1 / (2 pi tau)).
    LowpassEveryChannel,
    /// The element sees the measured base motion this much later; parameter: d [s].
    ExciterDelay,
}

impl RigChannelEffect {
    /// The name of its parameter in the identification.
    pub fn parameter(self) -> &'static str {
        match self {
            RigChannelEffect::LowpassEveryChannel => "sensor_time_constant_s",
            RigChannelEffect::ExciterDelay => "exciter_delay_s",
        }
    }

    /// The parameter's starting values for records whose top excitation frequency is
    /// `top_frequency_hz`.
    fn starts(self, top_frequency_hz: f64) -> Vec<f64> {
        match self {
            RigChannelEffect::LowpassEveryChannel => LOWPASS_START_MULTIPLES
                .iter()
                .map(|m| 1.0 / (TAU * m * top_frequency_hz))
                .collect(),
            RigChannelEffect::ExciterDelay => DELAY_START_PERIODS
                .iter()
                .map(|p| p / top_frequency_hz)
                .collect(),
        }
    }
}

impl RecordsOutputError<'_> {
    /// The problem with `effect` between the rig and its channels (a base-excited rig's
    /// records only; not with a hysteresis state).
    pub fn with_channel_effect(self, effect: RigChannelEffect) -> Result<Self, IdentifyError> {
        let first = self.records.first().map_or(0, |r| r.step);
        if !matches!(self.drive, SampledDrive::Base { .. }) {
            return Err(step_error(
                first,
                format!(
                    "{} is a base-excited rig's channel effect",
                    effect.parameter()
                ),
            ));
        }
        if self.hysteresis.is_some() {
            return Err(step_error(
                first,
                "a channel effect is not fitted beside a hysteresis state",
            ));
        }
        Ok(RecordsOutputError {
            channel_effect: Some(effect),
            ..self
        })
    }

    /// The excitation's shortest period over 2 pi [s]: the time constant of a low-pass whose
    /// cutoff is the records' top frequency, the scale of the channel effect's parameter.
    pub(super) fn shortest_time_s(&self) -> f64 {
        1.0 / (TAU * self.top_frequency_hz)
    }

    /// Index of the channel effect's parameter (after the element's others).
    pub(super) fn channel_effect_index(&self) -> usize {
        self.hysteresis_index()
            + super::HYSTERESIS_PARAMETERS.len() * usize::from(self.hysteresis.is_some())
    }

    /// Record `k`'s base input as the element sees it with the channel effect's parameter
    /// `value` (None: no channel effect); an error for a low-pass time constant below zero.
    pub(super) fn effective_input(
        &self,
        k: usize,
        value: Option<f64>,
    ) -> Result<std::borrow::Cow<'_, [f64]>, IdentifyError> {
        let r = self.records[k];
        Ok(match (self.channel_effect, value) {
            (Some(RigChannelEffect::LowpassEveryChannel), Some(tau)) => {
                if tau.is_nan() || tau < 0.0 {
                    return Err(step_error(r.step, "a low-pass time constant below zero"));
                }
                let rate = &self.input_rates[k];
                self.inputs[k]
                    .iter()
                    .zip(rate)
                    .map(|(x, v)| x + tau * v)
                    .collect::<Vec<f64>>()
                    .into()
            }
            (Some(RigChannelEffect::ExciterDelay), Some(d)) => {
                delayed(&self.inputs[k], r.sample_rate_hz, d).into()
            }
            _ => self.inputs[k].as_slice().into(),
        })
    }

    /// The cutoff of the low-pass on the simulated channels at the channel effect's parameter
    /// `value` (None: no low-pass).
    pub(super) fn sensor_lowpass_hz(&self, value: Option<f64>) -> Option<f64> {
        match (self.channel_effect, value) {
            (Some(RigChannelEffect::LowpassEveryChannel), Some(tau)) if tau > 0.0 => {
                Some(1.0 / (TAU * tau))
            }
            _ => None,
        }
    }

    /// The first samples of record `k` left out of the fit (their residual rows zero) with a
    /// low-pass: the filters' state at a record's start is the filtered past, which the record
    /// does not hold, and a filter started on its channel's first value differs from it for a
    /// few time constants (on a record cut from a run, or one whose drive starts with a jump
    /// of acceleration, as the simulator's random records do).
    /// [`LOWPASS_TRANSIENT_TIME_CONSTANTS`] time constants of the grid's slowest filter (its
    /// cutoff at the top excitation frequency).
    pub(super) fn filter_transient_samples(&self, k: usize) -> usize {
        if self.channel_effect != Some(RigChannelEffect::LowpassEveryChannel) {
            return 0;
        }
        let slowest_s = self.shortest_time_s() / LOWPASS_START_MULTIPLES[0];
        let r = self.records[k];
        ((LOWPASS_TRANSIENT_TIME_CONSTANTS * slowest_s * r.sample_rate_hz).ceil() as usize)
            .min(r.len() / 2)
    }

    /// Fits the element, the channel effect's parameter and every record's initial state from
    /// `baseline` (the output-error fit of the same records without the effect, its parameters
    /// this problem's element's): the parameter starts from the best of a grid
    /// ([`LOWPASS_START_MULTIPLES`], [`DELAY_START_PERIODS`]) at the baseline's element and
    /// the records' starting states.
    pub fn fit_channel_effect(
        &self,
        baseline: &Identification,
    ) -> Result<Identification, IdentifyError> {
        let Some(effect) = self.channel_effect else {
            return self.fit(baseline);
        };
        let np = self.p_element();
        let element = baseline.theta();
        if element.len() + 1 != np {
            return Err(step_error(
                self.records[0].step,
                "the baseline has not the element parameters of this output-error problem",
            ));
        }
        let mut best: Option<(f64, f64)> = None;
        for value in effect.starts(self.top_frequency_hz) {
            let mut p = element.clone();
            p.push(value);
            for s in &self.start_states {
                p.extend(&s[..self.state_len()]);
            }
            let cost: f64 = self.residual(&p)?.iter().map(|r| r * r).sum();
            if best.is_none_or(|(c, _)| cost < c) {
                best = Some((cost, value));
            }
        }
        let (_, value) = best.ok_or_else(|| {
            step_error(
                self.records[0].step,
                format!("no starting {} could be simulated", effect.parameter()),
            )
        })?;
        let mut start = baseline.clone();
        start.warnings.clear();
        start.parameters.push(Parameter {
            name: effect.parameter().into(),
            value,
            std: 0.0,
        });
        self.fit(&start)
    }
}
