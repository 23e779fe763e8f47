//! Rows of numbers (a measurement file's channels, `read_number_rows`) are read as the CSV
//! export that writes each number in shortest round-trip form (`read_csv_from` over that text):
//! the same records bit for bit, the same warnings and notices, the same error naming the same
//! line, whatever the block size. The rows: the paper's rig run (sine steps and band-random
//! records), then with values an export would refuse or read otherwise (not finite, a negative
//! or fractional step, a negative frequency, a time that goes back, a time rounded to fewer
//! decimals).
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::convert::Infallible;
use std::path::Path;

use forcemap_io::csv_export::{
    CsvImport, NumberRowsError, read_csv_from, read_number_rows, write_csv,
};
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::RunSpec;

/// The paper's rig run as an export's column names and rows.
fn rig_rows(dir: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let records = RunSpec::paper_rig(Some(40.0), 3).simulate().unwrap();
    let path = dir.join("rig.csv");
    write_csv(&path, &records, SetupKind::BaseExcited).unwrap();
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let names = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|c| c.parse().unwrap_or(0.0)).collect())
        .collect();
    (names, rows)
}

/// A cell as an export writes a number: shortest round-trip, an exponent for the very large
/// or small, a step index that is an integer as an integer.
fn cell(name: &str, v: f64) -> String {
    let a = v.abs();
    if name == "step" && v.fract() == 0.0 && a < 1e15 {
        format!("{}", v as i64)
    } else if a == 0.0 || (1e-5..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

fn text_of(names: &[String], rows: &[Vec<f64>]) -> String {
    let mut text = names.join(",") + "\n";
    for row in rows {
        let cells: Vec<String> = names.iter().zip(row).map(|(n, &v)| cell(n, v)).collect();
        text.push_str(&cells.join(","));
        text.push('\n');
    }
    text
}

/// What a reader gave, in a form that tells every bit (`Debug` of f64 is its shortest
/// round-trip text).
fn outcome(r: Result<CsvImport, String>) -> String {
    match r {
        Ok(import) => format!("{import:?}"),
        Err(e) => format!("error: {e}"),
    }
}

/// The rows read as numbers in blocks of several sizes and as the export's text: all agree.
fn same_as_text(names: &[String], rows: &[Vec<f64>], what: &str) -> String {
    let path = Path::new("table.mf4");
    let text = text_of(names, rows);
    let reference = outcome(read_csv_from(text.as_bytes(), path).map_err(|e| e.to_string()));
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    for block in [1, 7, 4096, rows.len().max(1)] {
        let mut next = 0;
        let fill = |out: &mut Vec<f64>| -> Result<usize, Infallible> {
            let n = block.min(rows.len() - next);
            rows[next..next + n]
                .iter()
                .for_each(|r| out.extend_from_slice(r));
            next += n;
            Ok(n)
        };
        let got = read_number_rows(path, &names, Some, fill).map_err(|e| match e {
            NumberRowsError::Rows(e) => e.to_string(),
            NumberRowsError::Source(e) => match e {},
        });
        assert_eq!(outcome(got), reference, "{what}: blocks of {block} rows");
    }
    reference
}

#[test]
fn number_rows_say_what_the_export_of_them_says() {
    let dir = tempfile::tempdir().unwrap();
    let (names, rows) = rig_rows(dir.path());
    let col = |name: &str| names.iter().position(|n| n == name).unwrap();
    let whole = same_as_text(&names, &rows, "the rig run");
    assert!(whole.contains("records: ["), "{}", &whole[..200]);

    // One value changed at row 700 (line 702): each is the error or the reading the export's
    // cell gives.
    let cases: [(&str, f64, &str); 13] = [
        ("force_n", f64::NAN, "error"),
        (
            "mass_acceleration_mps2",
            f64::NAN,
            "line 702, column 'mass_acceleration_mps2'",
        ),
        ("base_displacement_m", f64::INFINITY, "line 702"),
        ("time_s", f64::NAN, "line 702, column 'time_s'"),
        ("time_s", f64::NEG_INFINITY, "line 702"),
        ("time_s", 0.5, "line 702"),
        ("step", -1.0, "must be a non-negative integer"),
        ("step", 2.5, "'2.5'"),
        ("step", f64::NAN, "line 702"),
        ("step", 1e15, "line 702"),
        ("frequency_hz", -2.0, "must not be negative"),
        ("frequency_hz", f64::NAN, "line 702"),
        ("frequency_hz", -0.0, "error"),
    ];
    for (name, v, says) in cases {
        let Some(c) = names.iter().position(|n| n == name) else {
            // A channel this run does not have: a NaN in another one.
            continue;
        };
        let mut changed = rows.clone();
        changed[700][c] = v;
        let got = same_as_text(&names, &changed, &format!("{name} = {v}"));
        assert!(got.contains(says), "{name} = {v}: {got:.300}");
    }

    // A clock 0.1 ppm slow, its times to 10 us: read as 100 Hz within the rounding of the
    // times, which the cells' decimals tell (a rounding read as finer would give 99.99999 Hz).
    let mut rounded = rows.clone();
    let t = col("time_s");
    for r in &mut rounded {
        r[t] = (r[t] * (1.0 + 1e-7) * 1e5).round() / 1e5;
    }
    let read = same_as_text(&names, &rounded, "times to 10 us");
    assert!(read.contains("sample_rate_hz: 100.0,"), "{read:.400}");
    // No rows: the export of its header alone.
    let empty = same_as_text(&names, &[], "no rows");
    assert!(empty.starts_with("error: "), "{empty}");
}
