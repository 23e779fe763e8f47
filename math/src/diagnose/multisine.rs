//! The diagnosis on the identification's equations, for periodic multisine records (and the
//! sine steps beside them) and for an element test's records with no steps: the baseline and
//! each candidate effect identified through the equations `forcemap identify` solves (the sine
//! steps' fd-multi blocks, every multisine record's per-line block through
//! [`accumulate_multisines`], a record's time-domain rows, [`super::sampled_records`]),
//! cross-validated by leaving out a whole step (a sine step, a multisine realisation or a
//! record) and scoring its equations, weighted by their noise, with the parameters fitted on
//! the others.
//!
//! The candidates that are extra element terms are fitted on these equations (friction,
//! damping and stiffness nonlinearities, free play, preload), and so are the two that are
//! linear per line ([`super::multisine_state`]): sensor_lowpass (each member's filter undone on
//! every step's phasors) and series_compliance (the damper's column lagged per line; on
//! multisine records only). Hysteresis and drift are listed, with the reason, as not fitted
//! here; on records with no steps only the extra element terms are fitted.

use std::borrow::Cow;

use nalgebra::DVector;
use serde::Serialize;

use super::DiagnoseError;
use super::cycles::synthesize;
use super::effects::{Effect, Scales, Structure, baseline_has, structures};
use super::element_heldout::TermFit;
use super::fit::root_ratio_percent;
use super::locate::{Located, StatePlane};
use super::multisine_state;
use super::sampled_records::SampledRecord;
use crate::signal::bouc_wen::HysteresisLaw;

/// The name of the hysteresis state's coefficient (the axis path's and the rig's).
const HYSTERESIS_COEFFICIENT: &str = "alpha";
use super::search::POSITIVE_SYMBOLS;
use crate::identify::{
    EquationAccumulator, FdMultiOptions, Identification, Method, StepEquations, TermLag, Weighting,
    accumulate_multisines_lagged, multisine_equations_about_lagged, step_equations,
};
use crate::model::Model;
use crate::phasor::{HarmonicAnalysis, MultisineAnalysis};
use crate::recipe::Setup;
use crate::record::Channel;

/// Fewest steps (sine steps, multisine realisations, records) to cross-validate over when one
/// is a multisine or a record: one determines every parameter, so two can predict each other.
pub const MIN_BLOCKS: usize = 2;

/// One candidate fitted on the equations of every step.
#[derive(Debug, Clone)]
pub struct BlockCandidate {
    pub effect: Effect,
    pub structure: Structure,
    /// Leave-one-step-out cross-validated error of the weighted equations [%].
    pub cv_percent: f64,
    /// (name, value, std) of what the structure added, fitted on every step.
    pub added_parameters: Vec<(String, f64, f64)>,
    /// (name, value, std) of the baseline's coefficients (and the moving mass where the setup
    /// leaves it unknown) refitted beside the structure.
    pub refitted_baseline: Vec<(String, f64, f64)>,
    /// Baseline + structure fitted on every step, where it only adds element terms (a
    /// held-out record is predicted from the terms alone, without a filter or a lag).
    pub fit: Option<TermFit>,
}

/// A candidate that gave no fit on these steps, and why.
#[derive(Debug, Clone, Serialize)]
pub struct DroppedEffect {
    pub effect: Effect,
    pub reason: String,
}

/// What a step of the block diagnosis is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BlockKind {
    Sine,
    Multisine,
    /// A record with no steps, fitted sample by sample.
    Samples,
}

/// The baseline's fit on one step.
#[derive(Debug, Clone)]
pub struct BlockGap {
    pub step: usize,
    pub kind: BlockKind,
    /// 100 * |weighted residual| / |weighted force| on the step's equations, fitted on every
    /// step [%].
    pub mismatch_percent: f64,
    /// What the noise alone would leave on them [%].
    pub floor_percent: f64,
}

