//! CDR encoding (XCDR1, plain CDR) with the 4-byte encapsulation header.

use byteorder::{BigEndian, ByteOrder, LittleEndian};
use cdr_encoding::{CdrDeserializer, Error as CdrLibError};
use serde::{Serialize, de::DeserializeOwned};

/// Encapsulation header of plain CDR, little endian (what [`encode`] writes).
pub const ENCAPSULATION_CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];
/// Encapsulation header of plain CDR, big endian (accepted by [`decode`]).
pub const ENCAPSULATION_CDR_BE: [u8; 4] = [0x00, 0x00, 0x00, 0x00];

/// Bytes that may follow the last field: padding up to the next 4-byte boundary, which some
/// writers add (RTPS serialized payloads are a multiple of 4 bytes).
const MAX_TRAILING_PADDING: usize = 3;

/// Why CDR bytes could not be decoded. Offsets count from the start of the buffer (the
/// encapsulation header is bytes 0..4).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    #[error(
        "{type_name}: CDR buffer of {len} bytes is too short to hold the 4-byte encapsulation header"
    )]
    MissingHeader { type_name: &'static str, len: usize },
    #[error(
        "{type_name}: unsupported CDR encapsulation header {:02x} {:02x} {:02x} {:02x}: expected 00 01 00 00 (plain CDR, little endian) or 00 00 00 00 (big endian)",
        header[0], header[1], header[2], header[3]
    )]
    BadEncapsulation {
        type_name: &'static str,
        header: [u8; 4],
    },
    #[error(
        "{type_name}: CDR buffer truncated: it has {len} bytes and ends inside the message (a field at byte {offset} needs more)"
    )]
    Truncated {
        type_name: &'static str,
        len: usize,
        offset: usize,
    },
    #[error("{type_name}: string ending before byte {offset} is not valid UTF-8: {detail}")]
    InvalidUtf8 {
        type_name: &'static str,
        offset: usize,
        detail: String,
    },
    #[error("{type_name}: bool at byte {offset} is {value}, must be 0 or 1")]
    BadBool {
        type_name: &'static str,
        offset: usize,
        value: u8,
    },
    #[error(
        "{type_name}: {count} bytes left after the end of the message at byte {offset} (at most {MAX_TRAILING_PADDING} bytes of padding may follow): wrong message type?"
    )]
    TrailingBytes {
        type_name: &'static str,
        offset: usize,
        count: usize,
    },
    #[error("{type_name}: cannot decode CDR at byte {offset}: {detail}")]
    Other {
        type_name: &'static str,
        offset: usize,
        detail: String,
    },
}

/// Encodes `msg` as plain CDR, little endian, after the encapsulation header `00 01 00 00`.
/// Alignment counts from the end of the header.
pub fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    let body = cdr_encoding::to_vec::<T, LittleEndian>(msg)
        // Only unsized sequences or maps can fail, and the message types have none.
        .expect("CDR encoding of a message struct cannot fail");
    let mut out = Vec::with_capacity(4 + body.len());
    out.extend_from_slice(&ENCAPSULATION_CDR_LE);
    out.extend_from_slice(&body);
    out
}

/// Decodes CDR bytes that start with an encapsulation header (plain CDR, either byte order;
/// the two option bytes are ignored). `type_name` names the type in errors.
pub fn decode<T: DeserializeOwned>(bytes: &[u8], type_name: &'static str) -> Result<T, CdrError> {
    if bytes.len() < 4 {
        return Err(CdrError::MissingHeader {
            type_name,
            len: bytes.len(),
        });
    }
    let header = [bytes[0], bytes[1], bytes[2], bytes[3]];
    match [header[0], header[1]] {
        [0x00, 0x01] => decode_body::<T, LittleEndian>(bytes, type_name),
        [0x00, 0x00] => decode_body::<T, BigEndian>(bytes, type_name),
        _ => Err(CdrError::BadEncapsulation { type_name, header }),
    }
}

fn decode_body<T: DeserializeOwned, BO: ByteOrder>(
    bytes: &[u8],
    type_name: &'static str,
) -> Result<T, CdrError> {
    let body = &bytes[4..];
    let mut de = CdrDeserializer::<BO>::new(body);
    let result = T::deserialize(&mut de);
    let offset = 4 + de.bytes_consumed();
    match result {
        Ok(value) => {
            let count = bytes.len() - offset;
            if count > MAX_TRAILING_PADDING {
                Err(CdrError::TrailingBytes {
                    type_name,
                    offset,
                    count,
                })
            } else {
                Ok(value)
            }
        }
        Err(e) => Err(match e {
            CdrLibError::Eof => CdrError::Truncated {
                type_name,
                len: bytes.len(),
                offset,
            },
            CdrLibError::BadUTF8(u) => CdrError::InvalidUtf8 {
                type_name,
                offset,
                detail: u.to_string(),
            },
            CdrLibError::BadBoolean(value) => CdrError::BadBool {
                type_name,
                // The bad byte has been consumed.
                offset: offset - 1,
                value,
            },
            other => CdrError::Other {
                type_name,
                offset,
                detail: other.to_string(),
            },
        }),
    }
}
