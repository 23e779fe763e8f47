//! Text files of columns as DAQs and test machines write them: comma, semicolon, tab or
//! whitespace-run separators, a header row or none, a units row, decimal commas, a preamble of
//! lines to skip, comment lines (`#`, `%`) and blank lines anywhere, a byte-order mark, CRLF
//! line ends, and a last line cut short by an interrupted recording. The layout is detected
//! from the first lines unless the map's `table:` block states it.

use std::ops::Range;
use std::path::Path;

use super::datetime::parse_instant;
use super::{ColumnFile, ColumnInfo, RawValues};
use crate::csv_export::dialect::{cells, line_spans};
use crate::table::TableError;
use crate::table_map::{Separator, TextOptions};
use crate::units::unit_in_name;

const FORMAT: &str = "text";
/// Lines looked at to detect the layout.
const SAMPLE_LINES: usize = 32;

/// A text file's layout and its rows.
pub struct TextColumns {
    path: std::path::PathBuf,
    bytes: Vec<u8>,
    separator: Separator,
    decimal_comma: bool,
    columns: Vec<ColumnInfo>,
    /// The byte range and 1-based line of each data row.
    rows: Vec<(Range<usize>, u64)>,
    lines: Vec<u64>,
    notices: Vec<String>,
}

fn separator_byte(s: Separator) -> Option<u8> {
    match s {
        Separator::Comma => Some(b','),
        Separator::Semicolon => Some(b';'),
        Separator::Tab => Some(b'\t'),
        Separator::Whitespace => None,
    }
}

/// The cells of a line under `separator` (quotes as the `csv` crate reads them for a
/// delimiter; whitespace runs split unquoted).
fn split(line: &[u8], separator: Separator) -> Vec<String> {
    match separator_byte(separator) {
        Some(b) => cells(line, b),
        None => String::from_utf8_lossy(line)
            .split_ascii_whitespace()
            .map(str::to_string)
            .collect(),
    }
}

/// The cells of a data row as [`split`] gives them, found in place (no allocation) for a row
/// that is UTF-8 without quotes or carriage returns; `false` (and `out` unspecified) for any
/// other row, which [`split`] reads.
fn split_in_place<'a>(line: &'a [u8], separator: Separator, out: &mut Vec<&'a str>) -> bool {
    out.clear();
    let Ok(text) = std::str::from_utf8(line) else {
        return false;
    };
    match separator_byte(separator) {
        Some(b) => {
            if line.is_empty() || memchr::memchr3(b'"', b'\r', b'\n', line).is_some() {
                return false;
            }
            out.extend(text.split(char::from(b)).map(str::trim_ascii));
        }
        None => out.extend(text.split_ascii_whitespace()),
    }
    true
}

fn is_number(cell: &str, decimal_comma: bool) -> bool {
    let c = cell.trim();
    if decimal_comma {
        c.replace(',', ".").parse::<f64>().is_ok()
    } else {
        c.parse::<f64>().is_ok()
    }
}

fn is_comment(line: &[u8]) -> bool {
    let t = line.trim_ascii_start();
    t.starts_with(b"#") || t.starts_with(b"%")
}

