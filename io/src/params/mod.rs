//! ROS 2 parameter files (`--params-file`) and `-p name:=value` overrides.
//!
//! The file format is the one `rcl` reads:
//!
//! ```yaml
//! /**:
//!   ros__parameters:
//!     mass_kg: 36.0
//!     model: coulomb
//! forcemap_analyzer:            # or /namespace/forcemap_analyzer, or nested namespaces
//!   ros__parameters:
//!     rig:
//!       mass_kg: 40             # flattened to `rig.mass_kg`
//! ```
//!
//! Node keys are fully qualified node names (a key without a leading `/` is in the root
//! namespace) and may contain the ROS wildcards `*` (one name token) and `**` (any number of
//! tokens); namespaces may also be written as nested mappings. Entries matching the node are
//! merged: entries with wildcards first, then exact ones, each group in file order, so a
//! node-specific value overrides a `/**` one.
//!
//! Values: bool, integer (int64), double, string, and arrays of one of those. As in ROS, a
//! quoted scalar is a string, `yes`/`no`/`on`/`off` are booleans, and an integer is accepted
//! where a double is asked for. An array mixing integers and doubles is read as a double
//! array (rcl would refuse it). `null` values, nested arrays and mappings inside arrays are
//! refused.

use std::collections::BTreeMap;
use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

/// The key under a node name that holds its parameters.
mod yaml;

use yaml::{Yaml, collect_nodes, flatten, glob_match, has_ros_parameters, to_param_value};

pub const ROS_PARAMETERS_KEY: &str = "ros__parameters";

/// One parameter value (the ROS 2 parameter types, without byte arrays).
#[derive(Debug, Clone, PartialEq)]
pub enum ParamValue {
    Bool(bool),
    Integer(i64),
    Double(f64),
    String(String),
    BoolArray(Vec<bool>),
    IntegerArray(Vec<i64>),
    DoubleArray(Vec<f64>),
    StringArray(Vec<String>),
    /// `[]`: accepted by every array getter.
    EmptyArray,
}

impl ParamValue {
    /// The ROS type name (`double`, `string_array`, ...).
    pub fn type_name(&self) -> &'static str {
        match self {
            ParamValue::Bool(_) => "bool",
            ParamValue::Integer(_) => "integer",
            ParamValue::Double(_) => "double",
            ParamValue::String(_) => "string",
            ParamValue::BoolArray(_) => "bool_array",
            ParamValue::IntegerArray(_) => "integer_array",
            ParamValue::DoubleArray(_) => "double_array",
            ParamValue::StringArray(_) => "string_array",
            ParamValue::EmptyArray => "empty array",
        }
    }
}

impl fmt::Display for ParamValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fn list<T: fmt::Debug>(f: &mut fmt::Formatter<'_>, v: &[T]) -> fmt::Result {
            write!(f, "{v:?}")
        }
        match self {
            ParamValue::Bool(v) => write!(f, "{v}"),
            ParamValue::Integer(v) => write!(f, "{v}"),
            ParamValue::Double(v) => write!(f, "{v:?}"),
            ParamValue::String(v) => write!(f, "{v:?}"),
            ParamValue::BoolArray(v) => list(f, v),
            ParamValue::IntegerArray(v) => list(f, v),
            ParamValue::DoubleArray(v) => list(f, v),
            ParamValue::StringArray(v) => list(f, v),
            ParamValue::EmptyArray => f.write_str("[]"),
        }
    }
}

