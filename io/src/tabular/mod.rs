//! Files of columns read through a channel map ([`crate::table_map`]): delimited and
//! whitespace text with or without a header, ASAM MDF4, NI TDMS, MATLAB MAT and JSON files. Each
//! format lists its columns (name, group, position, unit, its own time base) and reads the
//! ones the map picks; the picking, the units and the time are one piece of code for every
//! format ([`resolve`]), and the picked columns become the CSV contract's rows
//! ([`crate::table`]), so that a file read through a map gives the records, checks and
//! errors of the same samples in forcemap's CSV.

pub mod datetime;
mod default_map;
pub mod json;
pub mod mat;
mod read;
mod resolve;
pub mod text;

use std::path::Path;

use forcemap_math::record::Record;

use crate::csv_export::CsvImport;
use crate::input::FileFormat;
use crate::table::{RowLines, TableError};
use crate::table_map::TableMap;

pub use default_map::default_map;
pub use read::read_through;
pub use resolve::{Picks, pick};

/// One column of a file, as its format describes it.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnInfo {
    /// Header cell, channel name or variable name (`None` for a headerless text column).
    pub name: Option<String>,
    /// MDF4 channel group or TDMS group.
    pub group: Option<String>,
    /// 1-based position in the file (MDF4, TDMS: within its group).
    pub position: usize,
    /// The 1-based column of a MAT matrix this column is.
    pub matrix_column: Option<usize>,
    /// The unit the file gives (a units row, the name's `(unit)`, MDF4's unit, TDMS's
    /// `unit_string`).
    pub unit: Option<String>,
    /// What the file says of this column's time.
    pub time_base: Option<TimeBase>,
}

impl ColumnInfo {
    /// How the column is named in messages: `'Force (N)'` (group `G`), or `column 3`.
    pub fn label(&self) -> String {
        let mut s = match &self.name {
            Some(n) => format!("'{n}'"),
            None => format!("column {}", self.position),
        };
        if let Some(c) = self.matrix_column {
            s.push_str(&format!(" column {c}"));
        }
        if let Some(g) = &self.group {
            s.push_str(&format!(" (group '{g}')"));
        }
        s
    }
}

/// A time base a file carries beside its columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeBase {
    /// The column is its group's master time channel (MDF4).
    Master,
    /// The column's samples are at `start_s + k * increment_s` (TDMS waveform properties).
    Waveform { start_s: f64, increment_s: f64 },
}

/// A column's values as read.
#[derive(Debug, Clone, PartialEq)]
pub enum RawValues {
    Numbers(Vec<f64>),
    /// Cells that are not numbers (date-times), with the line of each for errors.
    Text(Vec<String>),
}

/// The values of columns picked from a file, a block of rows at a time.
pub struct ColumnBlocks<'f> {
    /// How many values each pick has in the whole file.
    pub lengths: Vec<usize>,
    /// Each block: every pick's values of the same rows (when the picks have as many values
    /// each), numbers; a format read whole gives one block, which may hold text.
    pub blocks: Box<dyn Iterator<Item = Result<Vec<RawValues>, TableError>> + 'f>,
}

impl ColumnBlocks<'_> {
    /// The picks' values of every block, one after the other (a pick is text in every block
    /// or in none).
    pub fn whole(self) -> Result<Vec<RawValues>, TableError> {
        let mut values: Option<Vec<RawValues>> = None;
        for block in self.blocks {
            let block = block?;
            let Some(values) = &mut values else {
                values = Some(block);
                continue;
            };
            for (v, b) in values.iter_mut().zip(block) {
                match (v, b) {
                    (RawValues::Numbers(v), RawValues::Numbers(b)) => v.extend(b),
                    (RawValues::Text(v), RawValues::Text(b)) => v.extend(b),
                    _ => unreachable!("a pick is text in every block or in none"),
                }
            }
        }
        Ok(values.unwrap_or_else(|| {
            self.lengths
                .iter()
                .map(|_| RawValues::Numbers(Vec::new()))
                .collect()
        }))
    }
}

