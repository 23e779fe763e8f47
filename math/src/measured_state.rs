//! The state of an element along its measured motion: displacement, velocity, acceleration and
//! force at every sample of a record, for the force law to be evaluated on (the time-domain
//! fit of an element test, its held-out predictions, the diagnosis's held-out records).
//!
//! The velocity is the measured displacement differentiated in the frequency domain up to
//! [`CUTOFF_MULTIPLE`] times the record's highest excitation frequency (above it the derivative
//! would be noise amplified by w); the acceleration is the measured one where the record has
//! it, else the displacement differentiated twice in the same band. The highest excitation
//! frequency is the label's (a sine, a sweep, a multisine's top line, a random record's band)
//! or, where the label gives none, the frequency below which [`BAND_POWER_SHARE`] of the
//! displacement's and the force's power lies. The first and last [`GUARD_FRACTION`] of the
//! record are not scored: the derivative of a record that is not periodic rings at its ends.

use thiserror::Error;

use crate::record::{Channel, Excitation, Record};
use crate::signal::differentiate::{band_limited_derivative, detrended_spectrum};

/// The velocity keeps the displacement's content up to this multiple of the record's highest
/// excitation frequency (a cubic term's third harmonic, with margin).
pub const CUTOFF_MULTIPLE: f64 = 4.0;
/// Fraction of the record at each end left out of the scored samples.
pub const GUARD_FRACTION: f64 = 0.05;
/// Share of a channel's power (mean and trend taken out) below the band estimated for a record
/// whose label gives no band.
pub const BAND_POWER_SHARE: f64 = 0.99;

#[derive(Debug, Error)]
pub enum MeasuredStateError {
    #[error(
        "record {step}: channel {channel} is missing (the force is evaluated along the measured displacement and compared with the measured force)"
    )]
    MissingChannel { step: usize, channel: &'static str },
    #[error(
        "record {step}: nothing in the {kind} record moves (no band to differentiate the displacement in)"
    )]
    NoBand { step: usize, kind: &'static str },
    #[error("record {step}: too short ({samples} samples)")]
    TooShort { step: usize, samples: usize },
}

/// The kind of excitation, as the messages name it.
pub fn excitation_kind(e: &Excitation) -> &'static str {
    match e {
        Excitation::Sine { .. } => "sine",
        Excitation::Random {
            band_hz: Some(_), ..
        } => "band-random",
        // A record nobody labelled (a whole file, an earthquake history): no band known.
        Excitation::Random { band_hz: None, .. } => "unlabelled",
        Excitation::Multisine { .. } => "multisine",
        Excitation::Sweep { .. } => "sweep",
    }
}

/// The measured state of a record and the samples scored.
#[derive(Debug, Clone)]
pub struct MeasuredState {
    pub step: usize,
    pub displacement_m: Vec<f64>,
    pub velocity_mps: Vec<f64>,
    pub acceleration_mps2: Vec<f64>,
    pub force_n: Vec<f64>,
    /// Samples scored (the guard at each end left out).
    pub scored: std::ops::Range<usize>,
    /// Whether the acceleration is the measured one (else the displacement's second
    /// derivative).
    pub acceleration_measured: bool,
    /// The highest excitation frequency the derivatives were taken for [Hz].
    pub top_frequency_hz: f64,
    /// Whether that frequency is estimated from the record's spectrum (its label gave none).
    pub band_estimated: bool,
    pub sample_rate_hz: f64,
}

/// Highest excitation frequency of a record by its label [Hz], if the label gives one.
fn labelled_top_frequency_hz(r: &Record) -> Option<f64> {
    match &r.excitation {
        Excitation::Sine { frequency_hz, .. } => Some(*frequency_hz),
        Excitation::Random {
            band_hz: Some([_, hi]),
            ..
        } => Some(*hi),
        Excitation::Random { band_hz: None, .. } => None,
        Excitation::Sweep { law } => Some(law.start_frequency_hz.max(law.end_frequency_hz)),
        Excitation::Multisine {
            base_frequency_hz,
            lines,
            ..
        } => lines.last().map(|k| *k as f64 * base_frequency_hz),
    }
}

