//! The harmonic node: turns each stepped-sine step into per-frequency phasors.
//!
//! Subscribes to the samples and the excitation state, assembles each step (the same
//! [`StepAssembler`] that reads bags, so a replayed step is the record `forcemap identify`
//! reads), finds its settled part and publishes the phasors of every harmonic once the step is
//! complete; a pause or lost samples split a step in records (warned about). Steps with
//! non-finite values are dropped and reported on /diagnostics. Random (validation) records and
//! sweeps give no phasors. A periodic multisine step (`ExcitationState` MULTISINE, its lines
//! found from the driven channel when the step is assembled) is analysed whole at its end
//! (`analyse_multisine`) and published as
//! the bins of its averaged period, harmonics of the base frequency, with `harmonic_cap`
//! [`HarmonicPhasors::MULTISINE_CAP`] (the identifier does not take them yet).
//!
//! The phasors are accumulated as the samples arrive ([`PhasorStream`](forcemap_math::phasor::PhasorStream)), so that when a step's
//! last sample comes only the settling walk and the joint fit remain (independent of the step's
//! length). The stream needs the sample rate from the start: it takes the nearest whole Hz of
//! the step's first interval; if the completed step's rate (from all its stamps) differs, or
//! anything else of the record differs from what was streamed, the record is analysed in batch
//! ([`analyse_record`](forcemap_math::phasor::analyse_record)), which gives what the stream would have given at that rate.
//!
//! Without `ExcitationState` (parameter `find_steps: true`), the steps are found in the driven
//! channel of the buffered samples ([`find_steps`]: the segmentation of an unlabelled export),
//! each analysed in batch once the next step has begun; excitation states are then ignored.
//! With `update_period_s` too, the step in progress gives provisional phasors from the samples
//! known to be its own ([`open_step`]), a few detection windows behind the newest.
//!
//! With `update_period_s: T` (default: off), a step in progress also gives provisional phasors
//! every T seconds of its samples once they have settled periods (a copy of its stream,
//! finished: [`provisional_analysis`](forcemap_math::phasor::provisional_analysis)), published on `phasors/provisional` in order with the
//! steps' phasors, so that a tracking identifier follows a drift within a long step.
//!
//! A sine step's labelled frequency is checked against its driven channel when the step
//! completes ([`outcome`]: the rule of `forcemap identify`): where the data put it elsewhere, the
//! step is analysed at the estimate, in batch, with one warning naming both values.
//!
//! Parameters: `max_harmonic` (100, as `forcemap identify`), `min_periods` (the phasor
//! analysis' minimum of settled periods), `find_steps` (false), `update_period_s` (off),
//! `frequency_tolerance` (relative; 1e-6, as `forcemap identify --frequency-tolerance`),
//! `frame_id`.

use std::collections::{BTreeMap, VecDeque};
use std::time::{Duration, Instant};

use forcemap_math::phasor::{
    IDENTIFICATION_MAX_HARMONIC, PhasorOptions, PhasorStream, ProvisionalUpdates,
};
use forcemap_math::record::Record;
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::diagnostic_msgs::{DiagnosticArray, DiagnosticStatus};
use forcemap_msgs::msg::{ExcitationState, HarmonicPhasors, RigSample};
use forcemap_msgs::std_msgs::Header;
use tokio::sync::mpsc;

pub mod find_steps;
pub mod open_step;
mod outcome;
mod provisional;
mod shell;
mod stream;

use find_steps::{Found, StepFinder};
use forcemap_math::segment::SegmentOptions;
pub use shell::run;
pub use stream::Analysis;
use stream::StepStream;

use crate::latency_trace;
use crate::log_line;
use crate::ros::{NodeSetup, OnTakeError, RosNode, forward, now_time, qos};
use forcemap_io::steps::timing::BREAK_MIN_INTERVALS;
use forcemap_io::steps::unlabelled::DEFAULT_FREQUENCY_TOLERANCE;
use forcemap_io::steps::{StepAssembler, StepError, StepPlan, StepSample};
use forcemap_io::topics;

