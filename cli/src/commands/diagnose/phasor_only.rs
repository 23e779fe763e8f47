//! The diagnosis of an element test's data, which hold no record to simulate the baseline on
//! (a drive point is refused until it has its held-out path): the phasor diagnosis the live
//! diagnoser runs (`forcemap_math::diagnose::PhasorDiagnosis`), its evidence the element-force
//! error cross-validated by leaving each step out. Data with no sine steps and no periodic
//! multisines (band-random records, ramped sines, whole files) are fitted record by record on
//! their samples, each record a step.

use anyhow::Context as _;
use forcemap_math::diagnose::sampled_records::SampledRecord;
use forcemap_math::diagnose::{PhasorDiagnosis, PhasorFindings, Verdict};
use forcemap_math::identify::{FdMultiOptions, Method, Weighting};
use forcemap_math::measured_state::{MeasuredState, excitation_kind};
use forcemap_math::model::Model;
use forcemap_math::phasor::MultisineOptions;
use forcemap_math::phasor::{PhasorOptions, analyse_record};
use forcemap_math::pipeline::{
    analyse_multisine_records, identify_records, multisine_too_short, sample_records,
};
use forcemap_math::recipe::Setup;
use forcemap_math::record::{Excitation, Record};

use super::Data;
use crate::cli::DiagnoseArgs;
use crate::report::{HtmlReport, model_with_effect_text, parameters_text};
use forcemap_io::atomic::{write_atomically, write_dir_atomically};

/// The setup with what it adds (an element test's moving mass) identified with the baseline
/// first: the candidates then refit the element force alone. Returns the note saying so.
fn with_known_extras(
    setup: &Setup,
    baseline: &Model,
    records: &[Record],
) -> anyhow::Result<(Setup, Option<String>)> {
    if setup.extra_parameters().is_empty() {
        return Ok((setup.clone(), None));
    }
    let id = identify_records(
        baseline,
        setup,
        Method::FdMulti,
        records,
        &PhasorOptions::for_identification(),
        // As the diagnosis weighs its fits: by the noise.
        &FdMultiOptions {
            weighting: Weighting::Noise,
            ..FdMultiOptions::default()
        },
    )
    .context("identifying the moving mass with the baseline")?;
    let mut extras = id.extra_values(setup);
    let first = id.parameters.len() - extras.len();
    let notes: Vec<String> = setup
        .extra_parameters()
        .iter()
        .zip(extras.iter_mut())
        .zip(&id.parameters[first..])
        .map(|((n, v), p)| {
            // A mass below zero is no mass: the baseline's missing terms went into it (a
            // friction's force correlates with -x'' on a sine), and every candidate would
            // inherit it.
            if *v < 0.0 {
                let note = format!(
                    "{n} = {:.4} +/- {:.1e} identified with the baseline is negative (the baseline's missing terms went into it): held at 0; give the moving mass (--mass-kg) if it is known",
                    *v, p.std
                );
                *v = 0.0;
                note
            } else {
                format!("{n} = {v:.4} identified with the baseline, then held")
            }
        })
        .collect();
    Ok((setup.with_extra_values(&extras), Some(notes.join(", "))))
}

/// One held-out record's force NMSE with the baseline and with the top candidate.
#[derive(Debug, Clone, serde::Serialize)]
struct HeldOut {
    step: usize,
    excitation: &'static str,
    baseline_nmse_percent: f64,
    effect: Option<&'static str>,
    /// None when the candidate transforms a channel, lags a term or drifts, which this path
    /// does not predict (extra terms and a hysteresis state it does).
    effect_nmse_percent: Option<f64>,
    acceleration_measured: bool,
}

