//! `forcemap diagnose FILE.mat --model emps-viscous|emps-coulomb --validate PULSES.mat`: the
//! time-domain path of the gap diagnosis on the EMPS benchmark (library:
//! `forcemap_math::diagnose::time_domain`).

use std::path::Path;

use anyhow::{Context, bail};
use forcemap_math::diagnose::Verdict;
use forcemap_math::diagnose::time_domain::{
    AxisBaseline, AxisRecord, TimeDomainOptions, diagnose_axis,
};

use crate::cli::DiagnoseArgs;
use crate::emps::read_emps;

/// Published relative force errors (METHOD.md section 6) [%].
const PUBLISHED: [(&str, f64); 3] = [
    ("symmetric Coulomb, fit record", 4.08),
    ("asymmetric friction, fit record", 3.11),
    ("symmetric Coulomb, pulses validation", 5.98),
];

/// True for a MATLAB file (the EMPS benchmark).
pub fn is_emps(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("mat"))
}

fn axis(path: &Path) -> anyhow::Result<AxisRecord> {
    let d = read_emps(path)?;
    let fs = d.sample_rate_hz();
    if !(fs.is_finite() && fs > 0.0) {
        bail!(
            "{}: no sample rate (fewer than two samples or constant time)",
            path.display()
        );
    }
    Ok(AxisRecord {
        sample_rate_hz: fs,
        position_m: d.position_m,
        force_n: d.force_n,
    })
}

pub fn run(args: &DiagnoseArgs, data: &Path) -> anyhow::Result<()> {
    let model = args.model.as_deref().unwrap_or_default();
    let Some(baseline) = AxisBaseline::from_name(model) else {
        bail!(
            "{}: an EMPS record takes the baseline emps-viscous (M q'' + Fv q' + offset) or emps-coulomb (+ Fc sgn(q')), not '{model}'",
            data.display()
        );
    };
    if args.report.is_some() {
        bail!("--report is for stepped-sine rig data; the EMPS path prints its summary or --json");
    }
    let Some(val_path) = &args.validate else {
        bail!(
            "{}: the time-domain path scores on another record: give --validate (e.g. DATA_EMPS_PULSES.mat)",
            data.display()
        );
    };
    let fit = axis(data)?;
    let val = axis(val_path)?;
    let d = diagnose_axis(baseline, &fit, &val, &TimeDomainOptions::default())
        .with_context(|| format!("{}: diagnosing baseline {model}", data.display()))?;
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
        d.baseline_parameters
            .iter()
            .map(|p| format!("{} = {:.4}", p.name, p.value))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "gap: relative force error {:.2} % on {} ({:.2} % on the fitting record)",
        d.gap_before_percent,
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
        "  {:<20} {:>9} {:>9} {:>9} {:>4}  added parameters",
        "effect", "val %", "fit %", "score %", "sig"
    );
    for r in &d.ranked_effects {
        println!(
            "  {:<20} {:>9.3} {:>9.3} {:>9.3} {:>4}  {}",
            r.effect.name(),
            r.gap_after_percent,
            r.fit_percent,
            r.score_percent,
            if r.significant { "yes" } else { "no" },
            r.added_parameters
                .iter()
                .map(|p| format!("{} = {:.4}", p.name, p.value))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    match (d.verdict, d.top_effect) {
        (Verdict::Explained, Some(e)) => println!(
            "verdict: explained by {}: {:.2} % -> {:.2} %",
            e.name(),
            d.gap_before_percent,
            d.gap_after_percent
        ),
        (v, _) => println!(
            "verdict: {} (best candidate {:.2} % -> {:.2} %)",
            v.name(),
            d.gap_before_percent,
            d.gap_after_percent
        ),
    }
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
