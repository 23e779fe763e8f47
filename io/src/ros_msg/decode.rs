//! Dynamic decoding of plain CDR (XCDR1), as ROS 2's rmw implementations write it: a 4-byte
//! encapsulation header (`00 01` little endian, `00 00` big endian, then two option bytes),
//! then the fields in definition order, each primitive aligned to its size (8 for 64-bit
//! types) counted from the end of the header; strings and sequences as a `uint32` length (a
//! string's counts its terminating NUL) then their elements; fixed arrays without a length.
//!
//! Any bytes against any checked definition give a value or an error, never a panic, and
//! never an allocation larger than the input: every element read consumes at least one byte
//! (the parser refuses empty fixed arrays, and an empty message has one `uint8`).

use super::parse::{ArrayKind, Field, FieldType, Primitive, Registry};

/// A decoded value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Bool(bool),
    Int(i64),
    UInt(u64),
    Float(f64),
    String(String),
    Array(Vec<Value>),
    /// A nested message: its fields in definition order.
    Message(Vec<(String, Value)>),
}

impl Value {
    /// The value as a number (integers and floats); `None` for other kinds.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            Value::Int(v) => Some(*v as f64),
            Value::UInt(v) => Some(*v as f64),
            Value::Float(v) => Some(*v),
            _ => None,
        }
    }

    /// The field `name` of a message value.
    pub fn field(&self, name: &str) -> Option<&Value> {
        match self {
            Value::Message(fields) => fields.iter().find(|(n, _)| n == name).map(|(_, v)| v),
            _ => None,
        }
    }
}

/// Why bytes did not decode as a type. Offsets count from the start of the buffer (the
/// encapsulation header is bytes 0..4).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    #[error("{len} bytes: too short for the 4-byte CDR encapsulation header")]
    MissingHeader { len: usize },
    #[error(
        "unsupported CDR encapsulation {:02x} {:02x}: expected plain CDR (00 01 little endian, 00 00 big endian)",
        header[0], header[1]
    )]
    BadEncapsulation { header: [u8; 2] },
    #[error("field {field}: the message ends at byte {len}, a value at byte {offset} needs more")]
    Truncated {
        field: String,
        offset: usize,
        len: usize,
    },
    #[error("field {field} at byte {offset}: {problem}")]
    Invalid {
        field: String,
        offset: usize,
        problem: String,
    },
    #[error("no definition of {0}")]
    Unknown(String),
    #[error(
        "{count} bytes left after the end of the message at byte {offset}: wrong message type?"
    )]
    TrailingBytes { offset: usize, count: usize },
}

/// Bytes that may follow the last field (padding to a 4-byte multiple, as RTPS payloads are).
const MAX_TRAILING_PADDING: usize = 3;

struct Cursor<'a> {
    buf: &'a [u8],
    /// Position in `buf` (the body, after the encapsulation header).
    pos: usize,
    big_endian: bool,
}

impl Cursor<'_> {
    fn truncated(&self, path: &str, need: usize) -> DecodeError {
        DecodeError::Truncated {
            field: path.to_string(),
            offset: 4 + self.pos + need,
            len: 4 + self.buf.len(),
        }
    }

    fn align(&mut self, n: usize, path: &str) -> Result<(), DecodeError> {
        let pad = (n - self.pos % n) % n;
        if self.pos + pad > self.buf.len() {
            return Err(self.truncated(path, pad));
        }
        self.pos += pad;
        Ok(())
    }

    /// `N` bytes after aligning to `N`, in native order (swapped from the wire's order).
    fn take<const N: usize>(&mut self, path: &str) -> Result<[u8; N], DecodeError> {
        self.align(N, path)?;
        let end = self.pos + N;
        let slice = self
            .buf
            .get(self.pos..end)
            .ok_or_else(|| self.truncated(path, N))?;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        if self.big_endian {
            out.reverse();
        }
        self.pos = end;
        Ok(out)
    }

    fn u32(&mut self, path: &str) -> Result<u32, DecodeError> {
        self.take::<4>(path).map(u32::from_le_bytes)
    }

    fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }

    fn invalid(&self, path: &str, problem: String) -> DecodeError {
        DecodeError::Invalid {
            field: path.to_string(),
            offset: 4 + self.pos,
            problem,
        }
    }
}

/// Decodes `bytes` (with the encapsulation header) as the message `type_name` of `registry`
/// (which should have passed [`Registry::check`] for it).
pub fn decode(registry: &Registry, type_name: &str, bytes: &[u8]) -> Result<Value, DecodeError> {
    if bytes.len() < 4 {
        return Err(DecodeError::MissingHeader { len: bytes.len() });
    }
    let big_endian = match [bytes[0], bytes[1]] {
        [0x00, 0x01] => false,
        [0x00, 0x00] => true,
        header => return Err(DecodeError::BadEncapsulation { header }),
    };
    let mut c = Cursor {
        buf: &bytes[4..],
        pos: 0,
        big_endian,
    };
    let value = message(registry, type_name, &mut c, "", 0)?;
    let count = c.remaining();
    if count > MAX_TRAILING_PADDING {
        return Err(DecodeError::TrailingBytes {
            offset: 4 + c.pos,
            count,
        });
    }
    Ok(value)
}