fn held_out(f: &PhasorFindings, records: &[&Record]) -> anyhow::Result<Vec<HeldOut>> {
    let Some(base) = &f.baseline_fit else {
        return Ok(Vec::new());
    };
    let top = f.ranked_effects.first();
    records
        .iter()
        .map(|r| {
            let state = MeasuredState::of(r)?;
            Ok(HeldOut {
                step: r.step,
                excitation: excitation_kind(&r.excitation),
                baseline_nmse_percent: state.force_nmse_percent(base),
                effect: top.map(|t| t.effect.name()),
                effect_nmse_percent: top
                    .and_then(|t| t.fit.as_ref())
                    .map(|fit| state.force_nmse_percent(fit)),
                acceleration_measured: state.acceleration_measured,
            })
        })
        .collect()
}

/// What the element diagnosis fitted: its findings, the setup they were fitted with (the moving
/// mass held where the baseline identified it first), the note saying so, and the records of
/// the data it holds out (sweeps and band-random records among steps, and `--validate`'s).
pub(crate) struct Fitted<'a> {
    pub findings: PhasorFindings,
    pub setup: Setup,
    pub note: Option<String>,
    pub held_out: Vec<&'a Record>,
}

/// What the element diagnosis fits its periodic records (sine steps, multisine records) on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PeriodicFit {
    /// One rebuilt period of each sine step and a multisine's lines (the diagnosis' own).
    Periods,
    /// Every record's samples, as records with no steps are fitted.
    Samples,
}

impl PeriodicFit {
    pub fn name(self) -> &'static str {
        match self {
            PeriodicFit::Periods => "periods",
            PeriodicFit::Samples => "samples",
        }
    }
}

/// How the element diagnosis fits: its periodic records on periods or samples, and the rows of
/// records fitted on their samples scaled by each record's noise (the diagnosis, which reads
/// residuals in units of the noise) or by the noise pooled over the records (an
/// identification, [`forcemap_math::diagnose::sampled_records::pool_row_noise`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct ElementFit {
    pub periodic: PeriodicFit,
    pub pooled_record_noise: bool,
}

impl ElementFit {
    /// The diagnosis' own.
    pub const DIAGNOSIS: ElementFit = ElementFit {
        periodic: PeriodicFit::Periods,
        pooled_record_noise: false,
    };
}

/// The element diagnosis of `data` against `baseline`, with every candidate or only `effects`:
/// sine steps and multisine records fitted (sweeps and band-random records held out), on their
/// periods or their samples as `how` says, or, with neither, the records fitted on their
/// samples.
pub(crate) fn fit_element_steps<'a>(
    data: &'a Data,
    baseline: &Model,
    effects: Option<&[forcemap_math::diagnose::Effect]>,
    how: ElementFit,
) -> anyhow::Result<Fitted<'a>> {
    let source = data.source.as_str();
    // Sine steps and multisine records are fitted; sweep and band-random records, in the data
    // or in --validate, are held out. Data with neither are fitted on their records' samples.
    let multisine_options = MultisineOptions::default();
    let periodic = |r: &Record| match r.excitation {
        Excitation::Sine { .. } => true,
        Excitation::Multisine { .. } => !multisine_too_short(r, &multisine_options),
        _ => false,
    };
    let has_periodic = data.records.iter().any(periodic);
    let by_samples = if has_periodic {
        how.periodic == PeriodicFit::Samples
    } else {
        !sample_records(&data.records, &multisine_options).is_empty()
    };
    let (fitted, in_data): (Vec<&Record>, Vec<&Record>) =
        data.records.iter().partition(|r| match r.excitation {
            Excitation::Sine { .. } | Excitation::Multisine { .. } => true,
            // Held out among periodic records however these are fitted.
            Excitation::Random { .. } => by_samples && !has_periodic,
            Excitation::Sweep { .. } => false,
        });
    let fitted: Vec<Record> = fitted.into_iter().cloned().collect();
    let heldout_records: Vec<&Record> = in_data.into_iter().chain(&data.validation).collect();
    let multisines = if by_samples {
        Vec::new()
    } else {
        analyse_multisine_records(&fitted, &multisine_options)
            .with_context(|| format!("{source}: analysing the multisine records"))?
    };
    // The identification's equations (a multisine's lines, a record's samples) fit the moving
    // mass with every model; the rebuilt sine periods need it held.
    let (setup, note) = if multisines.is_empty() && !by_samples {
        with_known_extras(&data.setup, baseline, &fitted)?
    } else {
        (data.setup.clone(), None)
    };
    let mut live = PhasorDiagnosis::new(setup.clone(), baseline.clone());
    if let Some(effects) = effects {
        live = live.with_effects(effects);
    }
    for r in fitted
        .iter()
        .filter(|r| !by_samples && matches!(r.excitation, Excitation::Sine { .. }))
    {
        live.push(
            analyse_record(r, &PhasorOptions::for_identification())
                .with_context(|| format!("{source}: step {}", r.step))?,
        );
    }
    for ms in multisines {
        live.push_multisine(ms);
    }
    if by_samples {
        for r in &fitted {
            live.push_record(
                SampledRecord::new(r).with_context(|| format!("{source}: record {}", r.step))?,
            );
        }
        if how.pooled_record_noise {
            live.pool_record_noise();
        }
    }
    let f = live
        .findings()
        .with_context(|| format!("{source}: diagnosing a {} setup", setup.kind()))?;
    Ok(Fitted {
        findings: f,
        setup,
        note,
        held_out: heldout_records,
    })
}

