//! Test-bench CSV export: the form in which rig data usually leaves a DAQ.
//!
//! # Contract
//!
//! A header row names the columns; all values are SI. Every data row is one sample.
//!
//! * Always required: `time_s`, `step` (record index 0, 1, 2, ...) and `frequency_hz`
//!   (excitation frequency of a stepped-sine step; `0` or empty for random excitation).
//! * [`SetupKind::BaseExcited`] (base-excited test rig) additionally requires
//!   `base_displacement_m`, `relative_displacement_m`, `mass_acceleration_mps2`.
//! * [`SetupKind::DrivePoint`] (force-driven structure, the 3-DOF example) additionally
//!   requires `relative_displacement_m`, `drive_point_displacement_m`, `force_n`.
//! * Any other [`Channel::name`] column is optional and read when present. Every cell of a
//!   present channel column must hold a finite number.
//! * Columns with other names are ignored and returned in [`CsvImport::ignored_columns`].
//!
//! The profile is decided from the header: rig if `base_displacement_m` is present,
//! drive-point if `force_n` and `drive_point_displacement_m` are present.
//!
//! Rows are grouped into records by `step`. A step's rows start when the excitation changed,
//! so they include the transient. Steps must be contiguous (each new step is the previous one
//! plus one; the first may be any non-negative integer) and each step must have at least 3
//! rows. Time must increase strictly over the whole file (it counts from the start of the
//! run). The sampling must be uniform within a step, and all steps must have the same sample
//! rate; the tolerance is 1e-6 relative plus the rounding of the time column when the file
//! writes time with a fixed number of decimals (e.g. `0.000100`).
//!
//! The excitation amplitude is not part of the export, so it is *estimated* on import: for a
//! sine step, `amplitude = sqrt(2) * RMS` of the driven channel (base displacement for the rig,
//! force for the drive-point profile) over the whole step after removing its mean; for a
//! random record, `rms` is the RMS of the driven channel after removing its mean. Both include
//! the transient at the start of the step, so they are estimates, not the commanded values.
//!
//! [`write_csv`] writes the same contract, with full f64 precision (shortest round-trip
//! formatting), atomically (temporary file in the same directory, renamed at the end).

use std::collections::HashMap;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Excitation, Record};

/// Column names of the fixed (non-channel) columns.
pub const TIME_COLUMN: &str = "time_s";
pub const STEP_COLUMN: &str = "step";
pub const FREQUENCY_COLUMN: &str = "frequency_hz";

/// Relative tolerance on the sampling interval (uniformity and consistency across steps).
pub const SAMPLE_INTERVAL_REL_TOL: f64 = 1e-6;

/// The columns an export of `kind` requires, fixed columns first. Which kind of test an
/// export describes (and so its driven channel) is `SetupKind`'s rule, from its channels.
pub fn required_columns(kind: SetupKind) -> Vec<&'static str> {
    let mut v = vec![TIME_COLUMN, STEP_COLUMN, FREQUENCY_COLUMN];
    v.extend(kind.required_channels().iter().map(|c| c.name()));
    v
}

/// The result of [`read_csv`].
#[derive(Debug, Clone, PartialEq)]
pub struct CsvImport {
    /// One record per step, in file order. Channels are in [`Channel::ALL`] order.
    pub records: Vec<Record>,
    /// Header names that are not part of the contract and were ignored (header order).
    /// The caller decides whether and how to tell the user.
    pub ignored_columns: Vec<String>,
    pub kind: SetupKind,
}

/// Errors of [`read_csv`] and [`write_csv`]. Line numbers are 1-based lines of the CSV file,
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
         drive-point profile requires [{}]{}",
        path.display(),
        missing.join(", "),
        match profile { Some(p) => format!(" for the {p} profile"), None => String::new() },
        required_columns(SetupKind::BaseExcited).join(", "),
        fmt_missing(missing_rig),
        required_columns(SetupKind::DrivePoint).join(", "),
        fmt_missing(missing_drive_point),
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
         {} s from line {prev_line} differs from the step's typical interval {} s",
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
        "{}: lines {first_line}-{last_line}, column 'time_s': step {step} is sampled at \
         {} Hz but step {reference_step} (from line {reference_line}) at {} Hz; all steps \
         must have the same sample rate",
        path.display(), fmt_sig(*rate_hz), fmt_sig(*reference_rate_hz)
    )]
    InconsistentSampleRate {
        path: PathBuf,
        step: usize,
        first_line: u64,
        last_line: u64,
        rate_hz: f64,
        reference_step: usize,
        reference_line: u64,
        reference_rate_hz: f64,
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
    format!("{:.9e}", x)
        .parse::<f64>()
        .map_or_else(|_| x.to_string(), |v| v.to_string())
}

