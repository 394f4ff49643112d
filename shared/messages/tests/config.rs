//! The project's iceoryx2 configuration: loaded explicitly, installed as the
//! global one (so iceoryx2 never warns "No config file was loaded"), and free
//! of keys iceoryx2 would silently ignore.
//!
//! Its own test binary: iceoryx2's logger and global configuration are
//! process-wide.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use exo_messages::ipc;
use iceoryx2::prelude::{set_log_level, set_logger, Config, LogLevel, SemanticString as _};

struct Capture;

static LOG: Mutex<Vec<(u8, String)>> = Mutex::new(Vec::new());

impl iceoryx2_log::Log for Capture {
    fn log(
        &self,
        level: LogLevel,
        origin: core::fmt::Arguments,
        formatted_message: core::fmt::Arguments,
    ) {
        let line = format!("{origin} | {formatted_message}");
        LOG.lock()
            .unwrap_or_else(|p| p.into_inner())
            .push((level as u8, line));
    }
}

static CAPTURE: Capture = Capture;

fn source_tree_config() -> PathBuf {
    PathBuf::from(ipc::SOURCE_TREE_CONFIG)
}

#[test]
fn the_project_config_is_loaded_explicitly_and_nothing_warns() {
    assert!(set_logger(&CAPTURE), "the logger is installed first");
    set_log_level(LogLevel::Trace);

    // Where the file comes from: argument, else the environment, else the
    // source tree. (Only this test touches the variable.)
    std::env::remove_var(ipc::CONFIG_ENV);
    assert_eq!(ipc::config_path(None), source_tree_config());
    std::env::set_var(ipc::CONFIG_ENV, "/etc/exo/iceoryx2.toml");
    assert_eq!(
        ipc::config_path(None),
        PathBuf::from("/etc/exo/iceoryx2.toml")
    );
    assert_eq!(
        ipc::config_path(Some(Path::new("/x.toml"))),
        PathBuf::from("/x.toml")
    );
    std::env::set_var(ipc::CONFIG_ENV, "");
    assert_eq!(ipc::config_path(None), source_tree_config());
    std::env::set_var(ipc::CONFIG_ENV, ipc::SOURCE_TREE_CONFIG);

    let node = ipc::open_node("exotest_config", None).expect("node");
    let report = ipc::cleanup_dead_nodes(node.config()).expect("cleanup");
    assert!(report.alive >= 1, "{report:?}");
    // Anything iceoryx2 looks up without an explicit configuration.
    let global = Config::global_config();

    {
        let log = LOG.lock().unwrap_or_else(|p| p.into_inner());
        assert!(
            !log.iter()
                .any(|(_, l)| l.contains("No config file was loaded")),
            "{log:#?}"
        );
        let warnings: Vec<_> = log
            .iter()
            .filter(|(level, _)| *level >= LogLevel::Warn as u8)
            .collect();
        assert!(warnings.is_empty(), "iceoryx2 warned: {warnings:#?}");
        assert!(
            !log.is_empty(),
            "the capture works (iceoryx2 traces node creation)"
        );
    }

    let file = ipc::load_config(&source_tree_config()).expect("load");
    assert_ne!(file, Config::default(), "the file was read");
    assert_eq!(file.global.prefix.as_bytes(), b"exo_");
    assert_eq!(node.config(), &file, "the node runs on the project's file");
    assert_eq!(
        global, &file,
        "the project's file is the global configuration"
    );
}

/// Every leaf `(dotted.key, value)` of a TOML table.
fn leaves(prefix: &str, table: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in table {
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        match v {
            toml::Value::Table(t) => leaves(&key, t, out),
            other => out.push((key, other.clone())),
        }
    }
}

fn get<'a>(table: &'a toml::Table, dotted: &str) -> Option<&'a toml::Value> {
    let mut parts = dotted.split('.');
    let mut v = table.get(parts.next()?)?;
    for p in parts {
        v = v.as_table()?.get(p)?;
    }
    Some(v)
}

#[test]
fn every_key_of_the_project_config_is_one_iceoryx2_reads() {
    let text = std::fs::read_to_string(source_tree_config()).expect("read");
    let written: toml::Table = toml::from_str(&text).expect("valid TOML");
    let loaded = ipc::load_config(&source_tree_config()).expect("load");
    // What iceoryx2 understood, written back out.
    let understood: toml::Table = match toml::Value::try_from(&loaded).expect("serialize") {
        toml::Value::Table(t) => t,
        other => panic!("not a table: {other:?}"),
    };
    let mut keys = Vec::new();
    leaves("", &written, &mut keys);
    assert!(
        keys.len() > 40,
        "the file lists the defaults: {}",
        keys.len()
    );
    for (key, value) in keys {
        match get(&understood, &key) {
            Some(v) => assert_eq!(v, &value, "{key}: iceoryx2 read another value"),
            None => panic!("{key} is not an iceoryx2 0.10 setting (ignored silently)"),
        }
    }
}