/// `simulated`: records whose motion the model can simulate (a base-excited rig's own records
/// when `data` are their element view, a force-driven element test's); the baseline and the
/// named effect are then refitted by output error on them ([`super::output_error_refits`]).
pub(super) fn run(
    args: &DiagnoseArgs,
    data: &Data,
    baseline: &Model,
    simulated: Option<&super::output_error_refits::SimulatedRecords>,
) -> anyhow::Result<()> {
    let source = data.source.as_str();
    let Fitted {
        findings: f,
        setup,
        note,
        held_out: heldout_records,
    } = fit_element_steps(data, baseline, None, ElementFit::DIAGNOSIS)?;
    let held =
        held_out(&f, &heldout_records).with_context(|| format!("{source}: held-out records"))?;
    let refits = match simulated {
        Some(sim) => super::output_error_refits::refit(sim, baseline, &f)
            .with_context(|| format!("{source}: the output-error refits"))?,
        None => Vec::new(),
    };
    let by_simulation = simulated.and_then(|sim| sim.verdict(&refits));
    if args.json {
        let mut v = serde_json::to_value(&f)?;
        v["baseline_model"] = baseline.name.clone().into();
        v["setup"] = setup.kind().to_string().into();
        v["notes"] = note.iter().cloned().collect::<Vec<_>>().into();
        v["heldout"] = serde_json::to_value(&held)?;
        if simulated.is_some() {
            v["output_error_refits"] = serde_json::to_value(&refits)?;
            v["simulation_verdict"] = serde_json::to_value(&by_simulation)?;
        }
        println!("{v}");
    } else {
        print_summary(
            source,
            &setup,
            baseline,
            &f,
            note.as_deref(),
            simulated.is_some(),
        );
        print_held_out(&held, baseline);
        if let Some(sim) = simulated {
            super::output_error_refits::print(sim, &refits);
            super::output_error_refits::print_verdict(sim, by_simulation.as_ref(), &f);
        }
    }
    if let Some(dir) = &args.report {
        let simulated_lines = simulated.map(|sim| {
            super::output_error_refits::report_lines(sim, &refits, by_simulation.as_ref())
        });
        write_report(dir, source, baseline, &f, simulated_lines.as_deref())?;
        eprintln!("wrote {}", dir.join("index.html").display());
    }
    Ok(())
}

fn print_held_out(held: &[HeldOut], baseline: &Model) {
    for h in held {
        let after = match (h.effect, h.effect_nmse_percent) {
            (Some(e), Some(n)) => format!(" -> {n:.2} % with {e}"),
            (Some(e), None) => format!(" ({e} is not extra element terms: not predicted here)"),
            (None, _) => String::new(),
        };
        println!(
            "held-out record {} ({}): force NMSE {:.2} % with {}{after}; the force predicted from the measured motion ({})",
            h.step,
            h.excitation,
            h.baseline_nmse_percent,
            baseline.name,
            if h.acceleration_measured {
                "displacement differentiated, acceleration measured"
            } else {
                "displacement differentiated once and twice"
            }
        );
    }
}

