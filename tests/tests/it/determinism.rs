//! Determinism, proven (issue 20): one run configuration three ways — in
//! one process twice (`exo sim`) and through the five processes in lockstep
//! (`exo run`) — records the same `exo/sensor`, `exo/command`,
//! `exo/protocol`, `exo/identifier/estimate` and `exo/identifier/frf`
//! messages, bit for bit and in order. The expected stream is the other
//! run's, never a stored copy: any difference in a node, in the order the
//! nodes are stepped, or in how the processes hand samples over shows here.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use exo_tests::*;

/// The topics compared: everything the control loop and the identifier
/// publish. (The bus topics are the plant simulator's and the driver's
/// private wire, on which the plant re-sends a frame when an answer is
/// slow to come, so their count depends on the machine's load.)
const TOPICS: [&str; 5] = [
    "exo/sensor",
    "exo/command",
    "exo/protocol",
    "exo/identifier/estimate",
    "exo/identifier/frf",
];

/// The messages of each compared topic, as the raw CDR bytes, in file order.
fn messages_by_topic(path: &Path) -> BTreeMap<String, Vec<Vec<u8>>> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut out: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        if TOPICS.contains(&m.channel.topic.as_str()) {
            out.entry(m.channel.topic.clone())
                .or_default()
                .push(m.data.into_owned());
        }
    }
    out
}

/// Asserts two recordings hold the same messages on every compared topic,
/// naming the first that differs.
fn assert_same(a: &Path, b: &Path) {
    let (ma, mb) = (messages_by_topic(a), messages_by_topic(b));
    for topic in TOPICS {
        let (x, y) = (&ma[topic], &mb[topic]);
        if let Some(i) = (0..x.len().min(y.len())).find(|&i| x[i] != y[i]) {
            panic!(
                "{topic}: message {i} differs between {} and {}",
                a.display(),
                b.display()
            );
        }
        assert_eq!(
            x.len(),
            y.len(),
            "{topic}: {} messages in {}, {} in {}",
            x.len(),
            a.display(),
            y.len(),
            b.display()
        );
    }
}

fn sim(sc: &Scenario, name: &str) -> PathBuf {
    let path = sc.dir.join(name);
    let out = exo(&[
        "sim",
        sc.config.to_str().unwrap(),
        "--no-report",
        "--output",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "exo sim failed:\n{}", stderr(&out));
    path
}

#[test]
fn a_run_records_the_same_messages_in_one_process_and_through_the_processes() {
    let sc = Scenario::new(
        "determinism",
        &[("periods = [1, 4, 7]", "periods = [1, 4]")],
    );
    let first = sim(&sc, "sim-1.mcap");
    let second = sim(&sc, "sim-2.mcap");
    let out = exo(&["run", sc.config.to_str().unwrap(), "--no-report"]);
    assert!(out.status.success(), "exo run failed:\n{}", stderr(&out));
    let processes = stderr(&out)
        .lines()
        .find_map(|l| l.strip_prefix("exo: recording "))
        .map(PathBuf::from)
        .unwrap_or_else(|| panic!("no recording named by exo run:\n{}", stderr(&out)));
    // Something to compare: the identifier fitted both experiments.
    let m = messages_by_topic(&first);
    for topic in TOPICS {
        assert!(!m[topic].is_empty(), "{topic}: no messages");
    }
    assert!(m["exo/sensor"].len() > 50_000, "{}", m["exo/sensor"].len());
    assert_same(&first, &second);
    assert_same(&first, &processes);
}
