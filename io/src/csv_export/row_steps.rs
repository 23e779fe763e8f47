//! A CSV export's rows into step records: each row's cells parsed and checked (the contract's
//! rules of cells, labels and time), then grouped into records by the step assembler of
//! [`crate::steps`]. The rows come from [`Rows`], over the whole text or chunk by chunk.

use std::path::Path;

use super::contract::{FREQUENCY_COLUMN, Layout, STEP_COLUMN, TIME_COLUMN};
use super::error::CsvError;
use super::multisine::{self, MultisineLabel};
use super::rows::Rows;
use super::sweep::{self, SweepLabel};
use crate::steps::timing::TimingNote;
use crate::steps::{
    AssembledStep, StepAssembler, StepError, StepFault, StepPlan, StepRules, StepSample,
    estimated_excitation,
};
use forcemap_math::phasor::SweepLaw;
use forcemap_math::record::{Channel, Excitation};

/// The rows read so far and the step being assembled.
pub(super) struct RowSteps<'a> {
    path: &'a Path,
    layout: &'a Layout,
    /// The next row is the units row (skipped).
    skip_units_row: bool,
    assembler: StepAssembler,
    steps: Vec<ReadStep>,
    current: Option<StepRows>,
    prev_time: Option<(f64, u64)>,
    /// The values' buffer, reused from row to row.
    values: Vec<(Channel, f64)>,
    /// Without labels every row is of one step 0, cut into steps once read (the rows' times
    /// kept for the records' start times).
    labelled: bool,
    unlabelled_times: Vec<f64>,
}

