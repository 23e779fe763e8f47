//! Samples back into records, one per excitation step: what reading a bag, the harmonic node
//! and the CSV reader all do, in one place, so that a step replayed through the node graph
//! becomes exactly the record `forcemap identify` reads from the same bag, and a CSV row and a
//! rig sample go through the same rules (contiguous samples per step, at least
//! [`MIN_STEP_SAMPLES`], finite values, uniform sampling within a record).
//!
//! Where the sources differ, [`StepRules`] says how: messages carry exact stamps and may lose
//! steps ([`StepRules::MESSAGES`]); a written export has rounded times and no gaps between
//! steps ([`StepRules::WRITTEN`]).
//!
//! The times are read by one rule ([`timing`]): a pause or a lost sample ends a record (the
//! step goes on in another record), and stamps that jitter about a uniform grid are read as
//! uniform. Each record has its own sample rate. Records are numbered in order from the first
//! step's label: a step split in two makes the records after it one more than their labels
//! ([`AssembledStep::label`] keeps the label).

mod complete;
use complete::complete;
pub mod label_check;
pub mod timing;
pub mod unlabelled;

use forcemap_math::record::{Channel, Excitation, Record};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::{ExcitationState, RigSample};

/// The fewest samples a step's record can have.
pub const MIN_STEP_SAMPLES: usize = 3;

/// How the steps of a source follow each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepOrder {
    /// Each new step comes after every earlier one; steps may be missing (lost or dropped
    /// before they reached the assembler).
    Increasing,
    /// Each new step is the previous one plus one (the first may be any).
    Consecutive,
}

/// Which intervals between a step's samples make exact stamps: within the rule a step is one
/// record as it is; beyond it the samples go through the timing rule ([`timing`]: breaks and
/// jitter).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IntervalRule {
    /// Every interval within `rel_tol` (relative) of the step's mean interval: exact stamps.
    Mean { rel_tol: f64 },
    /// Every interval within `rel_tol` (relative) of the step's median interval plus the
    /// rounding of the written times ([`StepTiming::rounding_s`]): the median points at the
    /// odd interval (a dropped sample), not at the first interval after it skews the mean.
    Median { rel_tol: f64 },
}

/// The rules a source's steps are assembled under.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepRules {
    pub order: StepOrder,
    pub interval: IntervalRule,
}

impl StepRules {
    /// Rig samples from a bag or live: stamps exact to the nanosecond, steps may be lost.
    pub const MESSAGES: StepRules = StepRules {
        order: StepOrder::Increasing,
        interval: IntervalRule::Mean { rel_tol: 1e-3 },
    };
    /// Rows of a written export (CSV): times rounded as written, every step present.
    pub const WRITTEN: StepRules = StepRules {
        order: StepOrder::Consecutive,
        interval: IntervalRule::Median {
            rel_tol: WRITTEN_INTERVAL_REL_TOL,
        },
    };
}

/// Relative tolerance on the sampling interval of written data ([`StepRules::WRITTEN`]).
pub const WRITTEN_INTERVAL_REL_TOL: f64 = 1e-6;

/// One sample as the assembler takes it: what a [`RigSample`] and a CSV row both become.
#[derive(Debug, Clone, PartialEq)]
pub struct StepSample {
    /// Time from the run start, in seconds.
    pub t_s: f64,
    /// The rounding of `t_s` where it was written as text (a CSV cell); 0 for exact stamps.
    pub t_resolution_s: f64,
    pub step: usize,
    /// The channels present and their values, in [`Channel::ALL`] order.
    pub values: Vec<(Channel, f64)>,
}

impl StepSample {
    /// A rig sample at `t_s` from the run start.
    pub fn of_rig(sample: &RigSample, t_s: f64) -> StepSample {
        StepSample {
            t_s,
            t_resolution_s: 0.0,
            step: sample.step as usize,
            values: sample
                .present()
                .into_iter()
                .map(|c| (c, sample.channel(c).unwrap_or(f64::NAN)))
                .collect(),
        }
    }
}

