//! Reading a bag directory or a bare MCAP file.
use std::collections::{BTreeSet, HashMap};
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use mcap::sans_io::{
    IndexedReadEvent, IndexedReader, IndexedReaderOptions, SummaryReadEvent, SummaryReader,
    SummaryReaderOptions,
};

use super::guard::{self, SummaryCheck};
use super::metadata::BagMetadata;
use super::scan::{self, Scan};
use super::{BagError, QOS_METADATA_KEY, SCHEMA_ENCODING};

/// A topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    pub name: String,
    /// `pkg/msg/Type`.
    pub type_name: String,
    /// The ros2msg schema text.
    pub schema_text: String,
    /// The offered QoS profiles YAML string (empty if the file has none).
    pub offered_qos_profiles: String,
    pub message_count: u64,
}

/// One message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagMessage {
    pub topic: Arc<TopicInfo>,
    /// Receive time, ns since the epoch.
    pub log_time: u64,
    /// Send time, ns since the epoch.
    pub publish_time: u64,
    pub sequence: u32,
    /// CDR bytes with the encapsulation header.
    pub data: Vec<u8>,
}

/// Topics, counts and times of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BagSummary {
    pub topics: Vec<TopicInfo>,
    pub message_count: u64,
    /// First and last log time (ns since the epoch); 0 when there are no messages.
    pub start_ns: u64,
    pub end_ns: u64,
    pub duration_ns: u64,
    /// From metadata.yaml (None for a bare MCAP file).
    pub ros_distro: Option<String>,
}

/// Largest record (and decompressed chunk) accepted, so that a damaged length cannot make the
/// reader allocate without bound. The writer's chunks are far smaller.
const RECORD_LIMIT: usize = 1 << 30;

enum Source {
    /// Summary with chunk indexes: streamed from the file in log-time order.
    Indexed { summary: Box<mcap::Summary> },
    /// No usable index: the whole file was scanned into memory.
    Scanned { scan: Box<Scan> },
}

/// An open bag.
pub struct BagReader {
    mcap_path: PathBuf,
    metadata: Option<BagMetadata>,
    topics: Vec<Arc<TopicInfo>>,
    by_channel: HashMap<u16, Arc<TopicInfo>>,
    source: Source,
    start: u64,
    end: u64,
    count: u64,
}

impl std::fmt::Debug for BagReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagReader")
            .field("mcap_path", &self.mcap_path)
            .field("topics", &self.topics)
            .finish_non_exhaustive()
    }
}

/// Checks the magic of a file; returns the open file.
pub(crate) fn open_mcap(path: &Path) -> Result<File, BagError> {
    let mut f = match File::open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(BagError::NotFound {
                path: path.to_path_buf(),
            });
        }
        Err(e) => return Err(BagError::io(path, e)),
    };
    let mut magic = Vec::with_capacity(8);
    (&mut f)
        .take(8)
        .read_to_end(&mut magic)
        .map_err(|e| BagError::io(path, e))?;
    if !scan::has_magic(&magic) {
        return Err(BagError::NotMcap {
            path: path.to_path_buf(),
            found: magic,
        });
    }
    f.seek(SeekFrom::Start(0))
        .map_err(|e| BagError::io(path, e))?;
    Ok(f)
}

/// The MCAP file of a bag directory (from metadata.yaml) or the file itself.
fn locate(path: &Path) -> Result<(PathBuf, Option<BagMetadata>), BagError> {
    if !path.exists() {
        return Err(BagError::NotFound {
            path: path.to_path_buf(),
        });
    }
    if !path.is_dir() {
        return Ok((path.to_path_buf(), None));
    }
    let meta = BagMetadata::read(path)?;
    match meta.relative_file_paths.as_slice() {
        [one] => Ok((path.join(one), Some(meta))),
        other => Err(BagError::Metadata {
            path: path.join("metadata.yaml"),
            reason: format!(
                "{} storage files listed; only single-file bags are supported",
                other.len()
            ),
        }),
    }
}

fn corrupt(path: &Path, stop: &scan::Stop) -> BagError {
    BagError::Corrupt {
        path: path.to_path_buf(),
        offset: Some(stop.offset),
        detail: stop.reason.clone(),
    }
}

