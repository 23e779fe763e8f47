//! Steps found in unlabelled data: where the drive changes (kind, frequency, amplitude), the
//! settled part of each step, and each sine step's frequency, from the driven channel alone
//! (base displacement for the rig, force for the drive point: `SetupKind::driven_channel`).
//!
//! # Method ([`detect_steps`])
//! 1. **Windows** ([`windows`]): the series is cut into overlapping windows of
//!    `window_periods` periods of the lowest strong line of its spectrum (hop a quarter
//!    window). Each window gets a one-sine fit ([`sine_fit`]: DFT peak, then nonlinear least
//!    squares) and is classed *rest* (RMS below `rest_fraction` of the largest window's),
//!    *sine* (the sine leaves less than `sine_max_unexplained` of the variance), or
//!    *broadband*. A sine window is *clean* when its residual is within
//!    `clean_residual_factor` times the median residual of all sine windows (the noise); a
//!    window that straddles a change leaves more and is a *transition*.
//! 2. **Runs**: consecutive windows of one kind whose fits agree (frequency and amplitude
//!    within `consistency_sigmas` standard deviations of each other, plus a rounding floor)
//!    form a run; transitions and runs shorter than three windows separate runs; neighbouring
//!    runs that agree are joined. Each run is a step.
//! 3. **Boundaries** ([`boundary`]): between two runs the change is placed at the sample
//!    that maximises the likelihood of "first model before, second model after" over the
//!    stretch between them, each model fitted on its run next to the stretch (a sine, or the
//!    mean and variance of a rest or broadband run). Samples where the likelihood is within
//!    `boundary_interval_nll` of its maximum form the boundary's interval; with `snap` on,
//!    the boundary is the sample in that interval whose time is roundest (fewest decimals),
//!    since programs switch at programmed times, as the sample-rate estimate of the CSV
//!    reader snaps to whole hertz.
//!    A broadband run between two sine runs is dropped when the two sines, changing at one
//!    sample, explain the stretch between them (within `clean_residual_factor` of the noise):
//!    windows across a large change are classed broadband, and three make a spurious run.
//! 4. **Frequency**: each sine step is fitted by nonlinear least squares over the step less
//!    its boundaries' intervals; the standard deviation is the fit's (at the Cramer-Rao bound
//!    for white noise). With `snap` on, the reported frequency is the roundest decimal within
//!    `snap_sigmas` standard deviations of the estimate (the estimate is kept beside it).
//! 5. **Settled part**: the first whole period from the step's start whose residual against
//!    the step's sine is within `clean_residual_factor` times the step's residual, and its
//!    end: before the last periods that leave three times that (a taper at the end of a
//!    test). The step's frequency is refitted over the settled part.
//!
//! Limits: a step needs at least three windows (1.5 windows, about six periods of the lowest
//! frequency) to be found; a series too short for that, in which no sine is found, is looked
//! at again with windows of 2.2 periods when three of them fit (3.3 periods: one sine test
//! per file). Consecutive broadband records are one step (their bands are not told apart).

mod boundary;
pub mod sine_fit;
mod windows;

#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};

pub use sine_fit::{SineFit, SineFitter};

/// Options of [`detect_steps`]; the defaults suit stepped sines at 10 dB SNR or better.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SegmentOptions {
    /// Window length in periods of the lowest strong line of the spectrum. Default 4.
    pub window_periods: f64,
    /// A window is a sine window when one sine leaves less than this fraction of its
    /// variance. Default 0.2.
    pub sine_max_unexplained: f64,
    /// A sine window is clean when its residual RMS is within this factor of the noise (the
    /// median residual of the sine windows). Default 1.5.
    pub clean_residual_factor: f64,
    /// Two windows agree when frequency and amplitude differ by less than this many standard
    /// deviations. Default 6.
    pub consistency_sigmas: f64,
    /// A window is at rest when its RMS is below this fraction of the largest window's.
    /// Default 0.05.
    pub rest_fraction: f64,
    /// Width of a boundary's interval, in negative log-likelihood. Default 4.5 (a likelihood
    /// ratio of e^4.5; the likelihood of a change is flat near an extremum of the sine, so a
    /// narrower interval misses the true sample too often: measured on the paper's rig at 30 dB).
    pub boundary_interval_nll: f64,
    /// Take the roundest boundary time and frequency within their uncertainty. Default true.
    pub snap: bool,
    /// The frequency snaps within this many standard deviations. Default 3.
    pub snap_sigmas: f64,
}

impl Default for SegmentOptions {
    fn default() -> Self {
        SegmentOptions {
            window_periods: 4.0,
            sine_max_unexplained: 0.2,
            clean_residual_factor: 1.5,
            consistency_sigmas: 6.0,
            rest_fraction: 0.05,
            boundary_interval_nll: 4.5,
            snap: true,
            snap_sigmas: 3.0,
        }
    }
}

/// What drove a detected step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum DetectedKind {
    /// One sine. `frequency_hz` is the snapped value (the estimate when `snap` is off).
    Sine {
        frequency_hz: f64,
        estimated_frequency_hz: f64,
        frequency_std_hz: f64,
        amplitude: f64,
    },
    /// Anything else that moves (random, multisine, sweep): `rms` about the mean.
    Broadband { rms: f64 },
    /// No drive: the RMS about the mean is at the noise level.
    Rest { rms: f64 },
}

impl DetectedKind {
    pub fn name(&self) -> &'static str {
        match self {
            DetectedKind::Sine { .. } => "sine",
            DetectedKind::Broadband { .. } => "broadband",
            DetectedKind::Rest { .. } => "rest",
        }
    }
}

