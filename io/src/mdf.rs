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

use mdf4_rs::MDF;

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
        let bytes = std::fs::read(path).map_err(|source| TableError::Io {
            path: path.to_path_buf(),
            action: "cannot read",
            source,
        })?;
        check_chains(&bytes).map_err(fail)?;
        drop(bytes);
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
        let ColumnBlocks { blocks, .. } = self.read_blocks(picks)?;
        let mut values: Vec<Vec<f64>> = vec![Vec::new(); picks.len()];
        for block in blocks {
            for (v, b) in values.iter_mut().zip(block?) {
                if let RawValues::Numbers(b) = b {
                    v.extend(b);
                }
            }
        }
        Ok(values.into_iter().map(RawValues::Numbers).collect())
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
            for &(k, _) in picks {
                let (g, c) = at[k];
                let channel = &groups[g].channels()[c];
                let error = |e: mdf4_rs::Error| TableError::Format {
                    path: path.clone(),
                    format: FORMAT,
                    message: format!("{}: {e}", columns[k].label()),
                };
                lengths.push(records_of(mdf, g, c).map_err(error)?);
                values.push((channel.iter_values().map_err(error)?, columns[k].label()));
            }
            Ok((lengths, values))
        })?;
        let blocks = std::iter::from_fn(move || {
            let block = catch(&path, || {
                let mut block = Vec::with_capacity(values.len());
                for (it, label) in &mut values {
                    let mut v = Vec::with_capacity(BLOCK_VALUES);
                    for value in it.by_ref().take(BLOCK_VALUES) {
                        let value = value.map_err(|e| TableError::Format {
                            path: path.clone(),
                            format: FORMAT,
                            message: format!("{label}: {e}"),
                        })?;
                        v.push(value.and_then(|v| v.as_f64()).unwrap_or(f64::NAN));
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

/// The records of channel `c` of the `g`-th channel group (counted over the data groups), as
/// the crate reads them for its values.
fn records_of(mdf: &MDF, g: usize, c: usize) -> Result<usize, mdf4_rs::Error> {
    let raw = mdf.raw();
    let (dg, cg) = raw
        .data_groups
        .iter()
        .flat_map(|dg| dg.channel_groups.iter().map(move |cg| (dg, cg)))
        .nth(g)
        .expect("the channel group of a column");
    Ok(cg.raw_channels[c].records(dg, cg, &raw.mmap)?.count())
}

fn u64_at(bytes: &[u8], at: usize) -> Option<u64> {
    let b = bytes.get(at..at.checked_add(8)?)?;
    Some(u64::from_le_bytes(b.try_into().ok()?))
}

/// The chains mdf4-rs 0.3.0 walks unchecked: from the header block (byte 64) the data groups,
/// their channel groups and their channels, each link inside the file at a block of its kind
/// whose links fit in it, no block reached twice.
fn check_chains(bytes: &[u8]) -> Result<(), String> {
    let mut seen = std::collections::HashSet::new();
    // The block at `addr`, checked to be `id`: its start, for reading its links.
    let mut block = |addr: u64, id: &[u8; 4]| -> Result<usize, String> {
        let kind = String::from_utf8_lossy(id).into_owned();
        let a = usize::try_from(addr)
            .ok()
            .filter(|a| a.checked_add(24).is_some_and(|e| e <= bytes.len()))
            .ok_or_else(|| {
                format!("a link to a {kind} block at byte {addr} is outside the file")
            })?;
        if &bytes[a..a + 4] != id {
            return Err(format!("byte {a}: expected a {kind} block"));
        }
        let length = u64_at(bytes, a + 8).unwrap_or(0);
        let links = u64_at(bytes, a + 16).unwrap_or(u64::MAX);
        let fits = links
            .checked_mul(8)
            .and_then(|l| l.checked_add(24))
            .is_some_and(|l| l <= length)
            && (a as u64)
                .checked_add(length)
                .is_some_and(|e| e <= bytes.len() as u64);
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
    let link = |a: usize, k: usize| u64_at(bytes, a + 24 + 8 * k).unwrap_or(0);
    let hd = block(64, b"##HD")?;
    let mut dg = link(hd, 0);
    while dg != 0 {
        let d = block(dg, b"##DG")?;
        let mut cg = link(d, 1);
        while cg != 0 {
            let c = block(cg, b"##CG")?;
            let mut cn = link(c, 1);
            // Its record's data and invalidation bytes (after record id, cycle count, flags,
            // path separator and reserved): records of 0 bytes made the crate divide by zero.
            let links = u64_at(bytes, c + 16).unwrap_or(0) as usize;
            let at = c + 24 + 8 * links + 24;
            let record = bytes
                .get(at..at + 8)
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
                let n = block(cn, b"##CN")?;
                cn = link(n, 0);
            }
            cg = link(c, 0);
        }
        dg = link(d, 0);
    }
    Ok(())
}
