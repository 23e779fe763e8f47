//! `forcemap diagnose DATA --model BASELINE`: the sim-to-real gap diagnosis (library:
//! `forcemap_math::diagnose`), as a summary, JSON, or an HTML report with SVG plots.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use forcemap_math::diagnose::sampled_records::element_view_of_rig;
use forcemap_math::diagnose::{self, DiagnoseOptions, DiagnosisDetail, Verdict};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::sim::{self, ElementDrive, RunSpec};

mod output_error_refits;
mod phasor_only;
mod plots;
mod time_domain;

pub(crate) use phasor_only::{ElementFit, Fitted, PeriodicFit, fit_element_steps};

use crate::cli::DiagnoseArgs;
use crate::report::{HtmlReport, model_with_effect_text, parameters_text};
use forcemap_io::atomic::{write_atomically, write_dir_atomically};
use forcemap_io::input::{Loaded, Measured};
use forcemap_io::steps::unlabelled::frequencies_from_data;
use forcemap_math::recipe::SetupKind;
use plots::{svg_harmonics, svg_heldout, svg_state_plane};

/// SNR of the built-in demo [dB] (the reproduction's rig SNR).
pub const DEMO_SNR_DB: f64 = 40.0;

/// The paper's validation errors, linear then Coulomb (Table 2): NMSE_1, NMSE_2 [%].
const PAPER_LINEAR_NMSE: [f64; 2] = [11.0, 17.2];
const PAPER_COULOMB_NMSE: [f64; 2] = [4.0, 6.5];

pub(crate) struct Data {
    pub records: Vec<Record>,
    pub validation: Vec<Record>,
    pub setup: Setup,
    pub source: String,
}

fn load(args: &DiagnoseArgs, files: &[PathBuf], mut import: Loaded) -> anyhow::Result<Data> {
    let file = super::identify::data_name(files);
    super::identify::check_frequency_tolerance(args.frequency_tolerance)?;
    for w in frequencies_from_data(
        &mut import.records,
        import.kind.driven_channel(),
        args.frequency_tolerance,
    ) {
        eprintln!("warning: {file}: {w}");
    }
    if import.kind == SetupKind::DrivePoint {
        bail!(
            "{file}: the diagnosis needs the base-excited rig channels (base and relative displacement, mass acceleration) or an element test's (relative displacement, force); this is a {} export",
            import.kind
        );
    }
    let setup = super::setup_of(
        import.kind,
        args.mass_kg,
        args.params.as_deref(),
        &import.parameters,
        &file,
    )?;
    let validation = if args.validate.is_empty() {
        Vec::new()
    } else {
        let held_out = forcemap_io::input::expand_paths(&args.validate)?;
        let mut vi = forcemap_io::input::load_files(&held_out, args.channels.as_deref())?;
        let name = super::identify::data_name(&held_out);
        if vi.kind != import.kind {
            bail!(
                "{name}: validation data must hold the channels of the data's {} setup; these are a {} setup's",
                import.kind,
                vi.kind
            );
        }
        for w in frequencies_from_data(
            &mut vi.records,
            import.kind.driven_channel(),
            args.frequency_tolerance,
        ) {
            eprintln!("warning: {name}: {w}");
        }
        vi.records
    };
    Ok(Data {
        records: import.records,
        validation,
        setup,
        source: file,
    })
}

/// The demo data: the paper's Coulomb rig (k 6380, c 184, F_d 12.3) at 40 dB with the two
/// band-random validation records.
fn demo_data() -> anyhow::Result<Data> {
    let records = RunSpec::paper_rig(Some(DEMO_SNR_DB), 1).simulate()?;
    Ok(Data {
        records,
        validation: Vec::new(),
        setup: Setup::BaseExcited {
            mass_kg: sim::rig::PAPER_RIG_MASS_KG,
        },
        source: format!("built-in demo (simulated rig, Coulomb friction 12.3 N, {DEMO_SNR_DB} dB)"),
    })
}