impl<'a> RowSteps<'a> {
    pub fn new(path: &'a Path, layout: &'a Layout, skip_units_row: bool) -> RowSteps<'a> {
        RowSteps {
            path,
            layout,
            skip_units_row,
            assembler: StepAssembler::with_rules(StepRules::WRITTEN),
            steps: Vec::new(),
            current: None,
            prev_time: None,
            values: Vec::with_capacity(layout.channel_cols.len()),
            labelled: layout.step_col.is_some(),
            unlabelled_times: Vec::new(),
        }
    }

    /// Reads every row `rows` has left.
    pub fn rows(&mut self, rows: &mut Rows) -> Result<(), CsvError> {
        while rows.next(self.path)? {
            self.row(rows)?;
        }
        Ok(())
    }

    /// The records of the rows read (the last step completed), with the rows' times of an
    /// unlabelled export.
    pub fn finish(mut self) -> Result<(Vec<ReadStep>, Vec<f64>), CsvError> {
        let path = self.path;
        match self.current.take() {
            Some(done) => {
                let result = self.assembler.finish_step();
                self.steps
                    .extend(done.completed(path, result, self.labelled)?);
            }
            None => {
                return Err(CsvError::HeaderOnly {
                    path: path.to_path_buf(),
                });
            }
        }
        if self.steps.is_empty() {
            return Err(CsvError::HeaderOnly {
                path: path.to_path_buf(),
            });
        }
        Ok((self.steps, self.unlabelled_times))
    }

    /// The current row of `rows`.
    fn row(&mut self, rows: &Rows) -> Result<(), CsvError> {
        let RowSteps {
            path,
            layout,
            skip_units_row,
            assembler,
            steps,
            current,
            prev_time,
            values,
            labelled,
            unlabelled_times,
        } = self;
        let path: &Path = path;
        if std::mem::take(skip_units_row) {
            return Ok(());
        }
        let line = rows.line();
        rows.check_utf8(path)?;
        let cell = |col: usize| rows.cell(col);

        let time_text = cell(layout.time_col);
        let time = parse_number(path, line, TIME_COLUMN, time_text)?;
        let step = match layout.step_col {
            Some(col) => parse_step(path, line, cell(col))?,
            None => 0,
        };
        let freq_text = layout.freq_col.map_or(&b""[..], cell);
        if !*labelled {
            unlabelled_times.push(time);
        }
        let freq = if freq_text.is_empty() {
            None
        } else {
            let f = parse_number(path, line, FREQUENCY_COLUMN, freq_text)?;
            if f < 0.0 {
                return Err(CsvError::InvalidValue {
                    path: path.to_path_buf(),
                    line,
                    column: FREQUENCY_COLUMN.to_string(),
                    cell: String::from_utf8_lossy(freq_text).into_owned(),
                    reason: "a frequency must not be negative",
                });
            }
            (f != 0.0).then_some(f)
        };
        let multisine = match layout.multisine_cols {
            Some((base_col, lines_col)) => multisine::parse_row(
                path,
                line,
                text(cell(base_col)),
                text(cell(lines_col)),
                freq,
            )?,
            None => None,
        };
        let swept = match layout.sweep_cols {
            Some(cols) => {
                let other = if freq.is_some() {
                    Some("a sine step")
                } else if multisine.is_some() {
                    Some("a multisine")
                } else {
                    None
                };
                sweep::parse_row(path, line, cols.map(|c| text(cell(c))), other)?
            }
            None => None,
        };

        if let Some((t0, l0)) = *prev_time
            && time <= t0
        {
            return Err(CsvError::TimeNotIncreasing {
                path: path.to_path_buf(),
                prev_line: l0,
                line,
                prev_time: t0,
                time,
            });
        }
        *prev_time = Some((time, line));

        if current.as_ref().is_none_or(|cur| cur.step != step) {
            // A new step: it must follow the previous one, which is complete (and checked)
            // before anything of this row but its time, step and frequency is read.
            if let Some(StepFault::OutOfOrder { previous }) = assembler.order_fault(step) {
                return Err(CsvError::StepNotContiguous {
                    path: path.to_path_buf(),
                    prev_line: current.as_ref().map_or(0, StepRows::last_line),
                    line,
                    prev_step: previous,
                    step,
                });
            }
            if let Some(done) = current.take() {
                let result = assembler.finish_step();
                steps.extend(done.completed(path, result, *labelled)?);
            }
            *current = Some(StepRows::new(step, freq, multisine.clone(), swept));
        }
        let cur = current.as_mut().expect("current step exists");
        if cur.frequency != freq {
            return Err(CsvError::FrequencyChanged {
                path: path.to_path_buf(),
                step,
                first_line: cur.lines[0],
                line,
                first: cur.frequency,
                found: freq,
            });
        }
        if cur.multisine != multisine {
            let text = |m: &Option<MultisineLabel>| {
                m.as_ref().map_or("no multisine".to_string(), |m| {
                    format!(
                        "base {} Hz, lines '{}'",
                        m.base_frequency_hz,
                        multisine::format_lines(&m.lines)
                    )
                })
            };
            return Err(CsvError::MultisineChanged {
                path: path.to_path_buf(),
                step,
                first_line: cur.lines[0],
                line,
                change: label_change(cur.lines[0], text(&cur.multisine), text(&multisine)),
            });
        }
        if cur.sweep != swept {
            let text = |s: &Option<SweepLabel>| {
                s.map_or("no sweep".to_string(), |s| {
                    format!(
                        "{} {} -> {} Hz",
                        sweep::law_name(s.kind),
                        s.start_frequency_hz,
                        s.end_frequency_hz
                    )
                })
            };
            return Err(CsvError::SweepChanged {
                path: path.to_path_buf(),
                step,
                first_line: cur.lines[0],
                line,
                change: label_change(cur.lines[0], text(&cur.sweep), text(&swept)),
            });
        }
        values.clear();
        for &(c, col) in &layout.channel_cols {
            values.push((c, parse_number(path, line, c.name(), cell(col))?));
        }
        cur.lines.push(line);
        let sample = StepSample {
            t_s: time,
            t_resolution_s: decimal_resolution(time_text),
            step,
            values: std::mem::take(values),
        };
        let done = assembler.push_sample(&sample, Some(&cur.plan));
        steps.extend(cur.completed(path, done, *labelled)?);
        *values = sample.values;
        Ok(())
    }
}

