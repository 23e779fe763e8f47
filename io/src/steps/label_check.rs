//! Labelled steps checked against what their driven channel shows, step by step: a labelled
//! start where the drive does not change, a change inside a labelled sine step, a sine labelled
//! random or the reverse (the frequency of a sine step is
//! [`frequency_from_data`](super::unlabelled::frequency_from_data)'s).
//!
//! Each pair of consecutive steps is segmented ([`detect_steps`] on the two steps' drive
//! joined), so the check holds two steps' drive at a time, whatever the length of the file, and
//! each pair's analysis windows suit its own frequencies (four periods of the pair's lowest
//! line), not the run's lowest. What a pair shows is read where the pair sees it best:
//! - a step's labelled start, in the pair that ends with the step;
//! - a change inside a step, in the pair where it lies nearer the middle: the step's first
//!   half in the pair that ends with it, its second half in the pair that starts with it (the
//!   first step of a run wholly in its first pair, the last wholly in its last);
//! - a step's kind, in the pair that ends with it (the first step of a run: its first pair).
//!
//! The pairs handed over together ([`LabelCheck::push_all`], a chunk of a file's records) are
//! segmented on the machine's cores, their findings read in order.
//!
//! A run of one step is segmented alone. Only what the segmentation can see is checked: a
//! change inside a random record is no disagreement, and a step shorter than three of its
//! pair's windows (1.5 windows at a hop of a quarter: about six periods of the pair's lowest
//! frequency), or a boundary next to one, is not checked. At most one line per record and kind.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::sync::Arc;

use forcemap_math::parallel;
use forcemap_math::record::{Channel, Record};
use forcemap_math::segment::{
    DetectedKind, DetectedStep, MIN_SERIES_SAMPLES, SegmentOptions, Segmentation, detect_steps,
};

use super::unlabelled::StepWithFrequency;

/// What a label check found, one kind per warning line a record may get.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum LabelFinding {
    /// A labelled start where the drive does not change.
    Start,
    /// The drive changes inside the step.
    Change,
    /// The step is labelled another kind of excitation than the drive shows.
    Kind,
}

/// A labelled step's drive as the check holds it.
struct Step {
    /// The step's place among the steps checked (the order of the lines).
    index: usize,
    /// Its label.
    step: usize,
    /// `None`: labelled random.
    frequency: Option<f64>,
    sample_rate_hz: f64,
    start_time_s: f64,
    drive: Vec<f64>,
}

impl Step {
    fn is_random(&self) -> bool {
        self.frequency.is_none()
    }
}

/// A change found inside a step, to be reported if the step turns out to be its run's last.
struct Change {
    index: usize,
    line: String,
}

/// What the check does next, in order: the segmentations are independent and run together,
/// their findings are read in this order.
enum Job {
    /// Two consecutive steps of one rate; the first is its run's first.
    Pair(Arc<Step>, Arc<Step>, bool),
    /// A run's only step.
    Alone(Arc<Step>),
    /// The run ends: its last step's late changes are reported.
    EndRun,
}

impl Job {
    /// The drive this job segments (none for the end of a run), and its first step.
    fn drive(&self) -> Option<(Cow<'_, [f64]>, &Step)> {
        match self {
            Job::Pair(a, b, _) => Some(([&a.drive[..], &b.drive[..]].concat().into(), a)),
            Job::Alone(a) => Some((Cow::Borrowed(&a.drive[..]), a)),
            Job::EndRun => None,
        }
    }

    fn samples(&self) -> usize {
        match self {
            Job::Pair(a, b, _) => a.drive.len() + b.drive.len(),
            Job::Alone(a) => a.drive.len(),
            Job::EndRun => 0,
        }
    }
}

/// A job's segmentation: `None` where there is nothing to segment or check, the error's line
/// where it cannot be had.
type Segmented = Option<Result<Segmentation, String>>;