/// Samples of a step whose excitation state has not arrived are held this long (the two topics
/// are not ordered with respect to each other).
const PLAN_WAIT: Duration = Duration::from_secs(2);
/// Finding steps (no excitation states), the run ends when no sample has come for this long.
/// A pause in the stream is not always the end: a reliable DDS writer that lost a sample holds
/// the stream until it repairs it, up to its heartbeat period (Fast DDS's default is 3 s), and
/// a flooding bench publisher with a full keep-all history stalls with it. At 2 s the graph
/// test with a Fast DDS bench saw its last step cut in two under load.
pub const RUN_END_SILENCE: Duration = Duration::from_secs(5);
/// The warning when samples resume after a silence ended the run, stamped `next` where the last
/// one was stamped `last` and `interval_s` after the one before it: none where the stamps break
/// ([`BREAK_MIN_INTERVALS`] intervals or more: the bench paused, or lost samples).
fn stall_warning(silence: Duration, last: Time, interval_s: f64, next: Time) -> Option<String> {
    let gap_s = next.secs_since(last);
    (interval_s > 0.0 && gap_s > 0.0 && gap_s < BREAK_MIN_INTERVALS * interval_s).then(|| {
        format!(
            "the samples stopped for {:.1} s and resumed with no break in their stamps ({gap_s:.6} s after the last, which came {interval_s:.6} s after the one before): the stream stalled (a reliable writer repairing a lost sample holds it), the bench did not pause; the run was ended at the silence and the step in progress cut in two there: raise run_end_silence_s above the stalls",
            silence.as_secs_f64()
        )
    })
}

/// At most this many samples wait for their excitation state.
const MAX_PENDING: usize = 1_000_000;
/// Plans of this many recent steps are kept.
const KEEP_PLANS: usize = 64;

pub enum Input {
    Sample(RigSample),
    Excitation(ExcitationState),
    Tick,
}

/// What the node decided about a step.
pub enum Outcome {
    /// A complete sine step to analyse, with the run's time origin.
    Analyse(Analysis, Time),
    /// The stream of a step in progress, due for provisional phasors, with the run's origin.
    Provisional(Box<PhasorStream>, Time),
    /// A complete random record: kept for validation, no phasors.
    Skipped(usize, String),
    Dropped(StepError),
    /// Something about a step to report, naming the step: what a complete step's data say
    /// against its label (it is analysed), or, finding the steps, provisional phasors given for
    /// samples the step turned out not to have.
    Warning(String),
}

/// The node's logic without the middleware, so that it can be tested alone.
pub struct HarmonicState {
    options: PhasorOptions,
    stream: Option<StepStream>,
    assembler: StepAssembler,
    plans: BTreeMap<u32, Option<StepPlan>>,
    pending: VecDeque<(RigSample, Instant)>,
    /// When the exciter went idle. The step in progress is closed only `PLAN_WAIT` later: the
    /// idle state travels on another topic and may overtake the step's last samples.
    idle_since: Option<Instant>,
    /// Steps found in the samples instead of told by excitation states.
    finder: Option<StepFinder>,
    /// When the last sample came (finding steps: the run ends `run_end_silence` after it).
    last_sample_at: Option<Instant>,
    /// Finding steps: how long a silence ends the run (default [`RUN_END_SILENCE`]).
    run_end_silence: Duration,
    /// Finding steps: the stamps of the last two samples.
    last_stamps: [Option<Time>; 2],
    /// Finding steps: the run was ended by a silence of this long after a sample stamped so,
    /// its interval to the one before that; checked against the next sample's stamp.
    ended_by_silence: Option<(Duration, Time, f64)>,
    /// Provisional phasors every this many seconds of a step's samples (`None`: off).
    update_period_s: Option<f64>,
    /// The record of the last step analysed from its stream ([`HarmonicState::take_spent`]).
    spent: Option<Record>,
    /// A sine step's label stands within this relative difference of its frequency estimate
    /// (and within its uncertainty): [`frequency_from_data`](forcemap_io::steps::unlabelled::frequency_from_data).
    frequency_tolerance: f64,
}

impl Default for HarmonicState {
    fn default() -> Self {
        Self::new()
    }
}

impl HarmonicState {
    /// A state with the identification's phasor options.
    pub fn new() -> HarmonicState {
        HarmonicState::with_options(PhasorOptions::for_identification())
    }

    /// A state whose streams analyse with `options` (those the records are analysed with).
    pub fn with_options(options: PhasorOptions) -> HarmonicState {
        HarmonicState {
            options,
            stream: None,
            assembler: StepAssembler::new(),
            plans: BTreeMap::new(),
            pending: VecDeque::new(),
            idle_since: None,
            finder: None,
            last_sample_at: None,
            run_end_silence: RUN_END_SILENCE,
            last_stamps: [None; 2],
            ended_by_silence: None,
            update_period_s: None,
            spent: None,
            frequency_tolerance: DEFAULT_FREQUENCY_TOLERANCE,
        }
    }

