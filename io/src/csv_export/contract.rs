//! The CSV contract's columns: their names, which an export requires, and where a header puts
//! them.

use std::collections::HashMap;
use std::path::Path;

use forcemap_math::recipe::SetupKind;
use forcemap_math::record::{Channel, Record};

use super::error::CsvError;
use super::multisine::{MULTISINE_BASE_COLUMN, MULTISINE_COLUMNS, MULTISINE_LINES_COLUMN};
use super::sweep::SWEEP_COLUMNS;
use crate::steps::WRITTEN_INTERVAL_REL_TOL;

/// Column names of the fixed (non-channel) columns.
pub const TIME_COLUMN: &str = "time_s";
pub const STEP_COLUMN: &str = "step";
pub const FREQUENCY_COLUMN: &str = "frequency_hz";

/// Relative tolerance on the sampling interval within which written times are exact: the step
/// assembler's rule for written data (beyond it, its timing rule reads breaks and jitter).
pub const SAMPLE_INTERVAL_REL_TOL: f64 = WRITTEN_INTERVAL_REL_TOL;

/// The label columns: optional, but both or neither (without them the steps are found in the
/// driven channel, see [`crate::steps::unlabelled`]).
pub const LABEL_COLUMNS: [&str; 2] = [STEP_COLUMN, FREQUENCY_COLUMN];

/// The columns an export of `kind` requires, time first. Which kind of test an export
/// describes (and so its driven channel) is `SetupKind`'s rule, from its channels.
pub fn required_columns(kind: SetupKind) -> Vec<&'static str> {
    let mut v = vec![TIME_COLUMN];
    v.extend(kind.required_channels().iter().map(|c| c.name()));
    v
}

/// The result of [`read_csv`](super::read_csv).
#[derive(Debug, Clone, PartialEq)]
pub struct CsvImport {
    /// One record per step, in file order. Channels are in [`Channel::ALL`] order.
    pub records: Vec<Record>,
    /// Header names that are not part of the contract and were ignored (header order).
    /// The caller decides whether and how to tell the user.
    pub ignored_columns: Vec<String>,
    pub kind: SetupKind,
    /// Where the labels (`step`, `frequency_hz`) disagree with what the driven channel shows,
    /// one line each; empty for agreeing labels and for unlabelled exports.
    pub warnings: Vec<String>,
    /// What the user is told: the dialect detected when it is not the plain one, a truncated
    /// last line skipped (each names the file and, where it applies, the line).
    pub notices: Vec<String>,
}

/// Where a header puts the contract's columns.
#[derive(Clone)]
pub(super) struct Layout {
    pub profile: SetupKind,
    pub time_col: usize,
    /// The label columns, both present or both absent.
    pub step_col: Option<usize>,
    pub freq_col: Option<usize>,
    /// The multisine label columns (base frequency, lines), both present or both absent, only
    /// with the label columns.
    pub multisine_cols: Option<(usize, usize)>,
    /// The sweep label columns (law, start, end), all present or all absent, only with the
    /// label columns.
    pub sweep_cols: Option<[usize; 3]>,
    /// The channel columns present, in [`Channel::ALL`] order.
    pub channel_cols: Vec<(Channel, usize)>,
    pub ignored_columns: Vec<String>,
}

