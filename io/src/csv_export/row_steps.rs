//! A CSV export's rows into step records: each row's cells parsed and checked (the contract's
//! rules of cells, labels and time: `row_cells`), then grouped into records by the step
//! assembler of [`crate::steps`]. The rows come from [`Rows`], over the whole text or chunk by
//! chunk; a long text's rows are parsed in parts over the cores (`row_parts`) and assembled in
//! order.

use std::path::Path;

use super::contract::{Layout, TIME_COLUMN};
use super::error::CsvError;
use super::multisine::{self, MultisineLabel};
use super::row_cells::{RowHead, parse_head, parse_values};
use super::row_parts::{PartRows, PartRule, parse_parts};
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
    /// Records completed and not yet taken ([`RowSteps::take_steps`]), and whether any was.
    steps: Vec<ReadStep>,
    any_step: bool,
    current: Option<StepRows>,
    prev_time: Option<(f64, u64)>,
    /// The values' buffers, reused from row to row.
    values: Vec<(Channel, f64)>,
    numbers: Vec<f64>,
    /// Without labels every row is of one step 0, cut into steps once read (the rows' times
    /// kept for the records' start times).
    labelled: bool,
    unlabelled_times: Vec<f64>,
    /// How a long text's rows are split over the cores, and the parts' buffers.
    rule: PartRule,
    kept_parts: Vec<PartRows>,
}

/// Where the rows of a text ended.
pub(super) struct RowsEnd {
    /// The byte, and the `csv` crate's line count there.
    pub pos: usize,
    pub line: u64,
    /// A row must be read by the `csv` crate with the rest of the file, from `pos`.
    pub wants_rest: bool,
}

impl<'a> RowSteps<'a> {
    /// The rows of an export of `layout`, a long text's rows split over the cores by `rule`.
    pub fn new(
        path: &'a Path,
        layout: &'a Layout,
        skip_units_row: bool,
        rule: PartRule,
    ) -> RowSteps<'a> {
        RowSteps {
            path,
            layout,
            skip_units_row,
            assembler: StepAssembler::with_rules(StepRules::WRITTEN),
            steps: Vec::new(),
            any_step: false,
            current: None,
            prev_time: None,
            values: Vec::with_capacity(layout.channel_cols.len()),
            numbers: Vec::with_capacity(layout.channel_cols.len()),
            labelled: layout.step_col.is_some(),
            unlabelled_times: Vec::new(),
            rule,
            kept_parts: Vec::new(),
        }
    }

    /// Reads the rows of `text` from byte `pos`, where the `csv` crate's line count is `line`
    /// (see [`Rows::of_chunk`]: `whole`, the text holds the rest of the file); returns where
    /// they ended and whether a row wants the rest of the file ([`Rows::position`],
    /// [`Rows::wants_rest`]).
    pub fn text_rows(
        &mut self,
        text: &[u8],
        separator: u8,
        width: usize,
        pos: usize,
        line: u64,
        whole: bool,
    ) -> Result<RowsEnd, CsvError> {
        let (mut pos, mut line) = (pos, line);
        let parts = self.rule.parts(text, pos);
        if parts.len() > 1 && !self.skip_units_row {
            let (path, layout) = (self.path, self.layout);
            let mut parsed = parse_parts(
                text,
                &parts,
                &mut self.kept_parts,
                self.rule.threads,
                separator,
                width,
                path,
                layout,
            );
            let columns = layout.channel_cols.len();
            for part in &mut parsed {
                // A part that the part before stopped short of is left to one reader.
                if part.start != pos {
                    break;
                }
                for (k, mut head) in part.heads.drain(..).enumerate() {
                    head.line += line;
                    let values = &part.values[k * columns..(k + 1) * columns];
                    self.assemble(head, |v| {
                        v.extend_from_slice(values);
                        Ok(())
                    })?;
                }
                (pos, line) = (part.end, line + part.line_feeds);
            }
            self.kept_parts.append(&mut parsed);
        }
        // The rest (all the rows of a short text; else the row a part stopped at and what
        // follows it, or the blank lines at the end) by one reader.
        let mut rows = Rows::of_chunk(text, separator, width, pos, line, whole);
        while rows.next(self.path)? {
            self.row(&rows)?;
        }
        let (pos, line) = rows.position();
        Ok(RowsEnd {
            pos,
            line,
            wants_rest: rows.wants_rest(),
        })
    }

    /// The records completed since the last call, in file order.
    pub fn take_steps(&mut self) -> Vec<ReadStep> {
        self.any_step |= !self.steps.is_empty();
        std::mem::take(&mut self.steps)
    }

    /// The records not yet taken (the last step completed), with the rows' times of an
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
        if self.steps.is_empty() && !self.any_step {
            return Err(CsvError::HeaderOnly {
                path: path.to_path_buf(),
            });
        }
        Ok((self.steps, self.unlabelled_times))
    }

    /// The current row of `rows`.
    fn row(&mut self, rows: &Rows) -> Result<(), CsvError> {
        if std::mem::take(&mut self.skip_units_row) {
            return Ok(());
        }
        let head = parse_head(self.path, self.layout, rows)?;
        let (path, layout, line) = (self.path, self.layout, head.line);
        self.assemble(head, |values| {
            parse_values(path, layout, rows, line, values)
        })
    }

    /// A row whose time and labels are `head`, checked against the rows before and added to its
    /// step; `values` appends its channel values (or refuses them), which is done after the
    /// checks so that a row's errors come in the order of one reader's.
    pub(super) fn assemble(
        &mut self,
        head: RowHead,
        values: impl FnOnce(&mut Vec<f64>) -> Result<(), CsvError>,
    ) -> Result<(), CsvError> {
        let RowSteps {
            path,
            layout,
            assembler,
            steps,
            current,
            prev_time,
            values: sample_values,
            numbers,
            labelled,
            unlabelled_times,
            ..
        } = self;
        let path: &Path = path;
        let RowHead {
            line,
            time_s: time,
            time_resolution_s,
            step,
            frequency_hz: freq,
            labels,
        } = head;
        let (multisine, swept) = labels.map_or((None, None), |l| (l.multisine, l.sweep));
        if !*labelled {
            unlabelled_times.push(time);
        }
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
        numbers.clear();
        values(numbers)?;
        sample_values.clear();
        sample_values.extend(
            layout
                .channel_cols
                .iter()
                .zip(numbers.iter())
                .map(|(&(c, _), &v)| (c, v)),
        );
        cur.lines.push(line);
        let sample = StepSample {
            t_s: time,
            t_resolution_s: time_resolution_s,
            step,
            values: std::mem::take(sample_values),
        };
        let done = assembler.push_sample(&sample, Some(&cur.plan));
        steps.extend(cur.completed(path, done, *labelled)?);
        *sample_values = sample.values;
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
