//! The ROS 2 `.msg` language, as far as decoding needs it: field lines (`TYPE NAME [DEFAULT]`),
//! constants (`TYPE NAME=VALUE`, read and ignored), comments, bounded strings (`string<=N`)
//! and arrays (`T[N]`, `T[<=N]`, `T[]`), nested types written `Type` (same package),
//! `pkg/Type` or `pkg/msg/Type`; and the schema text rosbag2 writes into an MCAP file: the
//! top-level definition, then each dependency after a line of `=` and a `MSG: pkg/Type` line.

use std::collections::BTreeMap;

/// The longest fixed or bounded array and bounded string accepted: a definition naming more
/// is refused (a fixed array's elements are decoded from the bytes one by one).
pub const MAX_BOUND: usize = 1 << 24;

/// Why a definition could not be read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MsgError {
    #[error("{type_name}, line {line}: {problem}")]
    Line {
        type_name: String,
        line: usize,
        problem: String,
    },
    #[error("{0}: not a message type name (expected pkg/msg/Type or pkg/Type)")]
    BadTypeName(String),
    #[error("schema of {root}: section {section} has no 'MSG: pkg/Type' line")]
    NoMsgLine { root: String, section: usize },
    #[error("{type_name}: field {field} has type {missing}, whose definition is not known")]
    Unresolved {
        type_name: String,
        field: String,
        missing: String,
    },
    #[error("{0}: the type contains itself (recursive definition)")]
    Recursive(String),
    #[error("no definition of {0}")]
    Unknown(String),
}

/// A primitive type of the `.msg` language.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    Bool,
    /// `byte`, `char`, `int8`, `uint8`: one byte (`char` and `uint8` unsigned, as in ROS 2).
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Float32,
    Float64,
    /// `string`, optionally bounded (`string<=N`).
    String(Option<usize>),
    /// `wstring`: UTF-16 code units.
    WString(Option<usize>),
}

impl Primitive {
    fn of(name: &str) -> Option<Primitive> {
        Some(match name {
            "bool" => Primitive::Bool,
            "int8" => Primitive::Int8,
            "byte" | "char" | "uint8" => Primitive::UInt8,
            "int16" => Primitive::Int16,
            "uint16" => Primitive::UInt16,
            "int32" => Primitive::Int32,
            "uint32" => Primitive::UInt32,
            "int64" => Primitive::Int64,
            "uint64" => Primitive::UInt64,
            "float32" => Primitive::Float32,
            "float64" => Primitive::Float64,
            "string" => Primitive::String(None),
            "wstring" => Primitive::WString(None),
            _ => return None,
        })
    }

    /// The `.msg` name of the type.
    pub fn name(self) -> &'static str {
        match self {
            Primitive::Bool => "bool",
            Primitive::Int8 => "int8",
            Primitive::UInt8 => "uint8",
            Primitive::Int16 => "int16",
            Primitive::UInt16 => "uint16",
            Primitive::Int32 => "int32",
            Primitive::UInt32 => "uint32",
            Primitive::Int64 => "int64",
            Primitive::UInt64 => "uint64",
            Primitive::Float32 => "float32",
            Primitive::Float64 => "float64",
            Primitive::String(_) => "string",
            Primitive::WString(_) => "wstring",
        }
    }

    /// True for the integer and floating point types (what a channel can be read from).
    pub fn is_numeric(self) -> bool {
        !matches!(
            self,
            Primitive::Bool | Primitive::String(_) | Primitive::WString(_)
        )
    }
}

/// The element type of a field.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FieldType {
    Primitive(Primitive),
    /// A nested message, by its full name `pkg/msg/Type`.
    Message(String),
}

/// Whether a field is an array, and of which kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArrayKind {
    Single,
    /// `T[N]`: exactly N elements, no length on the wire.
    Fixed(usize),
    /// `T[<=N]`: a sequence of at most N elements.
    Bounded(usize),
    /// `T[]`: a sequence.
    Unbounded,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    pub ty: FieldType,
    pub array: ArrayKind,
}

/// One message definition: its full name and fields in wire order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgDef {
    pub name: String,
    pub fields: Vec<Field>,
}

