//! Candidates scored where they act: friction acts most where the phasor fits look away (the
//! stick and slow-slip phase below [`super::fit::REVERSAL_BAND`] of the peak speed, left out
//! because the force is set-valued there), so a friction candidate's phasor fit can miss its
//! size (a Stribeck excess of 5 N fitted for 14 N planted) and its held-out prediction falls
//! short. The friction candidates near the top are refitted by output error on the sine steps
//! (the exact stick-slip simulation against every settled sample,
//! [`crate::identify::RigOutputError::compare`]), starting from their phasor fit, and scored on
//! the held-out records with the refitted parameters, which rank them; the output-error misfit of
//! each refit and of the baseline is reported beside it.
//!
//! When: only if the best candidate by the phasor fits does not already explain the gap and the
//! gap is large enough for a candidate to be significant ([`worth_refitting`]): each refit runs
//! tens of simulations of the whole run, and a ranking already settled by the phasor fits would
//! not change.
//!
//! Which candidates: those whose element the output-error simulator runs exactly and whose
//! signature lies in the stick or slow-slip phase, [`OUTPUT_ERROR_EFFECTS`]. Free play (a
//! dead-zone spring, a smooth term) would run exactly too, but it acts at small displacement,
//! where the speed is highest and the phasor fit looks; hysteresis (a Bouc-Wen state), the
//! exciter delay, the sensor low-pass and the mass error are not elements the output-error
//! simulator runs.

use super::effects::{Effect, Structure};
use super::findings::{explains, significant};
use super::fit::Fitted;
use super::score::{HeldOut, penalised};
use super::{RankedEffect, heldout_all, mean_nmse, member_of, parameter_values, search};
use crate::identify::{IdentifyError, RigDrive, RigMisfit, RigOutputError};
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::record::Record;

/// The families refitted by output error: the friction variants, whose stick and slow-slip
/// phase the phasor fits leave out.
pub const OUTPUT_ERROR_EFFECTS: [Effect; 2] = [Effect::CoulombFriction, Effect::StribeckFriction];

/// Only candidates among this many of the top of the held-out ranking are refitted (each refit
/// runs tens of simulations of the sine steps). Four since `drift` and `series_compliance`
/// joined the library: each adds a parameter that buys a little on any gap, enough to push an
/// underestimated Stribeck friction (phasor fit) from third to fourth place.
pub const OUTPUT_ERROR_TOP: usize = 4;

/// Whether a candidate of `effect` is refitted by output error (its family; the top is the
/// caller's).
pub fn refitted(effect: Effect) -> bool {
    OUTPUT_ERROR_EFFECTS.contains(&effect)
}

/// The sine steps of a rig run, ready for output-error fits of the baseline and candidates.
pub struct SineSteps<'a> {
    pub mass_kg: f64,
    pub records: &'a [Record],
    pub analyses: &'a [HarmonicAnalysis],
}

/// The model baseline + structure.
fn model_of(baseline: &Model, s: &Structure) -> Model {
    let name = format!(
        "{}+{}",
        baseline.name,
        s.effects
            .iter()
            .map(|e| e.name())
            .collect::<Vec<_>>()
            .join("+")
    );
    baseline.with_terms(name, &s.terms)
}

/// Fits baseline + `fitted`'s structure by output error from `fitted`'s parameters; the
/// fitted parameters in `fitted`'s form (least-squares std dropped: the phasor fit's no longer
/// apply) and the misfit. Structures with a hysteresis state or a channel transform are not
/// run by the output-error simulator (an error).
pub fn refit(
    steps: &SineSteps,
    baseline: &Model,
    fitted: &Fitted,
) -> Result<(Fitted, RigMisfit), IdentifyError> {
    let s = &fitted.structure;
    if s.hysteresis.is_some() || s.transform != Default::default() {
        return Err(IdentifyError::Step {
            step: 0,
            problem: "output error runs element terms only".into(),
        });
    }
    let model = model_of(baseline, s);
    let misfit = misfit_from(steps, &model, &fitted.theta)?;
    let mut out = fitted.clone();
    out.theta.clone_from(&misfit.theta);
    out.std = vec![f64::NAN; out.theta.len()];
    Ok((out, misfit))
}

