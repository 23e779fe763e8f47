//! Bad input at the process boundary: a clear error naming what and where (file, line,
//! column, step, parameter), a non-zero exit, and nothing half-written.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

mod common;

use common::{forcemap, stderr};

use std::path::Path;

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

/// A small, valid rig export: two sine steps of 3 periods each, then the text is edited.
fn small_rig_csv() -> String {
    let mut s = String::from(
        "time_s,step,frequency_hz,base_displacement_m,relative_displacement_m,mass_acceleration_mps2\n",
    );
    let fs = 100.0;
    for step in 0..2 {
        let f = 2.0 + step as f64;
        for i in 0..150 {
            let t = (step * 150 + i) as f64 / fs;
            let w = std::f64::consts::TAU * f;
            let x = 0.01 * (w * t).sin();
            s.push_str(&format!(
                "{t},{step},{f},{},{},{}\n",
                0.005 * (w * t).sin(),
                x,
                -w * w * x
            ));
        }
    }
    s
}

/// `text` with the cell at 1-based `line`, 0-based `column` replaced.
fn with_cell(text: &str, line: usize, column: usize, value: &str) -> String {
    text.lines()
        .enumerate()
        .map(|(i, l)| {
            if i + 1 == line {
                let mut cells: Vec<&str> = l.split(',').collect();
                cells[column] = value;
                cells.join(",") + "\n"
            } else {
                format!("{l}\n")
            }
        })
        .collect()
}

#[test]
fn bad_csv_input_names_file_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let good = small_rig_csv();
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        (
            "missing_column.csv",
            good.replace(",mass_acceleration_mps2", ""),
            vec!["mass_acceleration_mps2"],
        ),
        (
            "non_numeric.csv",
            good.replacen(",0.005", ",abc", 1),
            vec!["line", "abc"],
        ),
        (
            "nan.csv",
            with_cell(&good, 5, 4, "NaN"),
            vec!["line 5", "relative_displacement_m"],
        ),
        (
            "backwards.csv",
            good.replacen("\n0.02,", "\n0.005,", 1),
            vec!["line", "time"],
        ),
        ("empty.csv", String::new(), vec!["empty"]),
    ];
    for (name, text, needles) in cases {
        let path = write(dir.path(), name, &text);
        let o = forcemap(&["identify", &path, "--model", "coulomb", "--mass-kg", "36"]);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(name),
            "{name}: error does not name the file: {e}"
        );
        for n in needles {
            assert!(
                e.to_lowercase().contains(&n.to_lowercase()),
                "{name}: error lacks '{n}': {e}"
            );
        }
        assert!(o.stdout.is_empty(), "{name}: printed a result anyway");
    }
}

#[test]
fn too_few_equations_and_unidentifiable_parameters_are_refused_with_names() {
    let dir = tempfile::tempdir().unwrap();
    // one sine step of the paper's method gives 2 real equations: too few for 4 parameters
    let text: String = small_rig_csv()
        .lines()
        .filter(|l| !l.contains(",1,3,"))
        .map(|l| format!("{l}\n"))
        .collect();
    let path = write(dir.path(), "one_step.csv", &text);
    let o = forcemap(&[
        "identify",
        &path,
        "--model",
        "coulomb-cubic",
        "--mass-kg",
        "36",
        "--method",
        "fd",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("2 real equations for 4 parameters") && e.contains("one_step.csv"),
        "{e}"
    );
    // within one pure-sine step x x'^2 = A^2 w^2 x - w^2 x^3: the polynomial model is refused,
    // naming the terms involved
    let o = forcemap(&[
        "identify",
        &path,
        "--model",
        "polynomial",
        "--poly-order",
        "3,2",
        "--mass-kg",
        "36",
    ]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("cannot identify") && e.contains("p12"), "{e}");
}

#[test]
fn short_record_and_missing_mass_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    // 2 Hz at 100 Hz: one period is 50 samples; keep 60 samples of step 0 only
    let text: String = small_rig_csv()
        .lines()
        .take(61)
        .map(|l| format!("{l}\n"))
        .collect();
    let path = write(dir.path(), "short.csv", &text);
    let o = forcemap(&["identify", &path, "--model", "linear", "--mass-kg", "36"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("step 0") && stderr(&o).to_lowercase().contains("period"),
        "{}",
        stderr(&o)
    );
    let path = write(dir.path(), "ok.csv", &small_rig_csv());
    let o = forcemap(&["identify", &path, "--model", "linear"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--mass-kg"), "{}", stderr(&o));
    let o = forcemap(&[
        "identify",
        &path,
        "--model",
        "no-such-model",
        "--mass-kg",
        "36",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("unknown model 'no-such-model'"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn simulate_never_leaves_a_half_written_file() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("no_such_dir").join("out.csv");
    let o = forcemap(&["simulate", "--csv", target.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(!target.exists());
    assert!(
        std::fs::read_dir(dir.path()).unwrap().count() == 0,
        "something was left behind"
    );
}
