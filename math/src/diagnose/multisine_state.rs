//! The candidates of the multisine diagnosis ([`super::multisine`]) that are not extra element
//! terms but are still linear per line, so the identification's equations hold them:
//!
//! - sensor_lowpass: a filter `H` on measured channels multiplies each line `k` of those
//!   channels by `H(j k w0)`; a member's filter is undone on every step's phasors (the sine
//!   steps' harmonics alike) and the equations are written on what is left. The members are the
//!   rig grid's filters on every channel (for the element setup: the displacement and the
//!   acceleration, the force as measured) and a first-order filter on the displacement or the
//!   acceleration alone; the best member's cutoff is refined by golden section on its log.
//! - series_compliance: the damper `c x'` in series with a spring `ks` is the damper's column
//!   lagged by `1 / (1 + j k w0 tau)`, `tau = c / ks` ([`TermLag`]); `c` stays a coefficient of
//!   the equations, `tau` is searched on the grid and refined like the cutoff. Written into the
//!   multisine records' per-line equations only: with sine steps beside them (rebuilt periods,
//!   not lines) it is listed as not fitted.
//!
//! Hysteresis and drift are listed as not fitted, with the reason ([`not_fitted_reason`]).

use std::borrow::Cow;

use super::effects::{
    HYSTERESIS_YIELD_FRACTIONS, LOWPASS_CUTOFF_MULTIPLES, SERIES_RELAXATION_MULTIPLES, Structure,
    hysteresis_structure, sensor_structure, series_structure,
};
use super::multisine::{BlockCandidate, Steps};
use super::sensor::{self, SensorFilter};
use super::series::{DAMPER_SYMBOL, golden_section_ln};
use crate::identify::TermLag;
use crate::model::Model;
use crate::record::Channel;
use crate::signal::bouc_wen::HysteresisLaw;

/// Channels a single-channel sensor member may sit on in a multisine record (the element
/// setup's motion channels; the force is what the members compare against).
const SINGLE_CHANNELS: [Channel; 2] = [
    Channel::RelativeDisplacementM,
    Channel::MassAccelerationMps2,
];

/// Why `s` is not fitted on these steps' equations; None when it is.
pub(super) fn not_fitted_reason(s: &Structure, steps: &Steps) -> Option<String> {
    // A hysteresis state and element terms, nothing else: its column is written into the rows.
    let hysteresis_alone = s.hysteresis.is_some()
        && super::multisine::is_extra_terms(&Structure {
            hysteresis: None,
            ..s.clone()
        });
    if !steps.records.is_empty() {
        if hysteresis_alone && steps.sines.is_empty() && steps.multisines.is_empty() {
            return None;
        }
        if !super::multisine::is_extra_terms(s) {
            return Some(
                "records with no steps are fitted sample by sample, on the element's terms along the measured motion and a hysteresis state integrated along it (on records alone): a filter, a lag or a drift is not written into those rows".into(),
            );
        }
    }
    if s.hysteresis.is_some() {
        return Some(
            "the Bouc-Wen state is not written into the per-line equations (its column needs the steady periodic state over the multisine's period); fitted on sine steps alone".into(),
        );
    }
    if s.drift {
        return Some(
            "a drift of the damping over the run is not written into the per-line equations (across records it could be: each record's damper column scaled by its time; within a record a trend is no line of the period, it leaks into the low bins and the period-to-period scatter); fitted on sine steps alone".into(),
        );
    }
    if s.series_relaxation_s.is_some() && !steps.sines.is_empty() {
        return Some(
            "the series spring lags the damper per line of the multisine records; the sine steps beside them are rebuilt periods the lag is not written into: fitted on sine steps alone or on multisine records alone".into(),
        );
    }
    let t = &s.transform;
    if t.delay_s != 0.0 || t.mass_factor != 1.0 {
        return Some("a delay or a mass factor is not written into the per-line equations".into());
    }
    None
}

/// `options` with the sensor family's single-channel members added (first order, cutoffs the
/// grid's multiples of `max_frequency_hz`) where the multisine records carry that channel.
pub(super) fn with_members(
    mut options: Vec<Structure>,
    max_frequency_hz: f64,
    steps: &Steps,
) -> Vec<Structure> {
    if !options.iter().any(|o| o.transform.sensor.is_some()) {
        return options;
    }
    for ch in SINGLE_CHANNELS {
        if steps.multisines.iter().all(|m| m.channel(ch).is_none()) {
            continue;
        }
        options.extend(
            LOWPASS_CUTOFF_MULTIPLES
                .iter()
                .map(|m| sensor_structure(&SensorFilter::on(ch, 1, m * max_frequency_hz, 1.0))),
        );
    }
    options
}

