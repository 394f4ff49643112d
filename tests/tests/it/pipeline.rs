//! The real processes in closed loop, in lockstep (deterministic, no
//! wall-clock thresholds): the launcher runs a protocol end to end, a NaN
//! reading latches the safe state, a controller killed with SIGKILL brings
//! the driver to its safe state within the deadline plus one tick and can be
//! restarted without anyone cleaning shared memory.

use std::time::Duration;

use exo_messages::{status, ControlMode, ProtocolPhase};
use exo_service_kit::channels::{COMMAND, PROTOCOL, SENSOR};
use exo_tests::*;

const SHORT_RUN: &[(&str, &str)] = &[
    ("periods = [1, 4, 7]", "periods = [1]"),
    ("rest_s = 1.0 ", "rest_s = 0.5 "),
];

#[test]
fn one_experiment_runs_end_to_end_through_the_launcher() {
    let sc = Scenario::new("e2e", SHORT_RUN);
    let protocol = sc.collect(PROTOCOL);
    let commands = sc.collect(COMMAND);
    let out = exo(&["run", sc.config.to_str().unwrap()]);
    assert!(out.status.success(), "exo run failed:\n{}", stderr(&out));
    // The launcher saw the identifier and the recorder open their ports
    // before it started the real-time path (it warns when it gives up).
    assert!(
        !stderr(&out).contains("has not opened its ports"),
        "{}",
        stderr(&out)
    );
    let protocol = protocol.finish();
    let commands = commands.finish();
    // Every phase of period 1 of experiment 1 was reported, with Table I's sine.
    for phase in &ProtocolPhase::ALL[1..] {
        assert!(
            protocol
                .iter()
                .any(|p| p.experiment == 1 && p.period == 1 && p.protocol_phase() == Some(*phase)),
            "phase {phase:?} never reported"
        );
    }
    let sine = protocol
        .iter()
        .find(|p| p.protocol_phase() == Some(ProtocolPhase::Analysis))
        .unwrap();
    assert_eq!((sine.omega, sine.amplitude, sine.alpha), (2.0, 2.0, 1.0));
    // One command per sample, in order, none missing, all in Run mode with
    // finite torque. (A sample re-sent at start-up, before the controller was
    // up, is answered again with the same command: those repeats are dropped.)
    let mut answers = commands.clone();
    answers.dedup_by_key(|c| c.sensor_seq);
    assert!(answers.len() > 20_000, "{} commands", answers.len());
    for (i, c) in answers.iter().enumerate() {
        assert_eq!(
            c.sensor_seq,
            answers[0].sensor_seq + i as u64,
            "gap at command {i}"
        );
        assert!(c.tau_d.is_finite() && c.tau_d.abs() <= 40.0);
    }
    let (run, done) = (Some(ControlMode::Run), Some(ControlMode::Done));
    assert!(commands
        .iter()
        .filter(|c| c.control_mode() != done)
        .all(|c| c.control_mode() == run));
    assert!(
        commands.iter().any(|c| c.tau_excitation.abs() > 1.9),
        "no excitation seen"
    );
    assert!(stderr(&out).contains("protocol done"));
    // The recording and the report are the user's and their group's only.
    use std::os::unix::fs::PermissionsExt;
    let text = stdout(&out);
    for prefix in ["recording:", "report:"] {
        let path = text
            .lines()
            .find_map(|l| l.strip_prefix(prefix))
            .unwrap_or_else(|| panic!("no `{prefix}` line in:\n{text}"))
            .trim();
        let mode = std::fs::metadata(path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode & 0o137, 0, "{path}: mode {mode:o}, at most 0640");
        let dir = std::path::Path::new(path).parent().unwrap();
        if dir != sc.dir.path() {
            let dmode = std::fs::metadata(dir).unwrap().permissions().mode() & 0o777;
            assert_eq!(dmode & 0o027, 0, "{}: mode {dmode:o}", dir.display());
        }
    }
}

