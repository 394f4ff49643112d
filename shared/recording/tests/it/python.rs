//! Cross-checks with Python's `mcap` + `mcap-ros2-support`, which share no
//! code with exo: their decoder reads every field of every message we
//! write exactly, and their writer's files are read by our reader. The venv
//! is made once by `tools/python/ensure_venv.sh` (`target/py-venv`); when it
//! cannot be made the tests fail, they never skip.

use std::process::Command;

use crate::common::*;
use exo_recording::cdr::FieldValue;
use exo_recording::*;
use serde_json::Value;

fn py_float(v: &Value) -> f64 {
    v.as_str()
        .unwrap_or_else(|| panic!("float as repr string, got {v}"))
        .parse()
        .unwrap()
}

/// Every field of every message of one topic, compared exactly.
pub(crate) fn compare_topic<T: Recordable>(topics: &Value, ours: &[T]) {
    let t = &topics[T::TOPIC];
    assert_eq!(t["schema"], T::SCHEMA_NAME);
    assert_eq!(t["count"], ours.len(), "{}", T::TOPIC);
    let msgs = t["messages"].as_array().unwrap();
    assert_eq!(msgs.len(), ours.len());
    for (i, (m, o)) in msgs.iter().zip(ours).enumerate() {
        let names: Vec<&str> = T::fields().iter().map(|(n, _)| *n).collect();
        let mut keys: Vec<&str> = m
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .filter(|k| !k.starts_with('_'))
            .collect();
        keys.sort();
        let mut sorted = names.clone();
        sorted.sort();
        assert_eq!(keys, sorted, "{} fields", T::TOPIC);
        for (name, v) in o.field_values() {
            let p = &m[name];
            let ctx = format!("{}[{i}].{name}", T::TOPIC);
            match v {
                FieldValue::Uint(u) => assert_eq!(p.as_u64(), Some(u), "{ctx}"),
                FieldValue::Int(x) => assert_eq!(p.as_i64(), Some(x), "{ctx}"),
                FieldValue::Float(x) => assert_eq!(py_float(p).to_bits(), x.to_bits(), "{ctx}"),
                FieldValue::Floats(xs) => {
                    let ps: Vec<u64> = p
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|x| py_float(x).to_bits())
                        .collect();
                    assert_eq!(
                        ps,
                        xs.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                        "{ctx}"
                    );
                }
            }
        }
        assert_eq!(
            m["_log_time"],
            o.stamp_ns(),
            "{}: log_time = stamp_ns",
            T::TOPIC
        );
        assert_eq!(
            m["_publish_time"],
            o.stamp_ns(),
            "{}: publish_time = stamp_ns",
            T::TOPIC
        );
    }
    assert_eq!(t["first"], msgs[0]);
    assert_eq!(t["last"], msgs[msgs.len() - 1]);
}

#[test]
fn python_mcap_ros2_support_decodes_every_field_of_every_topic_exactly() {
    let dir = TempDir::new("py-check");
    let path = dir.join("py-check.mcap");
    let e = write_full(&path, 1200, 8192);
    let out = Command::new(python())
        .arg(tools_python("read_recording.py"))
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    let t = &v["topics"];
    assert_eq!(t.as_object().unwrap().len(), 8);
    compare_topic(t, &e.sensor);
    compare_topic(t, &e.command);
    compare_topic(t, &e.protocol);
    compare_topic(t, &e.frf);
    compare_topic(t, &e.estimate);
    compare_topic(t, &e.operator);
    compare_topic(t, &e.bus_sensor);
    compare_topic(t, &e.bus_motor);
    for (name, map) in &e.metadata {
        for (k, val) in map {
            assert_eq!(v["metadata"][name][k], val.as_str(), "metadata {name}.{k}");
        }
    }
    assert_eq!(v["attachments"]["config.toml"], CONFIG.len());
}

