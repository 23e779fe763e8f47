//! The picked columns of a file of columns made into the CSV contract's rows and read by its
//! reader ([`read_number_rows`](crate::csv_export::read_number_rows)), a block of rows at a
//! time as the format gives them: each value scaled to forcemap's unit, the time from its
//! column, the sample rate or the waveform timing, the labels of records the map names.

use std::path::Path;

use forcemap_math::record::Record;

use super::resolve::{Picks, date_times, pick};
use super::{ColumnBlocks, ColumnFile, ColumnInfo, RawValues};
use crate::csv_export::{CsvImport, FREQUENCY_COLUMN, STEP_COLUMN, TIME_COLUMN};
use crate::table::{RowLines, RowPlaces, TableError, check_columns, read_table_rows};
use crate::table_map::{NamedRows, RecordMaking, TableMap};

/// Reads the picked columns of `file` into the CSV contract's rows and through its reader,
/// each record handed to `keep` as soon as its rows are read.
pub fn read_through(
    file: &mut dyn ColumnFile,
    path: &Path,
    map: &TableMap,
    keep: impl FnMut(Record) -> Option<Record>,
) -> Result<CsvImport, TableError> {
    let Picks {
        plans,
        time_rate,
        waveform,
        time_format,
    } = pick(&*file, path, map)?;
    let columns = file.columns();
    let described: Vec<String> = plans
        .iter()
        .map(|p| {
            let mut s = format!("{} <- {}", p.name, columns[p.column].label());
            if !p.how.is_empty() {
                s.push_str(&format!(" ({})", p.how));
            }
            s
        })
        .collect();

    // What is said of the file, before its columns are read.
    let format = file.format();
    let row_lines: Option<RowLines> = file.row_lines().cloned();
    let infos: Vec<ColumnInfo> = plans.iter().map(|p| columns[p.column].clone()).collect();
    let mut notices = file.notices();
    let reads: Vec<(usize, bool)> = plans.iter().map(|p| (p.column, p.text_ok)).collect();
    let ColumnBlocks {
        mut lengths,
        mut blocks,
    } = file.read_blocks(&reads)?;
    // A block's values scaled (a column named twice is refused with the first block, before
    // any row is read); a column of date-times counts from its first, in the first block.
    let mut block_row = 0;
    let mut first_instants = vec![None; plans.len()];
    let mut scale = |raw: Vec<RawValues>| -> Result<Vec<Vec<f64>>, TableError> {
        let mut out = Vec::with_capacity(plans.len());
        let mut block_len = 0;
        for (k, ((plan, info), raw)) in plans.iter().zip(&infos).zip(raw).enumerate() {
            out.push(match raw {
                RawValues::Numbers(v) => v
                    .into_iter()
                    .map(|x| x * plan.factor + plan.offset)
                    .collect(),
                RawValues::Text(cells) => date_times(
                    (format, row_lines.as_ref()),
                    path,
                    info,
                    (&cells, block_row),
                    time_format.as_deref(),
                    &mut first_instants[k],
                )?
                .into_iter()
                .map(|t| t + plan.offset)
                .collect::<Vec<f64>>(),
            });
            block_len = block_len.max(out[k].len());
            if plans[..k].iter().any(|p| p.name == plan.name) {
                return Err(TableError::Format {
                    path: path.to_path_buf(),
                    format,
                    message: format!("channel '{}' appears more than once", plan.name),
                });
            }
        }
        block_row += block_len;
        Ok(out)
    };
    let mut first = match blocks.next() {
        Some(raw) => scale(raw?)?,
        None => scale(
            reads
                .iter()
                .map(|_| RawValues::Numbers(Vec::new()))
                .collect(),
        )?,
    };
    let n = lengths.last().copied().unwrap_or(0);
    let mut names: Vec<&'static str> = plans.iter().map(|p| p.name).collect();
    let generated_time = time_rate.is_some() || waveform.is_some();
    if generated_time {
        names.insert(0, TIME_COLUMN);
        lengths.insert(0, n);
    }
    // The records the map names: their rows of the whole columns, each labelled by its index.
    let mut kept_lines: Option<RowLines> = None;
    let mut named: Option<NamedValues> = None;
    let mut zero_labels = false;
    let mut labels_len = n;
    match &map.records {
        RecordMaking::Steps => {}
        RecordMaking::Whole => {
            if map.step.is_none() {
                zero_labels = true;
            }
        }
        RecordMaking::Rows(records) => {
            let mut whole = std::mem::take(&mut first);
            for raw in blocks.by_ref() {
                for (w, b) in whole.iter_mut().zip(scale(raw?)?) {
                    w.extend(b);
                }
            }
            let kept = rows_of_records(format, path, &map.file, records, n)?;
            check_columns(&names, &lengths, path, format)?;
            kept_lines = row_lines.as_ref().map(|lines| {
                kept.iter()
                    .map(|&(k, _)| lines.get(k).expect("a row of the file"))
                    .collect()
            });
            let (rows, record): (Vec<usize>, Vec<usize>) = kept.into_iter().unzip();
            let picked = whole
                .iter()
                .map(|v| rows.iter().map(|&k| v[k]).collect())
                .collect();
            lengths.iter_mut().for_each(|l| *l = rows.len());
            labels_len = rows.len();
            named = Some(NamedValues {
                values: picked,
                samples: rows,
                records: record,
            });
            zero_labels = true;
        }
    }
    if zero_labels {
        // Frequency 0 labels a record that is not a sine.
        names.extend([STEP_COLUMN, FREQUENCY_COLUMN]);
        lengths.extend([labels_len; 2]);
    }
    check_columns(&names, &lengths, path, format)?;
    let places = match kept_lines.as_ref().or(row_lines.as_ref()) {
        Some(lines) => RowPlaces::Lines(lines),
        None => RowPlaces::Samples,
    };

    // Rows: the time generated or read, the picked values, the records' labels.
    let width = names.len();
    let mut next_block = Some(first);
    let mut row = 0usize;
    let fill = |out: &mut Vec<f64>| -> Result<usize, TableError> {
        let (values, samples) = match named.take() {
            Some(NamedValues {
                values,
                samples,
                records,
            }) => {
                next_block = None;
                (values, Some((samples, records)))
            }
            None => match next_block.take() {
                Some(values) => (values, None),
                None => match blocks.next() {
                    Some(raw) => (scale(raw?)?, None),
                    None => return Ok(0),
                },
            },
        };
        let m = values.first().map_or(0, Vec::len);
        out.reserve(m * width);
        for i in 0..m {
            // The row's sample in the file.
            let k = samples.as_ref().map_or(row + i, |(rows, _)| rows[i]);
            if let Some(rate) = time_rate {
                out.push(k as f64 / rate);
            }
            if let Some((start_s, increment_s)) = waveform {
                out.push(start_s + k as f64 * increment_s);
            }
            out.extend(values.iter().map(|v| v[i]));
            if zero_labels {
                let step = samples.as_ref().map_or(0.0, |(_, record)| record[i] as f64);
                out.extend([step, 0.0]);
            }
        }
        row += m;
        Ok(m)
    };
    let mut import = read_table_rows(path, format, places, &names, keep, fill)?;
    if map.records.by_map() {
        // The step label is the map's, not the file's: checking it against the drive says
        // nothing (a sine test read as one record is not mislabelled).
        import
            .warnings
            .retain(|w| !(w.contains(" is labelled ") || w.contains("inside labelled step")));
    }
    notices.push(format!(
        "{}: read through the map {}: {}",
        path.display(),
        map.file,
        described.join(", ")
    ));
    notices.append(&mut import.notices);
    import.notices = notices;
    Ok(import)
}

/// The values of the records a map names: each row's values, its sample in the file and its
/// record.
struct NamedValues {
    values: Vec<Vec<f64>>,
    samples: Vec<usize>,
    records: Vec<usize>,
}

/// The samples (0-based) the map's named records keep, each with its record's index; an error
/// names the record whose rows the file does not have.
fn rows_of_records(
    format: &'static str,
    path: &Path,
    map_file: &str,
    records: &[NamedRows],
    samples: usize,
) -> Result<Vec<(usize, usize)>, TableError> {
    let mut kept = Vec::new();
    for (index, r) in records.iter().enumerate() {
        if r.last_row > samples {
            return Err(TableError::Format {
                path: path.to_path_buf(),
                format,
                message: format!(
                    "record '{}' of the map {map_file} ends at row {}, but the file has {samples} \
                     rows",
                    r.name, r.last_row
                ),
            });
        }
        kept.extend((r.first_row - 1..r.last_row).map(|k| (k, index)));
    }
    Ok(kept)
}
