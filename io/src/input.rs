//! Measured data from whichever form the user has: a bag directory, a bare .mcap, or a
//! test-bench CSV export.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::bail;
use forcemap_math::record::{Channel, Record};

use crate::csv_export::{CsvProfile, read_csv};
use crate::rig_bag::read_rig_bag;

/// Records and what came with them.
#[derive(Debug, Clone)]
pub struct Loaded {
    pub records: Vec<Record>,
    pub profile: CsvProfile,
    /// Rig constants carried by the data (bags: `/rig/parameters`).
    pub parameters: BTreeMap<String, f64>,
    /// CSV columns that are not part of the contract.
    pub ignored_columns: Vec<String>,
}

/// True when `path` is a bag (a directory, or a file ending in .mcap).
pub fn is_bag(path: &Path) -> bool {
    path.is_dir() || path.extension().is_some_and(|e| e == "mcap")
}

/// The profile of records from the channels they hold (as for the CSV header).
pub fn profile_of(records: &[Record], source: &str) -> anyhow::Result<CsvProfile> {
    let has = |c: Channel| records.first().is_some_and(|r| r.channel(c).is_some());
    for p in [CsvProfile::Rig, CsvProfile::DrivePoint] {
        if p.required_channels().iter().all(|c| has(*c)) {
            return Ok(p);
        }
    }
    bail!(
        "{source}: the samples hold neither the rig channels ({}) nor the drive-point channels ({})",
        CsvProfile::Rig
            .required_channels()
            .map(|c| c.name())
            .join(", "),
        CsvProfile::DrivePoint
            .required_channels()
            .map(|c| c.name())
            .join(", ")
    )
}

pub fn load(path: &Path) -> anyhow::Result<Loaded> {
    if is_bag(path) {
        let bag = read_rig_bag(path)?;
        if let Some(why) = &bag.left_out {
            eprintln!("notice: {}: {why}", path.display());
        }
        let profile = profile_of(&bag.records, &path.display().to_string())?;
        Ok(Loaded {
            records: bag.records,
            profile,
            parameters: bag.parameters,
            ignored_columns: vec![],
        })
    } else {
        let csv = read_csv(path)?;
        Ok(Loaded {
            records: csv.records,
            profile: csv.profile,
            parameters: BTreeMap::new(),
            ignored_columns: csv.ignored_columns,
        })
    }
}
