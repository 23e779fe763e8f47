//! A CSV export read from its file chunk by chunk, so that the file's bytes in memory are a
//! chunk and not the file: the dialect from the file's first lines (`dialect::detect`), a last
//! line cut short by an interrupted recording from its last lines (read from the end), then the
//! rows chunk by chunk, each chunk of whole lines. What is read is what [`read_csv_from`](super::read_csv_from) reads
//! from the whole file: the same records, notices and errors.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::path::Path;

use memchr::{memchr_iter, memrchr};

use super::contract::{CsvImport, Layout};
use super::dialect::{self, HEAD_LINES, Head, LinesFromEnd, is_blank};
use super::error::{CsvError, csv_error};
use super::import::{Import, Keep};
use super::read::read_bytes;
use super::row_parts::PartRule;
use super::row_steps::RowSteps;

/// Bytes read from the file at a time.
pub(super) const CHUNK_BYTES: usize = 16 << 20;

/// The bytes of the file's end first looked at for its last lines (doubled until they hold
/// them).
const TAIL_BYTES: u64 = 64 << 10;

const BYTE_ORDER_MARK: &[u8] = b"\xEF\xBB\xBF";

/// Reads the export at `path` in chunks of about `chunk_bytes`. A file whose head (the lines
/// the dialect is detected from) is the whole file is read whole.
pub fn read_csv_in_chunks(path: &Path, chunk_bytes: usize) -> Result<CsvImport, CsvError> {
    read_in_chunks(path, chunk_bytes, PartRule::of_machine(), &mut Some)
}

/// [`read_csv_in_chunks`], each chunk's rows split over the cores by `rule`, each record handed
/// to `keep` as the chunk that completes it is read.
pub(super) fn read_in_chunks(
    path: &Path,
    chunk_bytes: usize,
    rule: PartRule,
    keep: Keep,
) -> Result<CsvImport, CsvError> {
    let chunk_bytes = chunk_bytes.max(1);
    let io_error = |action: &'static str| {
        move |source: io::Error| CsvError::Io {
            path: path.to_path_buf(),
            action,
            source,
        }
    };
    let mut file = File::open(path).map_err(io_error("cannot open for reading"))?;
    let file_len = file.metadata().map_err(io_error("cannot read"))?.len();

    // The head: lines enough to detect the dialect and a line more (the head's lines whole).
    // A short file's buffer is the file's length (and a byte more, to see its end), not a
    // chunk: the buffer is zeroed before it is read into.
    let short = |read: usize| chunk_bytes.min((file_len as usize).saturating_sub(read) + 1);
    let mut buf = Vec::with_capacity(short(0) + (64 << 10));
    let mut lines = 0;
    while lines <= HEAD_LINES {
        let from = buf.len();
        if fill(&mut file, &mut buf, short(from)).map_err(io_error("cannot read"))? == 0 {
            // The whole file is its head.
            return read_bytes(&buf, path, rule, keep);
        }
        lines += memchr_iter(b'\n', &buf[from..]).count();
    }
    let byte_order_mark = buf.starts_with(BYTE_ORDER_MARK);
    let bom = if byte_order_mark {
        BYTE_ORDER_MARK.len()
    } else {
        0
    };
    buf.drain(..bom);
    let body_len = file_len - bom as u64;
    let head = dialect::detect(&buf, byte_order_mark, path)?
        .expect("the head has lines: it has line feeds");
    let data_start = head
        .data_start
        .expect("the head's lines reach past the header and units row");

    // Where the data end: before a last line cut short.
    let cut = cut_last_line(&mut file, &head, bom as u64, body_len, data_start as u64)
        .map_err(io_error("cannot read"))?;
    let end = cut.as_ref().map_or(body_len, |(start, _)| *start);
    let mut read_to = buf.len() as u64;
    if read_to > end {
        buf.truncate(end as usize);
        read_to = end;
    }
    file.seek(SeekFrom::Start(bom as u64 + read_to))
        .map_err(io_error("cannot read"))?;
    let decimal_comma = head.dialect.decimal_comma;
    if decimal_comma {
        let from = data_start.min(buf.len());
        dialect::decimal_points(&mut buf[from..]);
    }

    let separator = head.dialect.separator;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(true)
        .trim(csv::Trim::Headers)
        .flexible(false)
        .delimiter(separator)
        .from_reader(&buf[..]);
    let header = rdr.headers().map_err(|e| csv_error(path, e))?.clone();
    if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
        return Err(CsvError::Empty {
            path: path.to_path_buf(),
        });
    }
    let layout = Layout::of_header(&header, path)?;
    let after_header = rdr.position();
    let (mut pos, mut line) = (after_header.byte() as usize, after_header.line());
    drop(rdr);

    let mut read = RowSteps::new(path, &layout, head.dialect.units.is_some(), rule);
    let mut import = Import::new(layout.clone(), keep);
    // Line feeds of the data before the cut, for the notice's line.
    let mut line_feeds = 0;
    loop {
        let whole = read_to == end;
        // The chunk's whole lines (all of it at the file's end).
        let complete = if whole {
            buf.len()
        } else {
            memrchr(b'\n', &buf).map_or(0, |i| i + 1)
        };
        if complete > pos {
            let ended =
                read.text_rows(&buf[..complete], separator, header.len(), pos, line, whole)?;
            (pos, line) = (ended.pos, ended.line);
            if ended.wants_rest {
                // A row the `csv` crate reads: with the rest of the file, in memory.
                let rest = (end - read_to) as usize;
                let from = buf.len();
                buf.resize(from + rest, 0);
                file.read_exact(&mut buf[from..])
                    .map_err(io_error("cannot read"))?;
                if decimal_comma {
                    dialect::decimal_points(&mut buf[from..]);
                }
                line_feeds += memchr_iter(b'\n', &buf).count();
                read.text_rows(&buf, separator, header.len(), pos, line, true)?;
                break;
            }
            if cut.is_some() {
                line_feeds += memchr_iter(b'\n', &buf[..pos]).count();
            }
            import.records_read(read.take_steps());
            buf.drain(..pos);
            pos = 0;
        }
        if whole {
            break;
        }
        let want = (chunk_bytes as u64).min(end - read_to) as usize;
        let from = buf.len();
        let n = fill(&mut file, &mut buf, want).map_err(io_error("cannot read"))?;
        if n == 0 {
            // The file ended before its length said (it shrank): what was read is the data.
            read_to = end;
            continue;
        }
        if decimal_comma {
            dialect::decimal_points(&mut buf[from..]);
        }
        read_to += n as u64;
    }
    // The file's bytes go before an unlabelled export's segmentation.
    drop(buf);
    let (steps, unlabelled_times) = read.finish()?;
    import.records_read(steps);
    let mut notices = head.notices.clone();
    if let Some((_, why)) = &cut {
        notices.push(dialect::cut_notice(path, line_feeds + 1, why));
    }
    import.finish(path, &unlabelled_times, notices)
}

