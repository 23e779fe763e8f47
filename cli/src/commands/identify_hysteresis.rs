//! `forcemap identify --model NAME+hysteresis`: an element test's (or a rig's) model with a
//! Bouc-Wen hysteresis state beside its terms, fitted as `diagnose` refits a baseline with its
//! hysteresis candidate (one way to fit it, not a second): the yield and the loop's shape
//! searched and chosen by leave-one-step-out prediction of the element force, the coefficients
//! by least squares on every step. Held-out records (`--validate`) are predicted along their
//! measured motion with the state integrated from rest.
//!
//! A base-excited rig's sine steps are fitted as the element between base and mass (its force
//! the one that holds the mass, -m a_o, along the relative motion), and its held-out records
//! (the export's records with no steps, and `--validate`) are predicted as the rig's own are:
//! the mass simulated under each record's measured base displacement, with the fitted element
//! (its friction's stick-slip and its Bouc-Wen state), scored on the mass acceleration.
//!
//! Records with no steps whose motion the bench did not impose (a force-driven element test's,
//! a rig's) are fitted along the measured motion, then refined by output error
//! ([`super::identify_hysteresis_records`]); a force-driven held-out record's displacement is
//! simulated under its measured force.
//!
//! Sine steps are fitted either on one rebuilt period each (the diagnosis' fit, each test
//! counted once) or on their samples (the least squares of the force along the measured
//! motion, each test counted by its length), chosen as `identify` chooses between fd-multi and
//! the time-domain least squares for a model of terms
//! ([`forcemap_math::pipeline::choose_estimator`]): each step left out in turn, both fitted
//! to the others and the left-out step's force predicted along its measured motion; the
//! samples where their mean NMSE is lower by more than the same margin, the periods otherwise;
//! with fewer steps than that choice needs, the samples (their criterion is the force error a
//! held-out test is scored by).

use anyhow::{Context, bail};
use forcemap_math::diagnose::PhasorEffect;
use forcemap_math::diagnose::{Effect, ParameterValue};
use forcemap_math::model::{HYSTERESIS_SUFFIX, Model, ModelOptions};
use forcemap_math::pipeline::validate_element_fit;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::ElementDrive;
use serde_json::json;

use super::diagnose::{Data, ElementFit, Fitted, PeriodicFit, fit_element_steps};
use super::identify::{check_frequency_tolerance, data_name};
use super::identify_held_out::{held_out_records, no_better_than_zero};
use super::identify_hysteresis_records::{Refinement, predict_forced, refined_parameters};
use super::identify_plots::{LoopRecord, write_loop_plots};
use crate::cli::IdentifyArgs;
use forcemap_io::steps::unlabelled::frequencies_from_data;
use forcemap_math::diagnose::effects::Transform;
use forcemap_math::diagnose::element_heldout::TermFit;
use forcemap_math::diagnose::fitted_element::FittedElement;
use forcemap_math::diagnose::sampled_records::element_view_of_rig;
use forcemap_math::diagnose::score::predict_record;
use forcemap_math::measured_state::MeasuredState;
use forcemap_math::pipeline::{CHOICE_MARGIN, MIN_CROSS_VALIDATION_STEPS};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};

/// One held-out record predicted by the model with its hysteresis: an element test's force
/// along its measured motion, a rig's mass acceleration simulated under its measured base.
#[derive(Debug, Clone, serde::Serialize)]
struct HeldOut {
    file: String,
    step: usize,
    /// NMSE of the element force (element test) or of the mass acceleration (rig) [%].
    nmse_percent: f64,
    /// RMS error of the element force [N] (displacement-driven element tests).
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_error_n: Option<f64>,
    /// RMS error of the displacement [m] (force-driven element tests).
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_error_m: Option<f64>,
    /// RMS error of the mass acceleration [m/s^2] (rigs).
    #[serde(skip_serializing_if = "Option::is_none")]
    rms_error_mps2: Option<f64>,
    /// A rig's scored trace for `--plot`: the times [s], the measured and the simulated mass
    /// acceleration [m/s^2].
    #[serde(skip)]
    simulated: Option<[Vec<f64>; 3]>,
}

