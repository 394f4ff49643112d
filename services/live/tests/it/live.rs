//! The live view (`exo-live`) with a real client: an independent Python
//! client of the Foxglove WebSocket protocol (`tools/python/live_client.py`,
//! the `websockets` package, none of exo's code) connects during a lockstep
//! run, decodes every message with the advertised ros2msg schemas, and what
//! it decoded is compared with the recording of the same run, sample for
//! sample and bit for bit. Then the bad input: garbage from a client and a
//! subscription to a channel that does not exist are answered with an error
//! and the run goes on; a port in use and an address that cannot be bound
//! stop the live view with a clear error, never the run; a client that
//! stops reading and a live view killed mid-run never disturb control.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

use exo_messages::channels::{CHANNELS, IDENTIFIER_ESTIMATE, SENSOR};
use exo_recording::{FieldValue, Recordable, Recording};
use exo_tests::*;
use serde_json::Value;

/// A short identification run: one experiment, three periods at 7.9, 10
/// and 12.6 rad/s (so a 1 s analysis window holds more than a cycle),
/// short phases: 8.1 s, about 33 000 messages on the four channels
/// published every tick, below the live view's per-client backlog.
fn short_run(tag: &str) -> Scenario {
    Scenario::new(
        tag,
        &[
            ("experiments = [1, 7]", "experiments = [1]"),
            ("periods = [1, 4, 7]", "periods = [7, 8, 9]"),
            (
                "rest_s = 1.0",
                "rest_s = 0.2\nramp_in_s = 0.5\nsettling_s = 0.5\nanalysis_s = 1.0\nramp_out_s = 0.5",
            ),
        ],
    )
}

