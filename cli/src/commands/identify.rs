//! `forcemap identify FILE`: identify a model on a test-bench CSV export.

use std::collections::BTreeMap;

use anyhow::{Context, anyhow};
use forcemap_math::identify::{Identification, Method, TrackPoint};
use forcemap_math::model::{HYSTERESIS_SUFFIX, IdentifiedModel, ModelOptions};
use forcemap_math::phasor::{IDENTIFICATION_MAX_HARMONIC, PhasorOptions};
use forcemap_math::pipeline::{self, Validation};
use forcemap_math::recipe::Setup;
use forcemap_math::recipe::{ModelSpec, Recipe, SetupKind, SetupSpec, Tracking};
use forcemap_math::record::{Excitation, Record};
use serde_json::json;

use super::identify_held_out::{held_out_validations, print_held_out};
use super::{element_outputs, identify_plots, random_records};
use crate::cli::IdentifyArgs;
use forcemap_io::params::{Params, read_params};
use forcemap_io::spill::SpilledRecords;
use forcemap_io::steps::unlabelled::{frequencies_from_data, frequency_from_data};

/// The method asked for: `--method`, with `--td-points` (a number or `all`) for td.
fn method(args: &IdentifyArgs) -> anyhow::Result<Method> {
    match (args.method, &args.td_points) {
        (Method::Td { .. }, Some(points)) => format!("td-{points}").parse().map_err(|_| {
            anyhow!("--td-points: '{points}' is neither a positive whole number nor 'all'")
        }),
        (m, _) => Ok(m),
    }
}

/// The recipe of `forcemap identify` on data of `kind` with the constants they carry: flags
/// first, then the params file, then what the data carry.
pub fn recipe(
    args: &IdentifyArgs,
    kind: SetupKind,
    carried: &BTreeMap<String, f64>,
    file: &str,
) -> anyhow::Result<Recipe> {
    let params = match &args.params {
        Some(p) => read_params(p, None)?,
        None => Params::new(),
    };
    let mut setup = super::resolve_setup(
        kind,
        args.mass_kg,
        &params,
        args.params.as_deref(),
        carried,
        file,
    )?;
    if let Some(named) = args.drive {
        match &mut setup {
            SetupSpec::Element { drive, .. } => *drive = Some(named.into()),
            _ => anyhow::bail!(
                "{file}: --drive names what an element test's bench controlled; these data are a \
                 {kind} setup's"
            ),
        }
    }
    let model = args.model.parse::<ModelSpec>()?.with_options(ModelOptions {
        atan_slope_s_per_m: args.atan_m.or(params.opt_f64("atan_m")?),
        polynomial_order: args.poly_order,
    });
    Ok(Recipe {
        setup,
        model,
        method: method(args)?,
        weighting: args.weighting,
        phasor: phasor_options(args),
        tracking: Tracking::from_factor(args.forgetting_per_step)?,
    })
}

/// The phasor options of `forcemap identify`.
fn phasor_options(args: &IdentifyArgs) -> PhasorOptions {
    PhasorOptions {
        max_harmonic: args.max_harmonic.unwrap_or(IDENTIFICATION_MAX_HARMONIC),
        ..PhasorOptions::for_identification()
    }
}

/// The sine steps of a bag or export analysed as they are read (`Err`: the first analysis that
/// failed).
pub(super) type Streamed = pipeline::Analysed;

/// What `load` read: the data, the sine steps analysed as they were read (a streamed bag), and
/// the warnings of the labels the data corrected ([`frequency_from_data`]).
pub(super) struct Read {
    pub import: forcemap_io::input::Loaded,
    pub streamed: Option<Streamed>,
    pub frequency_warnings: Vec<String>,
    /// Samples of every record read, the analysed ones too.
    pub samples_read: usize,
    /// The band-random records read after a sine step of a streamed file, on disk
    /// ([`random_records`]).
    pub spilled: Option<SpilledRecords>,
}

