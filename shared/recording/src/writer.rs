//! Writing contract recordings: chunked, zstd-compressed MCAP with ros2msg
//! schemas and CDR messages, `log_time = publish_time = stamp_ns`.
//!
//! Messages are recorded as given, NaN included (a recording is the
//! evidence of what was on the bus); readers drop non-finite messages with
//! a warning ([`crate::reader`]). Nothing here panics: every failure is a
//! [`RecordingError`] naming the file.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};
use mcap::records::MessageHeader;
use mcap::{Attachment, WriteOptions, Writer};

use crate::cdr::Recordable;
use crate::schema::{MESSAGE_ENCODING, PROFILE, SCHEMA_ENCODING};
use crate::RecordingError;

/// Name of the metadata record describing the run (`subject`, …).
pub const RUN_METADATA: &str = "exo";
/// Name of the metadata record with per-topic sequence-gap counts.
pub const DROPS_METADATA: &str = "exo.drops";
/// Name of the attachment holding the run's configuration.
pub const CONFIG_ATTACHMENT: &str = "config.toml";

/// Uncompressed bytes after which a chunk is closed (compressed and written
/// out). Only closed chunks are readable after a SIGKILL, so this bounds the
/// loss: at 1 kHz `exo/sensor` + `exo/command` make 190 kB/s of MCAP
/// records (87 + 103 bytes a tick: a chunk every 0.35 s), and with the two
/// bus topics 380 kB/s (a chunk every 0.17 s; a writer killed at any moment
/// lost at most 0.17 s, measured in `tests/it/files.rs`). A recorder also
/// calls [`RecordingWriter::flush`] once a second, so sparse topics lose at
/// most a second. Larger chunks compress only slightly better.
pub const DEFAULT_CHUNK_BYTES: u64 = 64 * 1024;

/// The software that wrote a recording (metadata `exo.software_version`).
pub const SOFTWARE: &str = concat!("exo ", env!("CARGO_PKG_VERSION"));

/// Writes one contract recording.
///
/// Schemas and channels are registered once, on a topic's first message
/// (or all at once with [`register_contract`](Self::register_contract)).
pub struct RecordingWriter<W: Write + Seek> {
    mcap: Writer<W>,
    file: PathBuf,
    /// The partial file being written, renamed to `file` by
    /// [`finish`](Self::finish); `None` for a writer on any other sink.
    partial: Option<PathBuf>,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    messages: u64,
    scratch: Vec<u8>,
}

impl RecordingWriter<BufWriter<File>> {
    /// Starts a recording for `path` (creating its directory) with
    /// [`DEFAULT_CHUNK_BYTES`]. It is written to `path`'s partial file
    /// (`<path>.partial`, locked while written, [`crate::segments`]) and
    /// renamed to `path` by [`finish`](Self::finish): until then an earlier
    /// file at `path` stays as it was, and a writer that fails or dies
    /// never leaves a half file at `path`.
    pub fn create(path: &Path) -> Result<Self, RecordingError> {
        Self::create_with_chunk_bytes(path, DEFAULT_CHUNK_BYTES)
    }

    /// Like [`create`](Self::create) with chunks closed after `chunk_bytes`
    /// uncompressed bytes (at least 1024).
    pub fn create_with_chunk_bytes(path: &Path, chunk_bytes: u64) -> Result<Self, RecordingError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            crate::files::create_output_dir(dir).map_err(|e| RecordingError::io(path, e))?;
        }
        let partial = crate::segments::partial_path(path);
        let f = crate::files::create_locked_output_file(&partial)
            .map_err(|e| RecordingError::io(&partial, e))?;
        let mut w = Self::new(BufWriter::new(f), path, chunk_bytes)?;
        w.partial = Some(partial);
        Ok(w)
    }
}

impl<W: Write + Seek> RecordingWriter<W> {
    /// Starts a recording on `w`; `file` names it in errors; chunks close
    /// after `chunk_bytes` uncompressed bytes (at least 1024).
    pub fn new(w: W, file: &Path, chunk_bytes: u64) -> Result<Self, RecordingError> {
        let mcap = WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            // zstd's fastest level: the writer keeps up with the in-process
            // simulation (thousands of times real time), files about 10 %
            // larger than at the default level 3 (BENCHMARKS.md).
            .compression_level(1)
            // Compress in the caller's thread: chunks are small, and a
            // recorder should not start worker threads beside the control loop.
            .compression_threads(0)
            .chunk_size(Some(chunk_bytes.max(1024)))
            .profile(PROFILE)
            .library(SOFTWARE)
            .create(w)
            .map_err(|e| RecordingError::mcap(file, e))?;
        Ok(RecordingWriter {
            mcap,
            file: file.to_path_buf(),
            partial: None,
            channels: BTreeMap::new(),
            sequence: 0,
            messages: 0,
            scratch: Vec::with_capacity(256),
        })
    }

    /// The file (or name) given at creation.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// Messages written so far.
    pub fn messages_written(&self) -> u64 {
        self.messages
    }

    fn channel<T: Recordable>(&mut self) -> Result<u16, RecordingError> {
        if let Some(id) = self.channels.get(T::TOPIC) {
            return Ok(*id);
        }
        let schema = self
            .mcap
            .add_schema(T::SCHEMA_NAME, SCHEMA_ENCODING, T::schema().as_bytes())
            .map_err(|e| RecordingError::mcap(&self.file, e))?;
        let id = self
            .mcap
            .add_channel(schema, T::TOPIC, MESSAGE_ENCODING, &BTreeMap::new())
            .map_err(|e| RecordingError::mcap(&self.file, e))?;
        self.channels.insert(T::TOPIC, id);
        Ok(id)
    }

