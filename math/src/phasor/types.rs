//! What the harmonic analysis takes and gives: its options, the phasors of each channel with
//! their noise, the analysis of a record, and its errors.

use crate::record::Channel;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// The highest harmonic an identification or diagnosis analyses unless told otherwise: as
/// many as the sampling allows up to 100 (the improved method drops the harmonics that do not
/// stand out of their noise; the diagnosis needs the even ones and DC).
pub const IDENTIFICATION_MAX_HARMONIC: usize = 100;

/// Options of [`analyse_record`](super::analyse_record).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PhasorOptions {
    /// Highest harmonic `N` wanted; capped at `floor((floor(fs/f) - 1) / 2)` (see module docs).
    /// `usize::MAX` means "as many as allowed". Default 20 (a single record's analysis);
    /// identifications use [`PhasorOptions::for_identification`].
    pub max_harmonic: usize,
    /// Fewest whole periods a settled part must have (values below 2 act as 2). Default 2.
    pub min_periods: usize,
    /// Relative tolerance of the settling test, as a fraction of each channel's AC amplitude
    /// (~ its fundamental). It governs noise-free records. Default 1e-4.
    pub settle_relative_tolerance: f64,
    /// `k`: a period agrees with the tail when its phasors are within `k` per-period noise
    /// standard deviations of the tail mean (each harmonic and channel tested). Default 4,
    /// so a settled white-noise record is falsely truncated with probability `~e^{-16}` per test.
    pub settle_noise_factor: f64,
}

impl Default for PhasorOptions {
    fn default() -> Self {
        PhasorOptions {
            max_harmonic: 20,
            min_periods: 2,
            settle_relative_tolerance: 1e-4,
            settle_noise_factor: 4.0,
        }
    }
}

impl PhasorOptions {
    /// The options of every identification and diagnosis (the command, the harmonic node, the
    /// recipe): the defaults with up to [`IDENTIFICATION_MAX_HARMONIC`] harmonics.
    pub fn for_identification() -> PhasorOptions {
        PhasorOptions {
            max_harmonic: IDENTIFICATION_MAX_HARMONIC,
            ..PhasorOptions::default()
        }
    }
}

/// Phasors of one channel.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelPhasors {
    pub channel: Channel,
    /// `C_n`, `n = 0..=N`, referenced to `t_ref_s` (unit of the channel).
    pub phasors: Vec<Complex64>,
    /// Standard error of `C_n` from the scatter between periods (complex magnitude; see the
    /// module docs), `n = 0..=N`.
    pub noise_std: Vec<f64>,
    /// RMS of the residual of the joint fit over the used periods, per sample (unit of the
    /// channel): everything not periodic with the excitation period, i.e. noise, transient left
    /// in, and harmonics above `N`.
    pub residual_rms: f64,
    /// `dC_n/dt` [unit/s], `n = 0..=N`, where the phasors change across the fit (a sweep
    /// window's amplitude slope `D_n / W`); empty for a settled step, whose phasors are constant.
    /// The state's derivatives need it: see [`velocity_phasors`].
    pub rate_per_s: Vec<Complex64>,
}

/// Phasors of a signal's first time derivative at the instant its phasors `phasors` hold,
/// on the same phase, for a signal whose phasors change at `rate_per_s` (empty: constant):
/// `s = Re(sum A_n e^{j n psi})` with `psi' = omega_rad_s` and `A_n' = rate_n` gives
/// `s' = Re(sum (j n w A_n + A_n') e^{j n psi})`. On a settled step that is `j n w C_n`; in a
/// sweep window `A_n'` is first order in the sweep rate, and leaving it out biases the rebuilt
/// velocity by as much.
pub fn velocity_phasors(
    phasors: &[Complex64],
    rate_per_s: &[Complex64],
    omega_rad_s: f64,
) -> Vec<Complex64> {
    let zero = Complex64::new(0.0, 0.0);
    phasors
        .iter()
        .enumerate()
        .map(|(n, a)| {
            Complex64::new(0.0, n as f64 * omega_rad_s) * a
                + rate_per_s.get(n).copied().unwrap_or(zero)
        })
        .collect()
}