/// Reads `files`, each sine step at the frequency its driven channel shows
/// ([`frequency_from_data`]). A rig's or drive-point bag, CSV export, MDF4 or TDMS file
/// identified by fd or fd-multi, converged and without plots, is streamed: each sine step is
/// analysed into its phasors as soon as it is read and dropped, so that memory does not grow
/// with the file; the analyses are returned with it. The band-random records after a sine step
/// wait on disk for the validation ([`random_records`]); the other records are kept.
pub(super) fn load(args: &IdentifyArgs, files: &[std::path::PathBuf]) -> anyhow::Result<Read> {
    check_frequency_tolerance(args.frequency_tolerance)?;
    let file = match files {
        [f] => forcemap_io::input::streams(f, args.channels.as_deref()).then_some(f),
        _ => None,
    };
    let streams = file.is_some()
        && args.plot.is_none()
        && matches!(method(args)?, Method::Fd | Method::FdMulti)
        && Tracking::from_factor(args.forgetting_per_step)? == Tracking::Converged
        && args.update_period_s.is_none();
    if !streams {
        let mut import = forcemap_io::input::load_files(files, args.channels.as_deref())?;
        let frequency_warnings = frequencies_from_data(
            &mut import.records,
            import.kind.driven_channel(),
            args.frequency_tolerance,
        );
        let samples_read = import.records.iter().map(Record::len).sum();
        return Ok(Read {
            import,
            streamed: None,
            frequency_warnings,
            samples_read,
            spilled: None,
        });
    }
    let mut sines = pipeline::SineStepStream::new(phasor_options(args));
    let mut frequency_warnings = Vec::new();
    // An element test's outputs need its sine steps' samples: kept whole.
    let mut element = false;
    let file = file.expect("streams only a single file");
    let mut samples_read = 0;
    // Progress as the records arrive (drawn from this thread only, so that nothing else
    // writes to stderr while it shows).
    let pb = indicatif::ProgressBar::new_spinner();
    let mut records_read = 0;
    let mut spilled = SpilledRecords::new();
    let mut spill_failed = None;
    let mut sine_read = false;
    let loaded = forcemap_io::input::load_reduced(file, args.channels.as_deref(), |kind, mut r| {
        samples_read += r.len();
        records_read += 1;
        pb.set_message(format!(
            "{}: {records_read} records read ({:.1} M samples)",
            file.display(),
            samples_read as f64 * 1e-6
        ));
        element = kind == SetupKind::Element;
        frequency_warnings.extend(frequency_from_data(
            &mut r,
            kind.driven_channel(),
            args.frequency_tolerance,
        ));
        if !element && random_records::spills(&r, sine_read) {
            if spill_failed.is_none()
                && let Err(e) = spilled.push(r)
            {
                spill_failed = Some(e);
            }
            return None;
        }
        if element || !matches!(r.excitation, Excitation::Sine { .. }) {
            return Some(r);
        }
        sine_read = true;
        sines.push(r);
        None
    });
    pb.finish_and_clear();
    let (import, said) = loaded?;
    if let Some(e) = spill_failed {
        return Err(anyhow::Error::new(e).context(format!(
            "{}: keeping its band-random records for the validation",
            file.display()
        )));
    }
    forcemap_io::input::print_said(&said);
    Ok(Read {
        import,
        streamed: (!element).then(|| sines.finish()),
        frequency_warnings,
        samples_read,
        spilled: (!spilled.is_empty()).then_some(spilled),
    })
}

/// Refuses a relative frequency tolerance that is negative or not finite.
pub fn check_frequency_tolerance(relative: f64) -> anyhow::Result<()> {
    if relative.is_finite() && relative >= 0.0 {
        Ok(())
    } else {
        Err(anyhow!(
            "--frequency-tolerance {relative}: a relative tolerance is a finite number >= 0"
        ))
    }
}

/// How the data are named in messages: the file, or the first and how many more.
pub fn data_name(files: &[std::path::PathBuf]) -> String {
    match files {
        [one] => one.display().to_string(),
        [first, rest @ ..] => format!("{} (+{} files)", first.display(), rest.len()),
        [] => String::new(),
    }
}

