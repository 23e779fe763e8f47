//! The harmonic node without `ExcitationState`: the samples are buffered and the steps found in
//! the driven channel ([`segment_run`], the segmentation `forcemap identify` uses on an
//! unlabelled export), so a step is cut where the CSV reader would cut it.
//!
//! A step is complete once its end lies [`COMPLETE_AFTER_WINDOWS`] detection windows before the
//! buffer's end (the next step then has a run of windows of its own, so its boundary is placed
//! from both sides as in a whole-run segmentation); its samples are then dropped from the
//! buffer. The buffer is searched again when it has grown by a quarter (at least
//! [`MIN_SEARCH_SAMPLES`]), so the work per sample stays bounded while a step is reported at
//! most a quarter of the buffer late. At the end of a run (no sample for a while) every step
//! left is complete, and so is every step before a pause or lost samples (the timing rule of
//! [`forcemap_io::steps::timing`]: the run is cut there and each part segmented, as an
//! unlabelled export is read).
//!
//! With updates ([`StepFinder::with_updates`]), the step in progress also gives provisional
//! phasors every `update_period_s` of its samples, from the samples known to be its own
//! ([`open_step`](super::open_step)); the rest of its due updates come when it closes, before
//! its record (all of them, from a stream of its record, when it had no stream: see
//! `StepFinder::close_step`).

use forcemap_io::steps::unlabelled::{is_record, segment_run, step_record};
use forcemap_io::steps::{
    StepAssembler, StepError, StepFault, StepPlan, StepSample, estimated_excitation, rms_about_mean,
};
use forcemap_math::phasor::{PhasorOptions, PhasorStream, ProvisionalUpdates};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_math::segment::{DetectedKind, DetectedStep, MIN_SERIES_SAMPLES, SegmentOptions};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::RigSample;

use super::open_step::OpenStep;

/// Fewest new samples between two searches of the buffer.
pub const MIN_SEARCH_SAMPLES: usize = 256;
/// A step is complete once its end lies this many detection windows before the buffer's end:
/// the next step then has a run of three windows of its own (1.5 windows at a hop of a
/// quarter) and half a window more for its model, so its boundary is placed from both sides as
/// in a whole-run segmentation. After one window only, the windows past the end all straddle
/// the change and the boundary came out up to 12 samples off on a 30 dB dyno run.
pub const COMPLETE_AFTER_WINDOWS: usize = 2;
/// The buffer is searched again once it has grown by this fraction since the last search.
const SEARCH_GROWTH: f64 = 0.25;

/// What the finder hands out, in order.
pub enum Found {
    /// A complete step's record, or why its samples were dropped.
    Step(Result<Record, StepError>),
    /// The stream of the step in progress (or of the step about to be handed out), due for
    /// provisional phasors.
    Provisional(Box<PhasorStream>),
    /// Provisional phasors of `step` were given for more samples than the step turned out to
    /// have (the margin of [`open_step`](super::open_step) was too small): a warning.
    Misattributed { message: String },
}

impl Found {
    /// The step's record or error (`None` for the other kinds).
    pub fn into_step(self) -> Option<Result<Record, StepError>> {
        match self {
            Found::Step(r) => Some(r),
            _ => None,
        }
    }
}

/// Buffers samples and hands out the records of the steps found in them.
pub struct StepFinder {
    options: SegmentOptions,
    max_samples: usize,
    origin: Option<Time>,
    buffer: Vec<StepSample>,
    searched_len: usize,
    next_step: usize,
    /// Provisional updates: every this many seconds of a step's samples, analysed so.
    updates: Option<(f64, PhasorOptions)>,
    /// The step in progress and its frequency, as the last search found it.
    candidate: Option<(usize, f64)>,
    /// Its stream, once two searches agreed on its frequency.
    open: Option<OpenStep>,
    /// The run's sample rate and driven channel, as the last search found them.
    rate_and_driven: Option<(f64, Channel)>,
    /// Buffer length at the last check of the open step's samples.
    checked_len: usize,
}

