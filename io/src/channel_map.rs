//! The channel map: which topic and field of a bench's own messages supply each forcemap
//! channel, so that a bag recorded with the bench's tools (no forcemap messages) can be
//! analysed.
//!
//! ```yaml
//! channels:
//!   base_displacement_m:     {topic: /dyno/actuator, field: data[0], scale: 0.001}  # mm -> m
//!   relative_displacement_m: {topic: /dyno/joints, field: "position[shock_left]"}
//!   mass_acceleration_mps2:  {topic: /dyno/imu, field: wrench.force.z, scale: 9.80665}
//!   step:                    {topic: /dyno/state, field: step}
//!   frequency_hz:            {topic: /dyno/state, field: frequency_hz}
//! definitions:               # optional: .msg files of types a bag carries no schema for
//!   bench_msgs/msg/State: msg/State.msg   # relative to this file
//! ```
//!
//! An entry may name its topic's message type (`type: std_msgs/msg/Float64MultiArray`): a bag
//! carries its topics' types, so offline the key only checks them, but the live source of
//! foreign topics (the `foreign` node) subscribes by type and needs it once per topic.
//!
//! The same `channels` mapping may sit in a ROS 2 params file under `/**: ros__parameters:`.
//! Each value is `raw * scale + offset` (scale 1 and offset 0 unless given), in the unit of the
//! channel's name: metres (`_m`), metres per second squared (`_mps2`), newtons (`_n`); `step`
//! is the index of the excitation step (a whole number from 0) and `frequency_hz` its
//! frequency in hertz (0 for random excitation).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use forcemap_math::record::Channel;
use serde::Deserialize;

use crate::params::{ParamValue, Params, ROS_PARAMETERS_KEY};
use crate::ros_msg::FieldPath;
use crate::table_map::{TableMap, TextOptionsForm};

/// Name of the entry that gives each sample's time (table maps).
pub const TIME_LABEL: &str = "time_s";
/// Name of the label that gives each sample's excitation step.
pub const STEP_LABEL: &str = "step";
/// Name of the label that gives each sample's excitation frequency [Hz].
pub const FREQUENCY_LABEL: &str = "frequency_hz";
/// The key of the mapping (top level of its own file, or a parameter prefix in a params file).
pub const CHANNELS_KEY: &str = "channels";

/// Where one channel or label comes from.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    pub topic: String,
    /// The topic's message type (`pkg/msg/Type`), if the map names it.
    pub type_name: Option<String>,
    pub field: FieldPath,
    pub scale: f64,
    pub offset: f64,
}

impl Source {
    /// The value in forcemap's unit of a raw field value.
    pub fn apply(&self, raw: f64) -> f64 {
        raw * self.scale + self.offset
    }
}

