//! NI TDMS files (LabVIEW, DAQmx logging, npTDMS): the numeric channels whose names forcemap
//! knows, read into records through the CSV contract's rows ([`crate::table`]).
//!
//! Written here rather than taken from a crate: on crates.io, `tdms-rs` 2.0 (recent, pure
//! Rust) reads one chunk per segment and drops the others (NI writers put several chunks in a
//! segment), ignores metadata in segments without a new object list and interleaved data, and
//! sizes buffers from unchecked lengths in the file; `tdms` 0.3 handles those but has had no
//! release for years and opens paths only. The format is small: this reader follows NI's
//! description of it (segments of lead-in, metadata and raw data; little- or big-endian;
//! contiguous or interleaved chunks; object lists carried over between segments) and bounds
//! every length it reads by the bytes that are there.
//!
//! Channels are picked by a channel map (group and channel, [`crate::tabular`]), or without
//! one by forcemap's names ([`crate::table::contract_column`]); a channel's unit is its
//! `unit_string`; time is the `time_s` channel, or else the waveform properties of the
//! picked channels (`wf_start_offset + k * wf_increment`), which must agree.

use std::collections::HashMap;
use std::path::Path;

use crate::csv_export::CsvImport;
use crate::table::TableError;
use crate::tabular::{ColumnFile, ColumnInfo, RawValues, TimeBase};

const FORMAT: &str = "TDMS";
const LEAD_IN: usize = 28;
const TOC_META_DATA: u32 = 1 << 1;
const TOC_NEW_OBJ_LIST: u32 = 1 << 2;
const TOC_RAW_DATA: u32 = 1 << 3;
const TOC_INTERLEAVED: u32 = 1 << 5;
const TOC_BIG_ENDIAN: u32 = 1 << 6;
const TOC_DAQMX_RAW_DATA: u32 = 1 << 7;
const NO_RAW_DATA: u32 = 0xFFFF_FFFF;
const STRING_TYPE: u32 = 0x20;

/// True when `bytes` start as a TDMS file does.
pub fn is_tdms(bytes: &[u8]) -> bool {
    bytes.starts_with(b"TDSm")
}

/// Reads a TDMS file's forcemap channels (named as forcemap names them) into records.
pub fn read_tdms(path: &Path) -> Result<CsvImport, TableError> {
    crate::tabular::read_by_contract_names(path)
}

/// [`read_tdms`] of a file's bytes; `path` names it in errors.
pub fn read_tdms_bytes(bytes: &[u8], path: &Path) -> Result<CsvImport, TableError> {
    let mut file = TdmsColumns::from_bytes(bytes, path)?;
    let map = crate::tabular::default_map(&file, path)?;
    crate::tabular::read_through(&mut file, path, &map, Some)
}

/// A TDMS file as a file of columns: every channel of every group with data, its unit from
/// `unit_string`, its waveform timing from `wf_start_offset` and `wf_increment`.
pub struct TdmsColumns {
    columns: Vec<ColumnInfo>,
    values: Vec<Vec<f64>>,
}

impl TdmsColumns {
    pub fn open(path: &Path) -> Result<TdmsColumns, TableError> {
        let bytes = std::fs::read(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
        TdmsColumns::from_bytes(&bytes, path)
    }

    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<TdmsColumns, TableError> {
        let mut file = parse(bytes).map_err(|message| TableError::Format {
            path: path.to_path_buf(),
            format: FORMAT,
            message,
        })?;
        let mut columns = Vec::new();
        let mut values = Vec::new();
        for p in &file.order {
            let Some((group, channel)) = object_names(p) else {
                continue;
            };
            let obj = file.objects.remove(p).unwrap_or_default();
            let position = columns
                .iter()
                .filter(|c: &&ColumnInfo| c.group.as_deref() == Some(group.as_str()))
                .count()
                + 1;
            let time_base =
                obj.properties
                    .get("wf_increment")
                    .map(|&increment_s| TimeBase::Waveform {
                        start_s: obj
                            .properties
                            .get("wf_start_offset")
                            .copied()
                            .unwrap_or(0.0),
                        increment_s,
                    });
            columns.push(ColumnInfo {
                name: Some(channel),
                group: Some(group),
                position,
                matrix_column: None,
                unit: obj.text_properties.get("unit_string").cloned(),
                time_base,
            });
            values.push(obj.data);
        }
        Ok(TdmsColumns { columns, values })
    }
}

impl ColumnFile for TdmsColumns {
    fn format(&self) -> &'static str {
        FORMAT
    }

