//! Reading the CSV contract: the dialect undone, the header's layout, the rows parsed and
//! grouped into records (`row_steps`: the rules of cells, lines and columns, then the step
//! assembler of [`crate::steps`], whose rules a step's samples share with bag and live samples,
//! their timing among them: each record its own sample rate, a pause or lost rows ending a
//! record, jittered times read as uniform), then what only an export needs: the labels checked
//! against the drive, and the excitation amplitude estimated from the data since the export
//! carries none.

use std::io;
use std::path::Path;

use super::contract::{CsvImport, Layout, TIME_COLUMN};
use super::dialect;
use super::error::{CsvError, csv_error};
use super::label_runs::label_warnings;
use super::multisine::MultisineLabel;
use super::row_parts::PartRule;
use super::row_steps::{ReadStep, RowSteps};
use super::stream::{CHUNK_BYTES, read_csv_in_chunks};
use super::sweep::SweepLabel;
use crate::steps::timing::JitterSummary;
use crate::steps::unlabelled::{StepWithFrequency, split_parts};
use crate::steps::{estimated_excitation, rms_about_mean, sine_amplitude_from_rms};
use forcemap_math::phasor::SweepLaw;
use forcemap_math::record::{Excitation, Record};
use forcemap_math::segment::SegmentOptions;

/// Reads a test-bench CSV export (see the module documentation for the contract), chunk by
/// chunk: the file's bytes in memory are a chunk, not the file.
pub fn read_csv(path: impl AsRef<Path>) -> Result<CsvImport, CsvError> {
    read_csv_in_chunks(path.as_ref(), CHUNK_BYTES)
}

/// Reads the CSV contract from any reader; `path` is used in error messages only.
pub fn read_csv_from<R: io::Read>(mut reader: R, path: &Path) -> Result<CsvImport, CsvError> {
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|source| CsvError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
    read_bytes(&bytes, path, PartRule::of_machine())
}

/// [`read_csv_from`] of a file's `bytes`, its rows split over the cores by `rule`.
pub(super) fn read_bytes(bytes: &[u8], path: &Path, rule: PartRule) -> Result<CsvImport, CsvError> {
    let p = || path.to_path_buf();
    // The dialect is detected from the first lines and undone here (see `dialect`).
    let prepared = dialect::prepare(bytes, path)?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::Headers)
        .flexible(false)
        .delimiter(prepared.dialect.separator)
        .from_reader(&prepared.text[..]);
    let skip_units_row = prepared.dialect.units.is_some();
    let header = rdr.headers().map_err(|e| csv_error(path, e))?.clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        return Err(CsvError::Empty { path: p() });
    }
    let layout = Layout::of_header(&header, path)?;
    // The rows after the header, split in place (`rows`): no allocation per row.
    let after_header = rdr.position();
    let mut read = RowSteps::new(path, &layout, skip_units_row, rule);
    read.text_rows(
        &prepared.text,
        prepared.dialect.separator,
        header.len(),
        after_header.byte() as usize,
        after_header.line(),
        true,
    )?;
    let (steps, unlabelled_times) = read.finish()?;
    import_of(path, layout, steps, &unlabelled_times, prepared.notices)
}

/// The import of the records read (`steps`; `unlabelled_times`: the rows' times of an export
/// without labels), after the file's `notices`: the labels checked against the drive, and the
/// excitation estimated from the data.
pub(super) fn import_of(
    path: &Path,
    layout: Layout,
    steps: Vec<ReadStep>,
    unlabelled_times: &[f64],
    mut notices: Vec<String>,
) -> Result<CsvImport, CsvError> {
    let p = || path.to_path_buf();
    let labelled = layout.step_col.is_some();
    // What the timing rule did: each break and rows left out, and one notice of the jitter.
    let mut jitter = JitterSummary::default();
    for s in &steps {
        jitter.add(s.assembled.timing.jitter.as_ref());
        notices.extend(s.notices.iter().cloned());
    }
    if let Some(n) = jitter.notice() {
        notices.push(format!("{}: column '{TIME_COLUMN}': {n}", path.display()));
    }
    let driven = layout.profile.driven_channel();
    let multisines: Vec<Option<MultisineLabel>> =
        steps.iter().map(|s| s.multisine.clone()).collect();
    let sweeps: Vec<Option<SweepLabel>> = steps.iter().map(|s| s.sweep).collect();
    let first_samples: Vec<usize> = steps.iter().map(|s| s.assembled.first_sample).collect();
    let labels: Vec<usize> = steps.iter().map(|s| s.assembled.label).collect();
    let mut found: Vec<StepWithFrequency> = steps
        .into_iter()
        .map(|s| (s.assembled.record, s.frequency))
        .collect();
    let options = SegmentOptions::default();
    let warnings = if labelled {
        // The segmenter knows sines and the rest: a multisine or sweep label is not checked by
        // it.
        let checked = |k: usize| multisines[k].is_none() && sweeps[k].is_none();
        label_warnings(&found, &labels, checked, driven, &options)
    } else {
        // Every row is of one step; a pause or lost rows cut it in parts, each cut into steps
        // where its drive changes, the records numbered in order.
        let parts: Vec<(&Record, &[f64])> = found
            .iter()
            .zip(first_samples)
            .map(|((run, _), first)| (run, &unlabelled_times[first..first + run.len()]))
            .collect();
        found = split_parts(&parts, driven, &options).map_err(|e| CsvError::Unlabelled {
            path: p(),
            first_s: unlabelled_times.first().copied().unwrap_or(0.0),
            last_s: unlabelled_times.last().copied().unwrap_or(0.0),
            message: e.to_string(),
        })?;
        Vec::new()
    };
    let records = found
        .into_iter()
        .enumerate()
        .map(|(k, (mut record, frequency))| {
            let level = rms_about_mean(record.channel(driven).expect("a required channel"));
            record.excitation = match (multisines.get(k).cloned().flatten(), sweeps.get(k)) {
                (Some(m), _) => Excitation::Multisine {
                    base_frequency_hz: m.base_frequency_hz,
                    lines: m.lines,
                    rms: level,
                },
                (None, Some(Some(s))) => Excitation::Sweep {
                    law: SweepLaw {
                        kind: s.kind,
                        amplitude: sine_amplitude_from_rms(level),
                        start_frequency_hz: s.start_frequency_hz,
                        end_frequency_hz: s.end_frequency_hz,
                        duration_s: record.len() as f64 / record.sample_rate_hz,
                    },
                },
                _ => estimated_excitation(frequency, level),
            };
            record
        })
        .collect();
    Ok(CsvImport {
        records,
        ignored_columns: layout.ignored_columns,
        kind: layout.profile,
        warnings,
        notices,
    })
}