/// The output-error misfit of `model` fitted from `theta`.
pub fn misfit_from(
    steps: &SineSteps,
    model: &Model,
    theta: &[f64],
) -> Result<RigMisfit, IdentifyError> {
    RigOutputError::new(
        model,
        steps.mass_kg,
        steps.records,
        steps.analyses,
        RigDrive::FittedSine,
    )?
    .compare(theta)
}

/// What [`rescore`] needs of the diagnosis so far.
pub(super) struct Rescoring<'a> {
    pub steps: SineSteps<'a>,
    pub baseline: &'a Model,
    pub baseline_theta: &'a [f64],
    pub heldout: &'a [&'a Record],
    pub gap_before: f64,
    pub floor: f64,
    pub n_eff: f64,
    pub baseline_score: f64,
}

/// Whether the ranking could change by refitting: the best candidate by the phasor fits does
/// not explain the gap, and the gap leaves room for a significant candidate (one whose shrink
/// exceeds the floor, from an end about half the floor, where a true model ends at this noise).
pub(super) fn worth_refitting(best: Option<&RankedEffect>, gap_before: f64, floor: f64) -> bool {
    let room = gap_before - 0.5 * floor;
    let settled =
        best.is_some_and(|b| explains(gap_before, floor, b.gap_after_percent, b.significant));
    !settled && room > floor.max(0.1 * gap_before).max(0.2)
}

/// Refits the candidates of [`OUTPUT_ERROR_EFFECTS`] among the [`OUTPUT_ERROR_TOP`] of `order`
/// (best first) by output error when [`worth_refitting`], and rescores each on the held-out
/// records with its refitted parameters (`ranked` and `fits` updated in place; a refit that
/// fails or is not physical keeps the phasor fit, with a note). Returns the baseline's
/// output-error misfit when any candidate was refitted.
pub(super) fn rescore(
    c: &Rescoring,
    ranked: &mut [RankedEffect],
    fits: &mut [(Fitted, Vec<HeldOut>)],
    order: &[usize],
    notes: &mut Vec<String>,
) -> Option<f64> {
    if !worth_refitting(order.first().map(|&i| &ranked[i]), c.gap_before, c.floor) {
        return None;
    }
    let top: Vec<usize> = order
        .iter()
        .take(OUTPUT_ERROR_TOP)
        .copied()
        .filter(|&i| refitted(ranked[i].effect))
        .collect();
    if top.is_empty() {
        return None;
    }
    let base = match misfit_from(&c.steps, c.baseline, c.baseline_theta) {
        Ok(m) => m.misfit_rms,
        Err(e) => {
            notes.push(format!("output error not run: {e}"));
            return None;
        }
    };
    for i in top {
        let r = &mut ranked[i];
        let refit = refit(&c.steps, c.baseline, &fits[i].0)
            .map_err(|e| e.to_string())
            .and_then(|(f, m)| {
                let h = heldout_all(&f, c.steps.mass_kg, c.heldout).map_err(|e| e.to_string())?;
                Ok((f, m, h))
            });
        match refit {
            Ok((f, m, h)) if search::physical(&f) => {
                let after = mean_nmse(&h);
                let score = penalised(after, r.extra_parameters, c.n_eff);
                r.gap_after_percent = after;
                r.shrink_percent = c.gap_before - after;
                r.score_percent = score;
                r.significant = significant(c.gap_before, c.floor, after, score, c.baseline_score);
                r.added_parameters = parameter_values(f.added_parameters());
                // The member as refitted (a refitted family is never drift, whose description
                // alone needs the run's dissipation).
                r.member = member_of(&f, None);
                r.output_error_misfit = Some(m.misfit_rms);
                fits[i] = (f, h);
            }
            Ok(_) => notes.push(format!(
                "{}: output-error refit not physical; phasor fit kept",
                r.effect.name()
            )),
            Err(e) => notes.push(format!(
                "{}: output-error refit failed ({e}); phasor fit kept",
                r.effect.name()
            )),
        }
    }
    Some(base)
}
