//! `forcemap bench identify FILE`: how long `identify` takes on a rig's file, stage by stage
//! (reading the file, phasors, fit, validation by simulation; a file `identify` streams has its
//! sine steps analysed in the reading), medians over repeats, its throughput
//! (MB/s and rows/s of the whole identification) and the peak memory of the process; with
//! `--python`, a peer on the same file as a ratio: the time polars (or, without it, numpy; for
//! an MDF4 or TDMS file asammdf or npTDMS) needs to load the file (benches/load_peer.py), or the
//! numpy script a user would write to load
//! and fit it (benches/numpy_peer.py: fit the first harmonic of each step, solve the paper's
//! equations). A benchmark, not a test: figures go in docs/benchmarks.md with the command that
//! produced them.
//!
//! Each stage is timed twice: wall time, and the CPU time of the process. On a shared machine
//! the wall time of a stage is mostly waiting for a core; the CPU times compare the work.

use std::io::Write as _;
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::{Context as _, bail};
use forcemap_math::model::IdentifiedModel;
use forcemap_math::pipeline;
use forcemap_math::recipe::Setup;
use serde_json::json;

use crate::cli::{BenchIdentifyArgs, PeerArg};

/// The peers, shipped inside the binary so that the command works from any directory.
const NUMPY_PEER: &str = include_str!("../../../benches/numpy_peer.py");
const LOAD_PEER: &str = include_str!("../../../benches/load_peer.py");

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

/// CPU seconds used by this process so far (`CLOCK_PROCESS_CPUTIME_ID`); NaN if the clock
/// cannot be read.
fn process_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `clock_gettime` writes one `timespec` through a valid, exclusive pointer.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) };
    if rc == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// A wall clock and the process's CPU clock started together.
struct Clocks {
    wall: Instant,
    cpu_s: f64,
}

impl Clocks {
    fn start() -> Clocks {
        Clocks {
            wall: Instant::now(),
            cpu_s: process_cpu_s(),
        }
    }

    /// (wall, CPU) seconds since [`Clocks::start`].
    fn elapsed(&self) -> (f64, f64) {
        (
            self.wall.elapsed().as_secs_f64(),
            process_cpu_s() - self.cpu_s,
        )
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

/// The parameters found, by name.
type Theta = Vec<(String, f64)>;

/// One identification as `forcemap identify` does it, timed by stage; returns the stages' wall
/// and CPU seconds, theta, the samples read and whether the sine steps were analysed as they
/// were read.
fn identify_once(args: &BenchIdentifyArgs) -> anyhow::Result<(Stages, Stages, Theta, usize, bool)> {
    let a = &args.identify;
    let path = the_file(args)?;
    let file = path.display().to_string();
    let t0 = Clocks::start();
    // As `forcemap identify` reads: a file it streams has its sine steps analysed as they are
    // read, in the reading stage.
    let read = super::identify::load(a, &[path.to_path_buf()])?;
    let (csv_s, csv_cpu_s) = t0.elapsed();
    let (import, rows, streamed) = (read.import, read.samples_read, read.streamed.is_some());
    let spilled = read.spilled;
    let recipe = super::identify::recipe(a, import.kind, &import.parameters, &file)?;
    let setup = recipe.setup.setup()?;
    let model = recipe.model.build()?;
    let t1 = Clocks::start();
    let (analyses, notes) = match read.streamed {
        Some(streamed) => streamed,
        None => pipeline::analyse_sine_steps(&import.records, &recipe.phasor).map_err(Into::into),
    }
    .with_context(|| format!("{file}: harmonic analysis"))?;
    let (phasors_s, phasors_cpu_s) = t1.elapsed();
    let t2 = Clocks::start();
    let (id, _) = pipeline::identify_analysed(
        &model,
        &setup,
        recipe.method,
        &import.records,
        analyses,
        notes,
        &recipe.fd_options(),
    )
    .with_context(|| format!("{file}: identifying model '{}'", model.name))?;
    let (fit_s, fit_cpu_s) = t2.elapsed();
    let t3 = Clocks::start();
    if let Setup::BaseExcited { mass_kg } = setup {
        let fitted = IdentifiedModel::new(model.clone(), id.theta());
        super::random_records::validate_rig(&fitted, mass_kg, &import.records, spilled, &file)?;
    }
    let (validation_s, validation_cpu_s) = t3.elapsed();
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
        Stages {
            csv_s: csv_cpu_s,
            phasors_s: phasors_cpu_s,
            fit_s: fit_cpu_s,
            validation_s: validation_cpu_s,
        },
        theta,
        rows,
        streamed,
    ))
}