/// Result of [`search_blocks`].
#[derive(Debug, Clone)]
pub struct BlockSearch {
    pub baseline_cv_percent: f64,
    /// The baseline fitted on every step.
    pub baseline_fit: TermFit,
    /// Cross-validated error the noise alone would leave [%].
    pub noise_cv_percent: f64,
    /// Independent real equations over every step (the penalty's N).
    pub equations: f64,
    pub candidates: Vec<BlockCandidate>,
    /// Candidate effects with nothing to fit on these equations (no structure for this
    /// baseline, e.g. series compliance or drift without a damper).
    pub not_fitted: Vec<Effect>,
    /// Candidates not fitted or fitted but dropped, with the first reason (a state these
    /// equations do not hold, a fit these steps cannot identify, or one that needs the
    /// opposite sign).
    pub dropped: Vec<DroppedEffect>,
    pub by_step: Vec<BlockGap>,
}

/// The steps of the diagnosis: sine steps first, then records with no steps, then multisine
/// records (indices in that order); a sensor_lowpass member's steps have its filter undone, a
/// series_compliance structure's lag one term ([`super::multisine_state::steps_for`]).
#[derive(Clone)]
pub(super) struct Steps<'a> {
    pub(super) setup: &'a Setup,
    pub(super) sines: Cow<'a, [HarmonicAnalysis]>,
    pub(super) records: &'a [SampledRecord],
    pub(super) multisines: Cow<'a, [MultisineAnalysis]>,
    pub(super) options: FdMultiOptions,
    pub(super) lag: Option<TermLag>,
    /// A hysteresis law whose state is the records' last column, its coefficient alpha the
    /// last parameter (records with no steps only: [`SampledRecord::equations`]).
    pub(super) hysteresis: Option<HysteresisLaw>,
}

impl Steps<'_> {
    fn len(&self) -> usize {
        self.fixed() + self.multisines.len()
    }

    /// Steps whose equations do not depend on theta: the sine steps and the records.
    fn fixed(&self) -> usize {
        self.sines.len() + self.records.len()
    }

    fn kind(&self, index: usize) -> BlockKind {
        if index < self.sines.len() {
            BlockKind::Sine
        } else if index < self.fixed() {
            BlockKind::Samples
        } else {
            BlockKind::Multisine
        }
    }

    /// `model` identified on every step but `leave` as `forcemap identify` does it.
    fn identify(
        &self,
        model: &Model,
        fixed_blocks: &[StepEquations],
        leave: Option<usize>,
    ) -> Result<Identification, DiagnoseError> {
        let mut acc = EquationAccumulator::new(model, self.setup, Method::FdMulti);
        if self.hysteresis.is_some() {
            acc = acc.with_state_parameter(HYSTERESIS_COEFFICIENT);
        }
        for (i, b) in fixed_blocks.iter().enumerate() {
            if Some(i) != leave {
                acc.add(b)?;
            }
        }
        let nf = self.fixed();
        let ms: Vec<MultisineAnalysis> = self
            .multisines
            .iter()
            .enumerate()
            .filter(|(j, _)| Some(nf + j) != leave)
            .map(|(_, m)| m.clone())
            .collect();
        Ok(
            accumulate_multisines_lagged(&acc, model, self.setup, &ms, &self.options, self.lag)?
                .solve()?,
        )
    }

    /// The equations of step `index`, a multisine's weighted by its whole noise about `theta`.
    fn block(
        &self,
        model: &Model,
        fixed_blocks: &[StepEquations],
        index: usize,
        theta: &[f64],
    ) -> Result<StepEquations, DiagnoseError> {
        Ok(match index.checked_sub(self.fixed()) {
            None => fixed_blocks[index].clone(),
            Some(j) => multisine_equations_about_lagged(
                model,
                self.setup,
                &self.multisines[j],
                &self.options,
                theta,
                self.lag,
            )?,
        })
    }

    /// The equations of the steps that do not depend on theta, in step order: the sine steps'
    /// and the records'.
    fn fixed_blocks(&self, model: &Model) -> Result<Vec<StepEquations>, DiagnoseError> {
        let mut blocks: Vec<StepEquations> = self
            .sines
            .iter()
            .map(|an| step_equations(model, self.setup, Method::FdMulti, an, &self.options))
            .collect::<Result<_, _>>()?;
        for r in self.records {
            blocks.push(r.equations(model, self.setup, self.hysteresis.as_ref())?);
        }
        Ok(blocks)
    }

    fn step_number(&self, index: usize) -> usize {
        let ns = self.sines.len();
        match self.kind(index) {
            BlockKind::Sine => self.sines[index].step,
            BlockKind::Samples => self.records[index - ns].step(),
            BlockKind::Multisine => self.multisines[index - self.fixed()].step,
        }
    }
}