pub fn run(args: &IdentifyArgs) -> anyhow::Result<()> {
    if let Some(base) = args.model.strip_suffix(HYSTERESIS_SUFFIX) {
        return super::identify_hysteresis::run(args, base);
    }
    let files = forcemap_io::input::expand_paths(&args.files)?;
    let file = data_name(&files);
    let Read {
        import,
        mut streamed,
        frequency_warnings,
        spilled,
        ..
    } = load(args, &files)?;
    if !import.ignored_columns.is_empty() {
        eprintln!(
            "notice: {file}: ignored columns not in the contract: {}",
            import.ignored_columns.join(", ")
        );
    }
    let recipe = recipe(args, import.kind, &import.parameters, &file)?;
    let setup = recipe.setup.setup()?;
    let model = recipe.model.build()?;
    let method = recipe.method;
    let what = || {
        format!(
            "{file}: identifying model '{}' by {}",
            model.name,
            method.name()
        )
    };
    // Tracking: theta after every step, as the live identifier publishes it; the last is the
    // current one. Converged: one theta from every step.
    let (mut id, track, analyses) = match (recipe.tracking, args.update_period_s) {
        (Tracking::Converged, None) => {
            let (id, analyses) = match streamed.take() {
                Some(analysed) => analysed.and_then(|(analyses, notes)| {
                    pipeline::identify_analysed(
                        &model,
                        &setup,
                        method,
                        &import.records,
                        analyses,
                        notes,
                        &recipe.fd_options(),
                    )
                }),
                None => pipeline::identify_records_with_analyses(
                    &model,
                    &setup,
                    method,
                    &import.records,
                    &recipe.phasor,
                    &recipe.fd_options(),
                ),
            }
            .with_context(what)?;
            (id, Vec::new(), analyses)
        }
        (tracking, update_period_s) => {
            let (track, analyses) = pipeline::track_records_with_analyses(
                &model,
                &setup,
                method,
                &import.records,
                &recipe.phasor,
                &recipe.fd_options(),
                tracking.factor_per_step(),
                update_period_s,
            )
            .with_context(|| format!("{} (tracking)", what()))?;
            let id = track
                .last()
                .map(|t| t.identification.clone())
                .context("tracking gave no theta")?;
            (id, track, analyses)
        }
    };
    // The labels the data corrected come first, as the reader's notes do.
    id.warnings.splice(0..0, frequency_warnings);

    // Validation on the random records (rig only: the model is simulated on the measured base).
    let validations = match setup {
        Setup::BaseExcited { mass_kg } => {
            let fitted = IdentifiedModel::new(model.clone(), id.theta());
            random_records::validate_rig(&fitted, mass_kg, &import.records, spilled, &file)?
        }
        _ => Vec::new(),
    };
    // The element force with the parameters the setup added (an identified moving mass).
    let theta = id.theta();
    let element_setup = setup.with_extra_values(&id.extra_values(&setup));
    let held_out = held_out_validations(args, import.kind, &element_setup, &model, &theta)?;
    let element_steps = if setup.kind() == SetupKind::Element {
        element_outputs::element_steps(&element_setup, &model, &theta, &analyses, &import.records)
            .with_context(|| format!("{file}: the dynamic stiffness table"))?
    } else {
        Vec::new()
    };
    if let Some(dir) = &args.plot {
        identify_plots::write_plots(
            dir,
            &element_setup,
            &model,
            &id,
            &analyses,
            &import.records,
            &validations,
        )?;
        if !element_steps.is_empty() {
            element_outputs::write_plots(dir, &element_steps, &model.name)?;
        }
        identify_plots::write_held_out_plots(dir, &held_out)?;
    }
    if args.json {
        let mut json = identification_json(&recipe, &id, &validations, &import.ignored_columns);
        json["held_out"] = serde_json::to_value(&held_out)?;
        if !track.is_empty() {
            json["track"] = track
                .iter()
                .map(|t| {
                    json!({
                        "step": t.step,
                        "provisional": t.provisional,
                        "data_end_s": t.data_end_s,
                        "steps_used": t.identification.steps_used,
                        "parameters": t.identification.parameters.iter().map(|p| json!({"name": p.name, "value": p.value, "std": p.std})).collect::<Vec<_>>(),
                    })
                })
                .collect();
        }
        if !element_steps.is_empty() {
            json["dynamic_stiffness"] =
                serde_json::to_value(element_steps.iter().map(|s| &s.point).collect::<Vec<_>>())?;
        }
        println!("{json}");
    } else {
        print_identification(&file, &id, &validations);
        print_held_out(&held_out);
        print_track(&track);
        if !element_steps.is_empty() {
            element_outputs::print_table(&element_steps);
        }
    }
    Ok(())
}