/// Runs a peer `script` under `python` on the file with `extra` arguments and returns its JSON
/// output.
fn run_script(
    python: &std::path::Path,
    script: &str,
    args: &BenchIdentifyArgs,
    extra: &[String],
) -> anyhow::Result<serde_json::Value> {
    // `python - ARGS` runs the script from stdin.
    let mut child = Command::new(python)
        .arg("-")
        .arg(the_file(args)?)
        .args(extra)
        .args(["--repeats", &args.repeats.to_string()])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .with_context(|| format!("running {}", python.display()))?;
    child
        .stdin
        .take()
        .context("the peer's stdin")?
        .write_all(script.as_bytes())
        .context("passing the peer script")?;
    let out = child
        .wait_with_output()
        .with_context(|| format!("running {}", python.display()))?;
    if !out.status.success() {
        bail!(
            "the peer failed under {} (does it have polars or numpy?): {}",
            python.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let v: serde_json::Value =
        serde_json::from_slice(&out.stdout).context("reading the peer's JSON output")?;
    Ok(v)
}

/// The medians of a peer's list `key` of seconds.
fn median_of(v: &serde_json::Value, key: &str) -> anyhow::Result<f64> {
    let list: Vec<f64> = v[key]
        .as_array()
        .and_then(|a| a.iter().map(serde_json::Value::as_f64).collect())
        .with_context(|| format!("the peer's output has no list '{key}'"))?;
    Ok(median(list))
}

/// Median (parse, fit) seconds of the numpy peer and its parameters.
fn run_fit_peer(
    python: &std::path::Path,
    args: &BenchIdentifyArgs,
    mass_kg: f64,
) -> anyhow::Result<serde_json::Value> {
    let extra = ["--mass-kg".to_string(), mass_kg.to_string()];
    let v = run_script(python, NUMPY_PEER, args, &extra)?;
    let sums = |a: &str, b: &str| -> anyhow::Result<Vec<f64>> {
        let list = |key: &str| -> anyhow::Result<Vec<f64>> {
            v[key]
                .as_array()
                .and_then(|l| l.iter().map(serde_json::Value::as_f64).collect())
                .with_context(|| format!("the numpy peer's output has no list '{key}'"))
        };
        Ok(list(a)?.iter().zip(list(b)?).map(|(p, f)| p + f).collect())
    };
    Ok(json!({
        "parse_s": median_of(&v, "parse_s")?,
        "fit_s": median_of(&v, "fit_s")?,
        "total_s": median(sums("parse_s", "fit_s")?),
        "parse_cpu_s": median_of(&v, "parse_cpu_s")?,
        "fit_cpu_s": median_of(&v, "fit_cpu_s")?,
        "total_cpu_s": median(sums("parse_cpu_s", "fit_cpu_s")?),
        "k": v["k"], "c": v["c"], "fd": v["fd"], "rows": v["rows"],
    }))
}

/// The peak resident memory of this process so far [bytes] (`VmHWM` of /proc/self/status;
/// NaN where it cannot be read).
fn own_peak_bytes() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kib| kib * 1024.0)
}

const MIB: f64 = 1024.0 * 1024.0;

/// The one file a benchmark times.
fn the_file(args: &BenchIdentifyArgs) -> anyhow::Result<&std::path::Path> {
    match args.identify.files.as_slice() {
        [one] => Ok(one),
        _ => bail!("bench identify times one file at a time"),
    }
}

/// The bytes of the input: a file's length, or the sum of a directory's files (a bag); NaN
/// when it cannot be read.
fn input_bytes(path: &std::path::Path) -> f64 {
    fn bytes(path: &std::path::Path) -> std::io::Result<u64> {
        let meta = std::fs::metadata(path)?;
        if !meta.is_dir() {
            return Ok(meta.len());
        }
        let mut sum = 0;
        for entry in std::fs::read_dir(path)? {
            sum += bytes(&entry?.path())?;
        }
        Ok(sum)
    }
    bytes(path).map_or(f64::NAN, |b| b as f64)
}