/// (sum of squared weighted residuals, sum of squared weighted right-hand sides, what the
/// noise alone leaves: half an independent real equation each, a complex equation's noise
/// weighted to unit magnitude).
fn sums(b: &StepEquations, theta: &[f64]) -> (f64, f64, f64) {
    let r = &b.a * DVector::from_column_slice(theta) - &b.b;
    (
        r.norm_squared(),
        b.b.norm_squared(),
        0.5 * b.independent_equations,
    )
}

/// Leave-one-step-out cross-validated error of `model` [%] and its noise floor [%].
fn cross_validated(steps: &Steps, model: &Model) -> Result<(f64, f64), DiagnoseError> {
    let fixed_blocks = steps.fixed_blocks(model)?;
    let (mut num, mut den, mut noise) = (0.0, 0.0, 0.0);
    for k in 0..steps.len() {
        let theta = steps.identify(model, &fixed_blocks, Some(k))?.theta();
        let (n, d, s) = sums(&steps.block(model, &fixed_blocks, k, &theta)?, &theta);
        num += n;
        den += d;
        noise += s;
    }
    Ok((root_ratio_percent(num, den), root_ratio_percent(noise, den)))
}

/// The scales a candidate's searched parameter is relative to: the largest displacement and
/// velocity of any step's period and the highest excited frequency.
fn scales(setup: &Setup, steps: &Steps) -> Result<Scales, DiagnoseError> {
    let mut s = Scales {
        max_displacement_m: f64::MIN_POSITIVE,
        max_velocity_mps: f64::MIN_POSITIVE,
        max_frequency_hz: 0.0,
    };
    for an in steps.sines.iter() {
        let eh = crate::identify::element_harmonics(setup, an, false)?;
        let w = eh.omega_rad_s;
        let peak = |scale: f64| eh.displacement.get(1).map_or(0.0, |c| c.norm() * scale);
        s.max_displacement_m = s.max_displacement_m.max(peak(1.0));
        s.max_velocity_mps = s.max_velocity_mps.max(peak(w));
        s.max_frequency_hz = s.max_frequency_hz.max(an.frequency_hz);
    }
    for r in steps.records {
        s.max_displacement_m = s.max_displacement_m.max(r.max_displacement_m);
        s.max_velocity_mps = s.max_velocity_mps.max(r.max_velocity_mps);
        s.max_frequency_hz = s.max_frequency_hz.max(r.top_frequency_hz());
    }
    for ms in steps.multisines.iter() {
        let Some(x) = ms.channel(Channel::RelativeDisplacementM) else {
            continue;
        };
        let w0 = std::f64::consts::TAU * ms.base_frequency_hz;
        let top = ms.lines.last().copied().unwrap_or(1);
        // The period rebuilt from its excited lines (DC left out: it moves no scale).
        let mut c = vec![num_complex::Complex64::new(0.0, 0.0); top + 1];
        for &k in &ms.lines {
            c[k] = x.phasors[k];
        }
        let l = (8 * (top + 1)).next_power_of_two();
        let peak = |v: Vec<f64>| v.iter().fold(0.0f64, |m, y| m.max(y.abs()));
        s.max_displacement_m = s
            .max_displacement_m
            .max(peak(synthesize(&c, l, |_| 1.0.into())));
        s.max_velocity_mps = s.max_velocity_mps.max(peak(synthesize(&c, l, |k| {
            num_complex::Complex64::new(0.0, k as f64 * w0)
        })));
        s.max_frequency_hz = s.max_frequency_hz.max(top as f64 * ms.base_frequency_hz);
    }
    Ok(s)
}