impl TextColumns {
    pub fn open(path: &Path, options: &TextOptions) -> Result<TextColumns, TableError> {
        let bytes = std::fs::read(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
        TextColumns::from_bytes(bytes, path, options)
    }

    pub fn from_bytes(
        bytes: Vec<u8>,
        path: &Path,
        options: &TextOptions,
    ) -> Result<TextColumns, TableError> {
        let fail = |message: String| TableError::Format {
            path: path.to_path_buf(),
            format: FORMAT,
            message,
        };
        let bom = if bytes.starts_with(b"\xEF\xBB\xBF") {
            3
        } else {
            0
        };
        let spans: Vec<Range<usize>> = line_spans(&bytes[bom..])
            .into_iter()
            .map(|r| r.start + bom..r.end + bom)
            .collect();
        let text_of = |r: &Range<usize>| {
            let l = &bytes[r.clone()];
            l.strip_suffix(b"\n")
                .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
                .unwrap_or(l)
        };
        // The table's lines: after the preamble, without blank and comment lines.
        let table: Vec<(usize, Range<usize>)> = spans
            .iter()
            .enumerate()
            .skip(options.skip_lines)
            .filter(|(_, r)| {
                let l = text_of(r);
                !l.iter().all(u8::is_ascii_whitespace) && !is_comment(l)
            })
            .map(|(i, r)| (i, r.clone()))
            .collect();
        let Some((first_index, first)) = table.first().cloned() else {
            return Err(fail(format!(
                "no table: the file has no line{} that is not blank or a comment",
                if options.skip_lines > 0 {
                    format!(" after the {} skipped", options.skip_lines)
                } else {
                    String::new()
                }
            )));
        };
        let sample: Vec<&[u8]> = table
            .iter()
            .skip(1)
            .take(SAMPLE_LINES)
            .map(|(_, r)| text_of(r))
            .collect();
        let separator = match options.separator {
            Some(s) => s,
            None => detect_separator(text_of(&first), &sample).ok_or_else(|| {
                fail(format!(
                    "line {}: cannot tell how cells are separated (tried comma, semicolon, tab \
                     and whitespace); give table: {{separator: ...}} in the map",
                    first_index + 1
                ))
            })?,
        };
        let first_cells = split(text_of(&first), separator);
        let decimal_comma = options.decimal_comma.unwrap_or_else(|| {
            separator != Separator::Comma
                && sample
                    .iter()
                    .flat_map(|l| split(l, separator))
                    .any(|c| c.contains(',') && !is_number(&c, false) && is_number(&c, true))
        });
        let header = options.header.unwrap_or_else(|| {
            first_cells
                .iter()
                .any(|c| !is_number(c, decimal_comma) && parse_instant(c, None).is_none())
        });
        let mut data_from = usize::from(header);
        // A units row: text where the data below hold numbers.
        let mut units: Option<Vec<String>> = None;
        if header && let (Some((_, second)), Some((_, third))) = (table.get(1), table.get(2)) {
            let u = split(text_of(second), separator);
            let d = split(text_of(third), separator);
            let numbers_below = d.iter().filter(|c| is_number(c, decimal_comma)).count();
            if u.len() == first_cells.len()
                && numbers_below > 0
                && u.iter().zip(&d).all(|(u, d)| {
                    u.is_empty() || !is_number(u, decimal_comma) || !is_number(d, decimal_comma)
                })
                && u.iter()
                    .zip(&d)
                    .any(|(u, d)| !u.is_empty() && is_number(d, decimal_comma))
            {
                units = Some(u);
                data_from = 2;
            }
        }
        let width = first_cells.len();
        let columns: Vec<ColumnInfo> = (0..width)
            .map(|i| {
                let name = header.then(|| first_cells[i].clone());
                let unit = units
                    .as_ref()
                    .map(|u| u[i].clone())
                    .filter(|u| !u.is_empty())
                    .or_else(|| {
                        name.as_deref()
                            .and_then(unit_in_name)
                            .map(|(_, u)| u.to_string())
                    });
                ColumnInfo {
                    name,
                    group: None,
                    position: i + 1,
                    matrix_column: None,
                    unit,
                    time_base: None,
                }
            })
            .collect();
        let mut rows: Vec<(Range<usize>, u64)> = table
            .iter()
            .skip(data_from)
            .map(|(i, r)| (r.clone(), *i as u64 + 1))
            .collect();
        let mut notices = Vec::new();
        let mut layout = vec![
            match separator {
                Separator::Comma => "comma separators",
                Separator::Semicolon => "semicolon separators",
                Separator::Tab => "tab separators",
                Separator::Whitespace => "whitespace separators",
            }
            .to_string(),
        ];
        layout.push(if header {
            format!("a header on line {}", first_index + 1)
        } else {
            "no header (columns by position)".into()
        });
        if units.is_some() {
            layout.push(format!("a units row on line {}", table[1].0 + 1));
        }
        if decimal_comma {
            layout.push("decimal commas".into());
        }
        if options.skip_lines > 0 {
            layout.push(format!("{} preamble lines skipped", options.skip_lines));
        }
        notices.push(format!("{}: read as {}", path.display(), layout.join(", ")));
        // A last line cut short by an interrupted recording.
        if let Some((r, line)) = rows.last().cloned()
            && rows.len() > 1
            && split(text_of(&r), separator).len() < width
        {
            rows.pop();
            notices.push(format!(
                "{}: line {line}: skipped a truncated last line ({} of {width} fields; the \
                 recording was likely interrupted)",
                path.display(),
                split(text_of(&r), separator).len()
            ));
        }
        if rows.is_empty() {
            return Err(fail("no data rows".into()));
        }
        let lines = rows.iter().map(|(_, l)| *l).collect();
        Ok(TextColumns {
            path: path.to_path_buf(),
            bytes,
            separator,
            decimal_comma,
            columns,
            rows,
            lines,
            notices,
        })
    }
}

/// The separator of a file: the one that splits the first line and every sampled line into
/// the same number (at least two) of cells, the most cells winning, a delimiter before
/// whitespace runs on a tie (a test machine's file mixes tabs and spaces).
fn detect_separator(first: &[u8], sample: &[&[u8]]) -> Option<Separator> {
    let full = &sample[..sample.len().saturating_sub(1)];
    let mut best: Option<(Separator, usize)> = None;
    for s in [
        Separator::Comma,
        Separator::Semicolon,
        Separator::Tab,
        Separator::Whitespace,
    ] {
        let n = split(first, s).len();
        let consistent = n >= 2 && full.iter().all(|l| split(l, s).len() == n);
        if consistent && best.is_none_or(|(_, m)| n > m) {
            best = Some((s, n));
        }
    }
    best.map(|(s, _)| s)
}

impl ColumnFile for TextColumns {
    fn format(&self) -> &'static str {
        FORMAT
    }