impl StepFinder {
    /// A finder holding at most `max_samples` samples: a buffer that reaches it without a
    /// complete step is dropped as one (memory stays bounded whatever the drive).
    pub fn new(options: SegmentOptions, max_samples: usize) -> StepFinder {
        StepFinder {
            options,
            max_samples: max_samples.max(2 * MIN_SEARCH_SAMPLES),
            origin: None,
            buffer: Vec::new(),
            searched_len: 0,
            next_step: 0,
            updates: None,
            candidate: None,
            open: None,
            rate_and_driven: None,
            checked_len: 0,
        }
    }

    /// The same finder giving provisional phasors of the step in progress every
    /// `update_period_s` of its samples, analysed with `options`; refused unless the period is
    /// positive.
    pub fn with_updates(
        self,
        update_period_s: f64,
        options: PhasorOptions,
    ) -> anyhow::Result<StepFinder> {
        ProvisionalUpdates::new(update_period_s, 1.0)?;
        Ok(StepFinder {
            updates: Some((update_period_s, options)),
            ..self
        })
    }

    /// The time of t = 0 (the first sample's stamp).
    pub fn origin(&self) -> Option<Time> {
        self.origin
    }

    /// Samples held.
    pub fn buffered(&self) -> usize {
        self.buffer.len()
    }

    /// Adds a sample; returns the steps it completed (numbered from 0 in the order found; the
    /// samples' own `step` field is not used), each after the provisional phasors still due
    /// for it, and those of the step in progress.
    pub fn push(&mut self, s: &RigSample) -> Vec<Found> {
        let origin = *self.origin.get_or_insert(s.header.stamp);
        let mut sample = StepSample::of_rig(s, s.header.stamp.secs_since(origin));
        sample.step = 0;
        self.buffer.push(sample);
        let n = self.buffer.len();
        if n >= self.max_samples {
            return vec![Found::Step(Err(self.drop_buffer(format!(
                "no step boundary found in {n} samples (the buffer's limit)"
            ))))];
        }
        let grown = n - self.searched_len;
        let due = (SEARCH_GROWTH * self.searched_len as f64).max(MIN_SEARCH_SAMPLES as f64);
        if n >= MIN_SERIES_SAMPLES && grown as f64 >= due {
            self.search(false)
        } else {
            self.check_open()
        }
    }

    /// Between searches, every update period: feeds the open step the samples now known to be
    /// its own.
    fn check_open(&mut self) -> Vec<Found> {
        let (Some(open), Some((rate_hz, _)), Some((period_s, _))) =
            (&mut self.open, self.rate_and_driven, &self.updates)
        else {
            return Vec::new();
        };
        let n = self.buffer.len();
        let every = ProvisionalUpdates::new(*period_s, rate_hz)
            .map_or(usize::MAX, |u| u.samples_per_update());
        if n < self.checked_len + every {
            return Vec::new();
        }
        self.checked_len = n;
        let upto = open.confirmed(&self.buffer, rate_hz, &self.options);
        provisional(open.feed(&self.buffer, upto, 0))
    }

    /// The end of the run: every step in the buffer is complete.
    pub fn finish(&mut self) -> Vec<Found> {
        if self.buffer.is_empty() {
            return Vec::new();
        }
        self.search(true)
    }

    fn drop_buffer(&mut self, why: String) -> StepError {
        let samples = self.buffer.len();
        self.buffer.clear();
        self.searched_len = 0;
        self.checked_len = 0;
        self.open = None;
        self.candidate = None;
        let e = step_error(self.next_step, StepFault::Abandoned { why, samples });
        self.next_step += 1;
        e
    }