#[test]
fn nan_reading_latches_the_safe_state() {
    let sc = Scenario::new("nan", SHORT_RUN);
    let commands = sc.collect(COMMAND);
    let samples = sc.collect(SENSOR);
    let mut procs = vec![
        sc.spawn("exo-plant-sim", &["--inject-fault-at", "3000"]),
        sc.spawn("exo-sensor-driver", &[]),
        sc.spawn("exo-controller", &[]),
    ];
    commands.wait_for(Duration::from_secs(120), "commands past the fault", |c| {
        c.iter().any(|c| c.sensor_seq >= 3500)
    });
    for p in &mut procs {
        terminate(p);
    }
    let commands = commands.finish();
    let samples = samples.finish();
    // The NaN never reached a sample: the driver flags it instead.
    assert!(samples
        .iter()
        .all(|s| s.tau_c.is_finite() && s.theta_e.is_finite()));
    assert!(samples
        .iter()
        .filter(|s| s.seq >= 3000)
        .all(|s| s.status & status::FT_FAULT != 0));
    for c in &commands {
        assert!(c.tau_d.is_finite());
        let expected = if c.sensor_seq < 3000 {
            ControlMode::Run
        } else {
            ControlMode::SafeGravityOnly
        };
        assert_eq!(
            c.control_mode(),
            Some(expected),
            "command for sample {}: mode {}",
            c.sensor_seq,
            c.mode
        );
        if c.sensor_seq >= 3000 {
            assert_eq!(
                (c.tau_amplification, c.tau_excitation, c.tau_bias),
                (0.0, 0.0, 0.0)
            );
        }
    }
    assert!(
        sc.log("exo-controller")
            .contains("safe state latched at sample 3000"),
        "{}",
        sc.log("exo-controller")
    );
}

#[test]
fn killed_controller_brings_the_driver_to_its_safe_state_and_a_restart_works() {
    let sc = Scenario::new("kill", SHORT_RUN);
    let samples = sc.collect(SENSOR);
    let commands = sc.collect(COMMAND);
    // A second subscriber to the commands, finished right after the kill.
    let answered = sc.collect(COMMAND);
    let mut plant = sc.spawn("exo-plant-sim", &[]);
    let mut driver = sc.spawn("exo-sensor-driver", &[]);
    let mut controller = sc.spawn("exo-controller", &[]);
    samples.wait_for(Duration::from_secs(120), "2000 samples", |s| {
        s.iter().any(|s| s.seq >= 2000)
    });
    kill_9(&mut controller);
    // Everything the controller answered before it died, without a wait:
    // `kill_9` has reaped it, so every command it sent is already in this
    // subscriber's queue (a publisher delivers on send), and `finish` halts
    // the collector and drains that queue before returning.
    let last_answered = answered
        .finish()
        .iter()
        .map(|c| c.sensor_seq)
        .max()
        .unwrap();
    samples.wait_for(
        Duration::from_secs(120),
        "3 s of simulated time after the kill",
        |s| s.iter().any(|s| s.seq >= last_answered + 3000),
    );
    let s = samples.snapshot();
    // Frame last+1 goes unanswered: the driver latches there (deadline), and the
    // next sample, last+2, already carries the safe-state flag.
    let first_safe = s
        .iter()
        .find(|s| s.status & status::SAFE_STATE != 0)
        .expect("safe state")
        .seq;
    assert!(
        first_safe <= last_answered + 2,
        "safe state at sample {first_safe}, last answered {last_answered}"
    );
    assert!(sc.log("exo-sensor-driver").contains("safe state latched"));
    // Gravity-only safe state: the arm stays bounded.
    for x in s.iter().filter(|x| x.seq > last_answered) {
        assert!(
            x.theta_e > -0.6 && x.theta_e < 2.6,
            "θ = {} at {}",
            x.theta_e,
            x.seq
        );
    }
    // A controller restarted after kill -9 works without cleaning /dev/shm by hand.
    let before = commands.snapshot().len();
    let mut restarted = sc.spawn("exo-controller", &[]);
    commands.wait_for(
        Duration::from_secs(60),
        "commands from the restarted controller",
        |c| c.len() > before + 100,
    );
    let c = commands.finish();
    assert!(c[before..].iter().all(|c| c.sensor_seq > last_answered));
    for p in [&mut restarted, &mut driver, &mut plant] {
        terminate(p);
    }
}

