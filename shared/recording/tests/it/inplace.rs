//! Completing a dead writer's file in place (issue 32, item 2), what
//! `segments::finish_orphans` does where the completed copy does not fit
//! (a full disk). The truth each result is held to is independent of the
//! code under test: the file the `mcap` crate's writer finished (its bytes,
//! its summary), the messages written, exo's lenient reader on the cut
//! bytes (what the complete chunks hold), the `mcap` crate's indexed
//! reading, and Python's `mcap` `make_reader` (indexed reading through the
//! summary), which shares no code with exo.
//! On a full disk: `full_disk.rs`.

use std::path::Path;
use std::process::Command;

use crate::common::*;
use crate::python::compare_topic;
use exo_recording::*;
use serde_json::Value;

/// A finished recording, as the `mcap` crate's writer laid it out.
pub(crate) struct Full {
    pub(crate) bytes: Vec<u8>,
    pub(crate) summary: mcap::Summary,
    pub(crate) e: Expected,
}

pub(crate) fn full(dir: &TempDir, ticks: u64) -> Full {
    let path = dir.join("full.mcap");
    let e = write_full(&path, ticks, 8192);
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    Full { bytes, summary, e }
}

/// Bytes of a Data End record (opcode, length, CRC).
const DATA_END_BYTES: usize = 13;

/// Python's `make_reader` on `path`: every message of every topic decoded
/// (`tools/python/read_recording.py`), or the error it printed.
pub(crate) fn python_read(path: &Path) -> Result<Value, String> {
    let out = Command::new(python())
        .arg(tools_python("read_recording.py"))
        .arg(path)
        .output()
        .unwrap();
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    Ok(serde_json::from_slice(&out.stdout).unwrap())
}

/// Python's `make_reader` on `path` through the summary alone: its
/// statistics' message count, its chunk indexes, and the messages
/// `iter_messages` yields in log-time order (which it orders by the chunk
/// indexes' times).
pub(crate) fn python_indexed(path: &Path) -> Value {
    const SCRIPT: &str = r#"
import json, sys
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    s = r.get_summary()
    times = [m.log_time for _, _, m in r.iter_messages()]
    print(json.dumps({"statistics": s.statistics.message_count,
                      "chunks": len(s.chunk_indexes),
                      "messages": len(times),
                      "in_order": times == sorted(times)}))
"#;
    let out = Command::new(python())
        .args(["-c", SCRIPT])
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}: {}",
        path.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Every topic Python decoded equals the first messages written on it, as
/// many as exo's reader read from the cut bytes (`before`); a topic with
/// none there is absent.
pub(crate) fn python_has_what_was_kept(v: &Value, before: &Recording, e: &Expected) {
    fn topic<T: Recordable + PartialEq + std::fmt::Debug>(t: &Value, kept: &[T], written: &[T]) {
        assert_eq!(kept, &written[..kept.len()], "{}", T::TOPIC);
        if kept.is_empty() {
            assert!(t.get(T::TOPIC).is_none(), "{}: {}", T::TOPIC, t[T::TOPIC]);
        } else {
            compare_topic(t, kept);
        }
    }
    let t = &v["topics"];
    topic(t, &before.sensor, &e.sensor);
    topic(t, &before.command, &e.command);
    topic(t, &before.protocol, &e.protocol);
    topic(t, &before.frf, &e.frf);
    topic(t, &before.estimate, &e.estimate);
    topic(t, &before.operator, &e.operator);
    topic(t, &before.bus_sensor, &e.bus_sensor);
    topic(t, &before.bus_motor, &e.bus_motor);
}

