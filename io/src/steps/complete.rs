//! A step's completion: its samples' timing read ([`super::timing`]: one record, or one per
//! part between breaks), a sweep's duration, a multisine's lines found (and checked against its
//! labelled band), the assembled records.

use forcemap_math::phasor::{MultisineOptions, band_disagreement, find_multisine_lines};
use forcemap_math::record::{Channel, Excitation, Record};

use super::timing::{self, Jitter, TimingNote};
use super::{
    AssembledStep, Building, IntervalRule, MIN_STEP_SAMPLES, StepError, StepFault, StepTiming,
};

/// The records of a completed step, numbered from `first_record`.
pub(super) fn complete(
    b: Building,
    interval: IntervalRule,
    first_record: usize,
) -> Result<Vec<AssembledStep>, StepError> {
    let Building {
        record,
        stamps,
        resolution,
        expected,
        driven,
        multisine_band_hz,
        problem,
    } = b;
    let label = record.step;
    let err = |fault: StepFault| StepError::new(label, fault);
    if let Some(p) = problem {
        return Err(err(p));
    }
    let n = stamps.len();
    let lost = |n: usize| StepError {
        truncated: n < expected,
        ..err(StepFault::Lost {
            arrived: n,
            expected,
        })
    };
    if n < MIN_STEP_SAMPLES {
        return Err(if expected > 0 && n != expected {
            lost(n)
        } else {
            err(StepFault::TooFew { samples: n })
        });
    }
    let (parts, notes) = read_timing(&stamps, resolution, interval).map_err(err)?;
    let broken = notes.iter().any(|n| matches!(n, TimingNote::Break(_)));
    if !broken && expected > 0 && n != expected {
        return Err(lost(n));
    }
    if let (Excitation::Sweep { .. }, Some(TimingNote::Break(at))) = (
        &record.excitation,
        notes.iter().find(|n| matches!(n, TimingNote::Break(_))),
    ) {
        return Err(err(StepFault::SweepBroken { at: *at }));
    }
    let mut out = Vec::with_capacity(parts.len());
    let mut from = 0;
    for (k, (first, timing)) in parts.iter().enumerate() {
        let range = *first..*first + timing.samples;
        let mut part = Record {
            step: first_record + k,
            excitation: record.excitation.clone(),
            sample_rate_hz: timing.sample_rate_hz(),
            start_time_s: timing.first_s,
            channels: record
                .channels
                .iter()
                .map(|(c, x)| (*c, x[range.clone()].to_vec()))
                .collect(),
        };
        // A sweep lasts its step: its samples over the sample rate, as the CSV reader has it.
        let duration_s = part.len() as f64 / part.sample_rate_hz;
        if let Excitation::Sweep { law } = &mut part.excitation {
            law.duration_s = duration_s;
        }
        let found = fill_multisine_lines(&mut part, driven).map_err(err)?;
        // Lines found in the data are checked against the band the step is labelled with.
        let step = part.step;
        let warnings = match (&part.excitation, multisine_band_hz, driven) {
            (
                Excitation::Multisine {
                    base_frequency_hz,
                    lines,
                    ..
                },
                Some(band),
                Some(driven),
            ) if found => band_disagreement(lines, *base_frequency_hz, band)
                .map(|why| format!("step {step}: multisine lines on {}: {why}", driven.name()))
                .into_iter()
                .collect(),
            _ => Vec::new(),
        };
        // Each note goes with the first record that ends after it (the last takes the rest).
        let end = if k + 1 == parts.len() {
            usize::MAX
        } else {
            range.end
        };
        let notes = notes
            .iter()
            .filter(|n| (from..end).contains(&note_sample(n)))
            .cloned()
            .collect();
        from = end;
        out.push(AssembledStep {
            record: part,
            timing: *timing,
            warnings,
            label,
            first_sample: *first,
            notes,
        });
    }
    Ok(out)
}

fn note_sample(n: &TimingNote) -> usize {
    match n {
        TimingNote::Break(b) => b.sample,
        TimingNote::LeftOut { first, .. } => *first,
    }
}

/// A record of a step: where it starts among the step's samples, and its timing.
type Part = (usize, StepTiming);