/// The rows of the step being read: its frequency, its lines (sample `k` of the step is on
/// `lines[k]`) and the plan it is assembled under.
struct StepRows {
    step: usize,
    /// `None` stands for random excitation (0 or empty).
    frequency: Option<f64>,
    multisine: Option<MultisineLabel>,
    sweep: Option<SweepLabel>,
    lines: Vec<u64>,
    plan: StepPlan,
}

/// A record read and assembled (a step, or a part of a step its timing cut).
pub(super) struct ReadStep {
    pub frequency: Option<f64>,
    pub multisine: Option<MultisineLabel>,
    pub sweep: Option<SweepLabel>,
    pub assembled: AssembledStep,
    /// What the timing rule did to the step before the record's end, naming the lines.
    pub notices: Vec<String>,
}

impl StepRows {
    fn new(
        step: usize,
        frequency: Option<f64>,
        multisine: Option<MultisineLabel>,
        sweep: Option<SweepLabel>,
    ) -> StepRows {
        // The export carries no amplitude: it is estimated once the step is complete (a
        // sweep's duration too, by the assembler).
        let excitation = match (&multisine, sweep) {
            (Some(m), _) => Excitation::Multisine {
                base_frequency_hz: m.base_frequency_hz,
                lines: m.lines.clone(),
                rms: f64::NAN,
            },
            (None, Some(s)) => Excitation::Sweep {
                law: SweepLaw {
                    kind: s.kind,
                    amplitude: f64::NAN,
                    start_frequency_hz: s.start_frequency_hz,
                    end_frequency_hz: s.end_frequency_hz,
                    duration_s: f64::NAN,
                },
            },
            (None, None) => estimated_excitation(frequency, f64::NAN),
        };
        StepRows {
            step,
            frequency,
            multisine,
            sweep,
            lines: Vec::new(),
            plan: StepPlan {
                excitation,
                sample_count: 0,
                driven: None,
                multisine_band_hz: None,
            },
        }
    }

    fn last_line(&self) -> u64 {
        *self.lines.last().unwrap_or(&0)
    }

    fn line(&self, sample: usize) -> u64 {
        self.lines.get(sample).copied().unwrap_or(0)
    }

    /// The assembler's verdict on this step (its records, or why it has none), with the
    /// step's lines; `labelled`: the file labels its steps (else this is the whole run).
    fn completed(
        &self,
        path: &Path,
        results: Vec<Result<AssembledStep, StepError>>,
        labelled: bool,
    ) -> Result<Vec<ReadStep>, CsvError> {
        results
            .into_iter()
            .map(|r| {
                let assembled = r.map_err(|e| self.error(path, e))?;
                let notices = assembled
                    .notes
                    .iter()
                    .map(|n| self.notice(path, n, assembled.record.step, labelled))
                    .collect();
                Ok(ReadStep {
                    frequency: self.frequency,
                    multisine: self.multisine.clone(),
                    sweep: self.sweep,
                    assembled,
                    notices,
                })
            })
            .collect()
    }

    /// What the timing rule did to this step, naming its lines; `record` is the number of the
    /// record the note comes with.
    fn notice(&self, path: &Path, note: &TimingNote, record: usize, labelled: bool) -> String {
        let at = match labelled {
            true => format!("{}: step {}", path.display(), self.step),
            false => path.display().to_string(),
        };
        match note {
            TimingNote::Break(b) => format!(
                "{at}, line {}, column '{TIME_COLUMN}': {} after line {}: {}",
                self.line(b.sample),
                b.describe(),
                self.line(b.sample - 1),
                match labelled {
                    true => format!(
                        "the step goes on in another record from here (record {record} or after)"
                    ),
                    false => "the run is cut here, each part searched for steps apart".to_string(),
                }
            ),
            TimingNote::LeftOut { first, count } => format!(
                "{at}, lines {}-{}: {count} row{} between breaks of the sampling, too few for a record: left out",
                self.line(*first),
                self.line(first + count - 1),
                if *count == 1 { "" } else { "s" }
            ),
        }
    }

