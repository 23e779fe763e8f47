//! A CSV export read from its file chunk by chunk (`read_csv`) is the export read whole
//! (`read_csv_from` over the file's bytes): the same records bit for bit, the same warnings and
//! notices, the same error naming the same line, at any chunk size. The exports: simulated rig
//! runs in the lab dialects, with a last line cut short, a quoted cell (read by the `csv`
//! crate with the rest of the file), blank lines, and faults late in the file. Read record by
//! record (`read_csv_reduced`), the records handed over are the same, in order, and the import
//! holds those kept.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use std::path::Path;

use forcemap_io::csv_export::{
    read_csv, read_csv_from, read_csv_in_chunks, read_csv_reduced, write_csv,
};
use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Excitation;
use forcemap_math::sim::RunSpec;

/// The paper's rig run (sine steps and band-random records) as an export's text.
fn rig_export(dir: &Path) -> String {
    let records = RunSpec::paper_rig(Some(40.0), 3).simulate().unwrap();
    let path = dir.join("rig.csv");
    write_csv(&path, &records, SetupKind::BaseExcited).unwrap();
    std::fs::read_to_string(path).unwrap()
}

/// What a reader gave, in a form that tells every bit: `Debug` of f64 is its shortest
/// round-trip text, distinct for distinct values.
fn outcome(
    r: Result<forcemap_io::csv_export::CsvImport, forcemap_io::csv_export::CsvError>,
) -> String {
    match r {
        Ok(import) => format!("{import:?}"),
        Err(e) => format!("error: {e}"),
    }
}

/// Reads `bytes` as a file whole and in chunks of several sizes; all must agree.
fn same_in_chunks(dir: &Path, name: &str, bytes: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let whole = outcome(read_csv_from(bytes, &path));
    assert_eq!(outcome(read_csv(&path)), whole, "{name}: read_csv");
    for chunk in [1, 7, 100, 4096, 100_000] {
        assert_eq!(
            outcome(read_csv_in_chunks(&path, chunk)),
            whole,
            "{name}: chunks of {chunk} bytes"
        );
    }
    // Record by record, the sine steps handed over and dropped.
    let mut seen = Vec::new();
    let reduced = read_csv_reduced(&path, |r| {
        seen.push(r.clone());
        (!matches!(r.excitation, Excitation::Sine { .. })).then_some(r)
    });
    match reduced {
        Ok(mut import) => {
            let kept: Vec<_> = seen
                .iter()
                .filter(|r| !matches!(r.excitation, Excitation::Sine { .. }))
                .cloned()
                .collect();
            assert_eq!(import.records, kept, "{name}: the records kept");
            import.records = seen;
            assert_eq!(outcome(Ok(import)), whole, "{name}: record by record");
        }
        Err(e) => assert_eq!(format!("error: {e}"), whole, "{name}: record by record"),
    }
    whole
}

/// `text` with line `n` (1-based) replaced by what `f` makes of it.
fn with_line(text: &str, n: usize, f: impl Fn(&str) -> String) -> String {
    text.split_inclusive('\n')
        .enumerate()
        .map(|(i, l)| if i + 1 == n { f(l) } else { l.to_string() })
        .collect()
}

/// `text` with cell `col` (0-based) of line `n` set to `value`.
fn with_cell(text: &str, n: usize, col: usize, value: &str) -> String {
    with_line(text, n, |l| {
        let mut cells: Vec<&str> = l.trim_end().split(',').collect();
        cells[col] = value;
        format!("{}\n", cells.join(","))
    })
}

#[test]
fn an_export_in_chunks_is_the_export_read_whole() {
    let dir = tempfile::tempdir().unwrap();
    let plain = rig_export(dir.path());
    let rows = plain.lines().count();
    assert!(rows > 10_000, "{rows}");

    let read = same_in_chunks(dir.path(), "plain.csv", plain.as_bytes());
    assert!(read.starts_with("CsvImport"), "{}", &read[..200]);

    let crlf_bom = format!("\u{feff}{}", plain.replace('\n', "\r\n"));
    let read = same_in_chunks(dir.path(), "crlf_bom.csv", crlf_bom.as_bytes());
    assert!(read.contains("CRLF line ends"), "{}", &read[..200]);

    // Semicolons, decimal commas and a units row, the last line cut inside its last cell.
    let units = "s;-;Hz;m;m;m/s^2;m;m/s^2\n";
    let lab = plain.replace(',', ";").replace('.', ",");
    let lab = with_line(&lab, 1, |h| format!("{h}{units}"));
    let cut = lab.trim_end();
    let lab = format!("{};1e", &cut[..cut.rfind(';').unwrap()]);
    let read = same_in_chunks(dir.path(), "lab.csv", lab.as_bytes());
    assert!(
        read.contains("skipped a truncated last line"),
        "{read:.300}"
    );

    // The last line with too few fields, then blank lines.
    let short = format!("{plain}0.5,1\n\n\r\n\n");
    let read = same_in_chunks(dir.path(), "short_last.csv", short.as_bytes());
    assert!(read.contains("2 of 8 fields"), "{read:.300}");

    // A quoted cell half-way: the `csv` crate reads from there.
    let quoted = with_line(&plain, rows / 2, |l| {
        let (time, rest) = l.split_once(',').unwrap();
        format!("\"{time}\",{rest}")
    });
    assert_eq!(
        same_in_chunks(dir.path(), "quoted.csv", quoted.as_bytes()),
        same_in_chunks(dir.path(), "plain_again.csv", plain.as_bytes())
    );

    // Blank lines between rows (the `csv` crate's line count goes on over them).
    let blank = with_line(&plain, rows / 3, |l| format!("\n\n{l}"));
    same_in_chunks(dir.path(), "blank.csv", blank.as_bytes());
}

#[test]
fn a_late_fault_is_the_same_error_on_the_same_line() {
    let dir = tempfile::tempdir().unwrap();
    let plain = rig_export(dir.path());
    let rows = plain.lines().count();
    let late = rows - 100;
    let cases: [(&str, String); 5] = [
        (
            "non_numeric",
            with_line(&plain, late, |l| l.replacen(',', ",x", 3)),
        ),
        (
            "missing_field",
            with_line(&plain, late, |l| l.replacen(',', "", 1)),
        ),
        ("non_finite", with_cell(&plain, late, 4, "NaN")),
        (
            "time_back",
            with_line(&plain, late, |l| format!("0{}", &l[l.find(',').unwrap()..])),
        ),
        (
            "crlf_quoted_then_short",
            with_line(&plain.replace('\n', "\r\n"), late, |_| {
                "\"1\",2\r\n".to_string()
            }),
        ),
    ];
    for (name, text) in &cases {
        let read = same_in_chunks(dir.path(), &format!("{name}.csv"), text.as_bytes());
        assert!(read.starts_with("error: "), "{name}: {read:.200}");
    }
    // Invalid UTF-8 in a late row.
    let mut bytes = plain.into_bytes();
    let at = (0..bytes.len() - 500)
        .rev()
        .find(|&i| bytes[i].is_ascii_digit())
        .unwrap();
    bytes[at] = 0xff;
    let read = same_in_chunks(dir.path(), "utf8.csv", &bytes);
    assert!(read.contains("invalid UTF-8"), "{read:.200}");
}