/// Waits until the identifier has opened its last port (what `exo run`
/// waits for before it starts the control path).
fn wait_for_identifier(sc: &Scenario) {
    let ipc = exo_service_kit::ipc::Ipc::open(
        &format!("live_probe_{}", std::process::id()),
        &sc.instance,
        None,
    )
    .unwrap();
    let t = Instant::now();
    while ipc.port_counts(IDENTIFIER_ESTIMATE).unwrap().publishers == 0 {
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "{}",
            sc.log("exo-identifier")
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Starts `exo-live` and returns it with its WebSocket URL (from its log).
fn start_live(sc: &Scenario) -> (Child, String) {
    let mut child = sc.spawn("exo-live", &[]);
    let t = Instant::now();
    let url = loop {
        let log = sc.log("exo-live");
        if let Some(url) = log.split_whitespace().find(|w| w.starts_with("ws://")) {
            break url.to_string();
        }
        if t.elapsed() > Duration::from_secs(60) {
            kill_9(&mut child);
            panic!("exo-live did not say where it listens: {log}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    (child, url)
}

/// The Python client, started and subscribed to every channel.
struct Client {
    child: Child,
    stdin: Option<ChildStdin>,
    out: std::path::PathBuf,
}

fn start_client(sc: &Scenario, url: &str, name: &str, extra: &[&str]) -> Client {
    let out = sc.dir.join(format!("{name}.json"));
    let err = std::fs::File::create(sc.dir.join(format!("{name}.log"))).unwrap();
    let mut child = Command::new(python())
        .arg(workspace_root().join("tools/python/live_client.py"))
        .arg(url)
        .arg(&out)
        .args(extra)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(err)
        .spawn()
        .expect("starting the Python client");
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert_eq!(
        line.trim(),
        "subscribed",
        "client: {}",
        std::fs::read_to_string(sc.dir.join(format!("{name}.log"))).unwrap_or_default()
    );
    let stdin = child.stdin.take();
    Client { child, stdin, out }
}

impl Client {
    /// Tells the client how many messages to expect per topic and returns
    /// what it wrote.
    fn finish(mut self, expected: &BTreeMap<String, usize>) -> Value {
        let mut stdin = self.stdin.take().unwrap();
        writeln!(stdin, "{}", serde_json::to_string(expected).unwrap()).unwrap();
        drop(stdin);
        let status = wait_exit(&mut self.child, Duration::from_secs(300), "the client");
        assert!(status.success(), "the Python client failed");
        serde_json::from_str(&std::fs::read_to_string(&self.out).unwrap()).unwrap()
    }
}

/// Every message of a recorded topic as `(field, value)` rows.
fn rows<T: Recordable>(v: &[T]) -> Vec<Vec<(&'static str, FieldValue)>> {
    v.iter().map(|m| m.field_values()).collect()
}

fn recorded(r: &Recording) -> BTreeMap<&'static str, Vec<Vec<(&'static str, FieldValue)>>> {
    let mut m = BTreeMap::new();
    m.insert("exo/sensor", rows(&r.sensor));
    m.insert("exo/command", rows(&r.command));
    m.insert("exo/protocol", rows(&r.protocol));
    m.insert("exo/identifier/frf", rows(&r.frf));
    m.insert("exo/identifier/estimate", rows(&r.estimate));
    m.insert("exo/operator", rows(&r.operator));
    m.insert("exo/bus/sensor", rows(&r.bus_sensor));
    m.insert("exo/bus/motor", rows(&r.bus_motor));
    m
}

/// Whether the client's decoded value (float64 as its bits) is the recorded one.
fn same(client: &Value, ours: &FieldValue) -> bool {
    match ours {
        FieldValue::Uint(u) => client.as_u64() == Some(*u),
        FieldValue::Int(i) => client.as_i64() == Some(*i),
        FieldValue::Float(f) => client.as_u64() == Some(f.to_bits()),
        FieldValue::Floats(fs) => client.as_array().is_some_and(|a| {
            a.len() == fs.len()
                && a.iter()
                    .zip(fs)
                    .all(|(c, f)| c.as_u64() == Some(f.to_bits()))
        }),
    }
}

/// A lockstep run with the live view and a recorder; the client's view
/// compared with the recording.
#[test]
fn a_real_client_sees_every_sample_of_the_recording() {
    let sc = short_run("live");
    sc.append("\n[live]\nport = 0\n");
    let rec = sc.dir.join("live.mcap");
    let mut recorder = sc.spawn("exo-recorder", &["--output", rec.to_str().unwrap()]);
    let (mut live, url) = start_live(&sc);
    assert!(
        url.starts_with("ws://127.0.0.1:"),
        "loopback by default: {url}"
    );
    let client = start_client(&sc, &url, "client", &["--float-bits"]);
    let mut identifier = sc.spawn("exo-identifier", &[]);
    wait_for_identifier(&sc);
    // The identifier's last window is published before it stops.
    sc.run_control_path();
    terminate(&mut identifier);
    terminate(&mut recorder);
    let r = exo_recording::read_recording(&rec).unwrap();
    assert!(!r.truncated);
    let ours = recorded(&r);
    let expected: BTreeMap<String, usize> =
        ours.iter().map(|(t, v)| (t.to_string(), v.len())).collect();
    let got = client.finish(&expected);
    terminate(&mut live);

    // Every channel of the recording contract advertised, with the
    // recording's schema names (the operator replies are not in it).
    for c in CHANNELS.iter().filter(|c| c.recorded) {
        assert_eq!(
            got["channels"][c.topic]["schemaName"], c.schema,
            "{}",
            c.topic
        );
    }
    assert_eq!(got["errors"], serde_json::json!([]));
    // The run published on the control path and the identifier.
    let counts: Vec<String> = ours
        .iter()
        .map(|(t, v)| format!("{t} {}", v.len()))
        .collect();
    for topic in [
        "exo/sensor",
        "exo/command",
        "exo/bus/sensor",
        "exo/bus/motor",
    ] {
        assert!(ours[topic].len() > 8000, "{counts:?}");
    }
    // A protocol state at each change of phase.
    assert!(ours["exo/protocol"].len() >= 15, "{counts:?}");
    // An FRF point per analysis window, and the estimates fitted to them.
    assert!(ours["exo/identifier/frf"].len() >= 2, "{counts:?}");
    assert!(!ours["exo/identifier/estimate"].is_empty(), "{counts:?}");
    assert!(ours["exo/sensor"].len() > 5000);
    for (topic, rows) in &ours {
        let theirs = got["messages"][*topic].as_array().unwrap();
        assert_eq!(
            theirs.len(),
            rows.len(),
            "{topic}: the client received {} messages, the recording holds {}",
            theirs.len(),
            rows.len()
        );
        let times = got["log_times"][*topic].as_array().unwrap();
        for (i, (row, msg)) in rows.iter().zip(theirs).enumerate() {
            for (field, value) in row {
                assert!(
                    same(&msg[*field], value),
                    "{topic} message {i} field {field}: client {} recording {value:?}",
                    msg[*field]
                );
            }
            // The live view's log time is the message's stamp, as in the recording.
            assert_eq!(times[i], msg["stamp_ns"], "{topic} message {i}");
        }
    }
    // The live view said what it forwarded.
    assert!(sc.log("exo-live").contains("samples forwarded"));
}

/// Garbage and a subscription to a channel that does not exist get an
/// error each; the server serves that client and the run goes on.
#[test]
fn a_client_sending_garbage_gets_errors_and_the_run_goes_on() {
    let sc = short_run("livebad");
    sc.append("\n[live]\nport = 0\n");
    let (mut live, url) = start_live(&sc);
    let samples = sc.collect(SENSOR);
    let client = start_client(&sc, &url, "bad", &["--bad-input", "--idle", "5"]);
    sc.run_control_path();
    let samples = samples.finish();
    let n = samples.len();
    let got = client.finish(&[("exo/sensor".to_string(), n)].into_iter().collect());
    // Still alive after the garbage: it served the whole run.
    assert!(live.try_wait().unwrap().is_none(), "{}", sc.log("exo-live"));
    terminate(&mut live);
    let statuses: Vec<String> = got["statuses"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["level"] == 2)
        .map(|s| s["message"].as_str().unwrap().to_string())
        .collect();
    assert!(
        statuses.iter().any(|m| m.contains("Invalid message")),
        "{statuses:?}"
    );
    assert!(
        statuses.iter().any(|m| m.contains("Unknown channel ID")),
        "{statuses:?}"
    );
    let log = sc.log("exo-live");
    assert!(log.contains("Invalid message"), "{log}");
    assert!(log.contains("unknown channel"), "{log}");
    // After the garbage the client still received every sample.
    assert_eq!(got["messages"]["exo/sensor"].as_array().unwrap().len(), n);
    assert!(samples.windows(2).all(|w| w[1].seq == w[0].seq + 1));
}

/// The flags of a sample that mean the control path was disturbed.
fn disturbed(s: &exo_messages::SensorSample) -> bool {
    s.status != 0
}

/// A client that stops reading and a live view killed with SIGKILL mid-run
/// never disturb control: the protocol runs to its end, every sample in
/// order, none flagged.
#[test]
fn a_stalled_client_and_a_killed_live_view_never_disturb_control() {
    let sc = short_run("livekill");
    sc.append("\n[live]\nport = 0\n");
    let (mut live, url) = start_live(&sc);
    let samples = sc.collect(SENSOR);
    let mut stalled = start_client(&sc, &url, "stalled", &["--stall"]);
    let mut plant = sc.spawn("exo-plant-sim", &[]);
    let mut driver = sc.spawn("exo-sensor-driver", &[]);
    let mut controller = sc.spawn("exo-controller", &[]);
    samples.wait_for(Duration::from_secs(120), "2 s of samples", |s| {
        s.len() > 2000
    });
    kill_9(&mut live);
    let status = wait_exit(&mut controller, Duration::from_secs(600), "controller");
    assert!(
        status.success(),
        "control was disturbed: {}",
        sc.log("exo-controller")
    );
    terminate(&mut driver);
    terminate(&mut plant);
    drop(stalled.stdin.take());
    kill_9(&mut stalled.child);
    let samples = samples.finish();
    assert!(samples.len() > 5000);
    assert!(samples.windows(2).all(|w| w[1].seq == w[0].seq + 1));
    assert!(
        !samples.iter().any(disturbed),
        "a sample carries a fault flag"
    );
}

/// `exo run` with the live view on a port that is taken: the live view
/// names the port and stops (restarted at most three times, then the run
/// goes on without it), the run goes on to its end with exit 0 (a
/// watcher's stop is no fault of the run). An address that is not this
/// computer's is named the same way.
#[test]
fn a_port_in_use_or_an_unbindable_address_stops_the_live_view_not_the_run() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    for (tag, live) in [
        ("liveport", format!("[live]\nport = {port}\n")),
        // TEST-NET-1 (RFC 5737) is never an address of this computer.
        (
            "liveaddr",
            "[live]\naddress = \"192.0.2.1\"\nport = 0\n".to_string(),
        ),
    ] {
        let sc = short_run(tag);
        sc.edit("recorder = true", "recorder = true\nlive = true");
        sc.append(&format!("\n{live}"));
        let out = Command::new(workspace_bin("exo"))
            .args(["run", sc.config.to_str().unwrap(), "--no-report"])
            .output()
            .unwrap();
        let err = stderr(&out);
        assert!(out.status.success(), "{tag}: the run must go on: {err}");
        let expected = if tag == "liveport" {
            format!("port {port}: the port is in use")
        } else {
            "cannot listen on 192.0.2.1".to_string()
        };
        assert!(err.contains(&expected), "{tag}: {err}");
        // The supervisor said so (how many restarts it saw before the
        // run's end depends on the machine's speed).
        assert!(
            err.contains("exo: live stopped (exit code 1)"),
            "{tag}: {err}"
        );
        // The control path ran to the end of the protocol.
        assert!(err.contains("controller: protocol done"), "{tag}: {err}");
    }
    drop(taken);
}
