//! ASAM MDF4 measurement files (`.mf4`, `.mdf`; written by INCA, CANape, asammdf, ...): the
//! channels whose names forcemap knows, read through the `mdf4-rs` crate (pure Rust; 0.3.0, the
//! last release within our rust-version) into records through the CSV contract's rows
//! ([`crate::table`]).
//!
//! Channels are picked by a channel map ([`crate::tabular`]), or without one by forcemap's
//! names ([`crate::table::contract_column`]) from one channel group; time is the `time_s`
//! channel, or else the group's master channel (its time stamps, as asammdf's `time`
//! master). Invalid samples (their invalidation bit set) become NaN, which the row rules
//! refuse naming the sample.

use std::path::Path;

use mdf4_rs::{DataType, MDF};

use crate::csv_export::CsvImport;
use crate::table::TableError;
use crate::tabular::{ColumnBlocks, ColumnFile, ColumnInfo, RawValues, TimeBase};

const FORMAT: &str = "MDF4";
/// `cn_type` of a master and a virtual master channel, `cn_sync_type` of time.
const MASTER: u8 = 2;
const VIRTUAL_MASTER: u8 = 3;
const SYNC_TIME: u8 = 1;

/// True when `bytes` start as an MDF file does (finalised or not).
pub fn is_mdf(bytes: &[u8]) -> bool {
    bytes.starts_with(b"MDF     ") || bytes.starts_with(b"UnFinMF ")
}

/// Reads an MDF4 file's forcemap channels (named as forcemap names them) into records.
pub fn read_mdf(path: &Path) -> Result<CsvImport, TableError> {
    crate::tabular::read_by_contract_names(path)
}

/// An MDF4 file as a file of columns: every channel of every channel group, with its unit;
/// a group's master time channel is its time base.
///
/// mdf4-rs 0.3.0 follows some links without checking them (fuzzing found a slice past the
/// file's end within 343 inputs; 0.6 checks them but needs Rust 1.97): the chains of data
/// groups, channel groups and channels are checked here first (inside the file, the expected
/// block, no cycle), and a panic left in the crate is caught and reported as a malformed file.
pub struct MdfColumns {
    path: std::path::PathBuf,
    mdf: MDF,
    columns: Vec<ColumnInfo>,
    /// The channel group and channel of each column.
    at: Vec<(usize, usize)>,
}

fn malformed(path: &Path) -> TableError {
    TableError::Format {
        path: path.to_path_buf(),
        format: FORMAT,
        message: "malformed: the MDF4 parser (mdf4-rs) failed on a block of this file".to_string(),
    }
}

impl MdfColumns {
    pub fn open(path: &Path) -> Result<MdfColumns, TableError> {
        let fail = |message: String| TableError::Format {
            path: path.to_path_buf(),
            format: FORMAT,
            message,
        };
        let file = std::fs::File::open(path)
            .and_then(|f| {
                Ok(FileAt {
                    len: f.metadata()?.len(),
                    file: f,
                })
            })
            .map_err(|source| TableError::Io {
                path: path.to_path_buf(),
                action: "cannot read",
                source,
            })?;
        check_chains(file).map_err(fail)?;
        let name = path
            .to_str()
            .ok_or_else(|| fail("the path is not UTF-8".to_string()))?;
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let mdf = MDF::from_file(name).map_err(|e| fail(e.to_string()))?;
            let mut columns = Vec::new();
            let mut at = Vec::new();
            for (g, group) in mdf.channel_groups().iter().enumerate() {
                let group_name = group
                    .name()
                    .ok()
                    .flatten()
                    .filter(|n| !n.is_empty())
                    .unwrap_or_else(|| g.to_string());
                for (c, ch) in group.channels().iter().enumerate() {
                    let block = ch.block();
                    let name = ch
                        .name()
                        .map_err(|e| fail(format!("channel group {g}: {e}")))?;
                    let is_time = matches!(block.channel_type, MASTER | VIRTUAL_MASTER)
                        && block.sync_type == SYNC_TIME;
                    columns.push(ColumnInfo {
                        name,
                        group: Some(group_name.clone()),
                        position: c + 1,
                        matrix_column: None,
                        unit: ch.unit().ok().flatten(),
                        time_base: is_time.then_some(TimeBase::Master),
                    });
                    at.push((g, c));
                }
            }
            Ok(MdfColumns {
                path: path.to_path_buf(),
                mdf,
                columns,
                at,
            })
        }))
        .map_err(|_| malformed(path))?
    }
}