    fn columns(&self) -> &[ColumnInfo] {
        &self.columns
    }

    fn read(&mut self, picks: &[(usize, bool)]) -> Result<Vec<RawValues>, TableError> {
        Ok(picks
            .iter()
            .map(|&(k, _)| RawValues::Numbers(std::mem::take(&mut self.values[k])))
            .collect())
    }
}

/// A channel's data type: its size in bytes and how a value becomes an f64 (`None` for types
/// that are not numbers, whose values are skipped).
#[derive(Debug, Clone, Copy, PartialEq)]
struct DataType {
    code: u32,
    size: usize,
}

impl DataType {
    fn of(code: u32) -> Result<DataType, String> {
        let size = match code {
            1 | 5 | 0x21 => 1,      // i8, u8, bool
            2 | 6 => 2,             // i16, u16
            3 | 7 | 9 | 0x19 => 4,  // i32, u32, f32 (with unit)
            4 | 8 | 10 | 0x1A => 8, // i64, u64, f64 (with unit)
            0x44 | 0x08_000c => 16, // timestamp, complex f32
            0x10_000d | 0x0B => 16, // complex f64, extended
            STRING_TYPE => 0,       // variable: sized by the index's byte count
            0xFFFF_FFFF => return Err("DAQmx raw data is not supported".to_string()),
            _ => return Err(format!("unknown data type 0x{code:x}")),
        };
        Ok(DataType { code, size })
    }

    fn value(self, b: &[u8], big: bool) -> Option<f64> {
        macro_rules! num {
            ($t:ty) => {{
                let a = b.try_into().ok()?;
                Some(if big {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                } as f64)
            }};
        }
        match self.code {
            1 => num!(i8),
            2 => num!(i16),
            3 => num!(i32),
            4 => num!(i64),
            5 | 0x21 => num!(u8),
            6 => num!(u16),
            7 => num!(u32),
            8 => num!(u64),
            9 | 0x19 => num!(f32),
            10 | 0x1A => num!(f64),
            _ => None,
        }
    }
}

/// An object's raw data in the segments that follow: type and values per chunk.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RawIndex {
    dtype: DataType,
    values: u64,
    /// Bytes per chunk (strings: as the index says).
    bytes: u64,
}

#[derive(Debug, Default)]
struct Object {
    index: Option<RawIndex>,
    properties: HashMap<String, f64>,
    /// String properties (`unit_string`, `NI_ChannelName`, ...).
    text_properties: HashMap<String, String>,
    data: Vec<f64>,
}

/// What the reader keeps of a file: objects by path, in first-seen order.
#[derive(Debug, Default)]
struct TdmsFile {
    order: Vec<String>,
    objects: HashMap<String, Object>,
}

/// A cursor over a segment's bytes in its byte order; every read is bounds-checked.
struct Cursor<'a> {
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

