//! Reading contract recordings, whoever wrote them, leniently: every
//! complete record is used, a file cut short (a recorder killed by SIGKILL)
//! yields what its complete chunks hold plus a warning `truncated after N
//! messages`, and nothing panics on any input (fuzzed:
//! `fuzz/fuzz_targets/read_recording.rs`).
//!
//! What is an error and what a warning:
//! - **Errors** ([`RecordingError`]): the file cannot be read or is not MCAP;
//!   a contract topic's channel has another schema name
//!   ([`RecordingError::WrongSchema`]), schema or message encoding
//!   ([`RecordingError::WrongEncoding`]), or a schema text whose fields are
//!   not the contract's ([`RecordingError::IncompatibleSchema`]).
//! - **Warnings** ([`Recording::warnings`], each naming the file): the file
//!   ends early, or a record's length runs past the end (reading stops
//!   there); a record whose inner lengths or fields are damaged, or a chunk
//!   that fails to decompress or fails its CRC (skipped, reading goes on);
//!   topics outside the contract (ignored); messages that do not decode or
//!   carry NaN/±∞ in a float field (dropped and counted per topic); fields
//!   of a writer's schema beyond the contract (ignored).
//! - Missing topics are neither: [`Recording::topics`] lists the contract
//!   topics present and the caller decides what it needs.
//!
//! Records are framed here, not by `mcap`'s `LinearReader`, and each
//! record's inner lengths are checked before `mcap::parse_record` sees it:
//! a damaged length never allocates more than the file holds. Each
//! channel is checked once, at its channel record; its messages then go
//! straight to their decoder.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};
use mcap::records::{op, Record};

use crate::cdr::Recordable;
use crate::framing::{chunk_body, lengths_fit, Frame, Framing};
use crate::schema::{self, MESSAGE_ENCODING, SCHEMA_ENCODING};
use crate::RecordingError;

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
    /// Contract topics with a channel in the file (with or without messages), in file order.
    pub topics: Vec<String>,
    /// Other topics in the file (ignored), in file order.
    pub other_topics: Vec<String>,
    /// Whether the file ended early (no footer, or a record cut short or damaged).
    pub truncated: bool,
    /// What could not be used, each naming the file.
    pub warnings: Vec<String>,
}

impl Recording {
    /// The `exo` metadata value `key`, if present.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata
            .get(crate::writer::RUN_METADATA)
            .and_then(|m| m.get(key))
            .map(String::as_str)
    }

    /// Whether the file has a channel for `topic`.
    pub fn has_topic(&self, topic: &str) -> bool {
        self.topics.iter().any(|t| t == topic)
    }

    /// Contract topics without a channel in the file.
    pub fn missing_topics(&self) -> Vec<&'static str> {
        schema::contract()
            .into_iter()
            .map(|t| t.topic)
            .filter(|t| !self.has_topic(t))
            .collect()
    }

    /// The attachment `name`, if present.
    pub fn attachment(&self, name: &str) -> Option<&[u8]> {
        self.attachments
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, d)| d.as_slice())
    }

    /// Decoded messages on all contract topics.
    pub fn message_count(&self) -> usize {
        self.sensor.len()
            + self.command.len()
            + self.protocol.len()
            + self.frf.len()
            + self.estimate.len()
            + self.operator.len()
            + self.bus_sensor.len()
            + self.bus_motor.len()
    }
}

/// Reads `path` (see [`read_recording_bytes`]) with its later segments
/// (`<stem>-part2.mcap`, …, [`crate::segments`]) as one recording.
pub fn read_recording(path: &Path) -> Result<Recording, RecordingError> {
    read_segments(path, None)
}

/// [`read_recording`], decoding only the contract topics in `topics` (e.g.
/// `exo fit` needs neither the bus topics nor the identifier's estimates,
/// half of a recording's messages). Every channel is still checked against
/// the contract; the other topics' vectors stay empty.
pub fn read_recording_topics(path: &Path, topics: &[&str]) -> Result<Recording, RecordingError> {
    read_segments(path, Some(topics))
}

fn read_segments(path: &Path, only: Option<&[&str]>) -> Result<Recording, RecordingError> {
    let mut first: Option<Recording> = None;
    let mut rest = Vec::new();
    let mut empty = Vec::new();
    for p in crate::segments::segments(path) {
        let bytes = std::fs::read(&p).map_err(|e| RecordingError::io(&p, e))?;
        if bytes.is_empty() && first.is_some() {
            // A restarted recorder that stopped before it wrote anything
            // (e.g. on a full disk): nothing to read, nothing lost.
            empty.push(format!(
                "{}: empty: its recorder stopped before it wrote anything",
                p.display()
            ));
            continue;
        }
        let mut rec = read_bytes(&p.display().to_string(), &bytes, only)?;
        if p.as_os_str()
            .to_string_lossy()
            .ends_with(crate::segments::PARTIAL_SUFFIX)
        {
            rec.warnings.push(format!(
                "{}: read from its partial file: its writer has not finished it (still writing, or it died); what its complete chunks hold is used",
                p.display()
            ));
        }
        match first {
            None => first = Some(rec),
            Some(_) => rest.push(rec),
        }
    }
    let first =
        first.ok_or_else(|| RecordingError::io(path, std::io::ErrorKind::NotFound.into()))?;
    let mut rec = join_segments(first, rest);
    rec.warnings.extend(empty);
    Ok(rec)
}

