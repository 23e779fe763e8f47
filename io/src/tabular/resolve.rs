//! The one rule for every file of columns: which column each map entry names, the factor its
//! unit needs and where time comes from (the rows they make: [`super::read`]).

use std::path::Path;

use super::datetime::{Instant, parse_instant, seconds_since};
use super::{ColumnFile, ColumnInfo, TimeBase};
use crate::channel_map::{FREQUENCY_LABEL, STEP_LABEL, TIME_LABEL};

use crate::csv_export::{FREQUENCY_COLUMN, STEP_COLUMN, TIME_COLUMN};
use crate::table::{RowLines, TableError};
use crate::table_map::{ColumnRef, ColumnSource, TableMap, TimeSource};
use crate::units::{Quantity, parse_unit, unit_in_name};

/// Column names that are a file's time when the map names none (case does not matter).
const TIME_NAMES: [&str; 5] = ["time_s", "time", "t", "timestamp", "zeit"];

pub(super) fn format_error(file: &dyn ColumnFile, path: &Path, message: String) -> TableError {
    TableError::Format {
        path: path.to_path_buf(),
        format: file.format(),
        message,
    }
}

/// The index of the column `src` names for `entry`.
fn find(
    file: &dyn ColumnFile,
    path: &Path,
    entry: &str,
    src: &ColumnSource,
) -> Result<usize, TableError> {
    let columns = file.columns();
    let in_group = |c: &ColumnInfo| {
        src.group
            .as_ref()
            .is_none_or(|g| c.group.as_ref() == Some(g))
    };
    let in_matrix = |c: &ColumnInfo| src.matrix_column.is_none_or(|m| c.matrix_column == Some(m));
    let candidates: Vec<usize> = match &src.column {
        ColumnRef::Index(i) => (0..columns.len())
            .filter(|&k| columns[k].position == *i && in_group(&columns[k]))
            .collect(),
        ColumnRef::Name(n) => {
            let by = |same: &dyn Fn(&str) -> bool| -> Vec<usize> {
                (0..columns.len())
                    .filter(|&k| {
                        let c = &columns[k];
                        c.name.as_deref().is_some_and(same) && in_group(c) && in_matrix(c)
                    })
                    .collect()
            };
            // Exactly as written, else without the unit the name carries, else in any case.
            let exact = by(&|name| name == n);
            if !exact.is_empty() {
                exact
            } else {
                let bare = by(&|name| unit_in_name(name).is_some_and(|(b, _)| b == n));
                if bare.is_empty() {
                    by(&|name| name.eq_ignore_ascii_case(n))
                } else {
                    bare
                }
            }
        }
    };
    let fail = |m: String| format_error(file, path, m);
    match candidates.as_slice() {
        [k] => {
            let c = &columns[*k];
            if src.matrix_column.is_none() && c.matrix_column.is_some() {
                let width = columns
                    .iter()
                    .filter(|o| o.name == c.name && o.matrix_column.is_some())
                    .count();
                return Err(fail(format!(
                    "{} (for {entry}) is a matrix of {width} columns; give 'column: 1..{width}'",
                    src.column
                )));
            }
            Ok(*k)
        }
        [] => {
            let names: Vec<String> = columns.iter().take(40).map(ColumnInfo::label).collect();
            let more = columns.len().saturating_sub(40);
            let group = src
                .group
                .as_ref()
                .map(|g| format!(" in group '{g}'"))
                .unwrap_or_default();
            Err(fail(format!(
                "no {}{group} for {entry}; the file has {}{}",
                src.column,
                names.join(", "),
                if more > 0 {
                    format!(" and {more} more")
                } else {
                    String::new()
                }
            )))
        }
        many => {
            // A matrix without `column:` is named as such by the first arm's rule.
            if many.iter().all(|&k| columns[k].matrix_column.is_some())
                && src.matrix_column.is_none()
            {
                return Err(fail(format!(
                    "{} (for {entry}) is a matrix of {} columns; give 'column: 1..{}'",
                    src.column,
                    many.len(),
                    many.len()
                )));
            }
            let found: Vec<String> = many.iter().map(|&k| columns[k].label()).collect();
            Err(fail(format!(
                "{} (for {entry}) is ambiguous: {}; give 'group:'",
                src.column,
                found.join(", ")
            )))
        }
    }
}

