//! A TDMS file's segments read for their layout: each segment's lead-in and metadata (the
//! objects, their raw data indices and properties, carried over from segment to segment),
//! and where its raw data lie and how they are laid out, their values counted; the raw data
//! themselves are read later, block by block ([`super::blocks`]).

use std::sync::Arc;

use super::blocks::{Bytes, parts_of_chunk, values_in};
use super::{DataType, Object, RawIndex, STRING_TYPE, Segment, TdmsFile, is_tdms};

pub(super) const LEAD_IN: usize = 28;
pub(super) const TOC_META_DATA: u32 = 1 << 1;
pub(super) const TOC_NEW_OBJ_LIST: u32 = 1 << 2;
pub(super) const TOC_RAW_DATA: u32 = 1 << 3;
pub(super) const TOC_INTERLEAVED: u32 = 1 << 5;
pub(super) const TOC_BIG_ENDIAN: u32 = 1 << 6;
pub(super) const TOC_DAQMX_RAW_DATA: u32 = 1 << 7;
pub(super) const NO_RAW_DATA: u32 = 0xFFFF_FFFF;

/// A cursor over a segment's bytes in its byte order; every read is bounds-checked.
pub(super) struct Cursor<'a> {
    b: &'a [u8],
    pos: usize,
    big: bool,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.b.len());
        let Some(end) = end else {
            return Err(format!(
                "byte {}: {n} bytes needed, {} left",
                self.pos,
                self.b.len() - self.pos
            ));
        };
        let s = &self.b[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, String> {
        let a = self.take(4)?.try_into().map_err(|_| "u32")?;
        Ok(if self.big {
            u32::from_be_bytes(a)
        } else {
            u32::from_le_bytes(a)
        })
    }
    fn u64(&mut self) -> Result<u64, String> {
        let a = self.take(8)?.try_into().map_err(|_| "u64")?;
        Ok(if self.big {
            u64::from_be_bytes(a)
        } else {
            u64::from_le_bytes(a)
        })
    }
    fn string(&mut self) -> Result<String, String> {
        let n = self.u32()? as usize;
        let at = self.pos;
        String::from_utf8(self.take(n)?.to_vec())
            .map_err(|_| format!("byte {at}: a string is not UTF-8"))
    }
}

/// What stopped the reading of a file's layout: its bytes, or reading them.
#[derive(Debug)]
pub(super) enum Fault {
    Format(String),
    Io(std::io::Error),
}

impl From<String> for Fault {
    fn from(m: String) -> Fault {
        Fault::Format(m)
    }
}

/// The file's objects and segments, from its lead-ins and metadata (the raw data are read
/// later, [`TdmsBlocks`](super::TdmsBlocks)): each segment's lead-in and metadata read, its raw data skipped.
pub(super) fn parse(bytes: &mut Bytes) -> Result<TdmsFile, Fault> {
    let len = bytes.len().map_err(Fault::Io)?;
    let mut lead = [0u8; LEAD_IN];
    let n = (len as usize).min(4);
    bytes.read_at(0, &mut lead[..n]).map_err(Fault::Io)?;
    if !is_tdms(&lead[..n]) {
        return Err("not a TDMS file (no 'TDSm' tag at byte 0)"
            .to_string()
            .into());
    }
    let mut file = TdmsFile::default();
    // The objects of the current segment's raw data, in order.
    let mut active: Vec<String> = Vec::new();
    let mut meta = Vec::new();
    let mut start = 0u64;
    let mut segment = 0usize;
    while start < len {
        let at = |m: String| format!("segment {segment} (byte {start}): {m}");
        if len - start < LEAD_IN as u64 {
            // A lead-in cut short: the recording stopped while writing it.
            break;
        }
        bytes.read_at(start, &mut lead).map_err(Fault::Io)?;
        if &lead[..4] != b"TDSm" {
            return Err(at("no 'TDSm' tag".to_string()).into());
        }
        let toc = u32::from_le_bytes([lead[4], lead[5], lead[6], lead[7]]);
        let big = toc & TOC_BIG_ENDIAN != 0;
        if toc & TOC_DAQMX_RAW_DATA != 0 {
            return Err(at("DAQmx raw data is not supported".to_string()).into());
        }
        let mut c = Cursor {
            b: &lead,
            pos: 8,
            big,
        };
        let _version = c.u32().map_err(at)?;
        let next = c.u64().map_err(at)?;
        let raw_offset = c.u64().map_err(at)?;
        let body = start + LEAD_IN as u64;
        // An unfinished last segment (0xFFFF...) runs to the end of the file.
        let end = if next == u64::MAX {
            len
        } else {
            body.checked_add(next).map_or(len, |e| e.min(len))
        };
        let raw_start = body
            .checked_add(raw_offset)
            .filter(|&r| r <= end)
            .ok_or_else(|| {
                at(format!(
                    "raw data offset {raw_offset} is past the segment's end"
                ))
            })?;

        if toc & TOC_META_DATA != 0 {
            meta.resize((raw_start - body) as usize, 0);
            bytes.read_at(body, &mut meta).map_err(Fault::Io)?;
            let mut m = Cursor {
                b: &meta,
                pos: 0,
                big,
            };
            if toc & TOC_NEW_OBJ_LIST != 0 {
                active.clear();
            }
            read_metadata(&mut m, &mut file, &mut active).map_err(at)?;
        }
        if toc & TOC_RAW_DATA != 0 {
            add_raw(
                &mut file,
                &active,
                raw_start,
                end - raw_start,
                toc & TOC_INTERLEAVED != 0,
                big,
            )
            .map_err(at)?;
        }
        if end <= start {
            break;
        }
        start = end;
        segment += 1;
    }
    Ok(file)
}

