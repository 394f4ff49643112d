//! Recordings as files: round trips, files cut anywhere or left by a killed
//! writer, damaged bytes, contract violations named, and files written by
//! other MCAP writers (unchunked, uncompressed, lz4).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::io::{Cursor, Seek, SeekFrom, Write};
use std::path::Path;
use std::rc::Rc;

use crate::common::*;
use exo_messages::*;
use exo_recording::*;
use mcap::records::MessageHeader;

#[test]
fn every_message_round_trips_through_a_file() {
    let dir = TempDir::new("round-trip");
    let path = dir.join("sub/full.mcap");
    let f = {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::File::create(&path).unwrap()
    };
    let mut w = RecordingWriter::new(std::io::BufWriter::new(f), &path, 4096).unwrap();
    let e = write_to(&mut w, 2500);
    assert_eq!(w.messages_written() as usize, {
        e.sensor.len()
            + e.command.len()
            + e.protocol.len()
            + e.frf.len()
            + e.estimate.len()
            + e.operator.len()
            + e.bus_sensor.len()
            + e.bus_motor.len()
    });
    w.finish().unwrap();
    let r = read_recording(&path).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert!(!r.truncated);
    assert_same(&r, &e);
    assert_eq!(r.sensor.len(), 2500);
    assert_eq!(r.estimate.len(), 5);
    assert_eq!(r.operator.len(), 3);
    assert_eq!(r.meta("subject"), Some("B"));
    assert_eq!(r.meta("config_toml"), Some(CONFIG));
    assert_eq!(r.metadata["exo.drops"]["exo/command"], "2");
    assert_eq!(r.topics.len(), 8);
    assert!(r.missing_topics().is_empty());
    assert!(r.other_topics.is_empty());
    assert_eq!(r.source, path.display().to_string());
    // The file is chunked, zstd-compressed, with log time = publish time = stamp.
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert!(summary.chunk_indexes.len() > 10);
    assert!(summary
        .chunk_indexes
        .iter()
        .all(|c| c.compression == "zstd"));
    assert_eq!(summary.schemas.len(), 8);
    assert_eq!(summary.channels.len(), 8);
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.log_time, m.publish_time);
        assert_eq!(m.channel.message_encoding, "cdr");
        assert_eq!(m.channel.schema.as_ref().unwrap().encoding, "ros2msg");
        if m.channel.topic == "exo/sensor" {
            let s = SensorSample::decode(&m.data, 0).unwrap();
            assert_eq!(m.log_time, s.stamp_ns);
        }
    }
}

#[test]
fn a_topic_selection_decodes_only_those_topics_and_the_same_values() {
    let dir = TempDir::new("topics");
    let path = dir.join("sel.mcap");
    let mut w = RecordingWriter::create_with_chunk_bytes(&path, 4096).unwrap();
    let e = write_to(&mut w, 500);
    w.finish().unwrap();
    let all = read_recording(&path).unwrap();
    let sel = read_recording_topics(&path, &[SensorSample::TOPIC, ProtocolState::TOPIC]).unwrap();
    assert_eq!(sel.sensor, all.sensor);
    assert_eq!(sel.protocol, all.protocol);
    assert_eq!(sel.sensor.len(), e.sensor.len());
    assert!(sel.command.is_empty() && sel.bus_sensor.is_empty() && sel.estimate.is_empty());
    // Every topic is still listed (and was checked against the contract).
    assert_eq!(sel.topics, all.topics);
    assert_eq!(sel.metadata, all.metadata);
    assert!(sel.warnings.is_empty(), "{:?}", sel.warnings);
}

