//! Errors of the bag layer.
use std::path::PathBuf;

/// Everything that can go wrong reading, writing or recovering a bag.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The bag directory or MCAP file does not exist.
    #[error("{}: no such bag directory or MCAP file", path.display())]
    NotFound { path: PathBuf },

    /// The file does not start with the MCAP magic bytes.
    #[error(
        "{}: not an MCAP file (it starts with {found:02x?}, not the MCAP magic 89 4d 43 41 50 30 0d 0a)",
        path.display()
    )]
    NotMcap { path: PathBuf, found: Vec<u8> },

    /// The MCAP file ends early or holds a record that does not parse.
    #[error(
        "{}: truncated or corrupt MCAP file{}: {detail}; if the recorder was interrupted, \
         `forcemap bag recover {} NEW_BAG` rebuilds a bag with every complete message",
        path.display(),
        at_offset(*offset),
        path.display()
    )]
    Corrupt {
        path: PathBuf,
        /// Byte offset of the first record that is cut off or does not parse, if known.
        offset: Option<u64>,
        detail: String,
    },

    /// metadata.yaml is missing, unreadable, or not a rosbag2 metadata file.
    #[error("{}: metadata.yaml unreadable: {reason}", path.display())]
    Metadata { path: PathBuf, reason: String },

    /// A topic asked for by name is not in the bag.
    #[error("topic '{topic}' not found; the bag has: {}", list(available))]
    TopicNotFound {
        topic: String,
        available: Vec<String>,
    },

    /// A channel's schema is not a ROS 2 .msg definition.
    #[error(
        "{}: topic '{topic}' has schema encoding '{encoding}', only 'ros2msg' is supported",
        path.display()
    )]
    SchemaEncoding {
        path: PathBuf,
        topic: String,
        encoding: String,
    },

    /// A topic given to the writer is not valid (name, type name, or a second type on a topic).
    #[error("topic '{topic}': {reason}")]
    InvalidTopic { topic: String, reason: String },

    /// The output already exists (bags are never overwritten).
    #[error("{}: already exists; bags are never overwritten", path.display())]
    OutputExists { path: PathBuf },

    /// Recovery found not even the MCAP header.
    #[error("{}: nothing to recover: {reason}", path.display())]
    NothingToRecover { path: PathBuf, reason: String },

    /// An I/O error on a file.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// An error of the MCAP library while writing or reading.
    #[error("{}: MCAP: {source}", path.display())]
    Mcap {
        path: PathBuf,
        #[source]
        source: mcap::McapError,
    },
}

fn at_offset(offset: Option<u64>) -> String {
    match offset {
        Some(o) => format!(" at byte {o}"),
        None => String::new(),
    }
}

fn list(topics: &[String]) -> String {
    if topics.is_empty() {
        "no topics".to_string()
    } else {
        topics.join(", ")
    }
}

impl BagError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        BagError::Io {
            path: path.into(),
            source,
        }
    }

    pub(crate) fn mcap(path: impl Into<PathBuf>, source: mcap::McapError) -> Self {
        BagError::Mcap {
            path: path.into(),
            source,
        }
    }
}
