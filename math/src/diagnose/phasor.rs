//! The phasor-only diagnosis for a live stream of harmonic analyses (what a diagnoser node
//! wraps): no held-out records to simulate on; the evidence is the element-force residual of
//! each step, cross-validated over steps. Offline, an element test's records with no steps
//! join as steps fitted sample by sample ([`super::sampled_records`]).

use serde::Serialize;

use super::effects::{Effect, Structure};
use super::element_heldout::TermFit;
use super::findings::{Evidence, Findings, TopCandidate, Verdict};
use super::fit::Fitted;
use super::locate::{Located, locate};
use super::multisine::{DroppedEffect, is_extra_terms, located_by_step, search_blocks};
use super::sampled_records::SampledRecord;
use super::score::penalised;
use super::search::search;
use super::{DiagnoseError, ParameterValue, parameter_values};
use crate::model::Model;
use crate::phasor::{HarmonicAnalysis, MultisineAnalysis};
use crate::recipe::Setup;

/// Fewest steps before [`PhasorDiagnosis::findings`] can cross-validate.
pub const MIN_STEPS: usize = 3;

/// One candidate in the live findings.
#[derive(Debug, Clone, Serialize)]
pub struct PhasorEffect {
    pub effect: Effect,
    /// Leave-one-step-out cross-validated element-force error with the effect [%].
    pub cv_percent: f64,
    /// Penalised score (lower is better) [%].
    pub score_percent: f64,
    pub added_parameters: Vec<ParameterValue>,
    /// The baseline's coefficients refitted beside the effect (with `added_parameters`, the
    /// whole model with the effect).
    pub refitted_baseline: Vec<ParameterValue>,
    pub significant: bool,
    /// Baseline + effect fitted on every step, where it is extra element terms or a hysteresis
    /// state and the moving mass is known or fitted (for held-out element records,
    /// [`super::element_heldout`]).
    #[serde(skip)]
    pub fit: Option<TermFit>,
}

/// What the live diagnosis finds after the steps so far.
#[derive(Debug, Clone, Serialize)]
pub struct PhasorFindings {
    pub steps: usize,
    /// The verdict on the cross-validated element-force error
    /// ([`Evidence::CrossValidatedForceError`]); its floor is what the force noise alone
    /// would leave [%].
    #[serde(flatten)]
    pub findings: Findings,
    pub ranked_effects: Vec<PhasorEffect>,
    pub located: Located,
    /// Exciter delay from the kinematic identity x_o - x = x_i [s] and its std, when the
    /// channels allow it. A delay is named when it stands out of its noise (4 standard
    /// deviations) and exceeds 0.5 ms; the force fit cannot see it (the element's own channels
    /// are consistent).
    pub kinematic_delay_s: Option<[f64; 2]>,
    /// Of `steps`, the periodic multisine records.
    pub multisine_steps: usize,
    /// Of `steps`, the records with no steps fitted sample by sample.
    pub sampled_records: usize,
    /// Candidates not fitted: with multisine records, those that are not extra element terms
    /// ([`super::multisine`]).
    pub not_fitted: Vec<Effect>,
    /// With multisine records, candidates that gave no fit on these steps, and why.
    pub dropped: Vec<DroppedEffect>,
    /// The baseline fitted on every step (as [`PhasorEffect::fit`]).
    #[serde(skip)]
    pub baseline_fit: Option<TermFit>,
}

/// Live gap diagnosis from harmonic analyses, one step at a time.
///
/// ```
/// use forcemap_math::diagnose::PhasorDiagnosis;
/// use forcemap_math::recipe::Setup;
/// use forcemap_math::model::{Model, ModelOptions};
///
/// let baseline = Model::by_name("linear", &ModelOptions::default()).unwrap();
/// let mut live = PhasorDiagnosis::new(Setup::BaseExcited { mass_kg: 36.0 }, baseline);
/// // for each settled step: live.push(analysis); then live.findings()
/// assert_eq!(live.steps(), 0);
/// assert!(live.findings().is_err()); // needs at least MIN_STEPS steps
/// ```
///
/// Feed [`push`](Self::push) each step's [`HarmonicAnalysis`] (from
/// `phasor::analyse_record`, or the identifier node's stream) as it settles; a step with the
/// number of an earlier one replaces it. [`findings`](Self::findings) refits everything (a
/// few milliseconds per step: the baseline and each candidate are least-squares fits on one
/// rebuilt period per step, cross-validated by leaving each step out) and returns the
/// verdict, the ranked candidates and where the residual lies. The verdict rule is that of
/// [`super::findings`], applied to the cross-validated element-force error instead of the
/// held-out NMSE; its floor is what the force noise alone leaves.
#[derive(Debug, Clone)]
pub struct PhasorDiagnosis {
    setup: Setup,
    baseline: Model,
    analyses: Vec<HarmonicAnalysis>,
    multisines: Vec<MultisineAnalysis>,
    records: Vec<SampledRecord>,
    effects: Vec<Effect>,
}