/// The factor from a column's raw values to forcemap's unit for `entry`, and how it was
/// found (for the notice).
fn factor(
    file: &dyn ColumnFile,
    path: &Path,
    entry: &str,
    src: &ColumnSource,
    info: &ColumnInfo,
) -> Result<(f64, String), TableError> {
    let fail = |m: String| format_error(file, path, m);
    if let Some(s) = src.scale {
        return Ok((s, format!("x {s} (the map's scale)")));
    }
    let quantity = Quantity::of_column(entry).unwrap_or(Quantity::Count);
    let from_name = info.name.as_deref().and_then(unit_in_name).map(|(_, u)| u);
    let (unit, whose) = match (
        &src.unit,
        info.unit.as_deref().filter(|u| !u.trim().is_empty()),
    ) {
        (Some(u), _) => (Some(u.as_str()), "the map's unit"),
        (None, Some(u)) => (Some(u), "the file's unit"),
        (None, None) => (from_name, "the unit in its name"),
    };
    let Some(unit) = unit else {
        // Unitless columns that cannot be mistaken.
        if info.name.as_deref() == Some(entry) || entry == STEP_LABEL {
            return Ok((1.0, String::new()));
        }
        if entry == FREQUENCY_LABEL || entry == TIME_LABEL {
            return Ok((
                1.0,
                format!("no unit in the file: read as {}", quantity.si_unit()),
            ));
        }
        return Err(fail(format!(
            "{} (for {entry}) has no unit in the file; give 'unit:' (such as {}) or 'scale:' \
             in the map",
            info.label(),
            match quantity {
                Quantity::Length => "mm",
                Quantity::Force => "kN",
                Quantity::Acceleration => "g",
                _ => quantity.si_unit(),
            }
        )));
    };
    let parsed = parse_unit(unit).ok_or_else(|| {
        fail(format!(
            "{} (for {entry}) has unit '{unit}' ({whose}), which forcemap does not know; give \
             'scale:' (and 'offset:') in the map",
            info.label()
        ))
    })?;
    if parsed.quantity != quantity {
        return Err(fail(format!(
            "{} (for {entry}) has unit '{unit}' ({whose}), not a unit of {entry} (its SI unit \
             is {})",
            info.label(),
            quantity.si_unit()
        )));
    }
    let how = if parsed.to_si == 1.0 {
        String::new()
    } else {
        format!("{unit} -> {} (x {})", quantity.si_unit(), parsed.to_si)
    };
    Ok((parsed.to_si, how))
}