/// The rig a fitted element is put back into when the data are a base-excited rig's: its mass,
/// its fitted records as measured (its sine steps; where it has none, its records with no
/// steps), and the records with no steps held out of a fit on sine steps (the export's
/// validation records).
struct Rig {
    mass_kg: f64,
    steps: Vec<Record>,
    records: Vec<Record>,
}

/// `data`'s sine steps as the element between base and mass, fitted with no moving mass, and
/// the rig they came from with its other records (see the module docs).
fn rig_steps_as_element(
    records: Vec<Record>,
    mass_kg: f64,
    file: &str,
    name: &str,
) -> anyhow::Result<(Data, Rig)> {
    let (mut steps, mut others): (Vec<Record>, Vec<Record>) = records
        .into_iter()
        .partition(|r| matches!(r.excitation, Excitation::Sine { .. }));
    let fitted = if steps.is_empty() {
        std::mem::swap(&mut steps, &mut others);
        "records (it has no sine steps; the fit is then refined by output error on the rig)"
    } else {
        "sine steps"
    };
    if steps.is_empty() {
        bail!("{file}: model {name}: the files hold no records");
    }
    let view = steps
        .iter()
        .map(|r| element_view_of_rig(r, mass_kg))
        .collect::<Result<Vec<_>, _>>()
        .with_context(|| format!("{file}: the rig's {fitted}"))?;
    eprintln!(
        "note: {file}: the rig's {fitted} fitted as the element between base and mass, its force the one that holds the {mass_kg} kg mass (-m a_o) along the relative motion; held-out records simulated on the rig"
    );
    let data = Data {
        records: view,
        validation: Vec::new(),
        setup: Setup::Element {
            moving_mass_kg: Some(0.0),
            drive: None,
        },
        source: file.to_string(),
    };
    Ok((
        data,
        Rig {
            mass_kg,
            steps,
            records: others,
        },
    ))
}

/// `record` predicted by `fit`: along its measured motion (element test), or on `rig` by
/// simulation (see the module docs).
fn predict_held_out(
    fit: &TermFit,
    rig: Option<&Rig>,
    file: &str,
    record: &Record,
) -> anyhow::Result<HeldOut> {
    let context = || format!("{file}: record {}", record.step);
    let Some(rig) = rig else {
        let v = validate_element_fit(fit, record).with_context(context)?;
        return Ok(HeldOut {
            file: file.to_string(),
            step: record.step,
            nmse_percent: v.nmse_percent,
            rms_error_n: Some(v.rms_error_n),
            rms_error_m: None,
            rms_error_mps2: None,
            simulated: None,
        });
    };
    let element = FittedElement::of_term_fit(fit);
    let h = predict_record(&element, rig.mass_kg, record, &Transform::default())
        .with_context(context)?;
    let rms_error_mps2 = h.rms_error_mps2();
    Ok(HeldOut {
        file: file.to_string(),
        step: record.step,
        nmse_percent: h.nmse_percent,
        rms_error_n: None,
        rms_error_m: None,
        rms_error_mps2: Some(rms_error_mps2),
        simulated: Some([
            (0..h.measured_mps2.len())
                .map(|i| record.time_s(i))
                .collect(),
            h.measured_mps2,
            h.predicted_mps2,
        ]),
    })
}

/// Refuses what this fit does not do, naming the option.
fn check_options(args: &IdentifyArgs, name: &str) -> anyhow::Result<()> {
    let refused = [
        (args.forgetting_per_step != 1.0, "--forgetting-per-step"),
        (args.update_period_s.is_some(), "--update-period-s"),
        (args.td_points.is_some(), "--td-points"),
    ];
    if let Some((_, option)) = refused.iter().find(|(set, _)| *set) {
        bail!(
            "model {name}: {option} is not available with a hysteresis state (the model is fitted \
             offline, on all the fitted records at once)"
        );
    }
    Ok(())
}