impl ColumnFile for MdfColumns {
    fn format(&self) -> &'static str {
        FORMAT
    }

    fn columns(&self) -> &[ColumnInfo] {
        &self.columns
    }

    fn read(&mut self, picks: &[(usize, bool)]) -> Result<Vec<RawValues>, TableError> {
        self.read_blocks(picks)?.whole()
    }

    /// Each picked channel's values decoded and converted a block at a time (the file is in
    /// memory, as mdf4-rs reads it; its decoded values are not).
    fn read_blocks(&mut self, picks: &[(usize, bool)]) -> Result<ColumnBlocks<'_>, TableError> {
        let path = self.path.clone();
        let (mdf, at, columns) = (&self.mdf, &self.at, &self.columns);
        let (lengths, mut values) = catch(&path, || {
            let groups = mdf.channel_groups();
            let mut lengths = Vec::new();
            let mut values = Vec::new();
            // The records of a channel group's fixed-length channels are the group's: counted
            // once.
            let mut counted: Vec<(usize, usize)> = Vec::new();
            for &(k, _) in picks {
                let (g, c) = at[k];
                let channel = &groups[g].channels()[c];
                let error = |e: mdf4_rs::Error| TableError::Format {
                    path: path.clone(),
                    format: FORMAT,
                    message: format!("{}: {e}", columns[k].label()),
                };
                let fixed = channel.block().channel_type != 1;
                let count = match counted.iter().find(|(group, _)| fixed && *group == g) {
                    Some(&(_, n)) => n,
                    None => {
                        let n = records_of(mdf, g, c).map_err(error)?.0.count();
                        if fixed {
                            counted.push((g, n));
                        }
                        n
                    }
                };
                lengths.push(count);
                let read = match PlainNumber::of(channel.block()) {
                    Some(number) => {
                        let (records, id_size) = records_of(mdf, g, c).map_err(error)?;
                        ChannelValues::Plain {
                            records,
                            at: id_size + channel.block().byte_offset as usize,
                            number,
                        }
                    }
                    None => ChannelValues::Decoded(channel.iter_values().map_err(error)?),
                };
                values.push((read, columns[k].label()));
            }
            Ok((lengths, values))
        })?;
        let blocks = std::iter::from_fn(move || {
            let block = catch(&path, || {
                let mut block = Vec::with_capacity(values.len());
                for (it, label) in &mut values {
                    let mut v = Vec::with_capacity(BLOCK_VALUES);
                    for value in std::iter::from_fn(|| it.next()).take(BLOCK_VALUES) {
                        v.push(value.map_err(|e| TableError::Format {
                            path: path.clone(),
                            format: FORMAT,
                            message: format!("{label}: {e}"),
                        })?);
                    }
                    block.push(v);
                }
                Ok(block)
            });
            match block {
                Ok(b) if b.first().is_none_or(Vec::is_empty) => None,
                Ok(b) => Some(Ok(b.into_iter().map(RawValues::Numbers).collect())),
                Err(e) => Some(Err(e)),
            }
        });
        Ok(ColumnBlocks {
            lengths,
            blocks: Box::new(blocks),
        })
    }
}

/// Values of each picked channel decoded at a time.
const BLOCK_VALUES: usize = 1 << 17;

/// `f` with a panic in mdf4-rs reported as a malformed file.
fn catch<T>(
    path: &std::path::Path,
    f: impl FnOnce() -> Result<T, TableError>,
) -> Result<T, TableError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).map_err(|_| malformed(path))?
}

/// The records of a channel group, each as its bytes.
type Records<'a> = Box<dyn Iterator<Item = mdf4_rs::Result<&'a [u8]>> + 'a>;

/// The records of channel `c` of the `g`-th channel group (counted over the data groups), as
/// the crate reads them for its values, and the size of their record id.
fn records_of(mdf: &MDF, g: usize, c: usize) -> mdf4_rs::Result<(Records<'_>, usize)> {
    let raw = mdf.raw();
    let (dg, cg) = raw
        .data_groups
        .iter()
        .flat_map(|dg| dg.channel_groups.iter().map(move |cg| (dg, cg)))
        .nth(g)
        .expect("the channel group of a column");
    let id_size = dg.block.record_id_size as usize;
    Ok((cg.raw_channels[c].records(dg, cg, &raw.mmap)?, id_size))
}

/// A channel's values as numbers (NaN for an invalid sample), read by one of two ways.
enum ChannelValues<'a> {
    /// Plain numbers straight from the records' bytes.
    Plain {
        records: Records<'a>,
        /// The channel's first byte in a record.
        at: usize,
        number: PlainNumber,
    },
    /// Decoded and converted by mdf4-rs.
    Decoded(mdf4_rs::ChannelValuesIter<'a>),
}