/// A rig's data with no sine steps (band-random records, road profiles) as the element between
/// base and mass (`diagnose::sampled_records::element_view_of_rig`): their records fitted on
/// their samples, the held-out ones predicted the same way; said on stderr. The rig's own
/// records are returned beside the view, for the output-error refits ([`output_error_refits`]).
/// Other data as they are.
fn rig_without_sine_steps_as_element(
    data: Data,
) -> anyhow::Result<(Data, Option<output_error_refits::SimulatedRecords>)> {
    let Setup::BaseExcited { mass_kg } = data.setup else {
        return Ok((data, None));
    };
    if data
        .records
        .iter()
        .any(|r| matches!(r.excitation, Excitation::Sine { .. }))
    {
        return Ok((data, None));
    }
    let view = |records: &[Record]| -> anyhow::Result<Vec<Record>> {
        records
            .iter()
            .map(|r| element_view_of_rig(r, mass_kg))
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}: the rig's records", data.source))
    };
    eprintln!(
        "note: {}: the rig's records have no sine steps: each is fitted on its samples as the element between base and mass, its force the one that holds the {mass_kg} kg mass (-m a_o) along the relative motion; the rig's channel effects (exciter delay, sensor low-pass, a mass error) are not fitted this way (the first two are refitted by simulation where the baseline's misses the records beyond their noise)",
        data.source
    );
    let view_data = Data {
        records: view(&data.records)?,
        validation: view(&data.validation)?,
        setup: Setup::Element {
            moving_mass_kg: Some(0.0),
            drive: None,
        },
        source: data.source,
    };
    let rig = output_error_refits::SimulatedRecords {
        records: data.records,
        validation: data.validation,
        simulation: output_error_refits::Simulation::Rig { mass_kg },
    };
    Ok((view_data, Some(rig)))
}

/// An element test's data with the drive the user names: with the force, its records with no
/// steps are kept for the output-error refits (the mass simulated under each record's measured
/// force, [`output_error_refits`]); the setup carries the drive either way.
fn force_driven_records(
    mut data: Data,
    named: ElementDrive,
) -> anyhow::Result<(Data, Option<output_error_refits::SimulatedRecords>)> {
    let Setup::Element {
        moving_mass_kg,
        drive,
    } = &mut data.setup
    else {
        bail!(
            "{}: --drive names what an element test's bench controlled; these data are a {} setup's",
            data.source,
            data.setup.kind()
        );
    };
    *drive = Some(named);
    let moving_mass_kg = *moving_mass_kg;
    // The records `identify` fits sample by sample: band-random, and multisines too short for
    // the periodic analysis.
    let stepless = |records: &[Record]| -> Vec<Record> {
        forcemap_math::pipeline::sample_records(
            records,
            &forcemap_math::phasor::MultisineOptions::default(),
        )
        .into_iter()
        .cloned()
        .collect()
    };
    let records = stepless(&data.records);
    if named != ElementDrive::Force || records.is_empty() {
        return Ok((data, None));
    }
    let simulated = output_error_refits::SimulatedRecords {
        records,
        validation: stepless(&data.validation),
        simulation: output_error_refits::Simulation::Forced { moving_mass_kg },
    };
    Ok((data, Some(simulated)))
}

pub fn run(args: &DiagnoseArgs) -> anyhow::Result<()> {
    // What the data are decides the path: a force-driven axis record goes to the time domain.
    let files = forcemap_io::input::expand_paths(&args.data)?;
    let measured = match files.as_slice() {
        _ if args.demo => None,
        [path] => Some(forcemap_io::input::load_measured_mapped(
            path,
            args.channels.as_deref(),
        )?),
        several => Some(Measured::Steps(forcemap_io::input::load_files(
            several,
            args.channels.as_deref(),
        )?)),
    };
    if let (Some(Measured::Axis(fit)), [path]) = (&measured, files.as_slice()) {
        return time_domain::run(args, path, fit);
    }
    // Refuse an existing report directory before any work.
    if let Some(dir) = &args.report
        && dir.exists()
    {
        bail!(
            "{}: the report directory exists already; remove it or choose a new one",
            dir.display()
        );
    }
    let (data, model_name) = if args.demo {
        (demo_data()?, "linear".to_string())
    } else {
        let model = args
            .model
            .clone()
            .expect("clap requires --model without --demo");
        let Some(Measured::Steps(import)) = measured else {
            unreachable!("an axis record returned above");
        };
        (load(args, &files, import)?, model)
    };
    let baseline = Model::by_name(
        &model_name,
        &ModelOptions {
            atan_slope_s_per_m: args.atan_m,
            polynomial_order: None,
        },
    )?;
    let (data, simulated) = match args.drive.map(ElementDrive::from) {
        Some(drive) => force_driven_records(data, drive)?,
        None => rig_without_sine_steps_as_element(data)?,
    };
    // Without a rig to simulate held-out records on, the steps are the evidence.
    if data.setup.kind() != SetupKind::BaseExcited {
        if !args.holdout_steps.is_empty() {
            bail!(
                "{}: --holdout-steps needs the base-excited rig (held-out steps are simulated)",
                data.source
            );
        }
        return phasor_only::run(args, &data, &baseline, simulated.as_ref());
    }
    let pb = super::progress_spinner();
    pb.set_message(format!("diagnosing {} against {}", model_name, data.source));
    let options = DiagnoseOptions {
        holdout_steps: args.holdout_steps.clone(),
        ..DiagnoseOptions::default()
    };
    let detail = diagnose::diagnose(
        &data.setup,
        &baseline,
        &data.records,
        &data.validation,
        &options,
    )
    .with_context(|| format!("{}: diagnosing baseline '{model_name}'", data.source));
    pb.finish_and_clear();
    let detail = detail?;
    if let Some(dir) = &args.report {
        write_report(dir, &detail, &data, args.demo)?;
        eprintln!("wrote {}", dir.join("index.html").display());
    }
    if args.json {
        let mut v = serde_json::to_value(&detail.diagnosis)?;
        if args.demo {
            v["paper"] = serde_json::json!({
                "linear_nmse_percent": PAPER_LINEAR_NMSE,
                "coulomb_nmse_percent": PAPER_COULOMB_NMSE,
            });
        }
        println!("{v}");
    } else {
        print_summary(&data.source, &detail, args.demo);
    }
    Ok(())
}

