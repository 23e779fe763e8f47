//! Checks of the summary an MCAP file offers before the mcap crate's indexed reader trusts it.
//!
//! The crate's `SummaryReader` bounds each summary record by the file size, but parses the
//! length prefixes inside a record (strings, maps) by reserving memory first, and its
//! `IndexedReader` allocates (and zero-fills) a chunk index's `uncompressed_size` before
//! decompressing. A crafted summary could therefore make a small file allocate gigabytes. Here
//! the footer, every summary record's lengths, and every chunk index's offsets and sizes are
//! checked against the file; when something does not hold, the reader ignores the summary and
//! scans the file instead (`scan.rs`, which checks every record as it goes and decompresses
//! without trusting a declared size).
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

use mcap::records::op;

use super::scan;

/// Footer record (opcode, length, summary start, summary offset start, CRC) and closing magic.
const FOOTER_AND_MAGIC: u64 = 1 + 8 + 8 + 8 + 4 + 8;

/// A chunk may declare at most this many times its compressed size (plus [`SMALL_CHUNK`]) for
/// the indexed reader; the writer's zstd chunks come out 2-5 times smaller than their records.
/// A chunk that declares more (highly compressible data, or a crafted size) is read by the scan,
/// which allocates only what the decompressor actually produces.
pub(crate) const MAX_CHUNK_RATIO: u64 = 64;
/// Declared sizes up to this are always accepted.
pub(crate) const SMALL_CHUNK: u64 = 1 << 20;

/// What the summary check found.
#[derive(Debug, PartialEq, Eq)]
pub(crate) enum SummaryCheck {
    /// The file has a well-formed footer whose summary section passed: read it from here.
    Summary { summary_start: u64 },
    /// No summary, or no well-formed footer: the mcap crate's summary reader says which (it
    /// reads only the footer then).
    NoSummary,
    /// The summary cannot be trusted: the reason.
    Untrusted(String),
}

/// Summary-section records the summary reader may parse.
fn summary_opcode(opcode: u8) -> bool {
    matches!(
        opcode,
        op::SCHEMA
            | op::CHANNEL
            | op::CHUNK_INDEX
            | op::ATTACHMENT_INDEX
            | op::METADATA_INDEX
            | op::STATISTICS
            | op::SUMMARY_OFFSET
    ) || opcode > op::DATA_END
}

/// Checks the footer and walks the summary section record by record (reading at most one
/// record, bounded by the file, at a time): each length must stay inside the section and every
/// length prefix inside its record ([`scan::check_lengths`]).
/// Leaves the file at its start.
pub(crate) fn check_summary(file: &mut File, size: u64, record_limit: u64) -> SummaryCheck {
    let check = match check_summary_inner(file, size, record_limit) {
        Ok(c) => c,
        Err(e) => SummaryCheck::Untrusted(format!("cannot read the summary: {e}")),
    };
    match file.seek(SeekFrom::Start(0)) {
        Ok(_) => check,
        Err(e) => SummaryCheck::Untrusted(format!("cannot seek: {e}")),
    }
}

fn check_summary_inner(
    file: &mut File,
    size: u64,
    record_limit: u64,
) -> std::io::Result<SummaryCheck> {
    let magic = mcap::MAGIC.len() as u64;
    if size < magic + FOOTER_AND_MAGIC {
        return Ok(SummaryCheck::NoSummary);
    }
    let footer_at = size - FOOTER_AND_MAGIC;
    let mut tail = [0u8; FOOTER_AND_MAGIC as usize];
    file.seek(SeekFrom::Start(footer_at))?;
    file.read_exact(&mut tail)?;
    if tail[0] != op::FOOTER || &tail[29..] != mcap::MAGIC {
        return Ok(SummaryCheck::NoSummary);
    }
    let u64_at = |at: usize| {
        u64::from_le_bytes(
            tail[at..at + 8]
                .try_into()
                .expect("a slice of length 8 converts to [u8; 8]"),
        )
    };
    let (summary_start, offsets_start) = (u64_at(9), u64_at(17));
    if summary_start == 0 {
        return Ok(SummaryCheck::NoSummary);
    }
    if summary_start < magic || summary_start > footer_at {
        return Ok(SummaryCheck::Untrusted(format!(
            "the footer puts the summary at byte {summary_start}, outside the file's {size} bytes \
             before the footer at {footer_at}"
        )));
    }
    if offsets_start != 0 && !(summary_start..=footer_at).contains(&offsets_start) {
        return Ok(SummaryCheck::Untrusted(format!(
            "the footer puts the summary offsets at byte {offsets_start}, outside the summary \
             ({summary_start}..{footer_at})"
        )));
    }
    file.seek(SeekFrom::Start(summary_start))?;
    let mut pos = summary_start;
    let mut body = Vec::new();
    while pos < footer_at {
        let mut head = [0u8; 9];
        if footer_at - pos < 9 {
            return Ok(SummaryCheck::Untrusted(format!(
                "the summary ends inside a record header at byte {pos}"
            )));
        }
        file.read_exact(&mut head)?;
        let opcode = head[0];
        let len = u64::from_le_bytes(
            head[1..]
                .try_into()
                .expect("the 9-byte header minus its opcode is 8 bytes"),
        );
        let room = footer_at - pos - 9;
        if len > room || len > record_limit {
            return Ok(SummaryCheck::Untrusted(format!(
                "the summary record at byte {pos} (opcode {opcode:#04x}) claims {len} bytes, \
                 {room} are left before the footer"
            )));
        }
        if !summary_opcode(opcode) {
            return Ok(SummaryCheck::Untrusted(format!(
                "the summary holds a record of opcode {opcode:#04x} at byte {pos}, which belongs \
                 in the data section"
            )));
        }
        body.clear();
        body.resize(len as usize, 0);
        file.read_exact(&mut body)?;
        if let Err(e) = scan::check_lengths(opcode, &body) {
            return Ok(SummaryCheck::Untrusted(format!(
                "the summary record at byte {pos}: {e}"
            )));
        }
        pos += 9 + len;
    }
    Ok(SummaryCheck::Summary { summary_start })
}

