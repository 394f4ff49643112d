//! The import side of `exo-tunnel` refuses what must not reach this
//! computer's channels: bytes that do not decode, a sample carrying NaN,
//! and a key of no channel. Each is named in the log, counted, and never
//! published; good samples on the same link still arrive, intact.
//!
//! The "exo computer" here is this test's own Zenoh session: it puts
//! whatever a broken or hostile exporter could put on the keys.

use std::time::{Duration, Instant};

use exo_messages::channels::{COMMAND, SENSOR};
use exo_messages::SensorSample;
use exo_recording::Recordable;
use exo_tests::*;
use zenoh::Wait;

fn good(seq: u64) -> SensorSample {
    SensorSample {
        seq,
        stamp_ns: 1_000_000 * seq,
        theta_e: 0.01 * seq as f64,
        omega_e: -0.5,
        tau_c: 1.25,
        tau_s: -3.0,
        ..Default::default()
    }
}

#[test]
fn the_import_refuses_garbage_by_key_and_passes_good_samples() {
    let port = free_tcp_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let remote = format!("garbage{}", std::process::id());
    let config = exo_tunnel::zenoh_config(std::slice::from_ref(&endpoint), &[], None).unwrap();
    let session = zenoh::open(config).wait().unwrap();
    let put = |key: &str, bytes: &[u8]| {
        session
            .put(format!("{remote}/{key}"), bytes.to_vec())
            .wait()
            .unwrap()
    };

    let here = Scenario::new("tunimport", &[]);
    let samples = here.collect(SENSOR);
    let commands = here.collect(COMMAND);
    let mut import = here.spawn(
        "exo-tunnel",
        &["--import-from", &endpoint, "--remote-instance", &remote],
    );

    // Rounds of garbage then one good sample, until good ones arrive (the
    // link comes up at some round; Zenoh drops what it puts before).
    let nan = SensorSample {
        tau_c: f64::NAN,
        ..good(7)
    }
    .encode_into(Vec::new());
    let mut seq = 0;
    let t = Instant::now();
    while samples.snapshot().len() < 3 {
        assert!(
            t.elapsed() < Duration::from_secs(60),
            "no good sample arrived: {}",
            here.log("exo-tunnel")
        );
        put("command", b"\x00\x01 not CDR");
        put("sensor", &nan);
        put("nothing", &good(0).encode_into(Vec::new()));
        seq += 1;
        put("sensor", &good(seq).encode_into(Vec::new()));
        std::thread::sleep(Duration::from_millis(50));
    }
    terminate(&mut import);
    let status = wait_exit(&mut import, Duration::from_secs(30), "exo-tunnel");
    let got = samples.finish();
    assert!(commands.finish().is_empty(), "garbage became a command");
    assert!(status.success(), "{}", here.log("exo-tunnel"));

    // Only good samples, each exactly as put, in order.
    for (i, s) in got.iter().enumerate() {
        assert_eq!(*s, good(s.seq), "sample {i} differs from the one put");
        assert!(i == 0 || s.seq > got[i - 1].seq, "out of order: {got:?}");
    }
    let log = here.log("exo-tunnel");
    for (key, why) in [
        ("command", "refused"),
        ("sensor", "tau_c is NaN"),
        ("nothing", "no channel of exo has this key"),
    ] {
        let line = format!("{remote}/{key}");
        assert!(
            log.lines().any(|l| l.contains(&line) && l.contains(why)),
            "{line} not named with `{why}`: {log}"
        );
    }
    session.close().wait().unwrap();
}