/// The label check of records handed over as they are read ([`LabelCheck::push_all`]), in the
/// order of the file; the lines at the end ([`LabelCheck::finish`]).
pub struct LabelCheck {
    driven: Channel,
    options: SegmentOptions,
    /// The step before the one being read (complete), and the one being read.
    previous: Option<Arc<Step>>,
    current: Option<Step>,
    /// The run (steps of one rate in a row) has a pair.
    paired: bool,
    /// Segmentations to run.
    jobs: Vec<Job>,
    /// Changes in the second half of the last pair's later step.
    pending: Vec<Change>,
    found: BTreeMap<(usize, LabelFinding), (String, usize)>,
    /// Why a pair could not be segmented (the first), and how many more could not.
    not_checked: Option<(String, usize)>,
    next_index: usize,
}

impl LabelCheck {
    /// A check of the labelled steps against their `driven` channel.
    pub fn new(driven: Channel, options: &SegmentOptions) -> LabelCheck {
        LabelCheck {
            driven,
            options: options.clone(),
            previous: None,
            current: None,
            paired: false,
            jobs: Vec::new(),
            pending: Vec::new(),
            found: BTreeMap::new(),
            not_checked: None,
            next_index: 0,
        }
    }

    /// The next `records` of the file, in order, each (record, its labelled step, its labelled
    /// sine frequency or `None` for random); the steps they complete are segmented on the
    /// machine's cores. A record of the same label as the one before continues its step (a
    /// step its timing cut in parts is one step to the drive); a record at another sample rate
    /// starts another run (the segmenter takes one rate), as does one without the driven
    /// channel, which is not checked.
    pub fn push_all<'r>(
        &mut self,
        records: impl IntoIterator<Item = (&'r Record, usize, Option<f64>)>,
    ) {
        for (record, label, frequency) in records {
            self.take(record, label, frequency);
        }
        self.run_jobs();
    }

    /// The record taken in: the jobs of the steps it completes queued.
    fn take(&mut self, record: &Record, label: usize, frequency: Option<f64>) {
        let Some(drive) = record.channel(self.driven) else {
            self.step_complete();
            self.end_run();
            return;
        };
        if let Some(cur) = &mut self.current
            && cur.step == label
        {
            cur.drive.extend_from_slice(drive);
            return;
        }
        self.step_complete();
        let rate_changed = self
            .previous
            .as_ref()
            .is_some_and(|p| p.sample_rate_hz != record.sample_rate_hz);
        if rate_changed {
            self.end_run();
        }
        self.current = Some(Step {
            index: self.next_index,
            step: label,
            frequency,
            sample_rate_hz: record.sample_rate_hz,
            start_time_s: record.start_time_s,
            drive: drive.to_vec(),
        });
        self.next_index += 1;
    }

    /// The lines of the check, in record order (empty when labels and drive agree).
    pub fn finish(mut self) -> Vec<String> {
        self.step_complete();
        self.end_run();
        self.run_jobs();
        let mut lines: Vec<String> = self
            .not_checked
            .take()
            .map(|(line, more)| with_count(line, more))
            .into_iter()
            .collect();
        lines.extend(
            self.found
                .into_values()
                .map(|(line, more)| with_count(line, more)),
        );
        lines
    }

    /// The step being read is complete: checked with the step before it.
    fn step_complete(&mut self) {
        let Some(cur) = self.current.take() else {
            return;
        };
        let cur = Arc::new(cur);
        if let Some(prev) = self.previous.take() {
            let first_of_run = !self.paired;
            self.jobs.push(Job::Pair(prev, cur.clone(), first_of_run));
            self.paired = true;
        }
        self.previous = Some(cur);
    }

    /// The run of one rate ends with the step before: a lone step checked alone, the last
    /// step's late changes reported.
    fn end_run(&mut self) {
        if let Some(last) = self.previous.take() {
            self.jobs.push(match self.paired {
                true => Job::EndRun,
                false => Job::Alone(last),
            });
        }
        self.paired = false;
    }

