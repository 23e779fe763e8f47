//! The scores over a set of cases: top-1 hit rates, false alarms, out-of-library names,
//! predicted against true shrink, the confusable pairs and the confusion matrix.

use super::*;

/// A fraction with its counts.
#[derive(Debug, Clone, Serialize)]
pub struct Rate {
    pub hits: usize,
    pub of: usize,
    pub percent: f64,
}

fn rate(hits: usize, of: usize) -> Rate {
    Rate {
        hits,
        of,
        percent: if of == 0 {
            f64::NAN
        } else {
            100.0 * hits as f64 / of as f64
        },
    }
}

/// Held-out NMSE an effect must cause alone to count towards the top-1 target [%]: the
/// baseline's held-out NMSE minus the true model's on the same noisy records
/// ([`CaseResult::effect_gap_percent`]), so the noise, which no effect causes, is not counted.
pub const QUALIFYING_GAP_PERCENT: f64 = 2.0;

/// A baseline whose held-out NMSE is above this [%] predicts the held-out records worse than
/// predicting zero: its simulation diverges or nearly so (a strong sensor filter can make the
/// fitted baseline unstable), and the size of its gap says nothing about an effect's. Such
/// cases are counted apart from the shrink statistics.
pub const DIVERGED_BASELINE_PERCENT: f64 = forcemap_math::diagnose::findings::NO_PREDICTION_PERCENT;

/// The effect pairs that look alike and must be told apart (each shows something the other
/// cannot: see [`Effect::signature`]).
pub const CONFUSABLE_PAIRS: [[Effect; 2]; 6] = [
    [Effect::ExciterDelay, Effect::MassError],
    [Effect::SensorLowpass, Effect::ExciterDelay],
    [Effect::CoulombFriction, Effect::Hysteresis],
    [Effect::CoulombFriction, Effect::QuadraticDamping],
    [Effect::AsymmetricDamping, Effect::QuadraticStiffness],
    [Effect::FreePlay, Effect::CubicStiffness],
];

/// How often one effect of a confusable pair was named as the other.
#[derive(Debug, Clone, Serialize)]
pub struct ConfusablePair {
    pub effects: [Effect; 2],
    /// Single-effect cases planting either effect.
    pub cases: usize,
    /// Cases planting the first, named the second.
    pub first_named_second: usize,
    /// Cases planting the second, named the first.
    pub second_named_first: usize,
}

/// The scores of an evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct EvalSummary {
    pub cases: usize,
    pub failed: Vec<String>,
    /// Single effects that alone cause at least 2 % held-out NMSE at the lower SNR, named first.
    pub top1: Rate,
    /// The same at the lower SNR, counting the cases whose baseline gap (noise included) is at
    /// least 2 % instead.
    pub top1_by_baseline_gap: Rate,
    /// The same at every SNR.
    pub top1_all_snr: Rate,
    /// No-effect cases given anything but "adequate".
    pub false_alarms: Rate,
    /// Out-of-library cases given a library name.
    pub out_of_library_named: Rate,
    /// Out-of-library cases whose verdict names a library effect "in part": a name given with
    /// what it leaves, not a confident one, but a lead that is not there all the same.
    pub out_of_library_named_in_part: Rate,
    /// Single effects with a gap below 2 %: how many were still named right, called adequate,
    /// or given another answer (a wrong name or "unexplained").
    pub below_threshold_named_right: Rate,
    pub below_threshold_adequate: Rate,
    pub below_threshold_wrong: Rate,
    /// Two-effect cases whose top effect is one of the two.
    pub pairs_one_named: Rate,
    /// Two-effect cases whose top two are the two effects: the pair the verdict names, or else
    /// the two best-ranked candidates alone.
    pub pairs_both_top_two: Rate,
    /// The same over the wide pairs whose members each cause at least 2 % alone
    /// ([`CaseResult::member_gap_percent`]): a member too small to be found alone is not asked
    /// for, as a single effect below 2 % is not.
    pub pairs_qualifying_both_top_two: Rate,
    /// Two-effect cases whose verdict names both ("explained by A together with B").
    pub pairs_both_named: Rate,
    /// Single-effect cases (library or new name) whose verdict names a pair: a second effect
    /// claimed that is not there.
    pub singles_named_as_pair: Rate,
    /// Explained qualifying single effects whose predicted shrink is within 20 % of the true
    /// model's.
    pub shrink_within_20_percent: Rate,
    /// Mean and median |predicted shrink - true shrink| over the explained qualifying
    /// single-effect cases whose baseline did not diverge [%-points], and the mean true shrink
    /// for scale.
    pub shrink_mean_abs_error_percent: f64,
    pub shrink_median_abs_error_percent: f64,
    pub shrink_mean_true_percent: f64,
    /// Explained qualifying single-effect cases left out of the shrink statistics because the
    /// baseline's held-out NMSE is above [`DIVERGED_BASELINE_PERCENT`].
    pub shrink_baseline_diverged: usize,
    /// Rows: planted; columns: named ("adequate", "unexplained" or an effect); counts.
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// The pairs of effects most easily confused, over single-effect cases at every SNR.
    pub confusable_pairs: Vec<ConfusablePair>,
    pub lower_snr_db: f64,
}

