//! Reading contract recordings, whoever wrote them, leniently: every
//! complete record is used, a file cut short (a recorder killed by SIGKILL)
//! yields what its complete chunks hold plus a warning, and nothing panics
//! on any input (fuzzed: `fuzz/fuzz_targets/read_recording.rs`).

use std::borrow::Cow;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};
use mcap::read::{LinearReader, Options};
use mcap::records::Record;

use crate::cdr::Recordable;
use crate::RecordingError;

/// Largest uncompressed chunk accepted (bytes).
const MAX_CHUNK_BYTES: u64 = 1 << 30;
/// Largest compression ratio a chunk may claim (zstd and lz4 stay far below).
const MAX_COMPRESSION_RATIO: u64 = 4096;

/// How many individual problems per topic are spelled out before they are only counted.
const DETAILED_PER_TOPIC: usize = 3;

/// Everything a recording holds that the contract defines.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// The file (or name) it was read from.
    pub source: String,
    /// `exo/sensor`.
    pub sensor: Vec<SensorSample>,
    /// `exo/command`.
    pub command: Vec<ActuatorCommand>,
    /// `exo/protocol`.
    pub protocol: Vec<ProtocolState>,
    /// `exo/identifier/frf`.
    pub frf: Vec<FrfPoint>,
    /// `exo/identifier/estimate`.
    pub estimate: Vec<ImpedanceEstimate>,
    /// `exo/operator`.
    pub operator: Vec<OperatorCommand>,
    /// `exo/bus/sensor`.
    pub bus_sensor: Vec<BusSensorFrame>,
    /// `exo/bus/motor`.
    pub bus_motor: Vec<BusMotorCommand>,
    /// Metadata records by name (`exo`, `exo.drops`, …).
    pub metadata: BTreeMap<String, BTreeMap<String, String>>,
    /// Attachments: name and bytes.
    pub attachments: Vec<(String, Vec<u8>)>,
    /// Contract topics with a channel in the file (with or without messages).
    pub topics: Vec<String>,
    /// Whether the file ended early (no footer / a record cut short).
    pub truncated: bool,
    /// What could not be used, naming the file and topic.
    pub warnings: Vec<String>,
}

impl Recording {
    /// The `exo` metadata value `key`, if present.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata
            .get("exo")
            .and_then(|m| m.get(key))
            .map(String::as_str)
    }

    /// Whether the file has a channel for `topic`.
    pub fn has_topic(&self, topic: &str) -> bool {
        self.topics.iter().any(|t| t == topic)
    }
}

/// Reads `path` (see [`read_recording_bytes`]).
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    let bytes = std::fs::read(path).map_err(|e| RecordingError::io(path, e))?;
    read_recording_bytes(&path.display().to_string(), &bytes)
}

#[derive(Debug, Clone)]
struct ChannelInfo {
    topic: String,
    schema_id: u16,
    encoding: String,
}

#[derive(Default)]
struct Problems {
    count: BTreeMap<String, usize>,
    warnings: Vec<String>,
}

impl Problems {
    fn add(&mut self, source: &str, topic: &str, what: String) {
        let n = self.count.entry(topic.to_string()).or_insert(0);
        *n += 1;
        if *n <= DETAILED_PER_TOPIC {
            self.warnings.push(format!("{source}: {topic}: {what}"));
        }
    }
}

struct State<'s> {
    source: &'s str,
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, ChannelInfo>,
    rejected: HashMap<u16, ()>,
    /// Channels already checked: their topic (`Some`) or rejection (`None`).
    checked: HashMap<u16, Option<&'static str>>,
    rec: Recording,
    problems: Problems,
}

