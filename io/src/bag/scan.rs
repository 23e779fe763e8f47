//! A forgiving linear scan of an MCAP file held in memory: walks the records until the footer or
//! until the first record that is cut off or does not parse, and says where it stopped. Used to
//! report where a damaged file breaks, by the reader of files without an index, and by recovery.
use std::collections::{BTreeMap, HashMap};
use std::io::Read;

use mcap::records::{Record, op};

/// A schema record.
#[derive(Debug, Clone)]
pub(crate) struct RawSchema {
    pub name: String,
    pub encoding: String,
    pub data: Vec<u8>,
}

/// A channel record.
#[derive(Debug, Clone)]
pub(crate) struct RawChannel {
    pub topic: String,
    pub schema_id: u16,
    pub metadata: BTreeMap<String, String>,
}

/// A message record.
#[derive(Debug, Clone)]
pub(crate) struct RawMessage {
    pub channel_id: u16,
    pub sequence: u32,
    pub log_time: u64,
    pub publish_time: u64,
    pub data: Vec<u8>,
}

/// Where and why the scan stopped before the footer.
#[derive(Debug, Clone)]
pub(crate) struct Stop {
    /// Offset of the record that is cut off or broken.
    pub offset: u64,
    pub reason: String,
}

/// Everything a scan found, in file order.
#[derive(Debug, Default)]
pub(crate) struct Scan {
    pub schemas: HashMap<u16, RawSchema>,
    pub channels: HashMap<u16, RawChannel>,
    pub messages: Vec<RawMessage>,
    /// None when the footer was reached.
    pub stop: Option<Stop>,
    /// Chunks read whole.
    pub complete_chunks: usize,
    /// Messages taken from the decompressible prefix of a cut-off chunk.
    pub partial_chunk_messages: usize,
}

/// Whether the buffer starts with the MCAP magic.
pub(crate) fn has_magic(bytes: &[u8]) -> bool {
    bytes.len() >= mcap::MAGIC.len() && &bytes[..mcap::MAGIC.len()] == mcap::MAGIC
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    let s = b.get(at..at.checked_add(8)?)?;
    Some(u64::from_le_bytes(s.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(s.try_into().ok()?))
}

/// Scans a whole file (which must start with the magic).
/// A field of an MCAP record, as far as its size is concerned.
#[derive(Clone, Copy)]
enum Field {
    /// Fixed size in bytes.
    Fixed(usize),
    /// u32 length, then that many bytes (String, and Bytes with a u32 length).
    Len32,
    /// u64 length, then that many bytes.
    Len64,
    /// u32 byte length of a map of String to String.
    StrMap,
}

/// The fields of each record type with length prefixes (MCAP specification); records of fixed
/// size or with unprefixed trailing data have none to check.
fn prefixed_layout(opcode: u8) -> &'static [Field] {
    use Field::*;
    match opcode {
        op::HEADER => &[Len32, Len32],
        op::SCHEMA => &[Fixed(2), Len32, Len32, Len32],
        op::CHANNEL => &[Fixed(4), Len32, Len32, StrMap],
        op::CHUNK => &[Fixed(28), Len32, Len64],
        op::MESSAGE_INDEX => &[Fixed(2), Len32],
        op::CHUNK_INDEX => &[Fixed(32), Len32, Fixed(8), Len32, Fixed(16)],
        op::ATTACHMENT => &[Fixed(16), Len32, Len32, Len64, Fixed(4)],
        op::ATTACHMENT_INDEX => &[Fixed(40), Len32, Len32],
        op::STATISTICS => &[Fixed(42), Len32],
        op::METADATA => &[Len32, StrMap],
        op::METADATA_INDEX => &[Fixed(16), Len32],
        _ => &[],
    }
}

/// Checks every length prefix of a record against its body before the mcap crate parses it:
/// its parser reserves memory for a length before reading, so a damaged length made it reserve
/// 4 GiB for a 156-byte file (found by fuzzing).
pub(crate) fn check_lengths(opcode: u8, body: &[u8]) -> Result<(), String> {
    let bad = |what: &str, at: usize| {
        Err(format!(
            "record (opcode {opcode:#04x}): {what} at byte {at} runs past the record's {} bytes",
            body.len()
        ))
    };
    let len_at = |at: usize, width: usize| -> Option<u64> {
        let b = body.get(at..at + width)?;
        Some(if width == 4 {
            u32::from_le_bytes(b.try_into().ok()?) as u64
        } else {
            u64::from_le_bytes(b.try_into().ok()?)
        })
    };
    let mut pos = 0usize;
    for f in prefixed_layout(opcode) {
        let (width, is_map) = match *f {
            Field::Fixed(n) => {
                if pos + n > body.len() {
                    return bad("a fixed field", pos);
                }
                pos += n;
                continue;
            }
            Field::Len32 => (4, false),
            Field::Len64 => (8, false),
            Field::StrMap => (4, true),
        };
        let Some(len) = len_at(pos, width) else {
            return bad("a length", pos);
        };
        let start = pos + width;
        let Some(end) = usize::try_from(len)
            .ok()
            .and_then(|l| start.checked_add(l))
            .filter(|e| *e <= body.len())
        else {
            return bad("a length-prefixed field", pos);
        };
        if is_map {
            // entries: String key, String value, each with a u32 length
            let mut p = start;
            while p < end {
                let Some(l) = len_at(p, 4) else {
                    return bad("a map entry", p);
                };
                match usize::try_from(l)
                    .ok()
                    .and_then(|l| (p + 4).checked_add(l))
                    .filter(|e| *e <= end)
                {
                    Some(e) => p = e,
                    None => return bad("a map entry", p),
                }
            }
        }
        pos = end;
    }
    Ok(())
}

