//! A bench's own files read through a map of their columns, with no conversion step: a
//! damper dyno's element test (six sine steps at 1 kHz, 40 dB, unlabelled as a DAQ writes
//! it) as a headerless whitespace file in mm, a CSV with ISO 8601 date-times and units in its
//! column names, an MDF4 written by asammdf and a TDMS written by npTDMS in several segments,
//! each with the bench's channel names and units. Each gives the theta of forcemap's CSV of
//! the same samples; the mistakes a map can make are named.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use forcemap_io::input::{load_files, load_mapped};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::{ElementDrive, RunSpec, StepSpec};

fn dyno_records() -> Vec<Record> {
    let element = RunSpec::damper_dyno(None, 0).element;
    let steps = [2.0, 4.0, 8.0]
        .iter()
        .flat_map(|&f| {
            [0.005, 0.02].map(|a| StepSpec::Sine {
                frequency_hz: f,
                amplitude: a,
            })
        })
        .collect();
    RunSpec {
        snr_db: Some(40.0),
        seed: 11,
        ..RunSpec::element_test(
            ElementDrive::Displacement,
            0.8,
            element,
            steps,
            1000.0,
            4000,
        )
    }
    .simulate()
    .unwrap()
}

/// (time [s], displacement [m], force [N]) of every sample, in order.
fn samples(records: &[Record]) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    for r in records {
        let x = r.channel(Channel::RelativeDisplacementM).unwrap();
        let f = r.channel(Channel::ForceN).unwrap();
        for k in 0..r.len() {
            out.push((r.start_time_s + k as f64 / r.sample_rate_hz, x[k], f[k]));
        }
    }
    out
}