impl State<'_> {
    /// The contract topic of channel `id`, checked once (schema name and
    /// encoding), or `None` when its messages are not used.
    fn channel_ok(&mut self, id: u16) -> Option<&'static str> {
        if let Some(known) = self.checked.get(&id) {
            return *known;
        }
        let verdict = self.check_channel(id);
        if self.channels.contains_key(&id) {
            self.checked.insert(id, verdict);
        }
        verdict
    }

    fn check_channel(&mut self, id: u16) -> Option<&'static str> {
        if self.rejected.contains_key(&id) {
            return None;
        }
        let ch = self.channels.get(&id)?.clone();
        let Some((topic, expected, _)) = crate::cdr::contract()
            .into_iter()
            .find(|(t, _, _)| *t == ch.topic)
        else {
            self.rejected.insert(id, ());
            self.rec.warnings.push(format!(
                "{}: topic {} is not part of the recording contract; ignored",
                self.source, ch.topic
            ));
            return None;
        };
        let schema = self.schemas.get(&ch.schema_id).cloned().unwrap_or_default();
        if schema != expected {
            self.rejected.insert(id, ());
            self.rec.warnings.push(format!(
                "{}: topic {} has schema `{schema}`, expected `{expected}`; its messages are not used",
                self.source, ch.topic
            ));
            return None;
        }
        if ch.encoding != "cdr" {
            self.rejected.insert(id, ());
            self.rec.warnings.push(format!(
                "{}: topic {} has message encoding `{}`, expected `cdr`; its messages are not used",
                self.source, ch.topic, ch.encoding
            ));
            return None;
        }
        Some(topic)
    }

    fn decode_into<T: Recordable>(&mut self, data: &[u8], log_time: u64) -> Option<T> {
        match T::decode(data, log_time) {
            Ok(m) => match m.first_non_finite() {
                None => Some(m),
                Some((field, v)) => {
                    self.problems.add(
                        self.source,
                        T::TOPIC,
                        format!("message at log time {log_time} ns has {field} = {v}; dropped"),
                    );
                    None
                }
            },
            Err(e) => {
                self.problems.add(
                    self.source,
                    T::TOPIC,
                    format!("message at log time {log_time} ns does not decode: {e}; dropped"),
                );
                None
            }
        }
    }

    fn message(&mut self, channel_id: u16, log_time: u64, data: &[u8]) {
        let Some(topic) = self.channel_ok(channel_id) else {
            if !self.channels.contains_key(&channel_id) {
                self.problems.add(
                    self.source,
                    "(unknown channel)",
                    format!("message on channel {channel_id} before its channel record; dropped"),
                );
            }
            return;
        };
        match topic {
            "exo/sensor" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.sensor.push(m);
                }
            }
            "exo/command" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.command.push(m);
                }
            }
            "exo/protocol" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.protocol.push(m);
                }
            }
            "exo/identifier/frf" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.frf.push(m);
                }
            }
            "exo/identifier/estimate" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.estimate.push(m);
                }
            }
            "exo/operator" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.operator.push(m);
                }
            }
            "exo/bus/sensor" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.bus_sensor.push(m);
                }
            }
            "exo/bus/motor" => {
                if let Some(m) = self.decode_into(data, log_time) {
                    self.rec.bus_motor.push(m);
                }
            }
            _ => {}
        }
    }

    /// Handles one record; `Err` ends the reading (what came before stays).
    fn record(&mut self, r: Record<'_>) -> Result<(), String> {
        match r {
            Record::Schema { header, .. } => {
                self.schemas.insert(header.id, header.name);
            }
            Record::Channel(c) => {
                self.checked.remove(&c.id);
                if !self.rec.topics.contains(&c.topic) {
                    self.rec.topics.push(c.topic.clone());
                }
                self.channels.insert(
                    c.id,
                    ChannelInfo {
                        topic: c.topic,
                        schema_id: c.schema_id,
                        encoding: c.message_encoding,
                    },
                );
            }
            Record::Message { header, data } => {
                self.message(header.channel_id, header.log_time, &data);
            }
            Record::Chunk { header, data } => {
                // A damaged header can claim any size; mcap would allocate it.
                let plausible = (data.len() as u64)
                    .saturating_mul(MAX_COMPRESSION_RATIO)
                    .saturating_add(1 << 20)
                    .min(MAX_CHUNK_BYTES);
                if header.uncompressed_size > plausible {
                    return Err(format!(
                        "a chunk claims {} uncompressed bytes from {} compressed",
                        header.uncompressed_size,
                        data.len()
                    ));
                }
                // Decompress here, into a buffer of the claimed (checked) size,
                // and read the records with a length limit of that buffer.
                let body: Cow<'_, [u8]> = match header.compression.as_str() {
                    "" => data,
                    "zstd" => Cow::Owned(
                        zstd::bulk::decompress(&data, header.uncompressed_size as usize)
                            .map_err(|e| format!("zstd chunk: {e}"))?,
                    ),
                    "lz4" => {
                        let mut out = Vec::with_capacity(header.uncompressed_size as usize);
                        let mut dec =
                            lz4::Decoder::new(&data[..]).map_err(|e| format!("lz4 chunk: {e}"))?;
                        std::io::Read::read_to_end(
                            &mut std::io::Read::take(&mut dec, header.uncompressed_size),
                            &mut out,
                        )
                        .map_err(|e| format!("lz4 chunk: {e}"))?;
                        Cow::Owned(out)
                    }
                    other => return Err(format!("chunk compression `{other}` is not supported")),
                };
                if body.len() as u64 != header.uncompressed_size {
                    return Err(format!(
                        "a chunk decompresses to {} bytes, its header says {}",
                        body.len(),
                        header.uncompressed_size
                    ));
                }
                for inner in LinearReader::sans_magic(&body) {
                    let inner = inner.map_err(|e| format!("inside a chunk: {e}"))?;
                    self.record(inner)?;
                }
            }
            Record::Metadata(m) => {
                self.rec.metadata.insert(m.name, m.metadata);
            }
            Record::Attachment { header, data, .. } => {
                let bytes = match data {
                    Cow::Borrowed(b) => b.to_vec(),
                    Cow::Owned(b) => b,
                };
                self.rec.attachments.push((header.name, bytes));
            }
            Record::Footer(_) => self.rec.truncated = false,
            _ => {}
        }
        Ok(())
    }
}

