//! The excited lines of a periodic multisine found from its driven channel, for sources that
//! give the base frequency but not the line set (a bag's `ExcitationState`, a live step): a
//! random-odd design does not fit a message's number fields, and the lines are in the data.
//!
//! # Method ([`excited_lines`])
//! On the averaged period of the driven channel (whole periods after the transient, bins at
//! `k f0` exactly: [`super::multisine`]), the bins `0 < k < N / 2` are sorted by power. The
//! excited lines are the bins above the first drop of at least [`MIN_LINE_MARGIN_DB`] from the
//! strongest bin down: a designed multisine puts equal (or smoothly shaped) power on its lines
//! and only noise and distortion elsewhere, tens of dB lower, so the first such drop is the edge
//! of the line set; the low tail of the noise, where single bins fall far below their
//! neighbours by chance, is never reached. The lines must also repeat period after period:
//! their median level over their own standard error (the scatter between periods) must be at
//! least [`MIN_LINE_PERIODICITY_DB`], which a band-random record (power in the band, but not
//! periodic) fails. Refused with the margin found otherwise.

use super::HarmonicAnalysis;
use super::multisine::{
    LineSpectrum, MultisineError, MultisineOptions, PeriodAverager, PeriodGrid,
    averaged_period_samples,
};
use crate::record::{Channel, Record};

/// The weakest excited line stands at least this far above the strongest other bin [dB].
pub const MIN_LINE_MARGIN_DB: f64 = 10.0;
/// The median excited line stands at least this far above its period-to-period scatter [dB].
pub const MIN_LINE_PERIODICITY_DB: f64 = 20.0;
/// Powers below the strongest bin by more than this are taken as this (rounding noise of a
/// noise-free record, exact zeros) [dB].
const FLOOR_DB: f64 = 150.0;

/// The excited lines (ascending) of the multisine of base frequency `base_frequency_hz` on
/// channel `driven` of `record` (see the module docs).
pub fn find_multisine_lines(
    record: &Record,
    driven: Channel,
    base_frequency_hz: f64,
    options: &MultisineOptions,
) -> Result<Vec<usize>, MultisineError> {
    let step = record.step;
    let grid = PeriodGrid::of(record, base_frequency_hz, options)?;
    let data = record
        .channel(driven)
        .ok_or(MultisineError::DrivenMissing {
            step,
            channel: driven,
        })?;
    let spectrum = PeriodAverager::new(grid.samples_per_period).average(driven, grid.used(data));
    excited_lines(&spectrum, grid.samples_per_period, step, base_frequency_hz)
}

/// The excited lines (ascending) of the multisine whose averaged period `an` holds (its bins as
/// harmonics of the base frequency, [`MultisineAnalysis::as_harmonic_analysis`]: what a phasor
/// message carries), found on channel `driven` exactly as [`find_multisine_lines`] finds them
/// on the record (the same spectrum, the same rule).
///
/// [`MultisineAnalysis::as_harmonic_analysis`]: super::MultisineAnalysis::as_harmonic_analysis
pub fn excited_lines_of(
    an: &HarmonicAnalysis,
    driven: Channel,
) -> Result<Vec<usize>, MultisineError> {
    let step = an.step;
    let n = averaged_period_samples(an)?;
    let c = an.channel(driven).ok_or(MultisineError::DrivenMissing {
        step,
        channel: driven,
    })?;
    excited_lines(&LineSpectrum::of_channel(c), n, step, an.frequency_hz)
}

/// The excited lines (ascending) of an averaged period of `samples_per_period` samples of the
/// driven channel (its phasors at bins `0..=N/2`; see the module docs). `step` and
/// `base_frequency_hz` name the record in an error.
pub fn excited_lines(
    spectrum: &LineSpectrum,
    samples_per_period: usize,
    step: usize,
    base_frequency_hz: f64,
) -> Result<Vec<usize>, MultisineError> {
    let n = samples_per_period;
    let bins: Vec<usize> = (1..spectrum.phasors.len()).filter(|k| 2 * k < n).collect();
    let power = |k: usize| spectrum.phasors[k].norm_sqr();
    let top = bins.iter().map(|&k| power(k)).fold(0.0, f64::max);
    let not_found = |margin_db: f64| MultisineError::NoLineStandsOut {
        step,
        channel: spectrum.channel,
        base_frequency_hz,
        margin_db,
    };
    if !(top > 0.0 && top.is_finite()) || bins.len() < 2 {
        return Err(not_found(0.0));
    }
    let db = |k: usize| 10.0 * (power(k) / top).log10().max(-FLOOR_DB);
    let mut sorted: Vec<(usize, f64)> = bins.iter().map(|&k| (k, db(k))).collect();
    sorted.sort_by(|a, b| b.1.total_cmp(&a.1));
    let edge = sorted
        .windows(2)
        .position(|w| w[0].1 - w[1].1 >= MIN_LINE_MARGIN_DB);
    let Some(edge) = edge else {
        let widest = sorted
            .windows(2)
            .map(|w| w[0].1 - w[1].1)
            .fold(0.0, f64::max);
        return Err(not_found(widest));
    };
    let mut lines: Vec<usize> = sorted[..=edge].iter().map(|(k, _)| *k).collect();
    lines.sort_unstable();
    // Periodic: the lines' level over their scatter between periods (an exact zero scatter,
    // a noise-free record, passes).
    let mut ratios: Vec<f64> = lines
        .iter()
        .map(|&k| spectrum.phasors[k].norm() / spectrum.noise_std[k])
        .collect();
    ratios.sort_by(f64::total_cmp);
    let median_db = 20.0 * ratios[ratios.len() / 2].log10();
    if median_db < MIN_LINE_PERIODICITY_DB {
        return Err(MultisineError::LinesNotPeriodic {
            step,
            channel: spectrum.channel,
            lines: lines.len(),
            level_db: median_db,
        });
    }
    Ok(lines)
}

/// Where the excited `lines` (ascending) of a multisine of base frequency `base_frequency_hz`
/// disagree with a band it is labelled with (`band_hz`: its lowest and highest excited line,
/// as an `ExcitationState` gives them): `None` when both edges agree to within half a line
/// spacing (or when the band is not known), otherwise what disagrees (a label is checked
/// against what the data show).
pub fn band_disagreement(
    lines: &[usize],
    base_frequency_hz: f64,
    band_hz: [f64; 2],
) -> Option<String> {
    let (&lo, &hi) = (lines.first()?, lines.last()?);
    if !band_hz.iter().all(|b| b.is_finite()) {
        return None;
    }
    let found = [lo as f64 * base_frequency_hz, hi as f64 * base_frequency_hz];
    let tolerance = 0.5 * base_frequency_hz;
    let agree = found
        .iter()
        .zip(&band_hz)
        .all(|(f, b)| (f - b).abs() <= tolerance);
    (!agree).then(|| {
        format!(
            "the {} lines found span {} to {} Hz, but its excitation is labelled with lines from {} to {} Hz (the label or the data are wrong)",
            lines.len(),
            found[0],
            found[1],
            band_hz[0],
            band_hz[1]
        )
    })
}
