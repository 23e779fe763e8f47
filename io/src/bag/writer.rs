//! Writing a rosbag2 bag (directory with metadata.yaml and one MCAP file).
use std::collections::{BTreeMap, HashMap};
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mcap::records::MessageHeader;

use super::metadata::{BagMetadata, METADATA_VERSION, TopicEntry};
use super::{BagError, QOS_METADATA_KEY, SCHEMA_ENCODING};

/// Where a recorder writes: a bag being written ([`BagWriter`]), or anything else that takes
/// topics and CDR messages in log-time order (a test's memory, another storage).
pub trait BagSink {
    /// Declares a topic; messages are written against the id it returns.
    fn add_topic(&mut self, spec: &TopicSpec) -> Result<TopicId, BagError>;
    /// Writes one CDR message of `topic`.
    fn write(
        &mut self,
        topic: TopicId,
        log_time: u64,
        publish_time: u64,
        cdr: &[u8],
    ) -> Result<(), BagError>;
    /// Makes what was written so far durable (a bag closes its chunk).
    fn flush_chunk(&mut self) -> Result<(), BagError>;
    /// Completes the recording and says where it is.
    fn finish(self: Box<Self>) -> Result<PathBuf, BagError>;
}

impl BagSink for BagWriter {
    fn add_topic(&mut self, spec: &TopicSpec) -> Result<TopicId, BagError> {
        BagWriter::add_topic(self, spec)
    }

    fn write(
        &mut self,
        topic: TopicId,
        log_time: u64,
        publish_time: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        BagWriter::write(self, topic, log_time, publish_time, cdr)
    }

    fn flush_chunk(&mut self) -> Result<(), BagError> {
        BagWriter::flush_chunk(self)
    }

    fn finish(self: Box<Self>) -> Result<PathBuf, BagError> {
        BagWriter::finish(*self)
    }
}

/// A topic to record: name, ROS type, its .msg definition and QoS.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicSpec {
    /// Topic name, starting with '/'.
    pub name: String,
    /// ROS type name `pkg/msg/Type`.
    pub type_name: String,
    /// The ros2msg schema: the type's .msg text followed by its dependencies, each after a line
    /// of 80 '=' and `MSG: pkg/msg/Dep`, as rosbag2 and Foxglove expect.
    pub schema_text: String,
    /// The offered QoS profiles as a YAML string (see [`super::QosProfile::to_yaml_string`]).
    pub offered_qos_profiles: String,
    /// RIHS01 type hash, or empty.
    pub type_description_hash: String,
}

impl TopicSpec {
    /// A topic with rclcpp's default QoS and no type hash.
    pub fn new(name: &str, type_name: &str, schema_text: &str) -> Self {
        TopicSpec {
            name: name.to_string(),
            type_name: type_name.to_string(),
            schema_text: schema_text.to_string(),
            offered_qos_profiles: super::QosProfile::default().to_yaml_string(),
            type_description_hash: String::new(),
        }
    }

    fn check(&self) -> Result<(), BagError> {
        let bad = |reason: &str| {
            Err(BagError::InvalidTopic {
                topic: self.name.clone(),
                reason: reason.to_string(),
            })
        };
        if !self.name.starts_with('/') || self.name.len() < 2 {
            return bad("a topic name starts with '/'");
        }
        let parts: Vec<&str> = self.type_name.split('/').collect();
        if parts.len() != 3 || parts.iter().any(|p| p.is_empty()) {
            return bad(&format!(
                "type name '{}' is not of the form pkg/msg/Type",
                self.type_name
            ));
        }
        Ok(())
    }
}

/// Handle of a topic added to a [`BagSink`] (for a [`BagWriter`], the MCAP channel id).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TopicId(pub u16);

/// Writer options.
#[derive(Debug, Clone)]
pub struct BagWriterOptions {
    /// A chunk is closed when its uncompressed size reaches this many bytes.
    pub chunk_size: u64,
    /// A chunk is also closed before a message written this long (wall clock) after the chunk's
    /// first message; `None` closes chunks only on size and [`BagWriter::flush_chunk`].
    pub max_chunk_age: Option<Duration>,
    /// Compress chunks with zstd (true) or store them uncompressed.
    pub zstd: bool,
    /// `ros_distro` written to metadata.yaml.
    pub ros_distro: String,
}

