//! Exports without `step` and `frequency_hz`: the steps found in the driven channel give the
//! records, and the identification, of the labelled export of the same run; labels that
//! disagree with the drive are warned about; a drive without steps is an error naming the file
//! and its time span.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::{Path, PathBuf};

use forcemap_io::csv_export::{CsvError, read_csv, write_csv};
use forcemap_io::steps::unlabelled::{DEFAULT_FREQUENCY_TOLERANCE, frequencies_from_data};
use forcemap_math::identify::{FdMultiOptions, Method};
use forcemap_math::model::{Model, ModelOptions};
use forcemap_math::phasor::PhasorOptions;
use forcemap_math::pipeline::identify_records;
use forcemap_math::recipe::Setup;
use forcemap_math::recipe::SubstructureSpec;
use forcemap_math::record::{Channel, Record};
use forcemap_math::sim::{RunSpec, ThreeDofCase};

/// `path` rewritten without the columns named `drop` (and `edit` applied to each kept row's
/// cells, by column name).
fn rewrite(
    path: &Path,
    out: &Path,
    drop: &[&str],
    edit: impl Fn(usize, &mut Vec<String>, &[String]),
) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let keep: Vec<usize> = (0..header.len())
        .filter(|&i| !drop.contains(&header[i].as_str()))
        .collect();
    let mut s = keep
        .iter()
        .map(|&i| header[i].as_str())
        .collect::<Vec<_>>()
        .join(",");
    s.push('\n');
    for (row, line) in lines.enumerate() {
        let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
        edit(row, &mut cells, &header);
        s.push_str(
            &keep
                .iter()
                .map(|&i| cells[i].as_str())
                .collect::<Vec<_>>()
                .join(","),
        );
        s.push('\n');
    }
    std::fs::write(out, s).unwrap();
}

fn theta(spec: &RunSpec, records: &[Record]) -> Vec<f64> {
    let (model, setup) = match spec.mass_kg() {
        Some(mass_kg) => (
            Model::by_name("coulomb", &ModelOptions::default()).unwrap(),
            Setup::BaseExcited { mass_kg },
        ),
        None => (
            Model::by_name("coulomb-cubic", &ModelOptions::default()).unwrap(),
            Setup::DrivePoint {
                substructure: SubstructureSpec::PaperThreeDof.build().unwrap(),
            },
        ),
    };
    identify_records(
        &model,
        &setup,
        Method::FdMulti,
        records,
        &PhasorOptions::for_identification(),
        &FdMultiOptions::default(),
    )
    .unwrap()
    .theta()
}

/// Writes the run labelled and unlabelled; returns both paths.
fn exports(dir: &Path, name: &str, spec: &RunSpec) -> (PathBuf, PathBuf) {
    let labelled = dir.join(format!("{name}.csv"));
    let unlabelled = dir.join(format!("{name}_unlabelled.csv"));
    write_csv(&labelled, &spec.simulate().unwrap(), spec.setup_kind()).unwrap();
    rewrite(
        &labelled,
        &unlabelled,
        &["step", "frequency_hz"],
        |_, _, _| {},
    );
    (labelled, unlabelled)
}

/// The unlabelled export gives the labelled one's records (same samples, frequencies) and
/// theta within 1e-6 relative.
fn same_identification(spec: &RunSpec, name: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (labelled, unlabelled) = exports(dir.path(), name, spec);
    let a = read_csv(&labelled).unwrap();
    let b = read_csv(&unlabelled).unwrap();
    assert!(a.warnings.is_empty(), "{name}: {:?}", a.warnings);
    assert_eq!(a.kind, b.kind);
    let sines = |r: &[Record]| {
        r.iter()
            .filter(|r| r.excitation.frequency_hz().is_some())
            .count()
    };
    assert_eq!(sines(&a.records), sines(&b.records), "{name}");
    for (ra, rb) in a.records.iter().zip(&b.records) {
        if ra.excitation.frequency_hz().is_none() {
            continue;
        }
        assert_eq!(ra.excitation, rb.excitation, "{name}: step {}", ra.step);
        assert_eq!(ra.start_time_s, rb.start_time_s, "{name}: step {}", ra.step);
        assert_eq!(ra.channels, rb.channels, "{name}: step {}", ra.step);
    }
    let (ta, tb) = (theta(spec, &a.records), theta(spec, &b.records));
    for (x, y) in ta.iter().zip(&tb) {
        assert!(
            (x - y).abs() <= 1e-6 * x.abs(),
            "{name}: theta {ta:?} vs {tb:?}"
        );
    }
}

