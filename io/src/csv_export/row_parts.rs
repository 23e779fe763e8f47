//! A chunk's rows parsed on the machine's cores: the chunk cut at row ends into parts, each
//! part's rows split and parsed into numbers on a thread of its own ([`parallel::in_parts_on`]),
//! the parts' rows then assembled into steps in file order by one reader (`row_steps`).
//!
//! A part is read by the same [`Rows`] and cell parsers as one reader would read it, from the
//! same state: a [`Rows`] state is a byte offset and the line feeds before it, so a part that
//! starts where the part before it ended (a row's end) reads the rows one reader would. A part
//! stops before the first row it cannot take on its own (a row with an error, a quote, a lone
//! carriage return): that row and the rest of the chunk are left to one reader, which gives
//! the same records, the same error on the same line, as reading the whole chunk so.

use std::path::Path;
use std::sync::{Mutex, PoisonError};

use forcemap_math::parallel;
use memchr::memchr;

use super::contract::Layout;
use super::row_cells::{RowHead, parse_head, parse_values};
use super::rows::Rows;

/// The rows a part parsed, in order, up to where it stopped. Its buffers are kept from chunk to
/// chunk (the pages of a fresh buffer per chunk cost more than the copying saves, and a
/// thread's own allocations stay with its arena).
#[derive(Default)]
pub(super) struct PartRows {
    /// Where the part starts in the chunk.
    pub start: usize,
    /// The rows' time and labels, each row's line counted from the part's start.
    pub heads: Vec<RowHead>,
    /// The rows' channel values, the layout's channel columns of each row in turn.
    pub values: Vec<f64>,
    /// Where its rows ended: the byte, and the line feeds from the part's start to it.
    pub end: usize,
    pub line_feeds: u64,
}

/// How a chunk's rows are split over the cores.
#[derive(Debug, Clone, Copy)]
pub(super) struct PartRule {
    pub threads: usize,
    /// Rows a part should hold at least.
    pub min_rows: usize,
}

impl PartRule {
    /// One part per core, each of at least [`parallel::PART_MIN_SAMPLES`] rows (a row is a
    /// sample): a short file is read on one thread.
    pub fn of_machine() -> PartRule {
        PartRule {
            threads: parallel::threads(),
            min_rows: parallel::PART_MIN_SAMPLES,
        }
    }

    /// Where the rows of `text` from byte `pos` on are cut into parts: each part's start and
    /// end, the first starting at `pos`, each cut after a row's end (one part below the
    /// rule's size).
    pub fn parts(self, text: &[u8], pos: usize) -> Vec<(usize, usize)> {
        let rest = text.len().saturating_sub(pos);
        let rows = estimated_rows(&text[pos.min(text.len())..]);
        let parts = self.threads.min(rows / self.min_rows.max(1)).max(1);
        let mut starts = vec![pos];
        for k in 1..parts {
            let from = pos + k * rest / parts;
            match row_end_after(text, from) {
                Some(cut) if cut > *starts.last().unwrap_or(&pos) && cut < text.len() => {
                    starts.push(cut);
                }
                _ => {}
            }
        }
        let ends = starts.iter().skip(1).copied().chain([text.len()]);
        starts.iter().copied().zip(ends).collect()
    }
}

/// The rows of `text` estimated from its first line's length.
fn estimated_rows(text: &[u8]) -> usize {
    let first_line = memchr(b'\n', text).map_or(text.len(), |i| i + 1);
    text.len() / first_line.max(1)
}

/// The first row end at or after byte `from`: after a row's line feed, or at it when a carriage
/// return precedes it (one reader consumes a CRLF row's line feed with the next row). A line
/// end of a blank line is not a row end.
fn row_end_after(text: &[u8], mut from: usize) -> Option<usize> {
    loop {
        let lf = from + memchr(b'\n', &text[from..])?;
        let before = |k: usize| lf.checked_sub(k).map(|i| text[i]);
        let line_end = |b: Option<u8>| matches!(b, None | Some(b'\n' | b'\r'));
        match before(1) {
            Some(b'\r') if !line_end(before(2)) => return Some(lf),
            b if !line_end(b) => return Some(lf + 1),
            _ => from = lf + 1,
        }
    }
}