/// Finds where a file breaks, for an error message.
fn diagnose(path: &Path, fallback: String) -> BagError {
    match std::fs::read(path) {
        Ok(bytes) => match scan::scan(&bytes).stop {
            Some(stop) => corrupt(path, &stop),
            None => BagError::Corrupt {
                path: path.to_path_buf(),
                offset: None,
                detail: fallback,
            },
        },
        Err(e) => BagError::io(path, e),
    }
}

fn read_summary(path: &Path, file: &mut File) -> Result<Option<mcap::Summary>, BagError> {
    let size = file.metadata().map_err(|e| BagError::io(path, e))?.len();
    let mut reader = SummaryReader::new_with_options(
        SummaryReaderOptions::default()
            .with_file_size(size)
            .with_record_length_limit(RECORD_LIMIT),
    );
    while let Some(event) = reader.next_event() {
        let event = event.map_err(|e| diagnose(path, e.to_string()))?;
        match event {
            SummaryReadEvent::ReadRequest(n) => {
                let got = file
                    .read(reader.insert(n))
                    .map_err(|e| BagError::io(path, e))?;
                reader.notify_read(got);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let at = file.seek(to).map_err(|e| BagError::io(path, e))?;
                reader.notify_seeked(at);
            }
        }
    }
    Ok(reader.finish())
}