fn theta(records: &[Record]) -> Vec<f64> {
    common::dyno_identification(records).theta()
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// forcemap's CSV of the samples, without labels (as the bench files have none).
fn contract_csv(s: &[(f64, f64, f64)]) -> String {
    let mut t = String::from("time_s,relative_displacement_m,force_n\n");
    for (time, x, f) in s {
        writeln!(t, "{time},{x},{f}").unwrap();
    }
    t
}

fn assert_same_theta(reference: &[f64], got: &[f64], what: &str) {
    assert_eq!(reference.len(), got.len(), "{what}");
    for (a, b) in reference.iter().zip(got) {
        assert!(
            ((a - b) / a).abs() < 1e-9,
            "{what}: theta {got:?} vs the contract CSV's {reference:?}"
        );
    }
    println!("{what}: theta {got:?}");
}

#[test]
fn text_files_as_benches_write_them_give_the_contract_theta() {
    let dir = tempfile::tempdir().unwrap();
    let s = samples(&dyno_records());
    let plain = write(dir.path(), "plain.csv", &contract_csv(&s));
    let reference = theta(&load_mapped(&plain, None).unwrap().records);
    assert_eq!(reference.len(), 5);

    // A test machine's file: headerless, whitespace runs, mm and mm/s.
    let mut text = String::new();
    for (k, (t, x, f)) in s.iter().enumerate() {
        let v = if k == 0 { 0.0 } else { (x - s[k - 1].1) * 1e6 };
        writeln!(text, "  {t:.6}\t{:e}   {v:e} {f:e}", x * 1e3).unwrap();
    }
    let file = write(dir.path(), "sine_tests.txt", &text);
    let map = write(
        dir.path(),
        "machine.yaml",
        "channels:\n  time_s: {channel: 1, unit: s}\n  relative_displacement_m: {channel: 2, unit: mm}\n  force_n: {channel: 4, unit: N}\n",
    );
    let loaded = load_mapped(&file, Some(&map)).unwrap();
    assert_eq!(loaded.kind, SetupKind::Element);
    assert_same_theta(&reference, &theta(&loaded.records), "headerless whitespace");

    // A dyno's CSV: ISO 8601 date-times, units in the names, channels it does not map.
    let mut text =
        String::from("Timestamp,Force (N),Displacement (mm),Supply (V),Oil temperature [degC]\n");
    for (t, x, f) in &s {
        let micros = (t * 1e6).round() as i64;
        let (secs, frac) = (micros / 1_000_000, micros % 1_000_000);
        writeln!(
            text,
            "2026-11-28T10:{:02}:{:02}.{frac:06},{f},{},24.0,41.5",
            15 + secs / 60,
            secs % 60,
            x * 1e3
        )
        .unwrap();
    }
    let file = write(dir.path(), "dyno.csv", &text);
    let map = write(
        dir.path(),
        "dyno.yaml",
        "channels:\n  time_s: {channel: Timestamp}\n  relative_displacement_m: {channel: Displacement}\n  force_n: {channel: 'Force (N)'}\n",
    );
    let loaded = load_mapped(&file, Some(&map)).unwrap();
    assert_same_theta(&reference, &theta(&loaded.records), "ISO date-times");

    // The same export cut in two files, read together: the records of one.
    let lines: Vec<&str> = text.lines().collect();
    let cut = 1 + 3 * 4000;
    let first = write(dir.path(), "dyno_a.csv", &(lines[..cut].join("\n") + "\n"));
    let second = write(
        dir.path(),
        "dyno_b.csv",
        &(lines[0].to_string() + "\n" + &lines[cut..].join("\n") + "\n"),
    );
    let both = load_files(&[first, second], Some(&map)).unwrap();
    assert_eq!(both.records.len(), loaded.records.len());
    let steps: Vec<usize> = both.records.iter().map(|r| r.step).collect();
    assert_eq!(steps, (0..6).collect::<Vec<_>>());
    assert_same_theta(&reference, &theta(&both.records), "two files");
}

#[test]
fn a_maps_mistakes_are_named_with_file_and_channel() {
    let dir = tempfile::tempdir().unwrap();
    let s = samples(&dyno_records());
    let mut text = String::from("Time [s];Weg;Kraft [V];Temp\n");
    for (t, x, f) in s.iter().take(500) {
        writeln!(text, "{t};{x};{f};20").unwrap();
    }
    let file = write(dir.path(), "bench.csv", &text);
    let cases = [
        (
            "channels:\n  relative_displacement_m: {channel: Weg, unit: m}\n  force_n: {channel: Kraft}\n",
            "bench.csv: text: 'Kraft [V]' (for force_n) has unit 'V' (the file's unit), which forcemap does not know; give 'scale:'",
        ),
        (
            "channels:\n  relative_displacement_m: {channel: Weg}\n  force_n: {channel: Kraft, scale: 100}\n",
            "bench.csv: text: 'Weg' (for relative_displacement_m) has no unit in the file; give 'unit:' (such as mm) or 'scale:'",
        ),
        (
            "channels:\n  relative_displacement_m: {channel: Travel, unit: mm}\n  force_n: {channel: Kraft, scale: 100}\n",
            "bench.csv: text: no 'Travel' for relative_displacement_m; the file has 'Time [s]', 'Weg', 'Kraft [V]', 'Temp'",
        ),
        (
            "channels:\n  relative_displacement_m: {channel: 7, unit: mm}\n  force_n: {channel: Kraft, scale: 100}\n",
            "no column 7 for relative_displacement_m",
        ),
        (
            "channels:\n  relative_displacement_m: {channel: Weg, unit: m}\n  force_n: {channel: 'Time [s]'}\n",
            "'Time [s]' (for force_n) has unit 's' (the file's unit), not a unit of force_n (its SI unit is N)",
        ),
        (
            "channels:\n  relative_displacement_m: {topic: /a, field: x}\n  force_n: {topic: /a, field: f}\n",
            "maps a bag's topics (topic:, field:); a file of columns needs a map of its columns",
        ),
    ];
    for (k, (map, expected)) in cases.into_iter().enumerate() {
        let map = write(dir.path(), &format!("map{k}.yaml"), map);
        let e = format!("{:#}", load_mapped(&file, Some(&map)).unwrap_err());
        assert!(e.contains(expected), "map {k}:\n{e}\nexpected: {expected}");
    }
    // A cell that is no number: named with its line in the file and its column.
    let bad = write(
        dir.path(),
        "bad.csv",
        &text.replacen("\n0.01;", "\n0.01x;", 1),
    );
    let map = write(
        dir.path(),
        "good.yaml",
        "channels:\n  relative_displacement_m: {channel: Weg, unit: m}\n  force_n: {channel: Kraft, scale: 100}\n",
    );
    let e = format!("{:#}", load_mapped(&bad, Some(&map)).unwrap_err());
    assert!(
        e.contains("bad.csv: text: line 12: 'Time [s]': '0.01x' is not a number"),
        "{e}"
    );

    // What the contract's rules find in the rows names the file's own lines (a preamble and a
    // comment line put row k elsewhere than line k + 2).
    let mut text = String::from("# dyno export\n# operator: x\n");
    for (k, (t, x, f)) in s.iter().take(400).enumerate() {
        let t = if k == 300 { t - 0.01 } else { *t };
        if k == 100 {
            text.push_str("% a comment\n");
        }
        writeln!(text, "{t} {x} {f}").unwrap();
    }
    let back = write(dir.path(), "back.txt", &text);
    let map = write(
        dir.path(),
        "back.yaml",
        "channels:\n  time_s: {channel: 1, unit: s}\n  relative_displacement_m: {channel: 2, unit: m}\n  force_n: {channel: 3, unit: N}\n",
    );
    let e = format!("{:#}", load_mapped(&back, Some(&map)).unwrap_err());
    // Row 300 is on line 2 + 1 + 300 + 1 = 304; the row before it on line 303.
    assert!(e.contains("line 304") && e.contains("line 303"), "{e}");
}

fn python_with_writers() -> Option<String> {
    let py = std::env::var("FORCEMAP_PYTHON").ok();
    let usable = py.as_ref().is_some_and(|p| {
        Command::new(p)
            .args(["-c", "import asammdf, nptdms"])
            .status()
            .is_ok_and(|s| s.success())
    });
    if !usable {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON ({py:?}) has no asammdf/npTDMS: .ci/run must install them"
        );
        println!("skipped: set FORCEMAP_PYTHON to a Python with asammdf and npTDMS");
        return None;
    }
    py
}

