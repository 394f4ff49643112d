//! The operator channel end to end: `exo op` (and a raw `OperatorCommand`
//! where the tool would refuse to send one) into the real plant simulator,
//! sensor driver and controller in lockstep. Nothing here depends on wall
//! time: every wait is bounded and ends on what the channels or the logs
//! show, and the assertions are on simulated time (lockstep stamps are
//! exactly `seq` × 1 ms).
//!
//! - `stop` ramps the bias and excitation out over the protocol's ramp-out
//!   and holds gravity compensation in mode Run with no fault; `start`
//!   then continues with the interrupted period.
//! - `start 5` ramps the running period out and runs experiment 5.
//! - `reset` clears the controller's latched fault (an interaction torque
//!   over a lowered limit) and the driver's latched safe state (its
//!   controller killed).
//! - An unknown kind, invalid values and a repeated `seq` are refused with
//!   a log line and change nothing: the run is bit-identical to one without
//!   them.

use std::collections::BTreeMap;
use std::process::Child;
use std::time::{Duration, Instant};

use exo_messages::{
    status, ActuatorCommand, ControlMode, OperatorCommand, OperatorCommandKind, ProtocolPhase,
    ProtocolState, SensorSample,
};
use exo_service_kit::channels::{COMMAND, OPERATOR, PROTOCOL, SENSOR};
use exo_service_kit::ipc::Ipc;
use exo_tests::*;

/// Bound on every wait (the machine may be busy with other tests).
const WAIT: Duration = Duration::from_secs(240);
const RUN: ControlMode = ControlMode::Run;
const SAFE_GRAVITY: ControlMode = ControlMode::SafeGravityOnly;
const IDLE: ProtocolPhase = ProtocolPhase::Idle;
const RAMP_IN: ProtocolPhase = ProtocolPhase::RampIn;
const SETTLING: ProtocolPhase = ProtocolPhase::Settling;
const ANALYSIS: ProtocolPhase = ProtocolPhase::Analysis;
const RAMP_OUT: ProtocolPhase = ProtocolPhase::RampOut;
/// The protocol's ramp-out (configs/experiments.toml), in ns of simulated time.
const RAMP_OUT_NS: u64 = 5_000_000_000;

/// A run over `experiments` and `periods` (replacing the default run
/// file's), with a settling window of 1000 s instead of 5 s: a command
/// sent when the settling is seen arrives in it however busy the machine
/// is (the lockstep runs 10–20 k ticks/s here, so that is a minute or more
/// of wall time; the tests never wait for its end).
fn scenario(tag: &str, experiments: &str, periods: &str) -> Scenario {
    let sc = Scenario::new(
        tag,
        &[
            ("experiments = [1, 7]", experiments),
            ("periods = [1, 4, 7]", periods),
        ],
    );
    let table = std::fs::read_to_string(configs_dir().join("experiments.toml"))
        .unwrap()
        .replacen("settling_s = 5.0", "settling_s = 1000.0", 1);
    let path = sc.write("experiments.toml", &table);
    sc.edit(
        &format!("\"{}/experiments.toml\"", configs_dir().display()),
        &format!("\"{}\"", path.display()),
    );
    sc
}

/// The real-time path of a scenario, stopped when dropped (also when a
/// test fails): plant simulator, sensor driver, controller.
struct Procs(Vec<Child>);

impl Drop for Procs {
    fn drop(&mut self) {
        for p in self.0.iter_mut().rev() {
            terminate(p);
        }
    }
}

fn start(sc: &Scenario) -> Procs {
    Procs(vec![
        sc.spawn("exo-plant-sim", &[]),
        sc.spawn("exo-sensor-driver", &[]),
        sc.spawn("exo-controller", &[]),
    ])
}

fn stop_all(procs: Procs) {
    drop(procs);
}

