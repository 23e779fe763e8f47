//! The picked columns of a text file's data rows, read a block of rows at a time.

use std::io::BufRead;

use super::lines::{Lines, is_table_line};
use super::{FORMAT, TextColumns, io_error, split, split_in_place};
use crate::table::TableError;
use crate::tabular::RawValues;

/// The picked columns' values of a text file's data rows, a block of rows at a time.
pub(super) struct TextBlocks<'f> {
    file: &'f TextColumns,
    lines: Lines<Box<dyn BufRead + 'f>>,
    picks: Vec<(usize, bool)>,
    /// Table lines passed (the header and units rows are not data).
    table_seen: usize,
    /// Data rows read.
    row: usize,
    /// Which picks are text (a time column of date-times, as its first row shows).
    text: Vec<bool>,
    /// The cells of the row being read, in place.
    ranges: Vec<std::ops::Range<usize>>,
    done: bool,
}

impl<'f> TextBlocks<'f> {
    /// The blocks of `file`'s rows, its lines read from the first.
    pub(super) fn new(
        file: &'f TextColumns,
        lines: Lines<Box<dyn BufRead + 'f>>,
        picks: &[(usize, bool)],
    ) -> TextBlocks<'f> {
        TextBlocks {
            file,
            lines,
            picks: picks.to_vec(),
            table_seen: 0,
            row: 0,
            text: vec![false; picks.len()],
            ranges: Vec::new(),
            done: false,
        }
    }
}

impl Iterator for TextBlocks<'_> {
    type Item = Result<Vec<RawValues>, TableError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done || self.row >= self.file.lines.len() {
            return None;
        }
        let block = self.read_block();
        self.done = block.is_err();
        Some(block)
    }
}

impl TextBlocks<'_> {
    fn read_block(&mut self) -> Result<Vec<RawValues>, TableError> {
        let file = self.file;
        let width = file.columns.len();
        let rows = file.lines.len();
        let fail = |line: u64, message: String| TableError::Format {
            path: file.path.clone(),
            format: FORMAT,
            message: format!("line {line}: {message}"),
        };
        let block_rows = file.block_rows.min(rows - self.row);
        let mut numbers: Vec<Vec<f64>> = (0..self.picks.len())
            .map(|k| Vec::with_capacity(if self.text[k] { 0 } else { block_rows }))
            .collect();
        let mut texts: Vec<Option<Vec<String>>> = self
            .text
            .iter()
            .map(|&t| t.then(|| Vec::with_capacity(block_rows)))
            .collect();
        let end = self.row + block_rows;
        while self.row < end {
            let Some((index, _, raw)) = self
                .lines
                .next_line()
                .map_err(|source| io_error(&file.path, source))?
            else {
                return Err(TableError::Format {
                    path: file.path.clone(),
                    format: FORMAT,
                    message: format!(
                        "the file ended before its {rows} rows were read again (it changed while \
                         it was read)"
                    ),
                });
            };
            if !is_table_line(index, raw, file.skip_lines) {
                continue;
            }
            if self.table_seen < file.data_from {
                self.table_seen += 1;
                continue;
            }
            let line = index as u64 + 1;
            // A row's cells, in place in the line where they can be (`split_in_place`).
            let cells = match split_in_place(raw, file.separator, &mut self.ranges) {
                Some(text) => RowCells::InPlace(text, &self.ranges),
                None => RowCells::Owned(split(raw, file.separator)),
            };
            if cells.len() != width {
                return Err(fail(
                    line,
                    format!("{} fields where the table has {width}", cells.len()),
                ));
            }
            for (k, &(col, text_ok)) in self.picks.iter().enumerate() {
                let cell = cells.get(col).trim();
                if let Some(t) = &mut texts[k] {
                    t.push(cell.to_string());
                    continue;
                }
                let parsed = if file.decimal_comma && cell.contains(',') {
                    cell.replace(',', ".").parse::<f64>().ok()
                } else {
                    fast_float2::parse::<f64, _>(cell.as_bytes())
                        .ok()
                        .or_else(|| cell.parse::<f64>().ok())
                };
                let label = || file.columns[col].label();
                match parsed {
                    Some(v) if v.is_finite() => numbers[k].push(v),
                    Some(_) => {
                        return Err(fail(
                            line,
                            format!("{}: '{cell}' is not finite (NaN or infinite)", label()),
                        ));
                    }
                    // The first row decides: a column of date-times is text from there on.
                    None if text_ok && self.row == 0 => {
                        texts[k] = Some(vec![cell.to_string()]);
                        self.text[k] = true;
                    }
                    None if cell.is_empty() => {
                        return Err(fail(
                            line,
                            format!("{}: empty cell (a number is required)", label()),
                        ));
                    }
                    None => {
                        return Err(fail(line, format!("{}: '{cell}' is not a number", label())));
                    }
                }
            }
            self.row += 1;
        }
        Ok(numbers
            .into_iter()
            .zip(texts)
            .map(|(n, t)| match t {
                Some(t) => RawValues::Text(t),
                None => RawValues::Numbers(n),
            })
            .collect())
    }
}

/// The cells of a row: byte ranges of its text, or the cells split off it.
enum RowCells<'a> {
    InPlace(&'a str, &'a [std::ops::Range<usize>]),
    Owned(Vec<String>),
}

impl RowCells<'_> {
    fn len(&self) -> usize {
        match self {
            RowCells::InPlace(_, ranges) => ranges.len(),
            RowCells::Owned(cells) => cells.len(),
        }
    }

    fn get(&self, k: usize) -> &str {
        match self {
            RowCells::InPlace(text, ranges) => &text[ranges[k].clone()],
            RowCells::Owned(cells) => &cells[k],
        }
    }
}
