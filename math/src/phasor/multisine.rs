//! Phasors of a periodic multisine record: every DFT bin of every channel from whole periods
//! after the transient, with the noise of each bin from the scatter between periods and the
//! level of nonlinear distortion at the lines the multisine leaves out.
//!
//! # Method ([`analyse_multisine`])
//! A period is `N = fs / f0` samples (a whole number: the multisine was designed on the
//! sampling grid); period `p` is the samples `p N .. (p + 1) N` from the record's first
//! sample. The first `transient_periods` periods are left out, every later whole period is
//! used (`P >= 2` of them; a fraction at the end is not).
//! 1. **Per period**: the DFT of each used period of each channel, one-sided
//!    (`C_0 = X_0 / N`, `C_k = 2 X_k / N` for `0 < k < N / 2`, `C_{N/2} = X_{N/2} / N`), in the
//!    crate's convention `s(t) = Re sum_k C_k e^{j k w0 (t - t_ref)}`, all periods referenced
//!    to their own start, which is the same as to `t_ref`, the start of the first used period.
//! 2. **Phasor**: the mean over the used periods, at every bin (excited or not).
//! 3. **Noise**: the standard error of that mean from the scatter between periods,
//!    `sqrt(sum_p |C_p - mean|^2 / (P (P - 1)))` (complex magnitude); for white noise of
//!    standard deviation sigma it is `2 sigma / sqrt(N P)` at `0 < k < N / 2`.
//! 4. **Distortion**: per channel, over the band of the excited lines, the mean power
//!    `|C_k|^2` at the non-excited even and odd bins relative to that at the excited lines (dB),
//!    beside the noise power there: a linear system shows the noise level, a nonlinear one
//!    rises above it (even-order terms at even bins, odd-order ones at left-out odd bins).
//!
//! Cost: one FFT of `N` per period and channel. Measured (criterion, `cargo bench -p
//! forcemap_math --bench multisine`, three channels, shared 2-core machine): 9 periods of
//! 4000 samples in ~1.1 ms (~31 M samples/s), 10 periods of 10 000 in ~2.0 ms (~50 M samples/s).

use num_complex::Complex64;
use thiserror::Error;

use crate::record::{Channel, Excitation, Record};

/// Options of [`analyse_multisine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultisineOptions {
    /// Whole periods at the start of a record left out as the transient. Default 1.
    pub transient_periods: usize,
}

impl Default for MultisineOptions {
    fn default() -> Self {
        MultisineOptions {
            transient_periods: 1,
        }
    }
}

/// Fewest periods after the transient: the noise comes from the scatter between them.
pub const MIN_MULTISINE_PERIODS: usize = 2;

/// The averaged period of one channel.
#[derive(Debug, Clone, PartialEq)]
pub struct LineSpectrum {
    pub channel: Channel,
    /// `C_k` at every bin `k = 0..=N/2` (one-sided; unit of the channel).
    pub phasors: Vec<Complex64>,
    /// Standard error of each `C_k` from the scatter between periods.
    pub noise_std: Vec<f64>,
}

impl LineSpectrum {
    /// A channel of an averaged period carried as harmonics of the base frequency (what a
    /// phasor message holds) as the line spectrum it is.
    pub(crate) fn of_channel(c: &super::ChannelPhasors) -> LineSpectrum {
        LineSpectrum {
            channel: c.channel,
            phasors: c.phasors.clone(),
            noise_std: c.noise_std.clone(),
        }
    }
}

/// The nonlinear-distortion indicator of one channel over the excited band.
#[derive(Debug, Clone, PartialEq)]
pub struct DistortionLevel {
    pub channel: Channel,
    /// Lowest and highest excited line [Hz].
    pub band_hz: [f64; 2],
    /// Mean power at the non-excited even bins in the band, relative to the mean power at the
    /// excited lines [dB] (None: no such bin).
    pub even_db: Option<f64>,
    /// The same at the non-excited odd bins.
    pub odd_db: Option<f64>,
    /// Mean noise power (squared standard error) at the non-excited bins in the band,
    /// relative to the excited lines [dB]: where a linear system's levels would be.
    pub noise_db: Option<f64>,
}