/// The rows of each of `parts` of `text` parsed, a part per thread of `threads`, in order,
/// into the buffers of `kept` (or new ones).
#[allow(
    clippy::too_many_arguments,
    reason = "the text's reading as one reader's"
)]
pub(super) fn parse_parts(
    text: &[u8],
    parts: &[(usize, usize)],
    kept: &mut Vec<PartRows>,
    threads: usize,
    separator: u8,
    width: usize,
    path: &Path,
    layout: &Layout,
) -> Vec<PartRows> {
    // Each part's buffers go to its thread and come back filled. They are sized here for the
    // rows estimated: a buffer a thread grows stays in that thread's allocator arena, which
    // keeps its memory after the reading.
    let columns = layout.channel_cols.len();
    let work: Vec<((usize, usize), Mutex<PartRows>)> = parts
        .iter()
        .map(|&(start, end)| {
            let mut out = kept.pop().unwrap_or_default();
            // An eighth more for lines shorter than the first.
            let rows = estimated_rows(&text[start..end]) * 9 / 8;
            out.heads.reserve(rows.saturating_sub(out.heads.len()));
            out.values
                .reserve((rows * columns).saturating_sub(out.values.len()));
            ((start, end), Mutex::new(out))
        })
        .collect();
    parallel::in_parts_on(threads, &work, 1, |ps| {
        ps.iter()
            .map(|&((start, end), ref out)| {
                let mut out =
                    std::mem::take(&mut *out.lock().unwrap_or_else(PoisonError::into_inner));
                parse_part(
                    &text[..end],
                    start,
                    separator,
                    width,
                    path,
                    layout,
                    &mut out,
                );
                out
            })
            .collect()
    })
}

