//! The data rows of a CSV export's text, after its header: each row's line and its cells.
//!
//! A row without quotes and without a carriage return other than the one of its CRLF line end
//! (every row a DAQ writes) is split on its separator in place, its fields kept as byte ranges
//! of the text: no allocation per row. From the first row with a quote or a lone carriage
//! return on, the `csv` crate reads the rest. Both give what the `csv` crate gives over the
//! whole text: the same records, the same field-count errors, and the same line numbers, which
//! follow the `csv` crate's counting (a row's line is the count of line feeds consumed when the
//! row before it ended: a CRLF row's line feed is consumed with the next row, and blank lines
//! before a row are consumed after its line is taken).

use std::path::Path;

use memchr::{memchr, memchr_iter, memchr2};

use super::error::{CsvError, csv_error};

/// The rows of `text` from a byte offset on.
pub(super) struct Rows<'a> {
    text: &'a [u8],
    separator: u8,
    /// Fields every row must have (the header's).
    width: usize,
    /// Where the next row is read from, and the `csv` crate's line count there.
    pos: usize,
    line_count: u64,
    /// The current row: its line and its fields' byte ranges in `text` (split in place).
    row_line: u64,
    fields: Vec<(usize, usize)>,
    /// The `csv` crate's reader of the rest, once a row needed it, with the line it started
    /// on, and its current row.
    general: Option<General<'a>>,
    /// The data are UTF-8 throughout (one check for the file; otherwise each row is checked).
    utf8: bool,
    /// `text` holds the rest of the file (else a chunk of whole lines, more to come).
    whole: bool,
    /// A chunk's row needs the `csv` crate, which reads it with the rest of the file.
    wants_rest: bool,
}

struct General<'a> {
    reader: csv::Reader<&'a [u8]>,
    first_line: u64,
    row: csv::ByteRecord,
}