impl Default for BagWriterOptions {
    fn default() -> Self {
        BagWriterOptions {
            chunk_size: 512 * 1024,
            max_chunk_age: Some(Duration::from_secs(1)),
            zstd: true,
            // The sourced ROS 2 environment if any, else the distribution forcemap was built for.
            ros_distro: std::env::var("ROS_DISTRO")
                .ok()
                .filter(|d| !d.is_empty())
                .unwrap_or_else(|| crate::distro::BUILT_FOR_DISTRO.to_string()),
        }
    }
}

struct TopicState {
    spec: TopicSpec,
    channel_id: u16,
    count: u64,
    sequence: u32,
}

/// Writes a bag. The bag is built in a hidden directory `.NAME.partial` next to the final one
/// and renamed to NAME by [`BagWriter::finish`]; on an error, [`BagWriter::abort`] or a drop
/// without finish, the partial directory is removed. If the process is killed, the partial
/// directory stays: `recover` rebuilds a bag from it.
pub struct BagWriter {
    final_dir: PathBuf,
    tmp_dir: PathBuf,
    file_name: String,
    mcap_path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    options: BagWriterOptions,
    topics: Vec<TopicState>,
    by_name: HashMap<String, usize>,
    schemas: HashMap<(String, String), u16>,
    start: Option<u64>,
    end: u64,
    count: u64,
    chunk_opened: Option<Instant>,
}

impl std::fmt::Debug for BagWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BagWriter")
            .field("final_dir", &self.final_dir)
            .field("tmp_dir", &self.tmp_dir)
            .field("count", &self.count)
            .finish_non_exhaustive()
    }
}

/// The `.NAME.partial` directory a bag at `dir` is written in.
pub fn partial_dir(dir: &Path) -> PathBuf {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bag".to_string());
    parent_of(dir).join(format!(".{name}.partial"))
}

