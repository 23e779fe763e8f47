//! The YAML side of a params file: the untyped document, the node entries that apply to a
//! node (ROS wildcards), nested names flattened to dotted ones, and scalars into
//! [`ParamValue`]s.

use serde::de::{self, Deserialize, Deserializer, MapAccess, SeqAccess, Visitor};
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

use super::{ParamValue, ParamsError, ROS_PARAMETERS_KEY};

/// `*` matches one token, `**` any number (including none).
pub(super) fn glob_match(pattern: &[&str], name: &[&str]) -> bool {
    match pattern.split_first() {
        None => name.is_empty(),
        Some((&"**", rest)) => (0..=name.len()).any(|k| glob_match(rest, &name[k..])),
        Some((p, rest)) => match name.split_first() {
            Some((n, name_rest)) => (*p == "*" || p == n) && glob_match(rest, name_rest),
            None => false,
        },
    }
}

pub(super) fn has_ros_parameters(map: &[(String, Yaml)]) -> bool {
    map.iter().any(|(k, v)| {
        k == ROS_PARAMETERS_KEY || matches!(v, Yaml::Map(inner) if has_ros_parameters(inner))
    })
}

/// Finds every `ros__parameters` mapping, with the fully qualified node pattern above it.
pub(super) fn collect_nodes<'a>(
    map: &'a [(String, Yaml)],
    prefix: &mut Vec<String>,
    out: &mut Vec<(String, &'a Vec<(String, Yaml)>)>,
    path: &Path,
) -> Result<(), ParamsError> {
    fn here(prefix: &[String]) -> String {
        format!("/{}", prefix.join("/"))
    }
    for (key, value) in map {
        if key == ROS_PARAMETERS_KEY {
            if prefix.is_empty() {
                return Err(ParamsError::Structure {
                    path: path.to_path_buf(),
                    message: format!(
                        "'{ROS_PARAMETERS_KEY}' at the top level; it must be under a node name \
                         such as '/**:'"
                    ),
                });
            }
            match value {
                Yaml::Map(params) => out.push((here(prefix), params)),
                Yaml::Null => {
                    // `ros__parameters:` with nothing under it: no parameters.
                    static EMPTY: Vec<(String, Yaml)> = Vec::new();
                    out.push((here(prefix), &EMPTY));
                }
                _ => {
                    return Err(ParamsError::Structure {
                        path: path.to_path_buf(),
                        message: format!(
                            "'{ROS_PARAMETERS_KEY}' of '{}' is not a mapping of parameters",
                            here(prefix)
                        ),
                    });
                }
            }
        } else if let Yaml::Map(inner) = value {
            let tokens: Vec<String> = key
                .split('/')
                .filter(|t| !t.is_empty())
                .map(str::to_string)
                .collect();
            let n = tokens.len();
            prefix.extend(tokens);
            collect_nodes(inner, prefix, out, path)?;
            prefix.truncate(prefix.len() - n);
        } else {
            let at = if prefix.is_empty() {
                String::new()
            } else {
                format!(" under '{}'", here(prefix))
            };
            return Err(ParamsError::Structure {
                path: path.to_path_buf(),
                message: format!(
                    "key '{key}'{at} is not a node name with '{ROS_PARAMETERS_KEY}' under it \
                     (parameters must be inside '{ROS_PARAMETERS_KEY}')"
                ),
            });
        }
    }
    Ok(())
}

/// Flattens nested mappings to dotted names.
pub(super) fn flatten(
    map: &[(String, Yaml)],
    prefix: &str,
    out: &mut BTreeMap<String, (ParamValue, String)>,
    origin: &str,
) -> Result<(), ParamsError> {
    for (key, value) in map {
        let name = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match value {
            Yaml::Map(inner) => flatten(inner, &name, out, origin)?,
            other => {
                let v = to_param_value(other, &name, origin)?;
                out.insert(name, (v, origin.to_string()));
            }
        }
    }
    Ok(())
}

