//! `forcemap diagnose-eval`: the gap diagnosis checked on seeded simulated cases whose planted
//! effect it is not told (library: `forcemap_eval::diagnose_eval`).

use forcemap_eval::diagnose_eval::{
    self as eval, CaseResult, CaseSpec, DIVERGED_BASELINE_PERCENT, EvalSummary,
};

use crate::cli::{DiagnoseEvalArgs, EvalForms};
use forcemap_math::diagnose::findings::percent_text;

pub fn run(args: &DiagnoseEvalArgs) -> anyhow::Result<()> {
    if args.cases == 0 {
        anyhow::bail!("--cases must be at least 1");
    }
    if !args.snr_db.is_finite() {
        anyhow::bail!("--snr-db = {}: not a finite number", args.snr_db);
    }
    if let Some(s) = args
        .seed
        .iter()
        .enumerate()
        .find_map(|(i, s)| args.seed[..i].contains(s).then_some(s))
    {
        anyhow::bail!("--seed {s} is given twice: each seed's cases would count twice");
    }
    let mut cases: Vec<CaseSpec> = args
        .seed
        .iter()
        .flat_map(|&seed| match args.forms {
            EvalForms::Exact => eval::generate_cases(args.cases, seed, args.snr_db),
            EvalForms::Wide => eval::generate_wide_cases(args.cases, seed),
        })
        .collect();
    if let Some(i) = args.only.iter().find(|i| **i >= args.cases) {
        anyhow::bail!(
            "--only {i}: there are only {} cases (indices 0..{}); raise --cases",
            args.cases,
            args.cases - 1
        );
    }
    if !args.only.is_empty() {
        cases.retain(|c| args.only.contains(&c.index));
    }
    if let Some(path) = &args.json_file {
        // Before the run, not after: a long run should not end in a path it cannot write.
        let dir = forcemap_io::atomic::parent_dir(path);
        if !dir.is_dir() {
            anyhow::bail!(
                "--json-file {}: the directory {} does not exist",
                path.display(),
                dir.display()
            );
        }
    }
    let pb = indicatif::ProgressBar::new(cases.len() as u64);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{bar:40} {pos}/{len} cases, {elapsed} ({eta} left) {msg}",
        )
        .expect("a valid template"),
    );
    let progress = |r: &CaseResult| {
        pb.set_message(format!("last: {} -> {}", r.label, r.named));
        pb.inc(1);
    };
    let results = eval::run_cases(&cases, args.threads, &progress);
    pb.finish_and_clear();
    let summary = eval::summarise(&results, args.snr_db);
    // Built once, for the file and for stdout alike.
    let json = (args.json || args.json_file.is_some()).then(|| {
        let per_seed: Vec<_> = args
            .seed
            .iter()
            .map(|&seed| {
                let of_seed = of_seed(&cases, &results, seed);
                serde_json::json!({"seed": seed, "summary": eval::summarise(&of_seed, args.snr_db)})
            })
            .collect();
        let cases: Vec<_> = results.iter().filter_map(|r| r.as_ref().ok()).collect();
        serde_json::json!({"seeds": args.seed, "summary": summary, "per_seed": per_seed, "cases": cases})
    });
    if let (Some(path), Some(json)) = (&args.json_file, &json) {
        forcemap_io::atomic::write_atomically(path, &format!("{json}\n"))?;
    }
    if let (true, Some(json)) = (args.json, &json) {
        println!("{json}");
    } else if !args.only.is_empty() {
        for r in &results {
            match r {
                Ok(r) => print_case(r),
                Err(e) => println!("failed: {e}"),
            }
        }
    } else if args.forms == EvalForms::Wide {
        print_wide(args, &results);
    } else {
        print_summary(args, &summary, &results);
        if args.seed.len() > 1 {
            print_per_seed(args, &results);
        }
    }
    Ok(())
}

