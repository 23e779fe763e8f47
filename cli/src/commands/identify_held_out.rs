//! `--validate` of `forcemap identify`: the identified model predicting the records of
//! held-out files.

use anyhow::Context;
use forcemap_math::diagnose::findings::NO_PREDICTION_PERCENT;
use forcemap_math::identify::records_drive;
use forcemap_math::model::{IdentifiedModel, Model};
use forcemap_math::pipeline;
use forcemap_math::recipe::{Setup, SetupKind};
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::ElementDrive;

use crate::cli::IdentifyArgs;
use forcemap_io::steps::unlabelled::frequencies_from_data;

/// The records of a held-out file (`--validate` of identify and diagnose): a CSV export or a
/// bag (through the channel map `channels`, if any) of the same `kind` of setup as the data,
/// each sine step at the frequency its driven channel shows (the warnings printed).
pub fn held_out_records(
    path: &std::path::Path,
    channels: Option<&std::path::Path>,
    kind: SetupKind,
    frequency_tolerance: f64,
) -> anyhow::Result<Vec<Record>> {
    let mut held = forcemap_io::input::load_mapped(path, channels)?;
    if held.kind != kind {
        anyhow::bail!(
            "{}: validation data must hold the channels of the data's {} setup; these are a {} setup's",
            path.display(),
            kind,
            held.kind
        );
    }
    for w in frequencies_from_data(
        &mut held.records,
        kind.driven_channel(),
        frequency_tolerance,
    ) {
        eprintln!("warning: {}: {w}", path.display());
    }
    Ok(held.records)
}

/// One held-out record's prediction (`--validate`).
#[derive(Debug, Clone, serde::Serialize)]
pub(super) struct HeldOut {
    pub file: String,
    pub step: usize,
    /// NMSE of the element force (element test) or of the mass acceleration (rig) [%].
    nmse_percent: f64,
    /// RMS error of the element force [N] (element tests).
    rms_error_n: Option<f64>,
    /// RMS error of the mass acceleration [m/s^2] (rigs).
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_error_mps2: Option<f64>,
    /// A force-driven element test's displacement simulated under the record's measured force.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub simulated: Option<pipeline::ForcedValidation>,
}

/// The identified model on every record of the `--validate` files: an element test's force
/// predicted along each record's measured motion ([`pipeline::validate_element`], with the
/// moving mass of `setup`), a rig's simulated on each record's base ([`pipeline::validate_rig`]).
pub(super) fn held_out_validations(
    args: &IdentifyArgs,
    kind: SetupKind,
    setup: &Setup,
    model: &Model,
    theta: &[f64],
) -> anyhow::Result<Vec<HeldOut>> {
    let fitted = IdentifiedModel::new(model.clone(), theta[..model.terms.len()].to_vec());
    let mut out = Vec::new();
    for path in &forcemap_io::input::expand_paths(&args.validate)? {
        let file = path.display().to_string();
        let records = held_out_records(
            path,
            args.channels.as_deref(),
            kind,
            args.frequency_tolerance,
        )?;
        for r in &records {
            let context = || format!("{file}: validating on record {}", r.step);
            let held = match setup {
                Setup::Element {
                    moving_mass_kg,
                    drive,
                } => {
                    // The identified mass, when it is, follows theta.
                    let mass = moving_mass_kg.or_else(|| theta.get(model.terms.len()).copied());
                    let v = pipeline::validate_element(&fitted, mass.unwrap_or(0.0), r)
                        .with_context(context)?;
                    let forced = drive.unwrap_or_else(|| records_drive(&[r]))
                        == ElementDrive::Force
                        && !matches!(r.excitation, Excitation::Sine { .. });
                    let simulated = if forced {
                        Some(
                            pipeline::validate_forced_element(
                                model,
                                *moving_mass_kg,
                                None,
                                theta,
                                r,
                            )
                            .with_context(context)?,
                        )
                    } else {
                        None
                    };
                    (v.nmse_percent, Some(v.rms_error_n), simulated, None)
                }
                Setup::BaseExcited { mass_kg } => {
                    let v = pipeline::validate_rig(&fitted, *mass_kg, r).with_context(context)?;
                    (v.nmse_percent, None, None, Some(v.rms_error_mps2))
                }
                Setup::DrivePoint { .. } => anyhow::bail!(
                    "{file}: --validate predicts element tests and base-excited rigs; a drive-point setup's held-out records are not predicted"
                ),
            };
            out.push(HeldOut {
                file: file.clone(),
                step: r.step,
                nmse_percent: held.0,
                rms_error_n: held.1,
                simulated: held.2,
                rms_error_mps2: held.3,
            });
        }
    }
    Ok(out)
}

/// What a held-out line adds when its record is predicted no better than by zero: the fit's own
/// misfit may look modest while the model's form fails on a record unlike the fitted ones.
pub(super) fn no_better_than_zero(nmse_percent: f64) -> &'static str {
    if nmse_percent >= NO_PREDICTION_PERCENT {
        " (no better than predicting zero: the model's form fails on this record; `forcemap diagnose` names what it misses)"
    } else {
        ""
    }
}

pub(super) fn print_held_out(held: &[HeldOut]) {
    for h in held {
        if let Some(s) = &h.simulated {
            println!(
                "held out: {} record {}: displacement simulated under the measured force: NMSE {:.2} %, RMS error {:.3e} m{}",
                h.file,
                h.step,
                s.nmse_percent,
                s.rms_error_m,
                no_better_than_zero(s.nmse_percent)
            );
        }
        match h.rms_error_n {
            Some(rms) => println!(
                "held out: {} record {}: force NMSE {:.2} %, RMS error {:.3e} N{}",
                h.file,
                h.step,
                h.nmse_percent,
                rms,
                no_better_than_zero(h.nmse_percent)
            ),
            None => println!(
                "held out: {} record {}: NMSE of mass acceleration {:.2} % (eq. 27), RMS error {:.3e} m/s^2{}",
                h.file,
                h.step,
                h.nmse_percent,
                h.rms_error_mps2.unwrap_or(f64::NAN),
                no_better_than_zero(h.nmse_percent)
            ),
        }
    }
}
