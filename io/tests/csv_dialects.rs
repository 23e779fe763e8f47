//! The CSV dialects of lab exports read as the plain contract, and what stays an error: a
//! malformed line that is not the last, a unit that is not the contract's SI unit.
#![allow(
    clippy::unwrap_used,
    reason = "test helpers outside #[test] fns: a panic is how a test reports failure"
)]

use forcemap_io::csv_export::{CsvImport, read_csv, write_csv};
use forcemap_math::recipe::SetupKind;
use forcemap_math::sim::RunSpec;

const FILE: &str = "lab_run.csv";

/// The plain export of a short simulated rig run, as text.
fn plain_text(dir: &std::path::Path) -> String {
    let records = RunSpec::paper_rig_sine(Some(40.0), 5).simulate().unwrap();
    let path = dir.join("plain.csv");
    write_csv(&path, &records[..2], SetupKind::BaseExcited).unwrap();
    std::fs::read_to_string(path).unwrap()
}

fn read_text(dir: &std::path::Path, text: &str) -> Result<CsvImport, String> {
    let path = dir.join(FILE);
    std::fs::write(&path, text).unwrap();
    read_csv(&path).map_err(|e| e.to_string())
}

#[test]
fn tab_separated_with_a_truncated_last_line_reads_as_the_plain_file() {
    let dir = tempfile::tempdir().unwrap();
    let plain = plain_text(dir.path());
    let reference = read_text(dir.path(), &plain).unwrap();
    assert!(reference.notices.is_empty(), "{:?}", reference.notices);

    let lines: Vec<&str> = plain.lines().collect();
    let mut tab: String = lines.iter().map(|l| l.replace(',', "\t") + "\n").collect();
    // The recording stopped inside the next line's fourth cell.
    tab.push_str("99.5\t1\t3.2\t0.00");
    let lab = read_text(dir.path(), &tab).unwrap();
    assert_eq!(lab.records, reference.records);
    let notices = lab.notices.join("\n");
    assert!(notices.contains("tab separators"), "{notices}");
    assert!(
        notices.contains(&format!(
            "{FILE}: line {}: skipped a truncated last line (4 of 8 fields",
            lines.len() + 1
        )),
        "{notices}"
    );
}

#[test]
fn a_short_line_that_is_not_the_last_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let plain = plain_text(dir.path());
    let mut lines: Vec<String> = plain.lines().map(str::to_string).collect();
    lines[10] = lines[10].rsplit_once(',').unwrap().0.to_string();
    let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
    let e = read_text(dir.path(), &text).unwrap_err();
    assert!(
        e.contains(FILE) && e.contains("line 11") && e.contains("7 field(s)"),
        "{e}"
    );
}

#[test]
fn semicolons_with_decimal_points_and_a_thousands_separator() {
    let dir = tempfile::tempdir().unwrap();
    let plain = plain_text(dir.path());
    let reference = read_text(dir.path(), &plain).unwrap();
    // `;` with decimal points (no comma in any number): read as the plain file.
    let semi = plain.replace(',', ";");
    let lab = read_text(dir.path(), &semi).unwrap();
    assert_eq!(lab.records, reference.records);
    assert!(lab.notices[0].contains("semicolon separators"));
    assert!(!lab.notices[0].contains("decimal commas"));
    // Decimal commas with a thousands point in one cell: that cell's line is named.
    let mut lines: Vec<String> = plain
        .lines()
        .map(|l| l.replace(',', ";").replace('.', ","))
        .collect();
    lines[7] = format!("1.{}", lines[7]);
    let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
    let e = read_text(dir.path(), &text).unwrap_err();
    assert!(e.contains("line 8") && e.contains("is not a number"), "{e}");
}

#[test]
fn a_units_row_in_other_units_is_refused_naming_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let plain = plain_text(dir.path());
    let (header, rest) = plain.split_once('\n').unwrap();
    assert_eq!(
        header,
        "time_s,step,frequency_hz,base_displacement_m,relative_displacement_m,\
         mass_acceleration_mps2,mass_displacement_m,base_acceleration_mps2"
    );
    let ok = format!("{header}\n[s],-,[Hz],m,m,m/s²,m,m/s2\n{rest}");
    let lab = read_text(dir.path(), &ok).unwrap();
    assert_eq!(lab.records, read_text(dir.path(), &plain).unwrap().records);
    let mm = format!("{header}\ns,-,Hz,mm,m,m/s^2,m,m/s^2\n{rest}");
    let e = read_text(dir.path(), &mm).unwrap_err();
    assert!(
        e.contains("line 2") && e.contains("'base_displacement_m'") && e.contains("'mm'"),
        "{e}"
    );
}