/// `exo op --instance <sc's> args…`, which must succeed; its standard output.
fn op(sc: &Scenario, args: &[&str]) -> String {
    let mut all = vec!["op", "--instance", &sc.instance, "--wait-s", "30"];
    all.extend_from_slice(args);
    let out = exo(&all);
    assert!(
        out.status.success(),
        "exo {all:?} failed:\n{}\ncontroller log:\n{}",
        stderr(&out),
        sc.log("exo-controller")
    );
    stdout(&out)
}

/// `exo op --instance <sc's> args…`, which the controller must refuse
/// (exit 1); its standard error (the controller's reason).
fn op_refused(sc: &Scenario, args: &[&str]) -> String {
    let mut all = vec!["op", "--instance", &sc.instance, "--wait-s", "30"];
    all.extend_from_slice(args);
    let out = exo(&all);
    assert_eq!(
        out.status.code(),
        Some(1),
        "exo {all:?}:\n{}\ncontroller log:\n{}",
        stderr(&out),
        sc.log("exo-controller")
    );
    stderr(&out)
}

/// Waits (bounded) until the log of `bin` contains `text`.
fn wait_for_log(sc: &Scenario, bin: &str, text: &str) -> String {
    let t = Instant::now();
    loop {
        let log = sc.log(bin);
        if log.contains(text) {
            return log;
        }
        assert!(
            t.elapsed() < WAIT,
            "`{text}` never appeared in the {bin} log:\n{log}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The commands, one per sample (a sample re-sent at start-up is answered twice).
fn answers(mut c: Vec<ActuatorCommand>) -> Vec<ActuatorCommand> {
    c.dedup_by_key(|c| c.sensor_seq);
    c
}

/// A state's phase, decoded (every state the controller publishes has a known code).
fn phase(p: &ProtocolState) -> ProtocolPhase {
    p.protocol_phase().expect("a known phase code")
}

/// A command's mode, decoded (every command has a known code).
fn mode(c: &ActuatorCommand) -> ControlMode {
    c.control_mode().expect("a known mode code")
}

fn key(p: &ProtocolState) -> (u32, u32, ProtocolPhase) {
    (p.experiment, p.period, phase(p))
}

#[test]
fn stop_ramps_out_and_holds_gravity_without_a_fault_and_start_continues() {
    let sc = scenario("opstop", "experiments = [4]", "periods = [1, 4]");
    let protocol = sc.collect(PROTOCOL);
    let commands = sc.collect(COMMAND);
    let procs = start(&sc);
    // Experiment 4 (bias 4 Nm, sine 2 Nm), period 1, settling: bias and
    // sine on.
    protocol.wait_for(WAIT, "experiment 4's settling", |p| {
        p.iter().any(|p| key(p) == (4, 1, SETTLING))
    });
    let sent = op(&sc, &["stop"]);
    assert!(sent.contains("StopProtocol (4)"), "{sent}");
    protocol.wait_for(WAIT, "the stopped protocol (idle)", |p| {
        p.iter().any(|p| phase(p) == IDLE)
    });
    let states = protocol.snapshot();
    let idle_at = states.iter().find(|p| phase(p) == IDLE).unwrap().stamp_ns;
    // Three simulated seconds of holding.
    commands.wait_for(WAIT, "3 s of commands after the ramp-out", |c| {
        c.iter().any(|c| c.stamp_ns >= idle_at + 3_000_000_000)
    });
    let held = answers(commands.snapshot());
    // The stop interrupted the settling: the ramp-out of period 1 came
    // before its analysis window, and lasted the protocol's ramp-out.
    let before_idle: Vec<_> = states.iter().filter(|p| p.stamp_ns < idle_at).collect();
    assert!(
        before_idle.iter().all(|p| phase(p) != ANALYSIS),
        "the analysis window began before the stop took effect"
    );
    let stop_at = before_idle
        .iter()
        .find(|p| phase(p) == RAMP_OUT)
        .expect("a ramp-out before the hold")
        .stamp_ns;
    assert_eq!(
        key(before_idle.iter().find(|p| phase(p) == RAMP_OUT).unwrap()),
        (4, 1, RAMP_OUT)
    );
    assert_eq!(idle_at - stop_at, RAMP_OUT_NS, "ramp-out of 5 s");
    let idle = states.iter().find(|p| phase(p) == IDLE).unwrap();
    assert_eq!((idle.experiment, idle.period, idle.load_kg), (0, 0, 4.5));
    // Every command in mode Run: no fault.
    assert!(
        held.iter().all(|c| mode(c) == RUN),
        "modes: {:?}",
        held.iter()
            .map(|c| c.control_mode())
            .collect::<std::collections::HashSet<_>>()
    );
    // The ramp-out: the bias falls smoothly from its 4 Nm plateau to 0.
    let ramp: Vec<_> = held
        .iter()
        .filter(|c| c.stamp_ns >= stop_at && c.stamp_ns < idle_at)
        .collect();
    // (5000 ticks; a collector on a busy machine may have lost some.)
    assert!(ramp.len() <= 5000 && ramp.len() > 2500, "{}", ramp.len());
    let first = ramp[0];
    assert!(
        first.stamp_ns - stop_at < 100_000_000 && first.tau_bias > 3.9,
        "bias {} Nm at {} ns after the stop",
        first.tau_bias,
        first.stamp_ns - stop_at
    );
    for w in ramp.windows(2) {
        // From tick to tick (where the collector has both).
        if w[1].sensor_seq == w[0].sensor_seq + 1 {
            assert!(w[1].tau_bias <= w[0].tau_bias && w[0].tau_bias - w[1].tau_bias < 0.01);
            assert!((w[1].tau_excitation - w[0].tau_excitation).abs() < 0.01);
        }
    }
    // Held: no bias, excitation or amplification; gravity compensated.
    let hold: Vec<_> = held.iter().filter(|c| c.stamp_ns >= idle_at).collect();
    assert!(!hold.is_empty());
    for c in &hold {
        assert_eq!(
            (c.tau_bias, c.tau_excitation, c.tau_amplification),
            (0.0, 0.0, 0.0),
            "at sample {}",
            c.sensor_seq
        );
        assert!(c.tau_gravity > 1.0, "gravity {} Nm", c.tau_gravity);
        assert!((c.tau_d - c.tau_gravity).abs() < 1e-9);
    }
    let log = sc.log("exo-controller");
    assert!(
        log.contains(
            "protocol stopped at experiment 4 period 1: bias and excitation ramp out over 5 s"
        ),
        "{log}"
    );
    assert!(log.contains("holding gravity compensation"), "{log}");
    assert!(!log.contains("safe state latched"), "{log}");
    // `start` (no experiment) continues: period 1 again, from its ramp-in,
    // as its analysis window was never reached.
    let sent = op(&sc, &["start"]);
    assert!(sent.contains("StartProtocol (3) value 0"), "{sent}");
    protocol.wait_for(WAIT, "period 1's settling again", |p| {
        p.iter()
            .any(|p| p.stamp_ns > idle_at && key(p) == (4, 1, SETTLING))
    });
    let states = protocol.snapshot();
    let resumed = states
        .iter()
        .find(|p| p.stamp_ns > idle_at && phase(p) != IDLE);
    assert_eq!(resumed.map(key), Some((4, 1, RAMP_IN)));
    stop_all(procs);
    let c = answers(commands.finish());
    assert!(c.iter().all(|c| mode(c) == RUN));
    assert!(
        c.iter().any(|c| c.stamp_ns > idle_at && c.tau_bias == 4.0),
        "the bias is back after the start"
    );
    assert!(sc
        .log("exo-controller")
        .contains("protocol starts at experiment 4 period 1"));
}

#[test]
fn start_5_ramps_out_and_runs_experiment_5() {
    let sc = scenario("opstart", "experiments = [1, 5]", "periods = [1, 4]");
    let protocol = sc.collect(PROTOCOL);
    let commands = sc.collect(COMMAND);
    let procs = start(&sc);
    protocol.wait_for(WAIT, "experiment 1's settling", |p| {
        p.iter().any(|p| key(p) == (1, 1, SETTLING))
    });
    let sent = op(&sc, &["start", "5"]);
    assert!(sent.contains("StartProtocol (3) value 5"), "{sent}");
    protocol.wait_for(WAIT, "experiment 5's settling", |p| {
        p.iter().any(|p| key(p) == (5, 1, SETTLING))
    });
    stop_all(procs);
    let states = protocol.finish();
    let first5 = states.iter().position(|p| p.experiment == 5).unwrap();
    // Straight from experiment 1's first period, ramped out, to
    // experiment 5's first, from its ramp-in; period 4 of experiment 1
    // never ran.
    assert_eq!(key(&states[first5]), (5, 1, RAMP_IN));
    assert_eq!(key(&states[first5 - 1]), (1, 1, RAMP_OUT));
    assert!(states[..first5]
        .iter()
        .all(|p| p.experiment == 1 && p.period == 1));
    assert!(states[..first5].iter().all(|p| phase(p) != ANALYSIS));
    let ramp_out_at = states[..first5]
        .iter()
        .find(|p| phase(p) == RAMP_OUT)
        .unwrap()
        .stamp_ns;
    assert_eq!(states[first5].stamp_ns - ramp_out_at, RAMP_OUT_NS);
    // Experiment 5: α = 2, bias 4 Nm, Table I's first frequency.
    let p = &states[first5];
    assert_eq!((p.alpha, p.bias_nm, p.omega), (2.0, 4.0, 3.0));
    let c = answers(commands.finish());
    assert!(c.iter().all(|c| mode(c) == RUN));
    let log = sc.log("exo-controller");
    assert!(
        log.contains(
            "protocol starts at experiment 5 period 1 once the running period has ramped out (5 s)"
        ),
        "{log}"
    );
    assert!(log.contains("controller: experiment 5 period 1"), "{log}");
}

/// `exo op` answers with the controller's own verdict: a start at an
/// experiment the run does not have exits 1 with the controller's reason,
/// a stop exits 0 with what the controller did, both from its reply on
/// `exo/operator/reply` (before it, both printed "sent … the controller's
/// log says what it did" and exited 0).
#[test]
fn a_refused_command_exits_1_with_the_reason_and_an_accepted_one_exits_0_with_what_was_done() {
    let sc = scenario("opreply", "experiments = [1, 7]", "periods = [1]");
    let protocol = sc.collect(PROTOCOL);
    let procs = start(&sc);
    protocol.wait_for(WAIT, "experiment 1's settling", |p| {
        p.iter().any(|p| key(p) == (1, 1, SETTLING))
    });
    let all = [
        "op",
        "--instance",
        &sc.instance,
        "--wait-s",
        "30",
        "start",
        "3",
    ];
    let out = exo(&all);
    assert_eq!(out.status.code(), Some(1), "exo {all:?}: {}", stderr(&out));
    assert!(
        stderr(&out).contains(
            "the controller refused StartProtocol (3)"
        ) && stderr(&out).contains(
            "experiment 3 is not in this run's protocol (protocol.experiments = [1, 7]); nothing changed"
        ),
        "{}",
        stderr(&out)
    );
    let stopped = op(&sc, &["stop"]);
    assert!(
        stopped.contains("StopProtocol (4)")
            && stopped.contains("protocol stopped at experiment 1 period 1"),
        "{stopped}"
    );
    stop_all(procs);
    drop(protocol);
}

#[test]
fn reset_clears_the_controllers_latched_fault() {
    let sc = scenario("opreset", "experiments = [4]", "periods = [1]");
    // |τ_c| over 3 Nm latches: the subject raising the arm at the start
    // gets there (or else the 4 Nm bias in the ramp-in).
    sc.edit("tau_c_nm = 60.0", "tau_c_nm = 3.0");
    let protocol = sc.collect(PROTOCOL);
    let commands = sc.collect(COMMAND);
    let procs = start(&sc);
    commands.wait_for(WAIT, "the latched safe state", |c| {
        c.iter().any(|c| mode(c) == SAFE_GRAVITY)
    });
    wait_for_log(&sc, "exo-controller", "safe state latched");
    // A start is refused while latched (exo op exits 1 with the
    // controller's reason); a stop is taken.
    let refused = op_refused(&sc, &["start", "4"]);
    assert!(refused.contains("reset it first (ResetFault)"), "{refused}");
    wait_for_log(&sc, "exo-controller", "reset it first (ResetFault)");
    op(&sc, &["stop"]);
    protocol.wait_for(WAIT, "the stopped protocol", |p| {
        p.iter().any(|p| phase(p) == IDLE)
    });
    // Stopped, the simulated subject lowers the arm to rest (up to 9 Nm of
    // τ_c for a second or two): reset once it has settled, 5 s later.
    let idle_at = protocol
        .snapshot()
        .iter()
        .find(|p| phase(p) == IDLE)
        .unwrap()
        .stamp_ns;
    commands.wait_for(WAIT, "5 s of holding", |c| {
        c.iter().any(|c| c.stamp_ns >= idle_at + 5_000_000_000)
    });
    op(&sc, &["reset"]);
    let log = wait_for_log(&sc, "exo-controller", "fault latch reset (was:");
    assert!(log.contains("interaction torque"), "{log}");
    // Back in Run after the latch, holding gravity (stopped).
    commands.wait_for(WAIT, "3 s of commands in Run after the reset", |c| {
        let Some(first) = c.iter().rposition(|c| mode(c) == SAFE_GRAVITY) else {
            return false;
        };
        c[first..]
            .iter()
            .any(|x| mode(x) == RUN && x.stamp_ns >= c[first].stamp_ns + 3_000_000_000)
    });
    stop_all(procs);
    let c = answers(commands.finish());
    let latched = c.iter().position(|c| mode(c) == SAFE_GRAVITY).unwrap();
    let reset = latched + c[latched..].iter().position(|c| mode(c) == RUN).unwrap();
    assert!(c[..latched].iter().all(|c| mode(c) == RUN));
    assert!(c[latched..reset].iter().all(|c| mode(c) == SAFE_GRAVITY));
    // Stays unlatched: one latch in the whole run.
    for x in &c[reset..] {
        assert_eq!(mode(x), RUN, "at sample {}", x.sensor_seq);
        assert_eq!((x.tau_bias, x.tau_excitation), (0.0, 0.0));
        assert!(x.tau_gravity > 1.0);
    }
    let log = sc.log("exo-controller");
    assert_eq!(log.matches("safe state latched").count(), 1, "{log}");
}

/// In lockstep simulated time stands still while the driver waits, so a
/// controller that is slow but alive is not a fault: stopped (SIGSTOP) for
/// 2 s, over six times the lockstep time-out of 300 ms, it is waited for and
/// no sample carries the safe state (CI, stop 33: a loaded machine once
/// held a controller over the old 1 s time-out and the main job latched).
/// Its death is still declared: `reset_clears_the_drivers_latched_safe_state`.
#[test]
fn a_living_controller_stalled_in_lockstep_is_waited_for() {
    let sc = scenario("opslow", "experiments = [4]", "periods = [1]");
    sc.edit(
        "safe_state = \"gravity_only\"",
        "safe_state = \"gravity_only\"\nlockstep_timeout_ms = 300.0",
    );
    let samples = sc.collect(SENSOR);
    let procs = start(&sc);
    samples.wait_for(WAIT, "2000 samples", |s| s.iter().any(|s| s.seq >= 2000));
    signal(&procs.0[2], SIGSTOP);
    std::thread::sleep(Duration::from_secs(2));
    signal(&procs.0[2], SIGCONT);
    let before = samples.snapshot().last().unwrap().seq;
    samples.wait_for(WAIT, "1000 more samples", |s| {
        s.iter().any(|s| s.seq >= before + 1000)
    });
    stop_all(procs);
    let s = samples.finish();
    assert!(
        s.iter().all(|s| s.status & status::SAFE_STATE == 0),
        "a sample in the safe state: {:?}",
        s.iter().find(|s| s.status & status::SAFE_STATE != 0)
    );
    let log = sc.log("exo-sensor-driver");
    assert!(
        log.contains("the controller's process lives: waiting"),
        "{log}"
    );
    assert!(!log.contains("safe state latched"), "{log}");
}

#[test]
fn reset_clears_the_drivers_latched_safe_state() {
    let sc = scenario("opdrv", "experiments = [4]", "periods = [1]");
    sc.edit(
        "safe_state = \"gravity_only\"",
        "safe_state = \"gravity_only\"\nlockstep_timeout_ms = 300.0",
    );
    let samples = sc.collect(SENSOR);
    let mut procs = start(&sc);
    samples.wait_for(WAIT, "2000 samples", |s| s.iter().any(|s| s.seq >= 2000));
    // Without its controller the driver latches its safe state …
    kill_9(&mut procs.0[2]);
    samples.wait_for(WAIT, "the driver's safe state", |s| {
        s.iter().any(|s| s.status & status::SAFE_STATE != 0)
    });
    // … and keeps it with a controller back, until an operator reset.
    procs.0[2] = sc.spawn("exo-controller", &[]);
    wait_for_log(&sc, "exo-controller", "controller: experiment 4 period 1");
    let before = samples.snapshot().last().unwrap().seq;
    samples.wait_for(WAIT, "1000 more samples", |s| {
        s.iter().any(|s| s.seq >= before + 1000)
    });
    assert!(samples
        .snapshot()
        .iter()
        .filter(|s| s.seq >= before)
        .all(|s| s.status & status::SAFE_STATE != 0));
    op(&sc, &["reset"]);
    samples.wait_for(WAIT, "samples out of the safe state", |s| {
        s.iter()
            .any(|s| s.seq > before && s.status & status::SAFE_STATE == 0)
    });
    let log = wait_for_log(&sc, "exo-sensor-driver", "safe state reset (was:");
    assert!(log.contains("commands are applied again"), "{log}");
    let cleared = samples
        .snapshot()
        .iter()
        .find(|s| s.seq > before && s.status & status::SAFE_STATE == 0)
        .unwrap()
        .seq;
    samples.wait_for(WAIT, "1000 samples after the reset", |s| {
        s.iter().any(|s| s.seq >= cleared + 1000)
    });
    stop_all(procs);
    let s = samples.finish();
    assert!(s
        .iter()
        .filter(|s| s.seq >= cleared)
        .all(|s| s.status & status::SAFE_STATE == 0));
    // The restarted controller followed the driver's safe state (it saw
    // SAFE_STATE samples) without a latch of its own: the driver's reset
    // ended both.
    assert!(sc
        .log("exo-controller")
        .contains("fault latch reset (no fault was latched)"));
}

/// Sends `cmds` on the operator channel of `sc` once the controller and
/// the driver listen; keeps the publisher until `done` holds.
fn send_raw(sc: &Scenario, cmds: &[OperatorCommand], done: impl Fn() -> bool) {
    let ipc = Ipc::open(
        &format!("optest_{}", std::process::id()),
        &sc.instance,
        None,
    )
    .unwrap();
    let out = ipc.outbox(OPERATOR).unwrap();
    let t = Instant::now();
    while ipc.port_counts(OPERATOR).unwrap().subscribers < 2 {
        assert!(t.elapsed() < WAIT, "no controller and driver listening");
        std::thread::sleep(Duration::from_millis(5));
    }
    for c in cmds {
        out.send(*c).unwrap();
    }
    while !done() {
        assert!(t.elapsed() < WAIT, "the commands were never handled");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn unknown_kinds_bad_values_and_repeated_seqs_are_refused_and_change_nothing() {
    let command = |seq: u64, kind: u32, value: f64| OperatorCommand {
        seq,
        kind,
        value,
        ..Default::default()
    };
    let kind = |k: OperatorCommandKind| k.as_u32();
    let cmds = [
        command(1, 99, 0.0),
        command(2, kind(OperatorCommandKind::AdoptFractionalOrder), 1.5),
        command(3, kind(OperatorCommandKind::StartProtocol), 5.0),
        command(4, kind(OperatorCommandKind::StopProtocol), f64::NAN),
        // Acted on once; the repeat (even of another kind) is ignored.
        command(5, kind(OperatorCommandKind::ResetFault), 0.0),
        command(5, kind(OperatorCommandKind::StopProtocol), 0.0),
    ];
    // A run until sample `end` (the commands' run: 5000 samples after they
    // were all handled), sending `cmds` after sample 1000.
    let run = |tag: &str, cmds: &[OperatorCommand], end: Option<u64>| {
        let sc = scenario(tag, "experiments = [4]", "periods = [1]");
        let samples = sc.collect(SENSOR);
        let commands = sc.collect(COMMAND);
        let procs = start(&sc);
        let end = match end {
            Some(end) => end,
            None => {
                samples.wait_for(WAIT, "1000 samples", |s| s.iter().any(|s| s.seq >= 1000));
                send_raw(&sc, cmds, || {
                    sc.log("exo-controller").contains("seq 5: already handled")
                        && sc
                            .log("exo-sensor-driver")
                            .contains("seq 5: already handled")
                });
                // Every command was handled before this sample.
                samples.snapshot().last().unwrap().seq + 5000
            }
        };
        samples.wait_for(WAIT, "the end sample", |s| s.iter().any(|s| s.seq >= end));
        stop_all(procs);
        let (mut s, c) = (samples.finish(), answers(commands.finish()));
        s.retain(|s| s.seq <= end);
        s.dedup_by_key(|s| s.seq);
        (sc, s, c, end)
    };
    let (sc, s, c, end) = run("opunk", &cmds, None);
    let (_, s0, c0, _) = run("opunk0", &[], Some(end));
    let log = sc.log("exo-controller");
    let line = log
        .lines()
        .find(|l| l.contains("seq 1:"))
        .unwrap_or_else(|| panic!("{log}"));
    assert!(line.contains("WARN"), "{line}");
    assert!(
        line.contains(
            "unknown operator command kind 99 refused (known kinds: 1 ResetFault, \
             2 AdoptFractionalOrder, 3 StartProtocol, 4 StopProtocol); nothing changed"
        ),
        "{line}"
    );
    for (seq, text) in [
        ("seq 2:", "AdoptFractionalOrder (2) refused: f = 1.5 is outside [0, 1)"),
        (
            "seq 3:",
            "StartProtocol (3) refused: experiment 5 is not in this run's protocol (protocol.experiments = [4])",
        ),
        ("seq 4:", "StopProtocol (4) refused: value NaN is not finite"),
        ("seq 5:", "fault latch reset (no fault was latched)"),
        ("seq 5:", "already handled (seq 5); ignored"),
    ] {
        assert!(
            log.lines().any(|l| l.contains(seq) && l.contains(text)),
            "`{seq} {text}` not in the controller log:\n{log}"
        );
    }
    let driver = sc.log("exo-sensor-driver");
    assert!(
        driver.lines().any(|l| l.contains("WARN")
            && l.contains(
                "seq 1: unknown operator command kind 99 refused (known kinds: 1 ResetFault"
            )),
        "{driver}"
    );
    // Nothing changed: bit for bit the run without the commands, up to 5000
    // samples after they were handled. (A collector on a busy machine may
    // lose samples when it falls more than its buffer behind: the runs are
    // compared where both have them, which must include the end.)
    let by_seq = |s: &[SensorSample]| -> BTreeMap<u64, SensorSample> {
        s.iter().map(|x| (x.seq, *x)).collect()
    };
    let (a, b) = (by_seq(&s), by_seq(&s0));
    let mut common = 0;
    for (seq, x) in &a {
        let Some(y) = b.get(seq) else { continue };
        common += 1;
        assert_eq!(
            (
                x.status,
                x.theta_e.to_bits(),
                x.tau_c.to_bits(),
                x.tau_s.to_bits()
            ),
            (
                y.status,
                y.theta_e.to_bits(),
                y.tau_c.to_bits(),
                y.tau_s.to_bits()
            ),
            "sample {seq}"
        );
    }
    assert!(
        common as u64 >= end / 2,
        "only {common} of {end} samples in both runs"
    );
    assert!(a.contains_key(&end) && b.contains_key(&end));
    let commands = |c: &[ActuatorCommand]| -> BTreeMap<u64, ActuatorCommand> {
        c.iter()
            .filter(|x| x.sensor_seq <= end)
            .map(|x| (x.sensor_seq, *x))
            .collect()
    };
    let (a, b) = (commands(&c), commands(&c0));
    let mut compared = 0;
    for (seq, x) in &a {
        assert_eq!(mode(x), RUN, "command for {seq}");
        let Some(y) = b.get(seq) else { continue };
        compared += usize::from(*seq > end - 5000);
        assert_eq!(
            (x.mode, x.tau_d.to_bits(), x.tau_bias.to_bits()),
            (y.mode, y.tau_d.to_bits(), y.tau_bias.to_bits()),
            "command for sample {seq}"
        );
    }
    assert!(
        compared >= 2500,
        "only {compared} commands compared after the handling"
    );
}

#[test]
fn exo_op_refuses_bad_arguments_and_a_run_without_a_controller() {
    for (args, named) in [
        (
            &["adopt-f", "1.5"][..],
            "adopt-f: F must be a fractional order in [0, 1), not 1.5",
        ),
        (&["adopt-f", "NaN"][..], "not NaN"),
        (&["adopt-f", "-0.2"][..], "not -0.2"),
        (&["start", "10"][..], "start: N must be an experiment 1–9"),
        (&["start", "-1"][..], "'-1' for '[N]'"),
    ] {
        let mut all = vec!["op", "--instance", "opnobody"];
        all.extend_from_slice(args);
        let out = exo(&all);
        assert!(!out.status.success(), "{args:?} accepted");
        assert!(stderr(&out).contains(named), "{args:?}: {}", stderr(&out));
    }
    let instance = format!("opnone{}", std::process::id());
    let out = exo(&["op", "--instance", &instance, "--wait-s", "0.2", "stop"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains(&format!(
            "no controller is listening on `{instance}/operator` (waited 0.2 s)"
        )),
        "{}",
        stderr(&out)
    );
}

/// A replayed run has no controller: `exo op` against it exits 2, "no
/// controller is listening" (before the replies, the player's publisher on
/// the protocol channel was taken for a controller's and the command was
/// "sent" to nobody).
#[test]
fn a_replayed_run_is_not_taken_for_a_controller() {
    // 24 000 samples at 500 a second: the replay lasts longer than the
    // console waits.
    let sc = Scenario::replay("opreplay", 500.0);
    let protocol = sc.collect(PROTOCOL);
    // The recorder subscribes to the operator channel, the player publishes
    // the protocol: what the console took for a controller before.
    let rec = sc.dir.join("replayed.mcap");
    let player = Procs(vec![
        sc.spawn("exo-recorder", &["--output", rec.to_str().unwrap()]),
        sc.spawn("exo-player", &[]),
    ]);
    protocol.wait_for(WAIT, "the replayed protocol", |p| !p.is_empty());
    let out = exo(&["op", "--instance", &sc.instance, "--wait-s", "1", "stop"]);
    drop(player);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("no controller is listening"),
        "{}",
        stderr(&out)
    );
}