fn fmt_freq(f: Option<f64>) -> String {
    f.map_or("random (0 or empty)".to_string(), |f| format!("{f} Hz"))
}

// ---------------------------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------------------------

/// Reads a test-bench CSV export (see the module documentation for the contract).
pub fn read_csv(path: impl AsRef<Path>) -> Result<CsvImport, CsvError> {
    let path = path.as_ref();
    let file = File::open(path).map_err(|source| CsvError::Io {
        path: path.to_path_buf(),
        action: "cannot open for reading",
        source,
    })?;
    read_csv_from(io::BufReader::new(file), path)
}

/// Reads the CSV contract from any reader; `path` is used in error messages only.
pub fn read_csv_from<R: io::Read>(reader: R, path: &Path) -> Result<CsvImport, CsvError> {
    let p = || path.to_path_buf();
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::All)
        .flexible(false)
        .from_reader(reader);
    let header = rdr.headers().map_err(|e| csv_error(path, e))?.clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        return Err(CsvError::Empty { path: p() });
    }

    // Column layout.
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, name) in header.iter().enumerate() {
        if index.insert(name, i).is_some() {
            return Err(CsvError::DuplicateColumn {
                path: p(),
                column: name.to_string(),
            });
        }
    }
    let missing_for = |profile: SetupKind| -> Vec<String> {
        required_columns(profile)
            .into_iter()
            .filter(|c| !index.contains_key(c))
            .map(str::to_string)
            .collect()
    };
    let missing_rig = missing_for(SetupKind::BaseExcited);
    let missing_dp = missing_for(SetupKind::DrivePoint);
    let has = |c: Channel| index.contains_key(c.name());
    let profile = if has(Channel::BaseDisplacementM) {
        Some(SetupKind::BaseExcited)
    } else if has(Channel::ForceN) && has(Channel::DrivePointDisplacementM) {
        Some(SetupKind::DrivePoint)
    } else {
        None
    };
    let missing = match profile {
        Some(SetupKind::BaseExcited) => missing_rig.clone(),
        Some(SetupKind::DrivePoint) => missing_dp.clone(),
        None => {
            let mut all = missing_rig.clone();
            all.extend(
                missing_dp
                    .iter()
                    .filter(|c| !missing_rig.contains(c))
                    .cloned(),
            );
            all
        }
    };
    let profile = match profile {
        Some(p) if missing.is_empty() => p,
        _ => {
            return Err(CsvError::MissingColumns {
                path: p(),
                profile,
                missing,
                missing_rig,
                missing_drive_point: missing_dp,
            });
        }
    };
    let time_col = index[TIME_COLUMN];
    let step_col = index[STEP_COLUMN];
    let freq_col = index[FREQUENCY_COLUMN];
    let channel_cols: Vec<(Channel, usize)> = Channel::ALL
        .into_iter()
        .filter_map(|c| index.get(c.name()).map(|&i| (c, i)))
        .collect();
    let known = |name: &str| {
        name == TIME_COLUMN
            || name == STEP_COLUMN
            || name == FREQUENCY_COLUMN
            || Channel::from_name(name).is_some()
    };
    let ignored_columns: Vec<String> = header
        .iter()
        .filter(|n| !known(n))
        .map(str::to_string)
        .collect();

    // Rows.
    let mut steps: Vec<StepData> = Vec::new();
    let mut current: Option<StepData> = None;
    let mut prev_time: Option<(f64, u64)> = None;
    let mut row = csv::StringRecord::new();
    loop {
        match rdr.read_record(&mut row) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(csv_error(path, e)),
        }
        let line = row.position().map_or(0, |pos| pos.line());
        let cell = |col: usize| row.get(col).unwrap_or("");
        let col_name = |col: usize| header.get(col).unwrap_or("").to_string();

        let time_text = cell(time_col);
        let time = parse_number(path, line, TIME_COLUMN, time_text)?;
        let step = parse_step(path, line, cell(step_col))?;
        let freq_text = cell(freq_col);
        let freq = if freq_text.is_empty() {
            None
        } else {
            let f = parse_number(path, line, FREQUENCY_COLUMN, freq_text)?;
            if f < 0.0 {
                return Err(CsvError::InvalidValue {
                    path: p(),
                    line,
                    column: FREQUENCY_COLUMN.to_string(),
                    cell: freq_text.to_string(),
                    reason: "a frequency must not be negative",
                });
            }
            (f != 0.0).then_some(f)
        };

        if let Some((t0, l0)) = prev_time
            && time <= t0
        {
            return Err(CsvError::TimeNotIncreasing {
                path: p(),
                prev_line: l0,
                line,
                prev_time: t0,
                time,
            });
        }
        prev_time = Some((time, line));

        let start_new = match &current {
            None => true,
            Some(cur) if cur.step == step => false,
            Some(cur) if step == cur.step + 1 => true,
            Some(cur) => {
                return Err(CsvError::StepNotContiguous {
                    path: p(),
                    prev_line: cur.last_line(),
                    line,
                    prev_step: cur.step,
                    step,
                });
            }
        };
        if start_new {
            if let Some(done) = current.take() {
                done.check(path)?;
                steps.push(done);
            }
            current = Some(StepData {
                step,
                frequency: freq,
                lines: Vec::new(),
                times: Vec::new(),
                time_resolution: f64::INFINITY,
                channels: channel_cols.iter().map(|&(c, _)| (c, Vec::new())).collect(),
            });
        }
        let cur = current.as_mut().expect("current step exists");
        if cur.frequency != freq {
            return Err(CsvError::FrequencyChanged {
                path: p(),
                step,
                first_line: cur.lines[0],
                line,
                first: cur.frequency,
                found: freq,
            });
        }
        for (k, &(_, col)) in channel_cols.iter().enumerate() {
            let v = parse_number(path, line, &col_name(col), cell(col))?;
            cur.channels[k].1.push(v);
        }
        cur.lines.push(line);
        cur.times.push(time);
        cur.time_resolution = cur.time_resolution.min(decimal_resolution(time_text));
    }
    match current {
        Some(done) => {
            done.check(path)?;
            steps.push(done);
        }
        None => return Err(CsvError::HeaderOnly { path: p() }),
    }

    // Sample rate: consistent across steps, one value for the file.
    let reference = &steps[0];
    let (ref_rate, ref_rel_unc) = reference.rate();
    let mut intervals = 0.0;
    let mut elapsed = 0.0;
    let mut res_sum = 0.0;
    for s in &steps {
        let (rate, rel_unc) = s.rate();
        let tol = SAMPLE_INTERVAL_REL_TOL + rel_unc + ref_rel_unc;
        if (rate - ref_rate).abs() > tol * ref_rate {
            return Err(CsvError::InconsistentSampleRate {
                path: p(),
                step: s.step,
                first_line: s.lines[0],
                last_line: s.last_line(),
                rate_hz: rate,
                reference_step: reference.step,
                reference_line: reference.lines[0],
                reference_rate_hz: ref_rate,
            });
        }
        intervals += (s.times.len() - 1) as f64;
        elapsed += s.elapsed();
        res_sum += s.resolution_for_rate();
    }
    let mut sample_rate_hz = intervals / elapsed;
    // Snap to an integer rate when it is within the uncertainty of the estimate.
    let snapped = sample_rate_hz.round();
    let rel_unc = res_sum / elapsed + 1e-9;
    if snapped > 0.0 && (sample_rate_hz - snapped).abs() <= rel_unc * sample_rate_hz {
        sample_rate_hz = snapped;
    }

    let driven = profile.driven_channel();
    let records = steps
        .into_iter()
        .map(|s| {
            let level = {
                let x = &s
                    .channels
                    .iter()
                    .find(|(c, _)| *c == driven)
                    .expect("driven")
                    .1;
                rms_about_mean(x)
            };
            let excitation = match s.frequency {
                Some(frequency_hz) => Excitation::Sine {
                    frequency_hz,
                    amplitude: std::f64::consts::SQRT_2 * level,
                },
                None => Excitation::Random {
                    band_hz: None,
                    rms: level,
                },
            };
            Record {
                step: s.step,
                excitation,
                sample_rate_hz,
                start_time_s: s.times[0],
                channels: s.channels,
            }
        })
        .collect();
    Ok(CsvImport {
        records,
        ignored_columns,
        kind: profile,
    })
}

