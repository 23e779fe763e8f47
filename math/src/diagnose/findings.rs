//! What every diagnosis concludes, whichever evidence it weighs: the verdict, the rule it
//! follows, and the sentence a user reads. The stepped-sine rig diagnosis ([`super::diagnose`]),
//! the live phasor diagnosis ([`super::PhasorDiagnosis`]) and the time-domain axis diagnosis
//! ([`super::time_domain`]) differ in their evidence ([`Evidence`]: what the gap measures, how
//! candidates are ranked, when a shrink counts, what the floor is) and share everything else
//! here: one [`Findings`] type, one verdict rule ([`verdict`]), one description of it
//! ([`Evidence::rule`]) and one wording ([`Findings::headline`], [`Findings::status`]).

use serde::Serialize;

use super::effects::Effect;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    Adequate,
    Explained,
    /// The top candidate removes a significant share of the gap but leaves more than half of
    /// its excess over the floor: a real effect, and something else besides.
    ExplainedInPart,
    Unexplained,
}

impl Verdict {
    pub fn name(self) -> &'static str {
        match self {
            Verdict::Adequate => "adequate",
            Verdict::Explained => "explained",
            Verdict::ExplainedInPart => "explained_in_part",
            Verdict::Unexplained => "unexplained",
        }
    }
}

/// The evidence a diagnosis weighs: what its gap measures and how it judges candidates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Evidence {
    /// Stepped-sine rig: fit on the sine steps, the NMSE of the mass acceleration simulated on
    /// held-out records.
    HeldOutNmse,
    /// Live phasors: the element-force error cross-validated by leaving each step out.
    CrossValidatedForceError,
    /// Force-driven axis record: the relative force error on a validation record.
    ValidationForceError,
}

/// The part of the rule every evidence shares.
const SHARED_RULE: &str = "explained: the top candidate is significant and gap_after - floor <= 0.5 (gap_before - floor), explained by two: the best pair fitted together (the top candidate with the second effect searched on what it leaves) explains the gap, scores below the top candidate and leaves less than it by more than max(floor, 10 % of the gap, 0.2 %-points), and either the top candidate alone does not explain the gap or the pair leaves at most half of the top candidate's excess over the floor; a candidate or pair that leaves 100 % or more (no better than predicting zero) explains nothing; explained in part: gap_before > max(3 floor, 1 %), the top candidate is significant and gap_after - floor <= 0.75 (gap_before - floor), but not explained; unexplained: gap_before > max(3 floor, 1 %) and neither; adequate: otherwise";

/// A top candidate that removes at least this share of the gap's excess over the floor (but
/// not the half that explains it) explains the gap in part.
pub const IN_PART_SHARE: f64 = 0.25;

/// A relative error at or above this [%] predicts no better than zero does (a fitted model
/// whose simulation diverges on the held-out records lands here): a candidate that leaves this
/// much explains nothing, however much more the baseline left.
pub const NO_PREDICTION_PERCENT: f64 = 100.0;

impl Evidence {
    /// What the gap figures measure, for a sentence ("held-out NMSE").
    pub fn measure(self) -> &'static str {
        match self {
            Evidence::HeldOutNmse => "held-out NMSE of the mass acceleration",
            Evidence::CrossValidatedForceError => "cross-validated element-force error",
            Evidence::ValidationForceError => "relative force error on the validation record",
        }
    }

    fn ranking(self) -> &'static str {
        match self {
            Evidence::HeldOutNmse => {
                "penalised held-out score; candidates within the best's excess over the floor are tied, and one that explains the gap by itself goes first if its cross-validated force error on the sine steps is below 0.9 times the best's (below 0.5 times: whatever the held-out scores)"
            }
            Evidence::CrossValidatedForceError => {
                "penalised cross-validated score; an exciter delay that stands out of its noise in the kinematic identity (4 standard deviations and 0.5 ms) is named when no force candidate explains the gap"
            }
            Evidence::ValidationForceError => "penalised validation score",
        }
    }

    fn significance(self) -> &'static str {
        match self {
            Evidence::HeldOutNmse | Evidence::CrossValidatedForceError => {
                "score below the baseline's and shrink > max(floor, 10 % of the gap, 0.2 %-points)"
            }
            Evidence::ValidationForceError => {
                "score below the baseline's, shrink > max(10 % of the gap, 0.2 %-points) and consistent over 1 s blocks of the validation record (t >= 3)"
            }
        }
    }

    fn floor(self) -> &'static str {
        match self {
            Evidence::HeldOutNmse => "the measurement noise's share of the held-out NMSE",
            Evidence::CrossValidatedForceError => "what the force noise alone leaves",
            Evidence::ValidationForceError => {
                "the smallest validation error of the flexible memoryless laws, the baseline and the candidates (see floor.what)"
            }
        }
    }

    /// The verdict rule as applied with this evidence, for the output.
    pub fn rule(self) -> String {
        format!(
            "gap: {}; ranking: {}; significant: {}; {SHARED_RULE}; floor: {}",
            self.measure(),
            self.ranking(),
            self.significance(),
            self.floor()
        )
    }
}