/// Appends up to `want` bytes of `file` to `buf`; returns how many (0 at the file's end).
fn fill(file: &mut File, buf: &mut Vec<u8>, want: usize) -> io::Result<usize> {
    let from = buf.len();
    buf.resize(from + want, 0);
    let mut got = 0;
    while got < want {
        match file.read(&mut buf[from + got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => {
                buf.truncate(from);
                return Err(e);
            }
        }
    }
    buf.truncate(from + got);
    Ok(got)
}

/// The last data line, if an interrupted recording cut it short: where it starts in the body
/// (the file after `bom` bytes, `body_len` long; the data start at `data_start`) and why it
/// is read as cut. The file's end is read, more of it until it holds the last two lines that are
/// not blank (or reaches the data's start).
fn cut_last_line(
    file: &mut File,
    head: &Head,
    bom: u64,
    body_len: u64,
    data_start: u64,
) -> io::Result<Option<(u64, String)>> {
    let mut tail_bytes = TAIL_BYTES;
    loop {
        let start = body_len.saturating_sub(tail_bytes).max(data_start);
        let mut tail = vec![0; (body_len - start) as usize];
        file.seek(SeekFrom::Start(bom + start))?;
        file.read_exact(&mut tail)?;
        // A line that starts at the window's start may begin before it, unless the window
        // starts at the data.
        let complete = |s: &std::ops::Range<usize>| s.start > 0 || start == data_start;
        let from_end: Vec<std::ops::Range<usize>> = LinesFromEnd::new(&tail, 0)
            .filter(|s| !complete(s) || !is_blank(&tail[s.clone()]))
            .take(2)
            .collect();
        if from_end.iter().all(complete) {
            let last = from_end.first().map(|s| s.start);
            let why = head.cut_last_line(from_end.iter().map(|s| &tail[s.clone()]));
            return Ok(why.zip(last).map(|(why, at)| (start + at as u64, why)));
        }
        tail_bytes *= 2;
    }
}
