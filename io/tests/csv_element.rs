//! The element-test profile of the CSV contract: a damper dyno's export (relative
//! displacement, force, fixture acceleration) reads back as the element setup, labelled or
//! not, and identifies as the simulated records do.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use forcemap_io::csv_export::{read_csv, write_csv};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Record;
use forcemap_math::sim::{ElementDrive, RunSpec, StepSpec};

fn dyno_records() -> Vec<Record> {
    let element = RunSpec::damper_dyno(None, 0).element;
    // At least 8 periods per step: the step finder needs about 6 of the lowest frequency.
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
        seed: 5,
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
    .expect("simulates")
}

fn theta(records: &[Record]) -> Vec<f64> {
    std_theta(records).into_iter().map(|(v, _)| v).collect()
}

fn std_theta(records: &[Record]) -> Vec<(f64, f64)> {
    common::dyno_identification(records)
        .parameters
        .iter()
        .map(|p| (p.value, p.std))
        .collect()
}

fn assert_close(a: &[f64], b: &[f64], rel: f64) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert!(((x - y) / y).abs() < rel, "{x} vs {y}");
    }
}

#[test]
fn a_dyno_export_reads_back_as_the_element_setup() {
    let records = dyno_records();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("dyno.csv");
    write_csv(&path, &records, SetupKind::Element).expect("writes");
    let import = read_csv(&path).expect("reads");
    assert_eq!(import.kind, SetupKind::Element);
    assert_eq!(import.records.len(), records.len());
    // The CSV's 17 significant digits keep the identification (within round-off).
    assert_close(&theta(&import.records), &theta(&records), 1e-9);
}

#[test]
fn an_unlabelled_dyno_export_gives_the_labelled_theta() {
    let records = dyno_records();
    let dir = tempfile::tempdir().expect("tempdir");
    let labelled = dir.path().join("dyno.csv");
    write_csv(&labelled, &records, SetupKind::Element).expect("writes");
    // Drop the step and frequency_hz columns.
    let text = std::fs::read_to_string(&labelled).expect("reads");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&i| header[i] != "step" && header[i] != "frequency_hz")
        .collect();
    let pick = |l: &str| {
        let cells: Vec<&str> = l.split(',').collect();
        keep.iter().map(|&i| cells[i]).collect::<Vec<_>>().join(",")
    };
    let mut out = pick(&header.join(",")) + "\n";
    for l in lines {
        out += &pick(l);
        out.push('\n');
    }
    let unlabelled = dir.path().join("dyno_unlabelled.csv");
    std::fs::write(&unlabelled, out).expect("writes");
    let import = read_csv(&unlabelled).expect("reads");
    assert_eq!(import.kind, SetupKind::Element);
    let labelled_import = read_csv(&labelled).expect("reads");
    // The drive changes amplitude and frequency phase-continuously at zero crossings (every
    // step is whole periods): the steps are found at the labelled samples and frequencies,
    // so the records and the theta are the labelled ones.
    assert_eq!(import.records.len(), labelled_import.records.len());
    for (u, l) in import.records.iter().zip(&labelled_import.records) {
        assert_eq!((u.len(), u.start_time_s), (l.len(), l.start_time_s));
        assert_eq!(u.excitation.frequency_hz(), l.excitation.frequency_hz());
    }
    assert_close(
        &theta(&import.records),
        &theta(&labelled_import.records),
        1e-6,
    );
}

#[test]
fn a_force_column_alone_is_not_an_element_test() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("force_only.csv");
    std::fs::write(
        &path,
        "time_s,step,frequency_hz,force_n\n0,0,1,2\n0.001,0,1,2\n",
    )
    .expect("w");
    let e = read_csv(&path).expect_err("refused").to_string();
    assert!(
        e.contains("the element profile requires [time_s") && e.contains("relative_displacement_m"),
        "{e}"
    );
}