/// The rows of `text` from byte `start` on into `out`, up to the first row it cannot take on
/// its own.
fn parse_part(
    text: &[u8],
    start: usize,
    separator: u8,
    width: usize,
    path: &Path,
    layout: &Layout,
    out: &mut PartRows,
) {
    let columns = layout.channel_cols.len();
    let mut rows = Rows::of_chunk(text, separator, width, start, 0, false);
    out.start = start;
    out.heads.clear();
    out.values.clear();
    loop {
        (out.end, out.line_feeds) = rows.position();
        // An error ends the part here: one reader reads this row again and reports it.
        let row = match rows.next(path) {
            Ok(true) => parse_head(path, layout, &rows).ok().filter(|head| {
                parse_values(path, layout, &rows, head.line, &mut out.values).is_ok()
            }),
            Ok(false) | Err(_) => None,
        };
        match row {
            Some(head) => out.heads.push(head),
            None => {
                out.values.truncate(out.heads.len() * columns);
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::read::read_bytes;
    use super::super::stream::read_in_chunks;
    use super::super::{CsvError, CsvImport, write_csv};
    use super::*;
    use forcemap_math::recipe::SetupKind;
    use forcemap_math::sim::RunSpec;

    /// One reader: the reference.
    const ONE: PartRule = PartRule {
        threads: 1,
        min_rows: usize::MAX,
    };
    /// Three parts of a few hundred rows at least, so that a test export is read in parts.
    const SPLIT: PartRule = PartRule {
        threads: 3,
        min_rows: 150,
    };

    /// The paper's rig run (sine steps and band-random records) as an export's text.
    fn rig_export(dir: &Path) -> String {
        let records = RunSpec::paper_rig(Some(40.0), 3).simulate().unwrap();
        let path = dir.join("rig.csv");
        write_csv(&path, &records, SetupKind::BaseExcited).unwrap();
        std::fs::read_to_string(path).unwrap()
    }

    /// What a reader gave, every bit told (`Debug` of f64 is its shortest round-trip text).
    fn outcome(r: Result<CsvImport, CsvError>) -> String {
        match r {
            Ok(import) => format!("{import:?}"),
            Err(e) => format!("error: {e}"),
        }
    }

    /// `bytes` read in parts (whole, and chunk by chunk with chunks ending inside lines) is
    /// `bytes` read by one reader; the outcome.
    fn same_in_parts(dir: &Path, name: &str, bytes: &[u8]) -> String {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let one = outcome(read_bytes(bytes, &path, ONE, &mut Some));
        assert_eq!(
            outcome(read_bytes(bytes, &path, SPLIT, &mut Some)),
            one,
            "{name}: whole"
        );
        for chunk in [65_537, 400_003] {
            assert_eq!(
                outcome(read_in_chunks(&path, chunk, SPLIT, &mut Some)),
                one,
                "{name}: chunks of {chunk} bytes"
            );
        }
        one
    }

    /// `text` with line `n` (1-based) replaced by what `f` makes of it.
    fn with_line(text: &str, n: usize, f: impl Fn(&str) -> String) -> String {
        text.split_inclusive('\n')
            .enumerate()
            .map(|(i, l)| if i + 1 == n { f(l) } else { l.to_string() })
            .collect()
    }

    #[test]
    fn rows_read_in_parts_are_one_readers_rows() {
        let dir = tempfile::tempdir().unwrap();
        let plain = rig_export(dir.path());
        let rows = plain.lines().count();
        let header = plain.find('\n').unwrap() + 1;
        assert_eq!(SPLIT.parts(plain.as_bytes(), header).len(), 3);
        assert_eq!(ONE.parts(plain.as_bytes(), header).len(), 1);

        let plain_read = same_in_parts(dir.path(), "plain.csv", plain.as_bytes());
        assert!(plain_read.starts_with("CsvImport"), "{plain_read:.200}");
        let crlf_bom = format!("\u{feff}{}", plain.replace('\n', "\r\n"));
        let read = same_in_parts(dir.path(), "crlf.csv", crlf_bom.as_bytes());
        assert!(read.contains("CRLF line ends"), "{read:.200}");
        // Semicolons, decimal commas and a units row, the last line cut inside its last cell.
        let lab = with_line(&plain.replace(',', ";").replace('.', ","), 1, |h| {
            format!("{h}s;-;Hz;m;m;m/s^2;m;m/s^2\n")
        });
        let cut = lab.trim_end();
        let lab = format!("{};1e", &cut[..cut.rfind(';').unwrap()]);
        let read = same_in_parts(dir.path(), "lab.csv", lab.as_bytes());
        assert!(
            read.contains("skipped a truncated last line"),
            "{read:.300}"
        );
        // Blank lines (CRLF too) where a part may be cut, and at the end.
        let blank = (1..8).fold(plain.clone(), |t, k| {
            with_line(&t, k * rows / 8, |l| format!("\n\r\n\n{l}"))
        });
        same_in_parts(dir.path(), "blank.csv", format!("{blank}\n\n").as_bytes());
        // A quoted cell in the second part: the `csv` crate reads from there.
        let quoted = with_line(&plain, rows / 2, |l| {
            let (time, rest) = l.split_once(',').unwrap();
            format!("\"{time}\",{rest}")
        });
        assert_eq!(
            same_in_parts(dir.path(), "quoted.csv", quoted.as_bytes()),
            plain_read
        );
        // Without labels: every row of one run.
        let unlabelled: String = plain
            .split_inclusive('\n')
            .map(|l| {
                let cells: Vec<&str> = l.split(',').collect();
                format!("{},{}", cells[0], cells[3..].join(","))
            })
            .collect();
        let read = same_in_parts(dir.path(), "unlabelled.csv", unlabelled.as_bytes());
        assert!(read.starts_with("CsvImport"), "{read:.200}");
    }

    #[test]
    fn the_first_bad_row_in_file_order_is_reported_as_one_reader_reports_it() {
        let dir = tempfile::tempdir().unwrap();
        let plain = rig_export(dir.path());
        let rows = plain.lines().count();
        let (early, late) = (rows / 5, rows - 100);
        let non_numeric = |l: &str| l.replacen(',', ",x", 3);
        let time_back = |l: &str| format!("0{}", &l[l.find(',').unwrap()..]);
        let cases: [(&str, String, usize); 6] = [
            ("late_cell", with_line(&plain, late, non_numeric), late),
            (
                "late_field",
                with_line(&plain, late, |l| l.replacen(',', "", 1)),
                late,
            ),
            ("late_time", with_line(&plain, late, time_back), late),
            // A bad row early, another in a later part: the early one.
            (
                "two_cells",
                with_line(&with_line(&plain, late, non_numeric), early, non_numeric),
                early,
            ),
            // A time going back early (found in order, not by a part), a bad cell late.
            (
                "time_then_cell",
                with_line(&with_line(&plain, late, non_numeric), early, time_back),
                early,
            ),
            // The row's time goes back and a channel cell is bad: the time is reported.
            (
                "time_and_cell",
                with_line(&plain, late, |l| {
                    let back = time_back(l);
                    let cells: Vec<&str> = back.trim_end().split(',').collect();
                    format!("{},x\n", cells[..7].join(","))
                }),
                late,
            ),
        ];
        for (name, text, line) in &cases {
            let read = same_in_parts(dir.path(), &format!("{name}.csv"), text.as_bytes());
            assert!(read.starts_with("error: "), "{name}: {read:.200}");
            assert!(
                read.contains(&format!("line {line}")),
                "{name}: {read:.300}"
            );
        }
        // Invalid UTF-8 in a late row.
        let mut bytes = plain.into_bytes();
        let at = (0..bytes.len() - 500)
            .rev()
            .find(|&i| bytes[i].is_ascii_digit())
            .unwrap();
        bytes[at] = 0xff;
        let read = same_in_parts(dir.path(), "utf8.csv", &bytes);
        assert!(read.contains("invalid UTF-8"), "{read:.200}");
    }

    #[test]
    fn parts_are_cut_at_row_ends() {
        let text = b"a\n1,2\r\n\r\n3,4\n\n5,6\r\n7,8\n";
        // After an LF row's line feed; at a CRLF row's line feed; never in blank lines.
        assert_eq!(row_end_after(text, 2), Some(6));
        assert_eq!(row_end_after(text, 7), Some(13));
        assert_eq!(row_end_after(text, 13), Some(18));
        assert_eq!(row_end_after(text, 19), Some(23));
        assert_eq!(row_end_after(text, 23), None);
    }
}
