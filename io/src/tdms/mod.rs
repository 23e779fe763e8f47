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

mod blocks;
mod segments;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use blocks::{Bytes, TdmsBlocks};
use segments::{Fault, parse};

use crate::csv_export::CsvImport;
use crate::table::TableError;
use crate::tabular::{ColumnBlocks, ColumnFile, ColumnInfo, RawValues, TimeBase};

const FORMAT: &str = "TDMS";
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
    path: PathBuf,
    bytes: Bytes,
    columns: Vec<ColumnInfo>,
    /// The object path and the number of values of each column.
    objects: Vec<(String, u64)>,
    segments: Arc<[Segment]>,
}

impl TdmsColumns {
    pub fn open(path: &Path) -> Result<TdmsColumns, TableError> {
        let file = std::fs::File::open(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
        TdmsColumns::of(Bytes::File(file), path)
    }

    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<TdmsColumns, TableError> {
        TdmsColumns::of(Bytes::Memory(bytes.into()), path)
    }

    fn of(mut bytes: Bytes, path: &Path) -> Result<TdmsColumns, TableError> {
        let mut file = parse(&mut bytes).map_err(|f| fault(f, path))?;
        let mut columns = Vec::new();
        let mut objects = Vec::new();
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
            objects.push((p.clone(), obj.values));
        }
        Ok(TdmsColumns {
            path: path.to_path_buf(),
            bytes,
            columns,
            objects,
            segments: file.segments.into(),
        })
    }
}

/// A fault of a file's reading as the error naming the file.
fn fault(f: Fault, path: &Path) -> TableError {
    match f {
        Fault::Format(message) => TableError::Format {
            path: path.to_path_buf(),
            format: FORMAT,
            message,
        },
        Fault::Io(source) => TableError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        },
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
        self.read_blocks(picks)?.whole()
    }

    fn read_blocks(&mut self, picks: &[(usize, bool)]) -> Result<ColumnBlocks<'_>, TableError> {
        let path = self.path.clone();
        let bytes = self.bytes.try_clone().map_err(|source| TableError::Io {
            path: path.clone(),
            action: "cannot read",
            source,
        })?;
        let names = picks
            .iter()
            .map(|&(k, _)| self.objects[k].0.clone())
            .collect();
        let mut reader = TdmsBlocks::new(bytes, self.segments.clone(), names);
        let blocks = std::iter::from_fn(move || match reader.next_block() {
            Ok(block) => block.map(|b| Ok(b.into_iter().map(RawValues::Numbers).collect())),
            Err(source) => Some(Err(TableError::Io {
                path: path.clone(),
                action: "cannot read",
                source,
            })),
        });
        Ok(ColumnBlocks {
            lengths: picks
                .iter()
                .map(|&(k, _)| self.objects[k].1 as usize)
                .collect(),
            blocks: Box::new(blocks),
        })
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

    /// Whether [`value`](Self::value) reads values of this type.
    fn is_number(self) -> bool {
        matches!(self.code, 1..=10 | 0x19 | 0x1A | 0x21)
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
    /// Its values in all segments (none for types that are not numbers).
    values: u64,
}

/// A segment's raw data: where they are and how they are laid out.
#[derive(Debug, Clone)]
struct Segment {
    raw_start: u64,
    raw_len: u64,
    interleaved: bool,
    big: bool,
    /// The objects with raw data, in order, with their indices (shared with the segments
    /// before that have the same).
    layout: Arc<Vec<(String, RawIndex)>>,
}

/// What the reader keeps of a file: objects by path, in first-seen order, and the segments
/// with raw data.
#[derive(Debug, Default)]
struct TdmsFile {
    order: Vec<String>,
    objects: HashMap<String, Object>,
    segments: Vec<Segment>,
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
