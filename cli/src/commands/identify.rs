//! `forcemap identify FILE`: identify a model on a test-bench CSV export.

use anyhow::{Context, bail};
use forcemap_math::identify::{FdMultiOptions, Identification, Method, Setup, rebuilt_cycle};
use forcemap_math::model::{IdentifiedModel, Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::{self, Validation};
use forcemap_math::record::Excitation;
use serde_json::json;

use crate::cli::{IdentifyArgs, MethodArg};
use crate::plot::{self, ForceStateStep};
use forcemap_io::csv_export::CsvProfile;
use forcemap_io::params::{Params, read_params};

fn method(args: &IdentifyArgs) -> anyhow::Result<Method> {
    Ok(match args.method {
        MethodArg::Fd => Method::Fd,
        MethodArg::FdMulti => Method::FdMulti,
        MethodArg::OutputError => Method::OutputError,
        MethodArg::Td => {
            Method::Td {
                points_per_step: if args.td_points == "all" {
                    None
                } else {
                    Some(args.td_points.parse().ok().filter(|n: &usize| *n > 0).with_context(|| {
                    format!("--td-points: '{}' is neither a positive whole number nor 'all'", args.td_points)
                })?)
                },
            }
        }
    })
}

pub fn run(args: &IdentifyArgs) -> anyhow::Result<()> {
    let file = args.file.display().to_string();
    let import = forcemap_io::input::load(&args.file)?;
    if !import.ignored_columns.is_empty() {
        eprintln!(
            "notice: {file}: ignored columns not in the contract: {}",
            import.ignored_columns.join(", ")
        );
    }
    let params = match &args.params {
        Some(p) => read_params(p, None)?,
        None => Params::new(),
    };
    let params_source = args
        .params
        .as_ref()
        .map_or("no --params file".to_string(), |p| p.display().to_string());
    let setup = match import.profile {
        CsvProfile::Rig => {
            // flag, then params file, then the constants the bag carries
            let mass_kg = match (
                args.mass_kg,
                params.opt_f64("mass_kg")?,
                import.parameters.get("mass_kg"),
            ) {
                (Some(m), _, _) | (None, Some(m), _) | (None, None, Some(&m)) => m,
                (None, None, None) => bail!(
                    "{file}: the rig's mass is needed: give --mass-kg 36 or mass_kg in a --params file ({params_source})"
                ),
            };
            if !(mass_kg > 0.0 && mass_kg.is_finite()) {
                bail!("mass_kg = {mass_kg}: the rig's mass must be a positive number of kg");
            }
            Setup::BaseExcited { mass_kg }
        }
        CsvProfile::DrivePoint => Setup::DrivePoint {
            substructure: forcemap_io::rig_constants::substructure(&params, &params_source)?,
        },
    };
    let atan_m = args.atan_m.or(params.opt_f64("atan_m")?);
    let poly = args.poly_order;
    let model = Model::by_name(
        &args.model,
        &ModelOptions {
            atan_slope_s_per_m: atan_m,
            polynomial_order: poly,
        },
    )?;
    let method = method(args)?;
    let phasor_options = PhasorOptions {
        max_harmonic: args.max_harmonic.unwrap_or(100),
        ..PhasorOptions::default()
    };
    let (id, analyses) = pipeline::identify_records_with_analyses(
        &model,
        &setup,
        method,
        &import.records,
        &phasor_options,
        &FdMultiOptions::default(),
    )
    .with_context(|| {
        format!(
            "{file}: identifying model '{}' by {}",
            model.name,
            method.name()
        )
    })?;

    // Validation on the random records (rig only: the model is simulated on the measured base).
    let mut validations = Vec::new();
    if let Setup::BaseExcited { mass_kg } = setup {
        let fitted = IdentifiedModel::new(model.clone(), id.theta());
        for rec in import
            .records
            .iter()
            .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        {
            validations.push(
                pipeline::validate_rig(&fitted, mass_kg, rec)
                    .with_context(|| format!("{file}: validating on random record {}", rec.step))?,
            );
        }
    }
    if let Some(dir) = &args.plot {
        write_plots(
            dir,
            &setup,
            &model,
            &id,
            &analyses,
            &import.records,
            &validations,
        )?;
    }
    if args.json {
        println!(
            "{}",
            identification_json(&id, &validations, &import.ignored_columns)
        );
    } else {
        print_identification(&file, &id, &validations);
    }
    Ok(())
}

/// Force-state map of the fit and, for the rig, the validation time traces.
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

pub fn identification_json(
    id: &Identification,
    validations: &[Validation],
    ignored: &[String],
) -> serde_json::Value {
    json!({
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
    for w in &id.warnings {
        println!("warning: {w}");
    }
}
