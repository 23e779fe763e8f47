//! Which estimator an element test's data support when the model's form is not the element's.
//!
//! fd-multi weighs each step by its noise plus its form error and leaves a friction model's
//! velocity reversals out of theta's fit: at the Cramér-Rao bound when the form is right. When
//! the model misses the data by far more than their noise ([`FORM_WARNING_RATIO`]), no
//! estimator is right, and the one to trust is the one that predicts records it was not fitted
//! on. So, with the robust weighting (the default) on an element test whose fd-multi fit warns
//! of a wrong form, each step (record) is left out in turn, fd-multi and the time-domain least
//! squares of the force along the measured motion (`td-all`) are fitted to the others, and
//! each predicts the left-out record's force along its measured motion (the prediction of
//! `identify --validate`); the least squares is fitted to every step and reported when its mean
//! NMSE is lower by more than [`CHOICE_MARGIN`], fd-multi otherwise, with both scores.
//!
//! With fewer than [`MIN_CROSS_VALIDATION_STEPS`] steps the least squares is used without
//! scoring: each left-out fit would rest on two steps or fewer, too few to tell the
//! estimators apart, and the least squares' criterion is the very error a held-out test is
//! scored by. Measured on the UTFSM damper's second split (three tests, `linear`): leaving one
//! out favoured fd-multi (30.6 % against 35.8 %), which then predicted the three held-out tests
//! 1.55 times worse than the least squares.

use super::PipelineError;
use crate::diagnose::element_heldout::TermFit;
use crate::identify::{
    self, FORM_WARNING_RATIO, FdMultiOptions, Identification, Method, Weighting,
};
use crate::measured_state::MeasuredState;
use crate::model::Model;
use crate::phasor::HarmonicAnalysis;
use crate::recipe::Setup;
use crate::record::Record;

/// Fewest steps the choice is made on: with fewer, leaving one out leaves too little to fit,
/// and the least squares is used.
pub const MIN_CROSS_VALIDATION_STEPS: usize = 4;

/// How much better (relative) the time-domain least squares must predict the left-out steps to
/// be chosen: where both predict alike (a friction model of a friction element, whose sampled
/// jumps leave high harmonics above their noise and so warn of the form), fd-multi's efficiency
/// is kept.
pub const CHOICE_MARGIN: f64 = 0.05;

/// The time-domain least squares over every settled sample.
const TIME_DOMAIN: Method = Method::Td {
    points_per_step: None,
};

/// Whether [`choose_estimator`] applies to `fd`, the fd-multi identification of an element
/// test with `options`.
fn applies(setup: &Setup, method: Method, options: &FdMultiOptions, fd: &Identification) -> bool {
    matches!(setup, Setup::Element { .. })
        && method == Method::FdMulti
        && options.weighting == Weighting::Robust
        && fd
            .fit_quality
            .as_ref()
            .is_some_and(|q| q.residual_to_noise > FORM_WARNING_RATIO)
}

/// Mean NMSE [%] of `left_out`'s force predicted along its measured motion by `id`.
fn predicted_nmse(
    model: &Model,
    setup: &Setup,
    id: &Identification,
    left_out: &MeasuredState,
) -> f64 {
    left_out.force_nmse_percent(&TermFit::of_model(model, setup, &id.theta()))
}

/// The leave-one-step-out score of `method` on `analyses`: the mean NMSE [%] of each step's
/// force predicted by the fit to the other steps. None when a fit without some step fails
/// (that step alone determines a parameter).
fn cross_validation_nmse(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    analyses: &[HarmonicAnalysis],
    states: &[(usize, MeasuredState)],
    options: &FdMultiOptions,
) -> Option<f64> {
    let mut sum = 0.0;
    for (step, state) in states {
        let others: Vec<HarmonicAnalysis> = analyses
            .iter()
            .filter(|a| a.step != *step)
            .cloned()
            .collect();
        let id = identify::identify(model, setup, method, records, &others, options).ok()?;
        sum += predicted_nmse(model, setup, &id, state);
    }
    Some(sum / states.len() as f64)
}

