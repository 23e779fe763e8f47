//! `identify --model NAME+hysteresis` on records with no steps whose motion the bench did not
//! impose: a force-driven element test's (a single-DOF system on a shaker) and a base-excited
//! rig's. The fit along the measured motion (the hysteresis refit on every sample) differentiates
//! the noisy displacement, which biases it; it is the start of output error, which simulates the
//! mass under the measured input with the Bouc-Wen state and refits the terms, alpha, the yield
//! and each record's initial state ([`forcemap_math::pipeline::refine_hysteresis_on_records`]).
//! A force-driven held-out record is predicted the same way: its displacement simulated under
//! its measured force, from the initial state that fits it best with the model held.

use anyhow::Context;
use forcemap_math::diagnose::ParameterValue;
use forcemap_math::diagnose::element_heldout::TermFit;
use forcemap_math::identify::{Identification, records_drive};
use forcemap_math::model::Model;
use forcemap_math::pipeline::{
    HysteresisRefit, refine_hysteresis_on_records, validate_forced_hysteresis,
};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::ElementDrive;

/// Which records output error refines the fit on, and how they are simulated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Refinement {
    /// Sine steps, or a displacement drive: the force along the measured motion is the
    /// model's output, and its fit is final.
    AlongMotion,
    /// A force-driven element test's records with no steps: the mass simulated under the
    /// measured force.
    Forced { moving_mass_kg: Option<f64> },
    /// A base-excited rig's records with no steps: the mass simulated under the measured base.
    Rig { mass_kg: f64 },
}

impl Refinement {
    /// The refinement `records` of `setup` need: output error where none is a sine step and
    /// the bench drove the force (`drive`, else as the records say) or the base.
    pub fn of(setup: &Setup, drive: Option<ElementDrive>, records: &[Record]) -> Refinement {
        if records
            .iter()
            .any(|r| matches!(r.excitation, Excitation::Sine { .. }))
        {
            return Refinement::AlongMotion;
        }
        match setup {
            Setup::BaseExcited { mass_kg } => Refinement::Rig { mass_kg: *mass_kg },
            Setup::Element { moving_mass_kg, .. } => {
                let all: Vec<&Record> = records.iter().collect();
                match drive.unwrap_or_else(|| records_drive(&all)) {
                    ElementDrive::Force => Refinement::Forced {
                        moving_mass_kg: *moving_mass_kg,
                    },
                    ElementDrive::Displacement => Refinement::AlongMotion,
                }
            }
            Setup::DrivePoint { .. } => Refinement::AlongMotion,
        }
    }

    /// `start` (the fit along the measured motion) refined by output error on `records` (as
    /// read: a rig's, not their element view); None where the fit along the motion is final.
    pub fn refine(
        &self,
        baseline: &Model,
        records: &[Record],
        start: &TermFit,
    ) -> anyhow::Result<Option<HysteresisRefit>> {
        let setup = match *self {
            Refinement::AlongMotion => return Ok(None),
            Refinement::Forced { moving_mass_kg } => Setup::Element {
                moving_mass_kg,
                drive: Some(ElementDrive::Force),
            },
            Refinement::Rig { mass_kg } => Setup::BaseExcited { mass_kg },
        };
        let all: Vec<&Record> = records.iter().collect();
        let refit = refine_hysteresis_on_records(baseline, &setup, &all, start)
            .context("refining the fit by output error")?;
        Ok(Some(refit))
    }

    /// What the fit was refined on, for the summary line.
    pub fn describe(&self, records: usize) -> String {
        match self {
            Refinement::AlongMotion => String::new(),
            Refinement::Forced { .. } => format!(
                "refined by output error: the mass simulated under the measured force of {records} record(s), the terms, alpha, the yield, the loop's share r and each record's initial displacement, velocity and z fitted to the measured displacement (its exponent n held)"
            ),
            Refinement::Rig { .. } => format!(
                "refined by output error: the mass simulated under the measured base of {records} record(s), the terms, alpha, the yield, the loop's share r and each record's initial state fitted to the mass acceleration and the relative displacement (its exponent n held)"
            ),
        }
    }
}

/// The refined parameters with their standard deviations, then the searched values of
/// `start` (the fit along the motion) that output error held: the loop's exponent.
pub fn refined_parameters(id: &Identification, start: &[ParameterValue]) -> Vec<ParameterValue> {
    let mut out: Vec<ParameterValue> = id
        .parameters
        .iter()
        .map(|p| ParameterValue {
            name: p.name.clone(),
            value: p.value,
            std: Some(p.std),
        })
        .collect();
    let held: Vec<ParameterValue> = start
        .iter()
        .filter(|p| p.std.is_none() && !out.iter().any(|q| q.name == p.name))
        .cloned()
        .collect();
    out.extend(held);
    out
}

/// A force-driven `record`'s displacement simulated under its measured force with `fit`:
/// (NMSE [%], RMS error [m]).
pub fn predict_forced(
    baseline: &Model,
    fit: &TermFit,
    record: &Record,
) -> anyhow::Result<(f64, f64)> {
    let v = validate_forced_hysteresis(baseline, fit, record)?;
    Ok((v.nmse_percent, v.rms_error_m))
}
