//! Two effects at once: the second effect searched on what the first leaves (greedy forward
//! selection). Candidates are fitted one at a time, so with two effects present the
//! runner-up alone is the best alternative to the top one (a neighbour of it: cubic against
//! quadratic stiffness, free play), not the second effect. Here every other candidate effect is
//! fitted jointly with the top one, its searched parameter (free-play gap, Stribeck velocity,
//! hysteresis yield) chosen again by cross-validation of the joint fit on the sine steps, and
//! the joint model scored on the held-out records like a single candidate. The best pair by
//! that score is the one the verdict weighs ([`super::findings::pair_explains`]) and whose
//! second member is ranked second when the pair beats the top one alone clearly
//! ([`second_stands_out`]).

use super::cycles::StepCycle;
use super::effects::{Effect, Structure, Transform, structures};
use super::fit::{cross_validated_percent, fit};
use super::score::{HeldOut, penalised};
use super::search::{PhasorSearch, cycles_for, physical};
use super::{DiagnoseError, PairResult, heldout_all, mean_nmse, parameter_values};
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::record::Record;

/// What the pair search needs of the diagnosis.
pub struct PairContext<'a> {
    pub setup: &'a Setup,
    pub baseline: &'a Model,
    pub analyses: &'a [HarmonicAnalysis],
    pub search: &'a PhasorSearch,
    pub mass_kg: f64,
    pub heldout: &'a [&'a Record],
    pub n_eff: f64,
}

/// The families whose searched parameter is searched again jointly with the top effect: the
/// value that fits alone may be the one that mimics the top effect's share too. (The sensor
/// member, the exciter delay and the mass factor keep their single search: each costs a new
/// rebuild of the cycles per value.)
const RESEARCHED: [Effect; 3] = [
    Effect::StribeckFriction,
    Effect::FreePlay,
    Effect::Hysteresis,
];

/// The sine steps' cycles under a transform: the search's own for the identity, else rebuilt
/// once per transform (a top effect's joint fits and their scoring share its transform, so the
/// rebuild is done once, not per joint fit).
struct Cycles<'a> {
    ctx: &'a PairContext<'a>,
    rebuilt: Option<(Transform, Vec<StepCycle>)>,
}

impl Cycles<'_> {
    fn under(&mut self, t: &Transform) -> Result<&[StepCycle], DiagnoseError> {
        if *t == Transform::default() {
            return Ok(&self.ctx.search.cycles);
        }
        if self.rebuilt.as_ref().is_none_or(|(r, _)| r != t) {
            self.rebuilt = Some((*t, cycles_for(self.ctx.setup, self.ctx.analyses, t)?));
        }
        Ok(self.rebuilt.as_ref().map_or(&[][..], |(_, c)| c.as_slice()))
    }
}

/// The top structure combined with each member of `second`'s family worth trying, best by
/// cross-validated force error of the joint fit on the sine steps (in-sample residual with
/// fewer than 3 steps); None when no joint fit is physical.
fn joint_structure(
    ctx: &PairContext,
    cycles: &mut Cycles,
    top: &Structure,
    second: Effect,
    alone: &Structure,
) -> Result<Option<Structure>, DiagnoseError> {
    let options = if RESEARCHED.contains(&second) {
        structures(ctx.baseline, second, &ctx.search.scales)
    } else {
        vec![alone.clone()]
    };
    let mut best: Option<(f64, Structure)> = None;
    for o in options {
        let s = top.combine(&o);
        let cycles = cycles.under(&s.transform)?;
        let Ok(f) = fit(ctx.baseline, &s, cycles, None) else {
            continue;
        };
        if !physical(&f) {
            continue;
        }
        let key = cross_validated_percent(ctx.baseline, &s, cycles).unwrap_or(f.residual_percent);
        if best.as_ref().is_none_or(|(b, _)| key < *b) {
            best = Some((key, s));
        }
    }
    Ok(best.map(|(_, s)| s))
}

/// The joint model of `s` fitted on every step and scored on the held-out records; None when
/// the fit fails, is not physical or cannot be simulated.
fn scored(
    ctx: &PairContext,
    cycles: &mut Cycles,
    s: &Structure,
) -> Result<Option<(PairResult, Vec<HeldOut>)>, DiagnoseError> {
    let Ok(f) = fit(ctx.baseline, s, cycles.under(&s.transform)?, None) else {
        return Ok(None);
    };
    if !physical(&f) {
        return Ok(None);
    }
    let Ok(h) = heldout_all(&f, ctx.mass_kg, ctx.heldout) else {
        return Ok(None);
    };
    let after = mean_nmse(&h);
    let [first, second] = [s.effects[0], s.effects[s.effects.len() - 1]];
    Ok(Some((
        PairResult {
            effects: [first, second],
            gap_after_percent: after,
            score_percent: penalised(after, s.extra_parameters, ctx.n_eff),
            added_parameters: parameter_values(f.added_parameters()),
        },
        h,
    )))
}

/// The best pair with the top candidate: `top` (its structure) fitted jointly with each effect
/// of `others` (each with its structure alone), best by penalised held-out score.
pub fn forward_pair(
    ctx: &PairContext,
    top: &Structure,
    others: &[(Effect, &Structure)],
) -> Result<Option<PairResult>, DiagnoseError> {
    let mut best: Option<PairResult> = None;
    let mut cycles = Cycles { ctx, rebuilt: None };
    for (effect, alone) in others {
        let Some(s) = joint_structure(ctx, &mut cycles, top, *effect, alone)? else {
            continue;
        };
        let Some((p, _)) = scored(ctx, &mut cycles, &s)? else {
            continue;
        };
        if best
            .as_ref()
            .is_none_or(|b| p.score_percent < b.score_percent)
        {
            best = Some(p);
        }
    }
    Ok(best)
}

/// Whether the pair's second effect removes, next to the first, a share of the gap that
/// stands out as any candidate's must ([`super::significant`]: beyond the floor, a tenth of the
/// gap and 0.2 %-points), with a better penalised score than the first alone.
pub fn second_stands_out(
    gap_before: f64,
    floor: f64,
    single_after: f64,
    single_score: f64,
    pair: &PairResult,
) -> bool {
    pair.score_percent < single_score
        && single_after - pair.gap_after_percent > floor.max(0.1 * gap_before).max(0.2)
}