/// Rows of one step while reading.
struct StepData {
    step: usize,
    frequency: Option<f64>,
    lines: Vec<u64>,
    times: Vec<f64>,
    /// Finest decimal resolution of the time cells of this step.
    time_resolution: f64,
    channels: Vec<(Channel, Vec<f64>)>,
}

impl StepData {
    fn last_line(&self) -> u64 {
        *self.lines.last().unwrap_or(&0)
    }

    fn elapsed(&self) -> f64 {
        self.times[self.times.len() - 1] - self.times[0]
    }

    fn mean_interval(&self) -> f64 {
        self.elapsed() / (self.times.len() - 1) as f64
    }

    /// Rounding of the time column plus f64 rounding at this magnitude. The decimal
    /// resolution is capped at a quarter interval: shortest round-trip output of "nice" times
    /// (`0.001`, `0.002`, ...) looks coarse but is exact, and a missing sample must still be
    /// caught.
    fn resolution_for_rate(&self) -> f64 {
        let t_max = self.times[self.times.len() - 1]
            .abs()
            .max(self.times[0].abs());
        self.time_resolution.min(0.25 * self.mean_interval()) + 4.0 * f64::EPSILON * t_max
    }

    /// Sample rate and its relative uncertainty from the rounding of the time column.
    fn rate(&self) -> (f64, f64) {
        let elapsed = self.elapsed();
        (
            (self.times.len() - 1) as f64 / elapsed,
            self.resolution_for_rate() / elapsed,
        )
    }