/// The seeds as given: `1,2,3`.
fn seeds_text(args: &DiagnoseEvalArgs) -> String {
    args.seed
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

/// The results of the cases generated from `seed` (`results[i]` is `cases[i]`'s).
fn of_seed(
    cases: &[CaseSpec],
    results: &[Result<CaseResult, String>],
    seed: u64,
) -> Vec<Result<CaseResult, String>> {
    cases
        .iter()
        .zip(results)
        .filter(|(c, _)| c.generator_seed == seed)
        .map(|(_, r)| r.clone())
        .collect()
}

fn pct(r: &eval::Rate) -> String {
    if r.of == 0 {
        return "no such case".into();
    }
    format!("{:.1} % ({}/{})", r.percent, r.hits, r.of)
}

/// One rate of each seed's own summary of `results` (failed cases left out): "seed 1: 20/20,
/// seed 2: 25/27".
fn per_seed_rate(
    args: &DiagnoseEvalArgs,
    results: &[Result<CaseResult, String>],
    snr_db: f64,
    rate: impl Fn(&EvalSummary) -> &eval::Rate,
) -> String {
    args.seed
        .iter()
        .map(|&seed| {
            let of_seed: Vec<Result<CaseResult, String>> = results
                .iter()
                .filter(|r| r.as_ref().is_ok_and(|r| r.case.generator_seed == seed))
                .cloned()
                .collect();
            let s = eval::summarise(&of_seed, snr_db);
            let r = rate(&s);
            format!("seed {seed}: {}/{}", r.hits, r.of)
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// One rate picked out of a summary.
type RateOf = fn(&EvalSummary) -> &eval::Rate;

/// The exact forms' headline rates seed by seed, after the pooled report.
fn print_per_seed(args: &DiagnoseEvalArgs, results: &[Result<CaseResult, String>]) {
    println!("per seed:");
    let rates: [(&str, RateOf); 4] = [
        ("top-1 at the lower SNR", |s| &s.top1),
        ("false alarms", |s| &s.false_alarms),
        ("two-effect cases naming one of the two", |s| {
            &s.pairs_one_named
        }),
        ("both of a pair among the top two", |s| {
            &s.pairs_both_top_two
        }),
    ];
    for (name, rate) in rates {
        println!(
            "  {name}: {}",
            per_seed_rate(args, results, args.snr_db, rate)
        );
    }
}

fn print_summary(args: &DiagnoseEvalArgs, s: &EvalSummary, results: &[Result<CaseResult, String>]) {
    println!(
        "forcemap diagnose-eval --cases {} --seed {} --snr-db {}: {} cases ({} failed)",
        args.cases,
        seeds_text(args),
        args.snr_db,
        s.cases,
        s.failed.len()
    );
    println!(
        "top-1 hit rate, single effects causing >= 2 % held-out NMSE alone, at {} dB: {}  (target >= 95 %)",
        args.snr_db,
        pct(&s.top1)
    );
    println!(
        "top-1 hit rate, the same counting effects by the baseline's gap (noise included) >= 2 %: {}",
        pct(&s.top1_by_baseline_gap)
    );
    println!(
        "top-1 hit rate, the same at {} and {} dB: {}",
        args.snr_db,
        args.snr_db + 10.0,
        pct(&s.top1_all_snr)
    );
    println!(
        "false alarms on no-effect cases: {}  (target <= 5 %)",
        pct(&s.false_alarms)
    );
    println!(
        "out-of-library cases given a library name: {}  (target <= 10 %); named in part: {}",
        pct(&s.out_of_library_named),
        pct(&s.out_of_library_named_in_part)
    );
    println!(
        "single effects below 2 % gap: named right {}, adequate {}, other answer {}",
        pct(&s.below_threshold_named_right),
        pct(&s.below_threshold_adequate),
        pct(&s.below_threshold_wrong)
    );
    println!(
        "two-effect cases naming one of the two: {}",
        pct(&s.pairs_one_named)
    );
    println!(
        "shrink, explained single effects: |predicted - true| mean {:.2}, median {:.2} %-points (mean true shrink {:.2} %-points){}",
        s.shrink_mean_abs_error_percent,
        s.shrink_median_abs_error_percent,
        s.shrink_mean_true_percent,
        diverged_note(s)
    );
    print_confusion(s);
    println!("confusable pairs (single effects, every SNR; planted as the one, named the other):");
    for p in &s.confusable_pairs {
        println!(
            "  {} / {}: {} cases, {} named {}, {} named {}",
            p.effects[0].name(),
            p.effects[1].name(),
            p.cases,
            p.first_named_second,
            p.effects[1].name(),
            p.second_named_first,
            p.effects[0].name()
        );
    }
    for e in &s.failed {
        println!("failed: {e}");
    }
    let _ = results;
}

/// The confusion matrix (rows: planted; columns: named), with its column key.
fn print_confusion(s: &EvalSummary) {
    let mut columns: Vec<String> = s
        .confusion
        .values()
        .flat_map(|m| m.keys().cloned())
        .collect();
    columns.sort();
    columns.dedup();
    // Rows as wide as the longest planted label ("out_of_library:exciter_resonance").
    let width = s
        .confusion
        .keys()
        .map(String::len)
        .max()
        .unwrap_or(0)
        .max(28);
    println!("confusion matrix (rows: planted; columns: named):");
    print!("{:<width$}", "");
    for c in &columns {
        print!(" {:>8}", abbreviate(c));
    }
    println!();
    for (row, m) in &s.confusion {
        print!("{row:<width$}");
        for c in &columns {
            match m.get(c) {
                Some(n) => print!(" {n:>8}"),
                None => print!(" {:>8}", "."),
            }
        }
        println!();
    }
    println!(
        "columns: {}",
        columns
            .iter()
            .map(|c| format!("{} = {c}", abbreviate(c)))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// The wide forms' report: each group scored separately by the one summariser.
fn print_wide(args: &DiagnoseEvalArgs, results: &[Result<CaseResult, String>]) {
    let ok: Vec<&CaseResult> = results.iter().filter_map(|r| r.as_ref().ok()).collect();
    println!(
        "forcemap diagnose-eval --forms wide --cases {} --seed {}: {} cases ({} failed)",
        args.cases,
        seeds_text(args),
        results.len(),
        results.iter().filter(|r| r.is_err()).count()
    );
    let several = args.seed.len() > 1;
    let mut groups: Vec<String> = eval::WIDE_SNRS_DB
        .iter()
        .map(|snr| format!("single effects at {snr} dB"))
        .collect();
    groups.extend(["pairs", "out of library", "new names", "no effect"].map(String::from));
    for g in &groups {
        let subset: Vec<Result<CaseResult, String>> = ok
            .iter()
            .filter(|r| eval::wide_group(&r.case) == *g)
            .map(|r| Ok((*r).clone()))
            .collect();
        let snr = subset
            .first()
            .and_then(|r| r.as_ref().ok())
            .map_or(eval::WIDE_SNRS_DB[1], |r| r.case.snr_db);
        let s = eval::summarise(&subset, snr);
        let by_seed = |rate: RateOf| {
            if several {
                format!("\n  {}", per_seed_rate(args, &subset, snr, rate))
            } else {
                String::new()
            }
        };
        println!();
        println!("== {g}: {} cases", subset.len());
        match g.as_str() {
            "pairs" => {
                println!("top effect one of the two: {}", pct(&s.pairs_one_named));
                println!(
                    "both among the top two (the pair the verdict names, else the two best-ranked): {}  (target >= 80 %){}",
                    pct(&s.pairs_both_top_two),
                    by_seed(|s| &s.pairs_both_top_two)
                );
                println!(
                    "the same over the pairs whose members each cause >= 2 % held-out NMSE alone: {}{}",
                    pct(&s.pairs_qualifying_both_top_two),
                    by_seed(|s| &s.pairs_qualifying_both_top_two)
                );
                println!(
                    "both named by the verdict (explained by A together with B): {}",
                    pct(&s.pairs_both_named)
                );
                for r in subset.iter().filter_map(|r| r.as_ref().ok()) {
                    let top: Vec<&str> =
                        r.ranked.iter().take(2).map(|x| x.effect.as_str()).collect();
                    let named = match &r.second_named {
                        Some(second) => format!("{} + {second}", r.named),
                        None => r.named.clone(),
                    };
                    let alone = r.member_gap_percent.map_or(String::new(), |g| {
                        format!("  (alone {}, {})", percent_text(g[0]), percent_text(g[1]))
                    });
                    println!(
                        "  {:<8} {:<40} -> {:<42} ranked {}{alone}",
                        format!("{}/{}", r.case.generator_seed, r.case.index),
                        r.label,
                        named,
                        top.join(", ")
                    );
                }
                continue;
            }
            "out of library" => {
                println!(
                    "given a library name: {}  (target <= 10 %){}",
                    pct(&s.out_of_library_named),
                    by_seed(|s| &s.out_of_library_named)
                );
                println!(
                    "named \"in part\" (a lead that is not there): {}{}",
                    pct(&s.out_of_library_named_in_part),
                    by_seed(|s| &s.out_of_library_named_in_part)
                );
            }
            "no effect" => println!(
                "false alarms: {}  (target <= 5 %){}",
                pct(&s.false_alarms),
                by_seed(|s| &s.false_alarms)
            ),
            _ => {
                println!(
                    "top-1, effects causing >= 2 % held-out NMSE alone: {}{}{}",
                    pct(&s.top1),
                    if g.ends_with("30 dB") {
                        "  (target >= 95 %)"
                    } else {
                        ""
                    },
                    by_seed(|s| &s.top1)
                );
                println!(
                    "below 2 %: named right {}, adequate {}, other answer {}",
                    pct(&s.below_threshold_named_right),
                    pct(&s.below_threshold_adequate),
                    pct(&s.below_threshold_wrong)
                );
                println!(
                    "named as a pair (a second effect that is not there): {}",
                    pct(&s.singles_named_as_pair)
                );
                println!(
                    "shrink, explained (>= 2 %): within 20 % of the true model's {}  (|predicted - true| mean {:.2}, median {:.2} %-points, mean true {:.2} %-points{})",
                    pct(&s.shrink_within_20_percent),
                    s.shrink_mean_abs_error_percent,
                    s.shrink_median_abs_error_percent,
                    s.shrink_mean_true_percent,
                    diverged_note(&s)
                );
            }
        }
        print_confusion(&s);
    }
    for r in results.iter().filter_map(|r| r.as_ref().err()) {
        println!("failed: {r}");
    }
}

/// One case in full: what was planted, what was named, and every candidate's figures.
fn print_case(r: &CaseResult) {
    println!(
        "case {} of seed {} (case seed {}, {} dB): planted {} -> {}; gap {} -> {}, true model {}, noise floor {}; baseline step CV {}",
        r.case.index,
        r.case.generator_seed,
        r.case.seed,
        r.case.snr_db,
        r.label,
        r.named,
        percent_text(r.gap_before_percent),
        percent_text(r.gap_after_percent),
        percent_text(r.truth_nmse_percent),
        percent_text(r.noise_floor_percent),
        r.baseline_cv_percent
            .map_or("-".to_string(), |v| format!("{v:.3} %"))
    );
    if let Some(m) = r.baseline_output_error_misfit {
        println!("    (output-error misfit on the sine steps: baseline {m:.3} noise std)");
    }
    for c in &r.ranked {
        let cv = c
            .step_cv_percent
            .map_or("-".to_string(), |v| format!("{v:.3} %"));
        let [after, score] = [c.gap_after_percent, c.score_percent].map(|p| {
            if p.abs() < 1e4 {
                format!("{p:>7.3} %")
            } else {
                format!("{p:>7.2e} %")
            }
        });
        let oe = c
            .output_error_misfit
            .map_or(String::new(), |m| format!("  OE misfit {m:.3}"));
        println!(
            "    {:<22} held-out {after}  score {score}  step CV {cv:>9}{oe}",
            c.effect
        );
    }
    for n in &r.notes {
        println!("    note: {n}");
    }
}

/// A column label of at most 8 characters.
fn abbreviate(name: &str) -> String {
    match name {
        "adequate" => "adequate".into(),
        "unexplained" => "unexpl".into(),
        n if n.ends_with(eval::IN_PART) => {
            // "seri_c/p": a name in part beside the same name explained.
            let base: String = abbreviate(n.trim_end_matches(eval::IN_PART))
                .chars()
                .take(6)
                .collect();
            format!("{base}/p")
        }
        n => n
            .split('_')
            .map(|w| w.chars().take(4).collect::<String>())
            .collect::<Vec<_>>()
            .join("_")
            .chars()
            .take(8)
            .collect(),
    }
}

/// The cases left out of the shrink statistics because the baseline diverged, if any.
fn diverged_note(s: &EvalSummary) -> String {
    match s.shrink_baseline_diverged {
        0 => String::new(),
        n => format!(
            "; {n} case(s) left out whose baseline's held-out NMSE is above {DIVERGED_BASELINE_PERCENT} % (its simulation diverges)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_rate_of_no_case_says_so() {
        let none = eval::Rate {
            hits: 0,
            of: 0,
            percent: f64::NAN,
        };
        assert_eq!(pct(&none), "no such case");
        let some = eval::Rate {
            hits: 1,
            of: 4,
            percent: 25.0,
        };
        assert_eq!(pct(&some), "25.0 % (1/4)");
    }

    #[test]
    fn a_name_in_part_has_its_own_column_label() {
        assert_eq!(abbreviate("series_compliance"), "seri_com");
        let in_part = format!("series_compliance{}", eval::IN_PART);
        assert_eq!(abbreviate(&in_part), "seri_c/p");
        assert_eq!(abbreviate("unexplained"), "unexpl");
    }
}