/// Result of [`analyse_multisine`].
#[derive(Debug, Clone, PartialEq)]
pub struct MultisineAnalysis {
    pub step: usize,
    pub base_frequency_hz: f64,
    /// Excited lines `k` (bins of the period), ascending.
    pub lines: Vec<usize>,
    pub samples_per_period: usize,
    pub periods_used: usize,
    pub periods_available: usize,
    pub first_used_sample: usize,
    /// Start of the first used period [s since the start of the run].
    pub t_ref_s: f64,
    /// One per record channel, in record order.
    pub channels: Vec<LineSpectrum>,
    pub distortion: Vec<DistortionLevel>,
}

impl MultisineAnalysis {
    pub fn channel(&self, c: Channel) -> Option<&LineSpectrum> {
        self.channels.iter().find(|s| s.channel == c)
    }

    /// The averaged period as harmonics `n = 0..=N/2` of the base frequency (what a phasor
    /// message carries): the bins are exactly the harmonics of `f0` over a period, referenced
    /// to `t_ref_s`. Not a fit: `residual_rms` is 0, the step settled by construction (the
    /// transient periods left out) and `harmonic_cap` the last bin. `amplitude` is the
    /// excitation's (its RMS).
    pub fn as_harmonic_analysis(&self, amplitude: f64) -> super::HarmonicAnalysis {
        let bins = self.channels.first().map_or(1, |c| c.phasors.len());
        super::HarmonicAnalysis {
            step: self.step,
            frequency_hz: self.base_frequency_hz,
            amplitude,
            t_ref_s: self.t_ref_s,
            periods_used: self.periods_used,
            periods_available: self.periods_available,
            first_settled_sample: self.first_used_sample,
            samples_used: self.periods_used * self.samples_per_period,
            settled: true,
            harmonics: bins - 1,
            harmonic_cap: bins - 1,
            channels: self
                .channels
                .iter()
                .map(|c| super::ChannelPhasors {
                    channel: c.channel,
                    phasors: c.phasors.clone(),
                    noise_std: c.noise_std.clone(),
                    residual_rms: 0.0,
                    rate_per_s: Vec::new(),
                })
                .collect(),
            frequency_rate_hz_per_s: 0.0,
        }
    }
}

impl MultisineAnalysis {
    /// The analysis back from its averaged period as harmonics of the base frequency
    /// ([`MultisineAnalysis::as_harmonic_analysis`], what a phasor message carries) and its
    /// excited `lines` (ascending; the message does not carry them: [`excited_lines_of`] finds
    /// them): every field the equations use is as it was, the distortion recomputed from them.
    /// Refused when `an` cannot be an averaged period (`N = samples_used / periods_used`
    /// samples a period, bins `0..=N/2`, at least [`MIN_MULTISINE_PERIODS`] periods) or a line
    /// is not one of its bins below the Nyquist frequency.
    ///
    /// [`excited_lines_of`]: super::multisine_lines::excited_lines_of
    pub fn from_harmonic_analysis(
        an: &super::HarmonicAnalysis,
        lines: Vec<usize>,
    ) -> Result<MultisineAnalysis, MultisineError> {
        let step = an.step;
        let n = averaged_period_samples(an)?;
        if lines.is_empty() {
            return Err(MultisineError::NoLines { step });
        }
        if let Some(&line) = lines.iter().find(|&&k| 2 * k >= n || k == 0) {
            return Err(MultisineError::NotAveragedPeriod {
                step,
                problem: format!(
                    "excited line {line} is not a bin between 0 and N/2 = {}",
                    n / 2
                ),
            });
        }
        let f0 = an.frequency_hz;
        let channels: Vec<LineSpectrum> =
            an.channels.iter().map(LineSpectrum::of_channel).collect();
        let distortion = channels
            .iter()
            .map(|s| distortion_level(s, &lines, f0))
            .collect();
        Ok(MultisineAnalysis {
            step,
            base_frequency_hz: f0,
            lines,
            samples_per_period: n,
            periods_used: an.periods_used,
            periods_available: an.periods_available,
            first_used_sample: an.first_settled_sample,
            t_ref_s: an.t_ref_s,
            channels,
            distortion,
        })
    }
}