    /// At least 3 rows, uniform sampling.
    fn check(&self, path: &Path) -> Result<(), CsvError> {
        let n = self.times.len();
        if n < 3 {
            return Err(CsvError::TooFewRows {
                path: path.to_path_buf(),
                step: self.step,
                first_line: self.lines[0],
                rows: n,
            });
        }
        // Compare each interval with the median one, so the report points at the odd
        // interval (a dropped sample), not at the first interval after it skews the mean.
        let dts: Vec<f64> = self.times.windows(2).map(|w| w[1] - w[0]).collect();
        let mut sorted = dts.clone();
        sorted.sort_by(f64::total_cmp);
        let typical = sorted[sorted.len() / 2];
        let tol = SAMPLE_INTERVAL_REL_TOL * typical + self.resolution_for_rate();
        for (i, &dt) in dts.iter().enumerate() {
            if (dt - typical).abs() > tol {
                return Err(CsvError::NonUniformSampling {
                    path: path.to_path_buf(),
                    step: self.step,
                    prev_line: self.lines[i],
                    line: self.lines[i + 1],
                    interval: dt,
                    expected: typical,
                });
            }
        }
        Ok(())
    }
}

fn csv_error(path: &Path, e: csv::Error) -> CsvError {
    let line = e.position().map(|p| p.line());
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

fn parse_number(path: &Path, line: u64, column: &str, cell: &str) -> Result<f64, CsvError> {
    if cell.is_empty() {
        return Err(CsvError::EmptyCell {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
        });
    }
    let v: f64 = cell.parse().map_err(|_| CsvError::NonNumeric {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        cell: cell.to_string(),
    })?;
    if !v.is_finite() {
        return Err(CsvError::NonFinite {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
            cell: cell.to_string(),
        });
    }
    Ok(v)
}

/// A step index: a non-negative integer (an integral float such as `3.0` is accepted).
fn parse_step(path: &Path, line: u64, cell: &str) -> Result<usize, CsvError> {
    if let Ok(s) = cell.parse::<usize>() {
        return Ok(s);
    }
    let v = parse_number(path, line, STEP_COLUMN, cell)?;
    if v >= 0.0 && v.fract() == 0.0 && v <= u32::MAX as f64 {
        Ok(v as usize)
    } else {
        Err(CsvError::InvalidValue {
            path: path.to_path_buf(),
            line,
            column: STEP_COLUMN.to_string(),
            cell: cell.to_string(),
            reason: "a step index must be a non-negative integer",
        })
    }
}

/// The decimal resolution a number was written with: `0.000100` -> 1e-6, `1.5e-3` -> 1e-4.
fn decimal_resolution(text: &str) -> f64 {
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(i) => (&text[..i], text[i + 1..].parse::<i32>().unwrap_or(0)),
        None => (text, 0),
    };
    let decimals = mantissa.find('.').map_or(0, |i| {
        mantissa[i + 1..]
            .chars()
            .filter(char::is_ascii_digit)
            .count()
    });
    10f64.powi(exponent - decimals as i32)
}

