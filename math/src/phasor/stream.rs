//! The harmonic analysis of a step as its samples arrive: [`PhasorStream`] accumulates the sums
//! `X_n` of the current whole period sample by sample (the rotor and anchoring of the batch
//! accumulation, so the sums are the same to the last bit) and fits each period as it completes.
//! When the step ends, [`PhasorStream::finish`] only runs steps 2-5 of the method (module docs),
//! which work on the per-period fits: two joint normal matrices of `2N + 1` parameters, the
//! settling walk and the noise, `O(N^3 + periods N channels)`, independent of the samples. A
//! stream told the step's length ([`PhasorStream::expect_samples`]) runs them when the step's
//! last whole period completes, so that after the last sample `finish` only hands the result
//! over (unless the step ends on that period's last sample, where the two coincide).
//!
//! The result is [`analyse_record`](super::analyse_record)'s on the same samples, the same
//! sample rate and the same options (tests `phasor_stream`): the same periods, settled part and
//! phasors; the noise estimates may differ at rounding (~1e-14 relative), because periods of the
//! same length and phase share a Cholesky factor and the stream meets them in the other order. The sample rate must be known
//! when the step starts; a caller that only knows it at the end (from the stamps) compares it
//! then and analyses the record in batch if it differs.

use super::fit::{ANCHOR, Grid, Rotor};
use super::periods::{Periods, StepInfo, settle_and_fit};
use super::{
    HarmonicAnalysis, PhasorError, PhasorOptions, SineGrid, boundary, validate_options,
    whole_periods,
};
use crate::record::{Channel, Excitation};

/// A sine step's harmonic analysis, fed one sample (all channels) at a time.
#[derive(Clone)]
pub struct PhasorStream {
    step: usize,
    sine: SineGrid,
    sample_rate_hz: f64,
    start_time_s: f64,
    channels: Vec<Channel>,
    options: PhasorOptions,
    grid: Grid,
    rotor: Rotor,
    /// Samples pushed so far.
    samples: usize,
    /// The whole period being accumulated: `period_start..period_end`.
    period_start: usize,
    period_end: usize,
    /// Its sums, `[channel * (N + 1) + n]`, and `sum x^2` per channel.
    re: Vec<f64>,
    im: Vec<f64>,
    sumsq: Vec<f64>,
    /// The completed periods, fitted.
    periods: Periods<'static>,
    /// Samples the step will have, when known: the joint fits of its end are then prepared
    /// while its last period streams in ([`PhasorStream::expect_samples`]).
    expected_samples: Option<usize>,
    /// The analysis of the first `.0` periods, computed when the expected step's last whole
    /// period completed; [`PhasorStream::finish`] returns it if the step has that many.
    ready: Option<(usize, HarmonicAnalysis)>,
    /// The first problem met; [`PhasorStream::finish`] returns it.
    error: Option<PhasorError>,
}

impl PhasorStream {
    /// A stream for step `step` with `excitation`, sampled at `sample_rate_hz`, whose first
    /// sample is at `start_time_s`, with `channels` in the order [`PhasorStream::push`] gets
    /// their values. Fails as [`analyse_record`](super::analyse_record) would on the same
    /// excitation, rate and options.
    pub fn new(
        step: usize,
        excitation: &Excitation,
        sample_rate_hz: f64,
        start_time_s: f64,
        channels: Vec<Channel>,
        options: &PhasorOptions,
    ) -> Result<PhasorStream, PhasorError> {
        validate_options(options)?;
        let sine = SineGrid::of(step, excitation, sample_rate_hz)?;
        if channels.is_empty() {
            return Err(PhasorError::NoChannels { step });
        }
        let grid = Grid {
            nu: sine.frequency_hz / sample_rate_hz,
            harmonics: options.max_harmonic.min(sine.cap),
        };
        let (h, nc) = (grid.harmonics + 1, channels.len());
        Ok(PhasorStream {
            step,
            period_end: boundary(1, sine.samples_per_period),
            sine,
            sample_rate_hz,
            start_time_s,
            channels,
            options: options.clone(),
            rotor: Rotor::new(&grid),
            grid,
            samples: 0,
            period_start: 0,
            re: vec![0.0; nc * h],
            im: vec![0.0; nc * h],
            sumsq: vec![0.0; nc],
            periods: Periods::streamed(grid, nc, step),
            expected_samples: None,
            ready: None,
            error: None,
        })
    }

    pub fn step(&self) -> usize {
        self.step
    }

    /// The frequency the stream analyses at (its excitation's).
    pub fn frequency_hz(&self) -> f64 {
        self.sine.frequency_hz
    }

