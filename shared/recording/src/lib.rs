//! # exo-recording
//!
//! The recording contract of exo (`docs/recording-format.md`): ros2msg
//! schemas and CDR encoding of the exo messages ([`cdr`]), MCAP writing
//! ([`writer`]) and lenient reading of recordings whoever wrote them
//! ([`reader`]). Foxglove, the ROS 2 tools and Python (`mcap` with
//! `mcap-ros2-support`) read what this writes with nothing of ours installed.

#![warn(missing_docs)]

pub mod cdr;
pub mod reader;
pub mod writer;

use std::path::Path;

pub use cdr::{contract, CdrError, Recordable};
pub use reader::{read_recording, read_recording_bytes, Recording};
pub use writer::{RecordingWriter, DEFAULT_CHUNK_BYTES, SOFTWARE};

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
}

impl RecordingError {
    pub(crate) fn io(file: &Path, e: std::io::Error) -> Self {
        RecordingError::Io {
            file: file.display().to_string(),
            message: e.to_string(),
        }
    }

    pub(crate) fn mcap(file: &Path, e: mcap::McapError) -> Self {
        RecordingError::Mcap {
            file: file.display().to_string(),
            message: e.to_string(),
        }
    }
}
