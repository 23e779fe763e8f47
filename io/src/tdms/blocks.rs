//! A TDMS file's channel values read a block of rows at a time, after its metadata
//! ([`super::parse`]) has said where each segment's raw data are and how they are laid out:
//! memory follows the block, not the file. Interleaved rows are read a batch at a time; small
//! contiguous chunks a group of chunks at a time; a large chunk (a channel's whole segment
//! written at once) a block of each picked channel's values at a time, read from where each
//! channel's part of the chunk lies.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};
use std::sync::Arc;

use super::{DataType, RawIndex, Segment};

/// Values of each picked channel handed over at a time.
pub(super) const BLOCK_VALUES: usize = 1 << 17;

/// Bytes of small chunks read at once.
const CHUNK_GROUP_BYTES: u64 = 4 << 20;

/// Where a file's bytes are read from.
pub(super) enum Bytes {
    File(File),
    Memory(Arc<[u8]>),
}

impl Bytes {
    pub fn len(&self) -> io::Result<u64> {
        match self {
            Bytes::File(f) => Ok(f.metadata()?.len()),
            Bytes::Memory(b) => Ok(b.len() as u64),
        }
    }

    /// Fills `buf` from byte `at`.
    pub fn read_at(&mut self, at: u64, buf: &mut [u8]) -> io::Result<()> {
        match self {
            Bytes::File(f) => {
                f.seek(SeekFrom::Start(at))?;
                f.read_exact(buf)
            }
            Bytes::Memory(b) => {
                let from = usize::try_from(at).unwrap_or(usize::MAX);
                let src = from
                    .checked_add(buf.len())
                    .and_then(|end| b.get(from..end))
                    .ok_or_else(|| io::Error::from(io::ErrorKind::UnexpectedEof))?;
                buf.copy_from_slice(src);
                Ok(())
            }
        }
    }

    pub fn try_clone(&self) -> io::Result<Bytes> {
        Ok(match self {
            Bytes::File(f) => Bytes::File(f.try_clone()?),
            Bytes::Memory(b) => Bytes::Memory(b.clone()),
        })
    }
}

/// Where each object of a segment's layout lies in chunk `c` of its raw data (`raw_len` bytes,
/// chunks of `chunk` bytes): its offset in the raw data and the bytes it has there (fewer in a
/// last chunk cut short, none after the cut).
pub(super) fn parts_of_chunk(
    layout: &[(String, RawIndex)],
    chunk: u64,
    raw_len: u64,
    c: u64,
) -> Vec<(u64, u64)> {
    let mut off = c * chunk;
    let mut cut = false;
    layout
        .iter()
        .map(|(_, i)| {
            let have = if cut {
                0
            } else {
                raw_len.saturating_sub(off).min(i.bytes)
            };
            cut |= have < i.bytes;
            let part = (off, have);
            off += have;
            part
        })
        .collect()
}

/// The values a part of `bytes` bytes holds of a channel of type `t` (none for types that are
/// not numbers).
pub(super) fn values_in(t: DataType, bytes: u64) -> u64 {
    if t.is_number() {
        bytes / t.size as u64
    } else {
        0
    }
}

/// The picked channels' values, block by block.
pub(super) struct TdmsBlocks {
    bytes: Bytes,
    segments: Arc<[Segment]>,
    /// The object path of each pick.
    picks: Vec<String>,
    segment: usize,
    /// The next chunk (contiguous) and value within it (a large chunk), or row (interleaved).
    chunk: u64,
    value: u64,
    queues: Vec<Vec<f64>>,
    buf: Vec<u8>,
}

impl TdmsBlocks {
    pub fn new(bytes: Bytes, segments: Arc<[Segment]>, picks: Vec<String>) -> TdmsBlocks {
        let queues = vec![Vec::new(); picks.len()];
        TdmsBlocks {
            bytes,
            segments,
            picks,
            segment: 0,
            chunk: 0,
            value: 0,
            queues,
            buf: Vec::new(),
        }
    }

    /// The next block: each pick's values of the same rows (the picks have as many values
    /// each, checked before reading), or `None` at the end.
    pub fn next_block(&mut self) -> io::Result<Option<Vec<Vec<f64>>>> {
        loop {
            let ready = self.queues.iter().map(Vec::len).min().unwrap_or(0);
            let end = self.segment >= self.segments.len();
            if ready >= BLOCK_VALUES || (end && ready > 0) {
                return Ok(Some(
                    self.queues
                        .iter_mut()
                        .map(|q| q.drain(..ready).collect())
                        .collect(),
                ));
            }
            if end {
                return Ok(None);
            }
            self.step()?;
        }
    }