/// One recording from its segments: every topic's messages in time order
/// (a message a restarted recorder received twice, through the channel's
/// history, kept once), the first segment's metadata and attachments, and
/// a warning naming the samples no segment holds (the recorder was down).
fn join_segments(mut rec: Recording, rest: Vec<Recording>) -> Recording {
    if rest.is_empty() {
        return rec;
    }
    let n = rest.len() + 1;
    let mut gaps = Vec::new();
    for r in rest {
        if let (Some(last), Some(next)) = (rec.sensor.last(), r.sensor.first()) {
            if next.seq > last.seq + 1 {
                gaps.push(format!(
                    "exo/sensor seq {} to {} ({} samples) are in no segment: the recorder was down before {}",
                    last.seq + 1,
                    next.seq - 1,
                    next.seq - last.seq - 1,
                    r.source
                ));
            }
        }
        rec.sensor.extend(r.sensor);
        rec.command.extend(r.command);
        rec.protocol.extend(r.protocol);
        rec.frf.extend(r.frf);
        rec.estimate.extend(r.estimate);
        rec.operator.extend(r.operator);
        rec.bus_sensor.extend(r.bus_sensor);
        rec.bus_motor.extend(r.bus_motor);
        for t in r.topics {
            if !rec.topics.contains(&t) {
                rec.topics.push(t);
            }
        }
        rec.truncated |= r.truncated;
        rec.warnings.extend(r.warnings);
    }
    fn in_time<T: Recordable + PartialEq>(v: &mut Vec<T>) {
        v.sort_by_key(|m| m.stamp_ns());
        v.dedup();
    }
    in_time(&mut rec.sensor);
    in_time(&mut rec.command);
    in_time(&mut rec.protocol);
    in_time(&mut rec.frf);
    in_time(&mut rec.estimate);
    in_time(&mut rec.operator);
    in_time(&mut rec.bus_sensor);
    in_time(&mut rec.bus_motor);
    for g in gaps {
        rec.warnings.push(format!("{}: {g}", rec.source));
    }
    rec.source = format!(
        "{} (+{} segment{})",
        rec.source,
        n - 1,
        if n == 2 { "" } else { "s" }
    );
    rec
}

/// Where a contract message goes.
trait Stored: Recordable {
    fn slot(rec: &mut Recording) -> &mut Vec<Self>;
}

macro_rules! stored {
    ($($ty:ty => $field:ident),+ $(,)?) => {
        $(impl Stored for $ty {
            fn slot(rec: &mut Recording) -> &mut Vec<Self> {
                &mut rec.$field
            }
        })+

        /// The decoder of a contract topic.
        fn decoder_for(topic: &str) -> Option<Decoder> {
            $(if topic == <$ty as Recordable>::TOPIC {
                return Some(decode_push::<$ty>);
            })+
            None
        }
    };
}

stored!(
    SensorSample => sensor,
    ActuatorCommand => command,
    ProtocolState => protocol,
    FrfPoint => frf,
    ImpedanceEstimate => estimate,
    OperatorCommand => operator,
    BusSensorFrame => bus_sensor,
    BusMotorCommand => bus_motor,
);

/// Decodes one message (`Some(n)`: the first `n` fields; `None`: no schema
/// text, decode by the payload's length) and stores it or reports it.
type Decoder = fn(&mut State<'_>, &[u8], Option<usize>, u64);

fn decode_push<T: Stored>(st: &mut State<'_>, data: &[u8], n_fields: Option<usize>, log_time: u64) {
    let decoded = match n_fields {
        Some(n) => T::decode_fields(data, n, log_time),
        None => T::decode(data, log_time),
    };
    match decoded {
        Ok(m) => match m.first_non_finite() {
            None => T::slot(&mut st.rec).push(m),
            Some((field, v)) => st.problems.add(
                st.source,
                T::TOPIC,
                format!("message at log time {log_time} ns has {field} = {v}; dropped"),
            ),
        },
        Err(e) => st.problems.add(
            st.source,
            T::TOPIC,
            format!("message at log time {log_time} ns does not decode: {e}; dropped"),
        ),
    }
}

#[derive(Clone, Copy)]
enum ChannelUse {
    Decode(Decoder, Option<usize>),
    Ignore,
}

struct SchemaInfo {
    name: String,
    encoding: String,
    text: String,
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
    /// Contract topics to decode (`None`: all).
    only: Option<&'s [&'s str]>,
    schemas: HashMap<u16, SchemaInfo>,
    channels: HashMap<u16, ChannelUse>,
    rec: Recording,
    problems: Problems,
    chunks: usize,
}