/// A channel map read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ChannelMap {
    /// The file it was read from (named in errors).
    pub file: String,
    /// The channels mapped, in [`Channel::ALL`] order.
    pub channels: Vec<(Channel, Source)>,
    pub step: Option<Source>,
    pub frequency_hz: Option<Source>,
    /// `.msg` files by type name (`pkg/msg/Type`), paths resolved against the map's folder.
    pub definitions: BTreeMap<String, PathBuf>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChannelMapError {
    #[error("{file}: cannot read the channel map: {problem}")]
    Read { file: String, problem: String },
    #[error("{file}: {problem}")]
    Invalid { file: String, problem: String },
    #[error("{file}: '{entry}': {problem}")]
    Entry {
        file: String,
        entry: String,
        problem: String,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileForm {
    channels: BTreeMap<String, EntryForm>,
    #[serde(default)]
    definitions: BTreeMap<String, PathBuf>,
    /// How a text file is laid out (table maps only).
    table: Option<TextOptionsForm>,
}

/// One topic entry as written, before it is checked.
struct RawEntry {
    name: String,
    topic: String,
    type_name: Option<String>,
    field: String,
    unit: Option<String>,
    scale: Option<f64>,
    offset: Option<f64>,
}

impl RawEntry {
    /// A topic entry of a map file: `topic` and `field`, none of a table entry's keys.
    fn of_form(file: &str, name: String, e: EntryForm) -> Result<RawEntry, ChannelMapError> {
        let err = |problem: String| ChannelMapError::Entry {
            file: file.to_string(),
            entry: name.clone(),
            problem,
        };
        let table_keys = [
            ("group", e.group.is_some()),
            ("column", e.column.is_some()),
            ("sample_rate_hz", e.sample_rate_hz.is_some()),
            ("format", e.format.is_some()),
        ];
        if let Some((key, _)) = table_keys.iter().find(|(_, present)| *present) {
            return Err(err(format!(
                "'{key}' applies to file columns (channel:), not to topics"
            )));
        }
        let topic = e.topic.ok_or_else(|| err("'topic' is missing".into()))?;
        let field = e.field.ok_or_else(|| err("'field' is missing".into()))?;
        Ok(RawEntry {
            name,
            topic,
            type_name: e.type_name,
            field,
            unit: e.unit,
            scale: e.scale,
            offset: e.offset,
        })
    }
}

/// One entry as a map file writes it: a bag entry (`topic`, `field`) or a table entry
/// (`channel`, with `group`, `column`, `sample_rate_hz`, `format`); `unit`, `scale` and
/// `offset` are common.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct EntryForm {
    pub topic: Option<String>,
    #[serde(rename = "type")]
    pub type_name: Option<String>,
    pub field: Option<String>,
    pub channel: Option<ColumnForm>,
    pub group: Option<String>,
    pub column: Option<usize>,
    pub sample_rate_hz: Option<f64>,
    pub format: Option<String>,
    pub unit: Option<String>,
    pub scale: Option<f64>,
    pub offset: Option<f64>,
}

/// A table map's column: a name, or a 1-based index.
#[derive(Clone)]
pub(crate) enum ColumnForm {
    Index(i64),
    Name(String),
}

impl<'de> Deserialize<'de> for ColumnForm {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<ColumnForm, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = ColumnForm;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a column name or a 1-based column index")
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<ColumnForm, E> {
                Ok(ColumnForm::Index(v))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<ColumnForm, E> {
                i64::try_from(v)
                    .map(ColumnForm::Index)
                    .map_err(|_| E::custom(format!("column {v} is too large")))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<ColumnForm, E> {
                Ok(ColumnForm::Name(v.to_string()))
            }
            fn visit_bool<E: serde::de::Error>(self, v: bool) -> Result<ColumnForm, E> {
                Err(E::custom(format!(
                    "YAML reads this channel name as the boolean {v}: quote it ('F', 'no', 'on')"
                )))
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<ColumnForm, E> {
                Err(E::custom(format!(
                    "{v} is neither a column name nor a whole column index (quote a name)"
                )))
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// What a map file holds: where a bag's topics supply the channels, or where a file's
/// columns do.
#[derive(Debug, Clone, PartialEq)]
pub enum MapFile {
    Topics(ChannelMap),
    Columns(TableMap),
}

impl MapFile {
    /// Reads a map file (its own YAML, or a ROS 2 params file with `channels.*` parameters,
    /// which are always topic maps).
    pub fn read(path: &Path) -> Result<MapFile, ChannelMapError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ChannelMapError::Read {
            file: file.clone(),
            problem: e.to_string(),
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Ok(match MapFile::from_yaml_str(&text, &file)? {
            MapFile::Topics(mut map) => {
                for p in map.definitions.values_mut() {
                    if p.is_relative() {
                        *p = dir.join(&*p);
                    }
                }
                MapFile::Topics(map)
            }
            columns => columns,
        })
    }

    /// Parses the text of a map; `file` is named in errors. Entries with `topic` make a topic
    /// map, entries with `channel` a table map; one map is one or the other.
    pub fn from_yaml_str(text: &str, file: &str) -> Result<MapFile, ChannelMapError> {
        if text.contains(ROS_PARAMETERS_KEY) {
            let params = Params::from_yaml_str(text, Path::new(file), None).map_err(|e| {
                ChannelMapError::Invalid {
                    file: file.to_string(),
                    problem: e.to_string(),
                }
            })?;
            return ChannelMap::from_params(&params, file).map(MapFile::Topics);
        }
        let form: FileForm = serde_saphyr::from_str(text).map_err(|e| {
            let at = e
                .location()
                .map(|l| format!(" (line {}, column {})", l.line(), l.column()))
                .unwrap_or_default();
            ChannelMapError::Invalid {
                file: file.to_string(),
                problem: format!("{}{at}", e.without_snippet()),
            }
        })?;
        let tables = form
            .channels
            .values()
            .filter(|e| e.channel.is_some())
            .count();
        let topics = form.channels.values().filter(|e| e.topic.is_some()).count();
        if tables > 0 && topics > 0 {
            return Err(ChannelMapError::Invalid {
                file: file.to_string(),
                problem: "the map mixes topic entries (topic, field) and file-column entries \
                          (channel); a map reads either a bag's topics or a file's columns"
                    .into(),
            });
        }
        // A time_s entry, or a table block, makes a table map even without a channel key
        // (time from a sample rate alone).
        if tables > 0
            || form.table.is_some()
            || (topics == 0 && form.channels.contains_key(TIME_LABEL))
        {
            if !form.definitions.is_empty() {
                return Err(ChannelMapError::Invalid {
                    file: file.to_string(),
                    problem: "'definitions' (.msg files) apply to topic maps only".into(),
                });
            }
            return TableMap::from_forms(file, form.channels, form.table).map(MapFile::Columns);
        }
        let mut entries = Vec::new();
        for (name, e) in form.channels {
            entries.push(RawEntry::of_form(file, name, e)?);
        }
        ChannelMap::from_entries(file, entries, form.definitions).map(MapFile::Topics)
    }
}

impl ChannelMap {
    /// Reads a topic map file (its own YAML, or a ROS 2 params file with `channels.*`
    /// parameters under `/**`); a map of file columns is refused.
    pub fn read(path: &Path) -> Result<ChannelMap, ChannelMapError> {
        MapFile::read(path)?.into_topics()
    }

    /// Parses the text of a topic map; `file` is named in errors.
    pub fn from_yaml_str(text: &str, file: &str) -> Result<ChannelMap, ChannelMapError> {
        MapFile::from_yaml_str(text, file)?.into_topics()
    }

    /// The map from `channels.NAME.{topic,field,scale,offset}` parameters.
    pub fn from_params(params: &Params, file: &str) -> Result<ChannelMap, ChannelMapError> {
        let mut grouped: BTreeMap<String, BTreeMap<String, ParamValue>> = BTreeMap::new();
        let prefix = format!("{CHANNELS_KEY}.");
        for (name, value) in params.iter() {
            let Some(rest) = name.strip_prefix(&prefix) else {
                continue;
            };
            let (entry, key) = rest.split_once('.').ok_or_else(|| ChannelMapError::Entry {
                file: file.to_string(),
                entry: rest.to_string(),
                problem: "expected a mapping {topic, field, scale, offset}".into(),
            })?;
            grouped
                .entry(entry.to_string())
                .or_default()
                .insert(key.to_string(), value.clone());
        }
        let mut entries = Vec::new();
        for (entry, mut keys) in grouped {
            let err = |problem: String| ChannelMapError::Entry {
                file: file.to_string(),
                entry: entry.clone(),
                problem,
            };
            let type_name = match keys.remove("type") {
                Some(ParamValue::String(s)) => Some(s),
                Some(v) => {
                    return Err(err(format!(
                        "'type' must be a string, found {}",
                        v.type_name()
                    )));
                }
                None => None,
            };
            let mut text = |k: &str| match keys.remove(k) {
                Some(ParamValue::String(s)) => Ok(s),
                Some(v) => Err(err(format!(
                    "'{k}' must be a string, found {}",
                    v.type_name()
                ))),
                None => Err(err(format!("'{k}' is missing"))),
            };
            let (topic, field) = (text("topic")?, text("field")?);
            let mut number = |k: &str| match keys.remove(k) {
                Some(ParamValue::Double(v)) => Ok(Some(v)),
                Some(ParamValue::Integer(v)) => Ok(Some(v as f64)),
                Some(v) => Err(err(format!(
                    "'{k}' must be a number, found {}",
                    v.type_name()
                ))),
                None => Ok(None),
            };
            let (scale, offset) = (number("scale")?, number("offset")?);
            let unit = match keys.remove("unit") {
                Some(ParamValue::String(s)) => Some(s),
                Some(v) => {
                    return Err(err(format!(
                        "'unit' must be a string, found {}",
                        v.type_name()
                    )));
                }
                None => None,
            };
            if let Some(k) = keys.keys().next() {
                return Err(err(format!(
                    "unknown key '{k}' (expected topic, type, field, unit, scale, offset)"
                )));
            }
            entries.push(RawEntry {
                name: entry,
                topic,
                type_name,
                field,
                unit,
                scale,
                offset,
            });
        }
        ChannelMap::from_entries(file, entries, BTreeMap::new())
    }

    fn from_entries(
        file: &str,
        entries: Vec<RawEntry>,
        definitions: BTreeMap<String, PathBuf>,
    ) -> Result<ChannelMap, ChannelMapError> {
        let mut map = ChannelMap {
            file: file.to_string(),
            channels: Vec::new(),
            step: None,
            frequency_hz: None,
            definitions: BTreeMap::new(),
        };
        for RawEntry {
            name: entry,
            topic,
            type_name,
            field,
            unit,
            scale,
            offset,
        } in entries
        {
            let err = |problem: String| ChannelMapError::Entry {
                file: file.to_string(),
                entry: entry.clone(),
                problem,
            };
            if !topic.starts_with('/') || topic.len() < 2 || topic.contains(char::is_whitespace) {
                return Err(err(format!(
                    "topic '{topic}' is not an absolute topic name (e.g. /dyno/load_cell)"
                )));
            }
            let field: FieldPath = field.parse().map_err(|e| err(format!("{e}")))?;
            let type_name = type_name
                .map(|t| crate::ros_msg::full_type_name(&t).map_err(|e| err(format!("type: {e}"))))
                .transpose()?;
            // One topic, one type.
            if let Some(t) = &type_name
                && let Some((other_entry, other)) = map
                    .sources()
                    .find(|(_, s)| s.topic == topic && s.type_name.as_ref().is_some_and(|o| o != t))
            {
                return Err(err(format!(
                    "topic {topic} has type {t} here but {} for '{other_entry}'",
                    other.type_name.as_deref().unwrap_or_default()
                )));
            }
            let unit_scale = match &unit {
                Some(u) => Some(si_factor(&entry, u, scale.is_some()).map_err(&err)?),
                None => None,
            };
            let scale = scale.or(unit_scale).unwrap_or(1.0);
            let offset = offset.unwrap_or(0.0);
            if !(scale.is_finite() && scale != 0.0) {
                return Err(err(format!("scale {scale} must be finite and not 0")));
            }
            if !offset.is_finite() {
                return Err(err(format!("offset {offset} must be finite")));
            }
            let source = Source {
                topic,
                type_name,
                field,
                scale,
                offset,
            };
            match entry.as_str() {
                TIME_LABEL => {
                    return Err(err(
                        "a bag's time is its messages' stamps; 'time_s' applies to file \
                         columns (channel:)"
                            .into(),
                    ));
                }
                STEP_LABEL => map.step = Some(source),
                FREQUENCY_LABEL => map.frequency_hz = Some(source),
                name => match Channel::from_name(name) {
                    Some(c) => map.channels.push((c, source)),
                    None => {
                        let known: Vec<&str> = Channel::ALL.iter().map(|c| c.name()).collect();
                        return Err(err(format!(
                            "not a forcemap channel or label; expected one of {}, {STEP_LABEL}, {FREQUENCY_LABEL}",
                            known.join(", ")
                        )));
                    }
                },
            }
        }
        if map.channels.is_empty() {
            return Err(ChannelMapError::Invalid {
                file: file.to_string(),
                problem: format!("no channels mapped under '{CHANNELS_KEY}'"),
            });
        }
        map.channels
            .sort_by_key(|(c, _)| Channel::ALL.iter().position(|a| a == c));
        for (name, path) in definitions {
            let full =
                crate::ros_msg::full_type_name(&name).map_err(|e| ChannelMapError::Entry {
                    file: file.to_string(),
                    entry: format!("definitions.{name}"),
                    problem: e.to_string(),
                })?;
            map.definitions.insert(full, path);
        }
        Ok(map)
    }

    /// The message type the map names for `topic`, if any entry names one.
    pub fn topic_type(&self, topic: &str) -> Option<&str> {
        self.sources().find_map(|(_, s)| {
            (s.topic == topic)
                .then_some(s.type_name.as_deref())
                .flatten()
        })
    }

    /// The topics the map reads, each once, in the order of their first entry.
    pub fn topics(&self) -> Vec<&str> {
        let mut out: Vec<&str> = Vec::new();
        for (_, s) in self.sources() {
            if !out.contains(&s.topic.as_str()) {
                out.push(&s.topic);
            }
        }
        out
    }

    /// Every source (channels, then labels) with the name of what it supplies.
    pub fn sources(&self) -> impl Iterator<Item = (&str, &Source)> {
        self.channels
            .iter()
            .map(|(c, s)| (c.name(), s))
            .chain(self.step.iter().map(|s| (STEP_LABEL, s)))
            .chain(self.frequency_hz.iter().map(|s| (FREQUENCY_LABEL, s)))
    }
}

impl MapFile {
    /// The topic map, or an error saying that this map reads file columns.
    pub fn into_topics(self) -> Result<ChannelMap, ChannelMapError> {
        match self {
            MapFile::Topics(map) => Ok(map),
            MapFile::Columns(map) => Err(ChannelMapError::Invalid {
                file: map.file,
                problem: "this map names file columns (channel:); it applies to CSV and text, \
                          MDF4, TDMS and MAT files, not to a bag's topics (topic:, field:)"
                    .into(),
            }),
        }
    }
}

/// The factor from a map entry's `unit` to the SI unit of the channel or label it supplies;
/// an error text when the unit is unknown, measures something else, or comes with a `scale`.
pub(crate) fn si_factor(entry: &str, unit: &str, has_scale: bool) -> Result<f64, String> {
    if has_scale {
        return Err(format!(
            "give 'unit' or 'scale', not both (unit '{unit}' sets the scale)"
        ));
    }
    let quantity = crate::units::Quantity::of_column(entry);
    let parsed = crate::units::parse_unit(unit).ok_or_else(|| {
        format!("unit '{unit}' is not one forcemap knows (give 'scale' and 'offset' instead)")
    })?;
    match quantity {
        Some(q) if q != parsed.quantity => Err(format!(
            "unit '{unit}' is not a unit of {entry} (its SI unit is {})",
            q.si_unit()
        )),
        _ => Ok(parsed.to_si),
    }
}