/// Checks each chunk index against the data section (`8..summary_start`): the chunk lies inside
/// it, its compressed data inside the chunk, and the declared uncompressed size is one the
/// indexed reader may allocate up front (equal to the compressed size without compression, at
/// most [`MAX_CHUNK_RATIO`] times it plus [`SMALL_CHUNK`] with compression, at most
/// `record_limit`).
pub(crate) fn check_chunk_indexes(
    summary: &mcap::Summary,
    summary_start: u64,
    record_limit: u64,
) -> Result<(), String> {
    let magic = mcap::MAGIC.len() as u64;
    for (i, c) in summary.chunk_indexes.iter().enumerate() {
        let what = |detail: String| {
            format!(
                "chunk index {i} (chunk at byte {}): {detail}",
                c.chunk_start_offset
            )
        };
        let end = c.chunk_start_offset.checked_add(c.chunk_length);
        if c.chunk_start_offset < magic || end.is_none_or(|e| e > summary_start) {
            return Err(what(format!(
                "{} bytes from there run outside the data section (bytes {magic}..{summary_start})",
                c.chunk_length
            )));
        }
        let end = end.unwrap_or(u64::MAX);
        let data_end = c
            .compressed_data_offset()
            .ok()
            .and_then(|o| o.checked_add(c.compressed_size));
        if data_end.is_none_or(|e| e > end) {
            return Err(what(format!(
                "{} compressed bytes run past the chunk's end at byte {end}",
                c.compressed_size
            )));
        }
        let allowed = if c.compression.is_empty() {
            c.compressed_size
        } else {
            c.compressed_size
                .saturating_mul(MAX_CHUNK_RATIO)
                .saturating_add(SMALL_CHUNK)
        }
        .min(record_limit);
        let fits = if c.compression.is_empty() {
            c.uncompressed_size == c.compressed_size
        } else {
            c.uncompressed_size <= allowed
        };
        if !fits {
            return Err(what(format!(
                "declares {} bytes uncompressed from {} compressed ({:?}); at most {allowed} are \
                 taken on trust",
                c.uncompressed_size, c.compressed_size, c.compression
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn index(start: u64, len: u64, comp: &str, cs: u64, us: u64) -> mcap::records::ChunkIndex {
        mcap::records::ChunkIndex {
            message_start_time: 0,
            message_end_time: 0,
            chunk_start_offset: start,
            chunk_length: len,
            message_index_offsets: Default::default(),
            message_index_length: 0,
            compression: comp.into(),
            compressed_size: cs,
            uncompressed_size: us,
        }
    }

    fn check(c: mcap::records::ChunkIndex) -> Result<(), String> {
        let summary = mcap::Summary {
            chunk_indexes: vec![c],
            ..Default::default()
        };
        check_chunk_indexes(&summary, 10_000, 1 << 30)
    }

    #[test]
    fn chunk_indexes_are_held_to_the_data_section_and_a_plausible_size() {
        // zstd chunk at 8, 1000 bytes long (to 1008); its data start at 8 + 49 + 4 ("zstd") = 61
        assert!(check(index(8, 1000, "zstd", 900, 4000)).is_ok());
        assert!(check(index(8, 1000, "zstd", 900, 900 * 64 + (1 << 20))).is_ok());
        let e = check(index(8, 1000, "zstd", 900, 900 * 64 + (1 << 20) + 1)).unwrap_err();
        assert!(e.contains("taken on trust"), "{e}");
        assert!(check(index(8, 1000, "", 900, 901)).is_err());
        assert!(check(index(8, 1000, "", 900, 900)).is_ok());
        // outside the data section, or the data past the chunk
        assert!(check(index(9_500, 1000, "zstd", 100, 100)).is_err());
        assert!(check(index(u64::MAX - 10, 1000, "zstd", 100, 100)).is_err());
        assert!(check(index(4, 100, "zstd", 10, 10)).is_err());
        assert!(check(index(8, 1000, "zstd", 948, 948)).is_err());
        assert!(check(index(8, 1000, "zstd", 947, 947)).is_ok());
    }
}