impl Layout {
    /// The layout of a (non-empty) header, with the profile it describes.
    pub fn of_header(header: &csv::StringRecord, path: &Path) -> Result<Layout, CsvError> {
        let mut index: HashMap<&str, usize> = HashMap::new();
        for (i, name) in header.iter().enumerate() {
            if index.insert(name, i).is_some() {
                return Err(CsvError::DuplicateColumn {
                    path: path.to_path_buf(),
                    column: name.to_string(),
                });
            }
        }
        // One label column without the other is missing the other.
        let labels_present = LABEL_COLUMNS.iter().any(|c| index.contains_key(c));
        let missing_for = |profile: SetupKind| -> Vec<String> {
            let mut required = required_columns(profile);
            if labels_present {
                required.splice(1..1, LABEL_COLUMNS);
            }
            required
                .into_iter()
                .filter(|c| !index.contains_key(c))
                .map(str::to_string)
                .collect()
        };
        let missing_rig = missing_for(SetupKind::BaseExcited);
        let missing_dp = missing_for(SetupKind::DrivePoint);
        let has = |c: Channel| index.contains_key(c.name());
        let profile = if has(Channel::BaseDisplacementM) {
            Some(SetupKind::BaseExcited)
        } else if has(Channel::ForceN) && has(Channel::DrivePointDisplacementM) {
            Some(SetupKind::DrivePoint)
        } else {
            // Any other setup only when all its channels are there (the element test: the
            // relative displacement and the force).
            SetupKind::of_channels(has).ok()
        };
        let missing = match profile {
            Some(SetupKind::BaseExcited) => missing_rig.clone(),
            Some(SetupKind::DrivePoint) => missing_dp.clone(),
            Some(kind) => missing_for(kind),
            None => {
                let mut all = missing_rig.clone();
                all.extend(
                    missing_dp
                        .iter()
                        .filter(|c| !missing_rig.contains(c))
                        .cloned(),
                );
                all
            }
        };
        let profile = match profile {
            Some(p) if missing.is_empty() => p,
            _ => {
                return Err(CsvError::MissingColumns {
                    path: path.to_path_buf(),
                    profile,
                    missing,
                    missing_rig,
                    missing_drive_point: missing_dp,
                });
            }
        };
        let time_col = index[TIME_COLUMN];
        let step_col = index.get(STEP_COLUMN).copied();
        let freq_col = index.get(FREQUENCY_COLUMN).copied();
        let multisine_cols = match (
            index.get(MULTISINE_BASE_COLUMN),
            index.get(MULTISINE_LINES_COLUMN),
        ) {
            (Some(&b), Some(&l)) if step_col.is_some() => Some((b, l)),
            (None, None) => None,
            (b, _) => {
                let message = if b.is_some() != index.contains_key(MULTISINE_LINES_COLUMN) {
                    format!(
                        "the multisine columns '{}' and '{}' go together; the header has one \
                         without the other",
                        MULTISINE_COLUMNS[0], MULTISINE_COLUMNS[1]
                    )
                } else {
                    format!(
                        "the multisine columns '{}' and '{}' label steps, so they need the \
                         '{STEP_COLUMN}' and '{FREQUENCY_COLUMN}' columns too",
                        MULTISINE_COLUMNS[0], MULTISINE_COLUMNS[1]
                    )
                };
                return Err(CsvError::Malformed {
                    path: path.to_path_buf(),
                    line: Some(1),
                    message,
                });
            }
        };
        let sweep_found: Vec<Option<usize>> = SWEEP_COLUMNS
            .iter()
            .map(|c| index.get(c).copied())
            .collect();
        let sweep_cols = match sweep_found[..] {
            [Some(l), Some(a), Some(b)] if step_col.is_some() => Some([l, a, b]),
            [None, None, None] => None,
            _ => {
                let all = SWEEP_COLUMNS.join("', '");
                let message = if sweep_found.iter().any(Option::is_none) {
                    format!("the sweep columns '{all}' go together; the header has only some")
                } else {
                    format!(
                        "the sweep columns '{all}' label steps, so they need the \
                         '{STEP_COLUMN}' and '{FREQUENCY_COLUMN}' columns too"
                    )
                };
                return Err(CsvError::Malformed {
                    path: path.to_path_buf(),
                    line: Some(1),
                    message,
                });
            }
        };
        let channel_cols: Vec<(Channel, usize)> = Channel::ALL
            .into_iter()
            .filter_map(|c| index.get(c.name()).map(|&i| (c, i)))
            .collect();
        let known = |name: &str| {
            name == TIME_COLUMN
                || name == STEP_COLUMN
                || name == FREQUENCY_COLUMN
                || (multisine_cols.is_some() && MULTISINE_COLUMNS.contains(&name))
                || (sweep_cols.is_some() && SWEEP_COLUMNS.contains(&name))
                || Channel::from_name(name).is_some()
        };
        let ignored_columns: Vec<String> = header
            .iter()
            .filter(|n| !known(n))
            .map(str::to_string)
            .collect();
        Ok(Layout {
            profile,
            time_col,
            step_col,
            freq_col,
            multisine_cols,
            sweep_cols,
            channel_cols,
            ignored_columns,
        })
    }
}
