//! Every numeric key of the shipped run file (`configs/default.toml`), its
//! experiment table and its subject, set in turn to NaN, +inf, −inf, 0, a
//! negative value and 1e300: loading either refuses the file with an error
//! naming the file and that key (its dotted path, e.g. `protocol.rest_s`,
//! `experiment[3].alpha`), or accepts it, and then the value lies in the
//! key's documented range. Never a panic. A deterministic walk over every
//! leaf (no random sampling: there are few enough to try them all).
//!
//! The plant model's walk is in `shared/plant-model/src/lib.rs` (exo-config
//! does not load plant models).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use exo_config::{
    configs_dir, range_of, ConfigError, Ranges, RunConfig, EXPERIMENT_RANGES, RUN_RANGES,
    SUBJECT_RANGES,
};
use toml::{Table, Value};

/// The value at a dotted path (with `[i]` indices), mutably.
fn leaf_mut<'a>(doc: &'a mut Table, path: &str) -> &'a mut Value {
    exo_config::toml_paths::leaf_mut(doc, path).unwrap_or_else(|| panic!("no key {path}"))
}

/// The six bad values of a leaf holding `original`.
fn bad_values(original: &Value) -> Vec<Value> {
    let (is_int, magnitude) = match original {
        Value::Integer(i) => (true, (*i as f64).abs()),
        Value::Float(f) => (false, f.abs()),
        _ => unreachable!(),
    };
    let negative = if magnitude > 0.0 { -magnitude } else { -1.0 };
    let mut out = vec![
        Value::Float(f64::NAN),
        Value::Float(f64::INFINITY),
        Value::Float(f64::NEG_INFINITY),
    ];
    if is_int {
        out.push(Value::Integer(0));
        out.push(Value::Integer(negative as i64));
    } else {
        out.push(Value::Float(0.0));
        out.push(Value::Float(negative));
    }
    out.push(Value::Float(1e300));
    out
}

fn as_f64(v: &Value) -> f64 {
    match v {
        Value::Integer(i) => *i as f64,
        Value::Float(f) => *f,
        _ => unreachable!(),
    }
}

/// A scratch copy of the run file and every file it names, laid out as in `configs/`.
struct Scratch {
    dir: PathBuf,
}

