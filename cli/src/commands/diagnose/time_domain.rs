//! `forcemap diagnose FILE.mat --model emps-viscous|emps-coulomb --validate PULSES.mat`: the
//! time-domain path of the gap diagnosis on the EMPS benchmark (library:
//! `forcemap_math::diagnose::time_domain`).

use std::path::Path;

use anyhow::{Context, bail};
use forcemap_math::diagnose::time_domain::{
    AxisBaseline, AxisDiagnosis, AxisRecord, SHRINK_T_MIN, TimeDomainOptions, diagnose_axis,
};
use plotters::style::colors::BLACK;

use crate::cli::DiagnoseArgs;
use crate::plot::{
    AFTER_COLOR, BASELINE_COLOR, BinnedMean, Line, ScatterPanel, heatmap_panels_svg, lines_svg,
    scatter_panels_svg,
};
use crate::report::{HtmlReport, parameters_text};
use forcemap_io::atomic::{write_atomically, write_dir_atomically};
use forcemap_io::axis::read_axis;

/// Published relative force errors (METHOD.md section 6) [%].
const PUBLISHED: [(&str, f64); 3] = [
    ("symmetric Coulomb, fit record", 4.08),
    ("asymmetric friction, fit record", 3.11),
    ("symmetric Coulomb, pulses validation", 5.98),
];

