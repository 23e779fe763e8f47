//! The files test labs have, written by independent tools from forcemap's plain CSV of a run
//! (the paper's simulated rig, 40 dB): ASAM MDF4 by Python asammdf, NI TDMS by npTDMS (with a
//! time channel over several segments, and with waveform timing), and a CSV in a lab dialect
//! (byte-order mark, `;`, decimal commas, a units row, CRLF, a truncated last line). Each gives
//! the plain CSV's records and the same theta.
//!
//! Runs when FORCEMAP_PYTHON names a Python with asammdf and npTDMS (.ci/run installs them);
//! without them it says that it skipped, and under CI that fails.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};
use std::process::Command;

use forcemap_io::csv_export::{read_csv, write_csv};
use forcemap_io::input::{FileFormat, load};
use forcemap_math::identify::{FdMultiOptions, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Record;
use forcemap_math::sim::RunSpec;

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

/// The plain CSV of the paper's rig run and the files the Python tools made of it.
fn files(py: &str, dir: &Path) -> (PathBuf, u64) {
    let plain = dir.join("plain.csv");
    let records = RunSpec::paper_rig(Some(40.0), 3).simulate().unwrap();
    write_csv(&plain, &records, SetupKind::BaseExcited).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/measurement_files.py");
    let out = Command::new(py)
        .arg(&script)
        .arg(&plain)
        .arg(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "measurement_files.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truncated_line = String::from_utf8_lossy(&out.stdout).trim().parse().unwrap();
    (plain, truncated_line)
}

fn theta(records: &[Record]) -> Vec<f64> {
    let model = Model::by_name("coulomb", &ModelOptions::default()).unwrap();
    identify_records(
        &model,
        &Setup::BaseExcited { mass_kg: 36.0 },
        Method::FdMulti,
        records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap()
    .theta()
}

/// Same steps, excitations, rates and samples, bit for bit; start times to `start_tol_s`.
fn assert_same_records(a: &[Record], b: &[Record], what: &str, start_tol_s: f64) {
    assert_eq!(a.len(), b.len(), "{what}: record count");
    for (x, y) in a.iter().zip(b) {
        assert_eq!(x.step, y.step, "{what}");
        assert_eq!(x.excitation, y.excitation, "{what}: step {}", x.step);
        assert_eq!(
            x.sample_rate_hz, y.sample_rate_hz,
            "{what}: step {}",
            x.step
        );
        assert!(
            (x.start_time_s - y.start_time_s).abs() <= start_tol_s,
            "{what}: step {} starts at {} vs {}",
            x.step,
            x.start_time_s,
            y.start_time_s
        );
        assert_eq!(x.channels, y.channels, "{what}: step {} samples", x.step);
    }
}

#[test]
fn mdf4_tdms_and_a_lab_csv_give_the_plain_csvs_records_and_theta() {
    let Some(py) = python_with_writers() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (plain, truncated_line) = files(&py, dir.path());
    let reference = read_csv(&plain).unwrap();
    let theta_ref = theta(&reference.records);
    assert_eq!(theta_ref.len(), 3);

    for (name, format, start_tol_s) in [
        ("run.mf4", FileFormat::Mdf, 0.0),
        ("run.tdms", FileFormat::Tdms, 0.0),
        // Waveform timing: start + k * increment, a rounding away from the CSV's times.
        ("run_wf.tdms", FileFormat::Tdms, 1e-9),
        ("run_semicolon.csv", FileFormat::Csv, 0.0),
    ] {
        let path = dir.path().join(name);
        assert_eq!(FileFormat::of(&path), format, "{name}");
        let loaded = load(&path).unwrap_or_else(|e| panic!("{name}: {e:#}"));
        assert_eq!(loaded.kind, SetupKind::BaseExcited, "{name}");
        assert_same_records(&reference.records, &loaded.records, name, start_tol_s);
        let t = theta(&loaded.records);
        for (a, b) in theta_ref.iter().zip(&t) {
            assert!(
                ((a - b) / a).abs() <= 1e-12,
                "{name}: theta {t:?} vs the plain CSV's {theta_ref:?}"
            );
        }
        println!("{name}: theta {t:?} (plain CSV {theta_ref:?})");
    }

    // Channels over two channel groups: refused, naming the groups.
    let e = load(&dir.path().join("run_two_groups.mf4"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("run_two_groups.mf4: MDF4: forcemap channels are in several channel groups"),
        "{e}"
    );

    // The dialect and the skipped line are told, with the line.
    let lab = read_csv(dir.path().join("run_semicolon.csv")).unwrap();
    let notices = lab.notices.join("\n");
    for what in [
        "semicolon separators",
        "decimal commas",
        "units row",
        "byte-order mark",
        "CRLF",
        &format!("line {truncated_line}: skipped a truncated last line"),
    ] {
        assert!(notices.contains(what), "missing '{what}' in:\n{notices}");
    }
}

/// A file named for one format but holding another is read by its content.
#[test]
fn the_format_is_told_by_content_before_extension() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("really_tdms.mf4");
    std::fs::write(&p, b"TDSm\x0e\x00\x00\x00").unwrap();
    assert_eq!(FileFormat::of(&p), FileFormat::Tdms);
    let p = dir.path().join("really_mdf.csv");
    std::fs::write(&p, b"MDF     4.10    ").unwrap();
    assert_eq!(FileFormat::of(&p), FileFormat::Mdf);
    let p = dir.path().join("empty.tdms");
    std::fs::write(&p, b"").unwrap();
    assert_eq!(FileFormat::of(&p), FileFormat::Tdms);
    let e = load(&p).unwrap_err().to_string();
    assert!(e.contains("empty.tdms: TDMS: not a TDMS file"), "{e}");
}

/// The input with which fuzzing made mdf4-rs 0.3.0 slice past the end of the file (an asammdf
/// file whose channel link points far outside it): an error naming the file, no panic.
#[test]
fn a_channel_link_outside_the_file_is_an_error() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mdf_channel_link_past_end.mf4");
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("mdf_channel_link_past_end.mf4: MDF4:") && e.contains("outside the file"),
        "{e}"
    );
}

/// The input with which fuzzing made mdf4-rs 0.3.0 divide by zero (a channel group whose
/// records have 0 bytes): an error naming the file, no panic.
#[test]
fn a_record_of_zero_bytes_is_an_error() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mdf_zero_record_size.mf4");
    let e = load(&path).unwrap_err().to_string();
    assert!(e.contains("mdf_zero_record_size.mf4: MDF4:"), "{e}");
    println!("{e}");
}

/// A third fuzz input: a data-block link far outside the file, which the chain check does not
/// look at; mdf4-rs 0.3.0 panics on it, and the reader reports the file as malformed.
#[test]
fn a_panic_in_the_mdf_crate_is_an_error() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/mdf_data_link_past_end.mf4");
    let e = load(&path).unwrap_err().to_string();
    assert!(
        e.contains("mdf_data_link_past_end.mf4: MDF4: malformed: the MDF4 parser (mdf4-rs) failed"),
        "{e}"
    );
}