    /// The same state with another relative tolerance of a sine step's label against its
    /// frequency estimate (default [`DEFAULT_FREQUENCY_TOLERANCE`]); refused unless it is
    /// finite and not negative.
    pub fn with_frequency_tolerance(self, relative: f64) -> anyhow::Result<HarmonicState> {
        anyhow::ensure!(
            relative.is_finite() && relative >= 0.0,
            "frequency_tolerance {relative} is not a finite number >= 0"
        );
        Ok(HarmonicState {
            frequency_tolerance: relative,
            ..self
        })
    }

    /// The same state ending a run whose steps it finds after `seconds` without a sample
    /// (default [`RUN_END_SILENCE`]); refused unless it is positive and finite.
    pub fn with_run_end_silence(self, seconds: f64) -> anyhow::Result<HarmonicState> {
        anyhow::ensure!(
            seconds.is_finite() && seconds > 0.0,
            "run_end_silence_s {seconds} is not a positive number of seconds"
        );
        Ok(HarmonicState {
            run_end_silence: Duration::from_secs_f64(seconds),
            ..self
        })
    }

    /// The same state giving provisional phasors of the step in progress every
    /// `update_period_s` of its samples (see the module docs); refused unless it is positive.
    pub fn with_updates(self, update_period_s: f64) -> anyhow::Result<HarmonicState> {
        ProvisionalUpdates::new(update_period_s, 1.0)?;
        let finder = match self.finder {
            Some(f) => Some(f.with_updates(update_period_s, self.options.clone())?),
            None => None,
        };
        Ok(HarmonicState {
            update_period_s: Some(update_period_s),
            finder,
            ..self
        })
    }

    /// The same state finding the steps in the samples ([`find_steps`]); excitation states
    /// are then ignored. At most `MAX_PENDING` samples are buffered. With updates, the step in
    /// progress gives provisional phasors from the samples known to be its own
    /// ([`open_step`]).
    pub fn finding_steps(self) -> anyhow::Result<HarmonicState> {
        let mut finder = StepFinder::new(SegmentOptions::default(), MAX_PENDING);
        if let Some(t) = self.update_period_s {
            finder = finder.with_updates(t, self.options.clone())?;
        }
        Ok(HarmonicState {
            finder: Some(finder),
            ..self
        })
    }

    /// Samples the step finder holds (`None` when not finding steps).
    pub fn buffered_samples(&self) -> Option<usize> {
        self.finder.as_ref().map(StepFinder::buffered)
    }

    /// Without excitation states: samples go to the finder, and the run ends (every step left
    /// is complete) when no sample has come for `run_end_silence`. Where the next sample's
    /// stamp follows the last one's with no break (the stream stalled, its bench did not
    /// pause), a warning says that the step in progress was cut there.
    fn handle_found(&mut self, input: Input, now: Instant) -> Vec<Outcome> {
        let mut stalled = None;
        let found = match (&mut self.finder, input) {
            (Some(f), Input::Sample(s)) => {
                if let Some((silence, last, interval_s)) = self.ended_by_silence.take() {
                    stalled = stall_warning(silence, last, interval_s, s.header.stamp);
                }
                self.last_sample_at = Some(now);
                self.last_stamps = [self.last_stamps[1], Some(s.header.stamp)];
                f.push(&s)
            }
            (Some(f), Input::Tick)
                if self
                    .last_sample_at
                    .is_some_and(|t| now.duration_since(t) > self.run_end_silence) =>
            {
                if let [Some(before), Some(last)] = self.last_stamps {
                    let silence = self.last_sample_at.map(|t| now.duration_since(t));
                    self.ended_by_silence = silence.map(|d| (d, last, last.secs_since(before)));
                }
                self.last_sample_at = None;
                f.finish()
            }
            _ => Vec::new(),
        };
        let origin = self.finder.as_ref().and_then(StepFinder::origin);
        found
            .into_iter()
            .flat_map(|f| match f {
                Found::Step(r) => self.outcomes(r, None),
                Found::Provisional(s) => {
                    vec![Outcome::Provisional(s, origin.unwrap_or(Time::ZERO))]
                }
                Found::Misattributed { message } => vec![Outcome::Warning(message)],
            })
            .chain(stalled.map(Outcome::Warning))
            .collect()
    }