/// The identification as JSON, with the recipe that produced it.
pub fn identification_json(
    recipe: &Recipe,
    id: &Identification,
    validations: &[Validation],
    ignored: &[String],
) -> serde_json::Value {
    json!({
        "recipe": recipe,
        "model": id.model,
        "method": id.method,
        "parameters": id.parameters.iter().map(|p| json!({"name": p.name, "value": p.value, "std": p.std})).collect::<Vec<_>>(),
        "condition_number": id.condition_number,
        "equations": id.equations,
        "r": id.r.iter().map(|(n, x)| (n.clone(), json!(x))).collect::<serde_json::Map<_, _>>(),
        "covariance": id.covariance,
        "residual_rms": id.residual_rms,
        "fit_quality": id.fit_quality,
        "steps_used": id.steps_used,
        "validation": validations.iter().map(|v| json!({"step": v.step, "nmse_percent": v.nmse_percent, "rms_error_mps2": v.rms_error_mps2})).collect::<Vec<_>>(),
        "warnings": id.warnings,
        "ignored_columns": ignored,
    })
}

/// Theta after every step of a tracking identification, one row per step (and per update
/// within a step, marked provisional), with the end of the data it describes.
fn print_track(track: &[TrackPoint]) {
    let Some(first) = track.first() else {
        return;
    };
    println!("tracked theta after each step (the table above is the last row):");
    let names: Vec<&str> = first
        .identification
        .parameters
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    println!(
        "{:>6} {:>12} {:>12} {}",
        "step",
        "",
        "data end [s]",
        names.iter().map(|n| format!("{n:>14}")).collect::<String>()
    );
    for t in track {
        println!(
            "{:>6} {:>12} {:>12.3} {}",
            t.step,
            if t.provisional { "provisional" } else { "" },
            t.data_end_s,
            t.identification
                .parameters
                .iter()
                .map(|p| format!("{:>14.6e}", p.value))
                .collect::<String>()
        );
    }
}

fn print_identification(file: &str, id: &Identification, validations: &[Validation]) {
    println!(
        "{file}: model {} by {} ({} equations from steps {:?})",
        id.model, id.method, id.equations, id.steps_used
    );
    println!(
        "{:<8} {:>16} {:>12} {:>8}",
        "param", "value", "std", "r [%]"
    );
    for (p, (_, r)) in id.parameters.iter().zip(&id.r) {
        println!(
            "{:<8} {:>16.6e} {:>12.3e} {:>8.1}",
            p.name, p.value, p.std, r
        );
    }
    println!(
        "condition number {:.3e}, residual RMS {:.3e}",
        id.condition_number, id.residual_rms
    );
    if let Some(q) = &id.fit_quality {
        println!("fit against the noise: {}", q.summary());
    }
    for v in validations {
        println!(
            "validation on random record {}: NMSE of mass acceleration {:.2} % (eq. 27), RMS error {:.3e} m/s^2",
            v.step, v.nmse_percent, v.rms_error_mps2
        );
    }
    for w in forcemap_io::messages::grouped(&id.warnings) {
        println!("warning: {w}");
    }
}