/// `fd` (fd-multi's identification of `analyses`), or the time-domain least squares when the
/// model's form is wrong and that predicts left-out steps better (see the module docs); the
/// returned identification says which was chosen and why.
pub fn choose_estimator(
    model: &Model,
    setup: &Setup,
    method: Method,
    records: &[Record],
    analyses: &[HarmonicAnalysis],
    options: &FdMultiOptions,
    fd: Identification,
) -> Result<Identification, PipelineError> {
    if !applies(setup, method, options, &fd) {
        return Ok(fd);
    }
    let mut steps: Vec<usize> = analyses.iter().map(|a| a.step).collect();
    steps.sort_unstable();
    steps.dedup();
    let states: Vec<(usize, MeasuredState)> = steps
        .iter()
        .filter_map(|s| {
            let r = records.iter().find(|r| r.step == *s)?;
            MeasuredState::of(r).ok().map(|m| (*s, m))
        })
        .collect();
    if states.len() != steps.len() {
        return Ok(fd);
    }
    if states.len() < MIN_CROSS_VALIDATION_STEPS {
        let reason = format!(
            "the model's form is not the element's and {} steps are too few to choose an estimator by leaving one out (at least {MIN_CROSS_VALIDATION_STEPS}): the time-domain least squares of the force along the measured motion, whose criterion is the force error itself",
            states.len()
        );
        return time_domain_in_place_of(model, setup, records, analyses, options, fd, reason);
    }
    let score =
        |m: Method| cross_validation_nmse(model, setup, m, records, analyses, &states, options);
    let (Some(fd_score), Some(td_score)) = (score(Method::FdMulti), score(TIME_DOMAIN)) else {
        return Ok(fd);
    };
    let scores = format!(
        "mean NMSE of each of {} steps' force predicted by the fit to the others: fd-multi {fd_score:.2} %, time-domain least squares {td_score:.2} %",
        states.len()
    );
    if td_score < (1.0 - CHOICE_MARGIN) * fd_score {
        let reason = format!(
            "the model's form is not the element's, so the estimator is the one that predicts left-out steps best: the time-domain least squares of the force along the measured motion ({scores})"
        );
        time_domain_in_place_of(model, setup, records, analyses, options, fd, reason)
    } else {
        let mut fd = fd;
        fd.warnings.push(format!(
            "the model's form is not the element's; fd-multi predicts left-out steps within {:.0} % of the time-domain least squares or better ({scores})",
            100.0 * CHOICE_MARGIN
        ));
        Ok(fd)
    }
}

/// The time-domain least squares of every step in place of `fd`, with fd-multi's warnings,
/// `reason`, and fd-multi's fit against the noise (it says how wrong the form is).
fn time_domain_in_place_of(
    model: &Model,
    setup: &Setup,
    records: &[Record],
    analyses: &[HarmonicAnalysis],
    options: &FdMultiOptions,
    fd: Identification,
    reason: String,
) -> Result<Identification, PipelineError> {
    let mut td = identify::identify(model, setup, TIME_DOMAIN, records, analyses, options)?;
    let mut warnings = fd.warnings;
    warnings.push(reason);
    warnings.append(&mut td.warnings);
    td.warnings = warnings;
    td.fit_quality = fd.fit_quality;
    Ok(td)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::ModelOptions;
    use crate::phasor::PhasorOptions;
    use crate::pipeline::identify_records;
    use crate::sim::RunSpec;

    fn dyno_identification(model: &str) -> Identification {
        let records = RunSpec::damper_dyno(Some(40.0), 2).simulate().unwrap();
        identify_records(
            &Model::by_name(model, &ModelOptions::default()).unwrap(),
            &Setup::Element {
                moving_mass_kg: Some(0.8),
                drive: None,
            },
            Method::FdMulti,
            &records,
            &PhasorOptions::for_identification(),
            &FdMultiOptions::default(),
        )
        .unwrap()
    }

    /// The damper dyno's own model keeps fd-multi (its sampled friction jumps leave the high
    /// harmonics 5 times above their noise, so the form warning and the scoring run, and both
    /// estimators predict the left-out steps alike: 0.16 %). A `linear` model of the same
    /// damper (no preload, friction or asymmetry): the form is wrong, both estimators are
    /// scored on left-out steps and the choice is said.
    #[test]
    fn fd_multi_stays_where_the_estimators_predict_alike() {
        let right = dyno_identification("damper");
        assert_eq!(right.method, "fd-multi", "{:?}", right.warnings);
        let wrong = dyno_identification("linear");
        let said: Vec<&String> = wrong
            .warnings
            .iter()
            .filter(|w| w.contains("mean NMSE of each of 12 steps' force predicted"))
            .collect();
        assert_eq!(said.len(), 1, "{:?}", wrong.warnings);
        assert!(["fd-multi", "td-all"].contains(&wrong.method.as_str()));
        println!("{} | {}", wrong.method, said[0]);
    }
}