    pub fn handle(&mut self, input: Input, now: Instant) -> Vec<Outcome> {
        if self.finder.is_some() {
            return self.handle_found(input, now);
        }
        let mut done = Vec::new();
        match input {
            Input::Excitation(e) => {
                match StepPlan::from_state(&e) {
                    Ok(Some(plan)) => {
                        self.assembler.set_origin(e.start_time);
                        self.plans.insert(e.step, Some(plan));
                        self.idle_since = None;
                    }
                    Ok(None) => {
                        // IDLE: the run ended; the step in progress closes after the wait.
                        self.idle_since = Some(now);
                    }
                    Err(err) => {
                        self.plans.insert(e.step, None);
                        done.push(Outcome::Dropped(err));
                    }
                }
                while self.plans.len() > KEEP_PLANS {
                    self.plans.pop_first();
                }
                self.flush_pending(&mut done, false);
            }
            Input::Sample(s) => {
                if !self.pending.is_empty() || !self.plans.contains_key(&s.step) {
                    if self.pending.len() < MAX_PENDING {
                        self.pending.push_back((s, now));
                    }
                    self.flush_pending(&mut done, false);
                } else {
                    self.push(&s, &mut done);
                }
            }
            Input::Tick => {
                let expired = self
                    .pending
                    .front()
                    .is_some_and(|(_, t)| now.duration_since(*t) > PLAN_WAIT);
                self.flush_pending(&mut done, expired);
                if self
                    .idle_since
                    .is_some_and(|t| now.duration_since(t) > PLAN_WAIT)
                {
                    self.idle_since = None;
                    self.flush_pending(&mut done, true);
                    let mut stream = self.stream.take();
                    for r in self.assembler.finish_step() {
                        if let Ok(a) = &r {
                            done.extend(a.messages().map(Outcome::Warning));
                        }
                        done.extend(self.outcomes(r.map(|a| a.record), stream.take()));
                    }
                }
            }
        }
        done
    }

    /// Feeds waiting samples whose plan is known (all of them when `force`).
    fn flush_pending(&mut self, done: &mut Vec<Outcome>, force: bool) {
        while let Some((s, _)) = self.pending.front() {
            if !force && !self.plans.contains_key(&s.step) {
                break;
            }
            let (s, _) = self.pending.pop_front().expect("front exists");
            self.push(&s, done);
        }
    }

    fn push(&mut self, s: &RigSample, done: &mut Vec<Outcome>) {
        let plan = self.plans.get(&s.step).cloned().flatten();
        // What `StepAssembler::push` does with a rig sample, so that the stream gets the same
        // sample (time from the same origin, same values) before the assembler.
        self.assembler.set_origin(s.header.stamp);
        let origin = self.assembler.origin().unwrap_or(s.header.stamp);
        let sample = StepSample::of_rig(s, s.header.stamp.secs_since(origin));
        let step = sample.step;
        let previous = self.stream.take_if(|st| st.step != step);
        let stream = self
            .stream
            .get_or_insert_with(|| StepStream::new(step, plan.as_ref()));
        stream.push(&sample, &self.options);
        if let Some(p) = self.update_period_s.and_then(|t| stream.provisional(t)) {
            let origin = self.assembler.origin().unwrap_or(Time::ZERO);
            done.push(Outcome::Provisional(Box::new(p), origin));
        }
        let mut previous = previous;
        for r in self.assembler.push_sample(&sample, plan.as_ref()) {
            if let Ok(a) = &r {
                done.extend(a.messages().map(Outcome::Warning));
            }
            let r = r.map(|a| a.record);
            let step_of = r.as_ref().map_or_else(|e| e.step, |rec| rec.step);
            let st = if previous.as_ref().is_some_and(|p| p.step == step_of) {
                previous.take()
            } else {
                self.stream.take_if(|st| st.step == step_of)
            };
            done.extend(self.outcomes(r, st));
        }
    }

    /// The record of the last sine step whose phasors come from its stream, which needs it no
    /// more: for the caller to free when it suits (the node: after the phasors are published,
    /// as releasing a 10 kHz step's megabytes took up to ~1 ms). Replaced by the next one.
    pub fn take_spent(&mut self) -> Option<Record> {
        self.spent.take()
    }
}

#[cfg(test)]
mod tests;