/// The frequency [Hz] below which `share` of `y`'s power lies (the line through its end points
/// taken out); None when `y` does not move.
pub fn power_band_top_hz(y: &[f64], sample_rate_hz: f64, share: f64) -> Option<f64> {
    let n = y.len();
    if n < 4 {
        return None;
    }
    let buf = detrended_spectrum(y);
    let power: Vec<f64> = buf[1..=n / 2]
        .iter()
        .map(num_complex::Complex64::norm_sqr)
        .collect();
    let total: f64 = power.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let mut cumulative = 0.0;
    for (i, p) in power.iter().enumerate() {
        cumulative += p;
        if cumulative >= share * total {
            return Some((i + 1) as f64 * sample_rate_hz / n as f64);
        }
    }
    Some(sample_rate_hz / 2.0)
}

/// The standard deviation of white noise on `y` from its spectrum above `cutoff_hz` (where
/// the record holds nothing else): the mean of `|Y_k|^2 / n` over those bins (the line through
/// the end points taken out first). None when no bin lies above the cut-off.
pub fn white_noise_std_above(y: &[f64], sample_rate_hz: f64, cutoff_hz: f64) -> Option<f64> {
    let n = y.len();
    let bins = noise_bins(n, sample_rate_hz, cutoff_hz);
    if bins.is_empty() {
        return None;
    }
    let buf = detrended_spectrum(y);
    let count = bins.len() as f64;
    let power: f64 = buf[bins].iter().map(num_complex::Complex64::norm_sqr).sum();
    Some((power / count / n as f64).sqrt())
}

/// The spectral bins of `n` samples that [`white_noise_std_above`] measures the noise in: those
/// strictly between the cut-off and the Nyquist bin (a real bin of its own); none for fewer
/// than 8 samples.
fn noise_bins(n: usize, sample_rate_hz: f64, cutoff_hz: f64) -> std::ops::Range<usize> {
    if n < 8 {
        return 0..0;
    }
    let first = (cutoff_hz * n as f64 / sample_rate_hz).floor() as usize + 1;
    first..n.div_ceil(2)
}

/// The channels among `compared` whose noise [`white_noise_std_above`] cannot measure on any
/// of the records that hold them (`(channel, samples, sample rate [Hz], cut-off [Hz])` per
/// channel and record): no bin lies between the cut-off and the Nyquist frequency.
pub fn unmeasured_noise(compared: &[(Channel, usize, f64, f64)]) -> Vec<Channel> {
    let mut out: Vec<Channel> = Vec::new();
    for (c, ..) in compared {
        let measured = compared
            .iter()
            .filter(|(d, ..)| d == c)
            .any(|(_, n, fs, cutoff)| !noise_bins(*n, *fs, *cutoff).is_empty());
        if !measured && !out.contains(c) {
            out.push(*c);
        }
    }
    out
}

/// The noise std of `y` above `cutoff_hz` ([`white_noise_std_above`]), floored at 1e-6 of
/// its RMS about its mean (noise-free data would otherwise be weighted by round-off): the
/// weight of a channel's samples in a fit.
pub fn noise_std(y: &[f64], sample_rate_hz: f64, cutoff_hz: f64) -> f64 {
    white_noise_std_above(y, sample_rate_hz, cutoff_hz)
        .unwrap_or(0.0)
        .max(1e-6 * rms_about_mean(y).max(f64::MIN_POSITIVE))
}

