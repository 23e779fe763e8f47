//! A step's completion: its samples' timing and intervals checked, a sweep's duration, a
//! multisine's lines found (and checked against its labelled band), the assembled record.

use forcemap_math::phasor::{MultisineOptions, band_disagreement, find_multisine_lines};
use forcemap_math::record::{Channel, Excitation, Record};

use super::{
    AssembledStep, Building, IntervalRule, MIN_STEP_SAMPLES, StepError, StepFault, StepTiming,
};

pub(super) fn complete(b: Building, interval: IntervalRule) -> Result<AssembledStep, StepError> {
    let Building {
        mut record,
        stamps,
        resolution,
        expected,
        driven,
        multisine_band_hz,
        problem,
    } = b;
    let err = |fault: StepFault| StepError::new(record.step, fault);
    if let Some(p) = problem {
        return Err(err(p));
    }
    let n = stamps.len();
    if expected > 0 && n != expected {
        return Err(StepError {
            truncated: n < expected,
            ..err(StepFault::Lost {
                arrived: n,
                expected,
            })
        });
    }
    if n < MIN_STEP_SAMPLES {
        return Err(err(StepFault::TooFew { samples: n }));
    }
    let timing = StepTiming {
        samples: n,
        first_s: stamps[0],
        last_s: stamps[n - 1],
        resolution_s: resolution,
    };
    if let Some(fault) = interval_fault(&stamps, &timing, interval) {
        return Err(err(fault));
    }
    // Stamps are whole nanoseconds: snap a rate within that rounding of a whole number of Hz to
    // it, as the CSV reader does, so both forms of the same data give the same rate.
    let rate = 1.0 / timing.mean_interval_s();
    let snapped = rate.round();
    record.sample_rate_hz = if (rate - snapped).abs() < 1e-6 * rate {
        snapped
    } else {
        rate
    };
    // A sweep lasts its step: its samples over the sample rate, as the CSV reader has it.
    let duration_s = record.len() as f64 / record.sample_rate_hz;
    if let Excitation::Sweep { law } = &mut record.excitation {
        law.duration_s = duration_s;
    }
    let step = record.step;
    let found = fill_multisine_lines(&mut record, driven).map_err(|f| StepError::new(step, f))?;
    // Lines found in the data are checked against the band the step is labelled with.
    let warnings = match (&record.excitation, multisine_band_hz, driven) {
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
    Ok(AssembledStep {
        record,
        timing,
        warnings,
    })
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

/// The first interval of a step (at least 2 samples) that breaks `rule`.
fn interval_fault(stamps: &[f64], timing: &StepTiming, rule: IntervalRule) -> Option<StepFault> {
    // The intervals are not collected for the mean rule: this runs on a live step's path to
    // its phasors (a 10 kHz step has 130 000).
    let dts = || stamps.windows(2).map(|w| w[1] - w[0]);
    let first_beyond = |reference: f64, median: bool, beyond: &dyn Fn(f64) -> bool| {
        dts()
            .enumerate()
            .find(|(_, d)| beyond(*d))
            .map(|(i, d)| StepFault::NotUniform {
                sample: i + 1,
                interval: d,
                reference,
                median,
            })
    };
    match rule {
        IntervalRule::Mean { rel_tol } => {
            let dt = timing.mean_interval_s();
            first_beyond(dt, false, &|d| (d / dt - 1.0).abs() > rel_tol)
        }
        IntervalRule::Median { rel_tol } => {
            let mut sorted: Vec<f64> = dts().collect();
            sorted.sort_by(f64::total_cmp);
            let typical = sorted[sorted.len() / 2];
            let tol = rel_tol * typical + timing.rounding_s();
            first_beyond(typical, true, &|d| (d - typical).abs() > tol)
        }
    }
}
