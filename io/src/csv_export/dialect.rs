//! The CSV dialects test labs' DAQ software writes, detected from the first lines of a file and
//! undone before the rows are read, so that `read` parses one form: a UTF-8 byte-order mark,
//! `,` `;` or tab separators, decimal commas (with `;` or tab separators), a units row under
//! the header (`s;m;N`, checked against the contract's SI units), CRLF line ends (the `csv`
//! crate reads them as they are), and a last line cut short by an interrupted recording
//! (skipped with a notice; a malformed line anywhere else stays an error of that line).

use std::borrow::Cow;
use std::path::Path;

use super::error::CsvError;

/// Lines after the header that the detection looks at.
const SAMPLE_LINES: usize = 32;

/// The separators tried, in order of preference on a tie.
const SEPARATORS: [u8; 3] = [b',', b';', b'\t'];

/// How a file is written.
#[derive(Debug, Clone, PartialEq)]
pub struct Dialect {
    pub separator: u8,
    /// Numbers are written `0,25` (with a `;` or tab separator).
    pub decimal_comma: bool,
    pub byte_order_mark: bool,
    pub crlf: bool,
    /// The units row under the header (line 2), one cell per column, when present.
    pub units: Option<Vec<String>>,
}

impl Dialect {
    /// What differs from the plain contract (`,`, decimal point, no units row, LF), for the
    /// notice; `None` when nothing does.
    pub fn describe(&self) -> Option<String> {
        let mut parts = Vec::new();
        match self.separator {
            b';' => parts.push("semicolon separators".to_string()),
            b'\t' => parts.push("tab separators".to_string()),
            _ => {}
        }
        if self.decimal_comma {
            parts.push("decimal commas".to_string());
        }
        if let Some(units) = &self.units {
            parts.push(format!("a units row on line 2 ({})", units.join(" ")));
        }
        if self.byte_order_mark {
            parts.push("a UTF-8 byte-order mark".to_string());
        }
        if self.crlf {
            parts.push("CRLF line ends".to_string());
        }
        (!parts.is_empty()).then(|| parts.join(", "))
    }
}

/// A file made ready for the reader: its text in the plain form but for the separator (byte-
/// order mark dropped, decimal commas made points, a truncated last line cut off), the dialect
/// it was written in, and what the user is told.
#[derive(Debug)]
pub struct Prepared<'a> {
    pub text: Cow<'a, [u8]>,
    pub dialect: Dialect,
    pub notices: Vec<String>,
}

/// What the first lines of a file say: how it is written, the notice of it, where its data
/// start (the line after the header and the units row) and the header's cells.
#[derive(Debug)]
pub(crate) struct Head {
    pub dialect: Dialect,
    pub notices: Vec<String>,
    /// The byte of the file's body (without a byte-order mark) where the data start; `None`
    /// when the lines looked at end before them.
    pub data_start: Option<usize>,
    header_cells: Vec<String>,
}

/// Lines of a file's body that [`detect`] looks at: a file's head of this many complete lines
/// (or the whole file) detects as the whole file does.
pub(crate) const HEAD_LINES: usize = SAMPLE_LINES + 2;

/// Detects the dialect from the first [`HEAD_LINES`] lines of `body` (a file without its
/// byte-order mark); `None` for a file without lines.
pub(crate) fn detect(
    body: &[u8],
    byte_order_mark: bool,
    path: &Path,
) -> Result<Option<Head>, CsvError> {
    let lines = first_line_spans(body, HEAD_LINES);
    let Some(header) = lines.first().cloned() else {
        return Ok(None);
    };
    let crlf = body[..header.end].ends_with(b"\r\n");
    let sample: Vec<&[u8]> = lines
        .iter()
        .skip(1)
        .take(SAMPLE_LINES)
        .map(|s| &body[s.start..s.end])
        .filter(|l| !is_blank(l))
        .collect();
    let separator = detect_separator(&body[header.start..header.end], &sample);
    let header_cells = cells(&body[header.start..header.end], separator);

    // A units row: line 2 holds text where the time column (or, without one, every column)
    // holds a number.
    let second = lines.get(1).map(|s| &body[s.start..s.end]);
    let units = second
        .map(|l| cells(l, separator))
        .filter(|u| is_units_row(&header_cells, u));
    if let Some(u) = &units {
        check_units(&header_cells, u, path)?;
    }
    let data_from = if units.is_some() { 2 } else { 1 };
    let decimal_comma = separator != b','
        && lines
            .iter()
            .skip(data_from)
            .take(SAMPLE_LINES)
            .flat_map(|s| cells(&body[s.start..s.end], separator))
            .any(|c| c.contains(',') && parse_number(&c.replace(',', ".")).is_some());

    let dialect = Dialect {
        separator,
        decimal_comma,
        byte_order_mark,
        crlf,
        units,
    };
    let mut notices = Vec::new();
    if let Some(d) = dialect.describe() {
        notices.push(format!("{}: read as {d}", path.display()));
    }
    Ok(Some(Head {
        dialect,
        notices,
        data_start: lines.get(data_from).map(|s| s.start),
        header_cells,
    }))
}