impl<'a> Rows<'a> {
    /// The rows of `text` (a chunk of whole lines of the file) from byte `pos`, where the `csv`
    /// crate's line count is `line` (its position after the header), each to have `width`
    /// fields split on `separator`; `whole`: the chunk holds the rest of the file. A row of a
    /// chunk that is not whole and that needs the `csv` crate (a quote, a lone carriage
    /// return) ends the chunk's rows, with [`Rows::wants_rest`].
    pub fn of_chunk(
        text: &'a [u8],
        separator: u8,
        width: usize,
        pos: usize,
        line: u64,
        whole: bool,
    ) -> Rows<'a> {
        Rows {
            text,
            separator,
            width,
            pos,
            line_count: line,
            row_line: line,
            fields: Vec::with_capacity(width),
            general: None,
            utf8: std::str::from_utf8(&text[pos.min(text.len())..]).is_ok(),
            whole,
            wants_rest: false,
        }
    }

    /// Where the rows ended: the byte and the `csv` crate's line count there (in a chunk that
    /// is not whole, before the blank lines at its end).
    pub fn position(&self) -> (usize, u64) {
        (self.pos, self.line_count)
    }

    /// The chunk's rows ended at a row the `csv` crate must read with the rest of the file
    /// (from [`Rows::position`]).
    pub fn wants_rest(&self) -> bool {
        self.wants_rest
    }

    /// Reads the next row (`false`: no more rows); a row of another width than the header's is
    /// an error naming its line.
    pub fn next(&mut self, path: &Path) -> Result<bool, CsvError> {
        let len = match &mut self.general {
            Some(g) => {
                let more = g.reader.read_byte_record(&mut g.row).map_err(|e| {
                    let e = csv_error(path, e);
                    relative_to(e, g.first_line)
                })?;
                if !more {
                    return Ok(false);
                }
                self.row_line = g.first_line + g.row.position().map_or(1, csv::Position::line) - 1;
                g.row.len()
            }
            None => match self.split() {
                Split::End => return Ok(false),
                Split::Row => self.fields.len(),
                Split::NeedsCsv if !self.whole => {
                    self.wants_rest = true;
                    return Ok(false);
                }
                Split::NeedsCsv => {
                    let reader = csv::ReaderBuilder::new()
                        .has_headers(false)
                        .flexible(true)
                        .delimiter(self.separator)
                        .from_reader(&self.text[self.pos..]);
                    self.general = Some(General {
                        reader,
                        first_line: self.line_count,
                        row: csv::ByteRecord::new(),
                    });
                    return self.next(path);
                }
            },
        };
        if len != self.width {
            return Err(CsvError::Malformed {
                path: path.to_path_buf(),
                line: Some(self.row_line),
                message: format!(
                    "the row has {len} field(s) but the header has {}",
                    self.width
                ),
            });
        }
        Ok(true)
    }

    /// The current row's line, as the `csv` crate counts it.
    pub fn line(&self) -> u64 {
        self.row_line
    }

    /// Cell `col` of the current row, trimmed of ASCII whitespace (empty past the row's end).
    pub fn cell(&self, col: usize) -> &[u8] {
        let raw = match &self.general {
            Some(g) => g.row.get(col),
            None => self.fields.get(col).map(|&(a, b)| &self.text[a..b]),
        };
        raw.unwrap_or(b"").trim_ascii()
    }

    /// The current row refused, as the `csv` crate's string records refuse it, when its
    /// fields are not UTF-8.
    pub fn check_utf8(&self, path: &Path) -> Result<(), CsvError> {
        if self.utf8 {
            return Ok(());
        }
        // The fields joined, as a byte record holds them (an invalid sequence is found where
        // the `csv` crate finds it).
        let joined: Vec<u8>;
        let (bytes, ends): (&[u8], Vec<usize>) = match &self.general {
            Some(g) => (
                g.row.as_slice(),
                (0..g.row.len())
                    .filter_map(|i| g.row.range(i))
                    .map(|r| r.end)
                    .collect(),
            ),
            None => {
                joined = self
                    .fields
                    .iter()
                    .flat_map(|&(a, b)| &self.text[a..b])
                    .copied()
                    .collect();
                let mut end = 0;
                let ends = self
                    .fields
                    .iter()
                    .map(|&(a, b)| {
                        end += b - a;
                        end
                    })
                    .collect();
                (&joined[..], ends)
            }
        };
        let Err(e) = std::str::from_utf8(bytes) else {
            return Ok(());
        };
        let at = e.valid_up_to();
        let field = ends.iter().position(|&end| end > at).unwrap_or(0);
        Err(CsvError::Malformed {
            path: path.to_path_buf(),
            line: Some(self.row_line),
            message: format!("invalid UTF-8 in field {}", field + 1),
        })
    }

    /// Splits the next row in place (the `csv` crate's rules for a row without quotes).
    fn split(&mut self) -> Split {
        let t = self.text;
        let row_line = self.line_count;
        // Line ends at a row's start are blank lines: skipped, line feeds counted.
        let mut p = self.pos;
        let mut line = self.line_count;
        while p < t.len() && (t[p] == b'\n' || t[p] == b'\r') {
            line += u64::from(t[p] == b'\n');
            p += 1;
        }
        if p == t.len() {
            // The blank lines at a chunk's end are left to the next chunk's first row, whose
            // line is counted from before them.
            if self.whole {
                self.pos = p;
                self.line_count = line;
            }
            return Split::End;
        }
        let lf = memchr(b'\n', &t[p..]).map_or(t.len(), |i| p + i);
        let end = if t[lf - 1] == b'\r' { lf - 1 } else { lf };
        if memchr2(b'"', b'\r', &t[p..end]).is_some() {
            // The row is read by the `csv` crate from where this one started.
            return Split::NeedsCsv;
        }
        self.fields.clear();
        let mut from = p;
        for i in memchr_iter(self.separator, &t[p..end]) {
            self.fields.push((from, p + i));
            from = p + i + 1;
        }
        self.fields.push((from, end));
        self.row_line = row_line;
        // The row ends with its terminator: a CR (its LF is consumed with the next row, after
        // that row's line is taken) or an LF.
        (self.pos, self.line_count) = if end < lf || lf == t.len() {
            ((end + 1).min(t.len()), line)
        } else {
            (lf + 1, line + 1)
        };
        Split::Row
    }
}

enum Split {
    Row,
    End,
    /// The row has a quote or a lone carriage return: the `csv` crate reads it.
    NeedsCsv,
}