/// The samples `N` of a period of which `an` is the averaged period (see
/// [`MultisineAnalysis::from_harmonic_analysis`]).
pub(crate) fn averaged_period_samples(
    an: &super::HarmonicAnalysis,
) -> Result<usize, MultisineError> {
    let step = an.step;
    let refuse = |problem: String| MultisineError::NotAveragedPeriod { step, problem };
    let (used, samples) = (an.periods_used, an.samples_used);
    if used < MIN_MULTISINE_PERIODS || samples % used != 0 {
        return Err(refuse(format!(
            "{samples} samples in {used} periods (at least {MIN_MULTISINE_PERIODS} whole periods of a whole number of samples)"
        )));
    }
    let n = samples / used;
    let bins = n / 2 + 1;
    if let Some(c) = an
        .channels
        .iter()
        .find(|c| c.phasors.len() != bins || c.noise_std.len() != bins)
    {
        return Err(refuse(format!(
            "channel {} has {} bins where a period of {n} samples has {bins}",
            c.channel.name(),
            c.phasors.len()
        )));
    }
    Ok(n)
}

#[derive(Debug, Clone, PartialEq, Error)]
pub enum MultisineError {
    #[error("step {step}: not a periodic multisine record")]
    NotMultisine { step: usize },
    #[error("step {step}: the multisine excites no line")]
    NoLines { step: usize },
    /// Phasors taken for a multisine's averaged period that cannot be one.
    #[error("step {step}: not the averaged period of a multisine: {problem}")]
    NotAveragedPeriod { step: usize, problem: String },
    /// The record's channels themselves (none, unequal lengths, a non-finite sample).
    #[error(transparent)]
    Channels(#[from] super::PhasorError),
    #[error(
        "step {step}: a multisine period of {base_frequency_hz} Hz at {sample_rate_hz} Hz is {samples_per_period} samples, not a whole number"
    )]
    NotWholeSamples {
        step: usize,
        base_frequency_hz: f64,
        sample_rate_hz: f64,
        samples_per_period: f64,
    },
    #[error(
        "step {step}: excited line {line} ({frequency_hz} Hz) is at or above the Nyquist frequency {nyquist_hz} Hz"
    )]
    LineAboveNyquist {
        step: usize,
        line: usize,
        frequency_hz: f64,
        nyquist_hz: f64,
    },
    #[error("step {step}: the driven channel {} is not in the record", channel.name())]
    DrivenMissing { step: usize, channel: Channel },
    #[error(
        "step {step}: no excited line of a multisine of {base_frequency_hz} Hz stands out of the {} spectrum (the widest drop between its bins is {margin_db:.1} dB, {} dB needed): not a periodic multisine of this base frequency",
        channel.name(),
        super::multisine_lines::MIN_LINE_MARGIN_DB
    )]
    NoLineStandsOut {
        step: usize,
        channel: Channel,
        base_frequency_hz: f64,
        margin_db: f64,
    },
    #[error(
        "step {step}: the {lines} strongest bins of the {} spectrum do not repeat period after period (median {level_db:.1} dB over their scatter between periods, {} dB needed): not a periodic multisine",
        channel.name(),
        super::multisine_lines::MIN_LINE_PERIODICITY_DB
    )]
    LinesNotPeriodic {
        step: usize,
        channel: Channel,
        lines: usize,
        level_db: f64,
    },
    #[error(
        "step {step}: the multisine record is too short: {samples} samples hold {periods:.2} periods of {base_frequency_hz} Hz; it needs {needed} whole periods ({needed_samples} samples): {transient} transient and {min} for the noise estimate"
    )]
    TooShort {
        step: usize,
        samples: usize,
        periods: f64,
        base_frequency_hz: f64,
        transient: usize,
        min: usize,
        needed: usize,
        needed_samples: usize,
    },
}