/// The smallest drop of the held-out gap (percentage points) that the noise does not explain:
/// beyond the floor, a tenth of the gap and 0.2 %-points. One rule for a candidate against the
/// baseline, a pair against its single, and members of a family against each other.
pub fn least_significant_drop(gap_before: f64, floor: f64) -> f64 {
    floor.max(0.1 * gap_before).max(0.2)
}

/// Whether a candidate's shrink is beyond what the noise explains (the rig's and the live
/// diagnosis's significance; the axis has its own, see [`Evidence::ValidationForceError`]).
pub fn significant(
    gap_before: f64,
    floor: f64,
    gap_after: f64,
    score: f64,
    baseline_score: f64,
) -> bool {
    score < baseline_score && gap_before - gap_after > least_significant_drop(gap_before, floor)
}

/// Whether a candidate leaving `gap_after` would explain the gap: significant, and at most half
/// of the excess over the floor left.
pub fn explains(gap_before: f64, floor: f64, gap_after: f64, significant: bool) -> bool {
    significant
        && gap_after - floor <= 0.5 * (gap_before - floor)
        && gap_after < NO_PREDICTION_PERCENT
}

/// The verdict from the gap, the floor and the top candidate (gap_after, significant).
pub fn verdict(gap_before: f64, floor: f64, top: Option<(f64, bool)>) -> Verdict {
    if let Some((after, significant)) = top
        && explains(gap_before, floor, after, significant)
    {
        return Verdict::Explained;
    }
    if gap_before <= (3.0 * floor).max(1.0) {
        return Verdict::Adequate;
    }
    match top {
        Some((after, true))
            if gap_before - after >= IN_PART_SHARE * (gap_before - floor)
                && after < NO_PREDICTION_PERCENT =>
        {
            Verdict::ExplainedInPart
        }
        _ => Verdict::Unexplained,
    }
}

/// Two candidates fitted together, as the verdict sees them.
#[derive(Debug, Clone, Copy)]
pub struct PairEvidence {
    /// The better-ranked alone first.
    pub effects: [Effect; 2],
    pub gap_after_percent: f64,
    pub score_percent: f64,
    /// Significant against the baseline ([`significant`]).
    pub significant: bool,
    /// The score of the best single candidate.
    pub single_score_percent: f64,
}

/// Whether a pair explains a gap that the best single candidate (leaving `single_after`) does
/// not: the pair explains it ([`explains`]), scores better than the single with its extra
/// parameters, and its second effect removes a significant share of its own (beyond the floor,
/// a tenth of the gap and 0.2 %-points, as [`significant`] asks of any candidate).
pub fn pair_explains(gap_before: f64, floor: f64, single_after: f64, pair: &PairEvidence) -> bool {
    explains(gap_before, floor, pair.gap_after_percent, pair.significant)
        && pair.score_percent < pair.single_score_percent
        && single_after - pair.gap_after_percent > least_significant_drop(gap_before, floor)
}

