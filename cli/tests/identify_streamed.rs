//! `forcemap identify BAG` streams a bag (each sine step analysed into phasors as soon as it is
//! complete, its samples dropped) when it identifies by fd or fd-multi, converged and without
//! plots; with `--plot` it reads the bag whole. Both give the same output bit for bit on the
//! committed bags (the element test is read whole either way: its outputs need the samples).
//! The same for CSV exports, and for MDF4 and TDMS files of a run written by asammdf and
//! npTDMS (`$FORCEMAP_PYTHON`).
#![allow(clippy::unwrap_used, reason = "tests")]

mod common;

use std::path::Path;
use std::process::Output;

use common::forcemap;

/// The rig's simulated run (40 dB) as a CSV export in `dir`.
fn rig_export(dir: &Path) -> std::path::PathBuf {
    let rig = dir.join("rig.csv");
    let o = forcemap(&["simulate", "--snr-db", "40", "--csv", rig.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    rig
}

fn identify_json(args: &[&str]) -> String {
    let o = forcemap(args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

#[test]
fn a_streamed_bag_identifies_as_the_whole_bag_bit_for_bit() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let three_dof = root.join("launch_configs/three_dof.params.yaml");
    let three_dof = three_dof.to_str().unwrap();
    let plots = tempfile::tempdir().unwrap();
    let plots = plots.path().to_str().unwrap();
    for (bag, extra) in [
        ("rig_40db", vec!["--model", "coulomb"]),
        ("rig_40db", vec!["--model", "coulomb", "--method", "fd"]),
        (
            "three_dof_case_i",
            vec!["--model", "coulomb-cubic", "--params", three_dof],
        ),
        ("damper_dyno_40db", vec!["--model", "damper"]),
    ] {
        let bag = root.join("bags").join(bag);
        let mut args = vec!["identify", bag.to_str().unwrap(), "--json"];
        args.extend_from_slice(&extra);
        let streamed = identify_json(&args);
        args.extend_from_slice(&["--plot", plots]);
        let whole = identify_json(&args);
        assert!(!streamed.is_empty());
        assert_eq!(streamed, whole, "{}", bag.display());
    }
}

/// `args` streamed, and read whole (with `--plot` into `plots`): the same stdout, the same stderr
/// but for the plots' lines.
fn assert_streamed_as_whole(args: &[&str], plots: &str, what: &str) {
    let streamed = forcemap(args);
    let mut whole_args = args.to_vec();
    whole_args.extend_from_slice(&["--plot", plots]);
    let whole: Output = forcemap(&whole_args);
    assert!(
        streamed.status.success(),
        "{what}: {}",
        String::from_utf8_lossy(&streamed.stderr)
    );
    assert!(!streamed.stdout.is_empty());
    assert_eq!(streamed.stdout, whole.stdout, "{what}");
    let whole_stderr: String = String::from_utf8_lossy(&whole.stderr)
        .lines()
        .filter(|l| !l.starts_with("wrote "))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(
        String::from_utf8_lossy(&streamed.stderr),
        whole_stderr,
        "{what}"
    );
}

/// The same for CSV exports: read record by record, each sine step analysed as it is read,
/// stdout and stderr as those of the export read whole (`--plot`).
#[test]
fn a_streamed_export_identifies_as_the_whole_export_bit_for_bit() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let three_dof = root.join("launch_configs/three_dof.params.yaml");
    let three_dof = three_dof.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    let plots = plots.to_str().unwrap();
    for (system, extra) in [
        ("rig", vec!["--model", "coulomb", "--mass-kg", "36"]),
        (
            "three-dof",
            vec!["--model", "coulomb-cubic", "--params", three_dof],
        ),
        ("damper-dyno", vec!["--model", "damper"]),
    ] {
        let csv = dir.path().join(format!("{system}.csv"));
        let csv = csv.to_str().unwrap();
        let o = forcemap(&[
            "simulate", "--system", system, "--snr-db", "40", "--csv", csv,
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mut args = vec!["identify", csv, "--json"];
        args.extend_from_slice(&extra);
        assert_streamed_as_whole(&args, plots, system);
    }
}

/// The same for MDF4 and TDMS files of the rig's run (io/tests/python/measurement_files.py:
/// asammdf's `time` master; npTDMS with a time channel over several segments, and with
/// waveform timing): their rows read block by block, each sine step analysed as it is read.
#[test]
fn streamed_mdf4_and_tdms_files_identify_as_read_whole_bit_for_bit() {
    let Ok(python) = std::env::var("FORCEMAP_PYTHON") else {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but FORCEMAP_PYTHON is not: the asammdf and npTDMS writers did not run"
        );
        println!("skipped: set FORCEMAP_PYTHON to a Python with asammdf and npTDMS");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    let plots = plots.to_str().unwrap();
    let csv = rig_export(dir.path());
    let script =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../io/tests/python/measurement_files.py");
    let o = std::process::Command::new(&python)
        .arg(&script)
        .arg(&csv)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "measurement_files.py failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    for file in ["run.mf4", "run.tdms", "run_wf.tdms"] {
        let path = dir.path().join(file);
        let args = [
            "identify",
            path.to_str().unwrap(),
            "--json",
            "--model",
            "coulomb",
            "--mass-kg",
            "36",
        ];
        assert_streamed_as_whole(&args, plots, file);
    }
    // `bench identify --python` loads each with the format's own Python reader, the same rows.
    for (file, loader) in [("run.mf4", "asammdf"), ("run.tdms", "npTDMS")] {
        let path = dir.path().join(file);
        let o = forcemap(&[
            "bench",
            "identify",
            path.to_str().unwrap(),
            "--model",
            "coulomb",
            "--mass-kg",
            "36",
            "--repeats",
            "1",
            "--python",
            &python,
        ]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{out}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let rows = |line: &str| {
            line.split_whitespace()
                .zip(line.split_whitespace().skip(1))
                .find(|(_, w)| *w == "rows,")
                .map(|(n, _)| n.to_string())
        };
        let ours = out
            .lines()
            .find(|l| l.contains("throughput"))
            .and_then(rows);
        let peer = out
            .lines()
            .find(|l| l.starts_with(&format!("load peer ({loader}")))
            .and_then(rows);
        assert!(ours.is_some() && ours == peer, "{file}: {out}");
    }
}

/// Band-random records before the first sine step stay in memory, those after it wait on disk
/// for the validation: an export of random, sine and random records validates on every random
/// record in file order, as the export read whole does.
#[test]
fn random_records_before_and_after_the_sine_steps_validate_in_file_order() {
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    let rig = rig_export(dir.path());
    // The run's steps 0-9 are sine steps, 10 and 11 random: written as 10, 11, 0-9, 10, 11,
    // numbered 0-13, at 100 Hz from 0 s.
    let text = std::fs::read_to_string(&rig).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let rows: Vec<(usize, &str)> = lines
        .map(|l| {
            let mut cells = l.splitn(3, ',');
            let _time = cells.next().unwrap();
            let step = cells.next().unwrap().parse().unwrap();
            (step, cells.next().unwrap())
        })
        .collect();
    let order = [10, 11, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11];
    let mut out = format!("{header}\n");
    let mut i = 0;
    for (new_step, old_step) in order.iter().enumerate() {
        for (_, rest) in rows.iter().filter(|(s, _)| s == old_step) {
            out.push_str(&format!("{:.2},{new_step},{rest}\n", i as f64 / 100.0));
            i += 1;
        }
    }
    let csv = dir.path().join("random_sine_random.csv");
    std::fs::write(&csv, out).unwrap();
    let args = [
        "identify",
        csv.to_str().unwrap(),
        "--model",
        "coulomb",
        "--mass-kg",
        "36",
    ];
    assert_streamed_as_whole(&args, plots.to_str().unwrap(), "random, sine, random");
    let o = forcemap(&args);
    let validated: Vec<String> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .filter_map(|l| l.strip_prefix("validation on random record "))
        .map(|l| l.split(':').next().unwrap().to_string())
        .collect();
    assert_eq!(validated, ["0", "1", "12", "13"]);
}

/// Where the random records cannot wait on disk (no temporary directory), the identification
/// stops with an error naming the file and the directory, and a file with no random record
/// after its sine steps needs no temporary file.
#[test]
fn random_records_that_cannot_wait_on_disk_stop_with_an_error_naming_the_directory() {
    let dir = tempfile::tempdir().unwrap();
    let rig = rig_export(dir.path());
    let missing = dir.path().join("no_such_dir");
    let run = |file: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_forcemap"))
            .args(["identify", file.to_str().unwrap(), "--model", "coulomb"])
            .args(["--mass-kg", "36"])
            .env("TMPDIR", &missing)
            .output()
            .unwrap()
    };
    let o = run(&rig);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert!(
        stderr.contains("rig.csv: keeping its band-random records for the validation")
            && stderr.contains(&format!("a temporary file in {}", missing.display())),
        "{stderr}"
    );
    // Steps 0-9 only: sine steps.
    let text = std::fs::read_to_string(&rig).unwrap();
    let sines: String = text
        .lines()
        .take(13_001)
        .map(|l| format!("{l}\n"))
        .collect();
    let sines_csv = dir.path().join("sines.csv");
    std::fs::write(&sines_csv, sines).unwrap();
    let o = run(&sines_csv);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A lab's text file read through a channel map streams too: a preamble, semicolons, decimal
/// commas, a units row, displacements in mm and a comment line inside the data identify as the
/// file read whole does.
#[test]
fn a_text_file_through_a_channel_map_identifies_as_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    let rig = rig_export(dir.path());
    let text = std::fs::read_to_string(&rig).unwrap();
    let mut out = String::from(
        "Pruefstand 2\r\nexported 2026-12-07\r\nZeit;Schritt;Frequenz;Weg Basis;Weg rel;Beschl\r\n\
         s;;Hz;mm;mm;m/s^2\r\n",
    );
    for (i, line) in text.lines().skip(1).enumerate() {
        let c: Vec<&str> = line.split(',').collect();
        let mm = |v: &str| format!("{:e}", v.parse::<f64>().unwrap() * 1e3);
        let row = [
            c[0].into(),
            c[1].into(),
            c[2].into(),
            mm(c[3]),
            mm(c[4]),
            c[5].into(),
        ];
        out.push_str(&row.join(";").replace('.', ","));
        out.push_str("\r\n");
        if i == 5000 {
            out.push_str("# operator: paused the log\r\n");
        }
    }
    let file = dir.path().join("pruefstand.txt");
    std::fs::write(&file, out).unwrap();
    let map = dir.path().join("map.yaml");
    std::fs::write(
        &map,
        "table: {skip_lines: 2}\nchannels:\n  time_s: {channel: Zeit}\n  step: {channel: Schritt}\n  \
         frequency_hz: {channel: Frequenz}\n  base_displacement_m: {channel: Weg Basis}\n  \
         relative_displacement_m: {channel: Weg rel}\n  mass_acceleration_mps2: {channel: Beschl}\n",
    )
    .unwrap();
    let args = [
        "identify",
        file.to_str().unwrap(),
        "--channels",
        map.to_str().unwrap(),
        "--model",
        "coulomb",
        "--mass-kg",
        "36",
    ];
    assert_streamed_as_whole(&args, plots.to_str().unwrap(), "a lab's text file");
    let o = forcemap(&args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("decimal commas"), "{stderr}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("validation on random record 11"),
        "{stdout}"
    );
}