/// `pkg/msg/Type` from `pkg/msg/Type` or `pkg/Type`.
pub fn full_type_name(name: &str) -> Result<String, MsgError> {
    let parts: Vec<&str> = name.split('/').collect();
    let ok = |s: &str| {
        !s.is_empty()
            && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            && !s.starts_with(|c: char| c.is_ascii_digit())
    };
    match parts.as_slice() {
        [p, t] if ok(p) && ok(t) => Ok(format!("{p}/msg/{t}")),
        [p, "msg", t] if ok(p) && ok(t) => Ok(format!("{p}/msg/{t}")),
        _ => Err(MsgError::BadTypeName(name.to_string())),
    }
}

/// The text of a line before its comment (a `#` outside quotes).
fn strip_comment(line: &str) -> &str {
    let mut quote: Option<char> = None;
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (None, '#') => return &line[..i],
            (None, '"' | '\'') => quote = Some(c),
            (Some(q), _) if c == q => quote = None,
            _ => {}
        }
    }
    line
}

fn parse_bound(text: &str) -> Option<usize> {
    text.parse::<usize>().ok().filter(|n| *n <= MAX_BOUND)
}

/// Parses a type token (`float64`, `string<=5`, `Vector3[3]`, `pkg/Type[<=4]`) in package `pkg`.
fn parse_type(token: &str, pkg: &str) -> Result<(FieldType, ArrayKind), String> {
    let (base, array) = match token.find('[') {
        Some(i) => {
            let inner = token[i + 1..]
                .strip_suffix(']')
                .ok_or_else(|| format!("type '{token}': unclosed '['"))?;
            let array = if inner.is_empty() {
                ArrayKind::Unbounded
            } else if let Some(n) = inner.strip_prefix("<=") {
                ArrayKind::Bounded(
                    parse_bound(n).ok_or_else(|| format!("type '{token}': bad array bound"))?,
                )
            } else {
                // A fixed array takes at least one byte per element on the wire; an empty one
                // (which rosidl refuses too) would let a sequence of them cost nothing.
                ArrayKind::Fixed(
                    parse_bound(inner)
                        .filter(|n| *n > 0)
                        .ok_or_else(|| format!("type '{token}': bad array size"))?,
                )
            };
            (&token[..i], array)
        }
        None => (token, ArrayKind::Single),
    };
    let (base, bound) = match base.split_once("<=") {
        Some((b, n)) => (
            b,
            Some(parse_bound(n).ok_or_else(|| format!("type '{token}': bad string bound"))?),
        ),
        None => (base, None),
    };
    if let Some(p) = Primitive::of(base) {
        let p = match (p, bound) {
            (Primitive::String(_), b) => Primitive::String(b),
            (Primitive::WString(_), b) => Primitive::WString(b),
            (p, None) => p,
            (_, Some(_)) => return Err(format!("type '{token}': only strings can be bounded")),
        };
        return Ok((FieldType::Primitive(p), array));
    }
    if bound.is_some() {
        return Err(format!("type '{token}': only strings can be bounded"));
    }
    // ROS 1 names that ROS 2 tools still accept.
    let name = match base {
        "Header" => "std_msgs/msg/Header".to_string(),
        "time" => "builtin_interfaces/msg/Time".to_string(),
        "duration" => "builtin_interfaces/msg/Duration".to_string(),
        b if !b.contains('/') => {
            full_type_name(&format!("{pkg}/{b}")).map_err(|e| e.to_string())?
        }
        b => full_type_name(b).map_err(|e| e.to_string())?,
    };
    Ok((FieldType::Message(name), array))
}