#[test]
fn create_makes_the_directory_and_a_topic_without_messages_is_listed() {
    let dir = TempDir::new("create");
    let path = dir.join("a/b/c.mcap");
    let mut w = RecordingWriter::create(&path).unwrap();
    w.write(&sample(1)).unwrap();
    w.write(&protocol(1)).unwrap();
    w.finish().unwrap();
    let r = read_recording(&path).unwrap();
    assert_eq!(r.topics, ["exo/sensor", "exo/protocol"]);
    assert!(r.missing_topics().contains(&"exo/command"));
    assert_eq!(r.sensor, [sample(1)]);
    // Unwritable places and missing files are errors naming the file.
    let bad = dir.join("c.mcap/inside.mcap");
    std::fs::write(dir.join("c.mcap"), b"file").unwrap();
    let e = RecordingWriter::create(&bad).err().unwrap();
    assert!(e.to_string().contains("inside.mcap"), "{e}");
    let e = read_recording(&dir.join("missing.mcap")).unwrap_err();
    assert!(e.to_string().contains("missing.mcap"), "{e}");
}

#[test]
fn a_recording_gets_its_name_only_when_complete() {
    let dir = TempDir::new("publish");
    let path = dir.join("run.mcap");
    let partial = exo_recording::segments::partial_path(&path);
    std::fs::write(&path, b"earlier").unwrap();
    // While it is written, the earlier file is as it was and the new
    // recording is its partial file, which a second writer cannot take.
    let mut w = RecordingWriter::create(&path).unwrap();
    w.write(&sample(1)).unwrap();
    w.flush().unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"earlier");
    assert!(partial.exists());
    let e = RecordingWriter::create(&path).err().unwrap().to_string();
    assert!(
        e.contains("run.mcap.partial") && e.contains("another process"),
        "{e}"
    );
    w.finish().unwrap();
    // Finished: renamed over the earlier file in one step.
    assert!(!partial.exists());
    assert_eq!(read_recording(&path).unwrap().sensor, [sample(1)]);
    // A writer that never finishes (its process failed or died) leaves
    // the file at the path untouched.
    let mut w = RecordingWriter::create(&path).unwrap();
    w.write(&sample(2)).unwrap();
    drop(w);
    assert_eq!(read_recording(&path).unwrap().sensor, [sample(1)]);
    assert!(partial.exists());
}

#[test]
fn an_empty_later_segment_is_named_and_skipped() {
    let dir = TempDir::new("emptyseg");
    let path = dir.join("run.mcap");
    let mut w = RecordingWriter::create(&path).unwrap();
    w.write(&sample(1)).unwrap();
    w.finish().unwrap();
    let part2 = dir.join("run-part2.mcap");
    std::fs::write(&part2, b"").unwrap();
    // A segment after the empty one is still part of the run.
    let mut w = RecordingWriter::create(&dir.join("run-part3.mcap")).unwrap();
    w.write(&sample(2)).unwrap();
    w.finish().unwrap();
    let r = read_recording(&path).unwrap();
    assert_eq!(r.sensor, [sample(1), sample(2)]);
    assert!(
        r.warnings
            .iter()
            .any(|w| w.contains("run-part2.mcap") && w.contains("empty")),
        "{:?}",
        r.warnings
    );
    // An empty first segment is not a recording (and is named as such,
    // not as missing).
    std::fs::write(&path, b"").unwrap();
    let e = read_recording(&path).unwrap_err().to_string();
    assert!(e.contains("run.mcap") && !e.contains("No such file"), "{e}");
}

#[test]
fn run_info_needs_a_subject_and_stores_the_config_twice() {
    let mut w = RecordingWriter::new(Cursor::new(Vec::new()), Path::new("mem.mcap"), 4096).unwrap();
    let e = w.write_run_info(&BTreeMap::new(), "x = 1").unwrap_err();
    assert!(
        e.to_string().contains("mem.mcap") && e.to_string().contains("subject"),
        "{e}"
    );
    let meta = [("subject", "C"), ("software_version", "mine")]
        .into_iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    w.write_run_info(&meta, "x = 1\n").unwrap();
    w.finish().unwrap();
}

/// A `Write + Seek` sink whose bytes can be looked at while a writer still
/// owns it: what a file holds when the writing process is killed.
#[derive(Clone, Default)]
struct Shared(Rc<RefCell<Cursor<Vec<u8>>>>);

impl Shared {
    fn snapshot(&self) -> Vec<u8> {
        self.0.borrow().get_ref().clone()
    }
}