impl ChannelValues<'_> {
    fn next(&mut self) -> Option<mdf4_rs::Result<f64>> {
        Some(match self {
            ChannelValues::Plain {
                records,
                at,
                number,
            } => records.next()?.map(|r| number.read(r, *at)),
            ChannelValues::Decoded(it) => it
                .next()?
                .map(|v| v.and_then(|v| v.as_f64()).unwrap_or(f64::NAN)),
        })
    }
}

/// A channel whose values are plain numbers: a little-endian float or whole-byte integer at a
/// byte boundary, without a conversion or an invalidation bit. Its values read from the bytes
/// are those mdf4-rs decodes (`decode_value_internal`), without its per-value dispatch.
#[derive(Debug, Clone, Copy)]
enum PlainNumber {
    F64,
    F32,
    Unsigned(usize),
    Signed(usize),
}

impl PlainNumber {
    fn of(b: &mdf4_rs::blocks::ChannelBlock) -> Option<PlainNumber> {
        // cn_flags bits 0 and 1: all values invalid, an invalidation bit.
        let plain = matches!(b.channel_type, 0 | 2)
            && b.conversion.is_none()
            && b.flags & 0b11 == 0
            && b.bit_offset == 0;
        let whole_bytes = matches!(b.bit_count, 8 | 16 | 32 | 64);
        match b.data_type {
            DataType::FloatLE if plain && b.bit_count == 64 => Some(PlainNumber::F64),
            DataType::FloatLE if plain && b.bit_count == 32 => Some(PlainNumber::F32),
            DataType::UnsignedIntegerLE if plain && whole_bytes => {
                Some(PlainNumber::Unsigned(b.bit_count as usize / 8))
            }
            DataType::SignedIntegerLE if plain && whole_bytes => {
                Some(PlainNumber::Signed(b.bit_count as usize / 8))
            }
            _ => None,
        }
    }

    /// The value at byte `at` of `record`; NaN where the record is too short for it.
    fn read(self, record: &[u8], at: usize) -> f64 {
        let size = match self {
            PlainNumber::F64 => 8,
            PlainNumber::F32 => 4,
            PlainNumber::Unsigned(n) | PlainNumber::Signed(n) => n,
        };
        let Some(b) = at.checked_add(size).and_then(|end| record.get(at..end)) else {
            return f64::NAN;
        };
        let mut le = [0u8; 8];
        le[..size].copy_from_slice(b);
        let bits = u64::from_le_bytes(le);
        match self {
            PlainNumber::F64 => f64::from_bits(bits),
            PlainNumber::F32 => f64::from(f32::from_bits(bits as u32)),
            PlainNumber::Unsigned(_) => bits as f64,
            PlainNumber::Signed(n) => {
                let shift = 64 - 8 * n as u32;
                (((bits << shift) as i64) >> shift) as f64
            }
        }
    }
}

/// A file read where its blocks are, a few bytes at a time.
struct FileAt {
    file: std::fs::File,
    len: u64,
}

impl FileAt {
    /// The `n` bytes at `at`, if the file has them.
    fn bytes<const N: usize>(&mut self, at: u64) -> Option<[u8; N]> {
        use std::io::{Read, Seek, SeekFrom};
        let mut b = [0; N];
        at.checked_add(N as u64).filter(|&e| e <= self.len)?;
        self.file.seek(SeekFrom::Start(at)).ok()?;
        self.file.read_exact(&mut b).ok()?;
        Some(b)
    }

    fn u64_at(&mut self, at: u64) -> Option<u64> {
        self.bytes::<8>(at).map(u64::from_le_bytes)
    }
}