impl State<'_> {
    fn warn(&mut self, what: String) {
        self.rec.warnings.push(format!("{}: {what}", self.source));
    }

    /// Decides how a channel's messages are used; contract violations are errors.
    fn channel(&mut self, c: &mcap::records::Channel) -> Result<ChannelUse, RecordingError> {
        let file = self.source.to_string();
        let Some(row) = schema::find(&c.topic) else {
            if !self.rec.other_topics.contains(&c.topic) {
                self.rec.other_topics.push(c.topic.clone());
                self.warn(format!(
                    "topic {} is not part of the recording contract; ignored",
                    c.topic
                ));
            }
            return Ok(ChannelUse::Ignore);
        };
        let Some(decoder) = decoder_for(row.topic) else {
            return Ok(ChannelUse::Ignore);
        };
        if !self.rec.topics.iter().any(|t| t == row.topic) {
            self.rec.topics.push(row.topic.to_string());
        }
        // A topic outside the selection is checked against the contract like
        // any other, then ignored.
        let wanted = self.only.is_none_or(|only| only.contains(&row.topic));
        let decode = |n_fields| {
            if wanted {
                ChannelUse::Decode(decoder, n_fields)
            } else {
                ChannelUse::Ignore
            }
        };
        let Some(s) = self.schemas.get(&c.schema_id) else {
            return Err(RecordingError::WrongSchema {
                file,
                topic: c.topic.clone(),
                expected: row.schema_name.to_string(),
                found: if c.schema_id == 0 {
                    "(no schema)".to_string()
                } else {
                    format!("(schema id {} not defined before the channel)", c.schema_id)
                },
            });
        };
        if s.name != row.schema_name {
            return Err(RecordingError::WrongSchema {
                file,
                topic: c.topic.clone(),
                expected: row.schema_name.to_string(),
                found: s.name.clone(),
            });
        }
        if s.encoding != SCHEMA_ENCODING {
            return Err(RecordingError::WrongEncoding {
                file,
                topic: c.topic.clone(),
                what: "schema encoding",
                expected: SCHEMA_ENCODING,
                found: s.encoding.clone(),
            });
        }
        if c.message_encoding != MESSAGE_ENCODING {
            return Err(RecordingError::WrongEncoding {
                file,
                topic: c.topic.clone(),
                what: "message encoding",
                expected: MESSAGE_ENCODING,
                found: c.message_encoding.clone(),
            });
        }
        if s.text.trim().is_empty() {
            self.warn(format!(
                "topic {}: schema `{}` has no text; decoded with the contract's fields",
                c.topic, s.name
            ));
            return Ok(decode(None));
        }
        let m = schema::match_fields(&row, &s.text).map_err(|detail| {
            RecordingError::IncompatibleSchema {
                file: file.clone(),
                topic: c.topic.clone(),
                schema: s.name.clone(),
                detail,
            }
        })?;
        if !m.ignored.is_empty() {
            let ignored = m.ignored.join(", ");
            self.warn(format!(
                "topic {}: fields of the file's schema that the contract does not have there are ignored: {ignored}",
                c.topic
            ));
        }
        Ok(decode(Some(m.n_fields)))
    }

    fn message(&mut self, channel_id: u16, log_time: u64, data: &[u8]) {
        match self.channels.get(&channel_id).copied() {
            Some(ChannelUse::Decode(decode, n)) => decode(self, data, n, log_time),
            Some(ChannelUse::Ignore) => {}
            None => self.problems.add(
                self.source,
                "(unknown channel)",
                format!("message on channel {channel_id} before its channel record; dropped"),
            ),
        }
    }

    /// Handles one framed record (`opcode`, `body`) of the data or summary
    /// section, or of a chunk: `Ok(true)` after the footer (the end), `Err`
    /// when the file breaks the contract; a damaged record is skipped with
    /// a warning.
    fn record(&mut self, opcode: u8, body: &[u8], in_chunk: bool) -> Result<bool, RecordingError> {
        let wanted = match opcode {
            op::SCHEMA | op::CHANNEL | op::MESSAGE => true,
            op::CHUNK | op::METADATA | op::ATTACHMENT | op::FOOTER => !in_chunk,
            // Header, indexes, statistics, data end, unknown opcodes (which
            // MCAP readers must skip): nothing the contract needs.
            _ => false,
        };
        if !wanted {
            return Ok(false);
        }
        if !lengths_fit(opcode, body) {
            self.problems.add(
                self.source,
                "(damaged records)",
                format!(
                    "a record (opcode {opcode:#04x}, {} bytes) has lengths past its end; skipped",
                    body.len()
                ),
            );
            return Ok(false);
        }
        let r = match mcap::parse_record(opcode, body) {
            Ok(r) => r,
            Err(e) => {
                self.problems.add(
                    self.source,
                    "(damaged records)",
                    format!(
                        "a record (opcode {opcode:#04x}, {} bytes) does not parse ({e}); skipped",
                        body.len()
                    ),
                );
                return Ok(false);
            }
        };
        match r {
            Record::Schema { header, data } => {
                self.schemas.insert(
                    header.id,
                    SchemaInfo {
                        name: header.name,
                        encoding: header.encoding,
                        text: String::from_utf8_lossy(&data).into_owned(),
                    },
                );
            }
            // The summary section repeats every channel: decide once.
            Record::Channel(c) if !self.channels.contains_key(&c.id) => {
                let used = self.channel(&c)?;
                self.channels.insert(c.id, used);
            }
            Record::Channel(_) => {}
            Record::Message { header, data } => {
                self.message(header.channel_id, header.log_time, &data);
            }
            Record::Chunk { header, data } => {
                self.chunks += 1;
                match chunk_body(&header, &data) {
                    Ok(body) => {
                        let mut inner = Framing::new(&body, 0);
                        loop {
                            match inner.next() {
                                Frame::Record(o, b) => {
                                    self.record(o, b, true)?;
                                }
                                Frame::End => break,
                                Frame::Cut(e) => {
                                    self.warn(format!(
                                        "chunk {}: {e}; the rest of the chunk is skipped",
                                        self.chunks
                                    ));
                                    break;
                                }
                            }
                        }
                    }
                    Err(e) => self.warn(format!(
                        "chunk {} is damaged ({e}); its messages are skipped",
                        self.chunks
                    )),
                }
            }
            Record::Metadata(m) => {
                self.rec.metadata.insert(m.name, m.metadata);
            }
            Record::Attachment { header, data, .. } => {
                self.rec.attachments.push((header.name, data.into_owned()));
            }
            Record::Footer(_) => {
                self.rec.truncated = false;
                return Ok(true);
            }
            _ => {}
        }
        Ok(false)
    }
}