/// What is wrong with a step; its text is [`StepError::problem`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StepFault {
    /// The step does not follow `previous` as the rules require.
    #[error("its samples are not contiguous in time (step {previous} came before)")]
    OutOfOrder { previous: usize },
    #[error("no ExcitationState for this step")]
    NoPlan,
    /// The step's excitation state does not describe an excitation.
    #[error("{0}")]
    BadPlan(String),
    #[error("sample {sample}: the set of present channels changed within the step")]
    ChannelsChanged { sample: usize },
    #[error("sample {sample}: channel {} is flagged present but not finite", channel.name())]
    NonFinite { sample: usize, channel: Channel },
    #[error(
        "{arrived} of its {expected} samples arrived (samples were lost or the recording stopped)"
    )]
    Lost { arrived: usize, expected: usize },
    #[error("{samples} samples; a step needs at least {MIN_STEP_SAMPLES}")]
    TooFew { samples: usize },
    /// Sample `sample` follows the previous one after `interval` where the record's samples are
    /// `reference` apart, and is further from their uniform grid than jitter (and no break:
    /// see [`timing`]).
    #[error(
        "samples are not uniform: sample {sample} follows the previous after {interval:.6} s where the samples around are {reference:.6} s apart (a duplicate, or a sample off its time by more than {} of an interval)",
        timing::JITTER_MAX_INTERVALS
    )]
    NotUniform {
        sample: usize,
        interval: f64,
        reference: f64,
    },
    /// A sweep's samples break ([`timing::Break`]): a sweep is one record from its start.
    #[error("a sweep's samples break at sample {}: {}; a sweep is analysed whole, from its first sample", at.sample, at.describe())]
    SweepBroken { at: timing::Break },
    #[error("{why} after {samples} samples")]
    Abandoned { why: String, samples: usize },
    /// The multisine's excited lines could not be found on its driven channel.
    #[error("{0}")]
    MultisineLines(String),
}

/// Why a step's samples do not make a record.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("step {step}: {problem}")]
pub struct StepError {
    pub step: usize,
    /// The text of `fault`.
    pub problem: String,
    /// The step only ended early (fewer samples than planned, nothing else wrong): what the
    /// last step of an interrupted recording looks like.
    pub truncated: bool,
    pub fault: StepFault,
}

impl StepError {
    fn new(step: usize, fault: StepFault) -> StepError {
        StepError {
            step,
            problem: fault.to_string(),
            truncated: false,
            fault,
        }
    }
}

/// What the assembler knows of a step from its excitation state.
#[derive(Debug, Clone, PartialEq)]
pub struct StepPlan {
    pub excitation: Excitation,
    /// Samples the step lasts; 0 when not known (the step ends when the next one starts).
    pub sample_count: usize,
    /// The driven channel, where the source names it: a multisine's lines are found on it
    /// when the plan does not give them (an `ExcitationState`).
    pub driven: Option<Channel>,
    /// A multisine's band as its `ExcitationState` labels it (lowest and highest excited
    /// line, Hz), checked against the lines found ([`band_disagreement`]); `None` where the
    /// source labels no band.
    pub multisine_band_hz: Option<[f64; 2]>,
}

impl StepPlan {
    /// The plan of a step from its state; `None` for IDLE (no step).
    pub fn from_state(state: &ExcitationState) -> Result<Option<StepPlan>, StepError> {
        if state.is_idle() {
            return Ok(None);
        }
        let excitation = state
            .excitation()
            .map_err(|e| StepError::new(state.step as usize, StepFault::BadPlan(e.to_string())))?;
        let driven = match &excitation {
            Excitation::Multisine { .. } => Some(state.driven().map_err(|e| {
                StepError::new(state.step as usize, StepFault::BadPlan(e.to_string()))
            })?),
            _ => state.driven().ok(),
        };
        let multisine_band_hz = matches!(excitation, Excitation::Multisine { .. })
            .then_some([state.band_low_hz, state.band_high_hz])
            .filter(|b| b.iter().all(|f| f.is_finite()));
        Ok(Some(StepPlan {
            excitation,
            sample_count: state.sample_count as usize,
            driven,
            multisine_band_hz,
        }))
    }
}