    fn next_segment(&mut self) {
        self.segment += 1;
        self.chunk = 0;
        self.value = 0;
    }

    /// Reads the next piece of the current segment into the queues.
    fn step(&mut self) -> io::Result<()> {
        let seg = self.segments[self.segment].clone();
        // Each pick's place in the layout.
        let at: Vec<Option<usize>> = self
            .picks
            .iter()
            .map(|p| seg.layout.iter().position(|(q, _)| q == p))
            .collect();
        if at.iter().all(Option::is_none) {
            self.next_segment();
            return Ok(());
        }
        if seg.interleaved {
            self.step_interleaved(&seg, &at)
        } else {
            self.step_contiguous(&seg, &at)
        }
    }

    fn step_interleaved(&mut self, seg: &Segment, at: &[Option<usize>]) -> io::Result<()> {
        let row: u64 = seg.layout.iter().map(|(_, i)| i.dtype.size as u64).sum();
        let rows = seg.raw_len / row;
        let n = (BLOCK_VALUES as u64).min(rows.saturating_sub(self.value));
        if n > 0 {
            let offsets: Vec<u64> = seg
                .layout
                .iter()
                .scan(0, |o, (_, i)| {
                    let here = *o;
                    *o += i.dtype.size as u64;
                    Some(here)
                })
                .collect();
            self.buf.resize((n * row) as usize, 0);
            self.bytes
                .read_at(seg.raw_start + self.value * row, &mut self.buf)?;
            for (q, k) in self.queues.iter_mut().zip(at) {
                let Some(k) = *k else { continue };
                let (off, t) = (offsets[k] as usize, seg.layout[k].1.dtype);
                for r in self.buf.chunks_exact(row as usize) {
                    q.extend(t.value(&r[off..off + t.size], seg.big));
                }
            }
        }
        self.value += n;
        if self.value >= rows {
            self.next_segment();
        }
        Ok(())
    }

    fn step_contiguous(&mut self, seg: &Segment, at: &[Option<usize>]) -> io::Result<()> {
        let chunk: u64 = seg.layout.iter().map(|(_, i)| i.bytes).sum();
        let chunks = seg.raw_len.div_ceil(chunk);
        if self.chunk >= chunks {
            self.next_segment();
            return Ok(());
        }
        if chunk <= CHUNK_GROUP_BYTES {
            // Whole chunks at once.
            let group = (CHUNK_GROUP_BYTES / chunk).max(1).min(chunks - self.chunk);
            let from = self.chunk * chunk;
            let len = (group * chunk).min(seg.raw_len - from);
            self.buf.resize(len as usize, 0);
            self.bytes.read_at(seg.raw_start + from, &mut self.buf)?;
            for c in self.chunk..self.chunk + group {
                let parts = parts_of_chunk(&seg.layout, chunk, seg.raw_len, c);
                for (q, k) in self.queues.iter_mut().zip(at) {
                    let Some(k) = *k else { continue };
                    let t = seg.layout[k].1.dtype;
                    let (off, have) = parts[k];
                    let n = values_in(t, have) as usize * t.size;
                    let start = (off - from) as usize;
                    for b in self.buf[start..start + n].chunks_exact(t.size) {
                        q.extend(t.value(b, seg.big));
                    }
                }
            }
            self.chunk += group;
        } else {
            // A block of each pick's values from its part of the chunk.
            let parts = parts_of_chunk(&seg.layout, chunk, seg.raw_len, self.chunk);
            let mut more = false;
            for (q, k) in self.queues.iter_mut().zip(at) {
                let Some(k) = *k else { continue };
                let t = seg.layout[k].1.dtype;
                let (off, have) = parts[k];
                let count = values_in(t, have);
                let n = (BLOCK_VALUES as u64).min(count.saturating_sub(self.value));
                more |= self.value + n < count;
                if n == 0 {
                    continue;
                }
                self.buf.resize((n as usize) * t.size, 0);
                self.bytes.read_at(
                    seg.raw_start + off + self.value * t.size as u64,
                    &mut self.buf,
                )?;
                for b in self.buf.chunks_exact(t.size) {
                    q.extend(t.value(b, seg.big));
                }
            }
            self.value += BLOCK_VALUES as u64;
            if !more {
                self.chunk += 1;
                self.value = 0;
            }
        }
        if self.chunk >= chunks {
            self.next_segment();
        }
        Ok(())
    }
}