/// Whether the pair is named over the single candidate whose `single_verdict` left
/// `single_after`: the pair explains the gap ([`pair_explains`]) and either the single does not,
/// or the pair leaves at most half of the single's excess over the floor (the second effect
/// explains what the first leaves, as the first explains the gap).
pub fn pair_named(
    single_verdict: Verdict,
    gap_before: f64,
    floor: f64,
    single_after: f64,
    pair: &PairEvidence,
) -> bool {
    pair_explains(gap_before, floor, single_after, pair)
        && (single_verdict != Verdict::Explained
            || pair.gap_after_percent - floor <= 0.5 * (single_after - floor))
}

/// The top-ranked candidate as the verdict sees it.
#[derive(Debug, Clone, Copy)]
pub struct TopCandidate {
    pub effect: Effect,
    pub gap_after_percent: f64,
    pub significant: bool,
}

/// What a diagnosis concludes.
#[derive(Debug, Clone, Serialize)]
pub struct Findings {
    pub verdict: Verdict,
    /// The effect that explains the gap, or part of it (only when explained, or explained in
    /// part).
    pub top_effect: Option<Effect>,
    /// The second effect when the gap is explained by two effects fitted together and by no
    /// one alone ([`Findings::explained_by_pair`]); `top_effect` is then the first.
    pub second_effect: Option<Effect>,
    /// The family member `top_effect` stands for and its fitted shape, for a family (see
    /// [`super::RankedEffect::member`]).
    pub top_member: Option<String>,
    /// The best-ranked candidate, explained or not.
    pub best_candidate: Option<Effect>,
    pub gap_before_percent: f64,
    /// The gap with the best candidate (the baseline's when there is none).
    pub gap_after_percent: f64,
    /// What would be left with nothing more to explain ([`Evidence::rule`] says what).
    pub floor_percent: f64,
    pub evidence: Evidence,
    pub rule: String,
}

impl Findings {
    /// Applies the verdict rule.
    pub fn decide(
        evidence: Evidence,
        gap_before_percent: f64,
        floor_percent: f64,
        top: Option<TopCandidate>,
    ) -> Findings {
        let verdict = verdict(
            gap_before_percent,
            floor_percent,
            top.map(|t| (t.gap_after_percent, t.significant)),
        );
        Findings {
            verdict,
            top_effect: top
                .filter(|_| matches!(verdict, Verdict::Explained | Verdict::ExplainedInPart))
                .map(|t| t.effect),
            second_effect: None,
            top_member: None,
            best_candidate: top.map(|t| t.effect),
            gap_before_percent,
            gap_after_percent: top.map_or(gap_before_percent, |t| t.gap_after_percent),
            floor_percent,
            evidence,
            rule: evidence.rule(),
        }
    }

    /// Names `effect` as the explanation whatever the gap figures say (the live diagnosis's
    /// exciter delay, seen in the kinematic identity rather than in the force fit).
    pub fn explained_by(mut self, effect: Effect) -> Findings {
        self.verdict = Verdict::Explained;
        self.top_effect = Some(effect);
        self
    }

    /// Names two effects fitted together as the explanation when the pair explains the gap
    /// ([`pair_explains`]) and either the best single candidate does not, or the pair leaves at
    /// most half of the single's excess over the floor (the second effect explains what the
    /// first leaves, as the first explains the gap); otherwise unchanged.
    pub fn explained_by_pair(mut self, pair: &PairEvidence) -> Findings {
        if !pair_named(
            self.verdict,
            self.gap_before_percent,
            self.floor_percent,
            self.gap_after_percent,
            pair,
        ) {
            return self;
        }
        self.verdict = Verdict::Explained;
        if self.top_effect != Some(pair.effects[0]) {
            self.top_member = None;
        }
        self.top_effect = Some(pair.effects[0]);
        self.second_effect = Some(pair.effects[1]);
        self.gap_after_percent = pair.gap_after_percent;
        self
    }

    /// The verdict in one line: "explained by coulomb_friction: 14.80 % -> 0.96 %", with the
    /// family member found after it ("(channel mass_acceleration, 2nd order, 6.1 Hz, ...)").
    pub fn headline(&self) -> String {
        let line = self.headline_alone();
        match (&self.top_member, self.top_effect) {
            (Some(m), Some(_)) => format!("{line} ({m})"),
            _ => line,
        }
    }