fn valid_field_name(name: &str) -> bool {
    name.starts_with(|c: char| c.is_ascii_alphabetic())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// Parses the text of one `.msg` file defining `type_name` (`pkg/msg/Type` or `pkg/Type`).
/// Constants and default values are read and ignored (neither is on the wire). A definition
/// without fields gets the one `uint8` member ROS 2 generates for an empty message.
pub fn parse_msg(type_name: &str, text: &str) -> Result<MsgDef, MsgError> {
    let name = full_type_name(type_name)?;
    let pkg = name.split('/').next().unwrap_or_default().to_string();
    let mut fields: Vec<Field> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = strip_comment(raw).trim();
        if line.is_empty() {
            continue;
        }
        let err = |problem: String| MsgError::Line {
            type_name: name.clone(),
            line: i + 1,
            problem,
        };
        let (token, rest) = line
            .split_once(char::is_whitespace)
            .ok_or_else(|| err(format!("'{line}': a type without a field name")))?;
        let (ty, array) = parse_type(token, &pkg).map_err(err)?;
        let rest = rest.trim();
        // A constant: NAME=VALUE (spaces allowed around '=').
        let first = rest.split(char::is_whitespace).next().unwrap_or_default();
        if first.contains('=') || rest[first.len()..].trim_start().starts_with('=') {
            continue;
        }
        if !valid_field_name(first) {
            return Err(err(format!("'{first}' is not a field name")));
        }
        if fields.iter().any(|f| f.name == first) {
            return Err(err(format!("field '{first}' defined twice")));
        }
        fields.push(Field {
            name: first.to_string(),
            ty,
            array,
        });
    }
    if fields.is_empty() {
        fields.push(Field {
            name: "structure_needs_at_least_one_field".into(),
            ty: FieldType::Primitive(Primitive::UInt8),
            array: ArrayKind::Single,
        });
    }
    Ok(MsgDef { name, fields })
}

/// True for a line that separates the definitions of a schema (`=` only, at least three).
fn is_separator(line: &str) -> bool {
    let l = line.trim();
    l.len() >= 3 && l.chars().all(|c| c == '=')
}

/// Definitions by full type name; what a message is decoded against.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Registry {
    defs: BTreeMap<String, MsgDef>,
}

impl Registry {
    pub fn new() -> Registry {
        Registry::default()
    }

    /// Adds (or replaces) a definition.
    pub fn insert(&mut self, def: MsgDef) {
        self.defs.insert(def.name.clone(), def);
    }

    /// Adds every definition of `other` that this registry does not have.
    pub fn extend_missing(&mut self, other: &Registry) {
        for (k, v) in &other.defs {
            self.defs.entry(k.clone()).or_insert_with(|| v.clone());
        }
    }

    pub fn get(&self, type_name: &str) -> Option<&MsgDef> {
        self.defs.get(type_name)
    }

    pub fn contains(&self, type_name: &str) -> bool {
        self.defs.contains_key(type_name)
    }

    /// Parses a `ros2msg` schema as rosbag2 writes it for `root` (`pkg/msg/Type`): the root's
    /// definition, then `=====` lines each followed by `MSG: pkg/Type` and its definition.
    pub fn parse_schema(root: &str, text: &str) -> Result<Registry, MsgError> {
        let mut sections: Vec<Vec<&str>> = vec![Vec::new()];
        for line in text.lines() {
            if is_separator(line) {
                sections.push(Vec::new());
            } else if let Some(s) = sections.last_mut() {
                s.push(line);
            }
        }
        let mut reg = Registry::new();
        for (i, lines) in sections.iter().enumerate() {
            if i == 0 {
                reg.insert(parse_msg(root, &lines.join("\n"))?);
                continue;
            }
            let Some(pos) = lines
                .iter()
                .position(|l| !strip_comment(l).trim().is_empty())
            else {
                continue;
            };
            let name = lines[pos]
                .trim()
                .strip_prefix("MSG:")
                .ok_or_else(|| MsgError::NoMsgLine {
                    root: root.to_string(),
                    section: i,
                })?
                .trim();
            reg.insert(parse_msg(name, &lines[pos + 1..].join("\n"))?);
        }
        Ok(reg)
    }

    /// Checks that `root` and every type it uses are defined, and that none contains itself.
    pub fn check(&self, root: &str) -> Result<(), MsgError> {
        self.check_from(root, &mut Vec::new())
    }

    fn check_from(&self, name: &str, stack: &mut Vec<String>) -> Result<(), MsgError> {
        if stack.iter().any(|s| s == name) {
            return Err(MsgError::Recursive(name.to_string()));
        }
        let def = self
            .get(name)
            .ok_or_else(|| MsgError::Unknown(name.to_string()))?;
        stack.push(name.to_string());
        for f in &def.fields {
            if let FieldType::Message(m) = &f.ty {
                if !self.contains(m) {
                    return Err(MsgError::Unresolved {
                        type_name: name.to_string(),
                        field: f.name.clone(),
                        missing: m.clone(),
                    });
                }
                self.check_from(m, stack)?;
            }
        }
        stack.pop();
        Ok(())
    }
}