/// Phasors, noise and distortion of a periodic multisine record (see the module docs).
pub fn analyse_multisine(
    record: &Record,
    options: &MultisineOptions,
) -> Result<MultisineAnalysis, MultisineError> {
    let step = record.step;
    let Excitation::Multisine {
        base_frequency_hz,
        lines,
        ..
    } = &record.excitation
    else {
        return Err(MultisineError::NotMultisine { step });
    };
    let (f0, fs) = (*base_frequency_hz, record.sample_rate_hz);
    let mut lines = lines.clone();
    lines.sort_unstable();
    lines.dedup();
    if lines.is_empty() {
        return Err(MultisineError::NoLines { step });
    }
    let grid = PeriodGrid::of(record, f0, options)?;
    let (n, skip, available) = (grid.samples_per_period, grid.skip, grid.available);
    if let Some(&line) = lines.iter().find(|&&k| 2 * k >= n) {
        return Err(MultisineError::LineAboveNyquist {
            step,
            line,
            frequency_hz: line as f64 * f0,
            nyquist_hz: fs / 2.0,
        });
    }
    let used = available - skip;
    let mut averager = PeriodAverager::new(n);
    let channels = record
        .channels
        .iter()
        .map(|(c, data)| averager.average(*c, grid.used(data)))
        .collect::<Vec<_>>();
    let distortion = channels
        .iter()
        .map(|s| distortion_level(s, &lines, f0))
        .collect();
    let first_used_sample = skip * n;
    Ok(MultisineAnalysis {
        step,
        base_frequency_hz: f0,
        lines,
        samples_per_period: n,
        periods_used: used,
        periods_available: available,
        first_used_sample,
        t_ref_s: record.time_s(first_used_sample),
        channels,
        distortion,
    })
}

/// The whole periods of a multisine record of base frequency `f0`: `N` samples each, the
/// first `skip` left out as the transient, `available` in all (checked: `N` a whole number,
/// at least [`MIN_MULTISINE_PERIODS`] after the transient).
pub(crate) struct PeriodGrid {
    pub samples_per_period: usize,
    pub skip: usize,
    pub available: usize,
}

impl PeriodGrid {
    pub(crate) fn of(
        record: &Record,
        f0: f64,
        options: &MultisineOptions,
    ) -> Result<PeriodGrid, MultisineError> {
        let (step, fs) = (record.step, record.sample_rate_hz);
        let spp = fs / f0;
        let n = spp.round();
        if !(spp.is_finite() && n >= 2.0 && (spp - n).abs() <= 1e-9 * n) {
            return Err(MultisineError::NotWholeSamples {
                step,
                base_frequency_hz: f0,
                sample_rate_hz: fs,
                samples_per_period: spp,
            });
        }
        let n = n as usize;
        let len = super::checked_length(record)?;
        let available = len / n;
        let skip = options.transient_periods;
        if available < skip + MIN_MULTISINE_PERIODS {
            let needed = skip + MIN_MULTISINE_PERIODS;
            return Err(MultisineError::TooShort {
                step,
                samples: len,
                periods: len as f64 / spp,
                base_frequency_hz: f0,
                transient: skip,
                min: MIN_MULTISINE_PERIODS,
                needed,
                needed_samples: needed * n,
            });
        }
        Ok(PeriodGrid {
            samples_per_period: n,
            skip,
            available,
        })
    }