/// Lockstep is deterministic: the same configuration and seed give
/// bit-identical samples and commands (copper-rs's determinism test, here
/// across separate processes).
#[test]
fn same_seed_gives_bit_identical_runs() {
    let run = |tag: &str| {
        let sc = Scenario::new(tag, SHORT_RUN);
        let samples = sc.collect(SENSOR);
        let commands = sc.collect(COMMAND);
        let out = exo(&["run", sc.config.to_str().unwrap()]);
        assert!(out.status.success(), "{}", stderr(&out));
        let mut s = samples.finish();
        let mut c = commands.finish();
        s.dedup_by_key(|x| x.seq);
        c.dedup_by_key(|x| x.sensor_seq);
        (s, c)
    };
    let (s1, c1) = run("detA");
    let (s2, c2) = run("detB");
    assert_eq!(s1.len(), s2.len());
    assert!(s1.len() > 20_000);
    for (a, b) in s1.iter().zip(&s2) {
        assert_eq!(
            (
                a.seq,
                a.stamp_ns,
                a.theta_e.to_bits(),
                a.tau_c.to_bits(),
                a.tau_s.to_bits()
            ),
            (
                b.seq,
                b.stamp_ns,
                b.theta_e.to_bits(),
                b.tau_c.to_bits(),
                b.tau_s.to_bits()
            ),
            "sample {} differs",
            a.seq
        );
    }
    assert_eq!(c1.len(), c2.len());
    for (a, b) in c1.iter().zip(&c2) {
        assert_eq!(
            (a.sensor_seq, a.tau_d.to_bits()),
            (b.sensor_seq, b.tau_d.to_bits())
        );
    }
}

/// The driver measures its own sensor → controller → driver round trip and
/// writes it on exit when asked: every frame after the first (whose command
/// arms the watchdog) is one round trip, and the percentiles are ordered.
/// In lockstep the count is exact; the durations are not asserted.
#[test]
fn the_driver_reports_its_control_round_trip() {
    let sc = Scenario::new("rtt", SHORT_RUN);
    sc.edit("[run]\n", "[run]\nmax_sim_time_s = 2.0\n");
    let report = sc.dir.join("round-trip.json");
    let samples = sc.collect(SENSOR);
    let mut procs = [
        sc.spawn("exo-plant-sim", &[]),
        sc.spawn(
            "exo-sensor-driver",
            &[
                "--round-trip-report",
                report.to_str().unwrap(),
                "--round-trip-warmup-s",
                "0",
            ],
        ),
        sc.spawn("exo-controller", &[]),
    ];
    let status = wait_exit(&mut procs[0], Duration::from_secs(120), "lockstep plant");
    assert!(status.success(), "{}", sc.log("exo-plant-sim"));
    for p in procs.iter_mut().skip(1) {
        terminate(p);
    }
    let mut s = samples.finish();
    s.dedup_by_key(|x| x.seq);
    let log = sc.log("exo-sensor-driver");
    let text = std::fs::read_to_string(&report)
        .unwrap_or_else(|e| panic!("{}: {e}\n{log}", report.display()));
    let r: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(s.len(), 2000, "frames 0..2000 in 2 s at 1 kHz");
    assert_eq!(r["count"].as_u64(), Some(s.len() as u64 - 1), "{text}");
    assert_eq!(r["skipped"].as_u64(), Some(0));
    let ns = |k: &str| r[k].as_u64().unwrap_or_else(|| panic!("{k} in {text}"));
    assert!(ns("p50_ns") > 0);
    assert!(ns("p50_ns") <= ns("p99_ns") && ns("p99_ns") <= ns("p999_ns"));
    assert!(ns("p999_ns") <= ns("max_ns") + ns("max_ns") / 1000);
    assert!(log.contains("control round trip"), "{log}");
}

/// The driver refuses a negative warm-up before it starts, naming the argument.
#[test]
fn the_driver_names_a_bad_round_trip_warmup() {
    let sc = Scenario::new("rttbad", SHORT_RUN);
    let mut p = sc.spawn("exo-sensor-driver", &["--round-trip-warmup-s=-1"]);
    let status = wait_exit(&mut p, Duration::from_secs(30), "driver");
    assert!(!status.success());
    assert!(
        sc.log("exo-sensor-driver")
            .contains("--round-trip-warmup-s"),
        "{}",
        sc.log("exo-sensor-driver")
    );
}