pub fn run(args: &BenchIdentifyArgs) -> anyhow::Result<()> {
    if args.repeats == 0 {
        bail!("--repeats must be at least 1");
    }
    let file_bytes = input_bytes(the_file(args)?);
    let mut runs = Vec::with_capacity(args.repeats);
    let mut cpu_runs = Vec::with_capacity(args.repeats);
    let mut theta = Vec::new();
    let mut rows = 0;
    let mut streamed = false;
    for _ in 0..args.repeats {
        let (stages, cpu, th, n, s) = identify_once(args)?;
        runs.push(stages);
        cpu_runs.push(cpu);
        theta = th;
        rows = n;
        streamed = s;
    }
    // Read before any peer runs: the peak of the identifications (the children's is apart).
    let peak_bytes = own_peak_bytes();
    let med = |f: fn(&Stages) -> f64| median(runs.iter().map(f).collect());
    let med_cpu = |f: fn(&Stages) -> f64| median(cpu_runs.iter().map(f).collect());
    let ours = json!({
        "csv_s": med(|s| s.csv_s),
        "phasors_s": med(|s| s.phasors_s),
        "fit_s": med(|s| s.fit_s),
        "validation_s": med(|s| s.validation_s),
        "total_s": med(Stages::total_s),
        "csv_cpu_s": med_cpu(|s| s.csv_s),
        "phasors_cpu_s": med_cpu(|s| s.phasors_s),
        "fit_cpu_s": med_cpu(|s| s.fit_s),
        "validation_cpu_s": med_cpu(|s| s.validation_s),
        "total_cpu_s": med_cpu(Stages::total_s),
        "theta": theta.iter().map(|(n, v)| (n.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
    });
    let file = the_file(args)?.display().to_string();
    println!(
        "{file}: forcemap identify, medians of {} runs",
        args.repeats
    );
    println!("  {:<12} {:>10} {:>10}", "stage", "wall", "CPU");
    for (label, key) in [
        ("reading", "csv"),
        ("phasors", "phasors"),
        ("fit", "fit"),
        ("validation", "validation"),
        ("total", "total"),
    ] {
        let ms = |k: String| ours[k].as_f64().unwrap_or(f64::NAN) * 1e3;
        println!(
            "  {label:<12} {:>7.2} ms {:>7.2} ms",
            ms(format!("{key}_s")),
            ms(format!("{key}_cpu_s"))
        );
    }
    if streamed {
        println!("  (the sine steps analysed as they were read: their phasors are in the reading)");
    }
    println!("  theta        {}", ours["theta"]);
    let num = |v: &serde_json::Value, key: &str| v[key].as_f64().unwrap_or(f64::NAN);
    let total_s = num(&ours, "total_s");
    println!(
        "  throughput   {:.1} MB/s, {:.3} M rows/s ({:.1} MB, {rows} rows, by the median total \
         wall time); peak memory {:.1} MiB (VmHWM)",
        file_bytes / total_s * 1e-6,
        rows as f64 / total_s * 1e-6,
        file_bytes * 1e-6,
        peak_bytes / MIB
    );
    let Some(python) = &args.python else {
        println!(
            "peer not run: give --python PATH (a python with polars or numpy; asammdf or \
             npTDMS for an MDF4 or TDMS file)"
        );
        return Ok(());
    };
    if args.peer == PeerArg::Load {
        let peer = run_script(python, LOAD_PEER, args, &[])?;
        let (load_s, load_cpu_s) = (median_of(&peer, "load_s")?, median_of(&peer, "load_cpu_s")?);
        println!(
            "load peer ({}, {}), medians of {} runs: load {:.2} ms (CPU {:.2} ms), {} rows, \
             {:.1} MB/s; peak memory {:.1} MiB",
            peer["loader"].as_str().unwrap_or("?"),
            python.display(),
            args.repeats,
            load_s * 1e3,
            load_cpu_s * 1e3,
            peer["rows"],
            file_bytes / load_s * 1e-6,
            num(&peer, "peak_bytes") / MIB
        );
        println!(
            "ratio load peer / forcemap identify (total): {:.2}x wall, {:.2}x CPU (above 1: \
             identify is faster than loading alone)",
            load_s / total_s,
            load_cpu_s / num(&ours, "total_cpu_s")
        );
        return Ok(());
    }
    let mass_kg = match args.identify.mass_kg {
        Some(m) => m,
        None => {
            let import = forcemap_io::input::load(the_file(args)?)?;
            let recipe =
                super::identify::recipe(&args.identify, import.kind, &import.parameters, &file)?;
            match recipe.setup.setup()? {
                Setup::BaseExcited { mass_kg } => mass_kg,
                _ => bail!("{file}: the numpy peer fits a base-excited rig export only"),
            }
        }
    };
    let peer = run_fit_peer(python, args, mass_kg)?;
    let ratio = num(&peer, "total_s") / total_s;
    let cpu_ratio = num(&peer, "total_cpu_s") / num(&ours, "total_cpu_s");
    println!(
        "numpy peer ({}), medians of {} runs: parse {:.2} ms (CPU {:.2}), fit {:.2} ms (CPU {:.2}), total {:.2} ms (CPU {:.2}); k {:.6e}, c {:.6e}, fd {:.6e}",
        python.display(),
        args.repeats,
        num(&peer, "parse_s") * 1e3,
        num(&peer, "parse_cpu_s") * 1e3,
        num(&peer, "fit_s") * 1e3,
        num(&peer, "fit_cpu_s") * 1e3,
        num(&peer, "total_s") * 1e3,
        num(&peer, "total_cpu_s") * 1e3,
        num(&peer, "k"),
        num(&peer, "c"),
        num(&peer, "fd"),
    );
    println!("ratio numpy peer / forcemap (total): {ratio:.1}x wall, {cpu_ratio:.1}x CPU");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::input_bytes;

    /// A file's bytes are its length; a directory's (a bag) the sum of its files', nested
    /// ones too; what does not exist is NaN.
    #[test]
    fn a_bag_directory_counts_its_files_bytes() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.mcap"), [0u8; 100]).unwrap();
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        std::fs::write(dir.path().join("sub/metadata.yaml"), [0u8; 23]).unwrap();
        assert_eq!(input_bytes(&dir.path().join("a.mcap")), 100.0);
        assert_eq!(input_bytes(dir.path()), 123.0);
        assert!(input_bytes(&dir.path().join("nothing")).is_nan());
    }
}
