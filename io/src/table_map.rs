//! A channel map for files of columns: which column of a CSV or text file, an MDF4, TDMS or
//! MAT file supplies each forcemap channel, its time and its labels, and in which unit.
//!
//! ```yaml
//! channels:
//!   time_s:                  {channel: Timestamp}             # ISO 8601 date-times
//!   relative_displacement_m: {channel: "Displacement (mm)"}   # unit from the name
//!   force_n:                 {channel: 4, unit: kN}           # 1-based column, unit given
//!   mass_acceleration_mps2:  {channel: Body_AccZ, group: Chassis}   # MDF4/TDMS group
//! table: {separator: whitespace, header: false, skip_lines: 0, decimal_comma: false}
//! ```
//!
//! A value is `raw * factor + offset`: the factor is the map's `scale`, else that of the
//! map's `unit`, else that of the unit the file gives the column (an MDF4 channel's unit, a
//! TDMS `unit_string`, a units row, or a unit in the column's name such as `Force (N)`); a
//! column named as forcemap names it (`force_n`) is SI. The offset is in forcemap's unit.
//! `time_s` is seconds (or another time unit), ISO 8601 date-times (optionally with
//! `format:`, a chrono format such as `"%m/%d/%Y %I:%M:%S%.f %p"`), a sample counter
//! (`sample_rate_hz:` with a channel), or the row index over `sample_rate_hz` (no channel).
//! Without a `time_s` entry the time is the file's own: an MDF4 group's master channel, a TDMS
//! channel's waveform properties, or a column named `time_s`.

use std::collections::BTreeMap;

use forcemap_math::record::Channel;
use serde::Deserialize;

use crate::channel_map::{
    ChannelMapError, ColumnForm, EntryForm, FREQUENCY_LABEL, STEP_LABEL, TIME_LABEL, si_factor,
};

/// Which column: by name (a header cell, an MDF4 or TDMS channel, a MAT variable) or by its
/// 1-based position.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColumnRef {
    Name(String),
    Index(usize),
}

impl std::fmt::Display for ColumnRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ColumnRef::Name(n) => write!(f, "'{n}'"),
            ColumnRef::Index(i) => write!(f, "column {i}"),
        }
    }
}

/// Where one channel or label comes from in a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ColumnSource {
    pub column: ColumnRef,
    /// The MDF4 channel group or TDMS group (by name), when the file has several.
    pub group: Option<String>,
    /// The 1-based column of a MAT matrix variable.
    pub matrix_column: Option<usize>,
    /// The unit of the raw values, overriding the file's.
    pub unit: Option<String>,
    /// The factor to forcemap's unit, overriding any unit.
    pub scale: Option<f64>,
    /// Added after scaling, in forcemap's unit.
    pub offset: f64,
}

/// Where the samples' times come from.
#[derive(Debug, Clone, PartialEq)]
pub enum TimeSource {
    /// A column of times: a number in a time unit, or a date-time (`format` when given).
    Column {
        source: ColumnSource,
        format: Option<String>,
    },
    /// A column counting samples at a known rate.
    Counter {
        source: ColumnSource,
        sample_rate_hz: f64,
    },
    /// No time column: sample `k` is at `k / sample_rate_hz`.
    Rate { sample_rate_hz: f64 },
}

/// How a text file separates its cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Separator {
    Comma,
    Semicolon,
    Tab,
    /// Runs of spaces and tabs.
    Whitespace,
}

/// A text file's layout when the detection should not decide it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TextOptions {
    pub separator: Option<Separator>,
    /// Whether the first line read names the columns.
    pub header: Option<bool>,
    pub decimal_comma: Option<bool>,
    /// Lines before the table (a DAQ's preamble).
    pub skip_lines: usize,
}

/// A map of file columns.
#[derive(Debug, Clone, PartialEq)]
pub struct TableMap {
    /// The file it was read from (named in errors).
    pub file: String,
    pub time: Option<TimeSource>,
    /// The channels mapped, in [`Channel::ALL`] order.
    pub channels: Vec<(Channel, ColumnSource)>,
    pub step: Option<ColumnSource>,
    pub frequency_hz: Option<ColumnSource>,
    pub text: TextOptions,
    /// How the file's samples make records (`table: {records: ...}`).
    pub records: RecordMaking,
}

/// How a file's samples make records.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum RecordMaking {
    /// Steps found where the drive changes, or the file's own step labels (`records: steps`).
    #[default]
    Steps,
    /// Each file is one record of any excitation (`records: whole`): no step finding, for
    /// records that are not stepped sines (a road or earthquake profile, a sine test with
    /// ramps), which `identify` fits sample by sample.
    Whole,
    /// One record of any excitation per named range of rows, in the map's order; rows outside
    /// every range are left out. For a file that holds several tests back to back (a
    /// benchmark's estimation and test sections, runs separated by rests).
    Rows(Vec<NamedRows>),
}

impl RecordMaking {
    /// Whether the records are the map's rather than found in the drive (no step finding).
    pub fn by_map(&self) -> bool {
        !matches!(self, RecordMaking::Steps)
    }
}