/// The `mcap` crate's indexed reading of `bytes`: every message index
/// entry of every chunk index leads to a message of that channel and log
/// time, and they are as many as the chunks' messages. Returns that count.
pub(crate) fn mcap_indexed_messages(bytes: &[u8]) -> usize {
    let s = mcap::Summary::read(bytes).unwrap().unwrap();
    let mut n = 0;
    for index in &s.chunk_indexes {
        let streamed: Vec<_> = s
            .stream_chunk(bytes, index)
            .unwrap()
            .map(Result::unwrap)
            .collect();
        if index.message_index_offsets.is_empty() {
            assert!(streamed.is_empty(), "{index:?}");
            continue;
        }
        let mut entries = 0;
        for (channel, list) in s.read_message_indexes(bytes, index).unwrap() {
            for entry in list {
                let m = s.seek_message(bytes, index, &entry).unwrap();
                assert_eq!(m.channel.id, channel.id);
                assert_eq!(m.log_time, entry.log_time);
                entries += 1;
            }
        }
        assert_eq!(entries, streamed.len(), "{index:?}");
        n += entries;
    }
    n
}

/// A complete file's CRCs are right (MCAP spec): the Data End record's,
/// of every byte before it; the footer's, of the summary section, the
/// summary offsets and the footer up to its CRC.
pub(crate) fn assert_crcs(bytes: &[u8], what: &str) {
    let footer = mcap::read::footer(bytes).unwrap();
    let data_end = footer.summary_start as usize - DATA_END_BYTES;
    assert_eq!(bytes[data_end], mcap::records::op::DATA_END, "{what}");
    let crc = u32::from_le_bytes(bytes[data_end + 9..data_end + 13].try_into().unwrap());
    assert_eq!(crc, crc32fast::hash(&bytes[..data_end]), "{what}: data CRC");
    let summary = &bytes[footer.summary_start as usize..bytes.len() - 8 - 4];
    assert_eq!(
        footer.summary_crc,
        crc32fast::hash(summary),
        "{what}: summary CRC"
    );
}

/// The messages of the finished file's chunks that a cut at `cut` leaves
/// whole, counted by the `mcap` crate (no code of exo's reading).
pub(crate) fn messages_in_whole_chunks(bytes: &[u8], summary: &mcap::Summary, cut: usize) -> usize {
    summary
        .chunk_indexes
        .iter()
        .filter(|i| (i.chunk_start_offset + i.chunk_length) as usize <= cut)
        .map(|i| summary.stream_chunk(bytes, i).unwrap().count())
        .sum()
}