#[test]
fn unlabelled_rig_export_identifies_as_the_labelled_one() {
    same_identification(&RunSpec::paper_rig_sine(None, 0), "rig_clean");
    same_identification(&RunSpec::paper_rig_sine(Some(30.0), 1), "rig_30db");
    same_identification(&RunSpec::paper_rig(Some(40.0), 2), "rig_40db_with_random");
}

#[test]
fn unlabelled_three_dof_export_identifies_as_the_labelled_one() {
    same_identification(
        &RunSpec::three_dof(ThreeDofCase::I, Some(30.0), 1),
        "three_dof_30db",
    );
}

#[test]
fn labels_that_disagree_with_the_drive_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let spec = RunSpec::paper_rig_sine(Some(30.0), 3);
    let (labelled, _) = exports(dir.path(), "rig", &spec);
    let col = |header: &[String], name: &str| header.iter().position(|h| h == name).unwrap();
    // Step 3 (2.2 Hz) labelled 2.3 Hz.
    let wrong_frequency = dir.path().join("wrong_frequency.csv");
    rewrite(&labelled, &wrong_frequency, &[], |_, cells, header| {
        let f = col(header, "frequency_hz");
        if cells[col(header, "step")] == "3" {
            cells[f] = "2.3".to_string();
        }
    });
    // The reader keeps the label; the frequency is checked where the steps are analysed
    // (`frequency_from_data`), which analyses the step at its drive's frequency.
    let mut csv = read_csv(&wrong_frequency).unwrap();
    assert!(csv.warnings.is_empty(), "{:?}", csv.warnings);
    let w = frequencies_from_data(
        &mut csv.records,
        Channel::BaseDisplacementM,
        DEFAULT_FREQUENCY_TOLERANCE,
    );
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("step 3 is labelled 2.3 Hz, but base_displacement_m is at 2.19"),
        "{w:?}"
    );
    // Step 3 at 2.2 Hz; every other step keeps its label exactly.
    let as_read = read_csv(&wrong_frequency).unwrap().records;
    for (r, read) in csv.records.iter().zip(&as_read) {
        let f = r.excitation.frequency_hz().unwrap();
        if r.step == 3 {
            assert!((f / 2.2 - 1.0).abs() < 1e-4, "{f}");
        } else {
            assert_eq!(r.excitation, read.excitation, "step {}", r.step);
        }
    }
    // Step 5's first 200 rows labelled step 4: step 5 starts 2 s late.
    let late = dir.path().join("late_start.csv");
    rewrite(&labelled, &late, &[], |row, cells, header| {
        if (5 * 1300..5 * 1300 + 200).contains(&row) {
            cells[col(header, "step")] = "4".to_string();
            cells[col(header, "frequency_hz")] = "2.4".to_string();
        }
    });
    let w = read_csv(&late).unwrap().warnings;
    assert!(
        w.iter()
            .any(|l| l.contains("step 5 is labelled to start at 67.000 s")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|l| l.contains("changes at 65.000 s (to sine) inside labelled step 4")),
        "{w:?}"
    );
}

#[test]
fn a_drive_without_steps_is_an_error_naming_the_file_and_span() {
    let dir = tempfile::tempdir().unwrap();
    let spec = RunSpec::paper_rig_sine(Some(30.0), 0);
    let (labelled, _) = exports(dir.path(), "rig", &spec);
    // The base held still (noise only, 1e-6 m): no sine anywhere.
    let still = dir.path().join("still.csv");
    rewrite(
        &labelled,
        &still,
        &["step", "frequency_hz"],
        |row, cells, header| {
            let b = header
                .iter()
                .position(|h| h == "base_displacement_m")
                .unwrap();
            let u = ((row as u64 + 1).wrapping_mul(6_364_136_223_846_793_005) >> 40) as f64
                / (1u64 << 24) as f64;
            cells[b] = format!("{:e}", 1e-6 * (2.0 * u - 1.0));
        },
    );
    let e = read_csv(&still).unwrap_err();
    assert!(matches!(e, CsvError::Unlabelled { .. }), "{e}");
    let text = e.to_string();
    assert!(text.contains("still.csv"), "{text}");
    assert!(text.contains("0.000-129.990 s"), "{text}");
    assert!(
        text.contains("no stepped-sine steps found in channel base_displacement_m"),
        "{text}"
    );
    assert!(text.contains("found 1 step: "), "{text}");
}