fn read_metadata(
    c: &mut Cursor,
    file: &mut TdmsFile,
    active: &mut Vec<String>,
) -> Result<(), String> {
    let count = c.u32()?;
    for _ in 0..count {
        let path = c.string()?;
        let index = c.u32()?;
        let obj = file.objects.entry(path.clone()).or_insert_with(|| {
            file.order.push(path.clone());
            Object::default()
        });
        match index {
            NO_RAW_DATA => {
                obj.index = None;
                active.retain(|p| *p != path);
            }
            // "As in the previous segment": the object keeps its index.
            0 => {
                if obj.index.is_none() {
                    return Err(format!(
                        "object {path}: reuses a raw data index it never had"
                    ));
                }
                if !active.contains(&path) {
                    active.push(path.clone());
                }
            }
            0x6912_0000 | 0x6913_0000 | 0x6914_0000 | 0x6915_0000 => {
                return Err(format!("object {path}: DAQmx raw data is not supported"));
            }
            len => {
                let at = c.pos;
                let dtype = DataType::of(c.u32()?).map_err(|e| format!("object {path}: {e}"))?;
                let dimension = c.u32()?;
                if dimension != 1 {
                    return Err(format!(
                        "object {path}: array dimension {dimension} (only 1 is defined)"
                    ));
                }
                let values = c.u64()?;
                let bytes = if dtype.code == STRING_TYPE {
                    c.u64()?
                } else {
                    values
                        .checked_mul(dtype.size as u64)
                        .ok_or_else(|| format!("object {path}: {values} values overflow"))?
                };
                // The index's length counts itself and what was read (20, or 28 with a byte
                // count); a longer one is skipped to its end, a shorter one is malformed.
                let read = c.pos - at + 4;
                if (len as usize) < read {
                    return Err(format!(
                        "object {path}: raw data index of {len} bytes, {read} needed"
                    ));
                }
                c.take(len as usize - read)?;
                obj.index = Some(RawIndex {
                    dtype,
                    values,
                    bytes,
                });
                if !active.contains(&path) {
                    active.push(path.clone());
                }
            }
        }
        let properties = c.u32()?;
        for _ in 0..properties {
            let name = c.string()?;
            let code = c.u32()?;
            let value = if code == STRING_TYPE {
                let text = c.string()?;
                obj.text_properties.insert(name.clone(), text);
                None
            } else {
                let t = DataType::of(code)
                    .map_err(|e| format!("object {path}, property {name}: {e}"))?;
                t.value(c.take(t.size)?, c.big)
            };
            if let Some(v) = value {
                obj.properties.insert(name, v);
            }
        }
    }
    Ok(())
}

/// A segment's raw data (`raw_len` bytes from `raw_start`) laid out as the `active` objects'
/// indices say: the segment kept for reading and its values counted (a chunk or an
/// interleaved row cut short by an interrupted recording is left out).
fn add_raw(
    file: &mut TdmsFile,
    active: &[String],
    raw_start: u64,
    raw_len: u64,
    interleaved: bool,
    big: bool,
) -> Result<(), String> {
    let layout: Vec<(String, RawIndex)> = active
        .iter()
        .filter_map(|p| {
            file.objects
                .get(p)
                .and_then(|o| o.index)
                .map(|i| (p.clone(), i))
        })
        .collect();
    let chunk: u64 = layout
        .iter()
        .try_fold(0u64, |s, (_, i)| s.checked_add(i.bytes))
        .ok_or("chunk size overflows")?;
    if chunk == 0 {
        return Ok(());
    }
    let mut counts = vec![0u64; layout.len()];
    if interleaved {
        if layout.iter().any(|(_, i)| i.dtype.code == STRING_TYPE) {
            return Err("interleaved string data".to_string());
        }
        let row: u64 = layout.iter().map(|(_, i)| i.dtype.size as u64).sum();
        for (n, (_, i)) in counts.iter_mut().zip(&layout) {
            *n = values_in(i.dtype, (raw_len / row) * i.dtype.size as u64);
        }
    } else {
        if raw_len > 0
            && layout
                .iter()
                .any(|(_, i)| usize::try_from(i.bytes).is_err())
        {
            return Err("chunk too large".to_string());
        }
        let whole = raw_len / chunk;
        for (n, (_, i)) in counts.iter_mut().zip(&layout) {
            *n = whole * values_in(i.dtype, i.bytes);
        }
        if !raw_len.is_multiple_of(chunk) {
            let parts = parts_of_chunk(&layout, chunk, raw_len, whole);
            for ((n, (_, i)), (_, have)) in counts.iter_mut().zip(&layout).zip(parts) {
                *n += values_in(i.dtype, have);
            }
        }
    }
    for ((p, _), n) in layout.iter().zip(counts) {
        if let Some(o) = file.objects.get_mut(p) {
            o.values += n;
        }
    }
    // Segments that repeat the layout before share it.
    let layout = match file.segments.last() {
        Some(last) if *last.layout == layout => last.layout.clone(),
        _ => Arc::new(layout),
    };
    file.segments.push(Segment {
        raw_start,
        raw_len,
        interleaved,
        big,
        layout,
    });
    Ok(())
}