#[test]
fn mdf4_and_tdms_with_the_benchs_names_and_units_give_the_contract_theta() {
    let Some(py) = python_with_writers() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let s = samples(&dyno_records());
    let plain = write(dir.path(), "plain.csv", &contract_csv(&s));
    let reference = theta(&load_mapped(&plain, None).unwrap().records);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/bench_files.py");
    let out = Command::new(&py)
        .arg(&script)
        .arg(&plain)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "bench_files.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Units from the files' metadata: no scale or unit in the maps.
    let mdf_map = write(
        dir.path(),
        "mdf.yaml",
        "channels:\n  relative_displacement_m: {channel: Act_Pos}\n  force_n: {channel: Load, group: Dyno}\n",
    );
    let loaded = load_mapped(&dir.path().join("bench.mf4"), Some(&mdf_map)).unwrap();
    assert_same_theta(&reference, &theta(&loaded.records), "MDF4 (asammdf)");

    let tdms_map = write(
        dir.path(),
        "tdms.yaml",
        "channels:\n  time_s: {channel: Time, group: Dyno}\n  relative_displacement_m: {channel: Act_Pos, group: Dyno}\n  force_n: {channel: Load}\n",
    );
    let loaded = load_mapped(&dir.path().join("bench.tdms"), Some(&tdms_map)).unwrap();
    assert_same_theta(&reference, &theta(&loaded.records), "TDMS (npTDMS)");

    // A channel whose unit forcemap does not know, mapped without a scale: named.
    let volts = write(
        dir.path(),
        "volts.yaml",
        "channels:\n  relative_displacement_m: {channel: Act_Pos}\n  force_n: {channel: Supply}\n",
    );
    let e = format!(
        "{:#}",
        load_mapped(&dir.path().join("bench.tdms"), Some(&volts)).unwrap_err()
    );
    assert!(
        e.contains("bench.tdms: TDMS: 'Supply' (group 'Dyno') (for force_n) has unit 'V'"),
        "{e}"
    );
}