impl PhasorDiagnosis {
    pub fn new(setup: Setup, baseline: Model) -> PhasorDiagnosis {
        // Mass error cannot show without held-out prediction (see its signature).
        let effects = Effect::ALL
            .into_iter()
            .filter(|e| *e != Effect::MassError && e.applies_to(setup.kind()))
            .collect();
        PhasorDiagnosis {
            setup,
            baseline,
            analyses: Vec::new(),
            multisines: Vec::new(),
            records: Vec::new(),
            effects,
        }
    }

    /// The diagnosis with only those of its candidates that are among `effects` (the model with
    /// one named effect fitted, as `identify` of `NAME+hysteresis` does).
    pub fn with_effects(mut self, effects: &[Effect]) -> PhasorDiagnosis {
        self.effects.retain(|e| effects.contains(e));
        self
    }

    /// Adds (or replaces, by step number) one step's analysis.
    pub fn push(&mut self, analysis: HarmonicAnalysis) {
        match self.analyses.iter_mut().find(|a| a.step == analysis.step) {
            Some(a) => *a = analysis,
            None => self.analyses.push(analysis),
        }
    }

    /// Adds (or replaces, by step number) one periodic multisine record's analysis: the
    /// diagnosis then fits every step through the identification's equations
    /// ([`super::multisine`]).
    pub fn push_multisine(&mut self, analysis: MultisineAnalysis) {
        match self.multisines.iter_mut().find(|a| a.step == analysis.step) {
            Some(a) => *a = analysis,
            None => self.multisines.push(analysis),
        }
    }

    /// Adds (or replaces, by step number) an element test's record with no steps (band-random,
    /// ramped, a whole file): the diagnosis then fits every step through the identification's
    /// equations, this one by its samples ([`super::sampled_records`]).
    pub fn push_record(&mut self, record: SampledRecord) {
        match self.records.iter_mut().find(|r| r.step() == record.step()) {
            Some(r) => *r = record,
            None => self.records.push(record),
        }
    }

    /// Scales every record's rows by the noise pooled over the records
    /// ([`super::sampled_records::pool_row_noise`]), in place of each record's own: call it
    /// once every record is in.
    pub fn pool_record_noise(&mut self) {
        super::sampled_records::pool_row_noise(&mut self.records);
    }

    /// Steps so far: sine steps, multisine records and records with no steps.
    pub fn steps(&self) -> usize {
        self.analyses.len() + self.multisines.len() + self.records.len()
    }

    /// Forgets every step (e.g. when the rig or the baseline changes).
    pub fn clear(&mut self) {
        self.analyses.clear();
        self.multisines.clear();
        self.records.clear();
    }

    /// Whether the steps are fitted through the identification's equations ([`search_blocks`]):
    /// with a multisine record or a record with no steps among them.
    fn on_equations(&self) -> bool {
        !self.multisines.is_empty() || !self.records.is_empty()
    }

    /// Steps needed before [`findings`](Self::findings) can cross-validate: [`MIN_STEPS`] sine
    /// steps, or [`super::multisine::MIN_BLOCKS`] steps when one is a multisine record or a
    /// record with no steps.
    pub fn min_steps(&self) -> usize {
        if self.on_equations() {
            super::multisine::MIN_BLOCKS
        } else {
            MIN_STEPS
        }
    }

    /// The current findings; an error until [`min_steps`](Self::min_steps) steps are in.
    pub fn findings(&self) -> Result<PhasorFindings, DiagnoseError> {
        if self.steps() < self.min_steps() {
            return Err(DiagnoseError::NoSineSteps);
        }
        if self.on_equations() {
            return self.findings_on_equations();
        }
        let s = search(&self.setup, &self.baseline, &self.analyses, &self.effects)?;
        let before = s.baseline_cv_percent.unwrap_or(s.baseline.residual_percent);
        let candidates = s
            .candidates
            .iter()
            .filter(|c| c.effect != Effect::ExciterDelay)
            .map(|c| Scored {
                effect: c.effect,
                cv_percent: c.step_error_percent(),
                extra_parameters: c.structure.extra_parameters,
                added_parameters: c.fitted.added_parameters(),
                refitted_baseline: c.fitted.refitted_baseline(),
                fit: self.term_fit(&c.fitted),
            })
            .collect();
        let (mut findings, ranked) = conclude(before, s.noise_cv_percent, s.equations, candidates);
        let delay_named = s
            .exciter_delay
            .is_some_and(|(d, sd)| super::exciter::delay_shown(d, sd));
        if delay_named && findings.verdict != Verdict::Explained {
            findings = findings.explained_by(Effect::ExciterDelay);
        }
        Ok(PhasorFindings {
            steps: self.analyses.len(),
            multisine_steps: 0,
            sampled_records: 0,
            findings,
            located: locate(&s.baseline, &s.cycles),
            ranked_effects: ranked,
            kinematic_delay_s: s.exciter_delay.map(|(d, sd)| [d, sd]),
            not_fitted: Vec::new(),
            dropped: Vec::new(),
            baseline_fit: self.term_fit(&s.baseline),
        })
    }