fn parse(bytes: &[u8]) -> Result<TdmsFile, String> {
    if !is_tdms(bytes) {
        return Err("not a TDMS file (no 'TDSm' tag at byte 0)".to_string());
    }
    let mut file = TdmsFile::default();
    // The objects of the current segment's raw data, in order.
    let mut active: Vec<String> = Vec::new();
    let mut start = 0usize;
    let mut segment = 0usize;
    while start < bytes.len() {
        let at = |m: String| format!("segment {segment} (byte {start}): {m}");
        if bytes.len() - start < LEAD_IN {
            // A lead-in cut short: the recording stopped while writing it.
            break;
        }
        let lead = &bytes[start..start + LEAD_IN];
        if &lead[..4] != b"TDSm" {
            return Err(at("no 'TDSm' tag".to_string()));
        }
        let toc = u32::from_le_bytes([lead[4], lead[5], lead[6], lead[7]]);
        let big = toc & TOC_BIG_ENDIAN != 0;
        if toc & TOC_DAQMX_RAW_DATA != 0 {
            return Err(at("DAQmx raw data is not supported".to_string()));
        }
        let mut c = Cursor {
            b: lead,
            pos: 8,
            big,
        };
        let _version = c.u32().map_err(at)?;
        let next = c.u64().map_err(at)?;
        let raw_offset = c.u64().map_err(at)?;
        let body = start + LEAD_IN;
        // An unfinished last segment (0xFFFF...) runs to the end of the file.
        let end = if next == u64::MAX {
            bytes.len()
        } else {
            usize::try_from(next)
                .ok()
                .and_then(|n| body.checked_add(n))
                .map_or(bytes.len(), |e| e.min(bytes.len()))
        };
        let raw_start = usize::try_from(raw_offset)
            .ok()
            .and_then(|r| body.checked_add(r))
            .filter(|&r| r <= end)
            .ok_or_else(|| {
                at(format!(
                    "raw data offset {raw_offset} is past the segment's end"
                ))
            })?;

        if toc & TOC_META_DATA != 0 {
            let mut m = Cursor {
                b: &bytes[body..raw_start],
                pos: 0,
                big,
            };
            if toc & TOC_NEW_OBJ_LIST != 0 {
                active.clear();
            }
            read_metadata(&mut m, &mut file, &mut active).map_err(at)?;
        }
        if toc & TOC_RAW_DATA != 0 {
            read_raw(
                &bytes[raw_start..end],
                &mut file,
                &active,
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

fn read_raw(
    raw: &[u8],
    file: &mut TdmsFile,
    active: &[String],
    interleaved: bool,
    big: bool,
) -> Result<(), String> {
    let indices: Vec<(&String, RawIndex)> = active
        .iter()
        .filter_map(|p| file.objects.get(p).and_then(|o| o.index).map(|i| (p, i)))
        .collect();
    let chunk: u64 = indices
        .iter()
        .try_fold(0u64, |s, (_, i)| s.checked_add(i.bytes))
        .ok_or("chunk size overflows")?;
    if chunk == 0 {
        return Ok(());
    }
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); indices.len()];
    if interleaved {
        if indices.iter().any(|(_, i)| i.dtype.code == STRING_TYPE) {
            return Err("interleaved string data".to_string());
        }
        let row: usize = indices.iter().map(|(_, i)| i.dtype.size).sum();
        // Whole rows only: a row cut short by an interrupted recording is left out.
        for r in raw.chunks_exact(row) {
            let mut off = 0;
            for (k, (_, i)) in indices.iter().enumerate() {
                if let Some(v) = i.dtype.value(&r[off..off + i.dtype.size], big) {
                    columns[k].push(v);
                }
                off += i.dtype.size;
            }
        }
    } else {
        let mut pos = 0usize;
        // Chunks repeat the objects' layout; the last may be cut short.
        'chunks: while pos < raw.len() {
            for (k, (_, i)) in indices.iter().enumerate() {
                let n = usize::try_from(i.bytes).map_err(|_| "chunk too large")?;
                let have = (raw.len() - pos).min(n);
                let part = &raw[pos..pos + have];
                if i.dtype.size > 0 && i.dtype.code != STRING_TYPE {
                    for b in part.chunks_exact(i.dtype.size) {
                        if let Some(v) = i.dtype.value(b, big) {
                            columns[k].push(v);
                        }
                    }
                }
                pos += have;
                if have < n {
                    break 'chunks;
                }
            }
        }
    }
    for ((p, _), col) in indices.iter().zip(columns) {
        let path = (*p).clone();
        if let Some(o) = file.objects.get_mut(&path) {
            o.data.extend(col);
        }
    }
    Ok(())
}

/// The group and channel names of an object path `/'group'/'channel'` (quotes doubled
/// inside names).
fn object_names(path: &str) -> Option<(String, String)> {
    let mut parts = Vec::new();
    let mut rest = path;
    while let Some(r) = rest.strip_prefix("/'") {
        let mut name = String::new();
        let mut chars = r.char_indices().peekable();
        let mut end = None;
        while let Some((i, ch)) = chars.next() {
            if ch == '\'' {
                if chars.peek().is_some_and(|(_, c)| *c == '\'') {
                    chars.next();
                    name.push('\'');
                } else {
                    end = Some(i + 1);
                    break;
                }
            } else {
                name.push(ch);
            }
        }
        parts.push(name);
        rest = &r[end?..];
    }
    if parts.len() != 2 || !rest.is_empty() {
        return None;
    }
    let channel = parts.pop()?;
    Some((parts.pop()?, channel))
}

#[cfg(test)]
fn channel_name(path: &str) -> Option<String> {
    object_names(path).map(|(_, c)| c)
}

#[cfg(test)]
mod tests;