    /// A step error as the CSV error naming its lines.
    fn error(&self, path: &Path, e: StepError) -> CsvError {
        match e.fault {
            StepFault::TooFew { samples } => CsvError::TooFewRows {
                path: path.to_path_buf(),
                step: e.step,
                first_line: self.line(0),
                rows: samples,
            },
            StepFault::NotUniform {
                sample,
                interval,
                reference,
            } => CsvError::NonUniformSampling {
                path: path.to_path_buf(),
                step: e.step,
                prev_line: self.line(sample - 1),
                line: self.line(sample),
                interval,
                expected: reference,
            },
            StepFault::SweepBroken { at } => CsvError::Malformed {
                path: path.to_path_buf(),
                line: Some(self.line(at.sample)),
                message: format!(
                    "step {}: {} (remove the step, or export the sweep without a gap)",
                    e.step, e.problem
                ),
            },
            // Parsing refuses what the other faults stand for (a step out of order, a
            // non-finite value, a missing plan, a changed set of channels) before the
            // assembler sees the row.
            _ => CsvError::Malformed {
                path: path.to_path_buf(),
                line: Some(self.line(0)),
                message: e.to_string(),
            },
        }
    }
}

/// How a step's label changed within the step: "line 12 has X, this line Y".
fn label_change(first_line: u64, before: String, now: String) -> String {
    format!("line {first_line} has {before}, this line {now}")
}

/// A cell of a row `Rows::check_utf8` accepted, as text.
fn text(cell: &[u8]) -> &str {
    std::str::from_utf8(cell).unwrap_or_default()
}

fn parse_number(path: &Path, line: u64, column: &str, cell: &[u8]) -> Result<f64, CsvError> {
    if cell.is_empty() {
        return Err(CsvError::EmptyCell {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
        });
    }
    let lossy = || String::from_utf8_lossy(cell).into_owned();
    // What the fast parser refuses goes through `str::parse` trimmed of any Unicode
    // whitespace (as string records were; `cell` trims ASCII only), so that the same cells
    // are numbers, empty or refused as before.
    let v: f64 = match fast_float2::parse(cell) {
        Ok(v) => v,
        Err(_) => {
            let trimmed = text(cell).trim();
            if trimmed.is_empty() {
                return Err(CsvError::EmptyCell {
                    path: path.to_path_buf(),
                    line,
                    column: column.to_string(),
                });
            }
            trimmed.parse().map_err(|_| CsvError::NonNumeric {
                path: path.to_path_buf(),
                line,
                column: column.to_string(),
                cell: lossy(),
            })?
        }
    };
    if !v.is_finite() {
        return Err(CsvError::NonFinite {
            path: path.to_path_buf(),
            line,
            column: column.to_string(),
            cell: lossy(),
        });
    }
    Ok(v)
}

/// A step index: a non-negative integer (an integral float such as `3.0` is accepted).
fn parse_step(path: &Path, line: u64, cell: &[u8]) -> Result<usize, CsvError> {
    if let Ok(s) = text(cell).parse::<usize>() {
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
            cell: String::from_utf8_lossy(cell).into_owned(),
            reason: "a step index must be a non-negative integer",
        })
    }
}

/// The decimal resolution a number was written with: `0.000100` -> 1e-6, `1.5e-3` -> 1e-4.
fn decimal_resolution(text: &[u8]) -> f64 {
    let (mantissa, exponent) = match text.iter().position(|&b| b == b'e' || b == b'E') {
        Some(i) => (
            &text[..i],
            self::text(&text[i + 1..]).parse::<i32>().unwrap_or(0),
        ),
        None => (text, 0),
    };
    let decimals = mantissa.iter().position(|&b| b == b'.').map_or(0, |i| {
        mantissa[i + 1..]
            .iter()
            .filter(|b| b.is_ascii_digit())
            .count()
    });
    10f64.powi(exponent - decimals as i32)
}
