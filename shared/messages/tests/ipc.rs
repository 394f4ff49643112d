//! Round trips through real iceoryx2 shared memory, in one process. Every
//! test uses its own instance prefix, so parallel tests never collide.

use std::time::{Duration, Instant};

use exo_messages::ipc::{self, Inbox, IpcError, Outbox, Wake};
use exo_messages::services::{self, ServiceKind, SERVICES};
use exo_messages::{
    status, ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, Message,
    OperatorCommand, ProtocolState, SensorSample,
};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::EventId;

fn instance(tag: &str) -> String {
    format!("exotest-{tag}-{}", std::process::id())
}

/// The bytes of a message (no implicit padding, so every byte is initialised).
fn bytes<T: Message>(v: &T) -> Vec<u8> {
    // SAFETY: `T` is `repr(C)`, `Copy`, without implicit padding (pinned by
    // the layout tests), so all `size_of::<T>()` bytes are initialised.
    unsafe { std::slice::from_raw_parts((v as *const T).cast::<u8>(), size_of::<T>()) }.to_vec()
}

fn odd_sample() -> SensorSample {
    SensorSample {
        seq: u64::MAX - 1,
        stamp_ns: 1_234_567_890_123,
        theta_e: 0.123_456_789_012_345_67,
        omega_e: -1.5e-300,
        tau_c: f64::MIN_POSITIVE / 4.0,               // subnormal
        tau_s: f64::from_bits(0x7ff8_dead_beef_0001), // NaN with a payload
        status: status::STALE | status::REPLAY,
        _pad: 0,
    }
}

#[test]
fn sensor_sample_arrives_bit_identical() {
    let inst = instance("pubsub");
    let a = ipc::open_node("exotest_pub", None).expect("node a");
    let b = ipc::open_node("exotest_sub", None).expect("node b");
    let sub_service =
        ipc::open_publish_subscribe::<SensorSample>(&b, services::SENSOR, &inst).expect("open");
    let subscriber = sub_service
        .subscriber_builder()
        .buffer_size(4)
        .create()
        .expect("subscriber");
    let pub_service =
        ipc::open_publish_subscribe::<SensorSample>(&a, services::SENSOR, &inst).expect("open");
    let publisher = pub_service.publisher_builder().create().expect("publisher");

    let sent = odd_sample();
    let delivered = publisher
        .loan_uninit()
        .expect("loan")
        .write_payload(sent)
        .send()
        .expect("send");
    assert_eq!(delivered, 1);
    let sample = subscriber.receive().expect("receive").expect("a sample");
    let got = *sample.payload();
    assert_eq!(bytes(&got), bytes(&sent));
    assert_eq!(got.tau_s.to_bits(), 0x7ff8_dead_beef_0001);
    drop(sample);
    assert!(subscriber.receive().expect("receive").is_none());
}

#[test]
fn outbox_and_inbox_round_trip_with_a_wake_up() {
    // Ports of `ipc::Service` are not `Send`: the receiving process is a
    // thread with its own node and ports.
    let inst = instance("box");
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let receiver = {
        let inst = inst.clone();
        std::thread::spawn(move || {
            let b = ipc::open_node("exotest_box_sub", None).expect("node b");
            let inbox = Inbox::<SensorSample>::open(&b, services::SENSOR, &inst, 4, Wake::Listen)
                .expect("inbox");
            assert!(inbox.listener().is_some());
            ready_tx.send(()).expect("ready");
            let got = inbox.recv_timeout(Duration::from_secs(5)).expect("recv");
            got.map(|g| bytes(&g))
        })
    };
    let a = ipc::open_node("exotest_box_pub", None).expect("node a");
    let outbox = Outbox::<SensorSample>::open(&a, services::SENSOR, &inst).expect("outbox");
    assert_eq!(outbox.service(), format!("{inst}/sensor"));
    assert!(outbox.notifier().is_some());
    ready_rx.recv().expect("receiver ready");
    std::thread::sleep(Duration::from_millis(20)); // let it block in the wait

    let sent = odd_sample();
    assert_eq!(outbox.send(sent).expect("send"), 1);
    let got = receiver.join().expect("receiver thread").expect("a sample");
    assert_eq!(got, bytes(&sent));
}

