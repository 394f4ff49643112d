//! Round trips through real iceoryx2 shared memory, in one process.

use std::time::Duration;

use exo_messages::SensorSample;
use exo_service_kit::channels::SENSOR;
use exo_service_kit::ipc::Ipc;

fn instance(tag: &str) -> String {
    format!("exotest-{tag}-{}", std::process::id())
}

#[test]
fn sensor_sample_arrives_bit_identical_with_a_wake_up() {
    let inst = instance("pubsub");
    let a = Ipc::open("test_pub", &inst, None).unwrap();
    let b = Ipc::open("test_sub", &inst, None).unwrap();
    let inbox = b.inbox(SENSOR, 4).unwrap();
    let outbox = a.outbox(SENSOR).unwrap();
    let sent = SensorSample {
        seq: 42,
        stamp_ns: 7,
        theta_e: 0.123456789,
        omega_e: -1.5,
        tau_c: f64::MIN_POSITIVE,
        tau_s: 1e300,
        status: 5,
        _pad: 0,
    };
    outbox.send(sent).unwrap();
    let got = inbox
        .recv_timeout(Duration::from_secs(2))
        .unwrap()
        .expect("a sample");
    assert_eq!(got, sent);
    assert_eq!(got.tau_c.to_bits(), sent.tau_c.to_bits());
    assert!(inbox.try_recv().unwrap().is_none());
}

#[test]
fn bounded_wait_returns_none_without_a_publisher_sample() {
    let inst = instance("timeout");
    let b = Ipc::open("test_sub3", &inst, None).unwrap();
    let inbox = b.inbox(SENSOR, 4).unwrap();
    assert!(inbox
        .recv_timeout(Duration::from_millis(20))
        .unwrap()
        .is_none());
}

#[test]
fn missing_config_file_is_named() {
    let err = Ipc::open(
        "test_cfg",
        &instance("cfg"),
        Some(std::path::Path::new("/nonexistent/ice.toml")),
    )
    .err()
    .expect("error");
    assert!(err.to_string().contains("/nonexistent/ice.toml"), "{err}");
}

#[test]
#[ignore = "probe: prints how long a bounded wait with no sample takes"]
fn probe_timed_wait_granularity() {
    let inst = instance("probe");
    let b = Ipc::open("test_probe", &inst, None).unwrap();
    let inbox = b.inbox(SENSOR, 4).unwrap();
    for us in [1u64, 100, 1000, 5000] {
        let t = std::time::Instant::now();
        for _ in 0..20 {
            inbox.wait(Duration::from_micros(us)).unwrap();
        }
        eprintln!("wait({us} µs) took {:?} on average", t.elapsed() / 20);
    }
}

/// A subscriber that connects after samples were published (a restarted
/// recorder) is handed the channel's history only when the publisher
/// connects to it: iceoryx2 does that on the publisher's next send, and
/// in lockstep, while simulated time is held for that subscriber, nobody
/// sends. So a lockstep process whose step waited in vain (`Flow::Idle`)
/// has its ports connected by the runner; in real time the runner leaves
/// them (the next send connects them).
#[test]
fn an_idle_lockstep_step_hands_a_late_subscriber_the_history() {
    use exo_config::TimingMode;
    use exo_service_kit::channels::BUS_SENSOR;
    use exo_service_kit::ipc::Connect;
    use exo_service_kit::runner::on_idle;
    let inst = instance("idle");
    let a = Ipc::open("test_idle_pub", &inst, None).unwrap();
    let b = Ipc::open("test_idle_sub", &inst, None).unwrap();
    let outbox = a.outbox(BUS_SENSOR).unwrap();
    let frame = |seq| exo_messages::BusSensorFrame {
        seq,
        ..Default::default()
    };
    for seq in 0..5 {
        outbox.send(frame(seq)).unwrap();
    }
    let late = b.inbox_with_history(BUS_SENSOR, 64, 64).unwrap();
    let ports: [&dyn Connect; 1] = [&outbox];
    // Nobody sends: the history stays with the publisher.
    on_idle(TimingMode::Realtime, &ports).unwrap();
    late.connect().unwrap();
    assert!(
        late.try_recv().unwrap().is_none(),
        "history before the publisher connected"
    );
    on_idle(TimingMode::Lockstep, &ports).unwrap();
    let got: Vec<u64> = std::iter::from_fn(|| late.try_recv().unwrap())
        .map(|f| f.seq)
        .collect();
    assert_eq!(got, [0, 1, 2, 3, 4]);
}