/// One step found: samples `start..end` of the series.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectedStep {
    pub start: usize,
    pub end: usize,
    /// First sample of the settled part (`start` for non-sine steps).
    pub settled_start: usize,
    /// End of the steady part: before a taper at the step's end (`end` for a step without
    /// one, and for non-sine steps).
    pub settled_end: usize,
    /// Samples `start_interval.0..=start_interval.1` are as likely a start as `start` (a
    /// single sample for the first step and for noise-free data).
    pub start_interval: (usize, usize),
    pub kind: DetectedKind,
}

/// The steps of a series, in order, covering every sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Segmentation {
    pub steps: Vec<DetectedStep>,
    /// Samples per analysis window.
    pub window_samples: usize,
    /// Noise RMS of the drive (the median residual of the sine windows; 0 without any).
    pub noise_rms: f64,
}

/// Why a series could not be segmented.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SegmentError {
    #[error("sample rate {0} Hz is not a positive finite number")]
    InvalidSampleRate(f64),
    #[error("sample {sample} is not finite ({value})")]
    NonFinite { sample: usize, value: f64 },
    #[error("{samples} samples are too few to find steps in (at least {needed} are needed)")]
    TooShort { samples: usize, needed: usize },
    #[error("invalid segmentation options: {0}")]
    InvalidOptions(String),
}

/// The fewest samples [`detect_steps`] works on.
pub const MIN_SERIES_SAMPLES: usize = 64;

/// Finds the steps of the drive `x` sampled at `sample_rate_hz`, whose first sample is at
/// `t0_s` (used only to find round boundary times). See the module docs.
pub fn detect_steps(
    x: &[f64],
    sample_rate_hz: f64,
    t0_s: f64,
    options: &SegmentOptions,
) -> Result<Segmentation, SegmentError> {
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return Err(SegmentError::InvalidSampleRate(sample_rate_hz));
    }
    if let Some((sample, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(SegmentError::NonFinite { sample, value });
    }
    if x.len() < MIN_SERIES_SAMPLES {
        return Err(SegmentError::TooShort {
            samples: x.len(),
            needed: MIN_SERIES_SAMPLES,
        });
    }
    check_options(options)?;
    let mut fitter = SineFitter::new();
    let analysis = windows::analyse(x, options, &mut fitter);
    let segmentation = segment_with(x, sample_rate_hz, t0_s, analysis, options);
    let found_sine = segmentation
        .steps
        .iter()
        .any(|s| matches!(s.kind, DetectedKind::Sine { .. }));
    // A series too short for three windows of `window_period` periods (its windows clamped
    // to a third of it: a test machine's one sine test per file, a few periods of a slow
    // sine) is looked at again with windows of the fewest periods that show a sine, when
    // three such windows fit in it.
    if !found_sine && let Some(period) = windows::lowest_line_period(x) {
        let window =
            (windows::MIN_WINDOW_PERIODS * SHORT_SERIES_PERIOD_MARGIN * period).ceil() as usize;
        if window > segmentation.window_samples && window as f64 * 1.5 <= x.len() as f64 {
            let analysis = windows::analyse_in_windows(x, window, options, &mut fitter);
            return Ok(segment_with(x, sample_rate_hz, t0_s, analysis, options));
        }
    }
    Ok(segmentation)
}

/// The windows of a short series hold this much more than the fewest periods that show a
/// sine (the lowest line's period is read off a padded spectrum, to a few per cent).
const SHORT_SERIES_PERIOD_MARGIN: f64 = 1.1;

fn segment_with(
    x: &[f64],
    sample_rate_hz: f64,
    t0_s: f64,
    analysis: windows::Analysis,
    options: &SegmentOptions,
) -> Segmentation {
    let runs = windows::runs(&analysis, options);
    let steps = boundary::steps(x, sample_rate_hz, t0_s, &analysis, &runs, options);
    Segmentation {
        steps,
        window_samples: analysis.window,
        noise_rms: analysis.noise_rms,
    }
}

fn check_options(o: &SegmentOptions) -> Result<(), SegmentError> {
    let positive = [
        ("window_periods", o.window_periods),
        ("sine_max_unexplained", o.sine_max_unexplained),
        ("clean_residual_factor", o.clean_residual_factor),
        ("consistency_sigmas", o.consistency_sigmas),
        ("rest_fraction", o.rest_fraction),
        ("boundary_interval_nll", o.boundary_interval_nll),
        ("snap_sigmas", o.snap_sigmas),
    ];
    match positive.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
        Some((name, v)) => Err(SegmentError::InvalidOptions(format!(
            "{name} must be a positive finite number, not {v}"
        ))),
        None => Ok(()),
    }
}

/// The roundest of the values `candidates` yields (fewest decimals, up to 12), the first of
/// equally round ones. `None` for no candidates.
pub fn roundest(candidates: impl IntoIterator<Item = f64>) -> Option<f64> {
    candidates
        .into_iter()
        .map(|v| (decimals(v), v))
        .min_by_key(|(d, _)| *d)
        .map(|(_, v)| v)
}

/// Decimals needed to write `v` (within a relative 1e-12), at most 13.
fn decimals(v: f64) -> u32 {
    (0..13)
        .find(|&d| {
            let s = 10f64.powi(d as i32);
            ((v * s).round() / s - v).abs() <= 1e-12 * v.abs().max(1.0)
        })
        .unwrap_or(13)
}

/// The roundest decimal in `[lo, hi]` (fewest decimals; the one nearest `centre` of those).
pub fn roundest_in(lo: f64, hi: f64, centre: f64) -> f64 {
    for d in 0..13 {
        let s = 10f64.powi(d);
        let a = (lo * s).ceil();
        let b = (hi * s).floor();
        if a <= b {
            let c = (centre * s).round().clamp(a, b);
            return c / s;
        }
    }
    centre
}
