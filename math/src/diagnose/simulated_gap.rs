//! The verdict on records with no sine steps from the models' simulations: the baseline and the
//! candidate each refitted by output error on the fitted records and simulated on the held-out
//! ones. The gap is the baseline's held-out NMSE of the simulated channel, the candidate's is
//! what it leaves, and the rule is [`findings::verdict`], the one every other evidence uses.
//! A pair refitted together is named by the rule of the pairs ([`findings::pair_named`]).
//!
//! The floor is the held-out NMSE of a refitted model whose simulation fits the fitted records
//! within their noise (its output-error misfit at most [`FORM_MISFIT_VARIANCE`] noise
//! variances): what such a model leaves is the noise, measurement and input together. Where
//! none does, each model's held-out NMSE over its misfit variance (the noise's share, if the
//! held-out error grows as the fitted misfit does), the smallest; 0 where no misfit could be
//! compared with the noise. The noise of the held-out channel alone, from its spectrum above
//! the excitation's band, is no floor: a friction's stick-slip puts force there (on a simulated
//! rig with Coulomb friction it read 13 times the floor), and the noise of the measured input
//! that drives the simulation reaches the output inside the band.
//!
//! Why beside the diagnosis along the measured motion: there the velocity and acceleration are
//! differentiated from the noisy, sampled displacement, whose noise can hide an effect (a loop
//! whose force is below that noise) or make one up (a friction level biased low); a simulation
//! takes the motion from the model and has neither.

use serde::Serialize;

use super::effects::Effect;
use super::findings::{self, PairEvidence, Verdict, percent_text};
use crate::identify::FORM_MISFIT_VARIANCE;

/// A refitted model as the verdict sees it.
#[derive(Debug, Clone, Copy)]
pub struct SimulatedModel<'a> {
    /// The effect added to the baseline (None: the baseline).
    pub effect: Option<Effect>,
    /// A second effect fitted together with `effect` (a pair).
    pub second_effect: Option<Effect>,
    /// Held-out NMSE of the simulated channel per held-out record [%].
    pub heldout_nmse_percent: &'a [f64],
    /// The fit's output-error misfit in noise std (None: the noise was not measured).
    pub misfit_noise_std: Option<f64>,
}

impl SimulatedModel<'_> {
    fn within_noise(&self) -> bool {
        self.misfit_noise_std
            .is_some_and(|m| m * m <= FORM_MISFIT_VARIANCE)
    }

    /// The noise's share of the held-out NMSE if it grows as the fitted misfit does.
    fn scaled_floor(&self) -> Option<f64> {
        let m = self.misfit_noise_std?;
        Some(mean(self.heldout_nmse_percent) / (m * m).max(1.0))
    }
}

/// Where the floor of a [`SimulatedGap`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FloorSource {
    /// A model that fits the records within their noise: its held-out NMSE.
    WithinNoise,
    /// No model fits within the noise: a held-out NMSE over its misfit variance.
    ScaledByMisfit,
    /// No misfit could be compared with the noise: 0.
    Unmeasured,
}

/// The gap by simulation and what the verdict rule makes of it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SimulatedGap {
    pub verdict: Verdict,
    /// The candidate refitted beside the baseline, if any (the pair's first when a pair is
    /// named).
    pub effect: Option<Effect>,
    /// The pair's second effect, when two effects refitted together explain the gap where one
    /// alone does not, or leave at most half of what it leaves ([`findings::pair_named`]).
    pub second_effect: Option<Effect>,
    /// The baseline's mean held-out NMSE [%].
    pub gap_before_percent: f64,
    /// The candidate's mean held-out NMSE [%] (the baseline's where there is no candidate).
    pub gap_after_percent: f64,
    /// The noise's share of the held-out NMSE [%] (see the module's documentation).
    pub floor_percent: f64,
    /// How the floor was found.
    pub floor_from: FloorSource,
    /// The baseline's output-error misfit in noise std, where the noise was measured.
    pub baseline_misfit_noise_std: Option<f64>,
    /// Whether the candidate's shrink is beyond what the noise explains.
    pub significant: bool,
}

