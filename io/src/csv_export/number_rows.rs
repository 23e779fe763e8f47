//! Rows of numbers read by the CSV contract's rules: the channels of a measurement file (MDF4,
//! TDMS, a file of columns through a channel map) go through the checks, the step assembly and
//! the import of an export's rows without being written as text and parsed again. Each number
//! stands for the cell that writes it in shortest round-trip form (as
//! [`write_csv`](super::write_csv) writes a value; a step index that is an integer as an
//! integer), and a row says what that cell would say in an export: the same value, the same
//! errors, the same rounding of its time. Row `k` is line `k + 2` (the header is line 1).

use std::path::Path;

use forcemap_math::record::Record;

use super::contract::{CsvImport, Layout, TIME_COLUMN};
use super::error::CsvError;
use super::import::Import;
use super::row_cells::{
    RowHead, decimal_resolution, parse_frequency, parse_number, parse_step, resolution_of,
};
use super::row_parts::PartRule;
use super::row_steps::RowSteps;
use super::write::write_f64;

/// What stopped a reading of number rows: the rows (by the contract's rules), or their source.
#[derive(Debug)]
pub enum NumberRowsError<E> {
    Rows(CsvError),
    Source(E),
}

impl<E> From<CsvError> for NumberRowsError<E> {
    fn from(e: CsvError) -> Self {
        NumberRowsError::Rows(e)
    }
}

/// Reads rows of the columns `names` (contract names: `time_s`, `step`, `frequency_hz`, channel
/// names), which `fill` appends to its buffer a block at a time (row after row, `names.len()`
/// numbers a row; it returns how many rows it appended, 0 at the end), as the CSV reader reads
/// the same rows written in an export; each record is handed to `keep` as soon as its block is
/// read ([`read_csv_reduced`](super::read_csv_reduced)). The names carry no multisine or sweep
/// label (a measurement file's channels do not).
pub fn read_number_rows<E>(
    path: &Path,
    names: &[&str],
    mut keep: impl FnMut(Record) -> Option<Record>,
    mut fill: impl FnMut(&mut Vec<f64>) -> Result<usize, E>,
) -> Result<CsvImport, NumberRowsError<E>> {
    let header = csv::StringRecord::from(names.to_vec());
    let layout = Layout::of_header(&header, path)?;
    debug_assert!(layout.multisine_cols.is_none() && layout.sweep_cols.is_none());
    let mut read = RowSteps::new(path, &layout, false, PartRule::of_machine());
    let mut import = Import::new(layout.clone(), &mut keep);
    let width = names.len();
    let mut block = Vec::new();
    let mut line = 2;
    let mut cell = String::new();
    loop {
        block.clear();
        if fill(&mut block).map_err(NumberRowsError::Source)? == 0 {
            break;
        }
        for row in block.chunks_exact(width) {
            let head = row_head(path, &layout, line, row, &mut cell)?;
            read.assemble(head, |values| {
                row_values(path, &layout, line, row, values, &mut cell)
            })?;
            line += 1;
        }
        import.records_read(read.take_steps());
    }
    let (steps, unlabelled_times) = read.finish()?;
    import.records_read(steps);
    Ok(import.finish(path, &unlabelled_times, Vec::new())?)
}

/// The cell an export writes for `v`, in `cell`.
fn write_cell(cell: &mut String, v: f64) -> &[u8] {
    cell.clear();
    write_f64(cell, v);
    cell.as_bytes()
}

/// A row's time and labels, as `parse_head` reads them from the row's cells.
fn row_head(
    path: &Path,
    layout: &Layout,
    line: u64,
    row: &[f64],
    cell: &mut String,
) -> Result<RowHead, CsvError> {
    // A finite time is its cell's value (the shortest round-trip form reads back as itself),
    // with its cell's rounding; any other is its cell, refused as the cell is.
    let v = row[layout.time_col];
    let (time_s, time_resolution_s) = if v.is_finite() {
        (v, resolution_of(v))
    } else {
        let time_text = write_cell(cell, v);
        (
            parse_number(path, line, TIME_COLUMN, time_text)?,
            decimal_resolution(time_text),
        )
    };
    let step = match layout.step_col {
        Some(col) => {
            let v = row[col];
            if v >= 0.0 && v.fract() == 0.0 && v < 1e15 {
                v as usize
            } else if v.fract() == 0.0 && v.abs() < 1e15 {
                // A negative integer, written as one.
                cell.clear();
                cell.push_str(&(v as i64).to_string());
                parse_step(path, line, cell.as_bytes())?
            } else {
                parse_step(path, line, write_cell(cell, v))?
            }
        }
        None => 0,
    };
    let frequency_hz = match layout.freq_col {
        Some(col) => {
            let v = row[col];
            if v.is_finite() && v >= 0.0 {
                (v != 0.0).then_some(v)
            } else {
                parse_frequency(path, line, write_cell(cell, v))?
            }
        }
        None => None,
    };
    Ok(RowHead {
        line,
        time_s,
        time_resolution_s,
        step,
        frequency_hz,
        labels: None,
    })
}

/// A row's channel values, in the layout's order, appended to `values`; a value that is not
/// finite is refused as its cell is.
fn row_values(
    path: &Path,
    layout: &Layout,
    line: u64,
    row: &[f64],
    values: &mut Vec<f64>,
    cell: &mut String,
) -> Result<(), CsvError> {
    for &(c, col) in &layout.channel_cols {
        let v = row[col];
        values.push(if v.is_finite() {
            v
        } else {
            parse_number(path, line, c.name(), write_cell(cell, v))?
        });
    }
    Ok(())
}