pub fn run(args: &IdentifyArgs, base: &str) -> anyhow::Result<()> {
    let name = format!("{base}{HYSTERESIS_SUFFIX}");
    check_options(args, &name)?;
    check_frequency_tolerance(args.frequency_tolerance)?;
    let baseline = Model::by_name(
        base,
        &ModelOptions {
            atan_slope_s_per_m: args.atan_m,
            polynomial_order: args.poly_order,
        },
    )?;
    let files = forcemap_io::input::expand_paths(&args.files)?;
    let file = data_name(&files);
    let mut import = forcemap_io::input::load_files(&files, args.channels.as_deref())?;
    if !matches!(import.kind, SetupKind::Element | SetupKind::BaseExcited) {
        bail!(
            "{file}: model {name} is fitted on element tests (relative displacement and force) \
             and base-excited rigs; these are a {} setup's",
            import.kind
        );
    }
    for w in frequencies_from_data(
        &mut import.records,
        import.kind.driven_channel(),
        args.frequency_tolerance,
    ) {
        eprintln!("warning: {file}: {w}");
    }
    let setup = super::setup_of(
        import.kind,
        args.mass_kg,
        args.params.as_deref(),
        &import.parameters,
        &file,
    )?;
    let (data, rig) = match setup {
        Setup::BaseExcited { mass_kg } => {
            let (data, rig) = rig_steps_as_element(import.records, mass_kg, &file, &name)?;
            (data, Some(rig))
        }
        setup => (
            Data {
                records: import.records,
                validation: Vec::new(),
                setup,
                source: file.clone(),
            },
            None,
        ),
    };
    let (fitted_on, choice) = choose_fit(&data, &baseline, rig.as_ref())
        .with_context(|| format!("{file}: fitting model {name}"))?;
    let (h, findings, note) = fit(&data, &baseline, fitted_on)
        .with_context(|| format!("{file}: fitting model {name}"))?;
    let mut fit = h
        .fit
        .clone()
        .with_context(|| format!("{file}: model {name}: the fit holds no element force"))?;
    let mut parameters: Vec<ParameterValue> = h
        .refitted_baseline
        .iter()
        .chain(&h.added_parameters)
        .cloned()
        .collect();
    let fitted_records = rig.as_ref().map_or(&data.records, |rig| &rig.steps);
    let setup = match &rig {
        Some(rig) => Setup::BaseExcited {
            mass_kg: rig.mass_kg,
        },
        None => data.setup.clone(),
    };
    let refinement = Refinement::of(&setup, args.drive.map(ElementDrive::from), fitted_records);
    let refit = refinement
        .refine(&baseline, fitted_records, &fit)
        .with_context(|| format!("{file}: fitting model {name}"))?;
    if let Some(r) = &refit {
        fit = r.fit.clone();
        parameters = refined_parameters(&r.identification, &parameters);
    }
    // The held-out records as read (a rig's as the element between base and mass, for the
    // loops) beside their predictions.
    let mut held_out = Vec::new();
    let mut held_out_records_read = Vec::new();
    let mut predict = |shown: &str, r: Record| -> anyhow::Result<()> {
        held_out.push(match refinement {
            Refinement::Forced { .. } => {
                let (nmse_percent, rms_error_m) = predict_forced(&baseline, &fit, &r)
                    .with_context(|| format!("{shown}: record {}", r.step))?;
                HeldOut {
                    file: shown.to_string(),
                    step: r.step,
                    nmse_percent,
                    rms_error_n: None,
                    rms_error_m: Some(rms_error_m),
                    rms_error_mps2: None,
                    simulated: None,
                }
            }
            _ => predict_held_out(&fit, rig.as_ref(), shown, &r)?,
        });
        held_out_records_read.push(match &rig {
            Some(rig) => element_view_of_rig(&r, rig.mass_kg)
                .with_context(|| format!("{shown}: record {}", r.step))?,
            None => r,
        });
        Ok(())
    };
    for r in rig.iter().flat_map(|rig| rig.records.iter()) {
        predict(&file, r.clone())?;
    }
    for path in &args.validate {
        let shown = path.display().to_string();
        for r in held_out_records(
            path,
            args.channels.as_deref(),
            import.kind,
            args.frequency_tolerance,
        )? {
            predict(&shown, r)?;
        }
    }
    if let Some(dir) = &args.plot {
        let fitted = data.records.iter().map(|r| LoopRecord {
            file_name: format!("loop_step_{}.svg", r.step),
            caption: format!("{file} step {}", r.step),
            record: r,
        });
        let held = held_out
            .iter()
            .zip(&held_out_records_read)
            .enumerate()
            .map(|(i, (h, r))| LoopRecord {
                file_name: format!("held_out_{i}.svg"),
                caption: format!("held out: {} record {}", h.file, h.step),
                record: r,
            });
        write_loop_plots(dir, &name, &fit, &fitted.chain(held).collect::<Vec<_>>())
            .with_context(|| format!("{file}: plotting the loops"))?;
        for (i, h) in held_out.iter().enumerate() {
            let Some([t, measured, simulated]) = &h.simulated else {
                continue;
            };
            let path = dir.join(format!("held_out_{i}_simulated.svg"));
            let title = format!(
                "held out: {} record {}: mass acceleration, measured and simulated by {name} under the measured base (NMSE {:.2} %)",
                h.file, h.step, h.nmse_percent
            );
            crate::plot::time_trace(
                &path,
                &title,
                t,
                measured,
                simulated,
                "mass acceleration [m/s^2]",
            )
            .with_context(|| format!("{file}: plotting held-out record {}", h.step))?;
            eprintln!("wrote {}", path.display());
        }
    }
    let f = &findings.findings;
    if args.json {
        println!(
            "{}",
            json!({
                "model": name,
                "method": if refit.is_some() { "hysteresis-output-error" } else { "hysteresis-refit" },
                "parameters": parameters,
                "steps": findings.steps,
                "cv_percent": h.cv_percent,
                "baseline_cv_percent": f.gap_before_percent,
                "floor_percent": f.floor_percent,
                "fitted_on": fitted_on.name(),
                "fit_choice": choice,
                "notes": note.iter().collect::<Vec<_>>(),
                "held_out": held_out,
                "output_error": refit.as_ref().map(|r| json!({
                    "refined_on": refinement.describe(r.identification.steps_used.len()),
                    "residual_rms_noise_std": r.identification.residual_rms,
                    "warnings": r.identification.warnings,
                })),
            })
        );
        return Ok(());
    }
    let fitted = if findings.sampled_records == findings.steps {
        format!("{} records with no steps", findings.steps)
    } else {
        format!("{} steps", findings.steps)
    };
    println!(
        "{file}: model {name} on {fitted}: the {base} terms and a Bouc-Wen state, fitted as `diagnose` refits {base} with its hysteresis (yield and loop shape chosen by leave-one-out prediction of the force, coefficients by least squares)",
    );
    println!("{:<12} {:>14} {:>12}", "param", "value", "std");
    for p in &parameters {
        println!(
            "{:<12} {:>14.6e} {:>12}",
            p.name,
            p.value,
            p.std.map_or("(searched)".into(), |s| format!("{s:.3e}"))
        );
    }
    let before = if refit.is_some() {
        "the fit along the measured motion (the start of output error): "
    } else {
        ""
    };
    println!(
        "{before}cross-validated force error {:.2} % ({base} alone: {:.2} %; the force noise alone: {:.2} %)",
        h.cv_percent, f.gap_before_percent, f.floor_percent
    );
    if let Some(r) = &refit {
        println!("{}", refinement.describe(r.identification.steps_used.len()));
        for w in &r.identification.warnings {
            println!("{w}");
        }
    }
    if let Some(c) = &choice {
        println!("fitted on: {c}");
    }
    if let Some(n) = &note {
        println!("note: {n}");
    }
    for h in &held_out {
        let (what, rms) = match (h.rms_error_n, h.rms_error_mps2) {
            (Some(n), _) => ("force", format!("{n:.3e} N")),
            (None, None) if h.rms_error_m.is_some() => (
                "displacement (the mass simulated under its measured force)",
                format!("{:.3e} m", h.rms_error_m.unwrap_or(f64::NAN)),
            ),
            (None, a) => (
                "mass-acceleration (the mass simulated under its measured base)",
                format!("{:.3e} m/s^2", a.unwrap_or(f64::NAN)),
            ),
        };
        println!(
            "held out: {} record {}: {what} NMSE {:.2} %, RMS error {rms}{}",
            h.file,
            h.step,
            h.nmse_percent,
            no_better_than_zero(h.nmse_percent)
        );
    }
    Ok(())
}

