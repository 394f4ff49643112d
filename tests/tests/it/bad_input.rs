//! Every bad input refused at the boundary, by name (issue 22): each bad
//! run file a tester found goes through `exo run --check` and `exo run`,
//! which must exit non-zero within 30 s naming the key in stderr, without a
//! panic, without writing anything (in particular nothing outside
//! `run.output_dir`) and, for `exo run`, without leaving a service process
//! running. The shipped run file passes `exo run --check`. `exo design`
//! takes the stiffness range as `--k-range MIN,MAX` and names in its errors
//! the flags that were given.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use exo_tests::*;

/// A small protocol, so that nothing slow runs if a bad file got through.
const SMALL: &[(&str, &str)] = &[
    ("periods = [1, 4, 7]", "periods = [1]"),
    ("experiments = [1, 7]", "experiments = [1]"),
];

/// Every file under `dir`, with its size.
fn tree(dir: &Path) -> BTreeSet<(PathBuf, u64)> {
    let mut out = BTreeSet::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            if meta.is_dir() {
                stack.push(p.clone());
            }
            out.insert((p, if meta.is_dir() { 0 } else { meta.len() }));
        }
    }
    out
}

/// Processes whose command line mentions `needle`.
fn processes_mentioning(needle: &str) -> Vec<String> {
    let mut out = Vec::new();
    let me = std::process::id().to_string();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.chars().all(|c| c.is_ascii_digit()) || name == me {
            continue;
        }
        if let Ok(cmd) = std::fs::read(e.path().join("cmdline")) {
            let cmd = String::from_utf8_lossy(&cmd).replace('\0', " ");
            if cmd.contains(needle) {
                out.push(format!("{name}: {cmd}"));
            }
        }
    }
    out
}