    /// The used samples of `data` (whole periods after the transient).
    pub(crate) fn used<'a>(&self, data: &'a [f64]) -> &'a [f64] {
        let n = self.samples_per_period;
        &data[self.skip * n..self.available * n]
    }
}

/// The averaged period of a channel: the one-sided DFT of each period of `N` samples, their
/// mean and its standard error from the scatter between periods (steps 1-3 of the module
/// docs). One FFT plan for every channel of a record.
pub(crate) struct PeriodAverager {
    n: usize,
    fft: std::sync::Arc<dyn rustfft::Fft<f64>>,
    buf: Vec<Complex64>,
    scratch: Vec<Complex64>,
}

impl PeriodAverager {
    pub(crate) fn new(samples_per_period: usize) -> PeriodAverager {
        let n = samples_per_period;
        let fft = crate::signal::fft::forward(n);
        let scratch = vec![Complex64::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        PeriodAverager {
            n,
            fft,
            buf: vec![Complex64::new(0.0, 0.0); n],
            scratch,
        }
    }

    /// The averaged period of `data`, whole periods of `N` samples (at least 2; a fraction at
    /// the end is left out).
    pub(crate) fn average(&mut self, channel: Channel, data: &[f64]) -> LineSpectrum {
        let n = self.n;
        let half = n / 2;
        let scale = |k: usize| {
            if k == 0 || 2 * k == n {
                1.0 / n as f64
            } else {
                2.0 / n as f64
            }
        };
        let mut sum = vec![Complex64::new(0.0, 0.0); half + 1];
        let mut sumsq = vec![0.0; half + 1];
        let periods = data.len() / n;
        for period in data.chunks_exact(n) {
            for (b, x) in self.buf.iter_mut().zip(period) {
                *b = Complex64::new(*x, 0.0);
            }
            self.fft
                .process_with_scratch(&mut self.buf, &mut self.scratch);
            for k in 0..=half {
                let ck = self.buf[k] * scale(k);
                sum[k] += ck;
                sumsq[k] += ck.norm_sqr();
            }
        }
        let pf = periods as f64;
        let phasors: Vec<Complex64> = sum.iter().map(|s| s / pf).collect();
        let noise_std = phasors
            .iter()
            .zip(&sumsq)
            .map(|(m, s)| ((s - pf * m.norm_sqr()).max(0.0) / (pf * (pf - 1.0))).sqrt())
            .collect();
        LineSpectrum {
            channel,
            phasors,
            noise_std,
        }
    }
}

/// Mean of `f(k)` over `bins`, None when there are none.
fn mean_over(bins: &[usize], f: impl Fn(usize) -> f64) -> Option<f64> {
    (!bins.is_empty()).then(|| bins.iter().map(|&k| f(k)).sum::<f64>() / bins.len() as f64)
}

fn distortion_level(s: &LineSpectrum, lines: &[usize], f0: f64) -> DistortionLevel {
    let (lo, hi) = (lines[0], lines[lines.len() - 1]);
    let other: Vec<usize> = (lo..=hi)
        .filter(|k| lines.binary_search(k).is_err())
        .collect();
    let even: Vec<usize> = other.iter().copied().filter(|k| k % 2 == 0).collect();
    let odd: Vec<usize> = other.iter().copied().filter(|k| k % 2 == 1).collect();
    let excited = mean_over(lines, |k| s.phasors[k].norm_sqr()).unwrap_or(0.0);
    let db = |p: f64| 10.0 * (p / excited).log10();
    DistortionLevel {
        channel: s.channel,
        band_hz: [lo as f64 * f0, hi as f64 * f0],
        even_db: mean_over(&even, |k| s.phasors[k].norm_sqr()).map(db),
        odd_db: mean_over(&odd, |k| s.phasors[k].norm_sqr()).map(db),
        noise_db: mean_over(&other, |k| s.noise_std[k].powi(2)).map(db),
    }
}
