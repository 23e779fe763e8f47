//! Sim-to-real gap diagnosis: how large the gap between a baseline model and the data is, where
//! it lies, which unmodelled effect causes it, and how far it shrinks once that effect is added.
//!
//! # Steps ([`diagnose`])
//! 1. **Gap.** The baseline is fitted on the sine steps (weighted least squares on one rebuilt
//!    period per step, see [`fit`]; the model force is band-limited to the harmonics the
//!    measured force was rebuilt from, and steps where the element sticks throughout,
//!    [`cycles::StepCycle::stuck`], are left out); the gap is its held-out NMSE of the mass acceleration
//!    (eq. 27) on the random records (and any steps held out), the model simulated on the
//!    measured base motion; per step, the phasor mismatch of the element force.
//! 2. **Where.** [`locate`]: per step (frequency, amplitude), per harmonic order (DC, 1st,
//!    2nd, ...), and over the state plane (bins of displacement and velocity; regions such as
//!    near zero velocity or large displacement).
//! 3. **Which effect.** Every candidate of [`effects::Effect`] not already in the baseline is
//!    added, its searched parameter (gap, yield, Stribeck velocity, cutoff, mass factor)
//!    chosen by leave-one-step-out cross-validation on the sine steps (the sensor family's
//!    member on one channel by the channel identities, [`sensor`]), the exciter delay
//!    estimated from the kinematic identity (a fit whose friction level, Stribeck excess,
//!    free-play spring or hysteretic force comes out negative is not that effect and is
//!    dropped); the model is refitted and simulated on the
//!    held-out records. Score: held-out NMSE times `N^(p/N)` (BIC with the effective number
//!    of independent held-out samples `N = 2 B T`, `p` the added parameters; see
//!    [`score::penalised`]). Candidates are ranked by score; candidates whose score is within
//!    the best one's excess over the noise floor are tied with it, and among them the one with
//!    the lowest cross-validated force error on the sine steps goes first if that error is below
//!    0.9 times the best's and it explains the gap by itself; a candidate whose error on the
//!    steps is below half the best's goes first even without a tie ([`step_tie_break`]). The second
//!    effect is then searched on what the top one leaves ([`pairs`]): every other candidate fitted
//!    jointly with the top one and scored the same way, then the exchange step (the best
//!    addition kept, the top one's best-ranked rivals tried in its place); when the best pair
//!    scores better than the top candidate alone its members rank first and second.
//! 4. **Verdict** ([`findings`], shared with the live and the axis diagnosis), with `floor` the noise floor estimated from the data:
//!    - a candidate's shrink is *significant* when its score beats the baseline's and it
//!      removes more than `max(floor, 10 % of the gap, 0.2 %-points)`;
//!    - **explained** when the top candidate is significant and leaves at most half of the
//!      excess gap (`gap_after - floor <= 0.5 (gap_before - floor)`);
//!    - **unexplained** when the gap exceeds `max(3 floor, 1 %)` but no candidate is
//!      significant, or the top one removes less than half of the excess;
//!    - **adequate** otherwise.
//!
//! The phasor-only variant for a live stream of harmonic analyses is [`PhasorDiagnosis`].

pub mod cycles;
pub mod design;
pub mod drift;
pub mod effects;
pub mod element_heldout;
pub mod exciter;
pub mod findings;
pub mod fit;
pub mod fitted_element;
pub mod free_play;
pub mod hysteresis;
pub mod locate;
pub mod multisine;
mod multisine_state;
pub mod output_error;
pub mod pair_partners;
pub mod pairs;
pub mod phasor;
mod ranking;
mod results;
pub mod sampled_records;
pub mod score;
pub mod search;
pub mod sensor;
pub mod series;
pub mod simulated_gap;
pub mod stribeck;
pub mod time_domain;

use thiserror::Error;