/// Fits the baseline and every candidate of `effects` that is an extra element term on the
/// equations of `sines`, `records` and `multisines` (see the module docs).
pub fn search_blocks(
    setup: &Setup,
    baseline: &Model,
    sines: &[HarmonicAnalysis],
    records: &[SampledRecord],
    multisines: &[MultisineAnalysis],
    effects: &[Effect],
) -> Result<BlockSearch, DiagnoseError> {
    let steps = Steps {
        setup,
        sines: Cow::Borrowed(sines),
        records,
        multisines: Cow::Borrowed(multisines),
        // The diagnosis scores residuals in units of the noise: noise weights, whatever the
        // form error.
        options: FdMultiOptions {
            weighting: Weighting::Noise,
            ..FdMultiOptions::default()
        },
        lag: None,
        hysteresis: None,
    };
    if steps.len() < MIN_BLOCKS {
        return Err(DiagnoseError::NoSineSteps);
    }
    let (baseline_cv, noise_cv) = cross_validated(&steps, baseline)?;
    // The baseline on every step, per step.
    let fixed_blocks = steps.fixed_blocks(baseline)?;
    let theta = steps.identify(baseline, &fixed_blocks, None)?.theta();
    let baseline_fit = term_fit(&steps, baseline, &theta);
    let mut equations = 0.0;
    let mut by_step = Vec::new();
    for k in 0..steps.len() {
        let b = steps.block(baseline, &fixed_blocks, k, &theta)?;
        equations += b.independent_equations;
        let (n, d, s) = sums(&b, &theta);
        by_step.push(BlockGap {
            step: steps.step_number(k),
            kind: steps.kind(k),
            mismatch_percent: root_ratio_percent(n, d),
            floor_percent: root_ratio_percent(s, d),
        });
    }
    let scales = scales(setup, &steps)?;
    let mut candidates = Vec::new();
    let mut not_fitted = Vec::new();
    let mut dropped = Vec::new();
    for &effect in effects {
        if baseline_has(baseline, effect) {
            continue;
        }
        let options = structures(baseline, effect, &scales);
        if options.is_empty() {
            not_fitted.push(effect);
            continue;
        }
        if let Some(reason) = options
            .iter()
            .find_map(|o| multisine_state::not_fitted_reason(o, &steps))
        {
            dropped.push(DroppedEffect { effect, reason });
            continue;
        }
        let options = multisine_state::with_members(options, scales.max_frequency_hz, &steps);
        let mut best: Option<BlockCandidate> = None;
        let mut why_not = None;
        for structure in options {
            match evaluate(&steps, baseline, effect, structure) {
                Ok(c) => {
                    if best.as_ref().is_none_or(|b| c.cv_percent < b.cv_percent) {
                        best = Some(c);
                    }
                }
                Err(e) => {
                    why_not.get_or_insert(e);
                }
            }
        }
        let best = best
            .map(|b| multisine_state::refine(b, |s| evaluate(&steps, baseline, effect, s).ok()))
            // The hysteresis family's Bouc-Wen shapes from the refined yield, as on sine steps.
            .map(|b| {
                let Ok(b) = super::hysteresis::refine(
                    b,
                    |c| &c.structure,
                    |s| {
                        Ok::<_, std::convert::Infallible>(
                            evaluate(&steps, baseline, effect, s).ok(),
                        )
                    },
                    |c| c.cv_percent,
                );
                b
            });
        match best {
            Some(b) => candidates.push(b),
            None => dropped.push(DroppedEffect {
                effect,
                reason: why_not.unwrap_or_default(),
            }),
        }
    }
    Ok(BlockSearch {
        baseline_cv_percent: baseline_cv,
        baseline_fit,
        noise_cv_percent: noise_cv,
        equations,
        candidates,
        not_fitted,
        dropped,
        by_step,
    })
}

