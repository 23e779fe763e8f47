//! Text files of columns as DAQs and test machines write them: comma, semicolon, tab or
//! whitespace-run separators, a header row or none, a units row, decimal commas, a preamble of
//! lines to skip, comment lines (`#`, `%`) and blank lines anywhere, a byte-order mark, CRLF
//! line ends, and a last line cut short by an interrupted recording. The layout is detected
//! from the first lines unless the map's `table:` block states it.

use std::io::{BufRead, BufReader, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::datetime::parse_instant;
use super::{ColumnBlocks, ColumnFile, ColumnInfo, RawValues};
use crate::csv_export::dialect::cells;
use crate::table::{RowLines, TableError};
use crate::table_map::{Separator, TextOptions};
use crate::units::unit_in_name;
use blocks::TextBlocks;
use lines::{Lines, Scan, scan};

mod blocks;
mod lines;

const FORMAT: &str = "text";
/// Lines looked at to detect the layout.
const SAMPLE_LINES: usize = 32;
/// Rows read into one block of values.
const BLOCK_ROWS: usize = 1 << 17;
const BOM: &[u8] = b"\xEF\xBB\xBF";

/// A text file's layout and where its rows are. The file is read twice, neither time whole:
/// once to find its table lines (the layout from the first, a cut-short last line from the
/// last), once for the values of the columns picked, a block of rows at a time.
pub struct TextColumns {
    path: PathBuf,
    source: Source,
    skip_lines: usize,
    separator: Separator,
    decimal_comma: bool,
    columns: Vec<ColumnInfo>,
    /// Table lines (not blank, not comments, after the preamble) before the first data row:
    /// the header and the units row.
    data_from: usize,
    /// The 1-based line of each data row.
    lines: RowLines,
    notices: Vec<String>,
    /// Rows a block holds ([`BLOCK_ROWS`]; fewer in tests, to cross blocks).
    block_rows: usize,
}

/// Where the file's bytes are read from.
enum Source {
    File,
    Bytes(Vec<u8>),
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

/// The cells of a data row as [`split`] gives them, found in place (their byte ranges in the
/// line, no allocation) for a row that is UTF-8 without quotes or carriage returns: the row's
/// text; `None` (and `out` unspecified) for any other row, which [`split`] reads.
fn split_in_place<'a>(
    line: &'a [u8],
    separator: Separator,
    out: &mut Vec<std::ops::Range<usize>>,
) -> Option<&'a str> {
    out.clear();
    let text = std::str::from_utf8(line).ok()?;
    let range = |cell: &str| {
        let start = cell.as_ptr() as usize - text.as_ptr() as usize;
        start..start + cell.len()
    };
    match separator_byte(separator) {
        Some(b) => {
            if line.is_empty() || memchr::memchr3(b'"', b'\r', b'\n', line).is_some() {
                return None;
            }
            out.extend(text.split(char::from(b)).map(str::trim_ascii).map(range));
        }
        None => out.extend(text.split_ascii_whitespace().map(range)),
    }
    Some(text)
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
        let file = std::fs::File::open(path).map_err(|source| io_error(path, source))?;
        let scanned = scan(BufReader::with_capacity(1 << 20, file), options.skip_lines)
            .map_err(|source| io_error(path, source))?;
        TextColumns::from_scan(Source::File, scanned, path, options)
    }

    pub fn from_bytes(
        bytes: Vec<u8>,
        path: &Path,
        options: &TextOptions,
    ) -> Result<TextColumns, TableError> {
        let scanned =
            scan(&bytes[..], options.skip_lines).map_err(|source| io_error(path, source))?;
        TextColumns::from_scan(Source::Bytes(bytes), scanned, path, options)
    }

    /// The file's lines from the one with index `index` at byte `offset`.
    fn lines_from(
        &self,
        index: usize,
        offset: u64,
    ) -> Result<Lines<Box<dyn BufRead + '_>>, TableError> {
        let reader: Box<dyn BufRead + '_> = match &self.source {
            Source::File => {
                let mut file = std::fs::File::open(&self.path)
                    .map_err(|source| io_error(&self.path, source))?;
                file.seek(SeekFrom::Start(offset))
                    .map_err(|source| io_error(&self.path, source))?;
                Box::new(BufReader::with_capacity(1 << 20, file))
            }
            Source::Bytes(bytes) => {
                let from = usize::try_from(offset).map_or(bytes.len(), |o| o.min(bytes.len()));
                Box::new(&bytes[from..])
            }
        };
        let mut lines = Lines::new(reader);
        (lines.index, lines.offset) = (index, offset);
        Ok(lines)
    }

    fn from_scan(
        source: Source,
        scanned: Scan,
        path: &Path,
        options: &TextOptions,
    ) -> Result<TextColumns, TableError> {
        let fail = |message: String| TableError::Format {
            path: path.to_path_buf(),
            format: FORMAT,
            message,
        };
        let Scan {
            head: table,
            last,
            lines: table_lines,
        } = scanned;
        let Some((first_index, first)) = table.first() else {
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
            .map(|(_, r)| r.as_slice())
            .collect();
        let separator = match options.separator {
            Some(s) => s,
            None => detect_separator(first, &sample).ok_or_else(|| {
                fail(format!(
                    "line {}: cannot tell how cells are separated (tried comma, semicolon, tab \
                     and whitespace); give table: {{separator: ...}} in the map",
                    first_index + 1
                ))
            })?,
        };
        let first_cells = split(first, separator);
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
            let u = split(second, separator);
            let d = split(third, separator);
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
        let mut lines = table_lines.range(data_from, table_lines.len());
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
        let mut columns_file = TextColumns {
            path: path.to_path_buf(),
            source,
            skip_lines: options.skip_lines,
            separator,
            decimal_comma,
            columns,
            data_from,
            lines: RowLines::default(),
            notices: Vec::new(),
            block_rows: BLOCK_ROWS,
        };
        // A last line cut short by an interrupted recording.
        if lines.len() > 1
            && let Some((index, offset)) = last
        {
            let mut at = columns_file.lines_from(index, offset)?;
            let cut = match at.next_line() {
                Ok(Some((_, _, l))) => Some(split(l, separator).len()).filter(|&n| n < width),
                Ok(None) => None,
                Err(source) => return Err(io_error(path, source)),
            };
            if let Some(fields) = cut {
                lines = lines.range(0, lines.len() - 1);
                notices.push(format!(
                    "{}: line {}: skipped a truncated last line ({fields} of {width} fields; the \
                     recording was likely interrupted)",
                    path.display(),
                    index + 1
                ));
            }
        }
        if lines.is_empty() {
            return Err(fail("no data rows".into()));
        }
        columns_file.lines = lines;
        columns_file.notices = notices;
        Ok(columns_file)
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

fn io_error(path: &Path, source: std::io::Error) -> TableError {
    TableError::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    }
}

impl ColumnFile for TextColumns {
    fn format(&self) -> &'static str {
        FORMAT
    }

    fn columns(&self) -> &[ColumnInfo] {
        &self.columns
    }

    fn row_lines(&self) -> Option<&RowLines> {
        Some(&self.lines)
    }

    fn notices(&self) -> Vec<String> {
        self.notices.clone()
    }

    fn read(&mut self, picks: &[(usize, bool)]) -> Result<Vec<RawValues>, TableError> {
        self.read_blocks(picks)?.whole()
    }

    fn read_blocks(&mut self, picks: &[(usize, bool)]) -> Result<ColumnBlocks<'_>, TableError> {
        let lines = self.lines_from(0, 0)?;
        Ok(ColumnBlocks {
            lengths: vec![self.lines.len(); picks.len()],
            blocks: Box::new(TextBlocks::new(self, lines, picks)),
        })
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
        assert_eq!(t.lines.iter().collect::<Vec<_>>(), [2, 3]);
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
        assert_eq!(t.lines.iter().collect::<Vec<_>>(), [6, 8]);
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
            if let Some(text) = split_in_place(&line, separator, &mut out) {
                let cells: Vec<String> =
                    out.iter().map(|r| text[r.clone()].trim().to_string()).collect();
                let reference: Vec<String> =
                    split(&line, separator).iter().map(|c| c.trim().to_string()).collect();
                proptest::prop_assert_eq!(cells, reference);
            }
        }
    }

    /// A lab's file read a block of rows at a time, the blocks crossing comment and blank
    /// lines, read back as the rows of the file: the values, the lines that name them, and the
    /// date-times counted from the column's first, in the first block.
    #[test]
    fn blocks_of_any_size_read_the_rows_of_the_file() {
        let mut text = String::from("\u{feff}Pruefstand 2\r\nZeit;Weg;Kraft\r\ns;mm;kN\r\n");
        let mut expected = Vec::new();
        for i in 0..40 {
            if i % 7 == 3 {
                text.push_str("# pause\r\n\r\n");
            }
            let line = text.lines().count() + 1;
            text.push_str(&format!(
                "2024-03-01 12:00:{:02}.{:03};{},5;-{i}\r\n",
                i / 4,
                (i % 4) * 250,
                i
            ));
            expected.push((line as u64, i as f64 + 0.5, -f64::from(i)));
        }
        text.push_str("2024-03-01 12:00:10.000;7\r\n");
        let options = TextOptions {
            skip_lines: 1,
            ..TextOptions::default()
        };
        let map = |records: &str| {
            let text = format!(
                "table: {{records: {records}}}\nchannels:\n  time_s: {{channel: Zeit}}\n  \
                 relative_displacement_m: {{channel: Weg}}\n  force_n: {{channel: Kraft}}\n"
            );
            match crate::channel_map::MapFile::from_yaml_str(&text, "map.yaml").unwrap() {
                crate::channel_map::MapFile::Columns(map) => map,
                crate::channel_map::MapFile::Topics(_) => panic!("a map of columns"),
            }
        };
        let whole = map("whole");
        let named = map("[{name: a, rows: [3, 10]}, {name: b, rows: [20, 40]}]");
        let mut reference: Vec<Option<String>> = vec![None, None];
        for block_rows in [1, 2, 3, 7, 39, 40, BLOCK_ROWS] {
            let open = || {
                let mut t = TextColumns::from_bytes(
                    text.clone().into_bytes(),
                    Path::new("t.txt"),
                    &options,
                )
                .unwrap();
                t.block_rows = block_rows;
                t
            };
            let mut t = open();
            assert_eq!(
                t.lines.iter().collect::<Vec<_>>(),
                expected.iter().map(|e| e.0).collect::<Vec<_>>()
            );
            let v = t.read(&[(0, true), (1, false), (2, false)]).unwrap();
            assert!(matches!(&v[0], RawValues::Text(c) if c.len() == 40));
            assert_eq!(
                v[1],
                RawValues::Numbers(expected.iter().map(|e| e.1).collect())
            );
            assert_eq!(
                v[2],
                RawValues::Numbers(expected.iter().map(|e| e.2).collect())
            );
            for (k, map) in [&whole, &named].into_iter().enumerate() {
                let import =
                    super::super::read::read_through(&mut open(), Path::new("t.txt"), map, Some)
                        .unwrap();
                let last = import.records.last().unwrap();
                let end_s = last.start_time_s + (last.len() - 1) as f64 / last.sample_rate_hz;
                assert!((end_s - 9.75).abs() < 1e-9, "{block_rows}: {end_s}");
                let seen = format!(
                    "{:?} {:?} {:?}",
                    import.records, import.warnings, import.notices
                );
                match &reference[k] {
                    None => reference[k] = Some(seen),
                    Some(r) => assert_eq!(r, &seen, "{block_rows}"),
                }
            }
        }
    }

    #[test]
    fn a_bad_cell_in_a_later_block_is_named_with_its_line() {
        let mut t = open("a b\n1 2\n3 4\n% note\n5 6\n7 x\n9 10\n");
        t.block_rows = 2;
        let e = t.read(&[(1, false)]).unwrap_err().to_string();
        assert!(
            e.contains("t.txt: text: line 6: 'b': 'x' is not a number"),
            "{e}"
        );
    }

    #[test]
    fn a_truncated_last_line_is_skipped_with_its_line() {
        let t = open("1 2 3\n4 5 6\n7 8\n");
        assert_eq!(t.lines.iter().collect::<Vec<_>>(), [1, 2]);
        assert!(t.notices[1].contains("line 3: skipped a truncated last line"));
    }
}
