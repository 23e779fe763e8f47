//! The harmonic node without `ExcitationState`: the samples are buffered and the steps found in
//! the driven channel ([`segment_run`], the segmentation `forcemap identify` uses on an
//! unlabelled export), so a step is cut where the CSV reader would cut it.
//!
//! A step is complete once its end lies at least one detection window before the buffer's end
//! (the next step then has a run of windows of its own, so its boundary is placed from both
//! sides as in a whole-run segmentation); its samples are then dropped from the buffer. The
//! buffer is searched again when it has grown by a quarter (at least [`MIN_SEARCH_SAMPLES`]),
//! so the work per sample stays bounded while a step is reported at most a quarter of the
//! buffer late. At the end of a run (no sample for a while) every step left is complete.

use forcemap_io::steps::unlabelled::{is_record, segment_run, step_record};
use forcemap_io::steps::{
    StepAssembler, StepError, StepFault, StepPlan, StepSample, estimated_excitation, rms_about_mean,
};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::segment::{MIN_SERIES_SAMPLES, SegmentOptions};
use forcemap_msgs::builtin_interfaces::Time;
use forcemap_msgs::msg::RigSample;

/// Fewest new samples between two searches of the buffer.
pub const MIN_SEARCH_SAMPLES: usize = 256;
/// The buffer is searched again once it has grown by this fraction since the last search.
const SEARCH_GROWTH: f64 = 0.25;

/// Buffers samples and hands out the records of the steps found in them.
pub struct StepFinder {
    options: SegmentOptions,
    max_samples: usize,
    origin: Option<Time>,
    buffer: Vec<StepSample>,
    searched_len: usize,
    next_step: usize,
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
        }
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
    /// samples' own `step` field is not used).
    pub fn push(&mut self, s: &RigSample) -> Vec<Result<Record, StepError>> {
        let origin = *self.origin.get_or_insert(s.header.stamp);
        let mut sample = StepSample::of_rig(s, s.header.stamp.secs_since(origin));
        sample.step = 0;
        self.buffer.push(sample);
        let n = self.buffer.len();
        if n >= self.max_samples {
            return vec![Err(self.drop_buffer(format!(
                "no step boundary found in {n} samples (the buffer's limit)"
            )))];
        }
        let grown = n - self.searched_len;
        let due = (SEARCH_GROWTH * self.searched_len as f64).max(MIN_SEARCH_SAMPLES as f64);
        if n >= MIN_SERIES_SAMPLES && grown as f64 >= due {
            self.search(false)
        } else {
            Vec::new()
        }
    }

    /// The end of the run: every step in the buffer is complete.
    pub fn finish(&mut self) -> Vec<Result<Record, StepError>> {
        if self.buffer.is_empty() {
            return Vec::new();
        }
        self.search(true)
    }

    fn drop_buffer(&mut self, why: String) -> StepError {
        let samples = self.buffer.len();
        self.buffer.clear();
        self.searched_len = 0;
        let e = step_error(self.next_step, StepFault::Abandoned { why, samples });
        self.next_step += 1;
        e
    }

    /// The buffer as one record (the assembler's checks: uniform stamps, finite values, the
    /// same channels throughout).
    fn run_record(&self) -> Result<Record, StepError> {
        let plan = StepPlan {
            excitation: Excitation::Random {
                band_hz: None,
                rms: f64::NAN,
            },
            sample_count: 0,
            driven: None,
            multisine_band_hz: None,
        };
        let mut assembler = StepAssembler::new();
        for s in &self.buffer {
            // One step, no planned count: nothing completes before `finish`.
            let _ = assembler.push_sample(s, Some(&plan));
        }
        match assembler.finish() {
            Some(r) => r.map(|mut rec| {
                rec.step = self.next_step;
                rec
            }),
            None => Err(step_error(self.next_step, StepFault::TooFew { samples: 0 })),
        }
    }

    /// Segments the buffer and hands out its complete steps (all of them when `all`).
    fn search(&mut self, all: bool) -> Vec<Result<Record, StepError>> {
        self.searched_len = self.buffer.len();
        let run = match self.run_record() {
            Ok(run) => run,
            Err(e) => {
                return vec![Err(self.drop_buffer(format!(
                    "the samples since the last step do not make a record ({})",
                    e.problem
                )))];
            }
        };
        let driven = match SetupKind::of_channels(|c| run.channel(c).is_some()) {
            Ok(kind) => kind.driven_channel(),
            Err(e) => return vec![Err(self.drop_buffer(e.to_string()))],
        };
        let seg = match segment_run(&run, driven, &self.options) {
            Ok(seg) => seg,
            Err(e) if all => return vec![Err(self.drop_buffer(e.to_string()))],
            // Too few samples yet: wait for more.
            Err(_) => return Vec::new(),
        };
        let times: Vec<f64> = self.buffer.iter().map(|s| s.t_s).collect();
        let n = run.len();
        let mut consumed = 0;
        let mut out = Vec::new();
        for s in &seg.steps {
            if !(all || (s.end < n && s.end + seg.window_samples <= n)) {
                break;
            }
            consumed = s.end;
            if is_record(s) {
                let (mut record, frequency) = step_record(&run, s, &times, self.next_step);
                self.next_step += 1;
                let level = record.channel(driven).map_or(f64::NAN, rms_about_mean);
                record.excitation = estimated_excitation(frequency, level);
                out.push(Ok(record));
            }
        }
        self.buffer.drain(..consumed);
        self.searched_len = self.buffer.len();
        out
    }
}

fn step_error(step: usize, fault: StepFault) -> StepError {
    StepError {
        step,
        problem: fault.to_string(),
        truncated: false,
        fault,
    }
}
