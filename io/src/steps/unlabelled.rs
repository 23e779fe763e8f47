//! Steps of data that do not label them (a DAQ export without `step` and `frequency_hz`):
//! the run as one record is cut where its driven channel changes
//! ([`forcemap_math::segment`]), each piece a record with the frequency found, as a labelled
//! source would have given them. And labels, when a source has them, checked against what the
//! driven channel shows: where the steps change ([`super::label_check`]) and at which frequency a
//! sine step really is ([`frequency_from_data`]: a label is a hint, the data decide).

use forcemap_math::phasor::drive_frequency;
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};
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

/// Relative difference between a sine step's label and its frequency estimate below which the
/// label stands whatever the estimate's uncertainty: 1 ppm, above the rounding of a noise-free
/// estimate (1e-13) and below any clock a test bench keeps.
pub const DEFAULT_FREQUENCY_TOLERANCE: f64 = 1e-6;
/// A label stands while it is within this many standard deviations of the estimate.
pub const FREQUENCY_SIGMAS: f64 = 5.0;
/// The fundamental must explain at least this share of the driven channel's variance (period
/// by period) for the step to be a sine near its label.
const SINE_EXPLAINED: f64 = 0.5;

/// Checks a sine step's labelled frequency against its `driven` channel
/// ([`drive_frequency`]): where they differ by more than [`FREQUENCY_SIGMAS`] standard
/// deviations of the estimate and by more than `relative_tolerance` of the label, the record
/// takes the estimate and the one warning naming the step and both values is returned. A step
/// whose driven channel is no sine near its label keeps its label and gets a warning saying so;
/// a step too short for an estimate (fewer than three periods), a record that is not a sine, or
/// one without the channel, is left as it is.
pub fn frequency_from_data(
    record: &mut Record,
    driven: Channel,
    relative_tolerance: f64,
) -> Option<String> {
    let Excitation::Sine { frequency_hz, .. } = &mut record.excitation else {
        return None;
    };
    let label = *frequency_hz;
    let x = record.channels.iter().find(|(c, _)| *c == driven)?;
    let e = drive_frequency(&x.1, record.sample_rate_hz, label)?;
    let (step, name) = (record.step, driven.name());
    if e.unexplained > 1.0 - SINE_EXPLAINED {
        return Some(format!(
            "step {step} is labelled a sine of {label} Hz, but {name} is no sine near it (the fundamental leaves {:.0} % of its variance); analysed at the label",
            100.0 * e.unexplained
        ));
    }
    let diff = (e.frequency_hz - label).abs();
    if diff <= FREQUENCY_SIGMAS * e.std_hz || diff <= relative_tolerance * label {
        return None;
    }
    *frequency_hz = e.frequency_hz;
    Some(format!(
        "step {step} is labelled {label} Hz, but {name} is at {:.7} Hz (standard deviation {:.1e} Hz): analysed at {:.7} Hz",
        e.frequency_hz, e.std_hz, e.frequency_hz
    ))
}

/// The driven channel of a record by the setup its channels are
/// ([`SetupKind::of_channels`]); `None` for channels of no setup.
pub fn driven_channel_of(record: &Record) -> Option<Channel> {
    SetupKind::of_channels(|c| record.channel(c).is_some())
        .ok()
        .map(SetupKind::driven_channel)
}

/// [`frequency_from_data`] on every record, the warnings in record order.
pub fn frequencies_from_data(
    records: &mut [Record],
    driven: Channel,
    relative_tolerance: f64,
) -> Vec<String> {
    records
        .iter_mut()
        .filter_map(|r| frequency_from_data(r, driven, relative_tolerance))
        .collect()
}