impl Head {
    /// Why the last data line is read as cut short by an interrupted recording, if it is:
    /// `from_end` yields the data's lines that are not blank, last first.
    pub fn cut_last_line<'b>(
        &self,
        mut from_end: impl Iterator<Item = &'b [u8]>,
    ) -> Option<String> {
        let (separator, decimal_comma) = (self.dialect.separator, self.dialect.decimal_comma);
        let width = self.header_cells.len();
        let text = from_end.next()?;
        let ends_line = text.ends_with(b"\n");
        let found = cells(text, separator);
        let previous = from_end.next().map(|l| cells(l, separator));
        let number = |c: &str| {
            let c = if decimal_comma {
                Cow::Owned(c.replace(',', "."))
            } else {
                Cow::Borrowed(c)
            };
            parse_number(&c).is_some()
        };
        // Cut inside its last cell: the cell is not a number where the line before has one.
        let cut_cell = !ends_line
            && found.len() == width
            && !found.last().is_some_and(|c| number(c))
            && previous.is_some_and(|p| p.last().is_some_and(|c| number(c)));
        if cut_cell {
            Some("its last cell is not a number".to_string())
        } else if found.len() < width {
            Some(format!("{} of {width} fields", found.len()))
        } else {
            None
        }
    }
}

/// The notice of a last line cut short, on line `line` (1-based), `why` from
/// [`Head::cut_last_line`].
pub(crate) fn cut_notice(path: &Path, line: usize, why: &str) -> String {
    format!(
        "{}: line {line}: skipped a truncated last line ({why}; the recording was likely \
         interrupted)",
        path.display()
    )
}

/// Changes the decimal commas of data bytes to points.
pub(crate) fn decimal_points(data: &mut [u8]) {
    for b in data {
        if *b == b',' {
            *b = b'.';
        }
    }
}

/// Detects the dialect of `bytes` (a whole file) and prepares its text; `path` names the file
/// in notices and errors.
pub fn prepare<'a>(bytes: &'a [u8], path: &Path) -> Result<Prepared<'a>, CsvError> {
    let byte_order_mark = bytes.starts_with(b"\xEF\xBB\xBF");
    let body = if byte_order_mark { &bytes[3..] } else { bytes };
    let Some(head) = detect(body, byte_order_mark, path)? else {
        return Ok(Prepared {
            text: Cow::Borrowed(body),
            dialect: Dialect {
                separator: b',',
                decimal_comma: false,
                byte_order_mark,
                crlf: false,
                units: None,
            },
            notices: Vec::new(),
        });
    };
    let mut notices = head.notices.clone();

    // A last data line cut short: skipped, with its line number (the line feeds before it,
    // counted only here: the last lines are found from the end).
    let mut end = body.len();
    let data_start = head.data_start.unwrap_or(body.len());
    let mut from_end =
        LinesFromEnd::new(body, data_start).filter(|s| !is_blank(&body[s.start..s.end]));
    let last = from_end.clone().next();
    if let Some(why) = head.cut_last_line(from_end.by_ref().map(|s| &body[s.start..s.end]))
        && let Some(span) = last
    {
        end = span.start;
        let line = memchr::memchr_iter(b'\n', &body[..span.start]).count() + 1;
        notices.push(cut_notice(path, line, &why));
    }

    let body = &body[..end];
    let text = if head.dialect.decimal_comma {
        // Only the data: header names keep their commas.
        let mut owned = body.to_vec();
        decimal_points(&mut owned[data_start.min(body.len())..]);
        Cow::Owned(owned)
    } else {
        Cow::Borrowed(body)
    };
    Ok(Prepared {
        text,
        dialect: head.dialect,
        notices,
    })
}