    /// The buffer as records, each with where it starts in the buffer (the assembler's checks:
    /// finite values, the same channels throughout, and its timing rule: one record, or one
    /// per part between pauses or lost samples).
    fn run_records(&self) -> Result<Vec<(usize, Record)>, StepError> {
        let plan = StepPlan {
            excitation: Excitation::UNKNOWN,
            sample_count: 0,
            driven: None,
            multisine_band_hz: None,
        };
        let mut assembler = StepAssembler::new();
        for s in &self.buffer {
            // One step, no planned count: nothing completes before `finish`.
            let _ = assembler.push_sample(s, Some(&plan));
        }
        let parts = assembler.finish_step();
        if parts.is_empty() {
            return Err(step_error(self.next_step, StepFault::TooFew { samples: 0 }));
        }
        parts
            .into_iter()
            .map(|r| {
                r.map(|a| {
                    let mut rec = a.record;
                    rec.step = self.next_step;
                    (a.first_sample, rec)
                })
            })
            .collect()
    }

    /// Segments the buffer and hands out its complete steps (all of them when `all`). A pause
    /// or lost samples end the run before them: its steps are all complete.
    fn search(&mut self, all: bool) -> Vec<Found> {
        self.searched_len = self.buffer.len();
        let mut parts = match self.run_records() {
            Ok(parts) => parts,
            Err(e) => {
                return vec![Found::Step(Err(self.drop_buffer(format!(
                    "the samples since the last step do not make a record ({})",
                    e.problem
                ))))];
            }
        };
        // Samples before the first record (too few between breaks) are dropped.
        if parts[0].0 > 0 {
            self.buffer.drain(..parts[0].0);
            return self.search(all);
        }
        if let Some(&(next, _)) = parts.get(1) {
            let rest = self.buffer.split_off(next);
            let mut out = self.search(true);
            self.buffer = rest;
            self.checked_len = 0;
            out.extend(self.search(all));
            return out;
        }
        let (_, run) = parts.remove(0);
        let driven = match SetupKind::of_channels(|c| run.channel(c).is_some()) {
            Ok(kind) => kind.driven_channel(),
            Err(e) => return vec![Found::Step(Err(self.drop_buffer(e.to_string())))],
        };
        let seg = match segment_run(&run, driven, &self.options) {
            Ok(seg) => seg,
            Err(e) if all => return vec![Found::Step(Err(self.drop_buffer(e.to_string())))],
            // Too few samples yet: wait for more.
            Err(_) => return Vec::new(),
        };
        self.rate_and_driven = Some((run.sample_rate_hz, driven));
        let times: Vec<f64> = self.buffer.iter().map(|s| s.t_s).collect();
        let n = run.len();
        let mut consumed = 0;
        let mut out = Vec::new();
        let mut rest = seg.steps.iter().peekable();
        let after = COMPLETE_AFTER_WINDOWS * seg.window_samples;
        while let Some(s) = rest.next_if(|s| all || (s.end < n && s.end + after <= n)) {
            // The open step, if any, is the first to complete (it starts the buffer).
            let open = self.open.take();
            self.candidate = None;
            consumed = s.end;
            if is_record(s) {
                let (mut record, frequency) = step_record(&run, s, &times, self.next_step);
                self.next_step += 1;
                let level = record.channel(driven).map_or(f64::NAN, rms_about_mean);
                record.excitation = estimated_excitation(frequency, level);
                out.extend(self.close_step(
                    open,
                    s,
                    &record,
                    frequency,
                    seg.window_samples,
                    driven,
                ));
                out.push(Found::Step(Ok(record)));
            }
        }
        self.buffer.drain(..consumed);
        self.searched_len = self.buffer.len();
        if !all {
            out.extend(self.follow_open(rest.next(), consumed, &run, seg.window_samples));
        }
        out
    }