/// Real-time mode runs the same pipeline on the wall clock (nothing timed is
/// asserted: the machine is shared; the run must simply complete cleanly).
#[test]
fn realtime_mode_runs_and_stops_cleanly() {
    let sc = Scenario::new(
        "rt",
        &[
            ("timing = \"lockstep\"", "timing = \"realtime\""),
            ("periods = [1, 4, 7]", "periods = [1]"),
        ],
    );
    sc.edit("rest_s = 1.0 ", "rest_s = 0.0 ");
    // A one-second protocol: shorten the period by running only part of it.
    sc.edit("[run]\n", "[run]\nmax_sim_time_s = 1.5\n");
    let samples = sc.collect(SENSOR);
    let mut procs = [
        sc.spawn("exo-plant-sim", &[]),
        sc.spawn("exo-sensor-driver", &[]),
        sc.spawn("exo-controller", &[]),
    ];
    let status = wait_exit(
        &mut procs[0],
        std::time::Duration::from_secs(60),
        "real-time plant",
    );
    assert!(status.success(), "{}", sc.log("exo-plant-sim"));
    for p in procs.iter_mut().skip(1) {
        terminate(p);
    }
    let s = samples.finish();
    assert!(s.len() > 1000, "{} samples in 1.5 s at 1 kHz", s.len());
    assert!(
        s.windows(2).all(|w| w[1].stamp_ns >= w[0].stamp_ns),
        "wall-clock stamps go forward"
    );
}

/// In real time with the control path pinned, `exo run` keeps itself (and
/// so the identifier it starts) off the control path's CPU, and says where
/// everything runs. Nothing timed is asserted.
#[test]
fn the_launcher_keeps_off_the_control_path_cpus() {
    let sc = Scenario::new(
        "keepoff",
        &[
            ("timing = \"lockstep\"", "timing = \"realtime\""),
            ("periods = [1, 4, 7]", "periods = [1]"),
            ("recorder = true", "recorder = false"),
        ],
    );
    sc.edit("[run]\n", "[run]\nmax_sim_time_s = 0.5\n");
    sc.append("\n[realtime]\nplant_sim_cpu = 0\nsensor_driver_cpu = 0\ncontroller_cpu = 0\n");
    let out = exo(&["run", sc.config.to_str().unwrap()]);
    let err = stderr(&out);
    // Three processes on one CPU of a shared machine, without SCHED_FIFO,
    // may miss real-time deadlines, and a plant stalled past the bus
    // deadline latches the driver's safe state (seen in CI under load):
    // then the run finishes with those faults named (exit 3). What this
    // test holds is the placement, not the timing: exit 0, or exit 3 with
    // every fault named; never another exit.
    let faults = err.lines().filter(|l| l.starts_with("exo: fault:")).count();
    assert!(
        out.status.success() || (out.status.code() == Some(3) && faults > 0),
        "{err}"
    );
    let cpus = exo_service_kit::allowed_cpus().unwrap();
    let rest: Vec<usize> = cpus.iter().copied().filter(|&c| c != 0).collect();
    let expected = if rest.is_empty() {
        "no CPU left besides the control path's [0]".to_string()
    } else if rest.len() == cpus.len() {
        "the launcher was already confined to other CPUs".to_string()
    } else {
        format!("control path on CPU [0]; launcher, identifier and recorder on CPU {rest:?}")
    };
    assert!(err.contains(&expected), "expected `{expected}` in:\n{err}");
}

/// The pids whose parent is `pid` (from `/proc/*/stat`).
fn children_of(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(child) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{child}/stat")) else {
            continue;
        };
        // pid (comm) state ppid …: the comm may hold spaces, so split after ')'.
        let Some(rest) = stat.rsplit_once(')').map(|(_, r)| r) else {
            continue;
        };
        let ppid = rest.split_whitespace().nth(1).and_then(|p| p.parse().ok());
        if ppid == Some(pid) {
            out.push(child);
        }
    }
    out
}

/// Whether `pid` is alive (a zombie counts as gone: it runs no code).
fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, r)| r.trim_start().starts_with('Z'))
        })
        .is_some_and(|zombie| !zombie)
}