/// A file of columns: what it holds, and the values of the columns picked from it.
pub trait ColumnFile {
    fn format(&self) -> &'static str;
    fn columns(&self) -> &[ColumnInfo];
    /// The values of the columns at these indices of [`columns`](Self::columns); a column
    /// with `true` may come back as text (a time column of date-times), the others must be
    /// numbers.
    fn read(&mut self, picks: &[(usize, bool)]) -> Result<Vec<RawValues>, TableError>;
    /// [`read`](Self::read) a block of rows at a time, so that a long file is not held whole;
    /// a format that reads its columns whole gives them as one block.
    fn read_blocks(&mut self, picks: &[(usize, bool)]) -> Result<ColumnBlocks<'_>, TableError> {
        let values = self.read(picks)?;
        let lengths = values
            .iter()
            .map(|v| match v {
                RawValues::Numbers(v) => v.len(),
                RawValues::Text(v) => v.len(),
            })
            .collect();
        Ok(ColumnBlocks {
            lengths,
            blocks: Box::new(std::iter::once(Ok(values))),
        })
    }
    /// The file's line of each row, where the format has lines (text).
    fn row_lines(&self) -> Option<&RowLines> {
        None
    }
    /// What the reader found of the file's layout (dialect, skipped lines).
    fn notices(&self) -> Vec<String> {
        Vec::new()
    }
}

/// The values of the picked columns of a binary file held in memory (MAT, JSON), each checked
/// to be finite; the first that is not is named by its column and element.
pub(crate) fn finite_columns(
    path: &Path,
    format: &'static str,
    columns: &[ColumnInfo],
    values: &[Vec<f64>],
    picks: &[(usize, bool)],
) -> Result<Vec<RawValues>, TableError> {
    picks
        .iter()
        .map(|&(k, _)| {
            let v = &values[k];
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Err(TableError::Format {
                    path: path.to_path_buf(),
                    format,
                    message: format!(
                        "{}: element {} is not a finite number ({}; every sample must be)",
                        columns[k].label(),
                        i + 1,
                        v[i]
                    ),
                });
            }
            Ok(RawValues::Numbers(v.clone()))
        })
        .collect()
}

/// Opens `path` as the file of columns its format is.
pub fn open(path: &Path, map: Option<&TableMap>) -> Result<Box<dyn ColumnFile>, TableError> {
    Ok(match FileFormat::of(path) {
        FileFormat::Mdf => Box::new(crate::mdf::MdfColumns::open(path)?),
        FileFormat::Tdms => Box::new(crate::tdms::TdmsColumns::open(path)?),
        FileFormat::Mat => Box::new(mat::MatColumns::open(path)?),
        FileFormat::Json => Box::new(json::JsonColumns::open(path)?),
        FileFormat::Csv => Box::new(text::TextColumns::open(
            path,
            &map.map(|m| m.text.clone()).unwrap_or_default(),
        )?),
    })
}

/// The records of the file at `path`, its columns picked by `map`.
pub fn read_mapped(path: &Path, map: &TableMap) -> Result<CsvImport, TableError> {
    read_mapped_reduced(path, map, Some)
}

/// [`read_mapped`] with each record handed to `keep` as it is read
/// ([`read_csv_reduced`](crate::csv_export::read_csv_reduced)): the import's records are those
/// `keep` returns.
pub fn read_mapped_reduced(
    path: &Path,
    map: &TableMap,
    keep: impl FnMut(Record) -> Option<Record>,
) -> Result<CsvImport, TableError> {
    let mut file = open(path, Some(map))?;
    read::read_through(file.as_mut(), path, map, keep)
}

/// The records of an MDF4 or TDMS file whose channels are named as forcemap names them (no
/// map): the map of those names ([`default_map`]).
pub fn read_by_contract_names(path: &Path) -> Result<CsvImport, TableError> {
    read_by_contract_names_reduced(path, Some)
}

/// [`read_by_contract_names`] with each record handed to `keep` as it is read
/// ([`read_csv_reduced`](crate::csv_export::read_csv_reduced)): the import's records are those
/// `keep` returns.
pub fn read_by_contract_names_reduced(
    path: &Path,
    keep: impl FnMut(Record) -> Option<Record>,
) -> Result<CsvImport, TableError> {
    let mut file = open(path, None)?;
    let map = default_map(file.as_ref(), path)?;
    read::read_through(file.as_mut(), path, &map, keep)
}
