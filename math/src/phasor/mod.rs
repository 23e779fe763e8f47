//! Harmonic analysis of stepped-sine records: phasors of every channel at harmonics
//! `n = 0..=N` of the known excitation frequency, over the settled whole periods of a record,
//! with a per-harmonic noise estimate from the scatter between periods.
//!
//! # Convention
//! One-sided phasors (see the crate docs): `s(t) = Re(sum_{n>=0} C_n e^{j n w (t - t_ref)})`,
//! `|C_1|` is the amplitude of the fundamental, `C_0` the mean. [`synthesize`] is the inverse.
//!
//! # Method ([`analyse_record`])
//! With `L = fs / f` samples per period (rarely an integer), whole period `p` is the samples
//! with times in `[p T, (p + 1) T)` from the first sample, i.e. indices `ceil(p L)..ceil((p+1) L)`.
//! The record holds `P = floor(len / L)` whole periods; the fraction left at the end is unused.
//!
//! 1. **Per-period fits.** Each whole period of each channel is fitted separately by least
//!    squares with DC + `cos/sin(n w t)`, `n = 1..=N`. The fit is exact for a band-limited
//!    periodic signal even for non-integer `L`. All phasors are referenced to the first sample
//!    of the record, which is the same as referencing them to the start of any whole period.
//! 2. **Noise level.** The last `m = max(2, min_periods)` whole periods are fitted jointly; the
//!    residual gives the per-sample noise variance `sigma_c^2 = RSS / (samples - (2N+1))` of
//!    channel `c` (everything that is not periodic with `T`). Assuming white noise, the complex
//!    standard deviation of one per-period phasor is `s_{c,n} = sigma_c sqrt(v_n)` with `v_n`
//!    the diagonal of the inverse normal matrix of one period (`~ 4 / L` for `n >= 1`, i.e.
//!    `2 sigma / sqrt(L)`; `1 / L` for DC).
//! 3. **Settled part.** Start with the last period as the accepted set `A` and walk backwards.
//!    Period `p` is accepted if, for every channel `c` and harmonic `n`,
//!    `|C_{p,c,n} - mean_A(C_{c,n})| <= max(k s_{c,n} sqrt(1 + 1/|A|), tol * scale_c, 1e-10 * size_c)`
//!    (`k = settle_noise_factor`, `tol = settle_relative_tolerance`,
//!    `scale_c = sqrt(sum_{n>=1} |mean_A C_{c,n}|^2)`, the AC amplitude, `~|C_1|` for a
//!    near-sinusoid (`|C_0|` if the channel has no AC part), `size_c = max(|C_0|, scale_c)` is
//!    a rounding floor). The walk stops at the first period that is not accepted; the settled
//!    part starts at the first accepted period. All channels are tested jointly: a step is
//!    settled only when all channels are. If fewer than `min_periods` periods were accepted
//!    and the record ends in a ramp (a bench that ramps its drive down before it stops: last
//!    periods that each differ from the `m` before them by more than 5 % of a channel's AC
//!    amplitude and more than the noise allows, up to `floor(P / 4)` of them), the walk starts
//!    again before the ramp. Where that accepts fewer than `min_periods` too, the periods used
//!    are those the walk (before any ramp) accepts with `tol` raised to 5 %: a drift, as a
//!    damper's force as it heats up over its step or a test table's mean position wandering by
//!    a millimetre, differs from period to period by far more than the noise within a period,
//!    but far less than a ramp, and every period of it is a measurement of the element. The
//!    step is flagged `settled = false` then, and where even that finds no `min_periods`
//!    periods, the last `min_periods` periods (or all `P` if there are fewer) are used.
//! 4. **Phasors.** All used whole periods are fitted jointly (one least-squares fit over the
//!    contiguous window). `t_ref` is the start of the first used period.
//! 5. **Noise estimate.** `noise_std[n]` is the standard error of the mean of the per-period
//!    phasors of the used periods, `sqrt(sum_p |C_p - mean|^2 / (P (P - 1)))` (complex
//!    magnitude: the root of the sum of the variances of real and imaginary part). For white
//!    noise it is `~ 2 sigma / sqrt(samples used)` for `n >= 1` and `sigma / sqrt(samples used)`
//!    for DC.
//!
//! # Number of harmonics
//! `N = min(max_harmonic, cap)` with `cap = floor((floor(L) - 1) / 2)`: every per-period window
//! holds at least `floor(L)` samples, so `2N + 1 <= floor(L)` keeps each per-period fit
//! over-determined (or square), and it implies `N f <= fs/2 - f/2 < fs/2`, so no fitted harmonic
//! reaches the Nyquist frequency and the sampled harmonics are distinct (no aliasing between
//! them). Asking for more than the cap silently uses the cap; [`HarmonicAnalysis::harmonics`]
//! reports the `N` actually used and [`HarmonicAnalysis::harmonic_cap`] the cap. Content of the
//! signal between harmonic `N` and the Nyquist frequency is not modelled; with non-integer `L` it
//! leaks slightly into the per-period fits, so choose `N` at least as high as the harmonic
//! content that matters. A frequency with fewer than 3 samples per period (cap 0) is an error.
//!
//! # Cost
//! The samples are touched once (`O(samples * N * channels)`, with the harmonic rotations
//! advanced by vectorised element-wise products, no per-sample trigonometry); normal matrices
//! are built in closed form (`O(N^2)`, Dirichlet kernels) and their Cholesky factors are shared
//! between periods with the same length and starting phase (2 kinds at 62.5 samples/period);
//! joint fits reuse the per-period sums. Periods are fitted lazily from the end of the record,
//! so the transient periods before the first disagreeing one are never fitted.
//! Measured (criterion, `benches/phasor.rs`, 6 channels, shared 2-core machine): 1300 samples
//! at 100 Hz with N = 30 in ~0.45 ms (~2.9 M samples/s); 20000 samples at 10 kHz with N = 20
//! in ~1.1-1.7 ms (~12-18 M samples/s).
//!
//! [`PhasorStream`] does the same work as the samples arrive (each period fitted when it
//! completes), so that after a step's last sample only the settling and the joint fits remain:
//! 8.8 ms against 129 ms for [`analyse_record`] of a 13 s step at 10 kHz, 6 channels, N = 100
//! (criterion `phasor_step_end_*`, machine under heavy load); a pushed six-channel sample costs
//! ~0.35 us at N = 100 (`phasor_stream_push_*`, ~2.9 M samples/s).