fn print_summary(source: &str, detail: &DiagnosisDetail, demo: bool) {
    let d = &detail.diagnosis;
    println!(
        "{source}: baseline {} fitted on sine steps {:?}: {}",
        d.baseline_model,
        d.fit_steps,
        parameters_text(&d.baseline_parameters)
    );
    println!(
        "gap: held-out NMSE of the mass acceleration {:.2} % (records {:?}: {}); noise floor ~{:.2} %",
        d.findings.gap_before_percent,
        d.heldout_records,
        d.gap_before_by_record_percent
            .iter()
            .map(|v| format!("{v:.2} %"))
            .collect::<Vec<_>>()
            .join(", "),
        d.findings.floor_percent
    );
    println!("where:");
    for s in &d.located.summary {
        println!("  {s}");
    }
    println!("  per step (frequency, relative amplitude, element-force mismatch):");
    for s in &d.located.by_step {
        println!(
            "    step {:>2} {:>5.2} Hz {:>6.2} mm {:>7.2} %",
            s.step,
            s.frequency_hz,
            1e3 * s.amplitude_m,
            s.mismatch_percent
        );
    }
    println!("candidates (held-out NMSE with the effect; score = NMSE with the BIC penalty):");
    if let Some(m) = d.baseline_output_error_misfit {
        println!(
            "  (OE: output-error misfit on the sine steps in noise std, {m:.3} for the baseline; those candidates were refitted by output error and scored with the refit)"
        );
    }
    println!(
        "  {:<20} {:>9} {:>9} {:>8} {:>6} {:>4}  added parameters",
        "effect", "after %", "score %", "CV %", "OE", "sig"
    );
    for r in &d.ranked_effects {
        println!(
            "  {:<20} {:>9.3} {:>9.3} {:>8} {:>6} {:>4}  {}",
            r.effect.name(),
            r.gap_after_percent,
            r.score_percent,
            r.phasor_cv_percent
                .map_or("-".into(), |v| format!("{v:.2}")),
            r.output_error_misfit
                .map_or("-".into(), |v| format!("{v:.3}")),
            if r.significant { "yes" } else { "no" },
            candidate_text(r)
        );
    }
    if let Some(p) = &d.best_pair {
        println!(
            "best pair: {} + {}: held-out NMSE {:.3} % ({}){}",
            p.effects[0].name(),
            p.effects[1].name(),
            p.gap_after_percent,
            parameters_text(&p.added_parameters),
            p.form_neighbour.map_or(String::new(), |n| format!(
                "; {}'s form widened by {} (fitted with them)",
                p.effects[0].name(),
                n.name()
            ))
        );
    }
    println!("verdict: {}", d.findings.headline());
    if matches!(
        d.findings.verdict,
        Verdict::Explained | Verdict::ExplainedInPart
    ) && let Some(r) = d.ranked_effects.first()
    {
        println!("  signature: {}", r.signature);
        println!("  found: {}", candidate_text(r));
        match (&d.best_pair, d.findings.second_effect) {
            (Some(p), Some(_)) => println!(
                "  {}",
                model_with_effect_text(
                    &d.baseline_model,
                    &format!("{} + {}", p.effects[0].name(), p.effects[1].name()),
                    &p.refitted_baseline,
                    &p.added_parameters
                )
            ),
            _ if r.fitted_with.is_none() => println!(
                "  {}",
                model_with_effect_text(
                    &d.baseline_model,
                    r.effect.name(),
                    &r.refitted_baseline,
                    &r.added_parameters
                )
            ),
            _ => {}
        }
    }
    if d.findings.verdict == Verdict::ExplainedInPart
        && let Some(left) = &detail.after_located
    {
        println!(
            "  what is left, with {} added:",
            d.ranked_effects[0].effect.name()
        );
        for s in &left.summary {
            println!("    {s}");
        }
    }
    for n in &d.notes {
        println!("note: {n}");
    }
    if demo {
        let by = &d.gap_before_by_record_percent;
        let after: Vec<f64> = detail
            .after_heldout
            .iter()
            .map(|h| h.nmse_percent)
            .collect();
        if by.len() == 2 && after.len() == 2 {
            println!(
                "demo: held-out NMSE (1.5-2.5 Hz, 2.5-3.5 Hz) {:.1} / {:.1} % -> {:.1} / {:.1} %; the paper's rig: {:.1} / {:.1} % -> {:.1} / {:.1} %",
                by[0],
                by[1],
                after[0],
                after[1],
                PAPER_LINEAR_NMSE[0],
                PAPER_LINEAR_NMSE[1],
                PAPER_COULOMB_NMSE[0],
                PAPER_COULOMB_NMSE[1]
            );
        }
    }
    println!("rule: {}", d.findings.rule);
}

