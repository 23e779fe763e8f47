//! A model with a Bouc-Wen state refined by output error on records driven by a sampled
//! input: a force-driven element test's (the mass simulated under the measured force, its
//! displacement compared) and a base-excited rig's records with no steps (the mass simulated
//! under the measured base, its acceleration and the relative displacement compared).
//!
//! The start is the fit along the measured motion (the terms, the moving mass, the state's
//! force coefficient and its law, z integrated from rest), whose velocity and acceleration are
//! differentiated from the noisy displacement: errors in variables bias it (friction low,
//! damping high). Output error keeps the law's exponent n and fits the terms, the mass where it
//! is unknown, alpha, the yield and the share r, with each record's initial displacement,
//! velocity and state z, so records may start in motion with the loop anywhere.

use super::PipelineError;
use super::element::{ForcedValidation, validate_forced_element};
use crate::diagnose::element_heldout::TermFit;
use crate::identify::{
    HYSTERESIS_PARAMETERS, Identification, IdentifyError, Parameter, RecordsOutputError,
};
use crate::model::Model;
use crate::recipe::Setup;
use crate::record::Record;
use crate::signal::bouc_wen::HysteresisLaw;

/// The refined model: its identification (the terms, the mass where fitted, alpha, the yield
/// and r, with their standard deviations) and the same as the element force a held-out
/// record is predicted with.
#[derive(Debug, Clone)]
pub struct HysteresisRefit {
    pub identification: Identification,
    pub fit: TermFit,
}

/// Refines `start` (with its hysteresis) by output error on `records` of `setup` (a
/// force-driven element test, or a base-excited rig); see the module docs.
pub fn refine_hysteresis_on_records(
    model: &Model,
    setup: &Setup,
    records: &[&Record],
    start: &TermFit,
) -> Result<HysteresisRefit, PipelineError> {
    let step = records.first().map_or(0, |r| r.step);
    let Some((law, alpha)) = start.hysteresis else {
        return Err(IdentifyError::Step {
            step,
            problem: "the start has no hysteresis state".into(),
        }
        .into());
    };
    let (problem, fitted_mass) = match setup {
        Setup::Element { moving_mass_kg, .. } => (
            RecordsOutputError::forced(model, *moving_mass_kg, records)?,
            moving_mass_kg.is_none(),
        ),
        Setup::BaseExcited { mass_kg } => {
            (RecordsOutputError::rig(model, *mass_kg, records)?, false)
        }
        Setup::DrivePoint { .. } => {
            return Err(IdentifyError::Step {
                step,
                problem: "a hysteresis state is refined by output error on element tests and rigs, not on the drive-point setup".into(),
            }
            .into());
        }
    };
    let mut parameters: Vec<Parameter> = model
        .terms
        .iter()
        .zip(&start.theta)
        .map(|(t, v)| parameter(t.symbol(), *v))
        .collect();
    if fitted_mass {
        parameters.push(parameter(setup.extra_parameters()[0].into(), start.mass_kg));
    }
    for (name, value) in HYSTERESIS_PARAMETERS
        .iter()
        .zip([alpha, law.yield_m, law.r])
    {
        parameters.push(parameter((*name).into(), value));
    }
    let first = Identification {
        model: format!("{}+hysteresis", model.name),
        method: "time-domain".into(),
        covariance: vec![vec![0.0; parameters.len()]; parameters.len()],
        parameters,
        condition_number: f64::NAN,
        equations: 0,
        r: Vec::new(),
        residual_rms: f64::NAN,
        steps_used: records.iter().map(|r| r.step).collect(),
        fit_quality: None,
        misfit_noise_std: None,
        warnings: Vec::new(),
    };
    let mut identification = problem.with_hysteresis(law).fit(&first)?;
    identification.model = first.model;
    let values = identification.theta();
    let p = model.terms.len();
    let at = p + usize::from(fitted_mass);
    let fit = TermFit {
        terms: model.terms.clone(),
        theta: values[..p].to_vec(),
        mass_kg: if fitted_mass {
            values[p]
        } else {
            start.mass_kg
        },
        hysteresis: Some((
            HysteresisLaw {
                yield_m: values[at + 1],
                r: values[at + 2],
                ..law
            },
            values[at],
        )),
    };
    Ok(HysteresisRefit {
        identification,
        fit,
    })
}

/// A force-driven `record`'s displacement simulated under its measured force with `fit` (the
/// terms, the moving mass and the Bouc-Wen state), from the initial state (x, v and z) that
/// fits it best with the model held.
pub fn validate_forced_hysteresis(
    model: &Model,
    fit: &TermFit,
    record: &Record,
) -> Result<ForcedValidation, PipelineError> {
    let Some((law, alpha)) = fit.hysteresis else {
        return Err(IdentifyError::Step {
            step: record.step,
            problem: "the fit has no hysteresis state to simulate".into(),
        }
        .into());
    };
    let mut element = fit.theta.clone();
    element.extend([alpha, law.yield_m, law.r]);
    validate_forced_element(model, Some(fit.mass_kg), Some(law), &element, record)
}

fn parameter(name: String, value: f64) -> Parameter {
    Parameter {
        name,
        value,
        std: f64::NAN,
    }
}
