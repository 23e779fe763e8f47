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
}

/// One entry as written, before it is checked.
struct RawEntry {
    name: String,
    topic: String,
    type_name: Option<String>,
    field: String,
    scale: Option<f64>,
    offset: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EntryForm {
    topic: String,
    #[serde(rename = "type")]
    type_name: Option<String>,
    field: String,
    scale: Option<f64>,
    offset: Option<f64>,
}

impl ChannelMap {
    /// Reads a channel map file (its own YAML, or a ROS 2 params file with `channels.*`
    /// parameters under `/**`).
    pub fn read(path: &Path) -> Result<ChannelMap, ChannelMapError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ChannelMapError::Read {
            file: file.clone(),
            problem: e.to_string(),
        })?;
        let mut map = ChannelMap::from_yaml_str(&text, &file)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for p in map.definitions.values_mut() {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
        }
        Ok(map)
    }

    /// Parses the text of a channel map; `file` is named in errors.
    pub fn from_yaml_str(text: &str, file: &str) -> Result<ChannelMap, ChannelMapError> {
        if text.contains(ROS_PARAMETERS_KEY) {
            let params = Params::from_yaml_str(text, Path::new(file), None).map_err(|e| {
                ChannelMapError::Invalid {
                    file: file.to_string(),
                    problem: e.to_string(),
                }
            })?;
            return ChannelMap::from_params(&params, file);
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
        let entries = form
            .channels
            .into_iter()
            .map(|(name, e)| RawEntry {
                name,
                topic: e.topic,
                type_name: e.type_name,
                field: e.field,
                scale: e.scale,
                offset: e.offset,
            })
            .collect();
        ChannelMap::from_entries(file, entries, form.definitions)
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
            if let Some(k) = keys.keys().next() {
                return Err(err(format!(
                    "unknown key '{k}' (expected topic, type, field, scale, offset)"
                )));
            }
            entries.push(RawEntry {
                name: entry,
                topic,
                type_name,
                field,
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
            let scale = scale.unwrap_or(1.0);
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