/// Phasors of the second time derivative (see [`velocity_phasors`]), with `psi'' =
/// omega_rate_rad_s2` and `A_n'' = 0` (the fit's amplitudes are linear across a window):
/// `s'' = Re(sum (-(n w)^2 A_n + 2 j n w A_n' + j n w' A_n) e^{j n psi})`; `-(n w)^2 C_n` on a
/// settled step.
pub fn acceleration_phasors(
    phasors: &[Complex64],
    rate_per_s: &[Complex64],
    omega_rad_s: f64,
    omega_rate_rad_s2: f64,
) -> Vec<Complex64> {
    let zero = Complex64::new(0.0, 0.0);
    phasors
        .iter()
        .enumerate()
        .map(|(n, a)| {
            let jnw = Complex64::new(0.0, n as f64 * omega_rad_s);
            let d = rate_per_s.get(n).copied().unwrap_or(zero);
            jnw * jnw * a + 2.0 * jnw * d + Complex64::new(0.0, n as f64 * omega_rate_rad_s2) * a
        })
        .collect()
}

/// Result of [`analyse_record`](super::analyse_record).
#[derive(Debug, Clone, PartialEq)]
pub struct HarmonicAnalysis {
    pub step: usize,
    pub frequency_hz: f64,
    /// Excitation amplitude (from the record's excitation).
    pub amplitude: f64,
    /// Reference time of the phasors [s since the start of the run]: the start of the first
    /// used whole period (within one sample interval before `first_settled_sample`).
    pub t_ref_s: f64,
    /// Whole periods in the fit.
    pub periods_used: usize,
    /// Whole periods in the record.
    pub periods_available: usize,
    /// Index of the first sample of the fit.
    pub first_settled_sample: usize,
    /// Samples in the fit (`periods_used` whole periods).
    pub samples_used: usize,
    /// False when no settled part of at least `min_periods` periods was found; the phasors
    /// then come from the last `min_periods` periods anyway.
    pub settled: bool,
    /// `N`, the highest harmonic fitted.
    pub harmonics: usize,
    /// Highest `N` allowed at this frequency and sample rate.
    pub harmonic_cap: usize,
    /// One entry per record channel, in record order.
    pub channels: Vec<ChannelPhasors>,
    /// Rate of change of the excitation frequency at the phasors [Hz/s]: a sweep window's, 0
    /// for a step.
    pub frequency_rate_hz_per_s: f64,
}

impl HarmonicAnalysis {
    pub fn channel(&self, c: Channel) -> Option<&ChannelPhasors> {
        self.channels.iter().find(|p| p.channel == c)
    }