/// Byte ranges of the first `count` lines of `body`, each with its line end (`\n`; the last
/// line may have none).
fn first_line_spans(body: &[u8], count: usize) -> Vec<std::ops::Range<usize>> {
    let mut spans = Vec::with_capacity(count);
    let mut start = 0;
    for i in memchr::memchr_iter(b'\n', body) {
        if spans.len() == count {
            return spans;
        }
        spans.push(start..i + 1);
        start = i + 1;
    }
    if start < body.len() && spans.len() < count {
        spans.push(start..body.len());
    }
    spans
}

/// The lines of `body` that start at or after byte `from`, last first, as [`first_line_spans`]
/// gives them.
#[derive(Clone)]
pub(crate) struct LinesFromEnd<'a> {
    body: &'a [u8],
    from: usize,
    end: usize,
}

impl<'a> LinesFromEnd<'a> {
    pub fn new(body: &'a [u8], from: usize) -> LinesFromEnd<'a> {
        LinesFromEnd {
            body,
            from,
            end: body.len(),
        }
    }
}

impl Iterator for LinesFromEnd<'_> {
    type Item = std::ops::Range<usize>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.end == 0 {
            return None;
        }
        // The line ends at `end` (with its line feed, if any); it starts after the line feed
        // before that.
        let start = memchr::memrchr(b'\n', &self.body[..self.end - 1]).map_or(0, |i| i + 1);
        if start < self.from {
            return None;
        }
        let span = start..self.end;
        self.end = start;
        Some(span)
    }
}

pub(crate) fn is_blank(line: &[u8]) -> bool {
    line.iter().all(u8::is_ascii_whitespace)
}

/// The cells of one line (quotes as the `csv` crate reads them), trimmed.
pub(crate) fn cells(line: &[u8], separator: u8) -> Vec<String> {
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .trim(csv::Trim::All)
        .delimiter(separator)
        .from_reader(line);
    let mut record = csv::ByteRecord::new();
    match rdr.read_byte_record(&mut record) {
        Ok(true) => record
            .iter()
            .map(|c| String::from_utf8_lossy(c).into_owned())
            .collect(),
        _ => Vec::new(),
    }
}

/// The separator that splits the header into the most columns with every sampled line
/// (but a possibly truncated last one) having as many; `,` when none does better.
fn detect_separator(header: &[u8], sample: &[&[u8]]) -> u8 {
    let full = &sample[..sample.len().saturating_sub(1)];
    let mut best = (b',', 1);
    for sep in SEPARATORS {
        let n = cells(header, sep).len();
        if n > best.1 && full.iter().all(|l| cells(l, sep).len() == n) {
            best = (sep, n);
        }
    }
    best.0
}

fn parse_number(cell: &str) -> Option<f64> {
    cell.parse::<f64>().ok()
}

fn is_units_row(header: &[String], row: &[String]) -> bool {
    if row.len() != header.len() || row.iter().all(String::is_empty) {
        return false;
    }
    match header
        .iter()
        .position(|h| h == super::contract::TIME_COLUMN)
    {
        Some(t) => !row[t].is_empty() && parse_number(&row[t].replace(',', ".")).is_none(),
        None => row
            .iter()
            .all(|c| parse_number(&c.replace(',', ".")).is_none()),
    }
}

/// The units a column of the contract is in, by its name's SI suffix (the spellings a units
/// row may use); `None` for columns outside the contract, whose units are not checked.
fn contract_units(column: &str) -> Option<&'static [&'static str]> {
    use super::contract::{FREQUENCY_COLUMN, STEP_COLUMN, TIME_COLUMN};
    let known = column == TIME_COLUMN
        || column == STEP_COLUMN
        || column == FREQUENCY_COLUMN
        || forcemap_math::record::Channel::from_name(column).is_some();
    if !known {
        return None;
    }
    Some(if column == STEP_COLUMN {
        &["", "-", "1"]
    } else if column.ends_with("_mps2") {
        &["m/s^2", "m/s²", "m/s2", "m s^-2", "m*s^-2"]
    } else if column.ends_with("_hz") {
        &["Hz", "hz", "1/s"]
    } else if column.ends_with("_s") {
        &["s"]
    } else if column.ends_with("_n") {
        &["N"]
    } else if column.ends_with("_m") {
        &["m"]
    } else {
        return None;
    })
}