/// The times of a record's samples, as far as its sampling interval is concerned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepTiming {
    pub samples: usize,
    /// Time of the first and of the last sample from the run start, in seconds.
    pub first_s: f64,
    pub last_s: f64,
    /// The finest rounding of the step's times as written (0 for exact stamps).
    pub resolution_s: f64,
    /// How far the times scatter about a uniform grid when they are not exact (per the
    /// source's [`IntervalRule`]); `None` for exact times.
    pub jitter: Option<timing::Jitter>,
}

impl StepTiming {
    pub fn elapsed_s(&self) -> f64 {
        self.last_s - self.first_s
    }

    pub fn mean_interval_s(&self) -> f64 {
        self.elapsed_s() / (self.samples - 1) as f64
    }

    /// Rounding of the times plus f64 rounding at this magnitude. The written resolution is
    /// capped at a quarter interval: shortest round-trip output of "nice" times (`0.001`,
    /// `0.002`, ...) looks coarse but is exact, and a missing sample must still be caught.
    pub fn rounding_s(&self) -> f64 {
        let t_max = self.last_s.abs().max(self.first_s.abs());
        self.resolution_s.min(0.25 * self.mean_interval_s()) + 4.0 * f64::EPSILON * t_max
    }

    /// The sample rate [Hz]: the mean over the record's intervals (of jittered times, the
    /// interval of their least-squares grid), snapped to a whole number of Hz within the
    /// uncertainty of its first and last time (their rounding and jitter;
    /// [`timing::snap_rate`]).
    pub fn sample_rate_hz(&self) -> f64 {
        let elapsed = self.elapsed_s();
        let (rate, jitter) = match self.jitter {
            Some(j) => (1.0 / j.interval_s, 2.0 * j.max_s),
            None => ((self.samples - 1) as f64 / elapsed, 0.0),
        };
        timing::snap_rate(rate, (self.rounding_s() + jitter) / elapsed)
    }
}

/// A record of a completed step (a step split by a break gives several): its record and the
/// timing its sample rate came from.
#[derive(Debug, Clone, PartialEq)]
pub struct AssembledStep {
    pub record: Record,
    pub timing: StepTiming,
    /// What a user should know about the step, each naming it (a multisine's labelled band
    /// that disagrees with the lines found in its data).
    pub warnings: Vec<String>,
    /// The step's label (`record.step` is the record's number, larger after a split step).
    pub label: usize,
    /// Where the record starts among the step's samples (0 unless the step was split).
    pub first_sample: usize,
    /// What the timing rule did before this record's end: the break it starts after, samples
    /// left out, each at a sample counted in the step.
    pub notes: Vec<timing::TimingNote>,
}

impl AssembledStep {
    /// What a user should know about the record, each naming its step (its label): its
    /// warnings, the timing rule's notes (a step split at a pause or lost samples) and its
    /// times' jitter, if any. (A file's readers say the jitter once, [`timing::TimingReport`].)
    pub fn messages(&self) -> impl Iterator<Item = String> + '_ {
        let mut jitter = timing::JitterSummary::default();
        jitter.add(self.timing.jitter.as_ref());
        self.warnings
            .iter()
            .cloned()
            .chain(self.notes.iter().map(|n| n.describe(Some(self.label))))
            .chain(jitter.notice().map(|n| format!("step {}: {n}", self.label)))
    }
}

struct Building {
    record: Record,
    /// Sample times [s] from the run start.
    stamps: Vec<f64>,
    /// The finest rounding of the times.
    resolution: f64,
    expected: usize,
    driven: Option<Channel>,
    multisine_band_hz: Option<[f64; 2]>,
    /// The first problem met; the step is dropped when it completes.
    problem: Option<StepFault>,
}