/// The steps as `s` has them: a sensor member's filter undone on every step, a series
/// spring's lag on the baseline's damper.
pub(super) fn steps_for<'a>(
    steps: &Steps<'a>,
    baseline: &Model,
    s: &Structure,
) -> Result<Steps<'a>, String> {
    let mut out = steps.clone();
    if !steps.records.is_empty() {
        out.hysteresis = s.hysteresis;
    }
    if let Some(f) = &s.transform.sensor {
        out.sines = Cow::Owned(
            steps
                .sines
                .iter()
                .map(|an| sensor::unfiltered(an, f))
                .collect(),
        );
        out.multisines = Cow::Owned(
            steps
                .multisines
                .iter()
                .map(|an| sensor::unfiltered_multisine(an, f))
                .collect(),
        );
    }
    if let Some(tau) = s.series_relaxation_s {
        let term = damper_index(baseline).ok_or_else(|| {
            format!(
                "the baseline {} has no damper {DAMPER_SYMBOL}",
                baseline.name
            )
        })?;
        out.lag = Some(TermLag {
            term,
            relaxation_s: tau,
        });
    }
    Ok(out)
}

fn damper_index(baseline: &Model) -> Option<usize> {
    baseline
        .terms
        .iter()
        .position(|t| t.symbol() == DAMPER_SYMBOL)
}

/// A lagged damper must be positive to be a series spring and a damper.
pub(super) fn physical(steps: &Steps, theta: &[f64]) -> bool {
    steps
        .lag
        .is_none_or(|l| theta.get(l.term).is_some_and(|c| *c > 0.0))
}

/// Parameters that follow from the fit: the series spring ks = c / tau [N/m].
pub(super) fn derived(steps: &Steps, theta: &[f64]) -> Vec<(String, f64, f64)> {
    steps
        .lag
        .map(|l| ("ks".to_string(), theta[l.term] / l.relaxation_s, f64::NAN))
        .into_iter()
        .collect()
}

/// `best` with its shape parameter (a sensor member's cutoff, a series relaxation time, a
/// hysteresis yield fitted on records' samples)
/// refined by golden section of the cross-validated error on its log, between the grid's
/// neighbours ([`golden_section_ln`], as on sine steps); `evaluate` fits one structure (None when it gives no candidate). Other
/// candidates are returned as they are.
pub(super) fn refine(
    best: BlockCandidate,
    mut evaluate: impl FnMut(Structure) -> Option<BlockCandidate>,
) -> BlockCandidate {
    let s = &best.structure;
    let (value, spacing, build): (f64, f64, Box<dyn Fn(f64) -> Structure>) =
        if let Some(tau) = s.series_relaxation_s {
            (
                tau,
                SERIES_RELAXATION_MULTIPLES[1] / SERIES_RELAXATION_MULTIPLES[0],
                Box::new(series_structure),
            )
        } else if let Some(f) = s.transform.sensor {
            (
                f.cutoff_hz,
                LOWPASS_CUTOFF_MULTIPLES[2] / LOWPASS_CUTOFF_MULTIPLES[1],
                Box::new(move |c| sensor_structure(&SensorFilter { cutoff_hz: c, ..f })),
            )
        } else if let Some(zy) = s.hysteresis.and_then(|l| l.one_parameter_yield_m()) {
            (
                zy,
                HYSTERESIS_YIELD_FRACTIONS[2] / HYSTERESIS_YIELD_FRACTIONS[1],
                Box::new(|y| hysteresis_structure(HysteresisLaw::yield_law(y), false)),
            )
        } else {
            return best;
        };
    let infallible = golden_section_ln(value, spacing.ln(), |u| {
        let c = evaluate(build(u.exp()));
        Ok::<_, std::convert::Infallible>((c.as_ref().map_or(f64::INFINITY, |c| c.cv_percent), c))
    });
    let Ok(last) = infallible;
    let mut winner = best;
    for (k, c) in last {
        if let Some(c) = c
            && k < winner.cv_percent
        {
            winner = c;
        }
    }
    winner
}