/// Errors of [`read_params`], [`Params::set_from_override`] and the typed getters.
#[derive(Debug, thiserror::Error)]
pub enum ParamsError {
    #[error("{}: parameter file not found", path.display())]
    NotFound { path: PathBuf },
    #[error("{}: cannot read the parameter file: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error(
        "{}{}: YAML error: {message}",
        path.display(),
        match (line, column) {
            (Some(l), Some(c)) => format!(":{l}:{c} (line {l}, column {c})"),
            (Some(l), None) => format!(":{l} (line {l})"),
            _ => String::new(),
        }
    )]
    Syntax {
        path: PathBuf,
        line: Option<u64>,
        column: Option<u64>,
        message: String,
    },
    #[error(
        "{}: no '{ROS_PARAMETERS_KEY}' key; expected the ROS 2 layout \
         '/**:' (or '<node_name>:') -> '{ROS_PARAMETERS_KEY}:' -> parameters",
        path.display()
    )]
    NoRosParameters { path: PathBuf },
    #[error("{}: {message}", path.display())]
    Structure { path: PathBuf, message: String },
    #[error(
        "{}: no parameters apply to node '{node}'; the file has entries for [{}]",
        path.display(), available.join(", ")
    )]
    NoMatchingNode {
        path: PathBuf,
        node: String,
        available: Vec<String>,
    },
    #[error("{origin}: parameter '{name}': {reason}")]
    UnsupportedValue {
        origin: String,
        name: String,
        reason: String,
    },
    #[error("{origin}: parameter '{name}' is not set")]
    Missing { origin: String, name: String },
    #[error("{origin}: parameter '{name}': expected {expected}, found {found}")]
    WrongType {
        origin: String,
        name: String,
        expected: &'static str,
        /// Type and value found, e.g. `string "heavy"`.
        found: String,
    },
    #[error("bad parameter override '{text}': {reason} (expected 'name:=value')")]
    BadOverride { text: String, reason: String },
}

/// Parameter name -> value, with where each value came from (for error messages).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params {
    /// The file read (empty when built in memory); named in errors about missing parameters.
    source: String,
    values: BTreeMap<String, (ParamValue, String)>,
}

/// Reads a ROS 2 parameter file for `node_name` (e.g. `forcemap_analyzer` or
/// `/rig/forcemap_analyzer`; a name without a leading `/` is in the root namespace). With
/// `None`, only the entries that apply to every node (`/**`) are used.
pub fn read_params(path: impl AsRef<Path>, node_name: Option<&str>) -> Result<Params, ParamsError> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|source| {
        if source.kind() == io::ErrorKind::NotFound {
            ParamsError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            ParamsError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    })?;
    Params::from_yaml_str(&text, path, node_name)
}

impl Params {
    /// An empty parameter set.
    pub fn new() -> Params {
        Params::default()
    }

    /// Parses the text of a ROS 2 parameter file; `path` is used in messages only.
    pub fn from_yaml_str(
        text: &str,
        path: &Path,
        node_name: Option<&str>,
    ) -> Result<Params, ParamsError> {
        let p = || path.to_path_buf();
        let doc: Yaml = if text.trim().is_empty() {
            Yaml::Null
        } else {
            serde_saphyr::from_str(text).map_err(|e| {
                let loc = e.location();
                ParamsError::Syntax {
                    path: p(),
                    line: loc.map(|l| l.line()),
                    column: loc.map(|l| l.column()),
                    message: e.without_snippet().to_string(),
                }
            })?
        };
        let Yaml::Map(top) = doc else {
            return Err(ParamsError::NoRosParameters { path: p() });
        };
        if !has_ros_parameters(&top) {
            return Err(ParamsError::NoRosParameters { path: p() });
        }
        let mut entries: Vec<(String, &Vec<(String, Yaml)>)> = Vec::new();
        collect_nodes(&top, &mut Vec::new(), &mut entries, path)?;
        if entries.is_empty() {
            return Err(ParamsError::NoRosParameters { path: p() });
        }

        let node_tokens: Option<Vec<&str>> =
            node_name.map(|n| n.split('/').filter(|t| !t.is_empty()).collect());
        let applies = |pattern: &str| -> bool {
            let pat: Vec<&str> = pattern.split('/').filter(|t| !t.is_empty()).collect();
            match &node_tokens {
                Some(node) => glob_match(&pat, node),
                None => pat.iter().all(|t| *t == "**"),
            }
        };
        let is_wild = |pattern: &str| pattern.contains('*');
        let source = path.display().to_string();
        let mut params = Params {
            source: source.clone(),
            values: BTreeMap::new(),
        };
        let mut matched = false;
        for wild_pass in [true, false] {
            for (pattern, map) in &entries {
                if is_wild(pattern) == wild_pass && applies(pattern) {
                    matched = true;
                    flatten(map, "", &mut params.values, &source)?;
                }
            }
        }
        if !matched {
            return Err(ParamsError::NoMatchingNode {
                path: p(),
                node: node_name.map_or_else(
                    || "(none given: only '/**' entries apply)".to_string(),
                    str::to_string,
                ),
                available: entries.iter().map(|(k, _)| k.clone()).collect(),
            });
        }
        Ok(params)
    }

