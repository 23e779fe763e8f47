//! Every reading error names the file, the line (header = line 1) and the column.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::csv_export::{CsvError, read_csv};

const FILE: &str = "bench_run_42.csv";

/// A valid rig export as a table: row 0 is the header (line 1), row k is line k+1.
/// Steps: (rows, frequency cell); 1 kHz sampling, continuous time.
fn table(steps: &[(usize, &str)]) -> Vec<Vec<String>> {
    let mut rows = vec![
        "time_s,step,frequency_hz,base_displacement_m,relative_displacement_m,mass_acceleration_mps2"
            .split(',')
            .map(str::to_string)
            .collect::<Vec<_>>(),
    ];
    let mut i = 0;
    for (step, &(n, freq)) in steps.iter().enumerate() {
        for _ in 0..n {
            rows.push(vec![
                format!("{}", i as f64 / 1000.0),
                step.to_string(),
                freq.to_string(),
                format!("{}", (i as f64 * 0.3).sin() * 1e-3),
                "1e-5".into(),
                "-0.25".into(),
            ]);
            i += 1;
        }
    }
    rows
}

fn read_table(rows: &[Vec<String>]) -> (tempfile::TempDir, CsvError) {
    let text: String = rows.iter().map(|r| r.join(",") + "\n").collect();
    read_text(&text)
}

fn read_text(text: &str) -> (tempfile::TempDir, CsvError) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(FILE);
    std::fs::write(&path, text).unwrap();
    let err = read_csv(&path).expect_err("reading must fail");
    (dir, err)
}

fn assert_mentions(err: &CsvError, parts: &[&str]) {
    let msg = err.to_string();
    assert!(msg.contains(FILE), "message lacks the file name: {msg}");
    for p in parts {
        assert!(msg.contains(p), "message lacks {p:?}: {msg}");
    }
}

fn two_steps() -> Vec<Vec<String>> {
    table(&[(5, "10"), (5, "12.5")])
}

#[test]
fn the_valid_table_reads() {
    let rows = two_steps();
    let text: String = rows.iter().map(|r| r.join(",") + "\n").collect();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(FILE);
    std::fs::write(&path, text).unwrap();
    let import = read_csv(&path).unwrap();
    assert_eq!(import.records.len(), 2);
    assert_eq!(import.records[1].sample_rate_hz, 1000.0);
}

#[test]
fn missing_columns_list_both_profiles() {
    let mut rows = two_steps();
    for r in &mut rows {
        r.remove(5); // mass_acceleration_mps2
    }
    let (_d, err) = read_table(&rows);
    assert!(matches!(err, CsvError::MissingColumns { .. }), "{err:?}");
    assert_mentions(
        &err,
        &["line 1", "mass_acceleration_mps2", "rig", "drive-point"],
    );

    // Neither profile recognisable: both sets are listed with what is missing.
    let (_d, err) = read_text("time_s,step,frequency_hz,relative_displacement_m\n0,0,1,2\n");
    assert_mentions(
        &err,
        &[
            "line 1",
            "base_displacement_m",
            "mass_acceleration_mps2",
            "force_n",
            "drive_point_displacement_m",
        ],
    );
    match err {
        CsvError::MissingColumns {
            profile,
            missing_rig,
            missing_drive_point,
            ..
        } => {
            assert_eq!(profile, None);
            assert_eq!(
                missing_rig,
                vec!["base_displacement_m", "mass_acceleration_mps2"]
            );
            assert_eq!(
                missing_drive_point,
                vec!["drive_point_displacement_m", "force_n"]
            );
        }
        e => panic!("{e:?}"),
    }

    // Missing `time_s`.
    let mut rows = two_steps();
    for r in &mut rows {
        r.remove(0);
    }
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 1", "time_s"]);
}

