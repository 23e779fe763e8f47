//! The errors of reading and writing the CSV contract.

use std::io;
use std::path::{Path, PathBuf};

use forcemap_math::recipe::SetupKind;
use forcemap_math::record::Channel;

use super::contract::required_columns;

/// Errors of [`read_csv`](super::read_csv) and [`write_csv`](super::write_csv). Line numbers are 1-based lines of the CSV file,
/// the header being line 1.
#[derive(Debug, thiserror::Error)]
pub enum CsvError {
    #[error("{}: {action}: {source}", path.display())]
    Io {
        path: PathBuf,
        action: &'static str,
        #[source]
        source: io::Error,
    },
    #[error("{}: malformed CSV{}: {message}", path.display(), fmt_line(*line))]
    Malformed {
        path: PathBuf,
        line: Option<u64>,
        message: String,
    },
    #[error("{}: the file is empty (expected a header row naming the columns)", path.display())]
    Empty { path: PathBuf },
    #[error("{}: the file has a header (line 1) but no data rows", path.display())]
    HeaderOnly { path: PathBuf },
    #[error("{}: line 1: column '{column}' appears more than once in the header", path.display())]
    DuplicateColumn { path: PathBuf, column: String },
    #[error(
        "{}: line 1: missing required column(s) {}{}; the rig profile requires [{}]{}, the \
         drive-point profile requires [{}]{}, the element profile requires [{}]",
        path.display(),
        missing.join(", "),
        match profile { Some(p) => format!(" for the {p} profile"), None => String::new() },
        required_columns(SetupKind::BaseExcited).join(", "),
        fmt_missing(missing_rig),
        required_columns(SetupKind::DrivePoint).join(", "),
        fmt_missing(missing_drive_point),
        required_columns(SetupKind::Element).join(", "),
    )]
    MissingColumns {
        path: PathBuf,
        /// The profile chosen from the header, if any.
        profile: Option<SetupKind>,
        /// Missing columns of the chosen profile, or of both profiles (union) if none.
        missing: Vec<String>,
        missing_rig: Vec<String>,
        missing_drive_point: Vec<String>,
    },
    #[error(
        "{}: rows {first_s:.3}-{last_s:.3} s (the whole file, no step or frequency_hz column): {message}",
        path.display()
    )]
    Unlabelled {
        path: PathBuf,
        first_s: f64,
        last_s: f64,
        message: String,
    },
    #[error(
        "{}: line 2, column '{column}': the units row gives '{unit}' where the contract's SI \
         unit is '{expected}' (forcemap does not scale; export in SI units)",
        path.display()
    )]
    WrongUnit {
        path: PathBuf,
        column: String,
        unit: String,
        expected: &'static str,
    },
    #[error("{}: line {line}, column '{column}': cell '{cell}' is not a number", path.display())]
    NonNumeric {
        path: PathBuf,
        line: u64,
        column: String,
        cell: String,
    },
    #[error("{}: line {line}, column '{column}': empty cell (a number is required)", path.display())]
    EmptyCell {
        path: PathBuf,
        line: u64,
        column: String,
    },
    #[error("{}: line {line}, column '{column}': '{cell}' is not finite (NaN or infinite)", path.display())]
    NonFinite {
        path: PathBuf,
        line: u64,
        column: String,
        cell: String,
    },
    #[error("{}: line {line}, column '{column}': invalid value '{cell}': {reason}", path.display())]
    InvalidValue {
        path: PathBuf,
        line: u64,
        column: String,
        cell: String,
        reason: &'static str,
    },
    #[error("{}: line {line}, column '{column}': '{cell}': {reason}", path.display())]
    BadMultisineCell {
        path: PathBuf,
        line: u64,
        column: &'static str,
        cell: String,
        reason: String,
    },
    #[error("{}: line {line}, column '{column}': '{cell}': {reason}", path.display())]
    BadSweepCell {
        path: PathBuf,
        line: u64,
        column: &'static str,
        cell: String,
        reason: String,
    },
    #[error(
        "{}: line {line}, columns 'sweep_law'/'sweep_start_hz'/'sweep_end_hz': the sweep of \
         step {step} changes inside the step ({change})",
        path.display()
    )]
    SweepChanged {
        path: PathBuf,
        step: usize,
        first_line: u64,
        line: u64,
        /// What the step's first line has and what this line has.
        change: String,
    },
    #[error(
        "{}: line {line}, columns 'multisine_base_hz'/'multisine_lines': the multisine of \
         step {step} changes inside the step ({change})",
        path.display()
    )]
    MultisineChanged {
        path: PathBuf,
        step: usize,
        first_line: u64,
        line: u64,
        /// What the step's first line has and what this line has.
        change: String,
    },
    #[error(
        "{}: line {line}, column 'time_s': time {time} s does not increase \
         (line {prev_line} has {prev_time} s)",
        path.display()
    )]
    TimeNotIncreasing {
        path: PathBuf,
        prev_line: u64,
        line: u64,
        prev_time: f64,
        time: f64,
    },
    #[error(
        "{}: line {line}, column 'step': step {step} follows step {prev_step} (line {prev_line}); \
         steps must be contiguous and increasing (expected {prev_step} or {})",
        path.display(),
        prev_step + 1
    )]
    StepNotContiguous {
        path: PathBuf,
        prev_line: u64,
        line: u64,
        prev_step: usize,
        step: usize,
    },
    #[error(
        "{}: line {line}, column 'frequency_hz': frequency {} changes inside step {step} \
         (line {first_line} has {})",
        path.display(), fmt_freq(*found), fmt_freq(*first)
    )]
    FrequencyChanged {
        path: PathBuf,
        step: usize,
        first_line: u64,
        line: u64,
        /// `None` stands for random excitation (0 or empty).
        first: Option<f64>,
        found: Option<f64>,
    },
    #[error(
        "{}: line {line}, column 'time_s': non-uniform sampling in step {step}: interval \
         {} s from line {prev_line} where the rows around are {} s apart (a duplicated row, or \
         a time off its sample by more than a tenth of an interval: correct or remove the row; \
         a pause or lost rows only end a record)",
        path.display(), fmt_sig(*interval), fmt_sig(*expected)
    )]
    NonUniformSampling {
        path: PathBuf,
        step: usize,
        prev_line: u64,
        line: u64,
        interval: f64,
        expected: f64,
    },
    #[error(
        "{}: line {first_line}, column 'step': step {step} has only {rows} row(s); at least 3 \
         are required",
        path.display()
    )]
    TooFewRows {
        path: PathBuf,
        step: usize,
        first_line: u64,
        rows: usize,
    },
    #[error(
        "{}: refusing to write: record {record} (step {step}), channel '{}', sample {index} is \
         {value} (not finite); nothing was written",
        path.display(), channel.name()
    )]
    NonFiniteSample {
        path: PathBuf,
        record: usize,
        step: usize,
        channel: Channel,
        index: usize,
        value: f64,
    },
    #[error("{}: refusing to write: {reason}; nothing was written", path.display())]
    InvalidRecords { path: PathBuf, reason: String },
}