impl Write for Shared {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(b)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for Shared {
    fn seek(&mut self, p: SeekFrom) -> std::io::Result<u64> {
        self.0.borrow_mut().seek(p)
    }
}

#[test]
fn a_writer_killed_at_any_moment_loses_well_under_a_second_at_1_khz() {
    // Sensor, command and both bus topics at 1 kHz with the default chunk
    // size; the "kill" copies the bytes written so far at many ticks.
    let sink = Shared::default();
    let mut w =
        RecordingWriter::new(sink.clone(), Path::new("killed.mcap"), DEFAULT_CHUNK_BYTES).unwrap();
    let mut meta = BTreeMap::new();
    meta.insert("subject".to_string(), "K".to_string());
    w.write_run_info(&meta, CONFIG).unwrap();
    let ticks = 4000u64;
    let mut worst_lost = 0u64;
    let mut kills = 0;
    for k in 0..ticks {
        w.write(&bus_sensor(k)).unwrap();
        w.write(&sample(k)).unwrap();
        w.write(&command(k)).unwrap();
        w.write(&bus_motor(k)).unwrap();
        if k % 37 == 36 {
            let bytes = sink.snapshot();
            let r = read_recording_bytes("killed.mcap", &bytes).unwrap();
            assert!(r.truncated);
            assert_eq!(
                r.meta("subject"),
                Some("K"),
                "metadata written before the first chunk survives"
            );
            let n = r.sensor.len() as u64;
            assert!(r
                .sensor
                .iter()
                .enumerate()
                .all(|(i, s)| *s == sample(i as u64)));
            let warning = format!("truncated after {} messages", r.message_count());
            assert!(
                r.warnings.iter().any(|w| w.contains(&warning)),
                "{:?}",
                r.warnings
            );
            worst_lost = worst_lost.max(k + 1 - n);
            kills += 1;
        }
    }
    w.finish().unwrap();
    let bytes = sink.snapshot();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let chunks = summary.chunk_indexes.len() as f64;
    let uncompressed: u64 = summary
        .chunk_indexes
        .iter()
        .map(|c| c.uncompressed_size)
        .sum();
    let secs = ticks as f64 / 1000.0;
    eprintln!(
        "1 kHz, 4 topics: {:.0} kB/s of records, {:.0} kB/s on disk, a chunk every {:.3} s; \
         worst loss over {kills} kills: {worst_lost} ticks",
        uncompressed as f64 / secs / 1e3,
        bytes.len() as f64 / secs / 1e3,
        secs / chunks
    );
    assert!(worst_lost < 500, "a kill lost {worst_lost} ms of samples");
    assert!(secs / chunks < 0.5);
}

/// Messages MCAP's own `MessageStream` yields before it stops at a cut: the
/// independent count of messages in complete chunks.
fn mcap_count_until_error(bytes: &[u8]) -> usize {
    let Ok(stream) =
        mcap::MessageStream::new_with_options(bytes, mcap::read::Options::IgnoreEndMagic.into())
    else {
        return 0;
    };
    stream.take_while(|m| m.is_ok()).count()
}

#[test]
fn a_file_cut_anywhere_reads_its_complete_chunks() {
    let dir = TempDir::new("cut");
    let path = dir.join("cut.mcap");
    let e = write_full(&path, 3000, 8192);
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let mut cuts = vec![0, 8, 9, 20, bytes.len() - 1];
    for c in &summary.chunk_indexes {
        let (s, l) = (c.chunk_start_offset as usize, c.chunk_length as usize);
        cuts.extend([
            s - 1,
            s,
            s + 1,
            s + 9,
            s + l / 2,
            s + l - 1,
            s + l,
            s + l + 1,
        ]);
    }
    for frac in [0.05, 0.33, 0.5, 0.71, 0.99] {
        cuts.push((bytes.len() as f64 * frac) as usize);
    }
    cuts.sort();
    cuts.dedup();
    let mut last = 0;
    for cut in cuts {
        let part = &bytes[..cut];
        let r = match read_recording_bytes("cut.mcap", part) {
            Ok(r) => r,
            Err(err) => {
                assert!(cut < 8, "cut at {cut}: {err}");
                assert!(err.to_string().contains("cut.mcap"));
                continue;
            }
        };
        if !r.truncated {
            // Only the end magic is gone: the footer was read, nothing is lost.
            assert!(cut > bytes.len() - mcap::MAGIC.len(), "cut at {cut}");
            assert_same(&r, &e);
            continue;
        }
        let warning = format!("cut.mcap: truncated after {} messages", r.message_count());
        assert!(
            r.warnings.iter().any(|w| w.contains(&warning)),
            "cut at {cut}: {:?}",
            r.warnings
        );
        assert_eq!(
            r.message_count(),
            mcap_count_until_error(part),
            "cut at {cut}"
        );
        // What survives is a prefix of what was written, growing with the cut.
        assert_eq!(r.sensor[..], e.sensor[..r.sensor.len()]);
        assert_eq!(r.command[..], e.command[..r.command.len()]);
        assert_eq!(r.protocol[..], e.protocol[..r.protocol.len()]);
        assert!(r.message_count() >= last, "cut at {cut}");
        last = r.message_count();
    }
    assert!(
        last > e.sensor.len() * 3,
        "almost everything survives a cut in the summary"
    );
}

#[test]
fn damaged_bytes_give_errors_or_warnings_never_a_panic_nor_silently_wrong_messages() {
    let dir = TempDir::new("corrupt");
    let path = dir.join("corrupt.mcap");
    let e = write_full(&path, 600, 2048);
    let bytes = std::fs::read(&path).unwrap();
    let err = read_recording_bytes("x.mcap", b"not an mcap file at all").unwrap_err();
    assert!(
        err.to_string().contains("x.mcap") && err.to_string().contains("not an MCAP"),
        "{err}"
    );
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    // Random bytes, with and without the magic.
    for i in 0..400 {
        let n = (next() % 4096) as usize;
        let mut b: Vec<u8> = (0..n).map(|_| next() as u8).collect();
        if i % 2 == 0 {
            b.splice(0..0, mcap::MAGIC.iter().copied());
        }
        match read_recording_bytes("random.mcap", &b) {
            Ok(r) => assert!(!r.warnings.is_empty()),
            Err(err) => assert!(err.to_string().contains("random.mcap"), "{err}"),
        }
    }
    // Flipped bytes in a real file.
    let (mut clean, mut warned, mut refused) = (0, 0, 0);
    for _ in 0..400 {
        let mut b = bytes.clone();
        for _ in 0..1 + next() % 4 {
            let i = 8 + (next() as usize) % (b.len() - 8);
            b[i] ^= (next() >> 40) as u8 | 1;
        }
        match read_recording_bytes("flipped.mcap", &b) {
            Ok(r) if r.warnings.is_empty() => {
                // Nothing reported: then every message is what was written.
                assert_eq!(r.sensor, e.sensor);
                assert_eq!(r.command, e.command);
                assert_eq!(r.bus_sensor, e.bus_sensor);
                clean += 1;
            }
            Ok(r) => {
                assert!(r.warnings.iter().all(|w| w.contains("flipped.mcap")));
                warned += 1;
            }
            Err(err) => {
                assert!(err.to_string().contains("flipped.mcap"), "{err}");
                refused += 1;
            }
        }
    }
    eprintln!("flipped bytes: {clean} harmless, {warned} warned, {refused} refused");
    assert!(warned > 100);
}

fn recording_with(
    schema: (&str, &str, &str),
    topic: &str,
    message_encoding: &str,
    payloads: &[Vec<u8>],
) -> Vec<u8> {
    let mut w = mcap::WriteOptions::new()
        .create(Cursor::new(Vec::new()))
        .unwrap();
    let schema_id = if schema.0.is_empty() {
        0
    } else {
        w.add_schema(schema.0, schema.1, schema.2.as_bytes())
            .unwrap()
    };
    let ch = w
        .add_channel(schema_id, topic, message_encoding, &BTreeMap::new())
        .unwrap();
    for (i, p) in payloads.iter().enumerate() {
        let t = 1000 * (i as u64 + 1);
        w.write_to_known_channel(
            &MessageHeader {
                channel_id: ch,
                sequence: i as u32,
                log_time: t,
                publish_time: t,
            },
            p,
        )
        .unwrap();
    }
    w.finish().unwrap();
    w.into_inner().into_inner()
}

#[test]
fn contract_violations_name_the_topic_and_what_was_expected() {
    let payload = vec![sample(1).encode_into(Vec::new())];
    let text = SensorSample::schema();
    type Case<'a> = ((&'a str, &'a str, &'a str), &'a str, &'a [&'a str]);
    let swapped = text.replace(
        "float64 tau_c\nfloat64 tau_s",
        "float64 tau_s\nfloat64 tau_c",
    );
    let cases: [Case; 5] = [
        (
            ("exo_msgs/msg/Sensor", "ros2msg", &text),
            "cdr",
            &[
                "exo/sensor",
                "`exo_msgs/msg/Sensor`",
                "`exo_msgs/msg/SensorSample`",
            ],
        ),
        (
            ("", "", ""),
            "cdr",
            &["exo/sensor", "(no schema)", "SensorSample"],
        ),
        (
            ("exo_msgs/msg/SensorSample", "jsonschema", &text),
            "cdr",
            &["exo/sensor", "schema encoding `jsonschema`", "`ros2msg`"],
        ),
        (
            ("exo_msgs/msg/SensorSample", "ros2msg", &text),
            "json",
            &["exo/sensor", "message encoding `json`", "`cdr`"],
        ),
        (
            ("exo_msgs/msg/SensorSample", "ros2msg", &swapped),
            "cdr",
            &[
                "exo/sensor",
                "field 5 must be `float64 tau_c`",
                "`float64 tau_s`",
            ],
        ),
    ];
    for (schema, enc, needles) in cases {
        let b = recording_with(schema, "exo/sensor", enc, &payload);
        let e = read_recording_bytes("bad.mcap", &b).unwrap_err();
        let s = e.to_string();
        assert!(s.starts_with("bad.mcap: "), "{s}");
        for n in needles {
            assert!(s.contains(n), "`{n}` not in: {s}");
        }
    }
}

#[test]
fn foreign_topics_extra_fields_and_bad_messages_are_warnings() {
    // A ProtocolState writer with its own tenth field instead of stamp_ns.
    let fixed: String = ProtocolState::schema()
        .lines()
        .take(9)
        .map(|l| format!("{l}\n"))
        .collect();
    let text = format!("# by another rig\n{fixed}float64 temperature_c\n");
    let mut p = protocol(2).encode_into(Vec::new());
    p.truncate(68);
    p.extend_from_slice(&36.6f64.to_le_bytes());
    let mut nan = protocol(3);
    nan.alpha = f64::NAN;
    let payloads = vec![p, nan.encode_into(Vec::new()), vec![0, 1, 0, 0, 1]];
    let b = recording_with(
        ("exo_msgs/msg/ProtocolState", "ros2msg", &text),
        "exo/protocol",
        "cdr",
        &payloads,
    );
    let r = read_recording_bytes("rig.mcap", &b).unwrap();
    let expected = ProtocolState {
        stamp_ns: 1000,
        ..protocol(2)
    };
    assert_eq!(r.protocol, [expected], "the stamp is the log time");
    let all = r.warnings.join("\n");
    assert!(
        all.contains("rig.mcap: topic exo/protocol: fields")
            && all.contains("float64 temperature_c"),
        "{all}"
    );
    assert!(
        all.contains(
            "rig.mcap: exo/protocol: message at log time 2000 ns has alpha = NaN; dropped"
        ),
        "{all}"
    );
    assert!(
        all.contains("log time 3000 ns does not decode") && all.contains("`experiment`"),
        "{all}"
    );
    // A topic outside the contract.
    let b = recording_with(
        ("std_msgs/msg/String", "ros2msg", "string data\n"),
        "rosout",
        "cdr",
        &[vec![0, 1, 0, 0]],
    );
    let r = read_recording_bytes("other.mcap", &b).unwrap();
    assert_eq!(r.other_topics, ["rosout"]);
    assert!(r.topics.is_empty());
    assert_eq!(r.missing_topics().len(), 8);
    assert!(
        r.warnings[0].contains("topic rosout is not part of the recording contract"),
        "{:?}",
        r.warnings
    );
    // Many bad messages: three spelled out, the rest counted.
    let payloads: Vec<Vec<u8>> = (0..10).map(|_| vec![0, 1, 0, 0]).collect();
    let b = recording_with(
        (
            "exo_msgs/msg/SensorSample",
            "ros2msg",
            &SensorSample::schema(),
        ),
        "exo/sensor",
        "cdr",
        &payloads,
    );
    let r = read_recording_bytes("short.mcap", &b).unwrap();
    assert_eq!(r.warnings.len(), 4, "{:?}", r.warnings);
    assert!(
        r.warnings[3].contains("7 more messages dropped like those above (10 in all)"),
        "{:?}",
        r.warnings
    );
}

/// Other writers' options: unchunked, uncompressed chunks, lz4 chunks.
pub fn other_writers() -> [(&'static str, mcap::WriteOptions); 3] {
    [
        ("unchunked", mcap::WriteOptions::new().use_chunks(false)),
        (
            "uncompressed",
            mcap::WriteOptions::new()
                .compression(None)
                .chunk_size(Some(3000)),
        ),
        (
            "lz4",
            mcap::WriteOptions::new()
                .compression(Some(mcap::Compression::Lz4))
                .chunk_size(Some(5000)),
        ),
    ]
}

#[test]
fn recordings_of_other_writers_unchunked_uncompressed_or_lz4_are_read() {
    for (name, opts) in other_writers() {
        let mut w = opts.create(Cursor::new(Vec::new())).unwrap();
        let schema = |w: &mut mcap::Writer<_>, n: &str, t: String| {
            w.add_schema(n, "ros2msg", t.as_bytes()).unwrap()
        };
        let s = schema(&mut w, SensorSample::SCHEMA_NAME, SensorSample::schema());
        let p = schema(&mut w, ProtocolState::SCHEMA_NAME, ProtocolState::schema());
        let cs = w
            .add_channel(s, "exo/sensor", "cdr", &BTreeMap::new())
            .unwrap();
        let cp = w
            .add_channel(p, "exo/protocol", "cdr", &BTreeMap::new())
            .unwrap();
        let put = |w: &mut mcap::Writer<_>, ch: u16, t: u64, data: Vec<u8>| {
            w.write_to_known_channel(
                &MessageHeader {
                    channel_id: ch,
                    sequence: 0,
                    log_time: t,
                    publish_time: t,
                },
                &data,
            )
            .unwrap()
        };
        for k in 0..700 {
            put(
                &mut w,
                cs,
                sample(k).stamp_ns,
                sample(k).encode_into(Vec::new()),
            );
            if k % 100 == 0 {
                put(
                    &mut w,
                    cp,
                    protocol(k).stamp_ns,
                    protocol(k).encode_into(Vec::new()),
                );
            }
        }
        w.write_metadata(&mcap::records::Metadata {
            name: "exo".into(),
            metadata: [("subject".to_string(), name.to_string())]
                .into_iter()
                .collect(),
        })
        .unwrap();
        w.finish().unwrap();
        let bytes = w.into_inner().into_inner();
        let r = read_recording_bytes(name, &bytes).unwrap();
        assert!(r.warnings.is_empty(), "{name}: {:?}", r.warnings);
        assert_eq!(r.sensor, (0..700).map(sample).collect::<Vec<_>>(), "{name}");
        assert_eq!(
            r.protocol,
            (0..7).map(|k| protocol(100 * k)).collect::<Vec<_>>(),
            "{name}"
        );
        assert_eq!(r.meta("subject"), Some(name));
        // Cut in the middle, still lenient.
        let half = read_recording_bytes(name, &bytes[..bytes.len() / 2]).unwrap();
        assert!(half.truncated && half.sensor.len() < 700, "{name}");
        assert_eq!(half.sensor[..], r.sensor[..half.sensor.len()]);
    }
}

fn raw(opcode: u8, body: &[u8]) -> Vec<u8> {
    let mut v = vec![opcode];
    v.extend_from_slice(&(body.len() as u64).to_le_bytes());
    v.extend_from_slice(body);
    v
}

fn string(s: &[u8]) -> Vec<u8> {
    let mut v = (s.len() as u32).to_le_bytes().to_vec();
    v.extend_from_slice(s);
    v
}

#[test]
fn records_whose_lengths_lie_are_skipped_without_allocating_or_panicking() {
    // Found by fuzzing: a string length of ~3.7 GB made mcap's parser
    // reserve it; an attachment body too short for its CRC made it slice
    // out of bounds.
    let mut f = mcap::MAGIC.to_vec();
    f.extend(raw(
        0x01,
        &[string(b"ros2"), vec![9, 0, 0, 0xdf], b"exo".to_vec()].concat(),
    ));
    let mut huge = 0xdf00_0009u32.to_le_bytes().to_vec();
    huge.extend_from_slice(b"exo");
    f.extend(raw(0x0C, &[huge, vec![0; 4]].concat()));
    let mut att = vec![0u8; 16];
    att.extend(string(b"config.toml"));
    att.extend(string(b"application/toml"));
    att.extend(&3u64.to_le_bytes());
    att.extend(b"abc"); // no CRC after the data
    f.extend(raw(0x09, &att));
    let mut meta = string(b"exo");
    let map = [string(b"subject"), string(b"Z")].concat();
    meta.extend((map.len() as u32).to_le_bytes());
    meta.extend(map);
    f.extend(raw(0x0C, &meta));
    let r = read_recording_bytes("lies.mcap", &f).unwrap();
    assert_eq!(
        r.meta("subject"),
        Some("Z"),
        "records after the bad ones are read"
    );
    assert!(r.attachments.is_empty());
    let skipped = r
        .warnings
        .iter()
        .filter(|w| {
            w.contains("lies.mcap: (damaged records)") && w.contains("lengths past its end")
        })
        .count();
    assert_eq!(skipped, 2, "{:?}", r.warnings);
    assert!(
        r.truncated
            && r.warnings
                .iter()
                .any(|w| w.contains("truncated after 0 messages"))
    );
}

#[test]
fn a_chunk_whose_records_are_cut_inside_keeps_the_ones_before() {
    let schema = [
        vec![1, 0],
        string(SensorSample::SCHEMA_NAME.as_bytes()),
        string(b"ros2msg"),
        string(SensorSample::schema().as_bytes()),
    ]
    .concat();
    let channel = [
        vec![1, 0, 1, 0],
        string(b"exo/sensor"),
        string(b"cdr"),
        vec![0; 4],
    ]
    .concat();
    let message = |k: u64| {
        let s = sample(k);
        let mut m = vec![1, 0, 0, 0, 0, 0];
        m.extend(s.stamp_ns.to_le_bytes());
        m.extend(s.stamp_ns.to_le_bytes());
        m.extend(s.encode_into(Vec::new()));
        raw(0x05, &m)
    };
    let mut body = [
        raw(0x03, &schema),
        raw(0x04, &channel),
        message(0),
        message(1),
    ]
    .concat();
    let cut = message(2);
    body.extend_from_slice(&cut[..cut.len() - 5]);
    let mut chunk = vec![0u8; 16];
    chunk.extend((body.len() as u64).to_le_bytes());
    chunk.extend(0u32.to_le_bytes()); // no CRC
    chunk.extend(string(b""));
    chunk.extend((body.len() as u64).to_le_bytes());
    chunk.extend(&body);
    let mut f = mcap::MAGIC.to_vec();
    f.extend(raw(0x06, &chunk));
    f.extend(raw(0x05, &[1, 0])); // a message record too short for its header
    let r = read_recording_bytes("inner.mcap", &f).unwrap();
    assert_eq!(r.sensor, [sample(0), sample(1)]);
    assert!(
        r.warnings.iter().any(
            |w| w.contains("inner.mcap: chunk 1: a record (opcode 0x05)")
                && w.contains("the rest of the chunk is skipped")
        ),
        "{:?}",
        r.warnings
    );
    assert!(
        r.warnings.iter().any(|w| w.contains("(damaged records)")),
        "{:?}",
        r.warnings
    );
}
