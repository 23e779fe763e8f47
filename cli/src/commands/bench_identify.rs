//! `forcemap bench identify FILE`: how long `identify` takes on a rig CSV export, stage by stage
//! (CSV parsing, phasors, fit, validation by simulation), medians over repeats, and the same file
//! through the numpy peer a user would write (benches/numpy_peer.py: parse with numpy, fit the
//! first harmonic of each step, solve the paper's equations) as a ratio. A benchmark, not a
//! test: figures go in docs/benchmarks.md with the command that produced them.

use std::io::Write as _;
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{Context as _, bail};
use forcemap_math::identify;
use forcemap_math::model::IdentifiedModel;
use forcemap_math::pipeline;
use forcemap_math::recipe::Setup;
use forcemap_math::record::Excitation;
use serde_json::json;

use crate::cli::BenchIdentifyArgs;

/// The numpy peer, shipped inside the binary so that the command works from any directory.
const NUMPY_PEER: &str = include_str!("../../../benches/numpy_peer.py");

/// Seconds of each stage of one identification.
#[derive(Debug, Clone, Copy, Default)]
struct Stages {
    csv_s: f64,
    phasors_s: f64,
    fit_s: f64,
    validation_s: f64,
}

impl Stages {
    fn total_s(&self) -> f64 {
        self.csv_s + self.phasors_s + self.fit_s + self.validation_s
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// One identification as `forcemap identify` does it, timed by stage; returns the stages and
/// theta.
fn identify_once(args: &BenchIdentifyArgs) -> anyhow::Result<(Stages, Vec<(String, f64)>)> {
    let a = &args.identify;
    let file = a.file.display().to_string();
    let t0 = Instant::now();
    let import = forcemap_io::input::load(&a.file)?;
    let csv_s = t0.elapsed().as_secs_f64();
    let recipe = super::identify::recipe(a, import.kind, &import.parameters, &file)?;
    let setup = recipe.setup.setup()?;
    let model = recipe.model.build()?;
    let t1 = Instant::now();
    let (analyses, _) = pipeline::analyse_sine_steps(&import.records, &recipe.phasor)
        .with_context(|| format!("{file}: harmonic analysis"))?;
    let phasors_s = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let id = identify::identify(
        &model,
        &setup,
        recipe.method,
        &import.records,
        &analyses,
        &recipe.fd_options(),
    )
    .with_context(|| format!("{file}: identifying model '{}'", model.name))?;
    let fit_s = t2.elapsed().as_secs_f64();
    let t3 = Instant::now();
    if let Setup::BaseExcited { mass_kg } = setup {
        let fitted = IdentifiedModel::new(model.clone(), id.theta());
        for rec in import
            .records
            .iter()
            .filter(|r| matches!(r.excitation, Excitation::Random { .. }))
        {
            pipeline::validate_rig(&fitted, mass_kg, rec)
                .with_context(|| format!("{file}: validating on random record {}", rec.step))?;
        }
    }
    let validation_s = t3.elapsed().as_secs_f64();
    let theta = id
        .parameters
        .iter()
        .map(|p| (p.name.clone(), p.value))
        .collect();
    Ok((
        Stages {
            csv_s,
            phasors_s,
            fit_s,
            validation_s,
        },
        theta,
    ))
}

/// Median (parse, fit) seconds of the numpy peer and its parameters, from its JSON line.
fn run_peer(
    python: &std::path::Path,
    args: &BenchIdentifyArgs,
    mass_kg: f64,
) -> anyhow::Result<serde_json::Value> {
    // `python - ARGS` runs the script from stdin.
    let mut child = Command::new(python)
        .arg("-")
        .arg(&args.identify.file)
        .args(["--mass-kg", &mass_kg.to_string()])
        .args(["--repeats", &args.repeats.to_string()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("running {}", python.display()))?;
    child
        .stdin
        .take()
        .context("the numpy peer's stdin")?
        .write_all(NUMPY_PEER.as_bytes())
        .context("passing the numpy peer script")?;
    let out = child
        .wait_with_output()
        .with_context(|| format!("running {}", python.display()))?;
    if !out.status.success() {
        bail!(
            "the numpy peer failed under {} (does it have numpy?): {}",
            python.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let v: serde_json::Value =
        serde_json::from_slice(&out.stdout).context("reading the numpy peer's JSON output")?;
    let times = |key: &str| -> anyhow::Result<Vec<f64>> {
        v[key]
            .as_array()
            .and_then(|a| a.iter().map(serde_json::Value::as_f64).collect())
            .with_context(|| format!("the numpy peer's output has no list '{key}'"))
    };
    let (parse, fit) = (times("parse_s")?, times("fit_s")?);
    let total: Vec<f64> = parse.iter().zip(&fit).map(|(p, f)| p + f).collect();
    Ok(json!({
        "parse_s": median(parse),
        "fit_s": median(fit),
        "total_s": median(total),
        "k": v["k"], "c": v["c"], "fd": v["fd"], "rows": v["rows"],
    }))
}

pub fn run(args: &BenchIdentifyArgs) -> anyhow::Result<()> {
    if args.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    let mut runs = Vec::with_capacity(args.repeats);
    let mut theta = Vec::new();
    for _ in 0..args.repeats {
        let (stages, th) = identify_once(args)?;
        runs.push(stages);
        theta = th;
    }
    let med = |f: fn(&Stages) -> f64| median(runs.iter().map(f).collect());
    let ours = json!({
        "csv_s": med(|s| s.csv_s),
        "phasors_s": med(|s| s.phasors_s),
        "fit_s": med(|s| s.fit_s),
        "validation_s": med(|s| s.validation_s),
        "total_s": med(Stages::total_s),
        "theta": theta.iter().map(|(n, v)| (n.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
    });
    let file = args.identify.file.display().to_string();
    println!(
        "{file}: forcemap identify, medians of {} runs",
        args.repeats
    );
    for (label, key) in [
        ("CSV parsing", "csv_s"),
        ("phasors", "phasors_s"),
        ("fit", "fit_s"),
        ("validation", "validation_s"),
        ("total", "total_s"),
    ] {
        println!(
            "  {label:<12} {:>10.2} ms",
            ours[key].as_f64().unwrap_or(f64::NAN) * 1e3
        );
    }
    println!("  theta        {}", ours["theta"]);
    let Some(python) = &args.python else {
        println!("numpy peer not run: give --python PATH (a python with numpy)");
        return Ok(());
    };
    let mass_kg = match args.identify.mass_kg {
        Some(m) => m,
        None => {
            let import = forcemap_io::input::load(&args.identify.file)?;
            let recipe =
                super::identify::recipe(&args.identify, import.kind, &import.parameters, &file)?;
            match recipe.setup.setup()? {
                Setup::BaseExcited { mass_kg } => mass_kg,
                _ => bail!("{file}: the numpy peer fits a base-excited rig export only"),
            }
        }
    };
    let peer = run_peer(python, args, mass_kg)?;
    let peer_total = peer["total_s"].as_f64().unwrap_or(f64::NAN);
    let ratio = peer_total / ours["total_s"].as_f64().unwrap_or(f64::NAN);
    println!(
        "numpy peer ({}), medians of {} runs: parse {:.2} ms, fit {:.2} ms, total {:.2} ms; k {:.6e}, c {:.6e}, fd {:.6e}",
        python.display(),
        args.repeats,
        peer["parse_s"].as_f64().unwrap_or(f64::NAN) * 1e3,
        peer["fit_s"].as_f64().unwrap_or(f64::NAN) * 1e3,
        peer_total * 1e3,
        peer["k"].as_f64().unwrap_or(f64::NAN),
        peer["c"].as_f64().unwrap_or(f64::NAN),
        peer["fd"].as_f64().unwrap_or(f64::NAN),
    );
    println!("ratio numpy peer / forcemap (total): {ratio:.1}x");
    Ok(())
}
