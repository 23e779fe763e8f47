//! The map of a file whose columns carry forcemap's own names (a contract CSV written by
//! another tool, an MDF4 or TDMS file whose channels are named `force_n`, ...): read without
//! a channel map.

use std::path::Path;

use forcemap_math::record::Channel;

use super::resolve::format_error;
use super::{ColumnFile, ColumnInfo};
use crate::csv_export::{FREQUENCY_COLUMN, STEP_COLUMN, TIME_COLUMN};
use crate::table::{TableError, contract_column};
use crate::table_map::{ColumnRef, ColumnSource, RecordMaking, TableMap, TextOptions, TimeSource};

/// The map of a file whose columns are named as forcemap names them: each such column, in
/// one group (several groups with forcemap names are refused, naming them).
pub fn default_map(file: &dyn ColumnFile, path: &Path) -> Result<TableMap, TableError> {
    let mut map = TableMap {
        file: "forcemap's channel names".into(),
        time: None,
        channels: Vec::new(),
        step: None,
        frequency_hz: None,
        text: TextOptions::default(),
        records: RecordMaking::Steps,
    };
    let columns = file.columns();
    let named: Vec<(&'static str, &ColumnInfo)> = columns
        .iter()
        .filter_map(|c| c.name.as_deref().and_then(contract_column).map(|n| (n, c)))
        .collect();
    let mut groups: Vec<(&Option<String>, Vec<&'static str>)> = Vec::new();
    for (n, c) in &named {
        match groups.iter_mut().find(|(g, _)| *g == &c.group) {
            Some((_, names)) => names.push(n),
            None => groups.push((&c.group, vec![n])),
        }
    }
    if groups.len() > 1 {
        let list: Vec<String> = groups
            .iter()
            .map(|(g, names)| {
                format!(
                    "group {} ({})",
                    g.as_deref().unwrap_or("-"),
                    names.join(", ")
                )
            })
            .collect();
        return Err(format_error(
            file,
            path,
            format!(
                "forcemap channels are in several channel groups: {}; forcemap reads one time \
                 base (put them in one group)",
                list.join("; ")
            ),
        ));
    }
    for (n, c) in named {
        let src = ColumnSource {
            column: ColumnRef::Name(n.to_string()),
            group: c.group.clone(),
            matrix_column: None,
            unit: None,
            scale: None,
            offset: 0.0,
        };
        if n == TIME_COLUMN {
            map.time = Some(TimeSource::Column {
                source: src,
                format: None,
            });
        } else if n == STEP_COLUMN {
            map.step = Some(src);
        } else if n == FREQUENCY_COLUMN {
            map.frequency_hz = Some(src);
        } else if let Some(ch) = Channel::from_name(n) {
            map.channels.push((ch, src));
        }
    }
    if map.channels.is_empty() {
        return Err(format_error(
            file,
            path,
            "no channel with a forcemap name (time_s, step, frequency_hz, force_n, \
             base_displacement_m, ...); read the file through a channel map (--channels)"
                .into(),
        ));
    }
    map.channels
        .sort_by_key(|(c, _)| Channel::ALL.iter().position(|a| a == c));
    Ok(map)
}
