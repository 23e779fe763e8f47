//! Steps of data that do not label them (a DAQ export without `step` and `frequency_hz`):
//! the run as one record is cut where its driven channel changes
//! ([`forcemap_math::segment`]), each piece a record with the frequency found, as a labelled
//! source would have given them. And labels, when a source has them, checked against what the
//! driven channel shows.

use forcemap_math::record::{Channel, Record};
use forcemap_math::segment::{
    DetectedKind, DetectedStep, SegmentError, SegmentOptions, Segmentation, detect_steps,
};

use super::MIN_STEP_SAMPLES;

/// A step's record and its excitation frequency (`None`: not a sine).
pub type StepWithFrequency = (Record, Option<f64>);

/// Why an unlabelled run gives no steps.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnlabelledError {
    #[error("channel {channel}: {source}")]
    Segment {
        channel: &'static str,
        #[source]
        source: SegmentError,
    },
    #[error(
        "no stepped-sine steps found in channel {channel} (found {found}); label the steps with \
         `step` and `frequency_hz` columns, or check that {channel} is the drive"
    )]
    NoSineSteps {
        channel: &'static str,
        found: String,
    },
    #[error("the run has no channel {channel}")]
    NoDrivenChannel { channel: &'static str },
    /// A part of a run cut at a pause or lost samples ([`super::timing`]) gives no steps.
    #[error(
        "samples at {first_s:.3}-{last_s:.3} s (a part of the run between breaks of its sampling): {source}"
    )]
    InPart {
        first_s: f64,
        last_s: f64,
        #[source]
        source: Box<UnlabelledError>,
    },
}

/// Cuts `run` (one record holding a whole unlabelled run) into one record per step its
/// `driven` channel shows; `times_s[i]` is the time of sample `i` as the source wrote it
/// (each record starts at the time of its first sample). Steps at rest, and pieces shorter
/// than a step can be, are left out; the
/// records are numbered from `run.step`. Fails when no sine step is found.
pub fn split_run(
    run: &Record,
    driven: Channel,
    times_s: &[f64],
    options: &SegmentOptions,
) -> Result<Vec<StepWithFrequency>, UnlabelledError> {
    split_parts(&[(run, times_s)], driven, options)
}

/// [`split_run`] of a run that its sampling cut in parts (at pauses or lost samples:
/// [`super::timing`]), each part with its times: every part is cut where its drive changes, the
/// records numbered in order from the first part's `step`. Fails when no part shows a sine
/// step, or a part cannot be segmented (naming its span).
pub fn split_parts(
    parts: &[(&Record, &[f64])],
    driven: Channel,
    options: &SegmentOptions,
) -> Result<Vec<StepWithFrequency>, UnlabelledError> {
    let whole = parts.len() == 1;
    let segs = parts
        .iter()
        .map(|(run, times)| {
            segment_run(run, driven, options).map_err(|e| match e {
                e if whole => e,
                e => UnlabelledError::InPart {
                    first_s: times.first().copied().unwrap_or(run.start_time_s),
                    last_s: times.last().copied().unwrap_or(run.start_time_s),
                    source: Box::new(e),
                },
            })
        })
        .collect::<Result<Vec<Segmentation>, _>>()?;
    if !segs
        .iter()
        .flat_map(|s| &s.steps)
        .any(|s| frequency(s).is_some())
    {
        let found: Vec<String> = segs
            .iter()
            .zip(parts)
            .map(|(seg, (run, _))| describe(seg, run))
            .collect();
        return Err(UnlabelledError::NoSineSteps {
            channel: driven.name(),
            found: found.join("; "),
        });
    }
    let first = parts.first().map_or(0, |(run, _)| run.step);
    let mut out = Vec::new();
    for (seg, (run, times)) in segs.iter().zip(parts) {
        for s in seg.steps.iter().filter(|s| is_record(s)) {
            out.push(step_record(run, s, times, first + out.len()));
        }
    }
    Ok(out)
}

/// The steps the `driven` channel of `run` shows ([`detect_steps`] on it).
pub fn segment_run(
    run: &Record,
    driven: Channel,
    options: &SegmentOptions,
) -> Result<Segmentation, UnlabelledError> {
    let channel = driven.name();
    let x = run
        .channel(driven)
        .ok_or(UnlabelledError::NoDrivenChannel { channel })?;
    detect_steps(x, run.sample_rate_hz, run.start_time_s, options)
        .map_err(|source| UnlabelledError::Segment { channel, source })
}

/// A found step becomes a record: it is not at rest and is long enough for a step.
pub fn is_record(s: &DetectedStep) -> bool {
    !matches!(s.kind, DetectedKind::Rest { .. }) && s.end - s.start >= MIN_STEP_SAMPLES
}

/// The record of found step `s` of `run`, numbered `step`, with its frequency (`None`: not a
/// sine): its samples from its start to the end of its steady part (a taper at the end of a
/// test is left out); `times_s` as in [`split_run`]. Its excitation is `run`'s (the caller
/// knows better).
pub fn step_record(
    run: &Record,
    s: &DetectedStep,
    times_s: &[f64],
    step: usize,
) -> StepWithFrequency {
    let record = Record {
        step,
        excitation: run.excitation.clone(),
        sample_rate_hz: run.sample_rate_hz,
        start_time_s: times_s.get(s.start).copied().unwrap_or(run.time_s(s.start)),
        channels: run
            .channels
            .iter()
            .map(|(c, v)| (*c, v[s.start..s.settled_end].to_vec()))
            .collect(),
    };
    (record, frequency(s))
}

