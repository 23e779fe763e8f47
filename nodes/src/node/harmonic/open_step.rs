//! Provisional phasors of the step in progress when the steps are found in the samples
//! ([`StepFinder`](super::find_steps::StepFinder) with updates): the open step's stream, fed
//! only with samples known to belong to the step, giving a copy every `update_period_s` of
//! them, as the labelled harmonic node does ([`ProvisionalUpdates`]).
//!
//! **Which samples are known to be the step's.** The step's start is fixed (the previous step
//! was cut there and its samples dropped). Its end is not known until the next step has run a
//! detection window, so a sample is fed only once it lies [`MARGIN_WINDOWS`] detection windows
//! (of the step's frequency, `window_periods` periods each, and at least the segmentation's
//! window) before the newest sample, *and* a segmentation of the samples from a margin before
//! the last one fed up to the newest finds a single sine step there. A change of the drive at
//! sample `b` gives a new run of windows once the samples after it span 1.75 windows (three
//! windows at a hop of a quarter), and its boundary is placed at the change's likelihood
//! maximum, never before the half-window after the last clean window of the step (0.75 window
//! before `b` at worst); with three windows, any change before the fed samples' end would have
//! been found. At the step's end (the finder closes it), the samples up to its last are fed,
//! so that every due update the offline [`provisional_analyses`] of the step's record gives is
//! given (the same numbers when the open step's frequency, rate and channels are the
//! record's). The frequency is the open step's, once two searches of the buffer agree on it.
//!
//! [`provisional_analyses`]: forcemap_math::phasor::provisional_analyses

use forcemap_io::steps::StepSample;
use forcemap_math::phasor::{PhasorOptions, PhasorStream, ProvisionalUpdates};
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::segment::{DetectedKind, SegmentOptions, detect_steps};

/// Samples are fed this many detection windows behind the newest (see the module docs).
pub const MARGIN_WINDOWS: usize = 3;

/// The open step's stream.
pub(super) struct OpenStep {
    /// The number the step's record will have.
    pub(super) step: usize,
    pub(super) frequency_hz: f64,
    stream: PhasorStream,
    updates: ProvisionalUpdates,
    /// Samples of the buffer pushed into the stream (the step's first `fed`).
    fed: usize,
    /// The most samples a published copy held.
    published: usize,
    /// Samples not fed until this many newer ones have come.
    pub(super) margin: usize,
    driven: Channel,
    values: Vec<f64>,
}

impl OpenStep {
    /// The open step numbered `step` at `frequency_hz` (`amplitude` as the segmentation fitted
    /// it: it only labels the phasors), starting at `buffer[0]`, sampled at
    /// `sample_rate_hz` (the run's); `window_samples` the segmentation's window; no copy is
    /// handed out for the first `published` samples (an earlier stream of the step gave them).
    /// `None` when no stream can be made of it (the phasor analysis refuses the frequency or
    /// rate).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        step: usize,
        frequency_hz: f64,
        amplitude: f64,
        buffer: &[StepSample],
        sample_rate_hz: f64,
        window_samples: usize,
        driven: Channel,
        segment: &SegmentOptions,
        options: &PhasorOptions,
        update_period_s: f64,
        published: usize,
    ) -> Option<OpenStep> {
        let first = buffer.first()?;
        let updates = ProvisionalUpdates::new(update_period_s, sample_rate_hz).ok()?;
        let excitation = Excitation::Sine {
            frequency_hz,
            amplitude,
        };
        let channels: Vec<Channel> = first.values.iter().map(|(c, _)| *c).collect();
        let stream = PhasorStream::new(
            step,
            &excitation,
            sample_rate_hz,
            first.t_s,
            channels,
            options,
        )
        .ok()?;
        let window = (segment.window_periods * sample_rate_hz / frequency_hz).ceil() as usize;
        Some(OpenStep {
            step,
            frequency_hz,
            stream,
            updates,
            fed: 0,
            published,
            margin: MARGIN_WINDOWS * window.max(window_samples),
            driven,
            values: Vec::new(),
        })
    }

    /// Samples fed so far.
    pub(super) fn fed(&self) -> usize {
        self.fed
    }

    /// The most samples a copy handed out held.
    pub(super) fn published(&self) -> usize {
        self.published
    }

    /// Feeds `buffer[fed..upto]`; a copy of the stream after each due update (of a step of
    /// `expected` samples; 0: not known).
    pub(super) fn feed(
        &mut self,
        buffer: &[StepSample],
        upto: usize,
        expected: usize,
    ) -> Vec<PhasorStream> {
        let mut out = Vec::new();
        let upto = upto.min(buffer.len());
        while self.fed < upto {
            self.values.clear();
            self.values
                .extend(buffer[self.fed].values.iter().map(|(_, v)| *v));
            self.stream.push(&self.values);
            self.fed += 1;
            if self.fed > self.published && self.updates.due(self.fed, expected) {
                self.published = self.fed;
                out.push(self.stream.clone());
            }
        }
        out
    }

    /// The samples known to be the step's in `buffer` (sampled at `sample_rate_hz`) by a
    /// segmentation of its end: the newest less the margin when the samples from a margin before
    /// the last fed are one sine step at this frequency, else those fed already.
    pub(super) fn confirmed(
        &self,
        buffer: &[StepSample],
        sample_rate_hz: f64,
        segment: &SegmentOptions,
    ) -> usize {
        let n = buffer.len();
        let from = self.fed.saturating_sub(self.margin);
        let x: Vec<f64> = buffer[from..]
            .iter()
            .map(|s| {
                s.values
                    .iter()
                    .find(|(c, _)| *c == self.driven)
                    .map_or(f64::NAN, |(_, v)| *v)
            })
            .collect();
        let one_sine = match detect_steps(&x, sample_rate_hz, buffer[from].t_s, segment) {
            Ok(seg) => match seg.steps.as_slice() {
                [only] => match only.kind {
                    DetectedKind::Sine {
                        estimated_frequency_hz,
                        frequency_std_hz,
                        ..
                    } => {
                        (estimated_frequency_hz - self.frequency_hz).abs()
                            <= segment.consistency_sigmas * frequency_std_hz
                                + 1e-9 * self.frequency_hz
                    }
                    _ => false,
                },
                _ => false,
            },
            Err(_) => false,
        };
        if one_sine {
            n.saturating_sub(self.margin).max(self.fed)
        } else {
            self.fed
        }
    }

    /// Whether the step's `record` is what the stream analyses: the same first sample time,
    /// rate, frequency and channels (then its provisional phasors are the offline ones).
    pub(super) fn matches(&self, record: &Record, frequency_hz: Option<f64>) -> bool {
        record.step == self.step
            && frequency_hz == Some(self.frequency_hz)
            && record.sample_rate_hz == self.stream.sample_rate_hz()
            && self
                .stream
                .channels()
                .iter()
                .eq(record.channels.iter().map(|(c, _)| c))
    }
}