/// Scores the results.
pub fn summarise(results: &[Result<CaseResult, String>], lower_snr_db: f64) -> EvalSummary {
    let ok: Vec<&CaseResult> = results.iter().filter_map(|r| r.as_ref().ok()).collect();
    let failed = results
        .iter()
        .filter_map(|r| r.as_ref().err().cloned())
        .collect();
    let single = |r: &&CaseResult| r.case.planted.is_single();
    let qualifying: Vec<&&CaseResult> = ok
        .iter()
        .filter(|r| single(r) && r.effect_gap_percent >= QUALIFYING_GAP_PERCENT)
        .collect();
    let hit = |r: &&&CaseResult| r.named == r.label;
    let by_baseline_gap: Vec<&&CaseResult> = ok
        .iter()
        .filter(|r| {
            single(r)
                && r.gap_before_percent >= QUALIFYING_GAP_PERCENT
                && (r.case.snr_db - lower_snr_db).abs() < 1e-9
        })
        .collect();
    let low: Vec<&&&CaseResult> = qualifying
        .iter()
        .filter(|r| (r.case.snr_db - lower_snr_db).abs() < 1e-9)
        .collect();
    let none: Vec<&&CaseResult> = ok
        .iter()
        .filter(|r| matches!(r.case.planted, Planted::None))
        .collect();
    let ool: Vec<&&CaseResult> = ok
        .iter()
        .filter(|r| r.case.planted.is_out_of_library())
        .collect();
    let below: Vec<&&CaseResult> = ok
        .iter()
        .filter(|r| single(r) && r.effect_gap_percent < QUALIFYING_GAP_PERCENT)
        .collect();
    let pairs: Vec<&&CaseResult> = ok
        .iter()
        .filter(|r| r.case.planted.pair_names().is_some())
        .collect();
    let qualifying_pairs: Vec<&&CaseResult> = pairs
        .iter()
        .copied()
        .filter(|r| {
            r.member_gap_percent
                .is_some_and(|g| g.iter().all(|&x| x >= QUALIFYING_GAP_PERCENT))
        })
        .collect();
    let explained: Vec<&&&CaseResult> = qualifying
        .iter()
        .filter(|r| r.verdict == Verdict::Explained)
        .collect();
    let (mut errors, mut tru, mut within, mut diverged) = (Vec::new(), 0.0, 0, 0);
    for r in &explained {
        let predicted = r.gap_before_percent - r.gap_after_percent;
        let truth = r.gap_before_percent - r.truth_nmse_percent;
        if (predicted - truth).abs() <= 0.2 * truth.abs() {
            within += 1;
        }
        if r.gap_before_percent > DIVERGED_BASELINE_PERCENT {
            diverged += 1;
            continue;
        }
        errors.push((predicted - truth).abs());
        tru += truth;
    }
    let ne = errors.len().max(1) as f64;
    // A fold from +0.0: the sum of no terms is -0.0 and would print as "-0.00".
    let err: f64 = errors.iter().fold(0.0, |a, e| a + e);
    errors.sort_by(f64::total_cmp);
    let median_err = match errors.len() {
        0 => 0.0,
        n if n % 2 == 1 => errors[n / 2],
        n => 0.5 * (errors[n / 2 - 1] + errors[n / 2]),
    };
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    for r in &ok {
        if r.case.planted.pair_names().is_some() {
            continue;
        }
        let row = if single(r) && r.effect_gap_percent < QUALIFYING_GAP_PERCENT {
            format!("{} (<2 %)", r.label)
        } else {
            r.label.clone()
        };
        *confusion
            .entry(row)
            .or_default()
            .entry(r.named.clone())
            .or_default() += 1;
    }
    EvalSummary {
        cases: results.len(),
        failed,
        top1: rate(low.iter().filter(|r| hit(r)).count(), low.len()),
        top1_by_baseline_gap: rate(
            by_baseline_gap
                .iter()
                .filter(|r| r.named == r.label)
                .count(),
            by_baseline_gap.len(),
        ),
        top1_all_snr: rate(
            qualifying.iter().filter(|r| hit(r)).count(),
            qualifying.len(),
        ),
        false_alarms: rate(
            none.iter()
                .filter(|r| r.verdict != Verdict::Adequate)
                .count(),
            none.len(),
        ),
        out_of_library_named: rate(
            ool.iter()
                .filter(|r| r.verdict == Verdict::Explained)
                .count(),
            ool.len(),
        ),
        out_of_library_named_in_part: rate(
            ool.iter()
                .filter(|r| r.verdict == Verdict::ExplainedInPart)
                .count(),
            ool.len(),
        ),
        below_threshold_named_right: rate(
            below.iter().filter(|r| r.named == r.label).count(),
            below.len(),
        ),
        below_threshold_wrong: rate(
            below
                .iter()
                .filter(|r| r.verdict != Verdict::Adequate && r.named != r.label)
                .count(),
            below.len(),
        ),
        below_threshold_adequate: rate(
            below
                .iter()
                .filter(|r| r.verdict == Verdict::Adequate)
                .count(),
            below.len(),
        ),
        pairs_one_named: rate(
            pairs
                .iter()
                .filter(|r| {
                    r.case
                        .planted
                        .pair_names()
                        .is_some_and(|n| n.contains(&r.named.as_str()))
                })
                .count(),
            pairs.len(),
        ),
        pairs_both_top_two: rate(
            pairs.iter().filter(|r| both_in_top_two(r)).count(),
            pairs.len(),
        ),
        pairs_qualifying_both_top_two: rate(
            qualifying_pairs
                .iter()
                .filter(|r| both_in_top_two(r))
                .count(),
            qualifying_pairs.len(),
        ),
        pairs_both_named: rate(
            pairs
                .iter()
                .filter(|r| {
                    r.second_named.as_deref().is_some_and(|second| {
                        r.case
                            .planted
                            .pair_names()
                            .is_some_and(|n| n.contains(&r.named.as_str()) && n.contains(&second))
                    })
                })
                .count(),
            pairs.len(),
        ),
        singles_named_as_pair: rate(
            ok.iter()
                .filter(|r| single(r) && r.second_named.is_some())
                .count(),
            ok.iter().filter(|r| single(r)).count(),
        ),
        shrink_within_20_percent: rate(within, explained.len()),
        shrink_mean_abs_error_percent: err / ne,
        shrink_median_abs_error_percent: median_err,
        shrink_mean_true_percent: tru / ne,
        shrink_baseline_diverged: diverged,
        confusion,
        confusable_pairs: CONFUSABLE_PAIRS
            .iter()
            .map(|&[a, b]| {
                let planted = |e: Effect| {
                    move |r: &&&CaseResult| r.case.planted.is_single() && r.label == e.name()
                };
                let count = |e: Effect, named: Effect| {
                    ok.iter()
                        .filter(planted(e))
                        .filter(|r| r.named == named.name())
                        .count()
                };
                ConfusablePair {
                    effects: [a, b],
                    cases: ok.iter().filter(planted(a)).count()
                        + ok.iter().filter(planted(b)).count(),
                    first_named_second: count(a, b),
                    second_named_first: count(b, a),
                }
            })
            .collect(),
        lower_snr_db,
    }
}

/// Whether a pair case's top two are its two planted effects: the two the verdict names, or
/// else the two best-ranked alone.
fn both_in_top_two(r: &CaseResult) -> bool {
    let top: Vec<&str> = match &r.second_named {
        Some(second) => vec![r.named.as_str(), second.as_str()],
        None => r.ranked.iter().take(2).map(|x| x.effect.as_str()).collect(),
    };
    r.case
        .planted
        .pair_names()
        .is_some_and(|n| n.iter().all(|e| top.contains(e)))
}