    fn headline_alone(&self) -> String {
        let before = percent_text(self.gap_before_percent);
        let after = percent_text(self.gap_after_percent);
        let floor = percent_text(self.floor_percent);
        match (self.verdict, self.top_effect) {
            (Verdict::Explained, Some(e)) if self.second_effect.is_some() => format!(
                "explained by {} together with {}: {before} -> {after}",
                e.name(),
                self.second_effect.map_or("", Effect::name),
            ),
            (Verdict::Explained, Some(e)) => {
                format!("explained by {}: {before} -> {after}", e.name())
            }
            (Verdict::ExplainedInPart, Some(e)) => format!(
                "explained in part by {}: {before} -> {after}, {:.2} %-points left above the floor of {floor}",
                e.name(),
                self.gap_after_percent - self.floor_percent,
            ),
            (v, _) => format!(
                "{} (gap {before}{}, floor {floor}{})",
                v.name(),
                if self.gap_before_percent >= NO_PREDICTION_PERCENT {
                    ": the baseline predicts no better than zero"
                } else {
                    ""
                },
                self.best_candidate.map_or(String::new(), |e| format!(
                    ", best candidate {} leaves {after}",
                    e.name()
                ))
            ),
        }
    }

    /// The verdict as a status line about `baseline` (the diagnoser's /diagnostics message,
    /// the report's heading).
    pub fn status(&self, baseline: &str) -> String {
        let before = percent_text(self.gap_before_percent);
        let after = percent_text(self.gap_after_percent);
        match (self.verdict, self.top_effect) {
            (Verdict::Explained, Some(e)) => format!(
                "baseline '{baseline}' misses {}{}: gap {before} -> {after}",
                e.name(),
                self.second_effect
                    .map_or(String::new(), |s| format!(" and {}", s.name())),
            ),
            (Verdict::ExplainedInPart, Some(e)) => format!(
                "baseline '{baseline}' misses {} and more: gap {before} -> {after} (floor {})",
                e.name(),
                percent_text(self.floor_percent)
            ),
            (Verdict::Adequate, _) => format!("baseline '{baseline}' is adequate"),
            _ => format!("baseline '{baseline}' has a gap of {before} that no candidate explains"),
        }
    }
}

