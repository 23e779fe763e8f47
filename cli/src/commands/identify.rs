//! `forcemap identify FILE`: identify a model on a test-bench CSV export.

use std::collections::BTreeMap;

use anyhow::{Context, anyhow};
use forcemap_math::identify::{Identification, Method, TrackPoint, rebuilt_cycle};
use forcemap_math::model::{IdentifiedModel, Model, ModelOptions};
use forcemap_math::phasor::{HarmonicAnalysis, IDENTIFICATION_MAX_HARMONIC, PhasorOptions};
use forcemap_math::pipeline::{self, Validation};
use forcemap_math::recipe::Setup;
use forcemap_math::recipe::{ModelSpec, Recipe, SetupKind, Tracking};
use forcemap_math::record::Excitation;
use serde_json::json;

use super::element_outputs;
use crate::cli::IdentifyArgs;
use crate::plot::{self, ForceStateStep};
use forcemap_io::params::{Params, read_params};

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
    let setup = super::resolve_setup(
        kind,
        args.mass_kg,
        &params,
        args.params.as_deref(),
        carried,
        file,
    )?;
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

/// The sine steps of a bag analysed as they are read (`Err`: the first analysis that failed).
type Streamed = Result<(Vec<HarmonicAnalysis>, Vec<String>), pipeline::PipelineError>;

/// Reads `args.files`. A rig's or drive-point bag identified by fd or fd-multi, converged and
/// without plots, is streamed: each sine step is analysed into its phasors as soon as it is
/// complete and dropped, so that memory does not grow with the bag (the other records are
/// kept, for validation); the analyses are returned with it.
fn load(
    args: &IdentifyArgs,
    files: &[std::path::PathBuf],
) -> anyhow::Result<(forcemap_io::input::Loaded, Option<Streamed>)> {
    let single_bag = match files {
        [f] => forcemap_io::input::is_bag(f).then_some(f),
        _ => None,
    };
    let Some(bag) = single_bag.filter(|_| args.channels.is_none()) else {
        let import = forcemap_io::input::load_files(files, args.channels.as_deref())?;
        return Ok((import, None));
    };
    let streams = args.plot.is_none()
        && args.plot.is_none()
        && matches!(method(args)?, Method::Fd | Method::FdMulti)
        && Tracking::from_factor(args.forgetting_per_step)? == Tracking::Converged
        && args.update_period_s.is_none();
    if !streams {
        return Ok((forcemap_io::input::load(bag)?, None));
    }
    let phasor = phasor_options(args);
    let mut streamed: Streamed = Ok((Vec::new(), Vec::new()));
    // An element test's outputs need its sine steps' samples: kept whole.
    let mut element = false;
    let import = forcemap_io::input::load_bag_reduced(bag, |kind, r| {
        element = kind == SetupKind::Element;
        let Ok((analyses, notes)) = &mut streamed else {
            return Some(r);
        };
        if element || !matches!(r.excitation, Excitation::Sine { .. }) {
            return Some(r);
        }
        match pipeline::analyse_sine_step(&r, &phasor) {
            Ok((an, note)) => {
                analyses.push(an);
                notes.extend(note);
                None
            }
            Err(e) => {
                streamed = Err(e.into());
                Some(r)
            }
        }
    })?;
    Ok((import, (!element).then_some(streamed)))
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
    let files = forcemap_io::input::expand_paths(&args.files)?;
    let file = data_name(&files);
    let (import, mut streamed) = load(args, &files)?;
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
    let (id, track, analyses) = match (recipe.tracking, args.update_period_s) {
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

    // Validation on the random records (rig only: the model is simulated on the measured base).
    let validations = match setup {
        Setup::BaseExcited { mass_kg } => {
            let fitted = IdentifiedModel::new(model.clone(), id.theta());
            pipeline::validate_rig_on_random_records(&fitted, mass_kg, &import.records)
                .with_context(|| format!("{file}: validating on the random records"))?
        }
        _ => Vec::new(),
    };
    // The element force with the parameters the setup added (an identified moving mass).
    let theta = id.theta();
    let element_setup = setup.with_extra_values(&id.extra_values(&setup));
    let element_steps = if setup.kind() == SetupKind::Element {
        element_outputs::element_steps(&element_setup, &model, &theta, &analyses, &import.records)
            .with_context(|| format!("{file}: the dynamic stiffness table"))?
    } else {
        Vec::new()
    };
    if let Some(dir) = &args.plot {
        write_plots(
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
    }
    if args.json {
        let mut json = identification_json(&recipe, &id, &validations, &import.ignored_columns);
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
        print_track(&track);
        if !element_steps.is_empty() {
            element_outputs::print_table(&element_steps);
        }
    }
    Ok(())
}

/// Force-state map of the fit (the element force of `setup`, whose identified extra
/// parameters are set) and, for the rig, the validation time traces.
fn write_plots(
    dir: &std::path::Path,
    setup: &Setup,
    model: &Model,
    id: &Identification,
    analyses: &[forcemap_math::phasor::HarmonicAnalysis],
    records: &[forcemap_math::record::Record],
    validations: &[Validation],
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("creating the plot directory {}", dir.display()))?;
    let theta = id.theta();
    let mut steps = Vec::new();
    for an in analyses {
        let cyc = rebuilt_cycle(setup, an, 256)?;
        let model_force_n = cyc
            .displacement_m
            .iter()
            .zip(&cyc.velocity_mps)
            .map(|(x, v)| model.force(&theta, *x, *v))
            .collect();
        steps.push(ForceStateStep {
            label: format!("step {} ({:.2} Hz)", an.step, an.frequency_hz),
            displacement_m: cyc.displacement_m,
            velocity_mps: cyc.velocity_mps,
            measured_force_n: cyc.force_n,
            model_force_n,
        });
    }
    let path = dir.join("force_state.svg");
    let title = format!(
        "force-state map: measured element force (points) and model {} by {} (lines)",
        id.model, id.method
    );
    plot::force_state_map(&path, &title, &steps)?;
    eprintln!("wrote {}", path.display());
    for v in validations {
        let Some(rec) = records.iter().find(|r| r.step == v.step) else {
            continue;
        };
        let t: Vec<f64> = (0..v.measured_mass_acceleration_mps2.len())
            .map(|i| rec.time_s(i))
            .collect();
        let path = dir.join(format!("validation_step{}.svg", v.step));
        let title = format!(
            "record {}: mass acceleration, measured and predicted by the identified model (NMSE {:.2} %)",
            v.step, v.nmse_percent
        );
        plot::time_trace(
            &path,
            &title,
            &t,
            &v.measured_mass_acceleration_mps2,
            &v.predicted_mass_acceleration_mps2,
            "mass acceleration [m/s^2]",
        )?;
        eprintln!("wrote {}", path.display());
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
        "steps_used": id.steps_used,
        "validation": validations.iter().map(|v| json!({"step": v.step, "nmse_percent": v.nmse_percent})).collect::<Vec<_>>(),
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
    for v in validations {
        println!(
            "validation on random record {}: NMSE of mass acceleration {:.2} % (eq. 27)",
            v.step, v.nmse_percent
        );
    }
    for w in forcemap_io::messages::grouped(&id.warnings) {
        println!("warning: {w}");
    }
}