/// Reads a recording from memory. `source` names it in warnings and errors.
///
/// Errors only when nothing can be read (not an MCAP file at all); every
/// other problem is a warning in [`Recording::warnings`]: a file cut short,
/// a corrupt chunk (reading stops there), a topic with the wrong schema or
/// encoding (skipped), a message that does not decode or carries NaN/inf
/// (dropped, counted per topic).
pub fn read_recording_bytes(source: &str, bytes: &[u8]) -> Result<Recording, RecordingError> {
    if bytes.len() < mcap::MAGIC.len() || bytes[..mcap::MAGIC.len()] != mcap::MAGIC[..] {
        return Err(RecordingError::NotMcap {
            file: source.to_string(),
        });
    }
    let mut st = State {
        source,
        schemas: HashMap::new(),
        channels: HashMap::new(),
        rejected: HashMap::new(),
        checked: HashMap::new(),
        rec: Recording {
            source: source.to_string(),
            truncated: true,
            ..Default::default()
        },
        problems: Problems::default(),
    };
    let reader = LinearReader::new_with_options(bytes, Options::IgnoreEndMagic.into())
        .map_err(|e| RecordingError::mcap(Path::new(source), e))?;
    let mut stopped: Option<String> = None;
    for r in reader {
        match r {
            Ok(r) => {
                if let Err(e) = st.record(r) {
                    stopped = Some(e);
                    break;
                }
            }
            Err(e) => {
                stopped = Some(e.to_string());
                break;
            }
        }
    }
    let n_messages = st.rec.sensor.len()
        + st.rec.command.len()
        + st.rec.protocol.len()
        + st.rec.frf.len()
        + st.rec.estimate.len()
        + st.rec.operator.len()
        + st.rec.bus_sensor.len()
        + st.rec.bus_motor.len();
    if let Some(e) = stopped {
        st.rec.truncated = true;
        st.rec.warnings.push(format!(
            "{source}: reading stopped at a damaged or cut-off record ({e}); the {n_messages} messages before it are used"
        ));
    } else if st.rec.truncated {
        st.rec.warnings.push(format!(
            "{source}: the file ends without its footer (recorder stopped early?); the {n_messages} messages of its complete chunks are used"
        ));
    }
    for (topic, n) in &st.problems.count {
        if *n > DETAILED_PER_TOPIC {
            st.problems.warnings.push(format!(
                "{source}: {topic}: {} more messages dropped like those above",
                n - DETAILED_PER_TOPIC
            ));
        }
    }
    let mut rec = st.rec;
    rec.warnings.extend(st.problems.warnings);
    Ok(rec)
}
