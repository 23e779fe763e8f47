//! Field paths into a message: `data[0]`, `wrench.force.z`, `position[shock_left]`.
//!
//! A path is field names joined by `.`, each optionally followed by one `[...]` on an array
//! field: an index (`data[0]`), or a key (`position[shock_left]`), which selects the element at
//! the index of the key in the string array `name` of the same message (the convention of
//! `sensor_msgs/JointState`). A path must end on a number (an integer or float field, or an
//! element of an array of them).

use super::decode::Value;
use super::parse::{ArrayKind, FieldType, Primitive, Registry};

/// The array field whose strings name the elements of its sibling arrays.
pub const KEY_FIELD: &str = "name";

#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Selector {
    Index(usize),
    Key(String),
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    pub field: String,
    pub select: Option<Selector>,
}

/// A parsed field path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldPath {
    pub text: String,
    pub segments: Vec<Segment>,
}

/// Why a path does not fit a message definition.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PathError {
    #[error("field path '{0}' is malformed: {1}")]
    Syntax(String, String),
    #[error("{type_name} has no field '{field}' (its fields: {available})")]
    MissingField {
        type_name: String,
        field: String,
        available: String,
    },
    #[error("field '{path}' is {found}, not a number")]
    NotNumeric { path: String, found: String },
    #[error("field '{path}': {problem}")]
    BadSelector { path: String, problem: String },
}

fn valid_name(s: &str) -> bool {
    s.starts_with(|c: char| c.is_ascii_alphabetic())
        && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

impl std::str::FromStr for FieldPath {
    type Err = PathError;

    fn from_str(text: &str) -> Result<FieldPath, PathError> {
        let bad = |why: &str| PathError::Syntax(text.to_string(), why.to_string());
        let mut segments = Vec::new();
        for part in text.split('.') {
            let (name, select) = match part.split_once('[') {
                Some((name, rest)) => {
                    let inner = rest
                        .strip_suffix(']')
                        .filter(|i| !i.is_empty() && !i.contains(['[', ']']))
                        .ok_or_else(|| bad("expected one '[index]' or '[key]' after a field"))?;
                    let select = match inner.parse::<usize>() {
                        Ok(i) => Selector::Index(i),
                        Err(_) if inner.starts_with(|c: char| c.is_ascii_digit() || c == '-') => {
                            return Err(bad("an index must be a whole number from 0"));
                        }
                        Err(_) => Selector::Key(inner.trim().to_string()),
                    };
                    (name, Some(select))
                }
                None => (part, None),
            };
            if !valid_name(name) {
                return Err(bad(&format!("'{name}' is not a field name")));
            }
            segments.push(Segment {
                field: name.to_string(),
                select,
            });
        }
        Ok(FieldPath {
            text: text.to_string(),
            segments,
        })
    }
}

impl FieldPath {
    /// Checks the path against the definition of `root` in `reg` (checked): every field exists,
    /// selectors sit on arrays (keys on arrays with a sibling `name` string array, indexes
    /// within a fixed array's size), and the path ends on a number.
    pub fn check(&self, reg: &Registry, root: &str) -> Result<(), PathError> {
        let mut type_name = root.to_string();
        let mut done = String::new();
        for (i, seg) in self.segments.iter().enumerate() {
            let def = reg.get(&type_name).ok_or_else(|| PathError::MissingField {
                type_name: type_name.clone(),
                field: seg.field.clone(),
                available: String::new(),
            })?;
            let f = def
                .fields
                .iter()
                .find(|f| f.name == seg.field)
                .ok_or_else(|| PathError::MissingField {
                    type_name: type_name.clone(),
                    field: seg.field.clone(),
                    available: def
                        .fields
                        .iter()
                        .map(|f| f.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", "),
                })?;
            if !done.is_empty() {
                done.push('.');
            }
            done.push_str(&seg.field);
            let selector_err = |problem: String| PathError::BadSelector {
                path: done.clone(),
                problem,
            };
            match (&seg.select, f.array) {
                (None, ArrayKind::Single) => {}
                (None, _) => {
                    return Err(PathError::NotNumeric {
                        path: self.text.clone(),
                        found: "an array (select an element: [index] or [name])".into(),
                    });
                }
                (Some(_), ArrayKind::Single) => {
                    return Err(selector_err("not an array".into()));
                }
                (Some(Selector::Index(k)), ArrayKind::Fixed(n)) if *k >= n => {
                    return Err(selector_err(format!("index {k} past its {n} elements")));
                }
                (Some(Selector::Key(_)), _) => {
                    let has_names = def.fields.iter().any(|g| {
                        g.name == KEY_FIELD
                            && g.array != ArrayKind::Single
                            && matches!(
                                g.ty,
                                FieldType::Primitive(Primitive::String(_) | Primitive::WString(_))
                            )
                    });
                    if !has_names {
                        return Err(selector_err(format!(
                            "a [key] needs a string array '{KEY_FIELD}' beside it in {type_name}"
                        )));
                    }
                }
                (Some(Selector::Index(_)), _) => {}
            }
            let last = i + 1 == self.segments.len();
            match &f.ty {
                FieldType::Message(m) if last => {
                    return Err(PathError::NotNumeric {
                        path: self.text.clone(),
                        found: format!("a message ({m})"),
                    });
                }
                FieldType::Message(m) => type_name = m.clone(),
                FieldType::Primitive(p) if last && !p.is_numeric() => {
                    return Err(PathError::NotNumeric {
                        path: self.text.clone(),
                        found: format!("a {}", p.name()),
                    });
                }
                FieldType::Primitive(_) if !last => {
                    return Err(PathError::MissingField {
                        type_name: type_name.clone(),
                        field: self.segments[i + 1].field.clone(),
                        available: format!("'{done}' is a number, it has no fields"),
                    });
                }
                FieldType::Primitive(_) => {}
            }
        }
        Ok(())
    }

    /// The number at this path in a decoded message; the error says what is missing (an index
    /// past the end of a sequence, a key not among the names).
    pub fn get(&self, msg: &Value) -> Result<f64, String> {
        let mut v = msg;
        for seg in &self.segments {
            let parent = v;
            v = parent
                .field(&seg.field)
                .ok_or_else(|| format!("no field '{}'", seg.field))?;
            let Some(select) = &seg.select else {
                continue;
            };
            let Value::Array(items) = v else {
                return Err(format!("'{}' is not an array", seg.field));
            };
            let k = match select {
                Selector::Index(k) => *k,
                Selector::Key(key) => match parent.field(KEY_FIELD) {
                    Some(Value::Array(names)) => names
                        .iter()
                        .position(|n| matches!(n, Value::String(s) if s == key))
                        .ok_or_else(|| {
                            let names: Vec<String> = names
                                .iter()
                                .filter_map(|n| match n {
                                    Value::String(s) => Some(s.clone()),
                                    _ => None,
                                })
                                .collect();
                            format!("no '{key}' among {KEY_FIELD} [{}]", names.join(", "))
                        })?,
                    _ => return Err(format!("no string array '{KEY_FIELD}' for [{key}]")),
                },
            };
            v = items.get(k).ok_or_else(|| {
                format!(
                    "'{}[{k}]': the message has {} elements",
                    seg.field,
                    items.len()
                )
            })?;
        }
        v.as_f64()
            .ok_or_else(|| format!("'{}' is not a number", self.text))
    }
}