    /// The queued jobs' segmentations (on the cores where they are many), their findings read
    /// in order.
    fn run_jobs(&mut self) {
        let jobs = std::mem::take(&mut self.jobs);
        if jobs.is_empty() {
            return;
        }
        let samples = jobs.iter().map(Job::samples).sum();
        let min_part = parallel::min_part_of(samples, jobs.len());
        let (driven, options) = (self.driven, &self.options);
        let segmented: Vec<Segmented> = parallel::in_parts(&jobs, min_part, |part| {
            part.iter().map(|j| segment(j, driven, options)).collect()
        });
        for (job, seg) in jobs.iter().zip(segmented) {
            match job {
                Job::Pair(a, b, a_first) => match self.segmentation(seg) {
                    Some(seg) => self.check_pair(&seg, a, b, *a_first),
                    None => self.pending.clear(),
                },
                Job::Alone(a) => {
                    if let Some(seg) = self.segmentation(seg) {
                        self.check_alone(&seg, a);
                    }
                }
                Job::EndRun => {
                    for c in std::mem::take(&mut self.pending) {
                        self.note(c.index, LabelFinding::Change, c.line);
                    }
                }
            }
        }
    }

    /// A job's segmentation, its failure noted.
    fn segmentation(&mut self, seg: Segmented) -> Option<Segmentation> {
        match seg? {
            Ok(seg) => Some(seg),
            Err(line) => {
                match &mut self.not_checked {
                    Some((_, more)) => *more += 1,
                    None => self.not_checked = Some((line, 0)),
                }
                None
            }
        }
    }

    fn note(&mut self, index: usize, what: LabelFinding, line: String) {
        self.found
            .entry((index, what))
            .and_modify(|(_, more)| *more += 1)
            .or_insert((line, 0));
    }

    /// Steps `a` and `b` (consecutive, one rate) read against their segmentation `seg`;
    /// `a_first`: `a` is its run's first step.
    fn check_pair(&mut self, seg: &Segmentation, a: &Step, b: &Step, a_first: bool) {
        // What the pair before found late in `a` is superseded by this pair, where it lies
        // nearer the middle.
        self.pending.clear();
        let view = View::new(seg, a);
        let boundary = a.drive.len();
        let (check_a, check_b) = (view.checkable(a.drive.len()), view.checkable(b.drive.len()));
        if check_a && check_b {
            // Consecutive broadband records are one found step (their bands are not told
            // apart).
            let inside_broadband = seg.steps.iter().any(|s| {
                matches!(s.kind, DetectedKind::Broadband { .. })
                    && s.start < boundary
                    && boundary < s.end
            });
            let one_broadband = a.is_random() && b.is_random() && inside_broadband;
            let found = seg.steps.iter().skip(1).any(|s| view.near(boundary, s));
            if !(one_broadband || found) {
                self.note(
                    b.index,
                    LabelFinding::Start,
                    format!(
                        "step {} is labelled to start at {:.3} s, but {} does not change there",
                        b.step,
                        b.start_time_s,
                        self.driven.name()
                    ),
                );
            }
        }
        for s in seg.steps.iter().skip(1) {
            if view.near(boundary, s) {
                continue;
            }
            if s.start < boundary {
                if check_a && !a.is_random() && (a_first || 2 * s.start >= a.drive.len()) {
                    let line = view.change_line(s, a, self.driven);
                    self.note(a.index, LabelFinding::Change, line);
                }
            } else if check_b && !b.is_random() {
                let line = view.change_line(s, b, self.driven);
                if 2 * (s.start - boundary) < b.drive.len() {
                    self.note(b.index, LabelFinding::Change, line);
                } else {
                    self.pending.push(Change {
                        index: b.index,
                        line,
                    });
                }
            }
        }
        if a_first && check_a {
            self.check_kind(seg, a, 0);
        }
        if check_b {
            self.check_kind(seg, b, boundary);
        }
    }