/// Nesting deeper than this is refused (a checked registry has no recursion; this guards an
/// unchecked one).
const MAX_DEPTH: usize = 64;

fn message(
    reg: &Registry,
    type_name: &str,
    c: &mut Cursor,
    path: &str,
    depth: usize,
) -> Result<Value, DecodeError> {
    let def = reg
        .get(type_name)
        .ok_or_else(|| DecodeError::Unknown(type_name.to_string()))?;
    if depth > MAX_DEPTH {
        return Err(c.invalid(path, format!("nested deeper than {MAX_DEPTH} messages")));
    }
    let mut fields = Vec::with_capacity(def.fields.len());
    for f in &def.fields {
        let p = if path.is_empty() {
            f.name.clone()
        } else {
            format!("{path}.{}", f.name)
        };
        fields.push((f.name.clone(), field(reg, f, c, &p, depth)?));
    }
    Ok(Value::Message(fields))
}

fn field(
    reg: &Registry,
    f: &Field,
    c: &mut Cursor,
    path: &str,
    depth: usize,
) -> Result<Value, DecodeError> {
    let n = match f.array {
        ArrayKind::Single => return element(reg, &f.ty, c, path, depth),
        ArrayKind::Fixed(n) => n,
        ArrayKind::Bounded(_) | ArrayKind::Unbounded => c.u32(path)? as usize,
    };
    if let ArrayKind::Bounded(bound) = f.array
        && n > bound
    {
        return Err(c.invalid(
            path,
            format!("{n} elements where at most {bound} are allowed"),
        ));
    }
    // Each element takes at least one byte: more elements than bytes left cannot decode.
    if n > c.remaining() {
        return Err(c.truncated(path, n));
    }
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        out.push(element(reg, &f.ty, c, &format!("{path}[{i}]"), depth)?);
    }
    Ok(Value::Array(out))
}

fn element(
    reg: &Registry,
    ty: &FieldType,
    c: &mut Cursor,
    path: &str,
    depth: usize,
) -> Result<Value, DecodeError> {
    let p = match ty {
        FieldType::Message(name) => return message(reg, name, c, path, depth + 1),
        FieldType::Primitive(p) => *p,
    };
    Ok(match p {
        Primitive::Bool => match c.take::<1>(path)?[0] {
            0 => Value::Bool(false),
            1 => Value::Bool(true),
            b => return Err(c.invalid(path, format!("bool is {b}, must be 0 or 1"))),
        },
        Primitive::Int8 => Value::Int(i8::from_le_bytes(c.take::<1>(path)?).into()),
        Primitive::UInt8 => Value::UInt(c.take::<1>(path)?[0].into()),
        Primitive::Int16 => Value::Int(i16::from_le_bytes(c.take::<2>(path)?).into()),
        Primitive::UInt16 => Value::UInt(u16::from_le_bytes(c.take::<2>(path)?).into()),
        Primitive::Int32 => Value::Int(i32::from_le_bytes(c.take::<4>(path)?).into()),
        Primitive::UInt32 => Value::UInt(u32::from_le_bytes(c.take::<4>(path)?).into()),
        Primitive::Int64 => Value::Int(i64::from_le_bytes(c.take::<8>(path)?)),
        Primitive::UInt64 => Value::UInt(u64::from_le_bytes(c.take::<8>(path)?)),
        Primitive::Float32 => Value::Float(f32::from_le_bytes(c.take::<4>(path)?).into()),
        Primitive::Float64 => Value::Float(f64::from_le_bytes(c.take::<8>(path)?)),
        Primitive::String(bound) => {
            let len = c.u32(path)? as usize;
            let bytes = c
                .buf
                .get(c.pos..c.pos.saturating_add(len))
                .ok_or_else(|| c.truncated(path, len))?;
            // The length counts the terminating NUL; some writers send 0 for "".
            let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
            let s = std::str::from_utf8(text)
                .map_err(|e| c.invalid(path, format!("string is not UTF-8: {e}")))?
                .to_string();
            if let Some(b) = bound
                && s.len() > b
            {
                return Err(c.invalid(path, format!("string of {} bytes, bound {b}", s.len())));
            }
            c.pos += len;
            Value::String(s)
        }
        Primitive::WString(bound) => {
            let len = c.u32(path)? as usize;
            if len.saturating_mul(2) > c.remaining() {
                return Err(c.truncated(path, len.saturating_mul(2)));
            }
            if let Some(b) = bound
                && len > b
            {
                return Err(c.invalid(path, format!("wstring of {len} units, bound {b}")));
            }
            let mut units = Vec::with_capacity(len);
            for _ in 0..len {
                units.push(u16::from_le_bytes(c.take::<2>(path)?));
            }
            let units = units.strip_suffix(&[0]).unwrap_or(&units);
            Value::String(String::from_utf16_lossy(units))
        }
    })
}
