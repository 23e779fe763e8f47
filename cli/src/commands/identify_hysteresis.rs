//! `forcemap identify --model NAME+hysteresis`: an element test's model with a Bouc-Wen
//! hysteresis state beside its terms, fitted as `diagnose` refits a baseline with its
//! hysteresis candidate (one way to fit it, not a second): the yield and the loop's shape
//! searched and chosen by leave-one-step-out prediction of the element force, the coefficients
//! by least squares on every step. Held-out records (`--validate`) are predicted along their
//! measured motion with the state integrated from rest.
//!
//! Sine steps are fitted on one rebuilt period each (the diagnosis' fit). Their samples could
//! be fitted too (the least squares along the measured motion); that waits for the state's
//! integration: one forward-Euler step per sample, accurate at 1 kHz, is not at the 200 Hz of
//! some damper tests (the UTFSM damper fitted so predicts its held-out tests at 6.81 / 2.83 %,
//! against 3.45 / 2.22 % with the same law integrated by RK4 and 2.94 / 1.92 % by periods).

use anyhow::{Context, bail};
use forcemap_math::diagnose::PhasorEffect;
use forcemap_math::diagnose::{Effect, ParameterValue};
use forcemap_math::model::{HYSTERESIS_SUFFIX, Model, ModelOptions};
use forcemap_math::pipeline::validate_element_fit;
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::ElementDrive;
use serde_json::json;

use super::diagnose::{Data, Fitted, fit_element_steps};
use super::identify::{
    check_frequency_tolerance, data_name, held_out_records, no_better_than_zero,
};
use crate::cli::IdentifyArgs;
use forcemap_io::steps::unlabelled::frequencies_from_data;

/// One held-out record's force predicted by the model with its hysteresis.
#[derive(Debug, Clone, serde::Serialize)]
struct HeldOut {
    file: String,
    step: usize,
    nmse_percent: f64,
    rms_error_n: f64,
}

/// Refuses what this fit does not do, naming the option.
fn check_options(args: &IdentifyArgs, name: &str) -> anyhow::Result<()> {
    let refused = [
        (args.plot.is_some(), "--plot"),
        (args.forgetting_per_step != 1.0, "--forgetting-per-step"),
        (args.update_period_s.is_some(), "--update-period-s"),
        (args.td_points.is_some(), "--td-points"),
        (
            args.drive.map(ElementDrive::from) == Some(ElementDrive::Force),
            "--drive force",
        ),
    ];
    if let Some((_, option)) = refused.iter().find(|(set, _)| *set) {
        bail!(
            "model {name}: {option} is not available with a hysteresis state (it is fitted along \
             the measured motion of a displacement-driven element test, converged over every step)"
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
    if import.kind != SetupKind::Element {
        bail!(
            "{file}: model {name} is fitted on element tests (relative displacement and force); \
             these are a {} setup's",
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
    let data = Data {
        records: import.records,
        validation: Vec::new(),
        setup,
        source: file.clone(),
    };
    let (h, findings, note) =
        fit(&data, &baseline).with_context(|| format!("{file}: fitting model {name}"))?;
    let fit = h
        .fit
        .clone()
        .with_context(|| format!("{file}: model {name}: the fit holds no element force"))?;
    let parameters: Vec<ParameterValue> = h
        .refitted_baseline
        .iter()
        .chain(&h.added_parameters)
        .cloned()
        .collect();
    let mut held_out = Vec::new();
    for path in &args.validate {
        let shown = path.display().to_string();
        for r in held_out_records(
            path,
            args.channels.as_deref(),
            SetupKind::Element,
            args.frequency_tolerance,
        )? {
            let v = validate_element_fit(&fit, &r)
                .with_context(|| format!("{shown}: record {}", r.step))?;
            held_out.push(HeldOut {
                file: shown.clone(),
                step: r.step,
                nmse_percent: v.nmse_percent,
                rms_error_n: v.rms_error_n,
            });
        }
    }
    let f = &findings.findings;
    if args.json {
        println!(
            "{}",
            json!({
                "model": name,
                "method": "hysteresis-refit",
                "parameters": parameters,
                "steps": findings.steps,
                "cv_percent": h.cv_percent,
                "baseline_cv_percent": f.gap_before_percent,
                "floor_percent": f.floor_percent,
                "notes": note.iter().collect::<Vec<_>>(),
                "held_out": held_out,
            })
        );
        return Ok(());
    }
    println!(
        "{file}: model {name} on {} steps: the {base} terms and a Bouc-Wen state, fitted as `diagnose` refits {base} with its hysteresis (yield and loop shape chosen by leave-one-step-out prediction of the force, coefficients by least squares)",
        findings.steps
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
    println!(
        "cross-validated force error {:.2} % ({base} alone: {:.2} %; the force noise alone: {:.2} %)",
        h.cv_percent, f.gap_before_percent, f.floor_percent
    );
    if let Some(n) = &note {
        println!("note: {n}");
    }
    for h in &held_out {
        println!(
            "held out: {} record {}: force NMSE {:.2} %, RMS error {:.3e} N{}",
            h.file,
            h.step,
            h.nmse_percent,
            h.rms_error_n,
            no_better_than_zero(h.nmse_percent)
        );
    }
    Ok(())
}

/// The hysteresis candidate of `baseline` on `data`, with the findings it ranks in and the
/// note of a moving mass held.
fn fit(
    data: &Data,
    baseline: &Model,
) -> anyhow::Result<(
    PhasorEffect,
    forcemap_math::diagnose::PhasorFindings,
    Option<String>,
)> {
    let Fitted { findings, note, .. } =
        fit_element_steps(data, baseline, Some(&[Effect::Hysteresis]))?;
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