fn frequency(s: &DetectedStep) -> Option<f64> {
    match s.kind {
        DetectedKind::Sine { frequency_hz, .. } => Some(frequency_hz),
        _ => None,
    }
}

/// What a segmentation found, for messages: `2 steps: rest 0.000-1.000 s (rms 1e-5), ...`.
pub fn describe(seg: &Segmentation, run: &Record) -> String {
    let parts: Vec<String> = seg
        .steps
        .iter()
        .map(|s| {
            let span = format!("{:.3}-{:.3} s", run.time_s(s.start), run.time_s(s.end));
            match s.kind {
                DetectedKind::Sine {
                    frequency_hz,
                    amplitude,
                    ..
                } => format!("sine {frequency_hz} Hz, amplitude {amplitude:.4e} over {span}"),
                DetectedKind::Broadband { rms } => format!("broadband, rms {rms:.4e} over {span}"),
                DetectedKind::Rest { rms } => format!("rest, rms {rms:.4e} over {span}"),
            }
        })
        .collect();
    format!(
        "{} step{}: {}",
        parts.len(),
        if parts.len() == 1 { "" } else { "s" },
        parts.join("; ")
    )
}

/// Where labelled steps disagree with what their `driven` channel shows: a labelled start
/// where the drive does not change, a change inside a labelled step, a labelled frequency
/// the drive is not at (beyond 5 standard deviations of the estimate). The steps must be
/// contiguous (as an export's are). One line per disagreement; empty when they agree.
pub fn check_labels(
    steps: &[StepWithFrequency],
    driven: Channel,
    options: &SegmentOptions,
) -> Vec<String> {
    let Some((first, _)) = steps.first() else {
        return Vec::new();
    };
    let mut x = Vec::new();
    let mut starts = Vec::new();
    for (r, _) in steps {
        starts.push(x.len());
        match r.channel(driven) {
            Some(v) => x.extend_from_slice(v),
            None => return Vec::new(),
        }
    }
    let fs = first.sample_rate_hz;
    let t = |i: usize| first.start_time_s + i as f64 / fs;
    let seg = match detect_steps(&x, fs, first.start_time_s, options) {
        Ok(seg) => seg,
        Err(e) => return vec![format!("labels not checked against {}: {e}", driven.name())],
    };
    // A labelled and a found start agree within the found start's interval plus a few samples
    // (a label may be written a sample or two off the change).
    let slack = (seg.window_samples / 16).max(2);
    let near = |label: usize, s: &DetectedStep| {
        label + slack >= s.start_interval.0 && label <= s.start_interval.1 + slack
    };
    let mut out = Vec::new();
    for (k, &b) in starts.iter().enumerate().skip(1) {
        // Consecutive broadband records are one found step (their bands are not told apart).
        let both_random = steps[k - 1].1.is_none() && steps[k].1.is_none();
        let inside_broadband = seg
            .steps
            .iter()
            .any(|s| matches!(s.kind, DetectedKind::Broadband { .. }) && s.start < b && b < s.end);
        if both_random && inside_broadband {
            continue;
        }
        if !seg.steps.iter().skip(1).any(|s| near(b, s)) {
            out.push(format!(
                "step {} is labelled to start at {:.3} s, but {} does not change there",
                steps[k].0.step,
                steps[k].0.start_time_s,
                driven.name()
            ));
        }
    }
    for s in seg.steps.iter().skip(1) {
        if !starts.iter().skip(1).any(|&b| near(b, s)) {
            let k = starts.partition_point(|&b| b <= s.start).saturating_sub(1);
            out.push(format!(
                "{} changes at {:.3} s (to {}) inside labelled step {}",
                driven.name(),
                t(s.start),
                s.kind.name(),
                steps[k].0.step
            ));
        }
    }
    for (k, (r, label)) in steps.iter().enumerate() {
        let (a, b) = (starts[k], starts[k] + r.len());
        // The found step that overlaps the labelled one most.
        let Some(found) = seg
            .steps
            .iter()
            .max_by_key(|s| s.end.min(b).saturating_sub(s.start.max(a)))
        else {
            continue;
        };
        match (label, &found.kind) {
            (
                Some(f),
                DetectedKind::Sine {
                    estimated_frequency_hz: e,
                    frequency_std_hz: sd,
                    ..
                },
            ) => {
                if (f - e).abs() > 5.0 * sd + 1e-9 * f {
                    out.push(format!(
                        "step {} is labelled {f} Hz, but {} is at {e:.7} Hz (standard deviation {sd:.1e} Hz)",
                        r.step,
                        driven.name()
                    ));
                }
            }
            (Some(f), kind) => out.push(format!(
                "step {} is labelled a sine of {f} Hz, but {} is {} there",
                r.step,
                driven.name(),
                kind.name()
            )),
            (None, DetectedKind::Sine { frequency_hz, .. }) => out.push(format!(
                "step {} is labelled random (frequency 0 or empty), but {} is a sine of {frequency_hz} Hz there",
                r.step,
                driven.name()
            )),
            (None, _) => {}
        }
    }
    out
}