fn rms_about_mean(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    (x.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt()
}

// ---------------------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------------------

/// Writes `records` in the CSV contract of this module for `profile`, atomically.
///
/// Columns: `time_s, step, frequency_hz`, then every channel of the records in
/// [`Channel::ALL`] order. Time of sample `i` is [`Record::time_s`]; random records write
/// frequency `0`. Numbers use Rust's shortest round-trip formatting, so reading the file back
/// gives the same f64 values bit for bit.
///
/// Everything is checked before the file system is touched (all records with the same
/// channels, the profile's channels present, at least 3 finite samples per channel, the same
/// positive sample rate, contiguous steps, increasing time, sine frequencies finite and
/// positive). The data go to a temporary file in the target directory which is renamed over
/// `path` at the end; on any error the temporary file is removed and `path` is untouched.
pub fn write_csv(
    path: impl AsRef<Path>,
    records: &[Record],
    profile: SetupKind,
) -> Result<(), CsvError> {
    let path = path.as_ref();
    let channels = validate_for_write(path, records, profile)?;

    let mut tmp = TempFile::create(path)?;
    let io_err = |source: io::Error| CsvError::Io {
        path: path.to_path_buf(),
        action: "cannot write",
        source,
    };
    {
        let file = tmp.file.take().expect("temporary file is open");
        let mut wtr = csv::WriterBuilder::new().from_writer(BufWriter::new(file));
        let mut header = vec![TIME_COLUMN, STEP_COLUMN, FREQUENCY_COLUMN];
        header.extend(channels.iter().map(|c| c.name()));
        wtr.write_record(&header).map_err(|e| csv_error(path, e))?;
        let mut fields: Vec<String> = Vec::with_capacity(header.len());
        for r in records {
            let step = r.step.to_string();
            let freq = match r.excitation {
                Excitation::Sine { frequency_hz, .. } => fmt_f64(frequency_hz),
                Excitation::Random { .. } => "0".to_string(),
            };
            let samples: Vec<&[f64]> = channels
                .iter()
                .map(|&c| r.channel(c).expect("validated"))
                .collect();
            for i in 0..r.len() {
                fields.clear();
                fields.push(fmt_f64(r.time_s(i)));
                fields.push(step.clone());
                fields.push(freq.clone());
                fields.extend(samples.iter().map(|x| fmt_f64(x[i])));
                wtr.write_record(&fields).map_err(|e| csv_error(path, e))?;
            }
        }
        let buf = wtr
            .into_inner()
            .map_err(|e| io_err(io::Error::other(e.to_string())))?;
        let file = buf.into_inner().map_err(|e| io_err(e.into_error()))?;
        file.sync_all().map_err(io_err)?;
    }
    tmp.persist()
}

/// Channels to write, in [`Channel::ALL`] order, after checking the records.
fn validate_for_write(
    path: &Path,
    records: &[Record],
    profile: SetupKind,
) -> Result<Vec<Channel>, CsvError> {
    let bad = |reason: String| CsvError::InvalidRecords {
        path: path.to_path_buf(),
        reason,
    };
    let Some(first) = records.first() else {
        return Err(bad("there are no records".into()));
    };
    let channels: Vec<Channel> = Channel::ALL
        .into_iter()
        .filter(|&c| first.channel(c).is_some())
        .collect();
    for c in profile.required_channels() {
        if !channels.contains(&c) {
            return Err(bad(format!(
                "the {profile} profile requires channel '{}', which record 0 (step {}) lacks",
                c.name(),
                first.step
            )));
        }
    }
    if profile == SetupKind::DrivePoint && channels.contains(&Channel::BaseDisplacementM) {
        return Err(bad(format!(
            "the records carry '{}', which would make the file read back as the rig profile; \
             write them with the rig profile or drop that channel",
            Channel::BaseDisplacementM.name()
        )));
    }
    let rate = first.sample_rate_hz;
    let mut prev_time: Option<f64> = None;
    for (k, r) in records.iter().enumerate() {
        let what = format!("record {k} (step {})", r.step);
        if r.step != first.step + k {
            return Err(bad(format!(
                "{what}: steps must be contiguous, expected step {}",
                first.step + k
            )));
        }
        let mut seen: Vec<Channel> = r.channels.iter().map(|(c, _)| *c).collect();
        seen.sort();
        if seen.windows(2).any(|w| w[0] == w[1]) {
            return Err(bad(format!("{what}: a channel appears twice")));
        }
        if seen != channels {
            let names = |v: &[Channel]| v.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ");
            return Err(bad(format!(
                "{what} has channels [{}] but record 0 has [{}]; all records must have the same \
                 channels",
                names(&seen),
                names(&channels)
            )));
        }
        let n = r.len();
        if n < 3 {
            return Err(bad(format!(
                "{what} has {n} sample(s); at least 3 are required"
            )));
        }
        for (c, x) in &r.channels {
            if x.len() != n {
                return Err(bad(format!(
                    "{what}: channel '{}' has {} samples but '{}' has {n}",
                    c.name(),
                    x.len(),
                    r.channels[0].0.name()
                )));
            }
        }
        for &c in &channels {
            let x = r.channel(c).expect("present");
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(CsvError::NonFiniteSample {
                    path: path.to_path_buf(),
                    record: k,
                    step: r.step,
                    channel: c,
                    index: i,
                    value: x[i],
                });
            }
        }
        if !(r.sample_rate_hz.is_finite() && r.sample_rate_hz > 0.0) {
            return Err(bad(format!(
                "{what}: sample rate {} Hz is not a positive number",
                r.sample_rate_hz
            )));
        }
        if (r.sample_rate_hz - rate).abs() > SAMPLE_INTERVAL_REL_TOL * rate {
            return Err(bad(format!(
                "{what}: sample rate {} Hz differs from record 0's {rate} Hz",
                r.sample_rate_hz
            )));
        }
        if !r.start_time_s.is_finite() {
            return Err(bad(format!(
                "{what}: start time {} is not finite",
                r.start_time_s
            )));
        }
        match r.excitation {
            Excitation::Sine { frequency_hz, .. } => {
                if !(frequency_hz.is_finite() && frequency_hz > 0.0) {
                    return Err(bad(format!(
                        "{what}: sine frequency {frequency_hz} Hz is not a positive number"
                    )));
                }
            }
            Excitation::Random { .. } => {}
        }
        for i in 0..n {
            let t = r.time_s(i);
            if let Some(t0) = prev_time
                && t <= t0
            {
                return Err(bad(format!(
                    "{what}: time of sample {i} ({t} s) does not increase (previous sample at \
                     {t0} s)"
                )));
            }
            prev_time = Some(t);
        }
    }
    Ok(channels)
}

