//! # exo-recording
//!
//! The recording contract of exo (`docs/recording-format.md`): the one
//! table of topics, schema names and fields ([`schema`]), CDR encoding of
//! the exo messages ([`cdr`]), chunked zstd MCAP writing ([`writer`]) and
//! lenient reading of recordings whoever wrote them ([`reader`]). Foxglove,
//! the ROS 2 tools and Python (`mcap` with `mcap-ros2-support`) read what
//! this writes with nothing of ours installed, and files they write are
//! read here.
//!
//! ```no_run
//! # fn main() -> Result<(), exo_recording::RecordingError> {
//! use exo_recording::{read_recording, RecordingWriter};
//! let path = std::path::Path::new("run.mcap");
//! let mut w = RecordingWriter::create(path)?;
//! w.write(&exo_messages::SensorSample { seq: 1, stamp_ns: 1_000_000, ..Default::default() })?;
//! w.finish()?;
//! let r = read_recording(path)?;
//! assert_eq!(r.sensor.len(), 1);
//! # Ok(()) }
//! ```

#![warn(missing_docs)]

pub mod cdr;
pub mod drops;
pub mod excitation;
pub mod files;
mod framing;
mod in_place;
pub mod reader;
pub mod record;
pub mod ros2msg;
pub mod schema;
pub mod segments;
pub mod writer;

use std::path::Path;

pub use cdr::{CdrError, FieldValue, Recordable};
pub use reader::{read_recording, read_recording_bytes, read_recording_topics, Recording};
pub use record::Record;
pub use schema::{contract, TopicSchema};
pub use writer::{
    RecordingWriter, CONFIG_ATTACHMENT, DEFAULT_CHUNK_BYTES, DROPS_METADATA, RUN_METADATA, SOFTWARE,
};

/// Errors reading or writing a recording, naming the file.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be read or written.
    #[error("{file}: {message}")]
    Io {
        /// The file.
        file: String,
        /// What went wrong.
        message: String,
    },
    /// The MCAP library refused.
    #[error("{file}: MCAP: {message}")]
    Mcap {
        /// The file.
        file: String,
        /// What went wrong.
        message: String,
    },
    /// Not an MCAP file (no magic bytes).
    #[error("{file}: not an MCAP file (it does not start with the MCAP magic bytes)")]
    NotMcap {
        /// The file.
        file: String,
    },
    /// A contract topic's channel names another schema.
    #[error(
        "{file}: topic {topic} has schema `{found}`, the recording contract requires `{expected}`"
    )]
    WrongSchema {
        /// The file.
        file: String,
        /// The topic.
        topic: String,
        /// The contract's schema name.
        expected: String,
        /// The file's schema name.
        found: String,
    },
    /// A contract topic's schema has the right name but not the contract's fields.
    #[error("{file}: topic {topic} (schema `{schema}`): {detail}")]
    IncompatibleSchema {
        /// The file.
        file: String,
        /// The topic.
        topic: String,
        /// The schema name.
        schema: String,
        /// Which field does not match.
        detail: String,
    },
    /// A contract topic's channel or schema uses another encoding.
    #[error(
        "{file}: topic {topic} has {what} `{found}`, the recording contract requires `{expected}`"
    )]
    WrongEncoding {
        /// The file.
        file: String,
        /// The topic.
        topic: String,
        /// `message encoding` or `schema encoding`.
        what: &'static str,
        /// The contract's encoding.
        expected: &'static str,
        /// The file's encoding.
        found: String,
    },
    /// A writer was asked for something the contract does not allow.
    #[error("{file}: {message}")]
    Invalid {
        /// The file.
        file: String,
        /// What was wrong.
        message: String,
    },
}

impl RecordingError {
    pub(crate) fn io(file: &Path, e: std::io::Error) -> Self {
        RecordingError::Io {
            file: file.display().to_string(),
            message: e.to_string(),
        }
    }

    pub(crate) fn mcap(file: &Path, e: mcap::McapError) -> Self {
        match e {
            // The operating system's error itself (no space, no
            // permission), not the library's summary of it.
            mcap::McapError::Io(io) => RecordingError::io(file, io),
            e => RecordingError::Mcap {
                file: file.display().to_string(),
                message: e.to_string(),
            },
        }
    }
}