impl SimulatedGap {
    /// The verdict on the baseline and the candidate refitted beside it, and a pair (the
    /// candidate with a second effect, refitted together) where there is one. A model's score
    /// is its held-out NMSE: its extra parameters are paid for by the held-out records.
    pub fn judge(
        baseline: SimulatedModel,
        candidate: Option<SimulatedModel>,
        pair: Option<SimulatedModel>,
    ) -> SimulatedGap {
        let before = mean(baseline.heldout_nmse_percent);
        let after = candidate.map(|c| mean(c.heldout_nmse_percent));
        let models = [Some(baseline), candidate, pair];
        let smallest = |f: Option<f64>, n: f64| Some(f.map_or(n, |f: f64| f.min(n)));
        let within = models
            .iter()
            .flatten()
            .filter(|m| m.within_noise())
            .map(|m| mean(m.heldout_nmse_percent))
            .fold(None, smallest);
        let scaled = models
            .iter()
            .flatten()
            .filter_map(SimulatedModel::scaled_floor)
            .fold(None, smallest);
        let (floor_percent, floor_from) = match (within, scaled) {
            (Some(f), _) => (f, FloorSource::WithinNoise),
            (None, Some(f)) => (f, FloorSource::ScaledByMisfit),
            (None, None) => (0.0, FloorSource::Unmeasured),
        };
        let significant =
            after.is_some_and(|a| findings::significant(before, floor_percent, a, a, before));
        let single = SimulatedGap {
            verdict: findings::verdict(before, floor_percent, after.map(|a| (a, significant))),
            effect: candidate.and_then(|c| c.effect),
            second_effect: None,
            gap_before_percent: before,
            gap_after_percent: after.unwrap_or(before),
            floor_percent,
            floor_from,
            baseline_misfit_noise_std: baseline.misfit_noise_std,
            significant,
        };
        let (Some(a), Some(pair)) = (after, pair) else {
            return single;
        };
        let (Some(first), Some(second)) = (pair.effect, pair.second_effect) else {
            return single;
        };
        let pair_after = mean(pair.heldout_nmse_percent);
        let evidence = PairEvidence {
            effects: [first, second],
            gap_after_percent: pair_after,
            score_percent: pair_after,
            significant: findings::significant(
                before,
                floor_percent,
                pair_after,
                pair_after,
                before,
            ),
            single_score_percent: a,
        };
        if findings::pair_named(single.verdict, before, floor_percent, a, &evidence) {
            SimulatedGap {
                verdict: Verdict::Explained,
                effect: Some(first),
                second_effect: Some(second),
                gap_after_percent: pair_after,
                significant: evidence.significant,
                ..single
            }
        } else {
            single
        }
    }