pub use effects::Effect;
pub use findings::{
    Evidence, Findings, PairEvidence, TopCandidate, Verdict, explains, significant, verdict,
};
pub use locate::Located;
pub use phasor::{PhasorDiagnosis, PhasorEffect, PhasorFindings};
pub use ranking::{DECISIVE_STEP_CV_RATIO, STEP_TIE_CV_RATIO, held_out_tie};
use ranking::{keep_best_member, pair_shown_by_steps, step_tie_break};
use results::parameter_values;
pub use results::{Diagnosis, DiagnosisDetail, PairResult, ParameterValue, RankedEffect};

use crate::identify::IdentifyError;
use crate::lstsq::LstsqError;
use crate::model::Model;
use crate::phasor::{HarmonicAnalysis, PhasorError, PhasorOptions, analyse_record};
use crate::recipe::Setup;
use crate::record::{Channel, Excitation, Record};
use crate::sim::SimError;
use fit::Fitted;
use score::{HeldOut, effective_samples, penalised, predict_record};

#[derive(Debug, Error)]
pub enum DiagnoseError {
    #[error(
        "no settled sine steps to fit the baseline on (the diagnosis fits on stepped-sine records, multisine records, or an element test's records with no steps)"
    )]
    NoSineSteps,
    #[error(transparent)]
    MeasuredState(#[from] crate::measured_state::MeasuredStateError),
    #[error(
        "no held-out records: the data hold no random records and no steps were held out; give validation data (--validate) or name steps to hold out"
    )]
    NoHeldOut,
    #[error("step {step} was named to hold out but the data have no such record")]
    UnknownStep { step: usize },
    #[error(
        "the diagnosis needs the base-excited rig (mass acceleration, base and relative displacement); this data set is {0}"
    )]
    NotRig(String),
    #[error(transparent)]
    Phasor(#[from] PhasorError),
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    #[error("fitting the baseline: {0}")]
    Lstsq(#[from] LstsqError),
    #[error("predicting held-out record {step}: {source}")]
    Simulation { step: usize, source: SimError },
}

/// Options of [`diagnose`].
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Sine steps to hold out (scored like the random records, not fitted).
    pub holdout_steps: Vec<usize>,
    /// Candidate effects to try (default: all).
    pub effects: Vec<Effect>,
    /// Whether to search a second effect jointly with the top one ([`pairs`]).
    pub pairs: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            holdout_steps: Vec::new(),
            effects: Effect::ALL.to_vec(),
            pairs: true,
        }
    }
}

/// The family member a fit stands for and its fitted shape (sensor_lowpass, series_compliance,
/// free_play, drift; see [`RankedEffect::member`]).
pub fn member_of(f: &Fitted, run: Option<&drift::RunDissipation>) -> Option<String> {
    f.structure
        .transform
        .sensor
        .map(|s| s.describe())
        .or_else(|| series::describe(f))
        .or_else(|| free_play::describe(f))
        .or_else(|| hysteresis::describe(f))
        .or_else(|| stribeck::describe(f))
        .or_else(|| drift::describe(f, run))
}

fn mass_of(setup: &Setup) -> Result<f64, DiagnoseError> {
    setup
        .rig_mass_kg()
        .ok_or_else(|| DiagnoseError::NotRig(format!("a {} setup", setup.kind())))
}

fn heldout_all(
    fitted: &Fitted,
    mass_kg: f64,
    records: &[&Record],
) -> Result<Vec<HeldOut>, DiagnoseError> {
    records
        .iter()
        .map(|r| {
            let element = fitted.element_at(r.start_time_s);
            predict_record(&element, mass_kg, r, &fitted.transform()).map_err(|source| {
                DiagnoseError::Simulation {
                    step: r.step,
                    source,
                }
            })
        })
        .collect()
}

fn mean_nmse(h: &[HeldOut]) -> f64 {
    h.iter().map(|h| h.nmse_percent).sum::<f64>() / h.len().max(1) as f64
}