/// `mcap::parse_record` after [`check_lengths`].
fn parse_checked(opcode: u8, body: &[u8]) -> Result<Record<'_>, String> {
    check_lengths(opcode, body)?;
    mcap::parse_record(opcode, body).map_err(|e| e.to_string())
}

pub(crate) fn scan(bytes: &[u8]) -> Scan {
    let mut s = Scan::default();
    let mut pos = mcap::MAGIC.len();
    loop {
        if pos == bytes.len() {
            s.stop = Some(Stop {
                offset: pos as u64,
                reason: "the file ends without a footer".into(),
            });
            return s;
        }
        let (Some(&opcode), Some(len)) = (bytes.get(pos), u64_at(bytes, pos + 1)) else {
            s.stop = Some(Stop {
                offset: pos as u64,
                reason: "the file ends inside a record header".into(),
            });
            return s;
        };
        let body_start = pos + 9;
        let body_end = usize::try_from(len)
            .ok()
            .and_then(|l| body_start.checked_add(l))
            .filter(|&e| e <= bytes.len());
        let Some(body_end) = body_end else {
            if opcode == op::CHUNK {
                s.partial_chunk_messages = partial_chunk(&bytes[body_start..], &mut s);
                s.stop = Some(Stop {
                    offset: pos as u64,
                    reason: format!(
                        "the file ends inside a chunk ({} complete messages decoded from it)",
                        s.partial_chunk_messages
                    ),
                });
            } else {
                s.stop = Some(Stop {
                    offset: pos as u64,
                    reason: format!("the file ends inside a record (opcode {opcode:#04x})"),
                });
            }
            return s;
        };
        let body = &bytes[body_start..body_end];
        if opcode == op::FOOTER {
            return s;
        }
        if opcode == 0 {
            s.stop = Some(Stop {
                offset: pos as u64,
                reason: "invalid record opcode 0x00".into(),
            });
            return s;
        }
        let res = match parse_checked(opcode, body) {
            Ok(Record::Chunk { header, data }) => {
                match decompress(&header.compression, &data, Some(header.uncompressed_size)) {
                    Ok(records) => {
                        let before = s.messages.len();
                        match inner_records(&records, &mut s) {
                            None => {
                                s.complete_chunks += 1;
                                Ok(())
                            }
                            Some(e) => {
                                s.messages.truncate(before);
                                Err(format!("chunk content: {e}"))
                            }
                        }
                    }
                    Err(e) => Err(format!("chunk does not decompress: {e}")),
                }
            }
            Ok(r) => {
                take(r, &mut s);
                Ok(())
            }
            Err(e) => Err(format!("record (opcode {opcode:#04x}) does not parse: {e}")),
        };
        if let Err(reason) = res {
            s.stop = Some(Stop {
                offset: pos as u64,
                reason,
            });
            return s;
        }
        pos = body_end;
    }
}

/// Keeps schemas, channels and messages.
fn take(r: Record<'_>, s: &mut Scan) {
    match r {
        Record::Schema { header, data } => {
            s.schemas.insert(
                header.id,
                RawSchema {
                    name: header.name,
                    encoding: header.encoding,
                    data: data.into_owned(),
                },
            );
        }
        Record::Channel(c) => {
            s.channels.insert(
                c.id,
                RawChannel {
                    topic: c.topic,
                    schema_id: c.schema_id,
                    metadata: c.metadata,
                },
            );
        }
        Record::Message { header, data } => s.messages.push(RawMessage {
            channel_id: header.channel_id,
            sequence: header.sequence,
            log_time: header.log_time,
            publish_time: header.publish_time,
            data: data.into_owned(),
        }),
        _ => {}
    }
}

/// Parses the records of a chunk; stops at the first incomplete or broken one and returns why.
fn inner_records(b: &[u8], s: &mut Scan) -> Option<String> {
    let mut pos = 0usize;
    while pos < b.len() {
        let (Some(&opcode), Some(len)) = (b.get(pos), u64_at(b, pos + 1)) else {
            return Some("cut inside a record header".into());
        };
        let start = pos + 9;
        let end = usize::try_from(len)
            .ok()
            .and_then(|l| start.checked_add(l))
            .filter(|&e| e <= b.len());
        let Some(end) = end else {
            return Some("cut inside a record".into());
        };
        match parse_checked(opcode, &b[start..end]) {
            Ok(r) => take(r, s),
            Err(e) => return Some(format!("record does not parse: {e}")),
        }
        pos = end;
    }
    None
}

