//! A text file's lines, and its table lines found in a first reading.

use std::io::BufRead;

use super::{BOM, SAMPLE_LINES, is_comment};
use crate::table::RowLines;

/// The lines of a text in order, each without its line end (`\n` or `\r\n`), the first
/// without a byte-order mark, with the byte offset it starts at.
pub(super) struct Lines<R> {
    reader: R,
    line: Vec<u8>,
    pub(super) index: usize,
    pub(super) offset: u64,
}

impl<R: BufRead> Lines<R> {
    pub(super) fn new(reader: R) -> Lines<R> {
        Lines {
            reader,
            line: Vec::new(),
            index: 0,
            offset: 0,
        }
    }

    /// The next line: its 0-based index, its byte offset and its text.
    pub(super) fn next_line(&mut self) -> std::io::Result<Option<(usize, u64, &[u8])>> {
        self.line.clear();
        let n = self.reader.read_until(b'\n', &mut self.line)?;
        if n == 0 {
            return Ok(None);
        }
        let (index, offset) = (self.index, self.offset);
        self.index += 1;
        self.offset += n as u64;
        let mut l = &self.line[..];
        if index == 0 {
            l = l.strip_prefix(BOM).unwrap_or(l);
        }
        let l = l
            .strip_suffix(b"\n")
            .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
            .unwrap_or(l);
        Ok(Some((index, offset, l)))
    }
}

/// Whether line `index` is one of the table's: after the preamble, not blank, not a comment.
pub(super) fn is_table_line(index: usize, line: &[u8], skip_lines: usize) -> bool {
    index >= skip_lines && !line.iter().all(u8::is_ascii_whitespace) && !is_comment(line)
}

/// What the first reading finds: the first table lines (for the layout), the last one's place,
/// and every table line's number.
pub(super) struct Scan {
    pub(super) head: Vec<(usize, Vec<u8>)>,
    pub(super) last: Option<(usize, u64)>,
    pub(super) lines: RowLines,
}

pub(super) fn scan(reader: impl BufRead, skip_lines: usize) -> std::io::Result<Scan> {
    let mut lines = Lines::new(reader);
    let mut out = Scan {
        head: Vec::new(),
        last: None,
        lines: RowLines::default(),
    };
    while let Some((index, offset, line)) = lines.next_line()? {
        if !is_table_line(index, line, skip_lines) {
            continue;
        }
        if out.head.len() <= SAMPLE_LINES {
            out.head.push((index, line.to_vec()));
        }
        out.last = Some((index, offset));
        out.lines.push(index as u64 + 1);
    }
    Ok(out)
}
