//! The partners the pair search tries beside the top candidate that no ranked candidate stands
//! for: an effect whose fit alone is not physical (free play whose spring comes out negative on
//! data a sensor filter distorts) or whose fitted model alone cannot be simulated (quadratic
//! damping with a negative coefficient, unstable). Fitted jointly with the top one (under its
//! channel transform) the same effect may be what the data show: seed 1 cases 166 and 192
//! (a sensor filter with quadratic damping) and 194 (with free play) never tried the planted
//! partner.

use super::effects::{Effect, Structure, baseline_has, structures};
use super::pairs::RESEARCHED;
use super::search::PhasorSearch;
use super::{PairResult, ParameterValue, RankedEffect};
use crate::model::Model;

/// Each effect of `effects` that is not in the baseline and not among `ranked`, with the
/// structure its joint fit starts from: the search's candidate (its searched parameter chosen
/// alone) when it had a physical fit, else the family's first structure when the pair search
/// searches the family again ([`RESEARCHED`]) or it has a single one. Members whose search
/// needs the data alone (the exciter delay from the kinematic identity; a sensor filter, a mass
/// factor, a series spring without a physical fit) are not offered.
pub fn unranked_partners(
    baseline: &Model,
    search: &PhasorSearch,
    effects: &[Effect],
    ranked: &[Effect],
) -> Vec<(Effect, Structure)> {
    effects
        .iter()
        .filter(|e| !baseline_has(baseline, **e) && !ranked.contains(e))
        .filter_map(|&e| {
            let candidate = search
                .candidates
                .iter()
                .filter(|c| c.effect == e)
                .min_by(|a, b| a.step_error_percent().total_cmp(&b.step_error_percent()))
                .map(|c| c.structure.clone());
            candidate
                .or_else(|| {
                    let mut options = structures(baseline, e, &search.scales);
                    let searched_again = RESEARCHED.contains(&e) && !options.is_empty();
                    (searched_again || options.len() == 1).then(|| options.swap_remove(0))
                })
                .map(|s| (e, s))
        })
        .collect()
}

/// The ranked entry of a pair's second member that no ranked candidate stands for (one of
/// [`unranked_partners`]): alone it has no held-out figures, so it carries the pair's (held-out
/// NMSE, score, step error) with `fitted_with` naming the top effect, and the parameters the
/// pair adds beside the top one's alone. Not significant by itself.
pub fn joint_only_entry(pair: &PairResult, top: &RankedEffect, gap_before: f64) -> RankedEffect {
    let effect = pair.effects[1];
    let added_parameters: Vec<ParameterValue> = pair
        .added_parameters
        .iter()
        .filter(|p| !top.added_parameters.iter().any(|t| t.name == p.name))
        .cloned()
        .collect();
    RankedEffect {
        effect,
        member: None,
        fitted_with: Some(top.effect),
        gap_after_percent: pair.gap_after_percent,
        shrink_percent: gap_before - pair.gap_after_percent,
        score_percent: pair.score_percent,
        phasor_cv_percent: pair.phasor_cv_percent,
        output_error_misfit: None,
        extra_parameters: added_parameters.len(),
        added_parameters,
        refitted_baseline: pair.refitted_baseline.clone(),
        significant: false,
        added: effect.added().into(),
        signature: effect.signature().into(),
    }
}