impl BagReader {
    /// Opens a bag directory (metadata.yaml + MCAP) or a bare .mcap file.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, BagError> {
        let (mcap_path, metadata) = locate(path.as_ref())?;
        let mut file = open_mcap(&mcap_path)?;
        let size = file
            .metadata()
            .map_err(|e| BagError::io(&mcap_path, e))?
            .len();
        // The summary is used only when it holds up against the file (guard.rs); otherwise the
        // file is scanned as if it had none.
        let summary = match guard::check_summary(&mut file, size, RECORD_LIMIT as u64) {
            SummaryCheck::Untrusted(_) => None,
            SummaryCheck::NoSummary => read_summary(&mcap_path, &mut file)?,
            SummaryCheck::Summary { summary_start } => {
                read_summary(&mcap_path, &mut file)?.filter(|s| {
                    guard::check_chunk_indexes(s, summary_start, RECORD_LIMIT as u64).is_ok()
                })
            }
        };
        match summary {
            Some(s)
                if !s.chunk_indexes.is_empty()
                    || s.stats.as_ref().is_some_and(|st| st.message_count == 0) =>
            {
                Self::from_summary(mcap_path, metadata, s)
            }
            _ => {
                let bytes = std::fs::read(&mcap_path).map_err(|e| BagError::io(&mcap_path, e))?;
                let scan = scan::scan(&bytes);
                if let Some(stop) = &scan.stop {
                    return Err(corrupt(&mcap_path, stop));
                }
                Self::from_scan(mcap_path, metadata, scan)
            }
        }
    }

    fn check_schema(path: &Path, topic: &str, encoding: &str) -> Result<(), BagError> {
        if encoding == SCHEMA_ENCODING {
            Ok(())
        } else {
            Err(BagError::SchemaEncoding {
                path: path.to_path_buf(),
                topic: topic.to_string(),
                encoding: encoding.to_string(),
            })
        }
    }

    fn from_summary(
        mcap_path: PathBuf,
        metadata: Option<BagMetadata>,
        summary: mcap::Summary,
    ) -> Result<Self, BagError> {
        let counts = summary
            .stats
            .as_ref()
            .map(|s| s.channel_message_counts.clone())
            .unwrap_or_default();
        let mut ids: Vec<u16> = summary.channels.keys().copied().collect();
        ids.sort_unstable();
        let mut by_channel = HashMap::new();
        let mut topics = Vec::new();
        for id in ids {
            let c = &summary.channels[&id];
            let (type_name, schema_text, encoding) = match &c.schema {
                Some(s) => (
                    s.name.clone(),
                    String::from_utf8_lossy(&s.data).into_owned(),
                    s.encoding.clone(),
                ),
                None => (String::new(), String::new(), String::new()),
            };
            Self::check_schema(&mcap_path, &c.topic, &encoding)?;
            let info = Arc::new(TopicInfo {
                name: c.topic.clone(),
                type_name,
                schema_text,
                offered_qos_profiles: c
                    .metadata
                    .get(QOS_METADATA_KEY)
                    .cloned()
                    .unwrap_or_default(),
                message_count: counts.get(&id).copied().unwrap_or(0),
            });
            by_channel.insert(id, info.clone());
            topics.push(info);
        }
        let (start, end, count) = match &summary.stats {
            Some(s) if s.message_count > 0 => {
                (s.message_start_time, s.message_end_time, s.message_count)
            }
            _ => (0, 0, 0),
        };
        Ok(BagReader {
            mcap_path,
            metadata,
            topics,
            by_channel,
            source: Source::Indexed {
                summary: Box::new(summary),
            },
            start,
            end,
            count,
        })
    }

    fn from_scan(
        mcap_path: PathBuf,
        metadata: Option<BagMetadata>,
        mut scan: Scan,
    ) -> Result<Self, BagError> {
        let mut counts: HashMap<u16, u64> = HashMap::new();
        for m in &scan.messages {
            *counts.entry(m.channel_id).or_default() += 1;
        }
        let mut ids: Vec<u16> = scan.channels.keys().copied().collect();
        ids.sort_unstable();
        let mut by_channel = HashMap::new();
        let mut topics = Vec::new();
        for id in ids {
            let c = &scan.channels[&id];
            let schema = scan.schemas.get(&c.schema_id);
            let encoding = schema.map(|s| s.encoding.clone()).unwrap_or_default();
            Self::check_schema(&mcap_path, &c.topic, &encoding)?;
            let info = Arc::new(TopicInfo {
                name: c.topic.clone(),
                type_name: schema.map(|s| s.name.clone()).unwrap_or_default(),
                schema_text: schema
                    .map(|s| String::from_utf8_lossy(&s.data).into_owned())
                    .unwrap_or_default(),
                offered_qos_profiles: c
                    .metadata
                    .get(QOS_METADATA_KEY)
                    .cloned()
                    .unwrap_or_default(),
                message_count: counts.get(&id).copied().unwrap_or(0),
            });
            by_channel.insert(id, info.clone());
            topics.push(info);
        }
        scan.messages.sort_by_key(|m| m.log_time);
        let start = scan.messages.first().map_or(0, |m| m.log_time);
        let end = scan.messages.last().map_or(0, |m| m.log_time);
        let count = scan.messages.len() as u64;
        Ok(BagReader {
            mcap_path,
            metadata,
            topics,
            by_channel,
            source: Source::Scanned {
                scan: Box::new(scan),
            },
            start,
            end,
            count,
        })
    }

    /// The MCAP file read.
    pub fn mcap_path(&self) -> &Path {
        &self.mcap_path
    }

    /// metadata.yaml, when a bag directory was opened.
    pub fn metadata(&self) -> Option<&BagMetadata> {
        self.metadata.as_ref()
    }

    /// The topics, in channel order.
    pub fn topics(&self) -> impl Iterator<Item = &TopicInfo> {
        self.topics.iter().map(AsRef::as_ref)
    }

    /// One topic by name.
    pub fn topic(&self, name: &str) -> Result<&TopicInfo, BagError> {
        self.topics
            .iter()
            .find(|t| t.name == name)
            .map(AsRef::as_ref)
            .ok_or_else(|| self.not_found(name))
    }

    fn not_found(&self, name: &str) -> BagError {
        BagError::TopicNotFound {
            topic: name.to_string(),
            available: self.topics.iter().map(|t| t.name.clone()).collect(),
        }
    }

    /// Topics, types, counts, start, end and duration.
    pub fn summary(&self) -> BagSummary {
        BagSummary {
            topics: self.topics.iter().map(|t| (**t).clone()).collect(),
            message_count: self.count,
            start_ns: self.start,
            end_ns: self.end,
            duration_ns: self.end.saturating_sub(self.start),
            ros_distro: self.metadata.as_ref().map(|m| m.ros_distro.clone()),
        }
    }

    /// All messages in log-time order (equal times in file order).
    pub fn messages(&self) -> Result<Messages<'_>, BagError> {
        self.make_messages(None)
    }

    /// The messages of some topics in log-time order; an unknown topic is an error. No topics
    /// give no messages.
    pub fn messages_on(&self, topics: &[&str]) -> Result<Messages<'_>, BagError> {
        for t in topics {
            self.topic(t)?;
        }
        self.make_messages(Some(topics.iter().map(ToString::to_string).collect()))
    }

    fn make_messages(&self, only: Option<BTreeSet<String>>) -> Result<Messages<'_>, BagError> {
        let inner = match &self.source {
            Source::Indexed { summary } => {
                let mut opts = IndexedReaderOptions::new().with_record_length_limit(RECORD_LIMIT);
                if let Some(only) = &only {
                    opts = opts.include_topics(only.iter().cloned());
                }
                let reader = IndexedReader::new_with_options(summary, opts)
                    .map_err(|e| BagError::mcap(&self.mcap_path, e))?;
                let file =
                    File::open(&self.mcap_path).map_err(|e| BagError::io(&self.mcap_path, e))?;
                Inner::Indexed {
                    reader: Box::new(reader),
                    file,
                    buffer: Vec::new(),
                }
            }
            Source::Scanned { .. } => Inner::Scanned { next: 0 },
        };
        Ok(Messages {
            bag: self,
            // The mcap reader would take an empty topic list as "every topic".
            done: only.as_ref().is_some_and(BTreeSet::is_empty),
            only,
            inner,
        })
    }
}