    /// Applies a `--ros-args -p name:=value` override; the value is parsed as a YAML scalar
    /// (or flow sequence such as `[1.0, 2.0]`) like ROS does. Replaces any previous value.
    pub fn set_from_override(&mut self, text: &str) -> Result<(), ParamsError> {
        let bad = |reason: &str| ParamsError::BadOverride {
            text: text.to_string(),
            reason: reason.to_string(),
        };
        let Some((name, value_text)) = text.split_once(":=") else {
            return Err(bad("no ':='"));
        };
        let name = name.trim();
        if name.is_empty() {
            return Err(bad("empty parameter name"));
        }
        if name.chars().any(|c| c.is_whitespace() || c == ':') {
            return Err(bad("the parameter name contains whitespace or ':'"));
        }
        if value_text.trim().is_empty() {
            return Err(bad("empty value"));
        }
        let yaml: Yaml = serde_saphyr::from_str(value_text)
            .map_err(|e| bad(&format!("invalid YAML value: {}", e.without_snippet())))?;
        if matches!(yaml, Yaml::Map(_)) {
            return Err(bad("the value is a mapping; expected a scalar or an array"));
        }
        let origin = format!("command-line override '{text}'");
        let value = to_param_value(&yaml, name, &origin)?;
        self.values.insert(name.to_string(), (value, origin));
        Ok(())
    }

    /// Sets a value read from somewhere else (`origin` is shown in errors).
    pub fn set_with_origin(&mut self, name: &str, value: ParamValue, origin: &str) {
        self.values
            .insert(name.to_string(), (value, origin.to_string()));
    }

    /// Sets a value directly (origin shown in errors: "set in code").
    pub fn set(&mut self, name: &str, value: ParamValue) {
        self.values
            .insert(name.to_string(), (value, "set in code".to_string()));
    }

    pub fn get(&self, name: &str) -> Option<&ParamValue> {
        self.values.get(name).map(|(v, _)| v)
    }

    pub fn contains(&self, name: &str) -> bool {
        self.values.contains_key(name)
    }