/// A lab's JSON (an object with a matrix of rows: time [s], displacement [in], force [kip],
/// and scalars and unit strings beside it) read through a map as one record per file
/// (`table: {records: whole}`): the samples of forcemap's CSV to round-off, one record of
/// unknown excitation where the step finder would have cut six sine steps; and the map's
/// mistakes named.
#[test]
fn a_json_matrix_read_whole_is_one_record_of_the_samples() {
    let dir = tempfile::tempdir().unwrap();
    let s = samples(&dyno_records());
    let mut rows = Vec::new();
    for (t, x, f) in &s {
        rows.push(format!(
            "[{t}, {}, {}, 0.0]",
            x / 0.0254,
            f / 4_448.221_615_260_5
        ));
    }
    let text = format!(
        "{{\"data\": [{}], \"dt\": 0.001, \"displacement units\": \"in\", \"force units\": \"kip\"}}",
        rows.join(", ")
    );
    let file = write(dir.path(), "test.json", &text);
    let map = write(
        dir.path(),
        "lab.yaml",
        "channels:\n  time_s: {channel: data, column: 1, unit: s}\n  relative_displacement_m: {channel: data, column: 2, unit: in}\n  force_n: {channel: data, column: 3, unit: kip}\ntable:\n  records: whole\n",
    );
    let loaded = load_mapped(&file, Some(&map)).unwrap();
    assert_eq!(loaded.records.len(), 1);
    let r = &loaded.records[0];
    assert!(
        matches!(
            r.excitation,
            forcemap_math::record::Excitation::Random { band_hz: None, .. }
        ),
        "{:?}",
        r.excitation
    );
    let got = samples(&loaded.records);
    assert_eq!(got.len(), s.len());
    for ((_, x, f), (_, x0, f0)) in got.iter().zip(&s) {
        assert!((x - x0).abs() <= 1e-12 * x0.abs().max(1e-3), "{x} {x0}");
        assert!((f - f0).abs() <= 1e-9 * f0.abs().max(1.0), "{f} {f0}");
    }
    // By steps (the default), the same file gives the six sine steps.
    let by_steps = write(
        dir.path(),
        "steps.yaml",
        "channels:\n  time_s: {channel: data, column: 1, unit: s}\n  relative_displacement_m: {channel: data, column: 2, unit: in}\n  force_n: {channel: data, column: 3, unit: kip}\n",
    );
    assert_eq!(
        load_mapped(&file, Some(&by_steps)).unwrap().records.len(),
        6
    );
    let bad = write(
        dir.path(),
        "bad.yaml",
        "channels:\n  relative_displacement_m: {channel: data, column: 2, unit: in}\n  force_n: {channel: data, column: 3, unit: kip}\ntable:\n  records: all\n",
    );
    let e = format!("{:#}", load_mapped(&file, Some(&bad)).unwrap_err());
    assert!(
        e.contains("table.records") && e.contains("'all' is not a way to make records"),
        "{e}"
    );
}

/// A map that names records by rows (`table.records` as a list) cuts one file into them, in
/// the map's order, leaving the rows between out; `FILE#NAMES` picks some; rows beyond the file,
/// overlapping records and unknown names are errors naming what is wrong.
#[test]
fn records_named_by_rows_cut_one_file() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("bench.csv");
    let mut text = String::from("x,F\n");
    for k in 0..40 {
        text.push_str(&format!("{},{}\n", (k as f64 * 0.3).sin(), k));
    }
    std::fs::write(&csv, text).unwrap();
    let map = |records: &str| {
        let p = dir.path().join("map.yaml");
        std::fs::write(
            &p,
            format!(
                "channels:\n  time_s: {{sample_rate_hz: 100}}\n  relative_displacement_m: {{channel: x, unit: m}}\n  force_n: {{channel: F, unit: N}}\ntable:\n  records:\n{records}"
            ),
        )
        .unwrap();
        p
    };
    let m = map("    - {name: a, rows: [3, 12]}\n    - {name: b, rows: [21, 40]}\n");
    let all = forcemap_io::input::load_files(std::slice::from_ref(&csv), Some(&m)).unwrap();
    assert_eq!(all.records.len(), 2);
    assert_eq!(
        (all.records[0].len(), all.records[1].len()),
        (10, 20),
        "rows 3-12 and 21-40"
    );
    // Row 3 holds F = 2, row 21 F = 20.
    let force = |r: &forcemap_math::record::Record| r.channel(Channel::ForceN).unwrap()[0];
    assert_eq!(
        (force(&all.records[0]), force(&all.records[1])),
        (2.0, 20.0)
    );
    let picked = PathBuf::from(format!("{}#b", csv.display()));
    let b = forcemap_io::input::load_files(&[picked], Some(&m)).unwrap();
    assert_eq!(b.records.len(), 1);
    assert_eq!((b.records[0].step, force(&b.records[0])), (0, 20.0));
    let unknown = PathBuf::from(format!("{}#c", csv.display()));
    let e = forcemap_io::input::load_files(&[unknown], Some(&m))
        .unwrap_err()
        .to_string();
    assert!(e.contains("no record 'c'") && e.contains("a, b"), "{e}");
    let beyond = map("    - {name: a, rows: [3, 41]}\n");
    let e = format!(
        "{:#}",
        forcemap_io::input::load_files(std::slice::from_ref(&csv), Some(&beyond)).unwrap_err()
    );
    assert!(e.contains("record 'a'") && e.contains("40 rows"), "{e}");
    let overlap = map("    - {name: a, rows: [3, 12]}\n    - {name: b, rows: [12, 20]}\n");
    let e = format!(
        "{:#}",
        forcemap_io::input::load_files(&[csv], Some(&overlap)).unwrap_err()
    );
    assert!(
        e.contains("table.records") && e.contains("without overlap"),
        "{e}"
    );
}