/// A dead writer's file cut in a chunk, at a chunk's start, in the message
/// indexes after a chunk, in the configuration attachment and in the
/// summary, completed in place: the file keeps its bytes up to the cut
/// record and goes on with what the `mcap` crate's writer writes after
/// them (in the summary: the very file it wrote; after a chunk whose
/// indexes were cut: those indexes, byte for byte); its summary holds the
/// chunk indexes of the complete chunks, as the writer's own summary; the
/// `mcap` crate's indexed reading and Python's `make_reader` (which refused
/// the cut file) read exactly the messages the complete chunks held, with
/// the metadata and attachment written before the cut.
#[test]
fn a_dead_writers_file_completed_in_place_is_one_pythons_indexed_reader_opens() {
    let dir = TempDir::new("in-place");
    let Full { bytes, summary, e } = full(&dir, 1200);
    let c = &summary.chunk_indexes[summary.chunk_indexes.len() / 2];
    let (start, end) = (
        c.chunk_start_offset as usize,
        (c.chunk_start_offset + c.chunk_length) as usize,
    );
    let indexes_end = end + c.message_index_length as usize;
    let attachment = summary.attachment_indexes[0].offset as usize;
    let attachment_end = attachment + summary.attachment_indexes[0].length as usize;
    let drops = summary
        .metadata_indexes
        .iter()
        .find(|m| m.name == DROPS_METADATA)
        .unwrap();
    let drops_end = (drops.offset + drops.length) as usize;
    let data_end = data_end(&bytes);
    // (name, cut, bytes kept as they were, whose bytes follow them)
    let cases = [
        ("in a chunk", start + (end - start) / 2, start, start),
        ("at a chunk's start", start, start, start),
        ("in the message indexes", end + 5, end, indexes_end),
        ("in the attachment", attachment + 10, attachment, attachment),
        ("in the summary", bytes.len() - 30, bytes.len(), bytes.len()),
    ];
    for (name, cut, same_to, tail_from) in cases {
        let dest = dir.join("run.mcap");
        let partial = segments::partial_path(&dest);
        std::fs::write(&partial, &bytes[..cut]).unwrap();
        let before = read_recording_bytes("cut.mcap", &bytes[..cut]).unwrap();
        let done = segments::complete_in_place(&partial, &dest).unwrap();
        assert!(dest.exists() && !partial.exists(), "{name}");
        let after = std::fs::read(&dest).unwrap();
        assert_crcs(&after, name);
        // In place: the bytes before the cut record are untouched, and the
        // data end record follows the records kept (after the indexes
        // written again, equal to the writer's).
        assert_eq!(after[..same_to], bytes[..same_to], "{name}");
        assert_eq!(
            after[same_to..tail_from],
            bytes[same_to..tail_from],
            "{name}"
        );
        if name == "in the summary" {
            assert_eq!(after, bytes, "{name}: the writer's own file");
        } else {
            assert_eq!(after[tail_from], mcap::records::op::DATA_END, "{name}");
        }
        // Its summary: the complete chunks' indexes as the writer made them.
        let s = mcap::Summary::read(&after).unwrap().unwrap();
        let complete: Vec<_> = summary
            .chunk_indexes
            .iter()
            .filter(|i| i.chunk_start_offset + i.chunk_length <= data_end.min(cut) as u64)
            .cloned()
            .collect();
        assert_eq!(s.chunk_indexes, complete, "{name}");
        let n = before.message_count();
        assert_eq!(n, messages_in_whole_chunks(&bytes, &summary, cut), "{name}");
        // The messages start after the attachment.
        assert_eq!(n > 0, cut > attachment_end, "{name}");
        assert_eq!(
            s.stats.as_ref().unwrap().message_count as usize,
            n,
            "{name}"
        );
        assert_eq!(mcap_indexed_messages(&after), n, "{name}");
        assert_eq!(done.messages, n, "{name}");
        // Python: its indexed reader opens it and reads what was kept.
        let v = python_read(&dest).unwrap_or_else(|err| panic!("{name}: {err}"));
        python_has_what_was_kept(&v, &before, &e);
        for (k, val) in &e.metadata["exo"] {
            assert_eq!(v["metadata"]["exo"][k], val.as_str(), "{name}: exo.{k}");
        }
        let attached = usize::from(cut >= attachment_end);
        assert_eq!(done.attachments, attached, "{name}");
        assert_eq!(
            v["attachments"].as_object().unwrap().len(),
            attached,
            "{name}"
        );
        if attached == 1 {
            assert_eq!(v["attachments"]["config.toml"], CONFIG.len(), "{name}");
        }
        let dropped = usize::from(cut >= drops_end);
        assert_eq!(done.metadata, 1 + dropped, "{name}");
        assert_eq!(
            v["metadata"].get(DROPS_METADATA).is_some(),
            dropped == 1,
            "{name}"
        );
        let p = python_indexed(&dest);
        assert_eq!(p["statistics"], n, "{name}: {p}");
        assert_eq!(p["messages"], n, "{name}: {p}");
        assert_eq!(p["chunks"], complete.len(), "{name}: {p}");
        assert_eq!(p["in_order"], true, "{name}: {p}");
        // And exo's reader reads the same, no longer truncated.
        let r = read_recording(&dest).unwrap();
        assert!(!r.truncated, "{name}: {:?}", r.warnings);
        assert_eq!(r.sensor, before.sensor, "{name}");
        assert_eq!(r.bus_motor, before.bus_motor, "{name}");
        std::fs::remove_file(&dest).unwrap();
    }
}