/// Runs `exo args…` with a 30 s limit; returns (exit code, stderr).
fn exo_within_30_s(args: &[&str], log: &Path) -> (Option<i32>, String) {
    let err = std::fs::File::create(log).unwrap();
    let mut child = Command::new(workspace_bin("exo"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(err)
        .spawn()
        .unwrap();
    let t = Instant::now();
    let status = wait_exit(
        &mut child,
        Duration::from_secs(30),
        &format!("exo {args:?}"),
    );
    assert!(t.elapsed() < Duration::from_secs(30));
    let text = std::fs::read_to_string(log).unwrap_or_default();
    let _ = std::fs::remove_file(log);
    (status.code(), text)
}

/// One bad run file: the scenario, and the key its refusal must name.
struct Bad {
    sc: Scenario,
    key: &'static str,
}

impl Bad {
    /// The default run (small protocol) with `replacements`, writing into
    /// `<dir>/out`.
    fn new(tag: &str, replacements: &[(&str, &str)], key: &'static str) -> Self {
        let mut all: Vec<(&str, &str)> = SMALL.to_vec();
        all.extend_from_slice(replacements);
        let sc = Scenario::new(tag, &all);
        let out_dir = sc.dir.join("out");
        sc.edit(
            &format!("output_dir = \"{}\"", sc.dir.display()),
            &format!("output_dir = \"{}\"", out_dir.display()),
        );
        Bad { sc, key }
    }

    /// Points the run file at a copy of `configs/<name>` in the scenario
    /// with `from` replaced by `to`.
    fn with_copy(self, name: &str, line_key: &str, from: &str, to: &str) -> Self {
        let text = std::fs::read_to_string(configs_dir().join(name)).unwrap();
        assert!(text.contains(from), "{from} not in {name}");
        let file = name.rsplit('/').next().unwrap();
        let copy = self
            .sc
            .write(&format!("copy-{file}"), &text.replacen(from, to, 1));
        let run = std::fs::read_to_string(&self.sc.config).unwrap();
        let old = run
            .lines()
            .find(|l| l.trim_start().starts_with(line_key))
            .unwrap_or_else(|| panic!("{line_key} not in the run file"))
            .to_string();
        self.sc
            .edit(&old, &format!("{line_key} = \"{}\"", copy.display()));
        self
    }

    /// `exo run --check` and `exo run` both refuse it as the issue asks.
    fn is_refused(&self) {
        let config = self.sc.config.to_str().unwrap().to_string();
        let before = tree(&self.sc.dir);
        let tmp_before = tree_top(&std::env::temp_dir());
        for args in [
            vec!["run", "--check", config.as_str()],
            vec!["run", config.as_str()],
        ] {
            let log = std::env::temp_dir().join(format!(
                "exo-bad-input-{}-{}.log",
                self.sc.instance,
                args.len()
            ));
            let (code, err) = exo_within_30_s(&args, &log);
            let what = format!("exo {} ({})", args.join(" "), self.key);
            assert!(code.is_some(), "{what}: killed by a signal:\n{err}");
            assert_ne!(code, Some(0), "{what}: accepted:\n{err}");
            assert_ne!(code, Some(101), "{what}: panicked:\n{err}");
            assert!(!err.contains("panicked"), "{what}: panicked:\n{err}");
            assert!(
                err.contains(self.key),
                "{what}: the key is not named:\n{err}"
            );
            assert!(
                err.contains("nothing was started"),
                "{what}: not refused before start:\n{err}"
            );
            assert!(
                !err.contains("exo: starting"),
                "{what}: processes were started:\n{err}"
            );
            let left = processes_mentioning(&config);
            assert!(left.is_empty(), "{what}: processes left running: {left:?}");
            assert_eq!(tree(&self.sc.dir), before, "{what}: wrote files");
        }
        let new_in_tmp: Vec<_> = tree_top(&std::env::temp_dir())
            .difference(&tmp_before)
            .filter(|p| p.to_string_lossy().contains("escaped"))
            .cloned()
            .collect();
        assert!(
            new_in_tmp.is_empty(),
            "{}: wrote outside output_dir: {new_in_tmp:?}",
            self.key
        );
    }
}

/// The entries directly in `dir`.
fn tree_top(dir: &Path) -> BTreeSet<PathBuf> {
    std::fs::read_dir(dir)
        .map(|r| r.flatten().map(|e| e.path()).collect())
        .unwrap_or_default()
}

#[test]
fn the_shipped_run_file_passes_the_check() {
    let out = exo(&[
        "run",
        "--check",
        configs_dir().join("default.toml").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = stdout(&out);
    assert!(text.starts_with("ok"), "{text}");
    for what in [
        "default.toml",
        "experiments.toml",
        "subjects/B.toml",
        "plants/default.toml",
        "iceoryx2",
        "output dir",
        "controller",
    ] {
        assert!(
            text.contains(what),
            "{what} not said to be checked:\n{text}"
        );
    }
}

#[test]
fn a_huge_lockstep_timeout_is_refused() {
    Bad::new(
        "blockstep",
        &[("[safety]\n", "[safety]\nlockstep_timeout_ms = 1e300\n")],
        "safety.lockstep_timeout_ms",
    )
    .is_refused();
}

#[test]
fn a_huge_command_deadline_is_refused() {
    Bad::new(
        "bdeadline",
        &[("command_deadline_ms = 5.0", "command_deadline_ms = 1e300")],
        "safety.command_deadline_ms",
    )
    .is_refused();
}

#[test]
fn an_endless_rest_is_refused() {
    Bad::new(
        "brest",
        &[("rest_s = 1.0", "rest_s = 1e300")],
        "protocol.rest_s",
    )
    .is_refused();
}

#[test]
fn an_empty_period_list_is_refused() {
    Bad::new(
        "bperiods",
        &[("periods = [1]", "periods = []")],
        "protocol.periods",
    )
    .is_refused();
}

#[test]
fn a_huge_gain_is_refused() {
    Bad::new(
        "bkp",
        &[("[controller]\n", "[controller]\nkp = 1e300\nf = 0.5\n")],
        "controller.kp",
    )
    .is_refused();
}

#[test]
fn an_unstable_fractional_order_is_refused_naming_the_margin() {
    let bad = Bad::new(
        "bunstable",
        &[("[controller]\n", "[controller]\nkp = 3.2\nf = 0.9\n")],
        "controller.f",
    );
    let out = exo(&["run", "--check", bad.sc.config.to_str().unwrap()]);
    assert!(stderr(&out).contains("phase margin"), "{}", stderr(&out));
    bad.is_refused();
}

#[test]
fn an_excitation_above_nyquist_is_refused() {
    Bad::new("bnyquist", &[], "start_omega_rad_s")
        .with_copy(
            "experiments.toml",
            "experiments_file",
            "start_omega_rad_s = 2.0",
            "start_omega_rad_s = 5000.0",
        )
        .is_refused();
}

#[test]
fn a_subject_name_with_a_path_is_refused() {
    Bad::new("bname", &[], "name")
        .with_copy(
            "subjects/B.toml",
            "subject_file",
            "name = \"B\"",
            "name = \"x/../../escaped\"",
        )
        .is_refused();
}

#[test]
fn a_huge_prony_bank_is_refused() {
    let bad = Bad::new(
        "bprony",
        &[],
        "human.hysteretic_damping.elements_per_decade",
    );
    let plant = std::fs::read_to_string(configs_dir().join("plants/default.toml"))
        .unwrap()
        .replace("mode = \"equivalent_viscous\"", "mode = \"prony\"")
        .replace("elements_per_decade = 3.0", "elements_per_decade = 1e9");
    let copy = bad.sc.write("copy-plant.toml", &plant);
    let run = std::fs::read_to_string(&bad.sc.config).unwrap();
    let old = run
        .lines()
        .find(|l| l.starts_with("plant_model"))
        .unwrap()
        .to_string();
    bad.sc
        .edit(&old, &format!("plant_model = \"{}\"", copy.display()));
    bad.is_refused();
}

#[test]
fn an_output_dir_that_is_a_file_is_refused() {
    let bad = Bad::new("boutfile", &[], "run.output_dir");
    let file = bad.sc.write("a-file", "not a directory\n");
    bad.sc.edit(
        &format!("output_dir = \"{}\"", bad.sc.dir.join("out").display()),
        &format!("output_dir = \"{}\"", file.display()),
    );
    bad.is_refused();
}

#[test]
fn every_error_is_listed_not_only_the_first() {
    let bad = Bad::new(
        "bmany",
        &[
            ("rest_s = 1.0", "rest_s = 1e300"),
            ("command_deadline_ms = 5.0", "command_deadline_ms = nan"),
            ("torque_nm = 40.0", "torque_nm = -1.0"),
        ],
        "protocol.rest_s",
    );
    let out = exo(&["run", "--check", bad.sc.config.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = stderr(&out);
    for key in [
        "protocol.rest_s",
        "safety.command_deadline_ms",
        "controller.limits.torque_nm",
    ] {
        assert!(err.contains(key), "{key} not listed:\n{err}");
    }
    assert!(err.contains("3 errors"), "{err}");
    bad.is_refused();
}

#[test]
fn the_protocol_limits_agree_with_the_protocol_channel() {
    assert_eq!(
        exo_config::MAX_EXPERIMENT,
        exo_messages::protocol::MAX_EXPERIMENT
    );
    assert_eq!(exo_config::MAX_PERIOD, exo_messages::protocol::MAX_PERIOD);
}

#[test]
fn exo_design_takes_the_stiffness_range_in_one_flag() {
    let base = [
        "design", "--f", "0.44", "--kp", "3.2", "--beta0", "-0.21", "--beta1", "1.03", "--json",
    ];
    let reference = exo(&[&base[..], &["--k-min", "10.03", "--k-max", "108.33"]].concat());
    assert!(reference.status.success(), "{}", stderr(&reference));
    for range in [
        vec!["--k-range", "10.03,108.33"],
        vec!["--k-range=10.03,108.33"],
        vec!["--k-range", "10.03", "108.33"],
    ] {
        let o = exo(&[&base[..], &range[..]].concat());
        assert!(o.status.success(), "{range:?}: {}", stderr(&o));
        assert_eq!(stdout(&o), stdout(&reference), "{range:?}");
    }
}

#[test]
fn exo_design_errors_name_the_flags_given() {
    for (args, named, not_named) in [
        // Only --k-max given: the reversed range names it, and the other
        // bound as the default it is.
        (
            vec!["design", "--f", "0.3", "--k-max", "5"],
            vec!["--k-max 5", "the default --k-min 10.03"],
            vec![],
        ),
        (
            vec!["design", "--f", "0.3", "--k-range", "100,10"],
            vec!["--k-range"],
            vec!["--k-min", "--k-max"],
        ),
        (
            vec!["design", "--f", "0.3", "--k-range", "10"],
            vec!["--k-range"],
            vec!["--k-min", "--k-max"],
        ),
        (
            vec![
                "design",
                "--f",
                "0.3",
                "--k-range",
                "10,100",
                "--k-min",
                "5",
            ],
            vec!["--k-range", "--k-min"],
            vec![],
        ),
    ] {
        let o = exo(&args);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} accepted");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        for n in named {
            assert!(err.contains(n), "{args:?} does not name {n}: {err}");
        }
        for n in not_named {
            assert!(!err.contains(n), "{args:?} names {n}, not given: {err}");
        }
    }
}