fn fmt_line(line: Option<u64>) -> String {
    line.map_or(String::new(), |l| format!(" at line {l}"))
}

fn fmt_missing(missing: &[String]) -> String {
    if missing.is_empty() {
        " (all present)".to_string()
    } else {
        format!(" (missing {})", missing.join(", "))
    }
}

/// 10 significant digits, for messages (the variant keeps the exact value).
fn fmt_sig(x: f64) -> String {
    format!("{x:.9e}")
        .parse::<f64>()
        .map_or_else(|_| x.to_string(), |v| v.to_string())
}

fn fmt_freq(f: Option<f64>) -> String {
    f.map_or("random (0 or empty)".to_string(), |f| format!("{f} Hz"))
}

/// A `csv` crate error as a [`CsvError`] of `path`.
pub(super) fn csv_error(path: &Path, e: csv::Error) -> CsvError {
    let line = e.position().map(csv::Position::line);
    match e.into_kind() {
        csv::ErrorKind::Io(source) => CsvError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        },
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => CsvError::Malformed {
            path: path.to_path_buf(),
            line,
            message: format!("the row has {len} field(s) but the header has {expected_len}"),
        },
        csv::ErrorKind::Utf8 { err, .. } => CsvError::Malformed {
            path: path.to_path_buf(),
            line,
            message: format!("invalid UTF-8 in field {}", err.field() + 1),
        },
        other => CsvError::Malformed {
            path: path.to_path_buf(),
            line,
            message: format!("{other:?}"),
        },
    }
}