/// `structure` on the baseline fitted on every step and cross-validated by leaving out a step;
/// Err says why it gives no candidate.
pub(super) fn evaluate(
    steps: &Steps,
    baseline: &Model,
    effect: Effect,
    structure: Structure,
) -> Result<BlockCandidate, String> {
    let steps = multisine_state::steps_for(steps, baseline, &structure)?;
    let model = baseline.with_terms(
        format!("{} + {}", baseline.name, effect.name()),
        &structure.terms,
    );
    let fixed_blocks = steps.fixed_blocks(&model).map_err(|e| e.to_string())?;
    let id = steps
        .identify(&model, &fixed_blocks, None)
        .map_err(|e| e.to_string())?;
    let mut added: Vec<(String, f64, f64)> = id.parameters[baseline.terms.len()..model.terms.len()]
        .iter()
        .chain(id.parameters.last().filter(|_| steps.hysteresis.is_some()))
        .map(|p| (p.name.clone(), p.value, p.std))
        .collect();
    // A fit that needs the opposite sign is not that effect.
    if !physical(&added) {
        return Err("its fit needs the opposite sign".to_string());
    }
    let theta = id.theta();
    if !multisine_state::physical(&steps, &theta) {
        return Err("its fit needs a damper of the opposite sign".to_string());
    }
    let (cv, _) =
        cross_validated(&steps, &model).map_err(|e| format!("leaving a step out: {e}"))?;
    added.extend(
        structure
            .searched
            .iter()
            .map(|(n, v)| (n.clone(), *v, f64::NAN)),
    );
    added.extend(multisine_state::derived(&steps, &theta));
    Ok(BlockCandidate {
        effect,
        cv_percent: cv,
        added_parameters: added,
        // The baseline's coefficients, and the moving mass (`m`) where the setup leaves it
        // unknown.
        refitted_baseline: id.parameters[..baseline.terms.len()]
            .iter()
            .chain(
                id.parameters[model.terms.len()..]
                    .iter()
                    .filter(|p| p.name == "m"),
            )
            .map(|p| (p.name.clone(), p.value, p.std))
            .collect(),
        fit: (is_extra_terms(&structure) || steps.hysteresis.is_some())
            .then(|| term_fit(&steps, &model, &theta)),
        structure,
    })
}

/// `model` with `theta` from the identification on `steps`: its terms' coefficients, then the
/// moving mass where the setup leaves it unknown, then the hysteresis state's coefficient
/// where the steps carry one.
fn term_fit(steps: &Steps, model: &Model, theta: &[f64]) -> TermFit {
    let n = model.terms.len();
    let mass_kg = match steps.setup {
        Setup::Element {
            moving_mass_kg: Some(m),
            ..
        } => *m,
        _ => theta.get(n).copied().unwrap_or(0.0),
    };
    TermFit {
        terms: model.terms.clone(),
        theta: theta[..n].to_vec(),
        mass_kg,
        hysteresis: steps.hysteresis.zip(theta.last().copied()),
    }
}

/// Whether a structure only adds element terms (so the identification's equations hold it
/// without changing the channels or lagging a term).
pub(crate) fn is_extra_terms(s: &Structure) -> bool {
    s.hysteresis.is_none()
        && s.series_relaxation_s.is_none()
        && !s.drift
        && s.transform == Default::default()
}

/// The sign rule of [`super::search::physical`] on (name, value, std) of the added terms.
fn physical(added: &[(String, f64, f64)]) -> bool {
    added
        .iter()
        .all(|(n, v, _)| !POSITIVE_SYMBOLS.contains(&n.as_str()) || *v > 0.0)
}

/// Where the baseline's residual lies, per step only: a multisine's equations are lines of
/// one period, not a state-plane cycle per frequency and amplitude, so the harmonic orders,
/// the regions and the state plane are left empty (their halves NaN).
pub fn located_by_step(by_step: &[BlockGap]) -> Located {
    let mut gaps: Vec<&BlockGap> = by_step.iter().collect();
    gaps.sort_by(|a, b| b.mismatch_percent.total_cmp(&a.mismatch_percent));
    let summary = gaps
        .iter()
        .map(|g| {
            format!(
                "step {} ({}): baseline residual {:.2} % of the force on its equations (noise alone {:.2} %)",
                g.step,
                match g.kind {
                    BlockKind::Multisine => "multisine, its lines and distortion bins",
                    BlockKind::Sine => "sine, its harmonics",
                    BlockKind::Samples => "a record with no steps, its samples",
                },
                g.mismatch_percent,
                g.floor_percent
            )
        })
        .collect();
    Located {
        by_step: Vec::new(),
        by_harmonic: Vec::new(),
        regions: Vec::new(),
        state_plane: StatePlane {
            displacement_edges_m: Vec::new(),
            velocity_edges_mps: Vec::new(),
            rms_residual_n: Vec::new(),
            mean_residual_n: Vec::new(),
        },
        low_amplitude_mismatch_percent: f64::NAN,
        high_amplitude_mismatch_percent: f64::NAN,
        low_frequency_mismatch_percent: f64::NAN,
        high_frequency_mismatch_percent: f64::NAN,
        summary,
    }
}