#[test]
fn event_notify_and_timed_wait_round_trip() {
    let inst = instance("event");
    let a = ipc::open_node("exotest_ev_notify", None).expect("node a");
    let b = ipc::open_node("exotest_ev_listen", None).expect("node b");
    let listener = ipc::open_event(&b, services::COMMAND_EVENT, &inst)
        .expect("open")
        .listener_builder()
        .create()
        .expect("listener");
    let notifier = ipc::open_event(&a, services::COMMAND_EVENT, &inst)
        .expect("open")
        .notifier_builder()
        .create()
        .expect("notifier");

    // Nothing pending: times out with no activation.
    let mut ids = Vec::new();
    let n = listener
        .timed_wait(|e| ids.push(e.id), Duration::from_millis(1))
        .expect("timed_wait");
    assert_eq!((n, ids.len()), (0, 0));

    assert_eq!(
        notifier.notify().expect("notify"),
        1,
        "one listener notified"
    );
    notifier
        .notify_with_custom_event_id(EventId::new(7))
        .expect("notify 7");
    let n = listener
        .timed_wait(|e| ids.push(e.id), Duration::from_secs(2))
        .expect("timed_wait");
    ids.sort_by_key(|id| id.as_value());
    assert_eq!(n, 2);
    assert_eq!(ids, vec![EventId::new(0), EventId::new(7)]);
    assert_eq!(listener.try_wait(|_| {}).expect("try_wait"), 0);

    // Across threads: a listener blocked in timed_wait wakes up when notified.
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let waiter = {
        let inst = inst.clone();
        std::thread::spawn(move || {
            let c = ipc::open_node("exotest_ev_listen2", None).expect("node c");
            let listener = ipc::open_event(&c, services::COMMAND_EVENT, &inst)
                .expect("open")
                .listener_builder()
                .create()
                .expect("listener");
            ready_tx.send(()).expect("ready");
            let t = Instant::now();
            let n = listener
                .timed_wait(|_| {}, Duration::from_secs(5))
                .expect("timed_wait");
            (n, t.elapsed())
        })
    };
    ready_rx.recv().expect("waiter ready");
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(
        notifier.notify().expect("notify"),
        2,
        "both listeners notified"
    );
    let (n, took) = waiter.join().expect("waiter");
    assert_eq!(n, 1);
    assert!(took < Duration::from_secs(4), "woke after {took:?}");
    drop(listener);
}

#[test]
fn inbox_wait_is_bounded_even_for_tiny_timeouts() {
    // iceoryx2 0.10's `Listener::timed_wait` blocks until notified when the
    // timeout is below 1 µs (SO_RCVTIMEO of 0); `Inbox::wait` must not.
    let inst = instance("tiny");
    let node = ipc::open_node("exotest_tiny", None).expect("node");
    let inbox = Inbox::<SensorSample>::open(&node, services::SENSOR, &inst, 2, Wake::Listen)
        .expect("inbox");
    for timeout in [
        Duration::ZERO,
        Duration::from_nanos(1),
        Duration::from_nanos(999),
        Duration::from_micros(100),
    ] {
        let t = Instant::now();
        assert!(!inbox.wait(timeout).expect("wait"));
        assert!(
            t.elapsed() < Duration::from_millis(500),
            "wait({timeout:?}) took {:?}",
            t.elapsed()
        );
    }
    // A polling inbox times out too.
    let polling = Inbox::<ProtocolState>::open(&node, services::PROTOCOL, &inst, 2, Wake::Poll)
        .expect("inbox");
    let t = Instant::now();
    assert_eq!(
        polling
            .recv_timeout(Duration::from_millis(5))
            .expect("recv"),
        None
    );
    assert!(t.elapsed() >= Duration::from_millis(5));
}

#[test]
fn latest_keeps_the_newest_and_counts_the_rest() {
    let inst = instance("latest");
    let node = ipc::open_node("exotest_latest", None).expect("node");
    let inbox = Inbox::<ActuatorCommand>::open(&node, services::COMMAND, &inst, 3, Wake::Poll)
        .expect("inbox");
    let outbox = Outbox::<ActuatorCommand>::open(&node, services::COMMAND, &inst).expect("outbox");
    assert_eq!(inbox.latest().expect("latest"), None);
    for seq in 1..=5 {
        outbox
            .send(ActuatorCommand {
                seq,
                ..Default::default()
            })
            .expect("send");
    }
    // Buffer of 3 with safe overflow: 3, 4, 5 are left; 5 is the newest.
    let (newest, discarded) = inbox.latest().expect("latest").expect("some");
    assert_eq!((newest.seq, discarded), (5, 2));
}