pub(super) fn to_param_value(
    y: &Yaml,
    name: &str,
    origin: &str,
) -> Result<ParamValue, ParamsError> {
    let unsupported = |reason: String| ParamsError::UnsupportedValue {
        origin: origin.to_string(),
        name: name.to_string(),
        reason,
    };
    Ok(match y {
        Yaml::Null => return Err(unsupported("null values are not supported".into())),
        Yaml::Bool(b) => ParamValue::Bool(*b),
        Yaml::Int(i) => ParamValue::Integer(*i),
        Yaml::Float(f) => ParamValue::Double(*f),
        Yaml::Str(s) => ParamValue::String(s.clone()),
        Yaml::Map(_) => return Err(unsupported("a mapping is not a parameter value".into())),
        Yaml::Seq(items) => {
            if items.is_empty() {
                return Ok(ParamValue::EmptyArray);
            }
            let all = |f: fn(&Yaml) -> bool| items.iter().all(f);
            if all(|y| matches!(y, Yaml::Bool(_))) {
                ParamValue::BoolArray(
                    items
                        .iter()
                        .map(|y| matches!(y, Yaml::Bool(true)))
                        .collect(),
                )
            } else if all(|y| matches!(y, Yaml::Int(_))) {
                ParamValue::IntegerArray(
                    items
                        .iter()
                        .map(|y| if let Yaml::Int(i) = y { *i } else { 0 })
                        .collect(),
                )
            } else if all(|y| matches!(y, Yaml::Int(_) | Yaml::Float(_))) {
                ParamValue::DoubleArray(
                    items
                        .iter()
                        .map(|y| match y {
                            Yaml::Int(i) => *i as f64,
                            Yaml::Float(f) => *f,
                            _ => 0.0,
                        })
                        .collect(),
                )
            } else if all(|y| matches!(y, Yaml::Str(_))) {
                ParamValue::StringArray(
                    items
                        .iter()
                        .map(|y| match y {
                            Yaml::Str(s) => s.clone(),
                            _ => String::new(),
                        })
                        .collect(),
                )
            } else {
                let kinds: Vec<&str> = items.iter().map(Yaml::kind).collect();
                return Err(unsupported(format!(
                    "an array must hold values of one type (bool, integer, double or string), \
                     found [{}]",
                    kinds.join(", ")
                )));
            }
        }
    })
}

/// An untyped YAML node, as far as ROS parameters need it.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Yaml {
    Null,
    Bool(bool),
    Int(i64),
    Float(f64),
    Str(String),
    Seq(Vec<Yaml>),
    /// Entries in file order.
    Map(Vec<(String, Yaml)>),
}

impl Yaml {
    fn kind(&self) -> &'static str {
        match self {
            Yaml::Null => "null",
            Yaml::Bool(_) => "bool",
            Yaml::Int(_) => "integer",
            Yaml::Float(_) => "double",
            Yaml::Str(_) => "string",
            Yaml::Seq(_) => "array",
            Yaml::Map(_) => "mapping",
        }
    }
}

impl<'de> Deserialize<'de> for Yaml {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Yaml, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Yaml;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a YAML value")
            }
            fn visit_unit<E>(self) -> Result<Yaml, E> {
                Ok(Yaml::Null)
            }
            fn visit_none<E>(self) -> Result<Yaml, E> {
                Ok(Yaml::Null)
            }
            fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<Yaml, D::Error> {
                Yaml::deserialize(d)
            }
            fn visit_bool<E>(self, v: bool) -> Result<Yaml, E> {
                Ok(Yaml::Bool(v))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Yaml, E> {
                Ok(Yaml::Int(v))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Yaml, E> {
                i64::try_from(v).map(Yaml::Int).map_err(|_| {
                    E::custom(format!("integer {v} does not fit a ROS integer (int64)"))
                })
            }
            fn visit_f64<E>(self, v: f64) -> Result<Yaml, E> {
                Ok(Yaml::Float(v))
            }
            fn visit_str<E>(self, v: &str) -> Result<Yaml, E> {
                Ok(Yaml::Str(v.to_string()))
            }
            fn visit_string<E>(self, v: String) -> Result<Yaml, E> {
                Ok(Yaml::Str(v))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Yaml, A::Error> {
                let mut items = Vec::new();
                while let Some(item) = seq.next_element::<Yaml>()? {
                    items.push(item);
                }
                Ok(Yaml::Seq(items))
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Yaml, A::Error> {
                let mut entries = Vec::new();
                while let Some(key) = map.next_key::<String>()? {
                    let value = map.next_value::<Yaml>()?;
                    entries.push((key, value));
                }
                Ok(Yaml::Map(entries))
            }
        }
        d.deserialize_any(V)
    }
}
