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
pub fn read_mdf(path: &Path) -> Result<CsvImport, TableError> {
    read_table(path)?.into_import(path, FORMAT)
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