/// The chains mdf4-rs 0.3.0 walks unchecked: from the header block (byte 64) the data groups,
/// their channel groups and their channels, each link inside the file at a block of its kind
/// whose links fit in it, no block reached twice. Only the blocks walked are read.
fn check_chains(mut file: FileAt) -> Result<(), String> {
    let mut seen = std::collections::HashSet::new();
    let len = file.len;
    // The block at `addr`, checked to be `id`: its start, for reading its links.
    let mut block = |file: &mut FileAt, addr: u64, id: &[u8; 4]| -> Result<u64, String> {
        let kind = String::from_utf8_lossy(id).into_owned();
        let outside = || format!("a link to a {kind} block at byte {addr} is outside the file");
        let a = usize::try_from(addr)
            .ok()
            .filter(|a| a.checked_add(24).is_some_and(|e| e as u64 <= len))
            .ok_or_else(outside)? as u64;
        let head = file.bytes::<24>(a).ok_or_else(outside)?;
        if &head[..4] != id {
            return Err(format!("byte {a}: expected a {kind} block"));
        }
        let length = u64::from_le_bytes(head[8..16].try_into().expect("8 bytes"));
        let links = u64::from_le_bytes(head[16..24].try_into().expect("8 bytes"));
        let fits = links
            .checked_mul(8)
            .and_then(|l| l.checked_add(24))
            .is_some_and(|l| l <= length)
            && a.checked_add(length).is_some_and(|e| e <= len);
        if !fits || links < 2 {
            return Err(format!(
                "byte {a}: the {kind} block's length or links do not fit"
            ));
        }
        if !seen.insert(a) {
            return Err(format!(
                "byte {a}: the {kind} block is linked twice (a cycle)"
            ));
        }
        Ok(a)
    };
    let link = |file: &mut FileAt, a: u64, k: u64| file.u64_at(a + 24 + 8 * k).unwrap_or(0);
    let f = &mut file;
    let hd = block(f, 64, b"##HD")?;
    let mut dg = link(f, hd, 0);
    while dg != 0 {
        let d = block(f, dg, b"##DG")?;
        let mut cg = link(f, d, 1);
        while cg != 0 {
            let c = block(f, cg, b"##CG")?;
            let mut cn = link(f, c, 1);
            // Its record's data and invalidation bytes (after record id, cycle count, flags,
            // path separator and reserved): records of 0 bytes made the crate divide by zero.
            let links = f.u64_at(c + 16).unwrap_or(0);
            let record = links
                .checked_mul(8)
                .and_then(|l| (c + 48).checked_add(l))
                .and_then(|at| f.bytes::<8>(at))
                .map(|b| {
                    u64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                        + u64::from(u32::from_le_bytes([b[4], b[5], b[6], b[7]]))
                })
                .unwrap_or(0);
            if cn != 0 && record == 0 {
                return Err(format!(
                    "byte {c}: a channel group with channels has records of 0 bytes"
                ));
            }
            while cn != 0 {
                let n = block(f, cn, b"##CN")?;
                cn = link(f, n, 0);
            }
            cg = link(f, c, 0);
        }
        dg = link(f, d, 0);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use mdf4_rs::blocks::ChannelBlock;
    use mdf4_rs::parsing::decoder::decode_channel_value_with_validity;

    /// A plain number read from a record's bytes is the value mdf4-rs decodes from them, bit
    /// for bit, for every plain type, at an offset after a record id, and NaN (mdf4-rs: no
    /// value) where the record is too short.
    #[test]
    fn plain_numbers_are_read_as_the_crate_decodes_them() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let kinds = [
            (DataType::FloatLE, 64),
            (DataType::FloatLE, 32),
            (DataType::UnsignedIntegerLE, 8),
            (DataType::UnsignedIntegerLE, 16),
            (DataType::UnsignedIntegerLE, 32),
            (DataType::UnsignedIntegerLE, 64),
            (DataType::SignedIntegerLE, 8),
            (DataType::SignedIntegerLE, 16),
            (DataType::SignedIntegerLE, 32),
            (DataType::SignedIntegerLE, 64),
        ];
        for (data_type, bit_count) in kinds {
            let block = ChannelBlock {
                data_type,
                bit_count,
                byte_offset: 3,
                ..ChannelBlock::default()
            };
            let number = PlainNumber::of(&block).expect("a plain number");
            let (id, at) = (2, 2 + 3);
            for _ in 0..2000 {
                let record: Vec<u8> = (0..16).map(|_| next() as u8).collect();
                let crate_value = decode_channel_value_with_validity(&record, id, 14, &block)
                    .and_then(|d| d.value.as_f64())
                    .unwrap_or(f64::NAN);
                let ours = number.read(&record, at);
                assert!(
                    ours.to_bits() == crate_value.to_bits()
                        || (ours.is_nan() && crate_value.is_nan()),
                    "{data_type:?} {bit_count}: {ours} against {crate_value}"
                );
            }
            let short = [0u8; 5];
            assert!(number.read(&short, at).is_nan());
            assert!(decode_channel_value_with_validity(&short, id, 14, &block).is_none());
        }
        // A conversion, an invalidation bit or a bit offset: decoded by the crate.
        for block in [
            ChannelBlock {
                data_type: DataType::FloatLE,
                bit_count: 64,
                flags: 0b10,
                ..ChannelBlock::default()
            },
            ChannelBlock {
                data_type: DataType::UnsignedIntegerLE,
                bit_count: 12,
                ..ChannelBlock::default()
            },
            ChannelBlock {
                data_type: DataType::FloatBE,
                bit_count: 64,
                ..ChannelBlock::default()
            },
        ] {
            assert!(PlainNumber::of(&block).is_none(), "{block:?}");
        }
    }
}
