//! Rebuilding a bag whose writer died before the footer and summary.
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::reader::open_mcap;
use super::scan;
use super::writer::{BagWriter, BagWriterOptions, TopicId, TopicSpec};
use super::{BagError, QOS_METADATA_KEY, SCHEMA_ENCODING};

/// What [`recover`] kept and lost.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecoveryReport {
    /// The damaged MCAP file read.
    pub input: PathBuf,
    /// The new bag directory.
    pub output: PathBuf,
    /// Input file size in bytes.
    pub input_bytes: u64,
    /// Byte offset of the first record that was cut off or broken (None: the input was whole).
    pub cut_offset: Option<u64>,
    /// Why reading stopped there.
    pub cut_reason: Option<String>,
    /// Chunks read whole.
    pub complete_chunks: usize,
    /// Messages taken from the readable prefix of the chunk the file ends inside.
    pub partial_chunk_messages: usize,
    /// Messages written to the new bag.
    pub messages: u64,
    /// Messages left out because their channel or schema record was lost or not ros2msg.
    pub skipped_messages: u64,
}

/// The MCAP file to recover: the file itself, or the single .mcap in a directory (for example
/// the `.NAME.partial` directory a killed recorder leaves).
fn input_file(input: &Path) -> Result<PathBuf, BagError> {
    if !input.exists() {
        return Err(BagError::NotFound {
            path: input.to_path_buf(),
        });
    }
    if !input.is_dir() {
        return Ok(input.to_path_buf());
    }
    let entries = std::fs::read_dir(input).map_err(|e| BagError::io(input, e))?;
    let mut found: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    found.sort();
    match found.len() {
        1 => Ok(found.remove(0)),
        n => Err(BagError::NothingToRecover {
            path: input.to_path_buf(),
            reason: format!("{n} .mcap files in the directory, expected one"),
        }),
    }
}

/// Reads every complete message of a (possibly truncated) MCAP file or bag directory `input`
/// and writes them, with their topics, schemas, QoS and times, to a new bag at `output`
/// (atomically; `output` must not exist).
///
/// Granularity: every message of every chunk that is whole in the file is kept. Of the chunk the
/// file ends inside, the messages that decompress completely from the part present are kept too
/// (uncompressed chunks: every complete message; zstd or lz4 chunks: the messages in the
/// compressed blocks that were flushed to the file before the cut, often none, since the
/// compressor writes a chunk's data when the chunk closes).
pub fn recover(
    input: impl AsRef<Path>,
    output: impl AsRef<Path>,
) -> Result<RecoveryReport, BagError> {
    let file = input_file(input.as_ref())?;
    let output = output.as_ref().to_path_buf();
    if output.exists() {
        return Err(BagError::OutputExists { path: output });
    }
    drop(open_mcap(&file)?);
    let bytes = std::fs::read(&file).map_err(|e| BagError::io(&file, e))?;
    let scan = scan::scan(&bytes);

    let mut writer = BagWriter::create_with(
        &output,
        BagWriterOptions {
            max_chunk_age: None,
            ..BagWriterOptions::default()
        },
    )?;
    let mut ids: HashMap<u16, Option<TopicId>> = HashMap::new();
    let mut skipped = 0u64;
    for m in &scan.messages {
        let id = match ids.get(&m.channel_id) {
            Some(id) => *id,
            None => {
                let id = match scan.channels.get(&m.channel_id) {
                    Some(c) => match scan.schemas.get(&c.schema_id) {
                        Some(s) if s.encoding == SCHEMA_ENCODING => {
                            let mut spec = TopicSpec::new(
                                &c.topic,
                                &s.name,
                                &String::from_utf8_lossy(&s.data),
                            );
                            if let Some(q) = c.metadata.get(QOS_METADATA_KEY) {
                                spec.offered_qos_profiles = q.clone();
                            }
                            if let Some(h) = c.metadata.get("topic_type_hash") {
                                spec.type_description_hash = h.clone();
                            }
                            Some(writer.add_topic(&spec)?)
                        }
                        _ => None,
                    },
                    None => None,
                };
                ids.insert(m.channel_id, id);
                id
            }
        };
        match id {
            Some(id) => writer.write(id, m.log_time, m.publish_time, &m.data)?,
            None => skipped += 1,
        }
    }
    let messages = writer.message_count();
    let output = writer.finish()?;
    Ok(RecoveryReport {
        input: file,
        output,
        input_bytes: bytes.len() as u64,
        cut_offset: scan.stop.as_ref().map(|s| s.offset),
        cut_reason: scan.stop.as_ref().map(|s| s.reason.clone()),
        complete_chunks: scan.complete_chunks,
        partial_chunk_messages: scan.partial_chunk_messages,
        messages,
        skipped_messages: skipped,
    })
}