/// An error of a reader that started on line `first_line` with the line it names in the file.
fn relative_to(e: CsvError, first_line: u64) -> CsvError {
    match e {
        CsvError::Malformed {
            path,
            line,
            message,
        } => CsvError::Malformed {
            path,
            line: line.map(|l| first_line + l - 1),
            message,
        },
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What a reader gives: each row's line and fields, then the error it stopped at.
    type Read = (Vec<(u64, Vec<Vec<u8>>)>, Option<String>);

    /// The rows as the `csv` crate reads the whole text after its header: the reader these
    /// rows stand in for.
    fn by_csv_crate(text: &[u8], separator: u8) -> Option<Read> {
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::Headers)
            .flexible(false)
            .delimiter(separator)
            .from_reader(text);
        rdr.byte_headers().ok()?;
        let mut out = Vec::new();
        let mut row = csv::ByteRecord::new();
        loop {
            match rdr.read_byte_record(&mut row) {
                Ok(true) => {}
                Ok(false) => return Some((out, None)),
                Err(e) => return Some((out, Some(csv_error(Path::new("t"), e).to_string()))),
            }
            let line = row.position().map_or(0, csv::Position::line);
            if let Err(e) = std::str::from_utf8(row.as_slice()) {
                let at = e.valid_up_to();
                let field = (0..row.len())
                    .find(|&i| row.range(i).is_some_and(|r| r.end > at))
                    .unwrap_or(0);
                let e = CsvError::Malformed {
                    path: "t".into(),
                    line: Some(line),
                    message: format!("invalid UTF-8 in field {}", field + 1),
                };
                return Some((out, Some(e.to_string())));
            }
            out.push((line, row.iter().map(|f| f.trim_ascii().to_vec()).collect()));
        }
    }

    /// The rows `rows` has left into `out`, then the error they stopped at.
    fn collect(
        rows: &mut Rows,
        width: usize,
        out: &mut Vec<(u64, Vec<Vec<u8>>)>,
    ) -> Option<String> {
        let path = Path::new("t");
        loop {
            match rows.next(path) {
                Ok(true) => {}
                Ok(false) => return None,
                Err(e) => return Some(e.to_string()),
            }
            if let Err(e) = rows.check_utf8(path) {
                return Some(e.to_string());
            }
            out.push((
                rows.line(),
                (0..width).map(|c| rows.cell(c).to_vec()).collect(),
            ));
        }
    }

    /// The header's width and the `csv` crate's position after it.
    fn after_header(text: &[u8], separator: u8) -> Option<(usize, usize, u64)> {
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::Headers)
            .delimiter(separator)
            .from_reader(text);
        let width = rdr.byte_headers().ok()?.len();
        let at = rdr.position();
        Some((width, at.byte() as usize, at.line()))
    }

    fn by_rows(text: &[u8], separator: u8) -> Option<Read> {
        let (width, pos, line) = after_header(text, separator)?;
        let mut out = Vec::new();
        let error = collect(
            &mut Rows::of_chunk(text, separator, width, pos, line, true),
            width,
            &mut out,
        );
        Some((out, error))
    }

    /// [`by_rows`] with each line its own chunk, as a file read chunk by chunk is read: the
    /// bytes a chunk's rows leave go on to the next chunk, and a row the `csv` crate must read
    /// is read with the rest of the text.
    fn by_line_chunks(text: &[u8], separator: u8) -> Option<Read> {
        let (width, mut pos, mut line) = after_header(text, separator)?;
        let mut out = Vec::new();
        let (mut start, mut end) = (0, pos);
        loop {
            end = memchr(b'\n', &text[end..]).map_or(text.len(), |i| end + i + 1);
            let whole = end == text.len();
            let mut rows = Rows::of_chunk(&text[start..end], separator, width, pos, line, whole);
            if let Some(e) = collect(&mut rows, width, &mut out) {
                return Some((out, Some(e)));
            }
            (pos, line) = rows.position();
            if rows.wants_rest() {
                let mut rows = Rows::of_chunk(&text[start..], separator, width, pos, line, true);
                let error = collect(&mut rows, width, &mut out);
                return Some((out, error));
            }
            if whole {
                return Some((out, None));
            }
            start += pos;
            pos = 0;
        }
    }

    fn same(text: &[u8], separator: u8) {
        let reference = by_csv_crate(text, separator);
        let shown = String::from_utf8_lossy(text);
        assert_eq!(by_rows(text, separator), reference, "{shown:?}");
        assert_eq!(
            by_line_chunks(text, separator),
            reference,
            "in chunks: {shown:?}"
        );
    }

    #[test]
    fn rows_are_the_csv_crates_rows_with_its_lines_and_errors() {
        for text in [
            &b"a,b\n1,2\n\n3,4\n"[..],
            b"a,b\r\n1,2\r\n\r\n3,4\r\n",
            b"\n\na,b\n1, 2 \n",
            b"a,b\n1,2\n\n\n3,4",
            b"a,b\n1,2\n3\n",
            b"a,b\n1,2\n\"3\",4\n5,6,7\n",
            b"a,b\n1,2\r3,4\n",
            b"a,b\n1,\xff\n",
            b"a,b\n1,\xc3,\xa9\n",
            b"a,b\n1,2\r",
            b"a,b\r\n1,2\r\n\r\n\"3\",4\r\n5\r\n",
            b"a,b\r\n1,2\r\n\r\n3,4\r\n5\r\n",
            b"a,b\n",
            b"a,b",
        ] {
            same(text, b',');
        }
        same(b"a;b\r\n0.5;1\r\n\"x;y\";2\r\n", b';');
    }

    proptest! {
        #[test]
        fn any_text_gives_the_csv_crates_rows(
            body in proptest::collection::vec(
                prop_oneof![
                    Just(b'1'), Just(b'.'), Just(b','), Just(b';'), Just(b' '), Just(b'\n'),
                    Just(b'\r'), Just(b'"'), Just(b'\t'), Just(0xc3u8), Just(0xa9u8),
                    Just(0xffu8),
                ],
                0..80,
            ),
            separator in prop_oneof![Just(b','), Just(b';'), Just(b'\t')],
        ) {
            let mut text = b"a,b;c\td\n".to_vec();
            text.extend(body);
            same(&text, separator);
        }
    }
}