impl Scratch {
    fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!(
            "exo-config-bad-values-{tag}-{}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        for sub in ["plants", "subjects"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        let s = Scratch { dir };
        for f in FILES {
            s.restore(f);
        }
        s
    }
    fn restore(&self, name: &str) {
        std::fs::copy(configs_dir().join(name), self.dir.join(name)).unwrap();
    }
    fn run_file(&self) -> PathBuf {
        self.dir.join("default.toml")
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The files walked (relative to `configs/`); the plant model is copied so
/// that the run file's paths resolve.
const FILES: [&str; 4] = [
    "default.toml",
    "experiments.toml",
    "subjects/B.toml",
    "plants/default.toml",
];

fn ranges_of(file: &str) -> Ranges {
    match file {
        "default.toml" => RUN_RANGES,
        "experiments.toml" => EXPERIMENT_RANGES,
        "subjects/B.toml" => SUBJECT_RANGES,
        _ => unreachable!(),
    }
}

/// Whether one of the errors names `file` and `key`.
fn names(err: &ConfigError, file: &Path, key: &str) -> bool {
    let file = file.display().to_string();
    err.each().iter().any(|e| {
        let text = e.to_string();
        text.contains(&file) && text.contains(key)
    })
}

#[test]
fn every_numeric_key_is_refused_by_name_or_accepted_within_its_documented_range() {
    let scratch = Scratch::new("walk");
    assert!(
        RunConfig::from_file(&scratch.run_file()).is_ok(),
        "the shipped files must load"
    );
    let mut failures = Vec::new();
    let mut tried = 0;
    for file in ["default.toml", "experiments.toml", "subjects/B.toml"] {
        let path = scratch.dir.join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        let doc: Table = toml::from_str(&text).unwrap();
        let mut leaves = Vec::new();
        leaves.extend(exo_config::toml_paths::numeric_leaves(&Value::Table(
            doc.clone(),
        )));
        assert!(leaves.len() > 5, "{file}: no numeric keys found");
        for (key, _) in &leaves {
            let original = leaf_mut(&mut doc.clone(), key).clone();
            if range_of(ranges_of(file), key).is_none() {
                failures.push(format!("{file}: {key}: no documented range"));
            }
            for bad in bad_values(&original) {
                tried += 1;
                let mut changed = doc.clone();
                *leaf_mut(&mut changed, key) = bad.clone();
                std::fs::write(&path, toml::to_string(&changed).unwrap()).unwrap();
                let run_file = scratch.run_file();
                let outcome = catch_unwind(AssertUnwindSafe(|| RunConfig::from_file(&run_file)));
                match outcome {
                    Err(_) => failures.push(format!("{file}: {key} = {bad}: panicked")),
                    Ok(Err(e)) => {
                        if !names(&e, &path, key) {
                            failures.push(format!(
                                "{file}: {key} = {bad}: refused without naming the file and key: {e}"
                            ));
                        }
                    }
                    Ok(Ok(_)) => {
                        let v = as_f64(&bad);
                        match range_of(ranges_of(file), key) {
                            Some(r) if r.contains(v) => {}
                            Some(r) => failures.push(format!(
                                "{file}: {key} = {bad}: accepted outside its documented range {r}"
                            )),
                            None => failures.push(format!(
                                "{file}: {key} = {bad}: accepted without a documented range"
                            )),
                        }
                    }
                }
            }
        }
        scratch.restore(file);
    }
    assert!(tried > 500, "only {tried} values tried");
    assert!(
        failures.is_empty(),
        "{} of {tried} bad values mishandled:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn every_error_is_reported_not_only_the_first() {
    let scratch = Scratch::new("all");
    let run = scratch.run_file();
    let text = std::fs::read_to_string(&run)
        .unwrap()
        .replace(
            "rate_hz = 1000.0",
            "rate_hz = 1000.0\nmax_sim_time_s = 1e300",
        )
        .replace("rest_s = 1.0", "rest_s = -1.0")
        .replace("torque_nm = 40.0", "torque_nm = nan")
        .replace("command_deadline_ms = 5.0", "command_deadline_ms = 1e9");
    std::fs::write(&run, text).unwrap();
    let table = scratch.dir.join("experiments.toml");
    let t = std::fs::read_to_string(&table)
        .unwrap()
        .replace("alpha = 2.0", "alpha = 1e300");
    std::fs::write(&table, t).unwrap();
    let err = RunConfig::from_file(&run).unwrap_err();
    for (file, key) in [
        (&run, "run.max_sim_time_s"),
        (&run, "protocol.rest_s"),
        (&run, "controller.limits.torque_nm"),
        (&run, "safety.command_deadline_ms"),
        (&table, "experiment[1].alpha"),
    ] {
        assert!(names(&err, file, key), "{key} not named in:\n{err}");
    }
}

#[test]
fn cross_checks_name_their_keys() {
    let scratch = Scratch::new("cross");
    let run = scratch.run_file();
    let base = std::fs::read_to_string(&run).unwrap();
    let table = scratch.dir.join("experiments.toml");
    let subject = scratch.dir.join("subjects/B.toml");
    let cases: [(&Path, &str, &str, &Path, &str); 8] = [
        // An excitation above the Nyquist frequency of the run's 1 kHz.
        (
            &table,
            "start_omega_rad_s = 4.0",
            "start_omega_rad_s = 5000.0",
            &table,
            "experiment[6].start_omega_rad_s",
        ),
        // Growth over the periods carries period 7 above Nyquist.
        (
            &table,
            "frequency_step = 1.2589254117941673",
            "frequency_step = 4.0",
            &table,
            "start_omega_rad_s",
        ),
        (
            &run,
            "periods = [1, 4, 7]",
            "periods = []",
            &run,
            "protocol.periods",
        ),
        (
            &subject,
            "name = \"B\"",
            "name = \"x/../../escaped\"",
            &subject,
            "name",
        ),
        (
            &run,
            "rest_s = 1.0",
            "rest_s = 1e300",
            &run,
            "protocol.rest_s",
        ),
        (
            &run,
            "[safety]\n",
            "[safety]\nlockstep_timeout_ms = 1e300\n",
            &run,
            "safety.lockstep_timeout_ms",
        ),
        (
            &run,
            "output_dir = \"out/runs\"",
            "output_dir = \"default.toml/sub\"",
            &run,
            "run.output_dir",
        ),
        (
            &run,
            "[controller]\n",
            "[controller]\nkp = 1e300\nf = 0.5\n",
            &run,
            "controller.kp",
        ),
    ];
    for (edit, from, to, file, key) in cases {
        for f in FILES {
            scratch.restore(f);
        }
        let text = std::fs::read_to_string(edit).unwrap();
        assert!(text.contains(from), "{from}");
        std::fs::write(edit, text.replacen(from, to, 1)).unwrap();
        // The output directory is relative to the working directory: make
        // the file it names exist there for the case that needs one.
        let err = if to.contains("default.toml/sub") {
            let rel = base.replace(
                "output_dir = \"out/runs\"",
                &format!("output_dir = \"{}/sub\"", run.display()),
            );
            std::fs::write(&run, rel).unwrap();
            RunConfig::from_file(&run).unwrap_err()
        } else {
            RunConfig::from_file(&run).unwrap_err()
        };
        assert!(names(&err, file, key), "{to}: {key} not named in:\n{err}");
    }
}

/// The watchers' tables: an address that is not an IP address, an endpoint
/// that is not a Zenoh endpoint, a missing Zenoh configuration file and a
/// port that does not fit 16 bits are refused naming their keys; good
/// values load, and the defaults are loopback.
#[test]
fn the_live_view_and_tunnel_tables_name_their_keys() {
    let scratch = Scratch::new("watchers");
    let run = scratch.run_file();
    let base = std::fs::read_to_string(&run).unwrap();
    for (table, key) in [
        ("[live]\naddress = \"localhost\"\n", "live.address"),
        ("[live]\nport = 70000\n", "port"),
        (
            "[tunnel]\nlisten = [\"127.0.0.1:7447\"]\n",
            "tunnel.listen[0]",
        ),
        ("[tunnel]\nlisten = []\n", "tunnel.listen"),
        (
            "[tunnel]\nzenoh_config = \"missing.json5\"\n",
            "tunnel.zenoh_config",
        ),
    ] {
        std::fs::write(&run, format!("{base}\n{table}")).unwrap();
        let err = RunConfig::from_file(&run).expect_err(table);
        assert!(names(&err, &run, key), "{table}: {err}");
    }
    std::fs::write(
        &run,
        format!("{base}\n[live]\naddress = \"0.0.0.0\"\nport = 0\n[tunnel]\nlisten = [\"tcp/0.0.0.0:7447\"]\n"),
    )
    .unwrap();
    let cfg = RunConfig::from_file(&run).unwrap();
    assert_eq!(cfg.live.as_ref().unwrap().address(), "0.0.0.0");
    assert_eq!(cfg.live.as_ref().unwrap().port(), 0);
    let d = exo_config::LiveSettings::default();
    assert_eq!((d.address(), d.port()), ("127.0.0.1", 8765));
    assert_eq!(
        exo_config::TunnelSettings::default().listen(),
        vec!["tcp/127.0.0.1:7447".to_string()]
    );
}