#[test]
fn recordings_written_by_pythons_mcap_ros2_writer_are_read() {
    let dir = TempDir::new("from-python");
    let mut first: Option<Recording> = None;
    for (compression, chunk) in [("zstd", "1048576"), ("lz4", "20000"), ("none", "5000")] {
        let path = dir.join(&format!("from-python-{compression}.mcap"));
        let out = Command::new(python())
            .arg(tools_python("write_recording.py"))
            .arg(&path)
            .args(["--periods", "2", "--subject", "PY"])
            .args(["--compression", compression, "--chunk-size", chunk])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let r = read_recording(&path).unwrap();
        assert!(r.warnings.is_empty(), "{compression}: {:?}", r.warnings);
        assert!(!r.truncated);
        assert_eq!(r.meta("subject"), Some("PY"));
        assert!(r.meta("config_toml").unwrap().contains("name = \"PY\""));
        assert_eq!(
            r.attachment("config.toml").map(|c| c.len()),
            r.meta("config_toml").map(str::len)
        );
        assert_eq!(r.topics, ["exo/protocol", "exo/sensor", "exo/command"]);
        // 2 periods of 8 s at 1 kHz.
        assert_eq!(r.sensor.len(), 16_000);
        assert_eq!(r.command.len(), 16_000);
        assert_eq!(r.protocol.len(), 7);
        assert!(r
            .sensor
            .iter()
            .enumerate()
            .all(|(i, s)| s.seq == i as u64 && s.stamp_ns == 1_000_000 * i as u64));
        assert!(r
            .command
            .iter()
            .zip(&r.sensor)
            .all(|(c, s)| c.sensor_seq == s.seq && c.tau_d == s.tau_s));
        // The writer leaves out ProtocolState.stamp_ns: it comes from the log time.
        assert_eq!(r.protocol[1].stamp_ns, 2_000_000_000);
        assert_eq!(r.protocol[1].phase, 3);
        assert_eq!(r.protocol[3].omega, 2.0 * 10f64.powf(0.1));
        match &first {
            None => first = Some(r),
            Some(f) => {
                assert_eq!(r.sensor, f.sensor, "{compression}");
                assert_eq!(r.protocol, f.protocol, "{compression}");
            }
        }
    }
}

/// A file its writer never finished (issue 32, item 2), cut in the middle
/// of a chunk, at a chunk's start and inside the summary, is completed by
/// `segments::complete` into a file that Python's `mcap` library opens with
/// `make_reader` (indexed reading: summary, chunk and message indexes,
/// footer) and decodes exactly the messages its complete chunks held; exo's
/// reader reads the same messages, no longer truncated, with the metadata
/// and the configuration attachment written before the cut.
#[test]
fn a_dead_writers_file_is_completed_into_one_pythons_indexed_reader_opens() {
    let dir = TempDir::new("complete");
    let full = dir.join("full.mcap");
    let e = write_full(&full, 1200, 8192);
    let bytes = std::fs::read(&full).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let c = &summary.chunk_indexes[summary.chunk_indexes.len() / 2];
    let (start, len) = (c.chunk_start_offset as usize, c.chunk_length as usize);
    for (i, cut) in [start + len / 2, start, bytes.len() - 30]
        .into_iter()
        .enumerate()
    {
        let dest = dir.join(&format!("cut{i}.mcap"));
        let partial = segments::partial_path(&dest);
        std::fs::write(&partial, &bytes[..cut]).unwrap();
        let before = read_recording_bytes("cut.mcap", &bytes[..cut]).unwrap();
        assert!(before.truncated || cut > bytes.len() - 40, "cut at {cut}");
        if i == 0 {
            // As it was left, the indexed reader does not open it (what a
            // rename alone gave Foxglove and Python's tools).
            let raw = dir.join("raw.mcap");
            std::fs::write(&raw, &bytes[..cut]).unwrap();
            let out = Command::new(python())
                .arg(tools_python("read_recording.py"))
                .arg(&raw)
                .args(["--max", "0"])
                .output()
                .unwrap();
            assert!(!out.status.success(), "Python read a cut file as it was");
        }
        let done = segments::complete(&partial, &dest).unwrap();
        assert!(dest.exists() && !partial.exists(), "cut at {cut}");
        assert_eq!(done.messages, before.message_count(), "cut at {cut}");
        assert!(done.messages > 0 && done.attachments == 1, "{done:?}");
        let after = read_recording(&dest).unwrap();
        assert!(!after.truncated, "cut at {cut}: {:?}", after.warnings);
        assert_eq!(after.sensor, before.sensor);
        assert_eq!(after.command, before.command);
        assert_eq!(after.protocol, before.protocol);
        assert_eq!(after.bus_sensor, before.bus_sensor);
        assert_eq!(after.metadata["exo"], e.metadata["exo"]);
        assert_eq!(after.attachment("config.toml"), Some(e.config.as_bytes()));
        let out = Command::new(python())
            .arg(tools_python("read_recording.py"))
            .arg(&dest)
            .args(["--max", "0"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "cut at {cut}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        let counts: u64 = v["topics"]
            .as_object()
            .unwrap()
            .values()
            .map(|t| t["count"].as_u64().unwrap())
            .sum();
        assert_eq!(counts as usize, before.message_count(), "cut at {cut}");
        assert_eq!(
            v["topics"]["exo/sensor"]["count"].as_u64().unwrap() as usize,
            before.sensor.len()
        );
    }
}