/// The RMS of `y` about its mean (0 for no samples).
pub fn rms_about_mean(y: &[f64]) -> f64 {
    let n = y.len().max(1) as f64;
    let mean = y.iter().sum::<f64>() / n;
    (y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The highest excitation frequency of record `r` [Hz]: its label's, or, where the label gives
/// none, the highest frequency below which [`BAND_POWER_SHARE`] of the power of one of
/// `channels` lies.
pub fn top_frequency_hz(r: &Record, channels: &[&[f64]]) -> Result<f64, MeasuredStateError> {
    if let Some(top) = labelled_top_frequency_hz(r) {
        return Ok(top);
    }
    channels
        .iter()
        .filter_map(|y| power_band_top_hz(y, r.sample_rate_hz, BAND_POWER_SHARE))
        .fold(None, |m: Option<f64>, t| Some(m.map_or(t, |m| m.max(t))))
        .ok_or(MeasuredStateError::NoBand {
            step: r.step,
            kind: excitation_kind(&r.excitation),
        })
}

impl MeasuredState {
    pub fn of(r: &Record) -> Result<MeasuredState, MeasuredStateError> {
        let step = r.step;
        let channel = |c: Channel| {
            r.channel(c).ok_or(MeasuredStateError::MissingChannel {
                step,
                channel: c.name(),
            })
        };
        let x = channel(Channel::RelativeDisplacementM)?;
        let f = channel(Channel::ForceN)?;
        let n = x.len();
        let guard = (GUARD_FRACTION * n as f64).ceil() as usize;
        if n < 16 || 2 * guard >= n {
            return Err(MeasuredStateError::TooShort { step, samples: n });
        }
        let fs = r.sample_rate_hz;
        let band_estimated = labelled_top_frequency_hz(r).is_none();
        let top = top_frequency_hz(r, &[x, f])?;
        let cutoff = CUTOFF_MULTIPLE * top;
        let measured_a = r.channel(Channel::MassAccelerationMps2);
        Ok(MeasuredState {
            step,
            displacement_m: x.to_vec(),
            velocity_mps: band_limited_derivative(x, fs, cutoff, 1),
            acceleration_mps2: match measured_a {
                Some(a) => a.to_vec(),
                None => band_limited_derivative(x, fs, cutoff, 2),
            },
            force_n: f.to_vec(),
            scored: guard..n - guard,
            acceleration_measured: measured_a.is_some(),
            top_frequency_hz: top,
            band_estimated,
            sample_rate_hz: fs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sum of sines at 3 and 7 Hz: 99 % of the power lies at or below 7 Hz, and above 3 Hz
    /// when the 7 Hz sine holds more than 1 %.
    #[test]
    fn the_power_band_ends_at_the_top_sine() {
        let fs = 200.0;
        let y: Vec<f64> = (0..2000)
            .map(|i| {
                let t = i as f64 / fs;
                (std::f64::consts::TAU * 3.0 * t).sin()
                    + 0.5 * (std::f64::consts::TAU * 7.0 * t).sin()
            })
            .collect();
        let top = power_band_top_hz(&y, fs, 0.99).unwrap();
        assert!((top - 7.0).abs() < 0.11, "{top}");
        assert_eq!(power_band_top_hz(&[1.0; 100], fs, 0.99), None);
    }

    /// White noise of std 0.01 on a 2 Hz sine sampled at 1 kHz: its std from the bins above
    /// 20 Hz within 5 % (about 4400 bins: the estimate's own scatter is 1.5 %).
    #[test]
    fn white_noise_is_measured_above_the_band() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let normal = Normal::new(0.0, 0.01).unwrap();
        let (fs, n) = (1000.0, 10_000);
        let y: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / fs;
                (std::f64::consts::TAU * 2.0 * t).sin() + normal.sample(&mut rng)
            })
            .collect();
        let s = white_noise_std_above(&y, fs, 20.0).unwrap();
        assert!((s / 0.01 - 1.0).abs() < 0.05, "{s}");
        assert_eq!(white_noise_std_above(&y, fs, 600.0), None);
    }

    /// An unlabelled record's derivatives are taken in the band its spectrum shows: a 5 Hz
    /// sine's velocity within 0.2 % of its amplitude
    /// (measured 0.13 %: the line taken out through the end points leaves a ripple).
    #[test]
    fn an_unlabelled_record_is_differentiated_in_its_own_band() {
        let (fs, n) = (500.0, 5000);
        let w = std::f64::consts::TAU * 5.0;
        let x: Vec<f64> = (0..n).map(|i| 0.01 * (w * i as f64 / fs).sin()).collect();
        let r = Record {
            step: 0,
            excitation: Excitation::UNKNOWN,
            sample_rate_hz: fs,
            start_time_s: 0.0,
            channels: vec![
                (Channel::RelativeDisplacementM, x.clone()),
                (Channel::ForceN, x.iter().map(|v| 1e4 * v).collect()),
            ],
        };
        let s = MeasuredState::of(&r).unwrap();
        assert!(s.band_estimated);
        assert!(
            (s.top_frequency_hz - 5.0).abs() < 0.11,
            "{}",
            s.top_frequency_hz
        );
        let worst = s
            .scored
            .clone()
            .map(|i| (s.velocity_mps[i] - 0.01 * w * (w * i as f64 / fs).cos()).abs())
            .fold(0.0, f64::max);
        assert!(worst < 2e-3 * 0.01 * w, "{worst}");
    }
}