/// Groups samples into records. Samples of a step must be contiguous; a step completes when
/// its planned sample count is reached, when a sample of another step arrives, or on
/// [`StepAssembler::finish`].
pub struct StepAssembler {
    rules: StepRules,
    origin: Option<Time>,
    building: Option<Building>,
    /// The last completed (or dropped) step, so that a step cannot come back.
    last_step: Option<usize>,
    /// Records beyond one per step so far (steps split by breaks): added to the labels.
    extra_records: usize,
}

impl Default for StepAssembler {
    fn default() -> Self {
        Self::new()
    }
}

impl StepAssembler {
    /// An assembler of rig samples ([`StepRules::MESSAGES`]).
    pub fn new() -> StepAssembler {
        StepAssembler::with_rules(StepRules::MESSAGES)
    }

    pub fn with_rules(rules: StepRules) -> StepAssembler {
        StepAssembler {
            rules,
            origin: None,
            building: None,
            last_step: None,
            extra_records: 0,
        }
    }

    pub fn rules(&self) -> StepRules {
        self.rules
    }

    /// Sets the time of t = 0 of the run (record start times count from it). Without it the
    /// first sample's stamp is taken.
    pub fn set_origin(&mut self, t: Time) {
        if self.origin.is_none() {
            self.origin = Some(t);
        }
    }

    pub fn origin(&self) -> Option<Time> {
        self.origin
    }

    /// The step being assembled and how many samples it has.
    pub fn in_progress(&self) -> Option<(usize, usize)> {
        self.building
            .as_ref()
            .map(|b| (b.record.step, b.stamps.len()))
    }

    /// What would be wrong with a sample of `step` arriving now under the rules' step order
    /// (`None`: nothing; the step in progress may always continue).
    pub fn order_fault(&self, step: usize) -> Option<StepFault> {
        let current = self.building.as_ref().map(|b| b.record.step);
        if current == Some(step) {
            return None;
        }
        let previous = self.last_step.max(current)?;
        let follows = match self.rules.order {
            StepOrder::Increasing => step > previous,
            StepOrder::Consecutive => step == previous + 1,
        };
        (!follows).then_some(StepFault::OutOfOrder { previous })
    }

    /// Adds one rig sample. `plan` is the plan of the sample's step (`None`: no excitation
    /// state was seen for it). Returns the records this sample completed: those of the previous
    /// step when the step changes, and this one's when it reaches its planned count.
    pub fn push(
        &mut self,
        sample: &RigSample,
        plan: Option<&StepPlan>,
    ) -> Vec<Result<Record, StepError>> {
        self.push_rig(sample, plan)
            .into_iter()
            .map(|r| r.map(|a| a.record))
            .collect()
    }

    /// [`StepAssembler::push`] with the timing and warnings of each completed step.
    pub fn push_rig(
        &mut self,
        sample: &RigSample,
        plan: Option<&StepPlan>,
    ) -> Vec<Result<AssembledStep, StepError>> {
        let origin = *self.origin.get_or_insert(sample.header.stamp);
        let t = sample.header.stamp.secs_since(origin);
        self.push_sample(&StepSample::of_rig(sample, t), plan)
    }