/// Most bytes a chunk may decompress to (the reader's record limit).
const DECOMPRESSED_LIMIT: u64 = 1 << 30;

/// Decompresses a chunk's records. With `expected` the whole output must come out; without, as
/// much as the (cut-off) input yields is returned. Memory grows with what the decompressor
/// produces, never with a declared size, and stops one byte past `expected` (or past
/// [`DECOMPRESSED_LIMIT`]), so neither a false size nor a decompression bomb can make it grow
/// further.
fn decompress(compression: &str, data: &[u8], expected: Option<u64>) -> Result<Vec<u8>, String> {
    if let Some(n) = expected
        && n > DECOMPRESSED_LIMIT
    {
        return Err(format!(
            "the chunk declares {n} bytes uncompressed, more than the {DECOMPRESSED_LIMIT} accepted"
        ));
    }
    let cap = expected.unwrap_or(DECOMPRESSED_LIMIT);
    let mut out = Vec::new();
    let res = match compression {
        "" => {
            out.extend_from_slice(data);
            Ok(())
        }
        "zstd" => match zstd::stream::read::Decoder::new(data) {
            Ok(d) => read_all(d.take(cap + 1), &mut out),
            Err(e) => Err(e.to_string()),
        },
        "lz4" => match lz4::Decoder::new(data) {
            Ok(d) => read_all(d.take(cap + 1), &mut out),
            Err(e) => Err(e.to_string()),
        },
        other => return Err(format!("unsupported compression '{other}'")),
    };
    if expected.is_none() && out.len() as u64 > cap {
        return Err(format!("decompresses to more than {cap} bytes"));
    }
    match expected {
        Some(n) => {
            res?;
            if out.len() as u64 != n {
                return Err(format!(
                    "decompressed to {} bytes, the header says {n}",
                    out.len()
                ));
            }
            Ok(out)
        }
        None => Ok(out),
    }
}

/// Reads until the end or the first error, keeping what came out before it.
fn read_all(mut r: impl Read, out: &mut Vec<u8>) -> Result<(), String> {
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        match r.read(&mut buf) {
            Ok(0) => return Ok(()),
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e.to_string()),
        }
    }
}

/// Takes the complete records out of a chunk the file ends inside. The chunk header may still be
/// the writer's placeholder (all lengths 0xff..ff). Returns the number of messages taken.
fn partial_chunk(body: &[u8], s: &mut Scan) -> usize {
    // message_start_time, message_end_time, uncompressed_size: u64; uncompressed_crc: u32;
    // compression: u32 length + bytes; records: u64 length + bytes.
    let Some(name_len) = u32_at(body, 28) else {
        return 0;
    };
    let name_start = 32usize;
    let Some(name_end) = name_start.checked_add(name_len as usize) else {
        return 0;
    };
    let Some(name) = body
        .get(name_start..name_end)
        .and_then(|n| std::str::from_utf8(n).ok())
    else {
        return 0;
    };
    let Some(records_len) = u64_at(body, name_end) else {
        return 0;
    };
    let data_start = name_end + 8;
    let avail = body.len().saturating_sub(data_start);
    let take_len = usize::try_from(records_len).map_or(avail, |l| l.min(avail));
    let data = &body[data_start..data_start + take_len];
    let Ok(records) = decompress(name, data, None) else {
        return 0;
    };
    let before = s.messages.len();
    let _ = inner_records(&records, s);
    s.messages.len() - before
}

#[cfg(test)]
mod length_tests {
    use super::*;

    fn string(s: &str) -> Vec<u8> {
        let mut b = (s.len() as u32).to_le_bytes().to_vec();
        b.extend_from_slice(s.as_bytes());
        b
    }

    #[test]
    fn lengths_inside_the_record_pass_and_a_huge_one_is_refused_before_parsing() {
        let header = [string("ros2"), string("forcemap")].concat();
        assert!(check_lengths(op::HEADER, &header).is_ok());
        assert!(parse_checked(op::HEADER, &header).is_ok());
        let mut huge = header.clone();
        huge[..4].copy_from_slice(&0xFFFF_0000u32.to_le_bytes());
        let e = parse_checked(op::HEADER, &huge).expect_err("refused");
        assert!(e.contains("runs past"), "{e}");
        // a channel whose metadata map holds a string longer than the map
        let mut channel = vec![1, 0, 1, 0];
        channel.extend(string("/rig/samples"));
        channel.extend(string("cdr"));
        let entry = [string("k"), 0xFFFF_FFF0u32.to_le_bytes().to_vec()].concat();
        channel.extend((entry.len() as u32).to_le_bytes());
        channel.extend(entry);
        assert!(check_lengths(op::CHANNEL, &channel).is_err());
    }
}