    /// A run's only step read against its segmentation alone.
    fn check_alone(&mut self, seg: &Segmentation, a: &Step) {
        let view = View::new(seg, a);
        if !view.checkable(a.drive.len()) {
            return;
        }
        if !a.is_random() {
            for s in seg.steps.iter().skip(1) {
                let line = view.change_line(s, a, self.driven);
                self.note(a.index, LabelFinding::Change, line);
            }
        }
        self.check_kind(seg, a, 0);
    }

    /// The kind of step `a`, whose drive starts at sample `from` of the segmented series,
    /// against the found step that overlaps it most.
    fn check_kind(&mut self, seg: &Segmentation, a: &Step, from: usize) {
        let end = from + a.drive.len();
        let Some(most) = seg
            .steps
            .iter()
            .max_by_key(|s| s.end.min(end).saturating_sub(s.start.max(from)))
        else {
            return;
        };
        let line = match (a.frequency, &most.kind) {
            (Some(_), DetectedKind::Sine { .. })
            | (None, DetectedKind::Broadband { .. })
            | (None, DetectedKind::Rest { .. }) => return,
            (Some(f), kind) => format!(
                "step {} is labelled a sine of {f} Hz, but {} is {} there",
                a.step,
                self.driven.name(),
                kind.name()
            ),
            (None, DetectedKind::Sine { frequency_hz, .. }) => format!(
                "step {} is labelled random (frequency 0 or empty), but {} is a sine of {frequency_hz} Hz there",
                a.step,
                self.driven.name()
            ),
        };
        self.note(a.index, LabelFinding::Kind, line);
    }
}

/// A segmentation of one or two steps, read against their labels.
struct View {
    window_samples: usize,
    /// A labelled and a found start agree within the found start's interval plus this many
    /// samples (a label may be written a sample or two off the change).
    slack: usize,
    start_time_s: f64,
    sample_rate_hz: f64,
}

impl View {
    fn new(seg: &Segmentation, first: &Step) -> View {
        View {
            window_samples: seg.window_samples,
            slack: (seg.window_samples / 16).max(2),
            start_time_s: first.start_time_s,
            sample_rate_hz: first.sample_rate_hz,
        }
    }

    /// A step of `len` samples spans three windows at a hop of a quarter (1.5 windows): the
    /// shortest step the segmentation finds.
    fn checkable(&self, len: usize) -> bool {
        2 * len >= 3 * self.window_samples
    }

    fn near(&self, label: usize, s: &DetectedStep) -> bool {
        label + self.slack >= s.start_interval.0 && label <= s.start_interval.1 + self.slack
    }

    fn change_line(&self, s: &DetectedStep, inside: &Step, driven: Channel) -> String {
        format!(
            "{} changes at {:.3} s (to {}) inside labelled step {}",
            driven.name(),
            self.start_time_s + s.start as f64 / self.sample_rate_hz,
            s.kind.name(),
            inside.step
        )
    }
}

/// The segmentation of a job's drive ([`Segmented`]).
fn segment(job: &Job, driven: Channel, options: &SegmentOptions) -> Segmented {
    let (drive, first) = job.drive()?;
    // Too short for a window of any step: nothing to check.
    if drive.len() < MIN_SERIES_SAMPLES {
        return None;
    }
    Some(
        detect_steps(&drive, first.sample_rate_hz, first.start_time_s, options)
            .map_err(|e| format!("labels not checked against {}: {e}", driven.name())),
    )
}

fn with_count(line: String, more: usize) -> String {
    match more {
        0 => line,
        1 => format!("{line} (and once more)"),
        n => format!("{line} (and {n} more times)"),
    }
}

/// [`LabelCheck`] of `steps`, each its own labelled step (its record's `step`), contiguous and
/// in order: the lines, empty when labels and drive agree.
pub fn check_labels(
    steps: &[StepWithFrequency],
    driven: Channel,
    options: &SegmentOptions,
) -> Vec<String> {
    let mut check = LabelCheck::new(driven, options);
    check.push_all(steps.iter().map(|(r, frequency)| (r, r.step, *frequency)));
    check.finish()
}