/// Reads a recording from memory. `source` names it in warnings and errors.
///
/// Errors when the bytes are not MCAP or a contract topic breaks the
/// contract (schema name, encodings, fields); every other problem is a
/// warning in [`Recording::warnings`] (see the module documentation).
pub fn read_recording_bytes(source: &str, bytes: &[u8]) -> Result<Recording, RecordingError> {
    read_bytes(source, bytes, None)
}

fn read_bytes<'s>(
    source: &'s str,
    bytes: &[u8],
    only: Option<&'s [&'s str]>,
) -> Result<Recording, RecordingError> {
    if bytes.len() < mcap::MAGIC.len() || bytes[..mcap::MAGIC.len()] != mcap::MAGIC[..] {
        return Err(RecordingError::NotMcap {
            file: source.to_string(),
        });
    }
    let mut st = State {
        source,
        only,
        schemas: HashMap::new(),
        channels: HashMap::new(),
        rec: Recording {
            source: source.to_string(),
            truncated: true,
            ..Default::default()
        },
        problems: Problems::default(),
        chunks: 0,
    };
    let mut framing = Framing::new(bytes, mcap::MAGIC.len());
    let mut damage: Option<String> = None;
    loop {
        match framing.next() {
            Frame::Record(opcode, body) => {
                if st.record(opcode, body, false)? {
                    break;
                }
            }
            Frame::End => break,
            Frame::Cut(e) => {
                damage = Some(e);
                break;
            }
        }
    }
    let n = st.rec.message_count();
    if let Some(e) = damage {
        st.rec.truncated = true;
        st.warn(format!(
            "truncated after {n} messages: reading stopped at a damaged or cut-off record ({e}); the messages before it are used"
        ));
    } else if st.rec.truncated {
        st.warn(format!(
            "truncated after {n} messages: the file ends without its footer (recorder killed?); the messages of its complete chunks are used"
        ));
    }
    for (topic, count) in &st.problems.count {
        if *count > DETAILED_PER_TOPIC {
            st.problems.warnings.push(format!(
                "{source}: {topic}: {} more messages dropped like those above ({count} in all)",
                count - DETAILED_PER_TOPIC
            ));
        }
    }
    let mut rec = st.rec;
    rec.warnings.extend(st.problems.warnings);
    Ok(rec)
}