/// Each contract column's unit in the units row must be its SI unit: forcemap does not scale,
/// and a file in mm read as m would give wrong parameters without a word.
fn check_units(header: &[String], units: &[String], path: &Path) -> Result<(), CsvError> {
    for (column, unit) in header.iter().zip(units) {
        let bare = unit
            .trim_start_matches(['[', '('])
            .trim_end_matches([']', ')'])
            .trim();
        if let Some(accepted) = contract_units(column)
            && !accepted.contains(&bare)
        {
            return Err(CsvError::WrongUnit {
                path: path.to_path_buf(),
                column: column.clone(),
                unit: unit.clone(),
                expected: accepted
                    .iter()
                    .find(|u| !u.is_empty())
                    .copied()
                    .unwrap_or("-"),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prep(text: &str) -> Prepared<'_> {
        prepare(text.as_bytes(), Path::new("t.csv")).unwrap()
    }

    #[test]
    fn plain_file_is_left_alone() {
        let p = prep("time_s,step,frequency_hz\n0,0,1\n0.1,0,1\n");
        assert_eq!(p.dialect.separator, b',');
        assert!(!p.dialect.decimal_comma && p.dialect.units.is_none());
        assert!(p.notices.is_empty());
        assert!(matches!(p.text, Cow::Borrowed(_)));
    }

    #[test]
    fn semicolon_decimal_comma_units_bom_crlf() {
        let text = "\u{feff}time_s;step;frequency_hz;force_n\r\ns;-;Hz;N\r\n0,0;0;1,5;2\r\n0,1;0;1,5;-0,25\r\n";
        let p = prep(text);
        assert_eq!(p.dialect.separator, b';');
        assert!(p.dialect.decimal_comma && p.dialect.byte_order_mark && p.dialect.crlf);
        assert_eq!(p.dialect.units.as_deref().unwrap(), ["s", "-", "Hz", "N"]);
        assert_eq!(
            std::str::from_utf8(&p.text).unwrap(),
            "time_s;step;frequency_hz;force_n\r\ns;-;Hz;N\r\n0.0;0;1.5;2\r\n0.1;0;1.5;-0.25\r\n"
        );
        let notice = &p.notices[0];
        for what in [
            "semicolon",
            "decimal commas",
            "units row",
            "byte-order mark",
            "CRLF",
        ] {
            assert!(notice.contains(what), "{notice}");
        }
    }

    #[test]
    fn tab_separator_with_points() {
        let p = prep("time_s\tstep\tx,y\n0.5\t0\t1\n0.6\t0\t2\n");
        assert_eq!(p.dialect.separator, b'\t');
        assert!(!p.dialect.decimal_comma);
    }

    #[test]
    fn truncated_last_line_is_cut_with_its_line() {
        let p = prep("time_s,step,f\n0,0,1\n0.1,0,1\n0.2,0");
        assert_eq!(
            std::str::from_utf8(&p.text).unwrap(),
            "time_s,step,f\n0,0,1\n0.1,0,1\n"
        );
        assert!(p.notices[0].contains("line 4") && p.notices[0].contains("2 of 3"));
        // Cut inside the last cell: `1e` is no number where the line before has one.
        let p = prep("time_s,step,f\n0,0,1\n0.1,0,1e");
        assert!(p.notices[0].contains("line 3"), "{:?}", p.notices);
        // A complete last line without a line end is kept.
        let p = prep("time_s,step,f\n0,0,1\n0.1,0,1");
        assert!(p.notices.is_empty());
    }

    #[test]
    fn a_unit_other_than_si_is_refused() {
        let e = prepare(b"time_s;force_n\ns;kN\n0;1\n", Path::new("t.csv")).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("force_n") && msg.contains("kN") && msg.contains("'N'"),
            "{msg}"
        );
        // Units of columns outside the contract are not checked.
        prep("time_s;temp\n[s];degC\n0;1\n");
    }
}