    fn columns(&self) -> &[ColumnInfo] {
        &self.columns
    }

    fn row_lines(&self) -> Option<&[u64]> {
        Some(&self.lines)
    }

    fn notices(&self) -> Vec<String> {
        self.notices.clone()
    }

    fn read(&mut self, picks: &[(usize, bool)]) -> Result<Vec<RawValues>, TableError> {
        let width = self.columns.len();
        let mut numbers: Vec<Vec<f64>> = picks
            .iter()
            .map(|_| Vec::with_capacity(self.rows.len()))
            .collect();
        let mut texts: Vec<Option<Vec<String>>> = picks.iter().map(|_| None).collect();
        let fail = |line: u64, message: String| TableError::Format {
            path: self.path.clone(),
            format: FORMAT,
            message: format!("line {line}: {message}"),
        };
        // A row's cells, borrowed from the file's bytes where they can be (`split_in_place`).
        let mut in_place: Vec<&str> = Vec::with_capacity(width);
        for (r, line) in &self.rows {
            let raw = &self.bytes[r.clone()];
            let raw = raw.strip_suffix(b"\n").unwrap_or(raw);
            let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
            let owned: Vec<String>;
            let borrowed: Vec<&str>;
            let cells: &[&str] = if split_in_place(raw, self.separator, &mut in_place) {
                &in_place
            } else {
                owned = split(raw, self.separator);
                borrowed = owned.iter().map(String::as_str).collect();
                &borrowed
            };
            if cells.len() != width {
                return Err(fail(
                    *line,
                    format!("{} fields where the table has {width}", cells.len()),
                ));
            }
            for (k, &(col, text_ok)) in picks.iter().enumerate() {
                let cell = cells[col].trim();
                if let Some(t) = &mut texts[k] {
                    t.push(cell.to_string());
                    continue;
                }
                let parsed = if self.decimal_comma && cell.contains(',') {
                    cell.replace(',', ".").parse::<f64>().ok()
                } else {
                    fast_float2::parse::<f64, _>(cell.as_bytes())
                        .ok()
                        .or_else(|| cell.parse::<f64>().ok())
                };
                match parsed {
                    Some(v) if v.is_finite() => numbers[k].push(v),
                    Some(_) => {
                        return Err(fail(
                            *line,
                            format!(
                                "{}: '{cell}' is not finite (NaN or infinite)",
                                self.columns[col].label()
                            ),
                        ));
                    }
                    None if text_ok && numbers[k].is_empty() => {
                        texts[k] = Some(vec![cell.to_string()]);
                    }
                    None if cell.is_empty() => {
                        return Err(fail(
                            *line,
                            format!(
                                "{}: empty cell (a number is required)",
                                self.columns[col].label()
                            ),
                        ));
                    }
                    None => {
                        return Err(fail(
                            *line,
                            format!("{}: '{cell}' is not a number", self.columns[col].label()),
                        ));
                    }
                }
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn open(text: &str) -> TextColumns {
        TextColumns::from_bytes(
            text.as_bytes().to_vec(),
            Path::new("t.txt"),
            &TextOptions::default(),
        )
        .unwrap()
    }

    #[test]
    fn headerless_whitespace_columns_by_position() {
        let mut t = open("  0.000   1.5  -2\n  0.005\t1.25  -3\n0.010 1.0 -4\n");
        assert_eq!(t.separator, Separator::Whitespace);
        assert_eq!(t.columns.len(), 3);
        assert!(t.columns.iter().all(|c| c.name.is_none()));
        let v = t.read(&[(0, false), (2, false)]).unwrap();
        assert_eq!(v[0], RawValues::Numbers(vec![0.0, 0.005, 0.010]));
        assert_eq!(v[1], RawValues::Numbers(vec![-2.0, -3.0, -4.0]));
    }

    #[test]
    fn header_with_units_in_names_and_date_times() {
        let mut t = open(
            "Timestamp,Force (N),Displacement (mm),Temp [degC]\n\
             2024-03-01T12:00:00.000,1.5,2,20\n\
             2024-03-01T12:00:00.005,1.6,3,20\n",
        );
        assert_eq!(t.separator, Separator::Comma);
        assert_eq!(t.columns[1].unit.as_deref(), Some("N"));
        assert_eq!(t.columns[2].unit.as_deref(), Some("mm"));
        assert_eq!(t.columns[0].unit, None);
        let v = t.read(&[(0, true), (2, false)]).unwrap();
        assert!(matches!(&v[0], RawValues::Text(c) if c.len() == 2));
        assert_eq!(t.lines, [2, 3]);
    }

    #[test]
    fn units_row_decimal_commas_preamble_and_comments() {
        let text = "DAQ export v2\nOperator: x\n# channels\nZeit;Weg;Kraft\ns;mm;kN\n0,000;1,5;2\n% pause\n0,001;1,6;2,5\n";
        let mut t = TextColumns::from_bytes(
            text.as_bytes().to_vec(),
            Path::new("t.txt"),
            &TextOptions {
                skip_lines: 2,
                ..TextOptions::default()
            },
        )
        .unwrap();
        assert_eq!(t.separator, Separator::Semicolon);
        assert!(t.decimal_comma);
        assert_eq!(t.columns[2].unit.as_deref(), Some("kN"));
        assert_eq!(t.lines, [6, 8]);
        let v = t.read(&[(2, false)]).unwrap();
        assert_eq!(v[0], RawValues::Numbers(vec![2.0, 2.5]));
        assert!(
            t.notices[0].contains("a units row on line 5"),
            "{:?}",
            t.notices
        );
    }

    #[test]
    fn a_bad_cell_is_named_with_its_line_and_column() {
        let mut t = open("a b\n1 2\n3 x\n5 6\n");
        let e = t.read(&[(1, false)]).unwrap_err().to_string();
        assert!(
            e.contains("t.txt: text: line 3: 'b': 'x' is not a number"),
            "{e}"
        );
    }

    proptest::proptest! {
        /// A row split in place has the cells `split` gives it (the `csv` crate's, or the
        /// whitespace runs'), or is left to `split`.
        #[test]
        fn cells_in_place_are_the_split_cells(
            line in proptest::collection::vec(
                proptest::sample::select(&b"1.5e-3 ,;\t\"\r\n\xc2\xa0\xff-x"[..]),
                0..40,
            ),
            separator in proptest::sample::select(&[
                Separator::Comma,
                Separator::Semicolon,
                Separator::Tab,
                Separator::Whitespace,
            ][..]),
        ) {
            let mut out = Vec::new();
            if split_in_place(&line, separator, &mut out) {
                let cells: Vec<String> = out.iter().map(|c| c.trim().to_string()).collect();
                let reference: Vec<String> =
                    split(&line, separator).iter().map(|c| c.trim().to_string()).collect();
                proptest::prop_assert_eq!(cells, reference);
            }
        }
    }

    #[test]
    fn a_truncated_last_line_is_skipped_with_its_line() {
        let t = open("1 2 3\n4 5 6\n7 8\n");
        assert_eq!(t.lines, [1, 2]);
        assert!(t.notices[1].contains("line 3: skipped a truncated last line"));
    }
}