enum Inner {
    Indexed {
        reader: Box<IndexedReader>,
        file: File,
        buffer: Vec<u8>,
    },
    Scanned {
        next: usize,
    },
}

/// Iterator over messages in log-time order.
pub struct Messages<'a> {
    bag: &'a BagReader,
    only: Option<BTreeSet<String>>,
    inner: Inner,
    done: bool,
}

fn topic_of(bag: &BagReader, channel_id: u16) -> Result<Arc<TopicInfo>, BagError> {
    bag.by_channel
        .get(&channel_id)
        .cloned()
        .ok_or_else(|| BagError::Corrupt {
            path: bag.mcap_path.clone(),
            offset: None,
            detail: format!("a message refers to unknown channel {channel_id}"),
        })
}

impl Messages<'_> {
    fn next_inner(&mut self) -> Option<Result<BagMessage, BagError>> {
        let path = self.bag.mcap_path.clone();
        match &mut self.inner {
            Inner::Scanned { next } => {
                let Source::Scanned { scan } = &self.bag.source else {
                    return None;
                };
                while let Some(m) = scan.messages.get(*next) {
                    *next += 1;
                    let topic = match topic_of(self.bag, m.channel_id) {
                        Ok(t) => t,
                        Err(e) => return Some(Err(e)),
                    };
                    if self.only.as_ref().is_some_and(|o| !o.contains(&topic.name)) {
                        continue;
                    }
                    return Some(Ok(BagMessage {
                        topic,
                        log_time: m.log_time,
                        publish_time: m.publish_time,
                        sequence: m.sequence,
                        data: m.data.clone(),
                    }));
                }
                None
            }
            Inner::Indexed {
                reader,
                file,
                buffer,
            } => loop {
                let event = reader.next_event()?;
                let event = match event {
                    Ok(e) => e,
                    Err(e) => return Some(Err(diagnose(&path, e.to_string()))),
                };
                match event {
                    IndexedReadEvent::ReadChunkRequest { offset, length } => {
                        let size = file.metadata().map(|m| m.len()).unwrap_or(0);
                        if offset.saturating_add(length as u64) > size {
                            return Some(Err(BagError::Corrupt {
                                path,
                                offset: Some(offset),
                                detail: format!(
                                    "the chunk index points past the end of the file ({size} bytes)"
                                ),
                            }));
                        }
                        buffer.resize(length, 0);
                        let r = file
                            .seek(SeekFrom::Start(offset))
                            .and_then(|_| file.read_exact(buffer));
                        if let Err(e) = r {
                            return Some(Err(if e.kind() == std::io::ErrorKind::UnexpectedEof {
                                diagnose(&path, e.to_string())
                            } else {
                                BagError::io(&path, e)
                            }));
                        }
                        if let Err(e) = reader.insert_chunk_record_data(offset, buffer) {
                            return Some(Err(diagnose(&path, e.to_string())));
                        }
                    }
                    IndexedReadEvent::Message { header, data } => {
                        let data = data.to_vec();
                        let topic = match topic_of(self.bag, header.channel_id) {
                            Ok(t) => t,
                            Err(e) => return Some(Err(e)),
                        };
                        return Some(Ok(BagMessage {
                            topic,
                            log_time: header.log_time,
                            publish_time: header.publish_time,
                            sequence: header.sequence,
                            data,
                        }));
                    }
                }
            },
        }
    }
}

impl Iterator for Messages<'_> {
    type Item = Result<BagMessage, BagError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = self.next_inner();
        if !matches!(item, Some(Ok(_))) {
            self.done = true;
        }
        item
    }
}