/// Noise floor of the held-out NMSE: the measured acceleration's own noise (per-sample residual
/// of the periodic fit of the sine steps) counted twice (once in the measurement, once, through
/// the noisy measured base, in the prediction), relative to the held-out variance.
fn noise_floor_percent(analyses: &[HarmonicAnalysis], heldout: &[&Record]) -> f64 {
    let s2: Vec<f64> = analyses
        .iter()
        .filter_map(|a| a.channel(Channel::MassAccelerationMps2))
        .map(|c| c.residual_rms.powi(2))
        .collect();
    let noise2 = s2.iter().sum::<f64>() / s2.len().max(1) as f64;
    let var: Vec<f64> = heldout
        .iter()
        .filter_map(|r| r.channel(Channel::MassAccelerationMps2))
        .map(|a| {
            let m = a.iter().sum::<f64>() / a.len() as f64;
            a.iter().map(|v| (v - m).powi(2)).sum::<f64>() / a.len() as f64
        })
        .collect();
    let var = var.iter().sum::<f64>() / var.len().max(1) as f64;
    100.0 * 2.0 * noise2 / var.max(f64::MIN_POSITIVE)
}

/// Diagnoses the gap between `baseline` and `records` (fit on the sine steps, score on the
/// random records, the steps in `options.holdout_steps` and `validation`).
pub fn diagnose(
    setup: &Setup,
    baseline: &Model,
    records: &[Record],
    validation: &[Record],
    options: &DiagnoseOptions,
) -> Result<DiagnosisDetail, DiagnoseError> {
    let mass_kg = mass_of(setup)?;
    for s in &options.holdout_steps {
        if !records.iter().any(|r| r.step == *s) {
            return Err(DiagnoseError::UnknownStep { step: *s });
        }
    }
    let is_sine = |r: &Record| matches!(r.excitation, Excitation::Sine { .. });
    let fit_records: Vec<&Record> = records
        .iter()
        .filter(|r| is_sine(r) && !options.holdout_steps.contains(&r.step))
        .collect();
    let heldout: Vec<&Record> = records
        .iter()
        .filter(|r| !is_sine(r) || options.holdout_steps.contains(&r.step))
        .chain(validation.iter())
        .collect();
    if fit_records.is_empty() {
        return Err(DiagnoseError::NoSineSteps);
    }
    if heldout.is_empty() {
        return Err(DiagnoseError::NoHeldOut);
    }
    for r in &heldout {
        for c in [
            Channel::BaseDisplacementM,
            Channel::RelativeDisplacementM,
            Channel::MassAccelerationMps2,
        ] {
            if r.channel(c).is_none() {
                return Err(DiagnoseError::NotRig(format!(
                    "missing channel {} in record {}",
                    c.name(),
                    r.step
                )));
            }
        }
    }
    // Many harmonics: the even ones and DC carry the asymmetric effects.
    let popts = PhasorOptions::for_identification();
    let analyses: Vec<HarmonicAnalysis> = fit_records
        .iter()
        .map(|r| analyse_record(r, &popts))
        .collect::<Result<_, _>>()?;
    let effects: Vec<Effect> = options
        .effects
        .iter()
        .copied()
        .filter(|e| e.applies_to(setup.kind()))
        .collect();
    let search = search::search(setup, baseline, &analyses, &effects)?;
    let floor = noise_floor_percent(&analyses, &heldout);
    let n_eff = effective_samples(&heldout);
    let baseline_heldout = heldout_all(&search.baseline, mass_kg, &heldout)?;
    let gap_before = mean_nmse(&baseline_heldout);
    let baseline_score = penalised(gap_before, 0, n_eff);

    let mut ranked = Vec::new();
    let mut fits: Vec<(Fitted, Vec<HeldOut>)> = Vec::new();
    let mut notes = Vec::new();
    if let Some((f, gain)) = search.amplified_base {
        notes.push(format!(
            "the kinematic identity (x_o - x = x_i) shows the base the rig receives amplified over the recorded one, by {gain:.3} at {f:.2} Hz: exciter dynamics with a gain above 1 (a resonance of the exciter, its mount or the fixture), which no delay or lag gives, or a low-pass on the base displacement channel (the sensor_lowpass family); exciter_delay not offered"
        ));
    }
    let dissipation = drift::run_dissipation(records, mass_kg);
    let mut cand_idx = Vec::new();
    for (ci, c) in search.candidates.iter().enumerate() {
        // A candidate whose fitted model cannot be simulated (e.g. an unstable negative
        // stiffness) explains nothing: it is left out, with a note.
        let h = match heldout_all(&c.fitted, mass_kg, &heldout) {
            Ok(h) => h,
            Err(e) => {
                notes.push(format!("{}: left out: {e}", c.effect.name()));
                continue;
            }
        };
        let after = mean_nmse(&h);
        let extra = c.structure.extra_parameters;
        let score = penalised(after, extra, n_eff);
        ranked.push(RankedEffect {
            effect: c.effect,
            member: member_of(&c.fitted, dissipation.as_ref()),
            fitted_with: None,
            gap_after_percent: after,
            shrink_percent: gap_before - after,
            score_percent: score,
            phasor_cv_percent: c.cv_percent,
            output_error_misfit: None,
            extra_parameters: extra,
            added_parameters: parameter_values(c.fitted.added_parameters()),
            refitted_baseline: parameter_values(c.fitted.refitted_baseline()),
            significant: significant(gap_before, floor, after, score, baseline_score),
            added: c.effect.added().into(),
            signature: c.effect.signature().into(),
        });
        fits.push((c.fitted.clone(), h));
        cand_idx.push(ci);
    }
    // The Stribeck family's member of each exponent, each at its own best velocity: the
    // output-error refit tries each ([`output_error::refit_shape`]).
    let stribeck_members: Vec<Fitted> = ranked
        .iter()
        .zip(&fits)
        .filter(|(r, _)| r.effect == Effect::StribeckFriction)
        .map(|(_, f)| f.0.clone())
        .collect();
    keep_best_member(&mut ranked, &mut fits, &mut cand_idx);
    let mut order: Vec<usize> = (0..ranked.len()).collect();
    order.sort_by(|&a, &b| ranked[a].score_percent.total_cmp(&ranked[b].score_percent));
    let baseline_output_error_misfit = if options.holdout_steps.is_empty() {
        let context = output_error::Rescoring {
            steps: output_error::SineSteps {
                mass_kg,
                records,
                analyses: &analyses,
            },
            baseline,
            baseline_theta: &search.baseline.theta,
            heldout: &heldout,
            gap_before,
            floor,
            n_eff,
            baseline_score,
            stribeck_members: &stribeck_members,
        };
        let base = output_error::rescore(&context, &mut ranked, &mut fits, &order, &mut notes);
        order.sort_by(|&a, &b| ranked[a].score_percent.total_cmp(&ranked[b].score_percent));
        base
    } else {
        None
    };
    if let Some(k) = step_tie_break(&ranked, &order, gap_before, floor) {
        let i = order.remove(k);
        order.insert(0, i);
    }
    let best_pair = if options.pairs && ranked.len() >= 2 {
        let ctx = pairs::PairContext {
            setup,
            baseline,
            analyses: &analyses,
            search: &search,
            mass_kg,
            heldout: &heldout,
            n_eff,
            floor,
        };
        let structure = |i: usize| {
            let c = &search.candidates[cand_idx[i]];
            (c.effect, &c.structure, ranked[i].score_percent)
        };
        let ranked_effects: Vec<Effect> = ranked.iter().map(|r| r.effect).collect();
        let unranked =
            pair_partners::unranked_partners(baseline, &search, &effects, &ranked_effects);
        let others: Vec<(Effect, &effects::Structure, f64)> = order
            .iter()
            .skip(1)
            .map(|&i| structure(i))
            .chain(unranked.iter().map(|(e, s)| (*e, s, f64::INFINITY)))
            .collect();
        pairs::forward_pair(
            &ctx,
            structure(order[0]).1,
            ranked[order[0]].phasor_cv_percent,
            &others,
        )?
    } else {
        None
    };
    // When the pair scores better than the top candidate alone, its members rank first and
    // second: the best addition to the top candidate ahead of the alternatives to it, and after
    // an exchange ([`pairs::forward_pair`]) the pair's better-ranked member on top. When the
    // held-out records cannot tell the pair from the top one alone but the sine steps show the
    // second effect ([`pair_shown_by_steps`]), it ranks second, the top one staying first; a
    // pair without the top one that the steps show so ranks first and second.
    if let (Some(p), Some(&top)) = (&best_pair, order.first()) {
        let shown = pair_shown_by_steps(&ranked[top], p, floor);
        let holds_top = p.effects[0] == ranked[top].effect;
        let slots = if p.score_percent < ranked[top].score_percent || (shown && !holds_top) {
            0..2
        } else if shown {
            1..2
        } else {
            0..0
        };
        // A second member no ranked candidate stands for (its fit alone not physical or not
        // simulable) ranks second with the pair's figures; only beside a ranked first member,
        // so it never leads and `fits` needs no entry for it.
        if slots.contains(&1)
            && !ranked.iter().any(|r| r.effect == p.effects[1])
            && let Some(first) = ranked.iter().position(|r| r.effect == p.effects[0])
        {
            ranked.push(pair_partners::joint_only_entry(
                p,
                &ranked[first],
                gap_before,
            ));
            order.push(ranked.len() - 1);
        }
        for slot in slots {
            if let Some(k) = order
                .iter()
                .position(|&i| ranked[i].effect == p.effects[slot])
            {
                let i = order.remove(k);
                order.insert(slot, i);
            }
        }
    }
    let ranked: Vec<RankedEffect> = order.iter().map(|&i| ranked[i].clone()).collect();
    let mut fits: Vec<Option<(Fitted, Vec<HeldOut>)>> = fits.into_iter().map(Some).collect();
    let top_fit = order.first().and_then(|&i| fits[i].take());

    let mut findings = Findings::decide(
        Evidence::HeldOutNmse,
        gap_before,
        floor,
        ranked.first().map(|r| TopCandidate {
            effect: r.effect,
            gap_after_percent: r.gap_after_percent,
            significant: r.significant,
        }),
    );
    if let (Some(p), Some(top)) = (&best_pair, ranked.first()) {
        findings = findings.explained_by_pair(&PairEvidence {
            effects: p.effects,
            gap_after_percent: p.gap_after_percent,
            score_percent: p.score_percent,
            significant: significant(
                gap_before,
                floor,
                p.gap_after_percent,
                p.score_percent,
                baseline_score,
            ),
            single_score_percent: top.score_percent,
        });
    }
    if findings.top_effect == ranked.first().map(|r| r.effect) {
        findings.top_member = ranked.first().and_then(|r| r.member.clone());
    }
    let located = locate::locate(&search.baseline, &search.cycles);
    let diagnosis = Diagnosis {
        findings,
        baseline_model: baseline.name.clone(),
        baseline_parameters: parameter_values(
            search
                .baseline
                .names
                .iter()
                .zip(&search.baseline.theta)
                .zip(&search.baseline.std)
                .map(|((n, v), s)| (n.clone(), *v, *s))
                .collect(),
        ),
        fit_steps: fit_records.iter().map(|r| r.step).collect(),
        heldout_records: heldout.iter().map(|r| r.step).collect(),
        gap_before_by_record_percent: baseline_heldout.iter().map(|h| h.nmse_percent).collect(),
        ranked_effects: ranked,
        best_pair,
        located,
        baseline_phasor_cv_percent: search.baseline_cv_percent,
        baseline_output_error_misfit,
        kinematic_delay_s: search.exciter_delay.map(|(d, s)| [d, s]),
        notes,
    };
    let (after_fit, after_heldout) = match top_fit {
        Some((f, h)) => (Some(f), h),
        None => (None, Vec::new()),
    };
    let after_located = match &after_fit {
        Some(f) => Some(locate::locate(
            f,
            &search::cycles_for(setup, &analyses, &f.transform())?,
        )),
        None => None,
    };
    Ok(DiagnosisDetail {
        diagnosis,
        search,
        baseline_heldout,
        after_heldout,
        after_fit,
        after_located,
    })
}