/// Other writers' files, finished by the `mcap` crate's writer: unchunked
/// (schemas, channels and messages outside chunks), uncompressed chunks,
/// lz4 chunks. Cut where their data end record starts, completed in place,
/// each is again the very file the writer wrote; cut in the middle, each
/// is one Python's indexed reader opens, with the messages exo's reader
/// reads from the cut bytes.
#[test]
fn other_writers_files_completed_in_place_are_the_files_they_wrote() {
    use exo_messages::SensorSample;
    let dir = TempDir::new("in-place-others");
    for (name, opts) in crate::files::other_writers() {
        let mut w = opts.create(std::io::Cursor::new(Vec::new())).unwrap();
        let s = w
            .add_schema(
                SensorSample::SCHEMA_NAME,
                "ros2msg",
                SensorSample::schema().as_bytes(),
            )
            .unwrap();
        let ch = w
            .add_channel(s, "exo/sensor", "cdr", &Default::default())
            .unwrap();
        for k in 0..600 {
            let m = sample(k);
            let header = mcap::records::MessageHeader {
                channel_id: ch,
                sequence: k as u32,
                log_time: m.stamp_ns,
                publish_time: m.stamp_ns,
            };
            w.write_to_known_channel(&header, &m.encode_into(Vec::new()))
                .unwrap();
        }
        w.write_metadata(&mcap::records::Metadata {
            name: "exo".into(),
            metadata: [("subject".to_string(), name.to_string())].into(),
        })
        .unwrap();
        w.finish().unwrap();
        let bytes = w.into_inner().into_inner();
        for cut in [data_end(&bytes), data_end(&bytes) / 2] {
            let dest = dir.join(&format!("{name}.mcap"));
            let partial = segments::partial_path(&dest);
            std::fs::write(&partial, &bytes[..cut]).unwrap();
            let before = read_recording_bytes(name, &bytes[..cut]).unwrap();
            let done = segments::complete_in_place(&partial, &dest).unwrap();
            assert_eq!(done.messages, before.message_count(), "{name} {cut}");
            let after = std::fs::read(&dest).unwrap();
            if cut == data_end(&bytes) {
                assert_eq!(after, bytes, "{name}");
            }
            let v = python_read(&dest).unwrap_or_else(|e| panic!("{name} {cut}: {e}"));
            assert!(before.sensor.len() > 100, "{name} {cut}");
            compare_topic(&v["topics"], &before.sensor);
            let p = python_indexed(&dest);
            assert_eq!(p["statistics"], before.message_count(), "{name} {cut}: {p}");
            assert_eq!(p["messages"], before.message_count(), "{name} {cut}: {p}");
        }
    }
}