/// The step's samples (at least [`MIN_STEP_SAMPLES`]) as records: where each starts among them
/// and its timing, and what was done to the step. Exact stamps under `rule` are one record;
/// otherwise the step is cut at its breaks, and each part's stamps must lie on a grid within
/// the jitter ([`timing`]).
fn read_timing(
    stamps: &[f64],
    resolution_s: f64,
    rule: IntervalRule,
) -> Result<(Vec<Part>, Vec<TimingNote>), StepFault> {
    let timing_of = |s: &[f64]| StepTiming {
        samples: s.len(),
        first_s: s[0],
        last_s: s[s.len() - 1],
        resolution_s,
        jitter: None,
    };
    let whole = timing_of(stamps);
    if interval_fault(stamps, &whole, rule).is_none() {
        return Ok((vec![(0, whole)], Vec::new()));
    }
    let breaks = timing::find_breaks(stamps);
    let mut notes: Vec<TimingNote> = Vec::new();
    let mut parts = Vec::new();
    let mut longest = 0;
    let bounds: Vec<usize> = std::iter::once(0)
        .chain(breaks.iter().map(|b| b.sample))
        .chain(std::iter::once(stamps.len()))
        .collect();
    for (k, w) in bounds.windows(2).enumerate() {
        if k > 0 {
            notes.push(TimingNote::Break(breaks[k - 1]));
        }
        let s = &stamps[w[0]..w[1]];
        longest = longest.max(s.len());
        if s.len() < MIN_STEP_SAMPLES {
            notes.push(TimingNote::LeftOut {
                first: w[0],
                count: s.len(),
            });
            continue;
        }
        let mut t = timing_of(s);
        if let Some(fault) = timing::jitter_fault(s, t.rounding_s(), w[0]) {
            return Err(fault);
        }
        if interval_fault(s, &t, rule).is_some() {
            t.jitter = Some(Jitter::of(s));
        }
        parts.push((w[0], t));
    }
    if parts.is_empty() {
        return Err(StepFault::TooFew { samples: longest });
    }
    Ok((parts, notes))
}

/// A multisine planned without its lines (an `ExcitationState` does not carry them) gets the
/// lines that stand out of its driven channel's spectrum over whole periods after the
/// transient ([`find_multisine_lines`]); true when it did.
fn fill_multisine_lines(record: &mut Record, driven: Option<Channel>) -> Result<bool, StepFault> {
    let Excitation::Multisine {
        base_frequency_hz,
        lines,
        ..
    } = &record.excitation
    else {
        return Ok(false);
    };
    if !lines.is_empty() {
        return Ok(false);
    }
    let Some(driven) = driven else {
        return Err(StepFault::MultisineLines(
            "a multisine without its lines and without a driven channel to find them on".into(),
        ));
    };
    let found = find_multisine_lines(
        record,
        driven,
        *base_frequency_hz,
        &MultisineOptions::default(),
    )
    .map_err(|e| {
        // The step's own error names the step already.
        let text = e.to_string();
        let prefix = format!("step {}: ", record.step);
        StepFault::MultisineLines(text.strip_prefix(&prefix).unwrap_or(&text).to_string())
    })?;
    if let Excitation::Multisine { lines, .. } = &mut record.excitation {
        *lines = found;
    }
    Ok(true)
}

/// Whether the stamps are not exact under `rule`: the first interval beyond it.
fn interval_fault(stamps: &[f64], timing: &StepTiming, rule: IntervalRule) -> Option<usize> {
    // The intervals are not collected for the mean rule: this runs on a live step's path to
    // its phasors (a 10 kHz step has 130 000).
    let mut dts = stamps.windows(2).map(|w| w[1] - w[0]);
    match rule {
        IntervalRule::Mean { rel_tol } => {
            let dt = timing.mean_interval_s();
            dts.position(|d| (d / dt - 1.0).abs() > rel_tol)
        }
        IntervalRule::Median { rel_tol } => {
            let mut sorted: Vec<f64> = dts.clone().collect();
            sorted.sort_by(f64::total_cmp);
            let typical = sorted[sorted.len() / 2];
            let tol = rel_tol * typical + timing.rounding_s();
            dts.position(|d| (d - typical).abs() > tol)
        }
    }
}