    /// The findings with multisine records or records with no steps: every step fitted through
    /// the identification's equations ([`search_blocks`]); the residual located per step only.
    fn findings_on_equations(&self) -> Result<PhasorFindings, DiagnoseError> {
        let s = search_blocks(
            &self.setup,
            &self.baseline,
            &self.analyses,
            &self.records,
            &self.multisines,
            &self.effects,
        )?;
        let candidates = s
            .candidates
            .iter()
            .map(|c| Scored {
                effect: c.effect,
                cv_percent: c.cv_percent,
                extra_parameters: c.structure.extra_parameters,
                added_parameters: c.added_parameters.clone(),
                refitted_baseline: c.refitted_baseline.clone(),
                fit: c.fit.clone(),
            })
            .collect();
        let (findings, ranked) = conclude(
            s.baseline_cv_percent,
            s.noise_cv_percent,
            s.equations,
            candidates,
        );
        Ok(PhasorFindings {
            steps: self.steps(),
            multisine_steps: self.multisines.len(),
            sampled_records: self.records.len(),
            findings,
            located: located_by_step(&s.by_step),
            ranked_effects: ranked,
            kinematic_delay_s: None,
            not_fitted: s.not_fitted,
            dropped: s.dropped,
            baseline_fit: Some(s.baseline_fit),
        })
    }

    /// A fit on the rebuilt sine periods as a [`TermFit`]: where it only adds element terms or
    /// a hysteresis state (its coefficient alpha after the terms'; the state integrated along a
    /// record's measured velocity) and the element setup's moving mass is known.
    fn term_fit(&self, f: &Fitted) -> Option<TermFit> {
        let Setup::Element {
            moving_mass_kg: Some(m),
            ..
        } = self.setup
        else {
            return None;
        };
        let n = f.terms.len();
        let without_hysteresis = Structure {
            hysteresis: None,
            ..f.structure.clone()
        };
        if !is_extra_terms(&without_hysteresis) {
            return None;
        }
        let hysteresis = match f.structure.hysteresis {
            Some(law) => Some((law, *f.theta.get(n)?)),
            None => None,
        };
        Some(TermFit {
            terms: f.terms.clone(),
            theta: f.theta[..n].to_vec(),
            mass_kg: m,
            hysteresis,
        })
    }
}

/// One candidate's evidence before ranking.
struct Scored {
    effect: Effect,
    cv_percent: f64,
    extra_parameters: usize,
    added_parameters: Vec<(String, f64, f64)>,
    refitted_baseline: Vec<(String, f64, f64)>,
    fit: Option<TermFit>,
}

/// The ranking and the verdict from the cross-validated errors: the same penalty and rule
/// whatever the steps were fitted on.
fn conclude(
    before: f64,
    floor: f64,
    n_eff: f64,
    candidates: Vec<Scored>,
) -> (Findings, Vec<PhasorEffect>) {
    // The CV error is an RMS ratio; the penalty applies to its square (a variance).
    let pen = |e: f64, p: usize| penalised(e * e, p, n_eff).sqrt();
    let base_score = pen(before, 0);
    let mut ranked: Vec<PhasorEffect> = candidates
        .into_iter()
        .map(|c| {
            let score = pen(c.cv_percent, c.extra_parameters);
            PhasorEffect {
                effect: c.effect,
                cv_percent: c.cv_percent,
                score_percent: score,
                added_parameters: parameter_values(c.added_parameters),
                refitted_baseline: parameter_values(c.refitted_baseline),
                significant: super::significant(before, floor, c.cv_percent, score, base_score),
                fit: c.fit,
            }
        })
        .collect();
    ranked.sort_by(|a, b| a.score_percent.total_cmp(&b.score_percent));
    // A family's members (the sensor family's two) stand for one effect: its best.
    let mut seen = Vec::new();
    ranked.retain(|r| {
        let first = !seen.contains(&r.effect);
        seen.push(r.effect);
        first
    });
    let findings = Findings::decide(
        Evidence::CrossValidatedForceError,
        before,
        floor,
        ranked.first().map(|r| TopCandidate {
            effect: r.effect,
            gap_after_percent: r.cv_percent,
            significant: r.significant,
        }),
    );
    (findings, ranked)
}