    /// One line: "explained by hysteresis: 1.52 % -> 0.06 % (floor 0.06 %)".
    pub fn headline(&self) -> String {
        let before = percent_text(self.gap_before_percent);
        let after = percent_text(self.gap_after_percent);
        let floor = match self.floor_from {
            FloorSource::WithinNoise => format!("floor {}", percent_text(self.floor_percent)),
            FloorSource::ScaledByMisfit => format!(
                "floor {} scaled by the misfit: no refitted model fits the records within their noise",
                percent_text(self.floor_percent)
            ),
            FloorSource::Unmeasured => "floor 0: the noise could not be measured".into(),
        };
        // A gap under the rule's least that still exceeds the noise: small, not absent.
        let small = match self.baseline_misfit_noise_std {
            Some(m) if self.verdict == Verdict::Adequate && m * m > FORM_MISFIT_VARIANCE => {
                format!(
                    "; the baseline's simulation misses the fitted records by {m:.1} noise std: a small gap, not none"
                )
            }
            _ => String::new(),
        };
        match (self.verdict, self.effect) {
            (Verdict::Explained, Some(e)) => match self.second_effect {
                Some(second) => format!(
                    "explained by {} together with {}: {before} -> {after} ({floor})",
                    e.name(),
                    second.name()
                ),
                None => format!("explained by {}: {before} -> {after} ({floor})", e.name()),
            },
            (Verdict::ExplainedInPart, Some(e)) => format!(
                "explained in part by {}: {before} -> {after}, {} left above the floor ({floor})",
                e.name(),
                percent_text(self.gap_after_percent - self.floor_percent)
            ),
            (v, Some(e)) => format!(
                "{} (gap {before}, {floor}; {} leaves {after}{}){small}",
                v.name(),
                e.name(),
                if self.significant {
                    ""
                } else {
                    ", not a significant shrink"
                }
            ),
            (v, None) => format!(
                "{} (gap {before}, {floor}; no candidate refitted){small}",
                v.name()
            ),
        }
    }
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(effect: Option<Effect>, nmse: &[f64], misfit: f64) -> SimulatedModel<'_> {
        SimulatedModel {
            effect,
            second_effect: None,
            heldout_nmse_percent: nmse,
            misfit_noise_std: Some(misfit),
        }
    }

    #[test]
    fn a_candidate_within_the_noise_sets_the_floor_and_explains() {
        let g = SimulatedGap::judge(
            model(None, &[1.5, 1.54], 8.8),
            Some(model(Some(Effect::Hysteresis), &[0.056, 0.058], 0.84)),
            None,
        );
        assert_eq!(g.verdict, Verdict::Explained);
        assert!((g.floor_percent - 0.057).abs() < 1e-12);
        assert!(
            g.headline()
                .starts_with("explained by hysteresis: 1.52 % -> 0.06 % (floor 0.06 %)"),
            "{}",
            g.headline()
        );
    }

    #[test]
    fn a_baseline_within_the_noise_is_adequate() {
        let g = SimulatedGap::judge(
            model(None, &[0.4], 1.1),
            Some(model(Some(Effect::Hysteresis), &[0.39], 1.05)),
            None,
        );
        assert_eq!(g.verdict, Verdict::Adequate);
        assert!(!g.significant);
        assert_eq!(g.floor_percent, 0.39);
    }

    #[test]
    fn without_a_model_within_the_noise_the_share_removed_decides() {
        // Floor 0: leaving 80 % of the gap is a significant shrink but under the in-part
        // share of a quarter; leaving 60 % is in part; leaving 40 % explains.
        let base = model(None, &[5.0], 9.0);
        let left = |nmse| {
            SimulatedGap::judge(base, Some(model(Some(Effect::Hysteresis), nmse, 4.0)), None)
        };
        let g = left(&[4.0]);
        assert_eq!(g.verdict, Verdict::Unexplained);
        assert!(g.significant);
        // Each model's NMSE over its misfit variance: 5 / 81 and 4 / 16.
        assert_eq!(g.floor_from, FloorSource::ScaledByMisfit);
        assert!((g.floor_percent - 5.0 / 81.0).abs() < 1e-12);
        assert!(
            g.headline().contains("no refitted model fits"),
            "{}",
            g.headline()
        );
        assert_eq!(left(&[3.0]).verdict, Verdict::ExplainedInPart);
        assert_eq!(left(&[2.0]).verdict, Verdict::Explained);
        let g = SimulatedGap::judge(base, None, None);
        assert_eq!(g.verdict, Verdict::Unexplained);
        assert!(
            g.headline().contains("no candidate refitted"),
            "{}",
            g.headline()
        );
        // A gap under 1 % is adequate by the rule, and says that it is there.
        let g = SimulatedGap::judge(model(None, &[0.9], 4.0), None, None);
        assert_eq!(g.verdict, Verdict::Adequate);
        assert!(
            g.headline()
                .ends_with("by 4.0 noise std: a small gap, not none"),
            "{}",
            g.headline()
        );
        // A misfit the noise could not measure sets no floor.
        let unmeasured = SimulatedModel {
            misfit_noise_std: None,
            ..model(None, &[0.5], 0.0)
        };
        let g = SimulatedGap::judge(unmeasured, None, None);
        assert_eq!(
            (g.floor_from, g.floor_percent),
            (FloorSource::Unmeasured, 0.0)
        );
    }

    #[test]
    fn a_pair_is_named_where_it_leaves_at_most_half_of_what_the_single_leaves() {
        // Gap 4.2 %, floor 0.04 % (the pair fits within the noise): the single leaves 1.0 %
        // (explained alone), the pair 0.04 %: under half of the single's excess, so the pair.
        let base = model(None, &[4.2], 11.0);
        let single = model(Some(Effect::CoulombFriction), &[1.0], 4.0);
        let pair = SimulatedModel {
            second_effect: Some(Effect::SensorLowpass),
            ..model(Some(Effect::CoulombFriction), &[0.04], 1.2)
        };
        let g = SimulatedGap::judge(base, Some(single), Some(pair));
        assert_eq!(g.verdict, Verdict::Explained);
        assert_eq!(
            (g.effect, g.second_effect),
            (Some(Effect::CoulombFriction), Some(Effect::SensorLowpass))
        );
        assert!(
            g.headline().starts_with(
                "explained by coulomb_friction together with sensor_lowpass: 4.20 % -> 0.04 %"
            ),
            "{}",
            g.headline()
        );
        // A pair that leaves more than half of the single's excess adds no name.
        let weak = SimulatedModel {
            second_effect: Some(Effect::SensorLowpass),
            ..model(Some(Effect::CoulombFriction), &[0.8], 3.5)
        };
        let g = SimulatedGap::judge(base, Some(single), Some(weak));
        assert_eq!(
            (g.effect, g.second_effect),
            (Some(Effect::CoulombFriction), None)
        );
    }
}