/// Times of date-times of a column, in seconds since the column's first (`first`, set by the
/// column's first cells): the cells of rows `first_row..` of the file, a bad one named by its
/// line (`row_lines`) or sample.
pub(super) fn date_times(
    (file_format, row_lines): (&'static str, Option<&RowLines>),
    path: &Path,
    info: &ColumnInfo,
    (cells, first_row): (&[String], usize),
    format: Option<&str>,
    first: &mut Option<Instant>,
) -> Result<Vec<f64>, TableError> {
    let error = |message| TableError::Format {
        path: path.to_path_buf(),
        format: file_format,
        message,
    };
    let mut seconds = Vec::with_capacity(cells.len());
    for (k, cell) in cells.iter().enumerate() {
        let row = first_row + k;
        let at = || match row_lines.and_then(|l| l.get(row)) {
            Some(line) => format!("line {line}"),
            None => format!("sample {row}"),
        };
        let i = parse_instant(cell, format).ok_or_else(|| {
            error(format!(
                "{}, {} (time_s): '{cell}' is neither a number nor a date-time ({})",
                at(),
                info.label(),
                format.map_or("ISO 8601 such as 2024-03-01T12:00:00.125".into(), |f| {
                    format!("the map's format '{f}'")
                })
            ))
        })?;
        let first = *first.get_or_insert(i);
        if first.zoned != i.zoned {
            return Err(error(format!(
                "{}, {} (time_s): '{cell}' mixes date-times with and without a zone",
                at(),
                info.label()
            )));
        }
        seconds.push(seconds_since(first, i));
    }
    Ok(seconds)
}

/// What each entry reads, before reading: the column, whether it may be text, its factor.
pub(super) struct Plan {
    pub name: &'static str,
    pub column: usize,
    pub text_ok: bool,
    pub factor: f64,
    pub offset: f64,
    pub how: String,
}

/// The file's own time when the map names none: a column named as time, an MDF4 master
/// channel, or TDMS waveform properties of the picked columns.
fn file_time(file: &dyn ColumnFile, path: &Path, picked: &[usize]) -> Result<FileTime, TableError> {
    let columns = file.columns();
    let group = picked.first().and_then(|&k| columns[k].group.clone());
    let same_group = |c: &ColumnInfo| c.group == group;
    if let Some(k) = (0..columns.len()).find(|&k| {
        let c = &columns[k];
        let bare = c
            .name
            .as_deref()
            .map(|n| unit_in_name(n).map_or(n, |(b, _)| b));
        same_group(c) && bare.is_some_and(|b| TIME_NAMES.iter().any(|t| t.eq_ignore_ascii_case(b)))
    }) {
        return Ok(FileTime::Column(k));
    }
    if let Some(k) = (0..columns.len())
        .find(|&k| same_group(&columns[k]) && columns[k].time_base == Some(TimeBase::Master))
    {
        return Ok(FileTime::Column(k));
    }
    let mut waveform: Option<(f64, f64, usize)> = None;
    for &k in picked {
        if let Some(TimeBase::Waveform {
            start_s,
            increment_s,
        }) = columns[k].time_base
        {
            match waveform {
                Some((s, i, first)) if (s, i) != (start_s, increment_s) => {
                    return Err(format_error(
                        file,
                        path,
                        format!(
                            "{} has wf_start_offset {start_s}, wf_increment {increment_s} but {} \
                             has {s}, {i}; the channels must share one time base",
                            columns[k].label(),
                            columns[first].label()
                        ),
                    ));
                }
                Some(_) => {}
                None => waveform = Some((start_s, increment_s, k)),
            }
        }
    }
    match waveform {
        Some((start_s, increment_s, _))
            if increment_s.is_finite() && increment_s > 0.0 && start_s.is_finite() =>
        {
            Ok(FileTime::Waveform {
                start_s,
                increment_s,
            })
        }
        Some((_, increment_s, _)) => Err(format_error(
            file,
            path,
            format!("wf_increment {increment_s} is not a positive time"),
        )),
        None => Err(format_error(
            file,
            path,
            "no time: no column named time_s or Time, no master time channel, no waveform \
             timing; map one (time_s: {channel: NAME}) or give the rate (time_s: \
             {sample_rate_hz: 1000})"
                .into(),
        )),
    }
}

enum FileTime {
    Column(usize),
    Waveform { start_s: f64, increment_s: f64 },
}

/// What a map reads from a file: each entry's column and factor, and where time comes from
/// when no column gives it.
pub struct Picks {
    pub(super) plans: Vec<Plan>,
    pub(super) time_rate: Option<f64>,
    pub(super) waveform: Option<(f64, f64)>,
    pub(super) time_format: Option<String>,
}

impl Picks {
    /// Each pick as (what it supplies, the column's index, how its unit is converted).
    pub fn described(&self) -> Vec<(&'static str, usize, String)> {
        self.plans
            .iter()
            .map(|p| (p.name, p.column, p.how.clone()))
            .collect()
    }
}

/// The columns `map` picks from `file`, their units and the time, checked before any value is
/// read.
pub fn pick(file: &dyn ColumnFile, path: &Path, map: &TableMap) -> Result<Picks, TableError> {
    let mut plans: Vec<Plan> = Vec::new();
    let entries: Vec<(&'static str, &ColumnSource)> = map
        .channels
        .iter()
        .map(|(c, s)| (c.name(), s))
        .chain(map.step.iter().map(|s| (STEP_COLUMN, s)))
        .chain(map.frequency_hz.iter().map(|s| (FREQUENCY_COLUMN, s)))
        .collect();
    for (name, src) in entries {
        let column = find(file, path, name, src)?;
        let (factor, how) = factor(file, path, name, src, &file.columns()[column])?;
        plans.push(Plan {
            name,
            column,
            text_ok: false,
            factor,
            offset: src.offset,
            how,
        });
    }
    let picked: Vec<usize> = plans.iter().map(|p| p.column).collect();
    // Time: the map's, else the file's.
    let mut time_rate: Option<f64> = None;
    let mut waveform: Option<(f64, f64)> = None;
    let mut time_format: Option<String> = None;
    match &map.time {
        Some(TimeSource::Column { source, format }) => {
            let column = find(file, path, TIME_LABEL, source)?;
            let (factor, how) = factor(file, path, TIME_LABEL, source, &file.columns()[column])?;
            time_format = format.clone();
            plans.insert(
                0,
                Plan {
                    name: TIME_COLUMN,
                    column,
                    text_ok: true,
                    factor,
                    offset: source.offset,
                    how,
                },
            );
        }
        Some(TimeSource::Counter {
            source,
            sample_rate_hz,
        }) => {
            let column = find(file, path, TIME_LABEL, source)?;
            plans.insert(
                0,
                Plan {
                    name: TIME_COLUMN,
                    column,
                    text_ok: false,
                    factor: 1.0 / sample_rate_hz,
                    offset: source.offset,
                    how: format!("sample counts at {sample_rate_hz} Hz"),
                },
            );
        }
        Some(TimeSource::Rate { sample_rate_hz }) => time_rate = Some(*sample_rate_hz),
        None => match file_time(file, path, &picked)? {
            FileTime::Column(column) => {
                let info = file.columns()[column].clone();
                let src = ColumnSource {
                    column: ColumnRef::Index(info.position),
                    group: info.group.clone(),
                    matrix_column: info.matrix_column,
                    unit: None,
                    scale: None,
                    offset: 0.0,
                };
                let (factor, how) = factor(file, path, TIME_LABEL, &src, &info)?;
                plans.insert(
                    0,
                    Plan {
                        name: TIME_COLUMN,
                        column,
                        text_ok: true,
                        factor,
                        offset: 0.0,
                        how,
                    },
                );
            }
            FileTime::Waveform {
                start_s,
                increment_s,
            } => waveform = Some((start_s, increment_s)),
        },
    }
    // One time base: the picked columns of one group.
    let columns = file.columns();
    let groups: Vec<&Option<String>> = plans.iter().map(|p| &columns[p.column].group).collect();
    if let Some(other) = groups.iter().find(|g| **g != groups[0]) {
        let mut list: Vec<String> = plans
            .iter()
            .map(|p| format!("{} in {}", p.name, columns[p.column].label()))
            .collect();
        list.dedup();
        return Err(format_error(
            file,
            path,
            format!(
                "the mapped channels are in several groups ({} and {}): {}; forcemap reads one \
                 time base (map channels of one group)",
                groups[0].as_deref().unwrap_or("-"),
                other.as_deref().unwrap_or("-"),
                list.join(", ")
            ),
        ));
    }
    Ok(Picks {
        plans,
        time_rate,
        waveform,
        time_format,
    })
}