    /// Adds one sample of any source; as [`StepAssembler::push`], with the timing of each
    /// completed step.
    pub fn push_sample(
        &mut self,
        sample: &StepSample,
        plan: Option<&StepPlan>,
    ) -> Vec<Result<AssembledStep, StepError>> {
        let mut done = Vec::new();
        let step = sample.step;
        let order = self.order_fault(step);
        if self
            .building
            .as_ref()
            .is_some_and(|b| b.record.step != step)
        {
            done.extend(self.finish_step());
        }
        if self.building.is_none() {
            let problem = order.or_else(|| plan.is_none().then_some(StepFault::NoPlan));
            self.building = Some(Building {
                record: Record {
                    step,
                    excitation: plan.map_or(Excitation::UNKNOWN, |p| p.excitation.clone()),
                    sample_rate_hz: 0.0,
                    start_time_s: sample.t_s,
                    channels: sample
                        .values
                        .iter()
                        .map(|(c, _)| (*c, Vec::new()))
                        .collect(),
                },
                stamps: Vec::new(),
                resolution: f64::INFINITY,
                expected: plan.map_or(0, |p| p.sample_count),
                driven: plan.and_then(|p| p.driven),
                multisine_band_hz: plan.and_then(|p| p.multisine_band_hz),
                problem,
            });
        }
        let b = self.building.as_mut().expect("started above");
        let index = b.stamps.len();
        if b.problem.is_none() {
            let same_channels = b.record.channels.len() == sample.values.len()
                && b.record
                    .channels
                    .iter()
                    .zip(&sample.values)
                    .all(|((a, _), (c, _))| a == c);
            if !same_channels {
                b.problem = Some(StepFault::ChannelsChanged { sample: index });
            } else if let Some((c, _)) = sample.values.iter().find(|(_, v)| !v.is_finite()) {
                b.problem = Some(StepFault::NonFinite {
                    sample: index,
                    channel: *c,
                });
            }
        }
        if b.problem.is_none() {
            for ((_, x), (_, v)) in b.record.channels.iter_mut().zip(&sample.values) {
                x.push(*v);
            }
        }
        b.stamps.push(sample.t_s);
        b.resolution = b.resolution.min(sample.t_resolution_s);
        if b.expected > 0 && b.stamps.len() >= b.expected {
            done.extend(self.finish_step());
        }
        done
    }

    /// Completes the step in progress, if any: its records, or why it makes none.
    pub fn finish(&mut self) -> Vec<Result<Record, StepError>> {
        self.finish_step()
            .into_iter()
            .map(|r| r.map(|a| a.record))
            .collect()
    }

    /// Completes the step in progress, if any, with the timing of each of its records.
    pub fn finish_step(&mut self) -> Vec<Result<AssembledStep, StepError>> {
        let Some(b) = self.building.take() else {
            return Vec::new();
        };
        let step = b.record.step;
        self.last_step = Some(self.last_step.map_or(step, |l| l.max(step)));
        match complete(b, self.rules.interval, step + self.extra_records) {
            Ok(parts) => {
                self.extra_records += parts.len().saturating_sub(1);
                parts.into_iter().map(Ok).collect()
            }
            Err(e) => vec![Err(e)],
        }
    }

    /// Drops the step in progress (e.g. when its excitation state says it was replaced).
    pub fn abandon(&mut self, why: &str) -> Option<StepError> {
        let b = self.building.take()?;
        self.last_step = Some(b.record.step);
        Some(StepError::new(
            b.record.step,
            StepFault::Abandoned {
                why: why.to_string(),
                samples: b.stamps.len(),
            },
        ))
    }
}

/// The excitation of a step whose source carries no amplitude (a CSV export, a foreign bag),
/// estimated from the RMS `level` of its driven channel: a sine of amplitude
/// `sqrt(2) * level`, or random of RMS `level`.
pub fn estimated_excitation(frequency: Option<f64>, level: f64) -> Excitation {
    match frequency {
        Some(frequency_hz) => Excitation::Sine {
            frequency_hz,
            amplitude: sine_amplitude_from_rms(level),
        },
        None => Excitation::Random {
            band_hz: None,
            rms: level,
        },
    }
}

/// The amplitude of a sine (or of a sweep, a sine of slowly changing frequency) whose RMS is
/// `level`.
pub fn sine_amplitude_from_rms(level: f64) -> f64 {
    std::f64::consts::SQRT_2 * level
}

/// Root mean square of `x` about its mean (0 for no samples): the mathematics' one.
pub use forcemap_math::measured_state::rms_about_mean;

#[cfg(test)]
mod tests;
