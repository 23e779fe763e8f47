//! ASAM MDF4 measurement files (`.mf4`, `.mdf`; written by INCA, CANape, asammdf, ...): the
//! channels whose names forcemap knows, read through the `mdf4-rs` crate (pure Rust; 0.3.0, the
//! last release within our rust-version) into records through the CSV contract's rows
//! ([`crate::table`]).
//!
//! Channels are picked by name ([`crate::table::contract_column`]) from one channel group;
//! time is the `time_s` channel, or else the group's master channel (its time stamps, as
//! asammdf's `time` master). Invalid samples (their invalidation bit set) become NaN, which
//! the row rules refuse naming the sample.

use std::path::Path;

use mdf4_rs::MDF;

use crate::csv_export::{CsvImport, TIME_COLUMN};
use crate::table::{SampleTable, TableError, contract_column};

const FORMAT: &str = "MDF4";
/// `cn_type` of a master and a virtual master channel, `cn_sync_type` of time.
const MASTER: u8 = 2;
const VIRTUAL_MASTER: u8 = 3;
const SYNC_TIME: u8 = 1;

/// True when `bytes` start as an MDF file does (finalised or not).
pub fn is_mdf(bytes: &[u8]) -> bool {
    bytes.starts_with(b"MDF     ") || bytes.starts_with(b"UnFinMF ")
}

/// Reads an MDF4 file's forcemap channels into records.
///
/// mdf4-rs 0.3.0 follows some links without checking them (fuzzing found a slice past the
/// file's end within 343 inputs; 0.6 checks them but needs Rust 1.97): the chains of data
/// groups, channel groups and channels are checked here first (inside the file, the expected
/// block, no cycle), and a panic left in the crate is caught and reported as a malformed file.
pub fn read_mdf(path: &Path) -> Result<CsvImport, TableError> {
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
    let table = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| read_table(path)))
        .map_err(|_| {
            fail("malformed: the MDF4 parser (mdf4-rs) failed on a block of this file".to_string())
        })??;
    table.into_import(path, FORMAT)
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

fn read_table(path: &Path) -> Result<SampleTable, TableError> {
    let fail = |message: String| TableError::Format {
        path: path.to_path_buf(),
        format: FORMAT,
        message,
    };
    let name = path
        .to_str()
        .ok_or_else(|| fail("the path is not UTF-8".to_string()))?;
    let mdf = MDF::from_file(name).map_err(|e| fail(e.to_string()))?;

    // The forcemap channels of each group, and the group's master time channel.
    let mut picked: Vec<(usize, Vec<(&'static str, mdf4_rs::Channel<'_>)>)> = Vec::new();
    let groups = mdf.channel_groups();
    for (g, group) in groups.iter().enumerate() {
        let mut found = Vec::new();
        let mut master = None;
        for ch in group.channels() {
            let block = ch.block();
            let name = ch
                .name()
                .map_err(|e| fail(format!("channel group {g}: {e}")))?;
            let column = name.as_deref().and_then(contract_column);
            if let Some(column) = column {
                found.push((column, ch));
            } else if matches!(block.channel_type, MASTER | VIRTUAL_MASTER)
                && block.sync_type == SYNC_TIME
            {
                master = Some(ch);
            }
        }
        if found.is_empty() {
            continue;
        }
        if !found.iter().any(|(c, _)| *c == TIME_COLUMN)
            && let Some(m) = master
        {
            found.insert(0, (TIME_COLUMN, m));
        }
        picked.push((g, found));
    }
    match picked.len() {
        0 => return Ok(SampleTable::default()),
        1 => {}
        _ => {
            let list: Vec<String> = picked
                .iter()
                .map(|(g, f)| {
                    let names: Vec<&str> = f.iter().map(|(c, _)| *c).collect();
                    format!("group {g} ({})", names.join(", "))
                })
                .collect();
            return Err(fail(format!(
                "forcemap channels are in several channel groups: {}; forcemap reads one time \
                 base (put them in one group)",
                list.join("; ")
            )));
        }
    }
    let (g, found) = picked.remove(0);
    let mut table = SampleTable::default();
    for (column, ch) in found {
        let values = ch
            .values()
            .map_err(|e| fail(format!("channel group {g}, channel '{column}': {e}")))?
            .into_iter()
            .map(|v| v.and_then(|v| v.as_f64()).unwrap_or(f64::NAN))
            .collect();
        table.push(column, values, path, FORMAT)?;
    }
    if !table.columns.iter().any(|(c, _)| *c == TIME_COLUMN) {
        return Err(fail(format!(
            "channel group {g} has neither a 'time_s' channel nor a master time channel"
        )));
    }
    Ok(table)
}