    /// The sample rate the stream was started with.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }

    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }

    /// Samples pushed so far.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Tells the stream how many samples the step will have (a plan's count), so that when
    /// the last whole period starts, the factors of the joint fits of the step's end (the tail,
    /// and the settled part as it stands) are computed ahead, and when it completes, the whole
    /// analysis: [`PhasorStream::finish`] then returns it if the step has that many whole
    /// periods. The results are the same either way.
    pub fn expect_samples(&mut self, samples: usize) {
        self.expected_samples = (samples > 0).then_some(samples);
    }

    /// Adds the next sample: one value per channel, in the order given to [`PhasorStream::new`].
    /// `O(N channels)`, plus the period's fit (`O(N^2 channels)`) when it completes a period.
    pub fn push(&mut self, values: &[f64]) {
        let k = self.samples;
        self.samples += 1;
        if self.error.is_some() {
            return;
        }
        if values.len() != self.channels.len() {
            self.error = Some(PhasorError::SampleWidth {
                step: self.step,
                sample: k,
                values: values.len(),
                channels: self.channels.len(),
            });
            return;
        }
        if let Some((c, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            self.error = Some(PhasorError::NonFinite {
                step: self.step,
                channel: self.channels[c],
                sample: k,
                value: *v,
            });
            return;
        }
        if (k - self.period_start).is_multiple_of(ANCHOR) {
            self.rotor.anchor(k);
        }
        let h = self.grid.harmonics + 1;
        for (((x, acc_r), acc_i), sq) in values
            .iter()
            .zip(self.re.chunks_exact_mut(h))
            .zip(self.im.chunks_exact_mut(h))
            .zip(self.sumsq.iter_mut())
        {
            self.rotor.add(*x, acc_r, acc_i, sq);
        }
        self.rotor.advance();
        if self.samples == self.period_end {
            self.complete_period();
        }
    }

    /// Fits the period that just completed and starts the next one.
    fn complete_period(&mut self) {
        let end = self.period_end;
        let (n, nc) = (self.re.len(), self.sumsq.len());
        let sums = (
            std::mem::replace(&mut self.re, vec![0.0; n]),
            std::mem::replace(&mut self.im, vec![0.0; n]),
            std::mem::replace(&mut self.sumsq, vec![0.0; nc]),
        );
        if let Err(e) = self.periods.push_period(end, sums) {
            self.error = Some(e);
            return;
        }
        self.period_start = end;
        let done = self.periods.count();
        self.period_end = boundary(done + 1, self.sine.samples_per_period);
        if let Some(n) = self.expected_samples {
            let last = whole_periods(n, self.grid.nu);
            if last >= 3 && done == last - 1 {
                self.prefetch(last);
            }
            if last >= 2 && done == last {
                let info = step_info(self.step, &self.sine, self.start_time_s, &self.channels);
                // An error is met again, and returned, by `finish`.
                self.ready = settle_and_fit(&mut self.periods, &info, &self.options)
                    .ok()
                    .map(|a| (last, a));
            }
        }
    }

    /// Prepares the joint fits of a step that ends with whole period `last - 1` (the one that
    /// starts now): the tail's window exactly, the used window as the settled part stands now.
    fn prefetch(&mut self, last: usize) {
        let spp = self.sine.samples_per_period;
        let end = boundary(last, spp);
        let tail = boundary(last - self.options.min_periods.max(2).min(last), spp);
        self.periods.prefetch_joint(tail, end - tail);
        let info = step_info(self.step, &self.sine, self.start_time_s, &self.channels);
        if let Ok(a) = settle_and_fit(&mut self.periods, &info, &self.options) {
            let start = self.periods.bound(a.periods_available - a.periods_used);
            self.periods.prefetch_joint(start, end - start);
        }
    }

    /// The analysis of the step from the samples pushed: the settled part, the joint fit and
    /// the noise (the same as [`analyse_record`](super::analyse_record) of those samples).
    pub fn finish(mut self) -> Result<HarmonicAnalysis, PhasorError> {
        self.analyse()
    }

    /// Whether [`PhasorStream::analyse`] only hands over the analysis computed when the step's
    /// last whole period completed ([`PhasorStream::expect_samples`]), with no work left.
    pub fn analysed_ahead(&self) -> bool {
        self.error.is_none()
            && self
                .ready
                .as_ref()
                .is_some_and(|(n, _)| *n == whole_periods(self.samples, self.grid.nu))
    }

    /// [`PhasorStream::finish`] without giving the stream up, so that the caller frees its
    /// memory (several megabytes of factors at N = 100, whose release took up to about 1 ms)
    /// when it suits, e.g. after the phasors are published. Only caches of the stream change.
    pub fn analyse(&mut self) -> Result<HarmonicAnalysis, PhasorError> {
        if let Some(e) = &self.error {
            return Err(e.clone());
        }
        let len = self.samples;
        let periods = whole_periods(len, self.grid.nu);
        if periods < 2 {
            return Err(PhasorError::TooShort {
                step: self.step,
                samples: len,
                periods: len as f64 * self.grid.nu,
                frequency_hz: self.sine.frequency_hz,
                needed: boundary(2, self.sine.samples_per_period),
            });
        }
        // The periods completed by the samples are the record's whole periods (the tolerance of
        // the count is below that of the boundaries); more cannot be used.
        if self.periods.count() < periods {
            return Err(PhasorError::InvalidFit {
                reason: format!(
                    "step {}: {periods} whole periods in {len} samples but only {} completed",
                    self.step,
                    self.periods.count()
                ),
            });
        }
        if let Some((n, analysis)) = &self.ready
            && *n == periods
        {
            return Ok(analysis.clone());
        }
        let info = step_info(self.step, &self.sine, self.start_time_s, &self.channels);
        if self.periods.count() > periods {
            let mut work = self.periods.clone();
            work.truncate(periods);
            return settle_and_fit(&mut work, &info, &self.options);
        }
        settle_and_fit(&mut self.periods, &info, &self.options)
    }
}

/// What [`settle_and_fit`] needs to know of the stream's step besides its periods (the fields
/// apart, so that the periods can be borrowed mutably beside them).
fn step_info<'a>(
    step: usize,
    sine: &SineGrid,
    start_time_s: f64,
    channels: &'a [Channel],
) -> StepInfo<'a> {
    StepInfo {
        step,
        frequency_hz: sine.frequency_hz,
        amplitude: sine.amplitude,
        start_time_s,
        channels,
        harmonic_cap: sine.cap,
    }
}