/// kill -9 of `exo run`: every service it started stops too (they get
/// SIGTERM when the supervisor dies) instead of running on as orphans.
/// Waits are bounded and driven by what is observed; the time it takes is
/// for the fault benchmark, not for this test.
#[test]
fn killing_the_launcher_stops_every_service_it_started() {
    // A protocol far longer than the wait below (3000 s of rest between
    // periods), and services that log nothing: a service that writes to the
    // dead launcher's pipe dies of the broken pipe anyway (a panic, not a
    // stop), which would hide a missing death signal.
    let sc = Scenario::new("orphans", &[("rest_s = 1.0", "rest_s = 3000.0")]);
    let mut launcher = std::process::Command::new(workspace_bin("exo"))
        .args(["run", sc.config.to_str().unwrap()])
        .env("RUST_LOG", "off")
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let pid = launcher.id();
    // Wait (bounded) until the five services run and samples flow.
    let samples = sc.collect(SENSOR);
    samples.wait_for(Duration::from_secs(120), "samples", |s| s.len() > 100);
    let services = children_of(pid);
    assert!(services.len() >= 5, "services of exo run: {services:?}");
    kill_9(&mut launcher);
    let _ = launcher.wait();
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    loop {
        let left: Vec<u32> = services.iter().copied().filter(|p| alive(*p)).collect();
        if left.is_empty() {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "services still running 60 s after exo run was killed: {left:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    drop(samples);
}

/// A run that latches its safe state on the way finishes, names the fault
/// and exits with code 3 ("finished with faults"), not 0: through the
/// processes and in one process alike. The angle limit is set below the
/// posture the subject takes in a period, so the controller latches there.
#[test]
fn a_run_that_latches_names_the_fault_and_exits_3() {
    let sc = Scenario::new(
        "latch3",
        &[
            ("periods = [1, 4, 7]", "periods = [1]"),
            ("experiments = [1, 7]", "experiments = [1]"),
            ("theta_rad = [-0.6, 2.6]", "theta_rad = [-0.6, 0.5]"),
        ],
    );
    for args in [
        vec!["run", sc.config.to_str().unwrap(), "--no-report"],
        vec!["sim", sc.config.to_str().unwrap(), "--no-report"],
    ] {
        let out = exo(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(3), "exo {}:\n{err}", args[0]);
        assert!(
            err.contains("exo: fault: the controller commanded its safe state (SafeGravityOnly)"),
            "exo {}:\n{err}",
            args[0]
        );
        assert!(err.contains("the run finished with faults"), "{err}");
        assert!(err.contains("exo: recording "), "{err}");
    }
}

/// A second controller on a running instance is refused at start (the
/// command channel allows one publisher) and exits non-zero naming the
/// channel and the instance, while the first goes on.
#[test]
fn a_second_controller_on_a_running_instance_is_refused() {
    let sc = Scenario::new("second", SHORT_RUN);
    let commands = sc.collect(COMMAND);
    let mut procs = vec![
        sc.spawn("exo-plant-sim", &[]),
        sc.spawn("exo-sensor-driver", &[]),
        sc.spawn("exo-controller", &[]),
    ];
    commands.wait_for(
        Duration::from_secs(120),
        "the first controller's commands",
        |c| c.len() > 100,
    );
    let second_log = sc.dir.join("second-controller.log");
    let mut second = std::process::Command::new(workspace_bin("exo-controller"))
        .arg("--config")
        .arg(&sc.config)
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::null())
        .stderr(std::fs::File::create(&second_log).unwrap())
        .spawn()
        .unwrap();
    let status = wait_exit(
        &mut second,
        Duration::from_secs(60),
        "the second controller",
    );
    let log = std::fs::read_to_string(&second_log).unwrap();
    assert!(!status.success(), "{log}");
    assert!(
        log.contains("already has its publisher (the controller)") && log.contains(&sc.instance),
        "{log}"
    );
    // The first controller still answers.
    let before = commands.snapshot().len();
    commands.wait_for(Duration::from_secs(120), "more commands", |c| {
        c.len() > before + 100
    });
    for p in &mut procs {
        terminate(p);
    }
}