/// A record the map cuts from a file: its name and its rows (the file's samples counted from
/// 1, both ends included).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NamedRows {
    pub name: String,
    pub first_row: usize,
    pub last_row: usize,
}

/// The `table:` block as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct TextOptionsForm {
    separator: Option<String>,
    header: Option<bool>,
    decimal_comma: Option<bool>,
    #[serde(default)]
    skip_lines: usize,
    records: Option<RecordsForm>,
}

/// `table.records` as written: a way (`steps`, `whole`) or a list of named row ranges.
#[derive(Deserialize)]
#[serde(untagged)]
pub(crate) enum RecordsForm {
    Way(String),
    Rows(Vec<NamedRowsForm>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct NamedRowsForm {
    name: String,
    rows: [usize; 2],
}

impl TableMap {
    /// The map of the entries and `table:` block of a map file.
    pub(crate) fn from_forms(
        file: &str,
        entries: BTreeMap<String, EntryForm>,
        text: Option<TextOptionsForm>,
    ) -> Result<TableMap, ChannelMapError> {
        let mut map = TableMap {
            file: file.to_string(),
            time: None,
            channels: Vec::new(),
            step: None,
            frequency_hz: None,
            text: TextOptions::default(),
            records: RecordMaking::Steps,
        };
        if let Some(mut t) = text {
            if let Some(form) = t.records.take() {
                map.records = record_making(file, form)?;
            }
            map.text = text_options(file, t)?;
        }
        for (name, e) in entries {
            let err = |problem: String| ChannelMapError::Entry {
                file: file.to_string(),
                entry: name.clone(),
                problem,
            };
            for (key, present) in [
                ("topic", e.topic.is_some()),
                ("field", e.field.is_some()),
                ("type", e.type_name.is_some()),
            ] {
                if present {
                    return Err(err(format!(
                        "'{key}' applies to a bag's topics; this map reads file columns (channel:)"
                    )));
                }
            }
            if name != TIME_LABEL && (e.sample_rate_hz.is_some() || e.format.is_some()) {
                return Err(err(
                    "'sample_rate_hz' and 'format' apply to time_s only".into()
                ));
            }
            if name == TIME_LABEL {
                map.time = Some(time_source(e).map_err(err)?);
                continue;
            }
            let source = column_source(&name, e).map_err(err)?;
            match name.as_str() {
                STEP_LABEL => map.step = Some(source),
                FREQUENCY_LABEL => map.frequency_hz = Some(source),
                other => match Channel::from_name(other) {
                    Some(c) => map.channels.push((c, source)),
                    None => {
                        let known: Vec<&str> = Channel::ALL.iter().map(|c| c.name()).collect();
                        return Err(err(format!(
                            "not a forcemap channel or label; expected one of {}, \
                             {TIME_LABEL}, {STEP_LABEL}, {FREQUENCY_LABEL}",
                            known.join(", ")
                        )));
                    }
                },
            }
        }
        if map.channels.is_empty() {
            return Err(ChannelMapError::Invalid {
                file: file.to_string(),
                problem: "no channels mapped under 'channels' (a table map needs at least the \
                          setup's channels, e.g. relative_displacement_m and force_n)"
                    .into(),
            });
        }
        if map.step.is_some() != map.frequency_hz.is_some() {
            return Err(ChannelMapError::Invalid {
                file: file.to_string(),
                problem: format!(
                    "the labels {STEP_LABEL} and {FREQUENCY_LABEL} are mapped both or neither"
                ),
            });
        }
        if map.step.is_some() && matches!(map.records, RecordMaking::Rows(_)) {
            return Err(ChannelMapError::Invalid {
                file: file.to_string(),
                problem: format!(
                    "the map names its records by rows (table.records) and also maps the label \
                     {STEP_LABEL}: the records are one or the other"
                ),
            });
        }
        map.channels
            .sort_by_key(|(c, _)| Channel::ALL.iter().position(|a| a == c));
        Ok(map)
    }

    /// Every column the map reads, with the name of what it supplies (time first).
    pub fn sources(&self) -> impl Iterator<Item = (&'static str, &ColumnSource)> {
        let time = match &self.time {
            Some(TimeSource::Column { source, .. } | TimeSource::Counter { source, .. }) => {
                Some(source)
            }
            _ => None,
        };
        time.map(|s| (TIME_LABEL, s))
            .into_iter()
            .chain(self.channels.iter().map(|(c, s)| (c.name(), s)))
            .chain(self.step.iter().map(|s| (STEP_LABEL, s)))
            .chain(self.frequency_hz.iter().map(|s| (FREQUENCY_LABEL, s)))
    }
}

fn record_making(file: &str, form: RecordsForm) -> Result<RecordMaking, ChannelMapError> {
    let err = |problem: String| ChannelMapError::Entry {
        file: file.to_string(),
        entry: "table.records".into(),
        problem,
    };
    let rows = match form {
        RecordsForm::Way(w) => {
            return match w.as_str() {
                "steps" => Ok(RecordMaking::Steps),
                "whole" => Ok(RecordMaking::Whole),
                other => Err(err(format!(
                    "'{other}' is not a way to make records (steps: found where the drive \
                     changes; whole: each file one record; or a list of \
                     {{name: NAME, rows: [FIRST, LAST]}})"
                ))),
            };
        }
        RecordsForm::Rows(rows) => rows,
    };
    if rows.is_empty() {
        return Err(err("an empty list of records".into()));
    }
    let mut out: Vec<NamedRows> = Vec::with_capacity(rows.len());
    for r in rows {
        let [first_row, last_row] = r.rows;
        let name = r.name.trim().to_string();
        if name.is_empty() || name.contains([',', '#']) {
            return Err(err(format!(
                "'{}' is not a record name (not empty, no ',' or '#')",
                r.name
            )));
        }
        if out.iter().any(|o| o.name == name) {
            return Err(err(format!("record '{name}' is named twice")));
        }
        if first_row < 1 || last_row < first_row {
            return Err(err(format!(
                "record '{name}': rows [{first_row}, {last_row}] are not a range of rows \
                 (counted from 1, first <= last)"
            )));
        }
        if let Some(prev) = out.last()
            && first_row <= prev.last_row
        {
            return Err(err(format!(
                "record '{name}' (rows from {first_row}) starts inside or before record '{}' \
                 (rows to {}); list the records in the file's order, without overlap",
                prev.name, prev.last_row
            )));
        }
        out.push(NamedRows {
            name,
            first_row,
            last_row,
        });
    }
    Ok(RecordMaking::Rows(out))
}

fn text_options(file: &str, t: TextOptionsForm) -> Result<TextOptions, ChannelMapError> {
    let separator = match t.separator.as_deref() {
        None => None,
        Some("," | "comma") => Some(Separator::Comma),
        Some(";" | "semicolon") => Some(Separator::Semicolon),
        Some("\t" | "tab") => Some(Separator::Tab),
        Some("whitespace" | " " | "space") => Some(Separator::Whitespace),
        Some(other) => {
            return Err(ChannelMapError::Entry {
                file: file.to_string(),
                entry: "table.separator".into(),
                problem: format!(
                    "'{other}' is not a separator (comma, semicolon, tab or whitespace)"
                ),
            });
        }
    };
    Ok(TextOptions {
        separator,
        header: t.header,
        decimal_comma: t.decimal_comma,
        skip_lines: t.skip_lines,
    })
}

fn column_ref(c: ColumnForm) -> Result<ColumnRef, String> {
    match c {
        ColumnForm::Index(i) if i < 1 => Err("column indices count from 1".into()),
        ColumnForm::Index(i) => usize::try_from(i)
            .map(ColumnRef::Index)
            .map_err(|_| format!("column {i} is too large")),
        ColumnForm::Name(n) if n.trim().is_empty() => Err("an empty channel name".into()),
        ColumnForm::Name(n) => Ok(ColumnRef::Name(n)),
    }
}

/// A column entry's source, its unit or scale checked against what `name` measures.
fn column_source(name: &str, e: EntryForm) -> Result<ColumnSource, String> {
    let column = column_ref(
        e.channel
            .ok_or("'channel' is missing (a column name or its 1-based index)")?,
    )?;
    if e.column == Some(0) {
        return Err("'column' counts from 1".into());
    }
    if let Some(unit) = &e.unit {
        si_factor(name, unit, e.scale.is_some())?;
    }
    if let Some(s) = e.scale
        && !(s.is_finite() && s != 0.0)
    {
        return Err(format!("scale {s} must be finite and not 0"));
    }
    let offset = e.offset.unwrap_or(0.0);
    if !offset.is_finite() {
        return Err(format!("offset {offset} must be finite"));
    }
    Ok(ColumnSource {
        column,
        group: e.group,
        matrix_column: e.column,
        unit: e.unit,
        scale: e.scale,
        offset,
    })
}

fn time_source(mut e: EntryForm) -> Result<TimeSource, String> {
    let rate = e.sample_rate_hz.take();
    if let Some(r) = rate
        && !(r.is_finite() && r > 0.0)
    {
        return Err(format!("sample_rate_hz {r} must be a positive rate"));
    }
    if e.channel.is_none() {
        let Some(sample_rate_hz) = rate else {
            return Err(
                "give 'channel' (a column of times or sample counts) or 'sample_rate_hz' \
                 (samples at a known rate from the first row)"
                    .into(),
            );
        };
        if e.unit.is_some() || e.scale.is_some() || e.format.is_some() {
            return Err("without a channel, only 'sample_rate_hz' applies".into());
        }
        return Ok(TimeSource::Rate { sample_rate_hz });
    }
    let format = e.format.take();
    let source = column_source(TIME_LABEL, e)?;
    match rate {
        Some(sample_rate_hz) => {
            if format.is_some() || source.unit.is_some() || source.scale.is_some() {
                return Err(
                    "a sample counter ('sample_rate_hz') takes no unit, scale or format".into(),
                );
            }
            Ok(TimeSource::Counter {
                source,
                sample_rate_hz,
            })
        }
        None => Ok(TimeSource::Column { source, format }),
    }
}