/// The time-domain diagnosis of the axis record `fit` (read from `data`), scored on the
/// `--validate` record (a MAT file or a bag of the same kind).
pub fn run(args: &DiagnoseArgs, data: &Path, fit: &AxisRecord) -> anyhow::Result<()> {
    let model = args.model.as_deref().unwrap_or_default();
    let Some(baseline) = AxisBaseline::from_name(model) else {
        bail!(
            "{}: an axis record takes the baseline emps-viscous (M q'' + Fv q' + offset) or emps-coulomb (+ Fc sgn(q')), not '{model}'",
            data.display()
        );
    };
    // Refuse an existing report directory before any work.
    if let Some(dir) = &args.report
        && dir.exists()
    {
        bail!(
            "{}: the report directory exists already; remove it or choose a new one",
            dir.display()
        );
    }
    let val_path = match args.validate.as_slice() {
        [one] => one,
        [] => bail!(
            "{}: the time-domain path scores on another record: give --validate (e.g. DATA_EMPS_PULSES.mat)",
            data.display()
        ),
        _ => bail!(
            "{}: the time-domain path scores on one record: give one --validate file",
            data.display()
        ),
    };
    let val = read_axis(val_path)?;
    let d = diagnose_axis(baseline, fit, &val, &TimeDomainOptions::default())
        .with_context(|| format!("{}: diagnosing baseline {model}", data.display()))?;
    if let Some(dir) = &args.report {
        write_report(dir, &d, data, val_path)
            .with_context(|| format!("writing the report {}", dir.display()))?;
        eprintln!("wrote {}", dir.join("index.html").display());
    }
    if args.json {
        let mut v = serde_json::to_value(&d)?;
        v["published"] = serde_json::json!(
            PUBLISHED
                .iter()
                .map(|(w, e)| serde_json::json!({"what": w, "relative_error_percent": e}))
                .collect::<Vec<_>>()
        );
        println!("{v}");
        return Ok(());
    }
    println!(
        "{}: baseline {} fitted ({} equations): {}",
        data.display(),
        d.baseline_model,
        d.equations,
        parameters_text(&d.baseline_parameters)
    );
    println!(
        "gap: relative force error {:.2} % on {} ({:.2} % on the fitting record)",
        d.findings.gap_before_percent,
        val_path.display(),
        d.fit_before_percent
    );
    println!(
        "floor: {:.2} % (set by {}): what no element effect removes, the smallest validation error of a memoryless force law fitted on the fitting record",
        d.floor.floor_percent, d.floor.set_by,
    );
    println!(
        "  best of {} flexible laws: {:.2} % on the validation record, {:.2} % on the fitting record: {}",
        d.floor.flexible_laws_tried,
        d.floor.flexible_law_percent,
        d.floor.flexible_law_fit_percent,
        d.floor.flexible_law
    );
    for s in &d.located.summary {
        println!("  {s}");
    }
    println!(
        "  {:<20} {:>9} {:>9} {:>9} {:>7} {:>4}  added parameters",
        "effect", "val %", "fit %", "score %", "t", "sig"
    );
    for r in &d.ranked_effects {
        println!(
            "  {:<20} {:>9.3} {:>9.3} {:>9.3} {:>7.2} {:>4}  {}",
            r.effect.name(),
            r.gap_after_percent,
            r.fit_percent,
            r.score_percent,
            r.shrink_t,
            if r.significant { "yes" } else { "no" },
            parameters_text(&r.added_parameters)
        );
    }
    if let Some(top) = d.ranked_effects.first() {
        println!("  {}", removable_text(&d, top.effect.name()));
    }
    println!("verdict: {}", d.findings.headline());
    println!(
        "published: {}",
        PUBLISHED
            .iter()
            .map(|(w, e)| format!("{e:.2} % ({w})"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}

/// How much of the removable gap (gap - floor) the top candidate removes, against the rule's
/// thresholds.
fn removable_text(d: &AxisDiagnosis, top: &str) -> String {
    let removable = d.findings.gap_before_percent - d.floor.floor_percent;
    let removed = d.findings.gap_before_percent - d.findings.gap_after_percent;
    format!(
        "removable gap (gap - floor) {removable:.2} %-points; {top} removes {removed:.2} of them ({:.0} %); explained needs at least half of them, a shrink above max(10 % of the gap, 0.2) = {:.2} %-points, consistent over the validation record (block t >= {}), and a penalised score below the baseline's",
        100.0 * removed / removable.max(f64::MIN_POSITIVE),
        (0.1 * d.findings.gap_before_percent).max(0.2),
        SHRINK_T_MIN
    )
}

/// Length of the readable window of the force trace [s].
const WINDOW_S: f64 = 5.0;
/// Bins of the state-plane map (position x velocity).
const STATE_BINS: (usize, usize) = (16, 16);

/// The index range of the `WINDOW_S` window (in whole seconds) where the baseline's residual
/// energy is largest.
fn worst_window(time_s: &[f64], residual: &[f64]) -> std::ops::Range<usize> {
    let n = time_s.len();
    if n < 2 {
        return 0..n;
    }
    let dt = (time_s[n - 1] - time_s[0]) / (n - 1) as f64;
    let width = ((WINDOW_S / dt).round() as usize).clamp(1, n);
    let step = ((1.0 / dt).round() as usize).max(1);
    let energy = |start: usize| {
        residual[start..start + width]
            .iter()
            .map(|r| r * r)
            .sum::<f64>()
    };
    let best = (0..=n - width)
        .step_by(step)
        .max_by(|a, b| energy(*a).total_cmp(&energy(*b)))
        .unwrap_or(0);
    best..best + width
}

/// The HTML report: measured against predicted force on the validation record (a window and
/// the whole), the residual against velocity and over the state plane, before and after the
/// top candidate.
fn write_report(dir: &Path, d: &AxisDiagnosis, fit: &Path, val: &Path) -> anyhow::Result<()> {
    let tr = &d.traces;
    let top = d.ranked_effects.first();
    let top_name = top.map_or("", |r| r.effect.name());
    let after_label = format!("with {top_name}");
    let residual = |model: &[f64]| -> Vec<f64> {
        tr.measured_n
            .iter()
            .zip(model)
            .map(|(m, p)| m - p)
            .collect()
    };
    let before = residual(&tr.baseline_n);
    let after = tr.top_n.as_deref().map(residual);
    write_dir_atomically(dir, |tmp| {
        let mut figures: Vec<(&str, String)> = Vec::new();
        let mut lines = vec![
            Line {
                label: "measured",
                values: &tr.measured_n,
                color: BLACK,
            },
            Line {
                label: &d.baseline_model,
                values: &tr.baseline_n,
                color: BASELINE_COLOR,
            },
        ];
        if let Some(t) = &tr.top_n {
            lines.push(Line {
                label: &after_label,
                values: t,
                color: AFTER_COLOR,
            });
        }
        let errors = format!(
            "{:.2} % {}{}",
            d.findings.gap_before_percent,
            d.baseline_model,
            top.map_or(String::new(), |r| format!(
                ", {:.2} % {after_label}",
                r.gap_after_percent
            ))
        );
        let w = worst_window(&tr.time_s, &before);
        let window: Vec<Line> = lines
            .iter()
            .map(|l| Line {
                label: l.label,
                values: &l.values[w.clone()],
                color: l.color,
            })
            .collect();
        write_atomically(
            &tmp.join("force_window.svg"),
            &lines_svg(
                &format!(
                    "validation record, the {WINDOW_S:.0} s with the largest baseline residual"
                ),
                &tr.time_s[w.clone()],
                "time [s]",
                "force [N]",
                &window,
            )?,
        )?;
        figures.push((
            "force_window.svg",
            format!("Measured against predicted force, {WINDOW_S:.0} s of the validation record where the baseline is worst (relative force error over the whole record: {errors})"),
        ));
        write_atomically(
            &tmp.join("force_whole.svg"),
            &lines_svg(
                "validation record, whole",
                &tr.time_s,
                "time [s]",
                "force [N]",
                &lines,
            )?,
        )?;
        figures.push((
            "force_whole.svg",
            "Measured against predicted force, the whole validation record".into(),
        ));
        let mut panels = vec![ScatterPanel {
            caption: format!(
                "{} ({:.2} %)",
                d.baseline_model, d.findings.gap_before_percent
            ),
            x: &tr.velocity_mps,
            y: &before,
            color: BASELINE_COLOR,
        }];
        if let (Some(a), Some(r)) = (&after, top) {
            panels.push(ScatterPanel {
                caption: format!("{after_label} ({:.2} %)", r.gap_after_percent),
                x: &tr.velocity_mps,
                y: a,
                color: AFTER_COLOR,
            });
        }
        write_atomically(
            &tmp.join("residual_velocity.svg"),
            &scatter_panels_svg(
                "residual force (measured - model) against velocity, validation record",
                "velocity q' [m/s]",
                "residual force [N]",
                &panels,
            )?,
        )?;
        figures.push((
            "residual_velocity.svg",
            "Residual against velocity, before and after the top candidate".into(),
        ));
        let (nq, nv) = STATE_BINS;
        let mut maps = vec![(
            d.baseline_model.clone(),
            BinnedMean::new(&tr.position_m, &tr.velocity_mps, &before, nq, nv),
        )];
        if let Some(a) = &after {
            maps.push((
                after_label.clone(),
                BinnedMean::new(&tr.position_m, &tr.velocity_mps, a, nq, nv),
            ));
        }
        write_atomically(
            &tmp.join("state_plane.svg"),
            &heatmap_panels_svg(
                "mean residual force over the state plane, validation record",
                "position q [m]",
                "velocity q' [m/s]",
                "N",
                &maps,
            )?,
        )?;
        figures.push((
            "state_plane.svg",
            format!("Mean residual force in {nq} x {nv} bins of position and velocity, before and after the top candidate"),
        ));
        write_atomically(&tmp.join("index.html"), &html(d, fit, val, &figures))
    })
}

fn html(d: &AxisDiagnosis, fit: &Path, val: &Path, figures: &[(&str, String)]) -> String {
    let mut page = HtmlReport::new(&format!(
        "Gap diagnosis (time domain): baseline {}",
        d.baseline_model
    ));
    page.paragraph(&format!(
        "Fitted on {} ({} equations), scored on {} ({} equations); relative force error of the decimated force.",
        fit.display(),
        d.equations,
        val.display(),
        d.validation_equations
    ));
    page.paragraph(&format!(
        "Baseline parameters: {}",
        parameters_text(&d.baseline_parameters)
    ));
    page.verdict(&d.findings);
    page.paragraph(&format!(
        "On the fitting record: {:.2} % with the baseline, {} with the top candidate. Floor {:.2} % (set by {}): {}.",
        d.fit_before_percent,
        d.ranked_effects
            .first()
            .map_or("-".into(), |r| format!("{:.2} %", r.fit_percent)),
        d.floor.floor_percent,
        d.floor.set_by,
        d.floor.what,
    ));
    page.paragraph(&format!(
        "Best flexible law: {} ({:.2} % on the validation record, {:.2} % on the fitting record; best of {}).",
        d.floor.flexible_law,
        d.floor.flexible_law_percent,
        d.floor.flexible_law_fit_percent,
        d.floor.flexible_laws_tried,
    ));
    if let Some(top) = d.ranked_effects.first() {
        page.paragraph(&format!("{}.", removable_text(d, top.effect.name())));
    }
    page.paragraph(&format!(
        "Published (EMPS): {}.",
        PUBLISHED
            .iter()
            .map(|(w, e)| format!("{e:.2} % ({w})"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    page.list("Where", &d.located.summary);
    let rows: Vec<Vec<String>> = d
        .ranked_effects
        .iter()
        .map(|r| {
            vec![
                r.effect.name().to_string(),
                format!("{:.3}", r.gap_after_percent),
                format!("{:.3}", r.fit_percent),
                format!("{:.3}", r.score_percent),
                format!("{:.2}", r.shrink_t),
                if r.significant { "yes" } else { "no" }.into(),
                parameters_text(&r.added_parameters),
                r.signature.clone(),
            ]
        })
        .collect();
    page.table(
        "Candidates",
        &[
            "effect",
            "validation [%]",
            "fit [%]",
            "score [%]",
            "t",
            "significant",
            "added",
            "signature",
        ],
        &rows,
    );
    page.figures(figures);
    page.finish(&d.findings.rule)
}