mod fit;
pub mod frequency;
pub mod multisine;
pub mod multisine_lines;
mod periods;
pub mod provisional;
mod stream;
pub mod sweep;
mod types;

pub use frequency::{FrequencyEstimate, drive_frequency};
pub use multisine::{
    MIN_MULTISINE_PERIODS, MultisineAnalysis, MultisineError, MultisineOptions, analyse_multisine,
};
pub use multisine_lines::{
    band_disagreement, excited_lines, excited_lines_of, find_multisine_lines,
};
pub use provisional::{ProvisionalUpdates, provisional_analyses, provisional_analysis};
pub use stream::PhasorStream;
pub use sweep::{SweepKind, SweepLaw, SweepOptions, analyse_sweep};
pub use types::{
    ChannelPhasors, HarmonicAnalysis, IDENTIFICATION_MAX_HARMONIC, PhasorError, PhasorOptions,
    acceleration_phasors, velocity_phasors,
};

use crate::record::{Channel, Excitation, Record};
use fit::{Factor, Grid, frac, phasors_of, rhs_matrix};
use num_complex::Complex64;
use periods::{Periods, StepInfo, settle_and_fit};

/// Fewest samples per period for which a per-period fit of DC + fundamental is possible.
pub const MIN_SAMPLES_PER_PERIOD: f64 = 3.0;

/// Tolerance (in samples) used when placing period boundaries on the sample grid, so that a
/// boundary that falls on a sample up to rounding is placed on that sample.
const BOUNDARY_TOLERANCE_SAMPLES: f64 = 1e-9;

/// Largest `N` with `2N + 1 <= floor(L)` (see the module docs); `None` if below 1.
fn harmonic_cap(samples_per_period: f64) -> usize {
    let whole = (samples_per_period + BOUNDARY_TOLERANCE_SAMPLES).floor();
    if whole < 3.0 {
        0
    } else {
        ((whole as usize) - 1) / 2
    }
}

