//! Writing contract recordings: chunked, zstd-compressed MCAP with ros2msg
//! schemas and CDR messages, `log_time = publish_time = stamp_ns`.

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
use crate::RecordingError;

/// Uncompressed bytes per chunk. At 1 kHz the sensor and command topics
/// make about 150 kB/s of CDR, so a chunk closes about every 0.4 s: a
/// recorder killed by SIGKILL loses at most the open chunk.
pub const DEFAULT_CHUNK_BYTES: u64 = 64 * 1024;

/// The software that wrote a recording (metadata `exo.software_version`).
pub const SOFTWARE: &str = concat!("exo ", env!("CARGO_PKG_VERSION"));

/// Writes one contract recording.
pub struct RecordingWriter<W: Write + Seek> {
    mcap: Writer<W>,
    file: PathBuf,
    channels: BTreeMap<&'static str, u16>,
    sequence: u32,
    scratch: Vec<u8>,
}

impl RecordingWriter<BufWriter<File>> {
    /// Creates `path` (its directory too) and starts a recording there.
    pub fn create(path: &Path) -> Result<Self, RecordingError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| RecordingError::io(path, e))?;
        }
        let f = File::create(path).map_err(|e| RecordingError::io(path, e))?;
        Self::new(BufWriter::new(f), path, DEFAULT_CHUNK_BYTES)
    }
}

impl<W: Write + Seek> RecordingWriter<W> {
    /// Starts a recording on `w`; `file` names it in errors.
    pub fn new(w: W, file: &Path, chunk_bytes: u64) -> Result<Self, RecordingError> {
        let mcap = WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(chunk_bytes.max(1024)))
            .profile("ros2")
            .library(SOFTWARE)
            .create(w)
            .map_err(|e| RecordingError::mcap(file, e))?;
        Ok(RecordingWriter {
            mcap,
            file: file.to_path_buf(),
            channels: BTreeMap::new(),
            sequence: 0,
            scratch: Vec::with_capacity(256),
        })
    }

    fn channel<T: Recordable>(&mut self) -> Result<u16, RecordingError> {
        if let Some(id) = self.channels.get(T::TOPIC) {
            return Ok(*id);
        }
        let schema = self
            .mcap
            .add_schema(T::SCHEMA_NAME, "ros2msg", T::schema().as_bytes())
            .map_err(|e| RecordingError::mcap(&self.file, e))?;
        let id = self
            .mcap
            .add_channel(schema, T::TOPIC, "cdr", &BTreeMap::new())
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
        r.map_err(|e| RecordingError::mcap(&self.file, e))
    }

    /// Writes a metadata record `name` (e.g. `exo`, `exo.drops`).
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

    /// Closes the open chunk and flushes it to the file, so a crash after
    /// this loses nothing written before.
    pub fn flush(&mut self) -> Result<(), RecordingError> {
        self.mcap
            .flush()
            .map_err(|e| RecordingError::mcap(&self.file, e))
    }

    /// Writes the summary and footer.
    pub fn finish(mut self) -> Result<(), RecordingError> {
        self.mcap
            .finish()
            .map_err(|e| RecordingError::mcap(&self.file, e))?;
        let mut inner = self.mcap.into_inner();
        inner.flush().map_err(|e| RecordingError::io(&self.file, e))
    }
}