    /// After a search: the step in progress (`open`, found at `start` of the buffer before the
    /// complete steps were dropped) gets a stream once two searches agree on its frequency,
    /// fed the samples known to be its own.
    fn follow_open(
        &mut self,
        open: Option<&DetectedStep>,
        start: usize,
        run: &Record,
        window_samples: usize,
    ) -> Vec<Found> {
        let Some((period_s, options)) = &self.updates else {
            return Vec::new();
        };
        let (frequency, amplitude) = match open.map(|s| &s.kind) {
            Some(DetectedKind::Sine {
                frequency_hz,
                amplitude,
                ..
            }) => (*frequency_hz, *amplitude),
            _ => {
                // Not a sine as the buffer stands: nothing is fed until it is one again.
                self.candidate = None;
                return Vec::new();
            }
        };
        let Some(s) = open.filter(|s| s.start == start) else {
            return Vec::new();
        };
        let step = self.next_step;
        let agreed = self.candidate == Some((step, frequency));
        self.candidate = Some((step, frequency));
        self.open.take_if(|o| o.step != step);
        if !agreed {
            // Nothing is fed while the frequency is not settled.
            return Vec::new();
        }
        // The estimate moved: copies given so far were of the earlier one; the stream starts
        // again at the new one, giving only later updates.
        let published = self
            .open
            .take_if(|o| o.frequency_hz != frequency)
            .map_or(0, |o| o.published());
        if self.open.is_none() {
            let (_, driven) = self.rate_and_driven.expect("set by the search");
            self.open = OpenStep::new(
                step,
                frequency,
                amplitude,
                &self.buffer,
                run.sample_rate_hz,
                window_samples,
                driven,
                &self.options,
                options,
                *period_s,
                published,
            );
        }
        let Some(open) = &mut self.open else {
            return Vec::new();
        };
        // The search saw the step up to its end (or the newest sample): a margin before it.
        let seen = s.end.min(run.len()) - start;
        let upto = seen.saturating_sub(open.margin).max(open.fed());
        self.checked_len = self.buffer.len();
        provisional(open.feed(&self.buffer, upto, 0))
    }

    /// Step `s` (the buffer's samples `s.start..s.end`) closes as `record`: the due updates
    /// that its open stream has not given, so that a step gives as many as the offline
    /// [`provisional_analyses`](forcemap_math::phasor::provisional_analyses) of its record.
    /// They come from a new stream of the record when the step had none (no two searches
    /// agreed on its frequency while it was in progress: a next step too short to be found
    /// pulls the estimate of a whole-buffer search) or its stream analyses another frequency
    /// or more samples than the record has; a new stream gives only updates past the most
    /// samples a copy held. A warning when copies held more samples than the step has.
    fn close_step(
        &self,
        open: Option<OpenStep>,
        s: &DetectedStep,
        record: &Record,
        frequency: Option<f64>,
        window_samples: usize,
        driven: Channel,
    ) -> Vec<Found> {
        let Some((period_s, options)) = &self.updates else {
            return Vec::new();
        };
        let len = record.len();
        let mut out = Vec::new();
        let published = open.as_ref().map_or(0, OpenStep::published);
        if published > len {
            out.push(Found::Misattributed {
                message: format!(
                    "provisional phasors of step {} were given for {published} samples, but the step has {len}",
                    record.step
                ),
            });
        }
        let samples = &self.buffer[s.start..];
        let open = open
            .filter(|o| o.matches(record, frequency) && o.fed() <= len)
            .or_else(|| {
                let (DetectedKind::Sine { amplitude, .. }, Some(frequency_hz)) =
                    (&s.kind, frequency)
                else {
                    return None;
                };
                OpenStep::new(
                    record.step,
                    frequency_hz,
                    *amplitude,
                    samples,
                    record.sample_rate_hz,
                    window_samples,
                    driven,
                    &self.options,
                    options,
                    *period_s,
                    published,
                )
            });
        if let Some(mut open) = open {
            out.extend(provisional(open.feed(samples, len, len)));
        }
        out
    }
}

fn provisional(streams: Vec<PhasorStream>) -> Vec<Found> {
    streams
        .into_iter()
        .map(|s| Found::Provisional(Box::new(s)))
        .collect()
}

fn step_error(step: usize, fault: StepFault) -> StepError {
    StepError {
        step,
        problem: fault.to_string(),
        truncated: false,
        fault,
    }
}