fn print_summary(
    source: &str,
    setup: &Setup,
    baseline: &Model,
    f: &PhasorFindings,
    note: Option<&str>,
    simulated: bool,
) {
    let steps = if f.sampled_records > 0 {
        format!(
            "{} records with no steps (each fitted on its samples, the element force along the measured motion)",
            f.sampled_records
        )
    } else if f.multisine_steps == 0 {
        format!("{} sine steps", f.steps)
    } else {
        format!(
            "{} sine steps and {} multisine records (fitted through the identification's equations per line)",
            f.steps - f.multisine_steps,
            f.multisine_steps
        )
    };
    let measure = f.findings.evidence.measure();
    let evidence = if simulated {
        format!(
            "the evidence is the {measure}; the baseline and the named effect are then refitted by output error on the records and simulated on the held-out ones, a verdict of their own"
        )
    } else {
        format!("no records to simulate on, so the evidence is the {measure}")
    };
    println!(
        "{source}: baseline {} on {steps} ({} setup); {evidence}",
        baseline.name,
        setup.kind(),
    );
    if !f.not_fitted.is_empty() {
        println!(
            "not fitted on multisine records (nothing to fit with this baseline): {}",
            f.not_fitted
                .iter()
                .map(|e| e.name())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    for d in &f.dropped {
        println!("not a candidate here: {}: {}", d.effect.name(), d.reason);
    }
    if let Some(n) = note {
        println!("note: {n}");
    }
    println!(
        "  {:<20} {:>9} {:>9} {:>4}  added parameters",
        "effect", "CV %", "score %", "sig"
    );
    for r in &f.ranked_effects {
        println!(
            "  {:<20} {:>9.3} {:>9.3} {:>4}  {}",
            r.effect.name(),
            r.cv_percent,
            r.score_percent,
            if r.significant { "yes" } else { "no" },
            parameters_text(&r.added_parameters)
        );
    }
    for s in &f.located.summary {
        println!("where: {s}");
    }
    println!("verdict: {}", f.findings.headline());
    if matches!(
        f.findings.verdict,
        Verdict::Explained | Verdict::ExplainedInPart
    ) && let Some(r) = f.ranked_effects.first()
    {
        println!(
            "{}",
            model_with_effect_text(
                &baseline.name,
                r.effect.name(),
                &r.refitted_baseline,
                &r.added_parameters
            )
        );
    }
    println!("rule: {}", f.findings.rule);
}

/// `by_simulation`: the output-error refits' lines and their verdict, where the records were
/// simulated.
fn write_report(
    dir: &std::path::Path,
    source: &str,
    baseline: &Model,
    f: &PhasorFindings,
    by_simulation: Option<&[String]>,
) -> anyhow::Result<()> {
    write_dir_atomically(dir, |tmp| {
        let mut page = HtmlReport::new(&format!("Gap diagnosis: baseline {}", baseline.name));
        page.paragraph(source);
        page.verdict(&f.findings);
        page.list("Where", &f.located.summary);
        let rows: Vec<Vec<String>> = f
            .ranked_effects
            .iter()
            .map(|r| {
                vec![
                    r.effect.name().to_string(),
                    format!("{:.3}", r.cv_percent),
                    format!("{:.3}", r.score_percent),
                    if r.significant { "yes" } else { "no" }.into(),
                    parameters_text(&r.added_parameters),
                ]
            })
            .collect();
        page.table(
            "Candidates",
            &["effect", "CV [%]", "score [%]", "significant", "added"],
            &rows,
        );
        if let Some(lines) = by_simulation {
            page.list("Refitted by output error and simulated", lines);
        }
        write_atomically(&tmp.join("index.html"), &page.finish(&f.findings.rule))
    })
}