/// What a writer wrote is kept as it wrote it: message indexes in another
/// order than the channels' (a writer's choice) after the last chunk, and
/// a record of an application's own (opcode 0x80, no body) at the very
/// end, stay byte for byte, and the summary follows them. Zeros after the
/// last record (a power cut that left the file's length ahead of its
/// data) are no record: the summary follows the records before them. A
/// damaged chunk (a flipped byte) before other chunks stays where it is,
/// unindexed, and every chunk after it is indexed.
#[test]
fn a_writers_own_indexes_and_records_are_kept_as_written() {
    let dir = TempDir::new("in-place-as-written");
    let Full { bytes, summary, .. } = full(&dir, 1200);
    let c = &summary.chunk_indexes[summary.chunk_indexes.len() / 2];
    let (end, indexes_end) = (
        (c.chunk_start_offset + c.chunk_length) as usize,
        (c.chunk_start_offset + c.chunk_length + c.message_index_length) as usize,
    );
    // The chunk's message index records, last first.
    let mut records = Vec::new();
    let mut at = end;
    while at < indexes_end {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        records.push(&bytes[at..at + 9 + len]);
        at += 9 + len;
    }
    assert!(records.len() > 2 && at == indexes_end);
    records.reverse();
    let reordered = [&bytes[..end], &records.concat()[..]].concat();
    let private = [&bytes[..indexes_end], &[0x80, 0, 0, 0, 0, 0, 0, 0, 0][..]].concat();
    let zeros = [&bytes[..indexes_end], &[0; 4096][..]].concat();
    let data_end = data_end(&bytes);
    let mut damaged = bytes[..data_end].to_vec();
    damaged[(c.chunk_start_offset + c.chunk_length / 2) as usize] ^= 0xff;
    for (name, partial_bytes, kept) in [
        ("reordered", reordered, indexes_end),
        ("private", private, indexes_end + 9),
        ("zeros", zeros, indexes_end),
        ("damaged chunk", damaged, data_end),
    ] {
        let dest = dir.join("run.mcap");
        let partial = segments::partial_path(&dest);
        std::fs::write(&partial, &partial_bytes).unwrap();
        let before = read_recording_bytes(name, &partial_bytes).unwrap();
        segments::complete_in_place(&partial, &dest).unwrap();
        let after = std::fs::read(&dest).unwrap();
        assert_crcs(&after, name);
        assert_eq!(after[..kept], partial_bytes[..kept], "{name}");
        assert_eq!(after[kept], mcap::records::op::DATA_END, "{name}");
        assert_eq!(mcap_indexed_messages(&after), before.message_count());
        let p = python_indexed(&dest);
        assert_eq!(p["messages"], before.message_count(), "{name}: {p}");
        // The damaged chunk stays where it was, unindexed; exo's reader
        // skips it (as it did before) and reads every other chunk.
        let chunks = mcap::Summary::read(&after).unwrap().unwrap().chunk_indexes;
        if name == "damaged chunk" {
            assert!(before.warnings.iter().any(|w| w.contains("damaged")));
            assert_eq!(chunks.len(), summary.chunk_indexes.len() - 1);
            assert!(!chunks.contains(c));
            let r = read_recording(&dest).unwrap();
            assert_eq!(r.message_count(), before.message_count());
        }
    }
}

/// A file cut before its header is complete, or none at all, keeps nothing
/// and becomes the empty recording the `mcap` crate's writer writes with
/// exo's options, byte for byte.
#[test]
fn a_file_without_a_complete_header_becomes_an_empty_recording() {
    let dir = TempDir::new("in-place-headless");
    let Full { bytes, .. } = full(&dir, 10);
    let mut empty = std::io::Cursor::new(Vec::new());
    RecordingWriter::new(&mut empty, Path::new("empty.mcap"), 8192)
        .unwrap()
        .finish()
        .unwrap();
    let empty = empty.into_inner();
    for cut in [
        &bytes[..0],
        &bytes[..5],
        &bytes[..20],
        &b"not an MCAP file"[..],
    ] {
        let dest = dir.join("run.mcap");
        let partial = segments::partial_path(&dest);
        std::fs::write(&partial, cut).unwrap();
        let done = segments::complete_in_place(&partial, &dest).unwrap();
        assert_eq!(done, segments::Completed::default());
        assert_eq!(std::fs::read(&dest).unwrap(), empty, "{cut:?}");
    }
    let p = python_indexed(&dir.join("run.mcap"));
    assert_eq!(p["messages"], 0, "{p}");
}

/// A partial file its writer still holds is refused, untouched, naming it.
#[test]
fn a_file_a_live_writer_holds_is_not_completed_in_place() {
    let dir = TempDir::new("in-place-held");
    let dest = dir.join("run.mcap");
    let mut w = RecordingWriter::create(&dest).unwrap();
    w.write(&sample(1)).unwrap();
    w.flush().unwrap();
    let partial = segments::partial_path(&dest);
    let was = std::fs::read(&partial).unwrap();
    let e = segments::complete_in_place(&partial, &dest)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("run.mcap.partial") && e.contains("another process"),
        "{e}"
    );
    assert_eq!(std::fs::read(&partial).unwrap(), was);
    assert!(!dest.exists());
    w.finish().unwrap();
}

/// Where a finished file's data section ends (its Data End record starts).
pub(crate) fn data_end(bytes: &[u8]) -> usize {
    mcap::read::footer(bytes).unwrap().summary_start as usize - DATA_END_BYTES
}