/// First sample index of whole period `p` (`ceil(p L)`, with a rounding tolerance).
fn boundary(p: usize, samples_per_period: f64) -> usize {
    let x = p as f64 * samples_per_period - BOUNDARY_TOLERANCE_SAMPLES * (1.0 + p as f64);
    x.ceil().max(0.0) as usize
}

/// Whole periods in `len` samples at `nu` cycles per sample (with the boundary tolerance).
fn whole_periods(len: usize, nu: f64) -> usize {
    ((len as f64 + BOUNDARY_TOLERANCE_SAMPLES) * nu).floor() as usize
}

fn validate_options(options: &PhasorOptions) -> Result<(), PhasorError> {
    let bad = |reason: &str| {
        Err(PhasorError::InvalidOptions {
            reason: reason.to_string(),
        })
    };
    if !(options.settle_relative_tolerance.is_finite() && options.settle_relative_tolerance >= 0.0)
    {
        return bad("settle_relative_tolerance must be finite and >= 0");
    }
    if !(options.settle_noise_factor.is_finite() && options.settle_noise_factor >= 0.0) {
        return bad("settle_noise_factor must be finite and >= 0");
    }
    Ok(())
}

/// The excitation of a sine step on its sampling grid, checked for a harmonic analysis.
#[derive(Clone)]
struct SineGrid {
    frequency_hz: f64,
    amplitude: f64,
    samples_per_period: f64,
    /// The harmonic cap (at least 1).
    cap: usize,
}

impl SineGrid {
    fn of(step: usize, excitation: &Excitation, sample_rate_hz: f64) -> Result<Self, PhasorError> {
        let (frequency_hz, amplitude) = match *excitation {
            Excitation::Sine {
                frequency_hz,
                amplitude,
            } => (frequency_hz, amplitude),
            Excitation::Random { .. } | Excitation::Multisine { .. } | Excitation::Sweep { .. } => {
                return Err(PhasorError::NotSine { step });
            }
        };
        let fs = sample_rate_hz;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(PhasorError::InvalidSampleRate {
                step,
                sample_rate_hz: fs,
            });
        }
        if !(frequency_hz.is_finite() && frequency_hz > 0.0) {
            return Err(PhasorError::InvalidFrequency { step, frequency_hz });
        }
        if frequency_hz >= 0.5 * fs {
            return Err(PhasorError::AboveNyquist {
                step,
                frequency_hz,
                nyquist_hz: 0.5 * fs,
            });
        }
        let spp = fs / frequency_hz;
        let cap = harmonic_cap(spp);
        if cap == 0 {
            return Err(PhasorError::TooFewSamplesPerPeriod {
                step,
                frequency_hz,
                samples_per_period: spp,
            });
        }
        Ok(SineGrid {
            frequency_hz,
            amplitude,
            samples_per_period: spp,
            cap,
        })
    }
}

/// Phasors of every channel of a stepped-sine record over its settled whole periods (see the
/// module docs for the method, tolerances and the harmonic cap).
pub fn analyse_record(
    record: &Record,
    options: &PhasorOptions,
) -> Result<HarmonicAnalysis, PhasorError> {
    validate_options(options)?;
    let step = record.step;
    let SineGrid {
        frequency_hz,
        amplitude,
        samples_per_period: spp,
        cap,
    } = SineGrid::of(step, &record.excitation, record.sample_rate_hz)?;
    let fs = record.sample_rate_hz;
    let len = checked_length(record)?;
    let nu = frequency_hz / fs;
    let periods = whole_periods(len, nu);
    if periods < 2 {
        return Err(PhasorError::TooShort {
            step,
            samples: len,
            periods: len as f64 * nu,
            frequency_hz,
            needed: boundary(2, spp),
        });
    }

    let harmonics = options.max_harmonic.min(cap);
    let data: Vec<&[f64]> = record.channels.iter().map(|(_, v)| v.as_slice()).collect();
    let mut work = Periods::new(
        Grid { nu, harmonics },
        &data,
        (0..=periods).map(|p| boundary(p, spp)).collect(),
        step,
    );
    let channels: Vec<Channel> = record.channels.iter().map(|(c, _)| *c).collect();
    let info = StepInfo {
        step,
        frequency_hz,
        amplitude,
        start_time_s: record.start_time_s,
        channels: &channels,
        harmonic_cap: cap,
    };
    settle_and_fit(&mut work, &info, options)
}