fn parent_of(dir: &Path) -> PathBuf {
    match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

impl BagWriter {
    /// Starts a bag at directory `dir` (which must not exist) with default options.
    pub fn create(dir: impl AsRef<Path>) -> Result<Self, BagError> {
        Self::create_with(dir, BagWriterOptions::default())
    }

    /// Starts a bag at directory `dir` (which must not exist).
    pub fn create_with(dir: impl AsRef<Path>, options: BagWriterOptions) -> Result<Self, BagError> {
        let final_dir = dir.as_ref().to_path_buf();
        if final_dir.exists() {
            return Err(BagError::OutputExists { path: final_dir });
        }
        let name = final_dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .filter(|n| !n.is_empty() && n != "." && n != "..")
            .ok_or_else(|| BagError::InvalidTopic {
                topic: String::new(),
                reason: format!("{}: not a usable bag directory name", final_dir.display()),
            })?;
        let parent = parent_of(&final_dir);
        if !parent.is_dir() {
            return Err(BagError::NotFound { path: parent });
        }
        let tmp_dir = partial_dir(&final_dir);
        if tmp_dir.exists() {
            return Err(BagError::OutputExists { path: tmp_dir });
        }
        fs::create_dir(&tmp_dir).map_err(|e| BagError::io(&tmp_dir, e))?;
        let file_name = format!("{name}_0.mcap");
        let mcap_path = tmp_dir.join(&file_name);
        let opened = File::create_new(&mcap_path)
            .map_err(|e| BagError::io(&mcap_path, e))
            .and_then(|f| {
                let opts = mcap::WriteOptions::new()
                    .profile("ros2")
                    .library(format!(
                        "forcemap {} (mcap-rust {})",
                        env!("CARGO_PKG_VERSION"),
                        mcap::VERSION
                    ))
                    .chunk_size(Some(options.chunk_size.max(1)))
                    .compression(if options.zstd {
                        Some(mcap::Compression::Zstd)
                    } else {
                        None
                    })
                    .compression_threads(0);
                opts.create(BufWriter::new(f))
                    .map_err(|e| BagError::mcap(&mcap_path, e))
            });
        let writer = match opened {
            Ok(w) => w,
            Err(e) => {
                let _ = fs::remove_dir_all(&tmp_dir);
                return Err(e);
            }
        };
        Ok(BagWriter {
            final_dir,
            tmp_dir,
            file_name,
            mcap_path,
            writer: Some(writer),
            options,
            topics: Vec::new(),
            by_name: HashMap::new(),
            schemas: HashMap::new(),
            start: None,
            end: 0,
            count: 0,
            chunk_opened: None,
        })
    }

    /// The directory the finished bag will have.
    pub fn path(&self) -> &Path {
        &self.final_dir
    }

    /// The hidden directory the bag is written in until [`Self::finish`].
    pub fn partial_path(&self) -> &Path {
        &self.tmp_dir
    }

    /// Messages written so far.
    pub fn message_count(&self) -> u64 {
        self.count
    }

    fn fail(&mut self, e: BagError) -> BagError {
        self.discard();
        e
    }

    fn discard(&mut self) {
        if let Some(w) = self.writer.take() {
            // The mcap writer finishes the file on drop; it is deleted right after.
            drop(w);
            let _ = fs::remove_dir_all(&self.tmp_dir);
        }
    }

    fn writer(&mut self) -> Result<&mut mcap::Writer<BufWriter<File>>, BagError> {
        let path = self.mcap_path.clone();
        self.writer.as_mut().ok_or_else(|| BagError::Io {
            path,
            source: std::io::Error::other("the bag writer failed earlier and was discarded"),
        })
    }

    /// Adds a topic (again adding the same topic returns the same id; the same name with another
    /// type is an error).
    pub fn add_topic(&mut self, spec: &TopicSpec) -> Result<TopicId, BagError> {
        spec.check()?;
        if let Some(&i) = self.by_name.get(&spec.name) {
            let t = &self.topics[i];
            if t.spec.type_name != spec.type_name || t.spec.schema_text != spec.schema_text {
                return Err(BagError::InvalidTopic {
                    topic: spec.name.clone(),
                    reason: format!(
                        "already added with type {} (and its schema); a topic has one type",
                        t.spec.type_name
                    ),
                });
            }
            return Ok(TopicId(t.channel_id));
        }
        let path = self.mcap_path.clone();
        let key = (spec.type_name.clone(), spec.schema_text.clone());
        let schema_id = match self.schemas.get(&key) {
            Some(&id) => id,
            None => {
                let r = self.writer()?.add_schema(
                    &spec.type_name,
                    SCHEMA_ENCODING,
                    spec.schema_text.as_bytes(),
                );
                let id = r.map_err(|e| BagError::mcap(&path, e));
                let id = id.map_err(|e| self.fail(e))?;
                self.schemas.insert(key, id);
                id
            }
        };
        let mut meta = BTreeMap::new();
        meta.insert(
            QOS_METADATA_KEY.to_string(),
            spec.offered_qos_profiles.clone(),
        );
        if !spec.type_description_hash.is_empty() {
            meta.insert(
                "topic_type_hash".to_string(),
                spec.type_description_hash.clone(),
            );
        }
        let r = self
            .writer()?
            .add_channel(schema_id, &spec.name, "cdr", &meta);
        let channel_id = r
            .map_err(|e| BagError::mcap(&path, e))
            .map_err(|e| self.fail(e))?;
        self.by_name.insert(spec.name.clone(), self.topics.len());
        self.topics.push(TopicState {
            spec: spec.clone(),
            channel_id,
            count: 0,
            sequence: 0,
        });
        Ok(TopicId(channel_id))
    }

    /// Writes one message: `log_time` is the receive time and `publish_time` the send time, in
    /// nanoseconds since the epoch; `cdr` the serialized message with its 4-byte encapsulation
    /// header.
    pub fn write(
        &mut self,
        topic: TopicId,
        log_time: u64,
        publish_time: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        let Some(t) = self.topics.iter_mut().find(|t| t.channel_id == topic.0) else {
            return Err(BagError::InvalidTopic {
                topic: format!("#{}", topic.0),
                reason: "not added to this bag".into(),
            });
        };
        t.sequence = t.sequence.wrapping_add(1);
        t.count += 1;
        let header = MessageHeader {
            channel_id: topic.0,
            sequence: t.sequence,
            log_time,
            publish_time,
        };
        if let (Some(age), Some(opened)) = (self.options.max_chunk_age, self.chunk_opened)
            && opened.elapsed() >= age
        {
            self.flush_chunk()?;
        }
        let path = self.mcap_path.clone();
        let r = self.writer()?.write_to_known_channel(&header, cdr);
        r.map_err(|e| BagError::mcap(&path, e))
            .map_err(|e| self.fail(e))?;
        if self.chunk_opened.is_none() {
            self.chunk_opened = Some(Instant::now());
        }
        self.start = Some(self.start.map_or(log_time, |s| s.min(log_time)));
        self.end = self.end.max(log_time);
        self.count += 1;
        Ok(())
    }

    /// Closes the current chunk and hands everything written so far to the operating system, so
    /// that a crash of this process loses nothing written before the call. Call it about once a
    /// second in a recorder (writes also close a chunk older than `max_chunk_age`).
    pub fn flush_chunk(&mut self) -> Result<(), BagError> {
        let path = self.mcap_path.clone();
        let r = self.writer()?.flush();
        r.map_err(|e| BagError::mcap(&path, e))
            .map_err(|e| self.fail(e))?;
        self.chunk_opened = None;
        Ok(())
    }

    /// Like [`Self::flush_chunk`], and also asks the OS to put the data on disk (fsync), so that
    /// a power loss loses nothing written before the call.
    pub fn sync(&mut self) -> Result<(), BagError> {
        self.flush_chunk()?;
        let path = self.mcap_path.clone();
        let r = self.writer()?.flush(); // nothing open; makes sure the BufWriter is empty
        r.map_err(|e| BagError::mcap(&path, e))
            .map_err(|e| self.fail(e))?;
        let file = File::open(&self.mcap_path).map_err(|e| BagError::io(&path, e));
        file.and_then(|f| f.sync_data().map_err(|e| BagError::io(&path, e)))
            .map_err(|e| self.fail(e))
    }

    /// The metadata of what was written so far.
    fn metadata(&self) -> BagMetadata {
        let start = self.start.unwrap_or(0);
        BagMetadata {
            version: METADATA_VERSION,
            storage_identifier: "mcap".into(),
            starting_time_ns: start,
            duration_ns: self.end.saturating_sub(start),
            message_count: self.count,
            topics: self
                .topics
                .iter()
                .map(|t| TopicEntry {
                    name: t.spec.name.clone(),
                    type_name: t.spec.type_name.clone(),
                    offered_qos_profiles: t.spec.offered_qos_profiles.clone(),
                    type_description_hash: t.spec.type_description_hash.clone(),
                    message_count: t.count,
                })
                .collect(),
            relative_file_paths: vec![self.file_name.clone()],
            ros_distro: self.options.ros_distro.clone(),
        }
    }

    /// Writes the summary and footer, metadata.yaml, and renames the bag into place. Returns the
    /// bag directory.
    pub fn finish(mut self) -> Result<PathBuf, BagError> {
        let r = self.finish_inner();
        match r {
            Ok(()) => Ok(self.final_dir.clone()),
            Err(e) => {
                let _ = fs::remove_dir_all(&self.tmp_dir);
                Err(e)
            }
        }
    }

    fn finish_inner(&mut self) -> Result<(), BagError> {
        let path = self.mcap_path.clone();
        let mut w = self.writer.take().ok_or_else(|| BagError::Io {
            path: path.clone(),
            source: std::io::Error::other("the bag writer failed earlier and was discarded"),
        })?;
        w.finish().map_err(|e| BagError::mcap(&path, e))?;
        let buf = w.into_inner();
        let file = buf
            .into_inner()
            .map_err(|e| BagError::io(&path, e.into_error()))?;
        file.sync_all().map_err(|e| BagError::io(&path, e))?;
        drop(file);
        let meta_path = self.tmp_dir.join("metadata.yaml");
        let mut f = File::create_new(&meta_path).map_err(|e| BagError::io(&meta_path, e))?;
        f.write_all(self.metadata().to_yaml().as_bytes())
            .and_then(|()| f.sync_all())
            .map_err(|e| BagError::io(&meta_path, e))?;
        if self.final_dir.exists() {
            return Err(BagError::OutputExists {
                path: self.final_dir.clone(),
            });
        }
        fs::rename(&self.tmp_dir, &self.final_dir).map_err(|e| BagError::io(&self.final_dir, e))?;
        if let Ok(d) = File::open(parent_of(&self.final_dir)) {
            let _ = d.sync_all();
        }
        Ok(())
    }

    /// Drops the bag: nothing is left on disk.
    pub fn abort(mut self) {
        self.discard();
    }
}

impl Drop for BagWriter {
    fn drop(&mut self) {
        self.discard();
    }
}