/// What the sine steps of `data` are fitted on, and the line saying why (None when the data
/// hold no sine step: records with no steps are fitted on their samples). A left-out step is
/// scored as a held-out record is: on a rig by the mass acceleration simulated under its
/// measured base, for along the measured motion the velocity differentiated from the noisy
/// displacement favours the samples' fit, whose friction it biases low.
fn choose_fit(
    data: &Data,
    baseline: &Model,
    rig: Option<&Rig>,
) -> anyhow::Result<(PeriodicFit, Option<String>)> {
    let sine_steps: Vec<&Record> = data
        .records
        .iter()
        .filter(|r| matches!(r.excitation, Excitation::Sine { .. }))
        .collect();
    if sine_steps.is_empty() {
        return Ok((PeriodicFit::Periods, None));
    }
    if sine_steps.len() < MIN_CROSS_VALIDATION_STEPS {
        return Ok((
            PeriodicFit::Samples,
            Some(format!(
                "the samples of every sine step ({} steps are too few to choose by leaving one out, at least {MIN_CROSS_VALIDATION_STEPS}: the least squares of the force along the measured motion, whose criterion is the force error itself)",
                sine_steps.len()
            )),
        ));
    }
    let pb = super::progress_spinner();
    let score = |on: PeriodicFit| -> anyhow::Result<f64> {
        let mut sum = 0.0;
        for (i, left_out) in sine_steps.iter().enumerate() {
            pb.set_message(format!(
                "choosing the fit: {} without step {} ({} of {})",
                on.name(),
                left_out.step,
                i + 1,
                sine_steps.len()
            ));
            let rest = Data {
                records: data
                    .records
                    .iter()
                    .filter(|r| r.step != left_out.step)
                    .cloned()
                    .collect(),
                validation: Vec::new(),
                setup: data.setup.clone(),
                source: data.source.clone(),
            };
            let (h, _, _) = fit(&rest, baseline, on)
                .with_context(|| format!("leaving step {} out", left_out.step))?;
            let f = h.fit.with_context(|| {
                format!(
                    "leaving step {} out: the fit holds no element force",
                    left_out.step
                )
            })?;
            sum += match rig {
                None => MeasuredState::of(left_out)
                    .with_context(|| format!("step {}'s measured state", left_out.step))?
                    .force_nmse_percent(&f),
                Some(rig) => {
                    let step = rig
                        .steps
                        .iter()
                        .find(|r| r.step == left_out.step)
                        .with_context(|| format!("step {} of the rig", left_out.step))?;
                    predict_held_out(&f, Some(rig), &data.source, step)?.nmse_percent
                }
            };
        }
        Ok(sum / sine_steps.len() as f64)
    };
    let periods = score(PeriodicFit::Periods)?;
    let samples = score(PeriodicFit::Samples)?;
    pb.finish_and_clear();
    let predicted = match rig {
        None => "force predicted",
        Some(_) => "mass acceleration simulated",
    };
    let scores = format!(
        "mean NMSE of each of {} steps' {predicted} by the fit to the others: periods {periods:.2} %, samples {samples:.2} %",
        sine_steps.len()
    );
    Ok(if samples < (1.0 - CHOICE_MARGIN) * periods {
        (
            PeriodicFit::Samples,
            Some(format!(
                "the samples of every sine step, which predict left-out steps best ({scores})"
            )),
        )
    } else {
        (
            PeriodicFit::Periods,
            Some(format!(
                "one rebuilt period of each sine step, which predicts left-out steps within {:.0} % of the samples or better ({scores})",
                100.0 * CHOICE_MARGIN
            )),
        )
    })
}

/// The hysteresis candidate of `baseline` on `data`, its sine steps fitted on `periodic_fit`,
/// with the findings it ranks in and the note of a moving mass held.
fn fit(
    data: &Data,
    baseline: &Model,
    periodic_fit: PeriodicFit,
) -> anyhow::Result<(
    PhasorEffect,
    forcemap_math::diagnose::PhasorFindings,
    Option<String>,
)> {
    let Fitted { findings, note, .. } = fit_element_steps(
        data,
        baseline,
        Some(&[Effect::Hysteresis]),
        ElementFit {
            periodic: periodic_fit,
            pooled_record_noise: true,
        },
    )?;
    let Some(h) = findings
        .ranked_effects
        .iter()
        .find(|e| e.effect == Effect::Hysteresis)
        .cloned()
    else {
        let why = findings
            .dropped
            .iter()
            .map(|d| d.reason.clone())
            .collect::<Vec<_>>()
            .join("; ");
        bail!("no hysteresis fits these data: {why}");
    };
    Ok((h, findings, note))
}