    /// Registers every contract topic now, so a reader sees them all even
    /// when some carry no message.
    pub fn register_contract(&mut self) -> Result<(), RecordingError> {
        self.channel::<SensorSample>()?;
        self.channel::<ActuatorCommand>()?;
        self.channel::<ProtocolState>()?;
        self.channel::<FrfPoint>()?;
        self.channel::<ImpedanceEstimate>()?;
        self.channel::<OperatorCommand>()?;
        self.channel::<BusSensorFrame>()?;
        self.channel::<BusMotorCommand>()?;
        Ok(())
    }

    /// Writes one message on its topic, stamped with its `stamp_ns`.
    pub fn write<T: Recordable>(&mut self, msg: &T) -> Result<(), RecordingError> {
        let channel_id = self.channel::<T>()?;
        let buf = std::mem::take(&mut self.scratch);
        let data = msg.encode_into(buf);
        let stamp = msg.stamp_ns();
        let r = self.mcap.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence: self.sequence,
                log_time: stamp,
                publish_time: stamp,
            },
            &data,
        );
        self.scratch = data;
        self.sequence = self.sequence.wrapping_add(1);
        r.map_err(|e| RecordingError::mcap(&self.file, e))?;
        self.messages += 1;
        Ok(())
    }

    /// Writes the run's description: the `exo` metadata record (`metadata`,
    /// which must name a non-empty `subject`, plus `software_version` =
    /// [`SOFTWARE`] unless given and `config_toml` = the configuration
    /// text) and the configuration as the attachment `config.toml`
    /// (`application/toml`).
    pub fn write_run_info(
        &mut self,
        metadata: &BTreeMap<String, String>,
        config_toml: &str,
    ) -> Result<(), RecordingError> {
        if metadata.get("subject").is_none_or(|s| s.trim().is_empty()) {
            return Err(RecordingError::Invalid {
                file: self.file.display().to_string(),
                message: "the `exo` metadata record needs a non-empty `subject`".to_string(),
            });
        }
        let mut m = metadata.clone();
        m.entry("software_version".to_string())
            .or_insert_with(|| SOFTWARE.to_string());
        m.insert("config_toml".to_string(), config_toml.to_string());
        self.write_metadata(RUN_METADATA, &m)?;
        self.attach(
            CONFIG_ATTACHMENT,
            "application/toml",
            config_toml.as_bytes(),
            0,
        )
    }

    /// Writes a metadata record `name` (e.g. `exo`, or `exo.drops` with
    /// per-topic counts of sequence gaps at the end of a run).
    pub fn write_metadata(
        &mut self,
        name: &str,
        map: &BTreeMap<String, String>,
    ) -> Result<(), RecordingError> {
        self.mcap
            .write_metadata(&mcap::records::Metadata {
                name: name.to_string(),
                metadata: map.clone(),
            })
            .map_err(|e| RecordingError::mcap(&self.file, e))
    }

    /// Attaches a file (e.g. the run configuration as `config.toml`).
    pub fn attach(
        &mut self,
        name: &str,
        media_type: &str,
        data: &[u8],
        time_ns: u64,
    ) -> Result<(), RecordingError> {
        self.mcap
            .attach(&Attachment {
                log_time: time_ns,
                create_time: time_ns,
                name: name.to_string(),
                media_type: media_type.to_string(),
                data: std::borrow::Cow::Borrowed(data),
            })
            .map_err(|e| RecordingError::mcap(&self.file, e))
    }

    /// Copies a message read from another MCAP file (its channel and schema
    /// are registered on first use): what [`crate::segments::complete`]
    /// rewrites a dead writer's file with.
    pub fn copy_message(&mut self, message: &mcap::Message<'_>) -> Result<(), RecordingError> {
        self.mcap
            .write(message)
            .map_err(|e| RecordingError::mcap(&self.file, e))
    }

    /// Closes the open chunk and flushes it to the file, so a crash after
    /// this loses nothing written before.
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.mcap
            .flush()
            .map_err(|e| RecordingError::mcap(&self.file, e))
    }

    /// Closes the last chunk, writes the summary and footer and flushes; a
    /// recording [`create`](RecordingWriter::create)d for a path is then
    /// synced and renamed from its partial file to that path (replacing an
    /// earlier file there in one step).
    pub fn finish(mut self) -> Result<(), RecordingError> {
        self.mcap
            .finish()
            .map_err(|e| RecordingError::mcap(&self.file, e))?;
        let mut inner = self.mcap.into_inner();
        inner
            .flush()
            .map_err(|e| RecordingError::io(&self.file, e))?;
        let Some(partial) = &self.partial else {
            return Ok(());
        };
        let publish = || -> std::io::Result<()> {
            // The data must be on disk before the name says it is complete.
            File::open(partial)?.sync_all()?;
            std::fs::rename(partial, &self.file)?;
            if let Some(dir) = self.file.parent().filter(|d| !d.as_os_str().is_empty()) {
                // Best effort: makes the rename itself durable.
                let _ = File::open(dir).and_then(|d| d.sync_all());
            }
            Ok(())
        };
        let done = publish().map_err(|e| {
            RecordingError::io(
                &self.file,
                std::io::Error::new(
                    e.kind(),
                    format!(
                        "finishing it from {}: {e}; the recording stays in {}",
                        partial.display(),
                        partial.display()
                    ),
                ),
            )
        });
        // The lock on the partial file ends with the file.
        drop(inner);
        done
    }
}
