//! A process killed with `kill -9` leaves its node and ports in shared
//! memory; `ipc::cleanup_dead_nodes` removes them, so the restarted process
//! gets its port back without anyone cleaning `/dev/shm`.
//!
//! The "process" is this test binary run again as a child (the
//! `child_holds_a_publisher_until_killed` test, which does nothing unless
//! `EXO_DEAD_NODE_CHILD` is set). Both use a configuration with their own
//! root path and prefix, so no other test or process sees this one's nodes.

use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use exo_messages::ipc::{self, ExoNode};
use exo_messages::services::{PubSubQos, STREAM_QOS};
use exo_messages::SensorSample;
use iceoryx2::prelude::{Config, FileName, Path as IoxPath, SemanticString as _};

const CHILD_ENV: &str = "EXO_DEAD_NODE_CHILD";
const SERVICE: &str = "dead/raw";

/// The project's configuration, moved to a root path and prefix of its own.
fn isolated_config(tag: &str) -> Config {
    let mut config = ipc::load_config(std::path::Path::new(ipc::SOURCE_TREE_CONFIG)).expect("load");
    let root = format!("/tmp/exotest-dead-{tag}/");
    config
        .global
        .set_root_path(&IoxPath::new(root.as_bytes()).expect("root path"));
    config.global.prefix =
        FileName::new(format!("exotest_dead_{tag}_").as_bytes()).expect("prefix");
    config
}

/// One publisher only: a dead one blocks its successor until cleaned up.
const ONE_PUBLISHER: PubSubQos = PubSubQos {
    max_publishers: 1,
    ..STREAM_QOS
};

fn open(node: &ExoNode) -> ipc::PubSubService<SensorSample> {
    ipc::open_publish_subscribe_with::<SensorSample>(node, SERVICE, &ONE_PUBLISHER)
        .expect("service")
}

#[test]
fn child_holds_a_publisher_until_killed() {
    let Ok(tag) = std::env::var(CHILD_ENV) else {
        return; // only meaningful as the parent's child
    };
    let config = isolated_config(&tag);
    let node = ipc::open_node_with_config("exotest_dead_child", &config).expect("node");
    let service = open(&node);
    let publisher = service.publisher_builder().create().expect("publisher");
    publisher
        .send_copy(SensorSample {
            seq: 1,
            ..Default::default()
        })
        .expect("send");
    println!("EXO-CHILD-READY");
    std::io::stdout().flush().expect("flush");
    // Bounded: the parent kills us long before this ends.
    std::thread::sleep(Duration::from_secs(30));
}

#[test]
fn a_killed_publisher_is_cleaned_up_and_its_successor_gets_the_port() {
    if std::env::var_os(CHILD_ENV).is_some() {
        return;
    }
    let tag = std::process::id().to_string();
    let config = isolated_config(&tag);
    let node = ipc::open_node_with_config("exotest_dead_parent", &config).expect("node");

    let mut child = Command::new(std::env::current_exe().expect("test binary"))
        .args([
            "child_holds_a_publisher_until_killed",
            "--exact",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_ENV, &tag)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("spawn child");
    let stdout = child.stdout.take().expect("child stdout");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if line.contains("EXO-CHILD-READY") {
                let _ = tx.send(());
            }
        }
    });
    let ready = rx.recv_timeout(Duration::from_secs(20));
    if ready.is_err() {
        let _ = child.kill();
        let _ = child.wait();
        panic!("the child never became ready");
    }

    let service = open(&node);
    let subscriber = service.subscriber_builder().create().expect("subscriber");
    assert!(
        service.publisher_builder().create().is_err(),
        "the child's publisher holds the only slot"
    );

    // kill -9.
    child.kill().expect("SIGKILL");
    child.wait().expect("reap");

    // The dead publisher still holds the slot...
    assert!(
        service.publisher_builder().create().is_err(),
        "a killed publisher is not removed by itself"
    );
    // ...until the dead node is cleaned up.
    let report = ipc::cleanup_dead_nodes(&config).expect("cleanup");
    assert_eq!(report.dead, 1, "{report:?}");
    assert_eq!(report.cleaned, 1, "{report:?}");
    assert_eq!(report.failed, 0, "{report:?}");
    assert!(report.alive >= 1, "this process's node: {report:?}");

    let publisher = service
        .publisher_builder()
        .create()
        .expect("the successor gets the port");
    publisher
        .send_copy(SensorSample {
            seq: 2,
            ..Default::default()
        })
        .expect("send");
    let mut seqs = Vec::new();
    while let Some(s) = subscriber.receive().expect("receive") {
        seqs.push(s.payload().seq);
    }
    assert_eq!(seqs.last(), Some(&2), "{seqs:?}");

    let again = ipc::cleanup_dead_nodes(&config).expect("cleanup");
    assert_eq!((again.dead, again.cleaned), (0, 0), "{again:?}");

    drop((publisher, subscriber, service, node));
    // What iceoryx2 keeps per prefix (its global management segment) and
    // the root directory: this test's own, so removed.
    let _ = std::fs::remove_dir_all(format!("/tmp/exotest-dead-{tag}"));
    if let Ok(entries) = std::fs::read_dir("/dev/shm") {
        let prefix = format!("exotest_dead_{tag}_");
        for e in entries.flatten() {
            if e.file_name().to_string_lossy().starts_with(&prefix) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}