/// Shortest round-trip formatting; exponent form for very large or small magnitudes to keep
/// cells short. Both forms parse back to the identical f64.
fn fmt_f64(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// A temporary file next to the target, removed on drop unless persisted.
struct TempFile {
    tmp_path: PathBuf,
    target: PathBuf,
    file: Option<File>,
    persisted: bool,
}

impl TempFile {
    fn create(target: &Path) -> Result<TempFile, CsvError> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let name = target
            .file_name()
            .map_or_else(|| "export.csv".into(), |n| n.to_string_lossy().into_owned());
        let mut attempt = 0;
        loop {
            let tmp_path = dir.join(format!(
                ".{name}.{}.{}.tmp",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            match OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&tmp_path)
            {
                Ok(file) => {
                    return Ok(TempFile {
                        tmp_path,
                        target: target.to_path_buf(),
                        file: Some(file),
                        persisted: false,
                    });
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists && attempt < 100 => {
                    attempt += 1;
                }
                Err(source) => {
                    return Err(CsvError::Io {
                        path: target.to_path_buf(),
                        action: "cannot create a temporary file in the target directory",
                        source,
                    });
                }
            }
        }
    }

    fn persist(mut self) -> Result<(), CsvError> {
        fs::rename(&self.tmp_path, &self.target).map_err(|source| CsvError::Io {
            path: self.target.clone(),
            action: "cannot rename the temporary file onto the target",
            source,
        })?;
        self.persisted = true;
        // Make the rename durable where the platform allows it; failure here is harmless.
        if let Some(dir) = self.target.parent()
            && let Ok(d) = File::open(if dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                dir
            })
        {
            let _ = d.sync_all();
        }
        Ok(())
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if !self.persisted {
            drop(self.file.take());
            let _ = fs::remove_file(&self.tmp_path);
        }
    }
}