    /// How far `other` is from this analysis in its real numbers: the largest difference of a
    /// phasor, noise or residual, relative to the largest phasor of its channel, and of
    /// `t_ref_s`, relative to a period. `None` when they differ in anything else (step,
    /// frequency, periods, settled part, harmonics, channels): not the same analysis at all.
    pub fn relative_difference(&self, other: &HarmonicAnalysis) -> Option<f64> {
        let same = self.step == other.step
            && self.frequency_hz == other.frequency_hz
            && self.amplitude.to_bits() == other.amplitude.to_bits()
            && self.periods_used == other.periods_used
            && self.periods_available == other.periods_available
            && self.first_settled_sample == other.first_settled_sample
            && self.samples_used == other.samples_used
            && self.settled == other.settled
            && self.harmonics == other.harmonics
            && self.harmonic_cap == other.harmonic_cap
            && self.frequency_rate_hz_per_s == other.frequency_rate_hz_per_s
            && self.channels.len() == other.channels.len()
            && self.channels.iter().zip(&other.channels).all(|(a, b)| {
                a.channel == b.channel
                    && a.phasors.len() == b.phasors.len()
                    && a.noise_std.len() == b.noise_std.len()
                    && a.rate_per_s.len() == b.rate_per_s.len()
            });
        if !same {
            return None;
        }
        let mut d = ((self.t_ref_s - other.t_ref_s) * self.frequency_hz).abs();
        for (a, b) in self.channels.iter().zip(&other.channels) {
            let scale = a.phasors.iter().map(|c| c.norm()).fold(0.0, f64::max);
            let rel = |x: f64| if scale > 0.0 { x / scale } else { x };
            let phasors = a
                .phasors
                .iter()
                .zip(&b.phasors)
                .map(|(p, q)| (p - q).norm());
            let noise = a
                .noise_std
                .iter()
                .zip(&b.noise_std)
                .map(|(p, q)| (p - q).abs());
            let residual = (a.residual_rms - b.residual_rms).abs();
            // A rate times a period is a change of phasor.
            let rates = a
                .rate_per_s
                .iter()
                .zip(&b.rate_per_s)
                .map(|(p, q)| (p - q).norm() / self.frequency_hz);
            d = phasors
                .chain(noise)
                .chain(rates)
                .chain(std::iter::once(residual))
                .map(rel)
                .fold(d, f64::max);
        }
        Some(d)
    }
}

/// Why a record could not be analysed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PhasorError {
    #[error(
        "step {step}: not a stepped-sine record (random, multisine or sweep excitation); harmonic analysis needs a sine step (a periodic multisine has its own: phasor::multisine; a sweep: phasor::sweep)"
    )]
    NotSine { step: usize },
    #[error("step {step}: record has no channels")]
    NoChannels { step: usize },
    #[error(
        "step {step}: channel {channel:?} has {len} samples but channel {first:?} has {expected}; all channels must have the same length"
    )]
    ChannelLengthMismatch {
        step: usize,
        channel: Channel,
        len: usize,
        first: Channel,
        expected: usize,
    },
    #[error("step {step}: channel {channel:?} sample {sample} is not finite ({value})")]
    NonFinite {
        step: usize,
        channel: Channel,
        sample: usize,
        value: f64,
    },
    #[error(
        "step {step}: sample {sample} has {values} values for the stream's {channels} channels"
    )]
    SampleWidth {
        step: usize,
        sample: usize,
        values: usize,
        channels: usize,
    },
    #[error("step {step}: sample rate {sample_rate_hz} Hz is not a positive finite number")]
    InvalidSampleRate { step: usize, sample_rate_hz: f64 },
    #[error("step {step}: excitation frequency {frequency_hz} Hz is not a positive finite number")]
    InvalidFrequency { step: usize, frequency_hz: f64 },
    #[error(
        "step {step}: excitation frequency {frequency_hz} Hz is at or above the Nyquist frequency {nyquist_hz} Hz"
    )]
    AboveNyquist {
        step: usize,
        frequency_hz: f64,
        nyquist_hz: f64,
    },
    #[error(
        "step {step}: only {samples_per_period:.3} samples per period at {frequency_hz} Hz (need at least 3 to fit DC and the fundamental per period)"
    )]
    TooFewSamplesPerPeriod {
        step: usize,
        frequency_hz: f64,
        samples_per_period: f64,
    },
    #[error(
        "step {step}: record of {samples} samples holds {periods:.3} periods of {frequency_hz} Hz; at least 2 whole periods ({needed} samples) are needed"
    )]
    TooShort {
        step: usize,
        samples: usize,
        periods: f64,
        frequency_hz: f64,
        needed: usize,
    },
    #[error("invalid phasor options: {reason}")]
    InvalidOptions { reason: String },
    #[error("fit_harmonics: {reason}")]
    InvalidFit { reason: String },
    #[error(
        "step {step}: normal matrix of the harmonic fit is not positive definite (window of {samples} samples)"
    )]
    IllConditioned { step: usize, samples: usize },
}