#[test]
fn history_reaches_a_late_subscriber_of_a_state_channel() {
    let inst = instance("history");
    let node = ipc::open_node("exotest_history", None).expect("node");
    let outbox = Outbox::<ProtocolState>::open(&node, services::PROTOCOL, &inst).expect("outbox");
    let state = ProtocolState {
        experiment: 2,
        period: 3,
        ..Default::default()
    };
    outbox.send(state).expect("send");
    let inbox = Inbox::<ProtocolState>::open(&node, services::PROTOCOL, &inst, 4, Wake::Poll)
        .expect("inbox");
    // The history is delivered when the publisher next updates its connections.
    outbox
        .publisher()
        .update_connections()
        .expect("update connections");
    assert_eq!(inbox.try_recv().expect("recv"), Some(state));
}

#[test]
fn every_service_of_the_table_opens_with_its_payload() {
    let inst = instance("all");
    let node = ipc::open_node("exotest_all", None).expect("node");
    fn open<T: Message>(node: &ipc::ExoNode, name: &str, inst: &str) {
        ipc::open_publish_subscribe::<T>(node, name, inst)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    for spec in &SERVICES {
        match spec.kind {
            ServiceKind::Event(_) => {
                ipc::open_event(&node, spec.name, &inst).unwrap_or_else(|e| panic!("{e}"));
            }
            ServiceKind::PublishSubscribe(_) => match spec.payload {
                Some(SensorSample::TYPE_NAME) => open::<SensorSample>(&node, spec.name, &inst),
                Some(ActuatorCommand::TYPE_NAME) => {
                    open::<ActuatorCommand>(&node, spec.name, &inst)
                }
                Some(ProtocolState::TYPE_NAME) => open::<ProtocolState>(&node, spec.name, &inst),
                Some(BusSensorFrame::TYPE_NAME) => open::<BusSensorFrame>(&node, spec.name, &inst),
                Some(BusMotorCommand::TYPE_NAME) => {
                    open::<BusMotorCommand>(&node, spec.name, &inst)
                }
                Some(FrfPoint::TYPE_NAME) => open::<FrfPoint>(&node, spec.name, &inst),
                Some(ImpedanceEstimate::TYPE_NAME) => {
                    open::<ImpedanceEstimate>(&node, spec.name, &inst)
                }
                Some(OperatorCommand::TYPE_NAME) => {
                    open::<OperatorCommand>(&node, spec.name, &inst)
                }
                other => panic!("{}: no test for payload {other:?}", spec.name),
            },
        }
    }
}

#[test]
fn misuse_is_an_error_naming_the_service() {
    let inst = instance("misuse");
    let node = ipc::open_node("exotest_misuse", None).expect("node");
    let e = ipc::open_publish_subscribe::<ActuatorCommand>(&node, services::SENSOR, &inst)
        .expect_err("payload mismatch");
    assert!(matches!(e, IpcError::PayloadMismatch { .. }), "{e}");
    assert!(e.to_string().contains("exo/sensor"), "{e}");
    assert!(e.to_string().contains("exo.ActuatorCommand.v1"), "{e}");

    let e = ipc::open_event(&node, services::SENSOR, &inst).expect_err("wrong pattern");
    assert!(matches!(e, IpcError::WrongPattern { .. }), "{e}");
    let e = ipc::open_event(&node, "exo/nothing", &inst).expect_err("unknown");
    assert!(matches!(e, IpcError::UnknownService { .. }), "{e}");
    let e = Inbox::<ProtocolState>::open(&node, services::PROTOCOL, &inst, 1, Wake::Listen)
        .expect_err("no event on the protocol channel");
    assert!(matches!(e, IpcError::NoWakeEvent { .. }), "{e}");
    assert!(e.to_string().contains("protocol"), "{e}");

    // A service created elsewhere with another layout under the same name.
    let raw = format!("{inst}/raw");
    // (Kept alive: a service whose last owner is dropped is removed.)
    let _existing =
        ipc::open_publish_subscribe_with::<SensorSample>(&node, &raw, &services::STREAM_QOS)
            .expect("create");
    let e = ipc::open_publish_subscribe_with::<ActuatorCommand>(&node, &raw, &services::STREAM_QOS)
        .expect_err("incompatible type");
    assert!(matches!(e, IpcError::Service { .. }), "{e}");
    assert!(e.to_string().contains(&raw), "{e}");

    let e = ipc::open_node(
        "exotest_cfg",
        Some(std::path::Path::new("/nonexistent/ice.toml")),
    )
    .expect_err("missing file");
    assert!(matches!(e, IpcError::Config { .. }), "{e}");
    assert!(e.to_string().contains("/nonexistent/ice.toml"), "{e}");
}