    /// Parameter names, sorted.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.values.keys().map(String::as_str)
    }

    /// (name, value), sorted by name.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &ParamValue)> {
        self.values.iter().map(|(k, (v, _))| (k.as_str(), v))
    }

    pub fn len(&self) -> usize {
        self.values.len()
    }

    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Where a parameter's value came from (file path or override), if set.
    pub fn origin(&self, name: &str) -> Option<&str> {
        self.values.get(name).map(|(_, o)| o.as_str())
    }

    fn typed<'a, T>(
        &'a self,
        name: &str,
        expected: &'static str,
        convert: impl Fn(&'a ParamValue) -> Option<T>,
    ) -> Result<Option<T>, ParamsError> {
        match self.values.get(name) {
            None => Ok(None),
            Some((v, origin)) => convert(v).map(Some).ok_or_else(|| ParamsError::WrongType {
                origin: origin.clone(),
                name: name.to_string(),
                expected,
                found: format!("{} {v}", v.type_name()),
            }),
        }
    }

    fn required<T>(&self, name: &str, v: Result<Option<T>, ParamsError>) -> Result<T, ParamsError> {
        v?.ok_or_else(|| ParamsError::Missing {
            origin: if self.source.is_empty() {
                "parameters".to_string()
            } else {
                self.source.clone()
            },
            name: name.to_string(),
        })
    }

    /// A double; an integer is accepted (as ROS does).
    pub fn opt_f64(&self, name: &str) -> Result<Option<f64>, ParamsError> {
        self.typed(name, "double", |v| match v {
            ParamValue::Double(x) => Some(*x),
            ParamValue::Integer(i) => Some(*i as f64),
            _ => None,
        })
    }

    pub fn opt_i64(&self, name: &str) -> Result<Option<i64>, ParamsError> {
        self.typed(name, "integer", |v| match v {
            ParamValue::Integer(i) => Some(*i),
            _ => None,
        })
    }

    /// A non-negative integer.
    pub fn opt_usize(&self, name: &str) -> Result<Option<usize>, ParamsError> {
        self.typed(name, "non-negative integer", |v| match v {
            ParamValue::Integer(i) => usize::try_from(*i).ok(),
            _ => None,
        })
    }

    pub fn opt_bool(&self, name: &str) -> Result<Option<bool>, ParamsError> {
        self.typed(name, "bool", |v| match v {
            ParamValue::Bool(b) => Some(*b),
            _ => None,
        })
    }

    pub fn opt_str(&self, name: &str) -> Result<Option<&str>, ParamsError> {
        self.typed(name, "string", |v| match v {
            ParamValue::String(s) => Some(s.as_str()),
            _ => None,
        })
    }

    /// A double array; integer arrays are accepted.
    pub fn opt_f64_array(&self, name: &str) -> Result<Option<Vec<f64>>, ParamsError> {
        self.typed(name, "double_array", |v| match v {
            ParamValue::DoubleArray(x) => Some(x.clone()),
            ParamValue::IntegerArray(x) => Some(x.iter().map(|&i| i as f64).collect()),
            ParamValue::EmptyArray => Some(Vec::new()),
            _ => None,
        })
    }

    pub fn opt_i64_array(&self, name: &str) -> Result<Option<Vec<i64>>, ParamsError> {
        self.typed(name, "integer_array", |v| match v {
            ParamValue::IntegerArray(x) => Some(x.clone()),
            ParamValue::EmptyArray => Some(Vec::new()),
            _ => None,
        })
    }

    pub fn opt_bool_array(&self, name: &str) -> Result<Option<Vec<bool>>, ParamsError> {
        self.typed(name, "bool_array", |v| match v {
            ParamValue::BoolArray(x) => Some(x.clone()),
            ParamValue::EmptyArray => Some(Vec::new()),
            _ => None,
        })
    }

    pub fn opt_str_array(&self, name: &str) -> Result<Option<Vec<String>>, ParamsError> {
        self.typed(name, "string_array", |v| match v {
            ParamValue::StringArray(x) => Some(x.clone()),
            ParamValue::EmptyArray => Some(Vec::new()),
            _ => None,
        })
    }

    /// A required double (integers accepted).
    pub fn get_f64(&self, name: &str) -> Result<f64, ParamsError> {
        self.required(name, self.opt_f64(name))
    }

    pub fn get_i64(&self, name: &str) -> Result<i64, ParamsError> {
        self.required(name, self.opt_i64(name))
    }

    pub fn get_usize(&self, name: &str) -> Result<usize, ParamsError> {
        self.required(name, self.opt_usize(name))
    }

    pub fn get_bool(&self, name: &str) -> Result<bool, ParamsError> {
        self.required(name, self.opt_bool(name))
    }

    pub fn get_str(&self, name: &str) -> Result<&str, ParamsError> {
        self.required(name, self.opt_str(name))
    }

    pub fn get_f64_array(&self, name: &str) -> Result<Vec<f64>, ParamsError> {
        self.required(name, self.opt_f64_array(name))
    }

    pub fn get_i64_array(&self, name: &str) -> Result<Vec<i64>, ParamsError> {
        self.required(name, self.opt_i64_array(name))
    }

    pub fn get_bool_array(&self, name: &str) -> Result<Vec<bool>, ParamsError> {
        self.required(name, self.opt_bool_array(name))
    }

    pub fn get_str_array(&self, name: &str) -> Result<Vec<String>, ParamsError> {
        self.required(name, self.opt_str_array(name))
    }
}