#[test]
fn non_numeric_cell_is_quoted() {
    let mut rows = two_steps();
    rows[3][4] = "12,5 mm".into(); // quoted by the CSV writer below
    let text: String = rows
        .iter()
        .map(|r| {
            r.iter()
                .map(|c| {
                    if c.contains(',') {
                        format!("\"{c}\"")
                    } else {
                        c.clone()
                    }
                })
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect();
    let (_d, err) = read_text(&text);
    assert!(
        matches!(err, CsvError::NonNumeric { line: 4, .. }),
        "{err:?}"
    );
    assert_mentions(&err, &["line 4", "relative_displacement_m", "'12,5 mm'"]);
}

#[test]
fn empty_required_cell() {
    let mut rows = two_steps();
    rows[7][5] = String::new();
    let (_d, err) = read_table(&rows);
    assert!(
        matches!(err, CsvError::EmptyCell { line: 8, .. }),
        "{err:?}"
    );
    assert_mentions(&err, &["line 8", "mass_acceleration_mps2", "empty"]);

    let mut rows = two_steps();
    rows[2][0] = "  ".into();
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 3", "time_s", "empty"]);
}

#[test]
fn nan_and_infinity_are_rejected() {
    for (cell, col, name) in [
        ("NaN", 3, "base_displacement_m"),
        ("inf", 4, "relative_displacement_m"),
        ("-infinity", 2, "frequency_hz"),
        ("1e999", 0, "time_s"),
    ] {
        let mut rows = two_steps();
        rows[6][col] = cell.into();
        let (_d, err) = read_table(&rows);
        assert!(
            matches!(err, CsvError::NonFinite { line: 7, .. }),
            "{err:?}"
        );
        assert_mentions(&err, &["line 7", name, cell]);
    }
}

#[test]
fn time_going_backwards_or_standing_still() {
    let mut rows = two_steps();
    rows[4][0] = "0.001".into(); // line 5 goes back below line 4 (0.002)
    let (_d, err) = read_table(&rows);
    assert!(
        matches!(
            err,
            CsvError::TimeNotIncreasing {
                prev_line: 4,
                line: 5,
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["line 5", "line 4", "time_s"]);

    let mut rows = two_steps();
    rows[6][0] = rows[5][0].clone(); // equal times on lines 6 and 7 (across the step change)
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 7", "line 6", "time_s", "does not increase"]);
}

#[test]
fn steps_must_be_contiguous() {
    let mut rows = two_steps();
    for r in rows.iter_mut().skip(6) {
        r[1] = "2".into(); // 0 then 2
    }
    let (_d, err) = read_table(&rows);
    assert!(
        matches!(
            err,
            CsvError::StepNotContiguous {
                prev_line: 6,
                line: 7,
                prev_step: 0,
                step: 2,
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["line 7", "step", "contiguous"]);

    // A step coming back after another one.
    let mut rows = table(&[(4, "10"), (4, "11"), (4, "12")]);
    for r in rows.iter_mut().skip(9) {
        r[1] = "0".into();
    }
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 10", "step 0 follows step 1"]);

    // Not an integer.
    let mut rows = two_steps();
    rows[2][1] = "0.5".into();
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 3", "step", "'0.5'"]);
}

#[test]
fn frequency_must_be_constant_within_a_step() {
    let mut rows = two_steps();
    rows[3][2] = "10.5".into();
    let (_d, err) = read_table(&rows);
    assert!(
        matches!(
            err,
            CsvError::FrequencyChanged {
                first_line: 2,
                line: 4,
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["line 4", "frequency_hz", "10.5", "step 0"]);

    // Random (empty) turning into a sine inside a step.
    let mut rows = table(&[(5, ""), (5, "3")]);
    rows[4][2] = "7".into();
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 5", "line 2", "frequency_hz", "random"]);

    // Negative frequency.
    let mut rows = two_steps();
    rows[2][2] = "-3".into();
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 3", "frequency_hz", "'-3'"]);
}

/// A time a third of an interval off its sample (no lost row, no jitter of a clock) is refused,
/// naming the lines and what to do. A lost row, a pause, a jittered clock and steps at other
/// rates are read (`csv_timing`).
#[test]
fn non_uniform_sampling_within_a_step() {
    let mut rows = table(&[(6, "10"), (40, "11")]);
    rows[10][0] = "0.0093".into();
    let (_d, err) = read_table(&rows);
    assert!(
        matches!(
            err,
            CsvError::NonUniformSampling {
                step: 1,
                prev_line: 10,
                line: 11,
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(
        &err,
        &[
            "line 11",
            "line 10",
            "time_s",
            "step 1",
            "correct or remove the row",
        ],
    );

    // A duplicated row (its time repeated) is refused as time not increasing.
    let mut rows = table(&[(6, "10"), (40, "11")]);
    rows[10][0] = rows[9][0].clone();
    let (_d, err) = read_table(&rows);
    assert!(matches!(err, CsvError::TimeNotIncreasing { .. }), "{err:?}");
}

#[test]
fn empty_file_and_header_only() {
    let (_d, err) = read_text("");
    assert!(matches!(err, CsvError::Empty { .. }), "{err:?}");
    assert_mentions(&err, &["empty"]);

    let (_d, err) = read_text(
        "time_s,step,frequency_hz,base_displacement_m,relative_displacement_m,mass_acceleration_mps2\n",
    );
    assert!(matches!(err, CsvError::HeaderOnly { .. }), "{err:?}");
    assert_mentions(&err, &["line 1", "no data rows"]);
}

#[test]
fn a_step_needs_three_rows() {
    let rows = table(&[(5, "10"), (2, "11"), (5, "12")]);
    let (_d, err) = read_table(&rows);
    assert!(
        matches!(
            err,
            CsvError::TooFewRows {
                step: 1,
                first_line: 7,
                rows: 2,
                ..
            }
        ),
        "{err:?}"
    );
    assert_mentions(&err, &["line 7", "step 1", "2 row"]);

    // The last step too.
    let rows = table(&[(5, "10"), (1, "11")]);
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 7", "step 1", "1 row"]);
}

#[test]
fn duplicate_column_and_ragged_row() {
    let mut rows = two_steps();
    rows[0][4] = "base_displacement_m".into();
    let (_d, err) = read_table(&rows);
    assert!(matches!(err, CsvError::DuplicateColumn { .. }), "{err:?}");
    assert_mentions(&err, &["line 1", "base_displacement_m"]);

    let mut rows = two_steps();
    rows[5].pop();
    let (_d, err) = read_table(&rows);
    assert_mentions(&err, &["line 6", "5 field"]);
}

#[test]
fn missing_file_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let err = read_csv(dir.path().join(FILE)).unwrap_err();
    assert!(matches!(err, CsvError::Io { .. }));
    assert!(err.to_string().contains(FILE), "{err}");
}