/// Writes the report (nothing half-written: see [`write_dir_atomically`]).
fn write_report(
    dir: &Path,
    detail: &DiagnosisDetail,
    data: &Data,
    demo: bool,
) -> anyhow::Result<()> {
    write_dir_atomically(dir, |tmp| {
        let d = &detail.diagnosis;
        let fs = data
            .records
            .iter()
            .chain(&data.validation)
            .find(|r| {
                detail
                    .baseline_heldout
                    .first()
                    .is_some_and(|h| h.step == r.step)
            })
            .map_or(100.0, |r| r.sample_rate_hz);
        let mut figures = Vec::new();
        for (i, hb) in detail.baseline_heldout.iter().enumerate() {
            let ha = detail.after_heldout.get(i);
            let title = format!(
                "held-out record {}: NMSE {:.2} % (baseline){}",
                hb.step,
                hb.nmse_percent,
                ha.map_or(String::new(), |h| format!(
                    ", {:.2} % with {}",
                    h.nmse_percent,
                    d.ranked_effects[0].effect.name()
                ))
            );
            let file = format!("heldout_{}.svg", hb.step);
            write_atomically(&tmp.join(&file), &svg_heldout(hb, ha, fs, &title)?)?;
            figures.push((
                file,
                "measured against predicted mass acceleration".to_string(),
            ));
        }
        write_atomically(&tmp.join("state_plane.svg"), &svg_state_plane(detail)?)?;
        figures.push((
            "state_plane.svg".into(),
            "residual over the state plane".into(),
        ));
        write_atomically(
            &tmp.join("harmonics.svg"),
            &svg_harmonics(&d.located, detail.after_located.as_ref())?,
        )?;
        figures.push((
            "harmonics.svg".into(),
            "per-harmonic residuals against frequency and amplitude".into(),
        ));
        let mut page = HtmlReport::new(&format!("Gap diagnosis: baseline {}", d.baseline_model));
        page.paragraph(&data.source);
        page.verdict(&d.findings);
        if demo {
            page.paragraph(&format!(
                "The paper's rig: linear {:.1} / {:.1} %, with Coulomb friction {:.1} / {:.1} % (Table 2).",
                PAPER_LINEAR_NMSE[0], PAPER_LINEAR_NMSE[1], PAPER_COULOMB_NMSE[0], PAPER_COULOMB_NMSE[1]
            ));
        }
        page.list("Where", &d.located.summary);
        let rows: Vec<Vec<String>> = d
            .ranked_effects
            .iter()
            .map(|r| {
                vec![
                    r.effect.name().to_string(),
                    format!("{:.3}", r.gap_after_percent),
                    format!("{:.3}", r.score_percent),
                    r.phasor_cv_percent
                        .map_or("-".into(), |v| format!("{v:.2}")),
                    r.output_error_misfit
                        .map_or("-".into(), |v| format!("{v:.3}")),
                    if r.significant { "yes" } else { "no" }.into(),
                    candidate_text(r),
                    r.signature.clone(),
                ]
            })
            .collect();
        page.table(
            "Candidates",
            &[
                "effect",
                "after [%]",
                "score [%]",
                "CV [%]",
                "OE misfit",
                "significant",
                "added",
                "signature",
            ],
            &rows,
        );
        page.figures(&figures);
        let html = page.finish(&d.findings.rule);
        write_atomically(&tmp.join("index.html"), &html)
    })
}

/// A candidate's added parameters, after its family member when it has one
/// ("[channel mass_acceleration, 2nd order, 6.1 Hz, damping 0.70] cutoff_hz = ...").
fn candidate_text(r: &forcemap_math::diagnose::RankedEffect) -> String {
    let text = match &r.member {
        Some(m) => format!("[{m}] {}", parameters_text(&r.added_parameters)),
        None => parameters_text(&r.added_parameters),
    };
    match r.fitted_with {
        Some(top) => format!(
            "{text} [fitted only with {}: alone not physical or not simulable; the pair's figures]",
            top.name()
        ),
        None => text,
    }
}