/// Least-squares fit of DC + harmonics `1..=harmonics` of `frequency_hz` to uniformly sampled
/// `samples`, with `t_ref` at the first sample: returns `C_0..=C_N` in the crate's one-sided
/// convention. Exact (to rounding) for a band-limited periodic signal. Needs
/// `samples.len() >= 2N + 1` and `N f < fs / 2`; the fit is well conditioned when the samples
/// span at least about one period.
pub fn fit_harmonics(
    samples: &[f64],
    sample_rate_hz: f64,
    frequency_hz: f64,
    harmonics: usize,
) -> Result<Vec<Complex64>, PhasorError> {
    let bad = |reason: String| Err(PhasorError::InvalidFit { reason });
    if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
        return bad(format!(
            "sample rate {sample_rate_hz} Hz is not a positive finite number"
        ));
    }
    if !(frequency_hz.is_finite() && frequency_hz > 0.0) {
        return bad(format!(
            "frequency {frequency_hz} Hz is not a positive finite number"
        ));
    }
    let nu = frequency_hz / sample_rate_hz;
    if harmonics as f64 * nu >= 0.5 {
        return bad(format!(
            "harmonic {harmonics} of {frequency_hz} Hz is at or above the Nyquist frequency {} Hz",
            0.5 * sample_rate_hz
        ));
    }
    if samples.len() < 2 * harmonics + 1 {
        return bad(format!(
            "{} samples cannot determine {} parameters (harmonics 0..={harmonics})",
            samples.len(),
            2 * harmonics + 1
        ));
    }
    if let Some((i, v)) = samples.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return bad(format!("sample {i} is not finite ({v})"));
    }
    let grid = Grid { nu, harmonics };
    let h = harmonics + 1;
    let (mut re, mut im, mut sq) = (vec![0.0; h], vec![0.0; h], vec![0.0; 1]);
    grid.accumulate(&[samples], 0..samples.len(), &mut re, &mut im, &mut sq);
    let Some(chol) = Factor::new(&grid.normal_matrix(0, samples.len()), grid.params()) else {
        return bad(format!(
            "normal matrix not positive definite ({} samples, {harmonics} harmonics)",
            samples.len()
        ));
    };
    let mut beta = rhs_matrix(harmonics, 1, &re, &im);
    chol.solve(&mut beta);
    Ok(phasors_of(&beta, 0, harmonics))
}

/// Value at time `t_s` (relative to `t_ref`) of the signal with one-sided phasors `phasors`
/// (`C_0..=C_N`) at harmonics of `frequency_hz`: `Re(sum_n C_n e^{j n w t})`.
pub fn synthesize(phasors: &[Complex64], frequency_hz: f64, t_s: f64) -> f64 {
    // Reduce the phase to one cycle first so that large t keeps full precision.
    let theta = 2.0 * std::f64::consts::PI * frac(frequency_hz * t_s);
    let z = Complex64::from_polar(1.0, theta);
    let mut w = Complex64::new(1.0, 0.0);
    let mut s = 0.0;
    for c in phasors {
        s += (c * w).re;
        w *= z;
    }
    s
}

/// The common length of a record's channels, refusing a record without channels, with
/// channels of unequal length or with a non-finite sample (every analysis's first check).
pub(crate) fn checked_length(record: &Record) -> Result<usize, PhasorError> {
    let step = record.step;
    let Some((first, first_data)) = record.channels.first() else {
        return Err(PhasorError::NoChannels { step });
    };
    let len = first_data.len();
    for (c, data) in &record.channels {
        if data.len() != len {
            return Err(PhasorError::ChannelLengthMismatch {
                step,
                channel: *c,
                len: data.len(),
                first: *first,
                expected: len,
            });
        }
        if let Some((i, v)) = data.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(PhasorError::NonFinite {
                step,
                channel: *c,
                sample: i,
                value: *v,
            });
        }
    }
    Ok(len)
}