/// A gap for a sentence: two decimals ("14.80 %"), or three significant digits when it is
/// beyond any meaning as a share ("5.19e20 %": a diverged simulation).
pub fn percent_text(percent: f64) -> String {
    if percent.abs() < 1e4 {
        format!("{percent:.2} %")
    } else {
        format!("{percent:.2e} %")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn top(after: f64, significant: bool) -> Option<TopCandidate> {
        Some(TopCandidate {
            effect: Effect::CoulombFriction,
            gap_after_percent: after,
            significant,
        })
    }

    #[test]
    fn a_candidate_that_predicts_no_better_than_zero_explains_nothing() {
        // A baseline whose simulation diverges (5e20 %) and a candidate that diverges less
        // (8e17 %): more than half the excess removed, yet nothing explained.
        let f = Findings::decide(Evidence::HeldOutNmse, 5.2e20, 2.0, top(8.0e17, true));
        assert_eq!(f.verdict, Verdict::Unexplained);
        assert_eq!(f.top_effect, None);
        assert_eq!(
            f.headline(),
            "unexplained (gap 5.20e20 %: the baseline predicts no better than zero, floor 2.00 %, best candidate coulomb_friction leaves 8.00e17 %)"
        );
        // The same baseline with a candidate that predicts: explained.
        let f = Findings::decide(Evidence::HeldOutNmse, 5.2e20, 2.0, top(2.5, true));
        assert_eq!(f.verdict, Verdict::Explained);
        assert_eq!(
            f.headline(),
            "explained by coulomb_friction: 5.20e20 % -> 2.50 %"
        );
        // Leaving 100 % or more cannot be "in part" either.
        let f = Findings::decide(Evidence::HeldOutNmse, 400.0, 1.0, top(250.0, true));
        assert_eq!(f.verdict, Verdict::Unexplained);
        let f = Findings::decide(Evidence::HeldOutNmse, 400.0, 1.0, top(99.0, true));
        assert_eq!(f.verdict, Verdict::Explained);
    }

    #[test]
    fn the_rule_names_the_effect_only_when_it_removes_half_the_excess() {
        // Gap 10 %, floor 1 %: the excess is 9; leaving 5.5 removes exactly half.
        let f = Findings::decide(Evidence::HeldOutNmse, 10.0, 1.0, top(5.5, true));
        assert_eq!(f.verdict, Verdict::Explained);
        assert_eq!(f.top_effect, Some(Effect::CoulombFriction));
        let f = Findings::decide(Evidence::HeldOutNmse, 10.0, 1.0, top(5.6, true));
        assert_eq!(f.verdict, Verdict::ExplainedInPart);
        assert_eq!(f.top_effect, Some(Effect::CoulombFriction));
        assert_eq!(f.gap_after_percent, 5.6);
        // In part down to a quarter of the excess removed (leaving 7.75); less is unexplained.
        let f = Findings::decide(Evidence::HeldOutNmse, 10.0, 1.0, top(7.7, true));
        assert_eq!(f.verdict, Verdict::ExplainedInPart);
        let f = Findings::decide(Evidence::HeldOutNmse, 10.0, 1.0, top(7.8, true));
        assert_eq!(f.verdict, Verdict::Unexplained);
        assert_eq!(f.top_effect, None);
        assert_eq!(f.best_candidate, Some(Effect::CoulombFriction));
        assert_eq!(f.gap_after_percent, 7.8);
        // A partial shrink of a gap the noise and the 1 % allow is no finding.
        let f = Findings::decide(Evidence::HeldOutNmse, 2.9, 1.0, top(2.2, true));
        assert_eq!(f.verdict, Verdict::Adequate);
        // Not significant: never explained.
        let f = Findings::decide(Evidence::HeldOutNmse, 10.0, 1.0, top(1.0, false));
        assert_eq!(f.verdict, Verdict::Unexplained);
        // A gap below max(3 floor, 1 %) is adequate.
        let f = Findings::decide(Evidence::HeldOutNmse, 2.9, 1.0, None);
        assert_eq!(f.verdict, Verdict::Adequate);
        assert_eq!(f.gap_after_percent, 2.9);
        let f = Findings::decide(Evidence::HeldOutNmse, 0.9, 0.1, None);
        assert_eq!(f.verdict, Verdict::Adequate);
    }

    #[test]
    fn a_pair_explains_only_what_no_single_candidate_does() {
        let pair = |after: f64, score: f64| PairEvidence {
            effects: [Effect::QuadraticDamping, Effect::CoulombFriction],
            gap_after_percent: after,
            score_percent: score,
            significant: true,
            single_score_percent: 6.5,
        };
        // Gap 10 %, floor 1 %: the best single leaves 6 % (in part); the pair 2 %.
        let single = Findings::decide(Evidence::HeldOutNmse, 10.0, 1.0, top(6.0, true));
        assert_eq!(single.verdict, Verdict::ExplainedInPart);
        let f = single.clone().explained_by_pair(&pair(2.0, 2.3));
        assert_eq!(f.verdict, Verdict::Explained);
        assert_eq!(f.top_effect, Some(Effect::QuadraticDamping));
        assert_eq!(f.second_effect, Some(Effect::CoulombFriction));
        assert_eq!(f.gap_after_percent, 2.0);
        assert_eq!(
            f.headline(),
            "explained by quadratic_damping together with coulomb_friction: 10.00 % -> 2.00 %"
        );
        // Its penalised score no better than the single's: not the pair.
        let f = single.clone().explained_by_pair(&pair(2.0, 6.6));
        assert_eq!(f.verdict, Verdict::ExplainedInPart);
        // Leaving more than half the excess: not explained by the pair either.
        let f = single.clone().explained_by_pair(&pair(5.6, 5.7));
        assert_eq!(f.second_effect, None);
        // A single candidate that explains the gap keeps it unless the pair leaves at most
        // half of its excess over the floor: with a floor of 0.5 %, 4 % leaves 3.5 above it.
        let alone = Findings::decide(Evidence::HeldOutNmse, 10.0, 0.5, top(4.0, true));
        assert_eq!(alone.verdict, Verdict::Explained);
        // 2.5 %: a significant second shrink (1.5 > 1), but 2.0 left above the floor > 1.75.
        let f = alone.clone().explained_by_pair(&pair(2.5, 2.6));
        assert_eq!((f.second_effect, f.gap_after_percent), (None, 4.0));
        let f = alone.explained_by_pair(&pair(2.0, 2.1));
        assert_eq!(f.second_effect, Some(Effect::CoulombFriction));
        assert_eq!(f.gap_after_percent, 2.0);
    }

    #[test]
    fn significance_needs_the_score_and_a_shrink_beyond_floor_and_tenth() {
        assert!(significant(10.0, 0.5, 8.9, 1.0, 2.0));
        assert!(!significant(10.0, 0.5, 9.1, 1.0, 2.0)); // below 10 % of the gap
        assert!(!significant(10.0, 1.5, 8.9, 1.0, 2.0)); // below the floor
        assert!(!significant(10.0, 0.5, 5.0, 2.0, 2.0)); // score not better
        assert!(!significant(1.0, 0.0, 0.85, 0.5, 1.0)); // below 0.2 %-points
    }

    #[test]
    fn every_rule_shares_the_verdict_and_names_its_measure() {
        for e in [
            Evidence::HeldOutNmse,
            Evidence::CrossValidatedForceError,
            Evidence::ValidationForceError,
        ] {
            let r = e.rule();
            assert!(r.contains(SHARED_RULE), "{r}");
            assert!(r.contains(e.measure()), "{r}");
        }
    }

    #[test]
    fn the_wording_says_what_was_found() {
        let f = Findings::decide(Evidence::HeldOutNmse, 14.8, 0.5, top(0.96, true));
        assert_eq!(
            f.headline(),
            "explained by coulomb_friction: 14.80 % -> 0.96 %"
        );
        assert_eq!(
            f.status("linear"),
            "baseline 'linear' misses coulomb_friction: gap 14.80 % -> 0.96 %"
        );
        let f = Findings::decide(Evidence::HeldOutNmse, 14.8, 0.5, top(9.0, true));
        assert_eq!(
            f.headline(),
            "explained in part by coulomb_friction: 14.80 % -> 9.00 %, 8.50 %-points left above the floor of 0.50 %"
        );
        assert_eq!(
            f.status("linear"),
            "baseline 'linear' misses coulomb_friction and more: gap 14.80 % -> 9.00 % (floor 0.50 %)"
        );
        let f = Findings::decide(Evidence::HeldOutNmse, 14.8, 0.5, top(12.0, true));
        assert_eq!(
            f.headline(),
            "unexplained (gap 14.80 %, floor 0.50 %, best candidate coulomb_friction leaves 12.00 %)"
        );
        assert_eq!(
            f.status("linear"),
            "baseline 'linear' has a gap of 14.80 % that no candidate explains"
        );
        let f = Findings {
            top_member: Some("channel mass_acceleration, 2nd order, 6.1 Hz, damping 0.70".into()),
            top_effect: Some(Effect::SensorLowpass),
            ..Findings::decide(Evidence::HeldOutNmse, 14.8, 0.5, top(0.96, true))
        };
        assert_eq!(
            f.headline(),
            "explained by sensor_lowpass: 14.80 % -> 0.96 % (channel mass_acceleration, 2nd order, 6.1 Hz, damping 0.70)"
        );
        let f = Findings::decide(Evidence::HeldOutNmse, 0.8, 0.5, None);
        assert_eq!(f.status("linear"), "baseline 'linear' is adequate");
        let f = f.explained_by(Effect::ExciterDelay);
        assert_eq!(f.top_effect, Some(Effect::ExciterDelay));
    }
}
