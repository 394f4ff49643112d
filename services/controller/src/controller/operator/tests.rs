//! The operator's commands, tick by tick.

use exo_messages::ProtocolPhase;
use exo_messages::{ControlMode, OperatorCommand, OperatorCommandKind as K};

use super::super::tests::{cfg, sample};
use super::super::Tick;
use super::*;

fn op(seq: u64, kind: K, value: f64) -> OperatorCommand {
    OperatorCommand::new(seq, 0, kind, value)
}

/// A controller over `experiments` (all periods as in the default run:
/// 1, 4, 7; 21 s each at 1 kHz).
fn controller_of(experiments: &[u32]) -> Controller {
    let mut c = cfg();
    c.protocol.experiments = experiments.to_vec();
    Controller::from_config(&c).unwrap()
}

/// Ticks `from..to` at a still arm; the last tick.
fn ticks(k: &mut Controller, from: u64, to: u64) -> Tick {
    (from..to)
        .map(|seq| k.tick(&sample(seq, 0.5, 0.0)))
        .last()
        .unwrap()
}

const RATE: u64 = 1000;

#[test]
fn operator_reset_clears_the_latched_fault() {
    let mut k = controller_of(&[1]);
    ticks(&mut k, 0, 10);
    assert_eq!(
        k.tick(&sample(10, 0.5, f64::NAN)).mode,
        ControlMode::SafeGravityOnly
    );
    let out = k.on_operator(&op(1, K::ResetFault, 0.0));
    assert_eq!(
        out,
        OperatorOutcome::FaultReset {
            cleared: Some(Fault::NonFiniteSample { field: "tau_c" })
        }
    );
    assert!(!out.is_refusal());
    assert!(out.to_string().contains("tau_c is not finite"), "{out}");
    assert_eq!(k.tick(&sample(11, 0.5, 0.0)).mode, ControlMode::Run);
    assert_eq!(
        k.on_operator(&op(2, K::ResetFault, 0.0)),
        OperatorOutcome::FaultReset { cleared: None }
    );
}

#[test]
fn operator_f_is_validated_then_clamped_to_the_run_bounds() {
    let mut k = controller_of(&[1]);
    // f_bounds = [0, 0.9] in the default run.
    assert_eq!(
        k.on_operator(&op(1, K::AdoptFractionalOrder, 0.4)),
        OperatorOutcome::FractionalOrderAdopted {
            asked: 0.4,
            f: 0.4,
            bounds: [0.0, 0.9]
        }
    );
    let out = k.on_operator(&op(2, K::AdoptFractionalOrder, 0.95));
    assert_eq!(
        out,
        OperatorOutcome::FractionalOrderAdopted {
            asked: 0.95,
            f: 0.9,
            bounds: [0.0, 0.9]
        }
    );
    assert!(out.to_string().contains("clamped to controller.f_bounds"));
    for (seq, f) in [
        (3, 1.0),
        (4, 1.5),
        (5, -0.1),
        (6, f64::NAN),
        (7, f64::INFINITY),
    ] {
        let out = k.on_operator(&op(seq, K::AdoptFractionalOrder, f));
        assert!(
            matches!(
                out,
                OperatorOutcome::InvalidValue {
                    kind: K::AdoptFractionalOrder,
                    ..
                }
            ),
            "f = {f}: {out:?}"
        );
        assert!(out.is_refusal());
        assert!(
            out.to_string().contains("AdoptFractionalOrder (2) refused"),
            "{out}"
        );
    }
    assert!(k
        .on_operator(&op(8, K::AdoptFractionalOrder, 1.5))
        .to_string()
        .contains("f = 1.5 is outside [0, 1)"));
    // The refused values changed nothing: the amplifier is the f = 0.9 one.
    let mut reference = controller_of(&[1]);
    assert!(reference.adopt_fractional_order(0.9));
    for seq in 0..500 {
        let s = sample(seq, 0.5, (seq as f64 * 0.01).sin());
        assert_eq!(
            k.tick(&s).tau_d_nm.to_bits(),
            reference.tick(&s).tau_d_nm.to_bits()
        );
    }
}

#[test]
fn operator_stop_ramps_out_and_holds_gravity_without_a_fault() {
    let mut k = controller_of(&[4]); // bias 4 Nm, sine 2 Nm
    let ramp_out = k.protocol().ramp_out_s();
    // 7 s: period 1's settling, bias at its plateau, sine fading in.
    let before = ticks(&mut k, 0, 7 * RATE);
    assert_eq!(before.protocol.phase, ProtocolPhase::Settling);
    assert_eq!(before.tau_bias_nm, 4.0);
    let out = k.on_operator(&op(1, K::StopProtocol, 0.0));
    assert_eq!(
        out,
        OperatorOutcome::Stopping {
            experiment: 4,
            period: 1,
            ramp_out_s: ramp_out
        }
    );
    assert!(out.to_string().contains("no fault"), "{out}");
    let ramp_ticks = (ramp_out * RATE as f64) as u64;
    let mut prev = before;
    for seq in 7 * RATE..7 * RATE + ramp_ticks {
        let t = k.tick(&sample(seq, 0.5, 0.0));
        assert_eq!((t.mode, t.fault), (ControlMode::Run, None));
        assert_eq!(
            (t.protocol.experiment, t.protocol.period, t.protocol.phase),
            (4, 1, ProtocolPhase::RampOut)
        );
        // Smooth: no step in the bias or the excitation.
        assert!(t.tau_bias_nm <= prev.tau_bias_nm && prev.tau_bias_nm - t.tau_bias_nm < 0.01);
        assert!((t.tau_excitation_nm - prev.tau_excitation_nm).abs() < 0.02);
        assert!(t.tau_excitation_nm.abs() <= 2.0);
        prev = t;
    }
    assert!(prev.tau_bias_nm < 1e-5 && prev.tau_excitation_nm.abs() < 1e-5);
    // Held: gravity compensation alone, mode Run, far past the protocol's end.
    let end = (k.protocol().duration_s() * RATE as f64) as u64 + 5 * RATE;
    let first_held = 7 * RATE + ramp_ticks;
    for seq in first_held..end {
        let t = k.tick(&sample(seq, 0.5, 0.0));
        assert_eq!((t.mode, t.fault), (ControlMode::Run, None), "at {seq}");
        assert!(!t.protocol_over());
        assert_eq!(
            (t.protocol.experiment, t.protocol.phase),
            (0, ProtocolPhase::Idle)
        );
        assert_eq!(
            (t.tau_bias_nm, t.tau_excitation_nm, t.tau_amplification_nm),
            (0.0, 0.0, 0.0)
        );
        assert_eq!(t.tau_gravity_nm, cfg().rig.gravity_torque_nm(0.5, 4.5));
        assert!(t.tau_gravity_nm != 0.0);
    }
    assert!(matches!(
        k.protocol_run(),
        ProtocolRun::Stopped { step: 0, resume: 0 }
    ));
    assert_eq!(
        k.on_operator(&op(2, K::StopProtocol, 0.0)),
        OperatorOutcome::AlreadyStopped
    );
}

#[test]
fn operator_start_zero_continues_a_stopped_protocol() {
    let mut k = controller_of(&[4]);
    let period = (k.protocol().period_s() * RATE as f64) as u64;
    ticks(&mut k, 0, 7 * RATE);
    k.on_operator(&op(1, K::StopProtocol, 0.0));
    ticks(&mut k, 7 * RATE, 20 * RATE);
    // Stopped before the end of the analysis window: period 1 again.
    assert_eq!(
        k.on_operator(&op(2, K::StartProtocol, 0.0)),
        OperatorOutcome::Starting {
            experiment: 4,
            period: 1,
            after_s: 0.0
        }
    );
    let t = k.tick(&sample(20 * RATE, 0.5, 0.0));
    assert_eq!(
        (t.protocol.experiment, t.protocol.period, t.protocol.phase),
        (4, 1, ProtocolPhase::RampIn)
    );
    assert_eq!(t.tau_bias_nm, 0.0, "the ramp-in starts from zero");
    // A whole period later, period 4 follows as it would have.
    let t = ticks(&mut k, 20 * RATE + 1, 20 * RATE + period + 1);
    assert_eq!(
        (t.protocol.period, t.protocol.phase),
        (4, ProtocolPhase::RampIn)
    );
    // Stopped in the rest after period 4's analysis: a resume goes on with period 7.
    let rest = 20 * RATE + 2 * period - RATE / 2;
    let t = ticks(&mut k, 20 * RATE + period + 1, rest);
    assert_eq!(
        (t.protocol.period, t.protocol.phase),
        (4, ProtocolPhase::Rest)
    );
    assert_eq!(
        k.on_operator(&op(3, K::StopProtocol, 0.0)),
        OperatorOutcome::Stopping {
            experiment: 4,
            period: 4,
            ramp_out_s: 0.0
        },
        "nothing to ramp out in a rest"
    );
    let t = k.tick(&sample(rest, 0.5, 0.0));
    assert_eq!(t.protocol.phase, ProtocolPhase::Idle);
    assert_eq!(
        k.on_operator(&op(4, K::StartProtocol, 0.0)),
        OperatorOutcome::Starting {
            experiment: 4,
            period: 7,
            after_s: 0.0
        }
    );
    let t = k.tick(&sample(rest + 1, 0.5, 0.0));
    assert_eq!(
        (t.protocol.period, t.protocol.phase),
        (7, ProtocolPhase::RampIn)
    );
    // After the last period, the protocol ends as usual.
    let t = ticks(&mut k, rest + 2, rest + 1 + period + 10);
    assert_eq!(t.mode, ControlMode::Done);
    assert!(t.protocol_over());
}

#[test]
fn operator_start_n_restarts_at_the_experiment_after_a_ramp_out() {
    let mut k = controller_of(&[1, 7]);
    let period = (k.protocol().period_s() * RATE as f64) as u64;
    let ramp = (k.protocol().ramp_out_s() * RATE as f64) as u64;
    ticks(&mut k, 0, 8 * RATE); // experiment 1, period 1, sine on
    assert_eq!(
        k.on_operator(&op(1, K::StartProtocol, 7.0)),
        OperatorOutcome::Starting {
            experiment: 7,
            period: 1,
            after_s: 5.0
        }
    );
    for seq in 8 * RATE..8 * RATE + ramp {
        let t = k.tick(&sample(seq, 0.5, 0.0));
        assert_eq!(
            (t.protocol.experiment, t.protocol.phase),
            (1, ProtocolPhase::RampOut),
            "at {seq}"
        );
    }
    let start = 8 * RATE + ramp;
    let t = k.tick(&sample(start, 0.5, 0.0));
    assert_eq!(
        (t.protocol.experiment, t.protocol.period, t.protocol.phase),
        (7, 1, ProtocolPhase::RampIn)
    );
    assert!(matches!(
        k.protocol_run(),
        ProtocolRun::Running { from_step: 3, since_tick, skipped_ticks: 0 } if since_tick == start
    ));
    // Experiment 7's three periods, then the end.
    let t = ticks(&mut k, start + 1, start + 2 * period + 10 * RATE);
    assert_eq!((t.protocol.experiment, t.protocol.period), (7, 7));
    let t = ticks(
        &mut k,
        start + 2 * period + 10 * RATE,
        start + 3 * period + 1,
    );
    assert_eq!(t.mode, ControlMode::Done);
    // Started in a ramp-in without bias (nothing applied): at once.
    let mut k = controller_of(&[1, 7]);
    ticks(&mut k, 0, 2 * RATE);
    assert_eq!(
        k.on_operator(&op(1, K::StartProtocol, 7.0)),
        OperatorOutcome::Starting {
            experiment: 7,
            period: 1,
            after_s: 0.0
        }
    );
    assert_eq!(k.tick(&sample(2 * RATE, 0.5, 0.0)).protocol.experiment, 7);
}

#[test]
fn operator_start_and_stop_while_ramping_out() {
    let mut k = controller_of(&[1, 7]);
    ticks(&mut k, 0, 8 * RATE);
    k.on_operator(&op(1, K::StopProtocol, 0.0));
    ticks(&mut k, 8 * RATE, 9 * RATE);
    // A start during the stop's ramp-out waits for its end.
    let out = k.on_operator(&op(2, K::StartProtocol, 7.0));
    let OperatorOutcome::Starting { after_s, .. } = out else {
        panic!("{out:?}")
    };
    assert!((after_s - 4.0).abs() < 1e-9, "{after_s}");
    // A stop cancels it again.
    assert!(matches!(
        k.on_operator(&op(3, K::StopProtocol, 0.0)),
        OperatorOutcome::Stopping { experiment: 1, .. }
    ));
    let t = ticks(&mut k, 9 * RATE, 20 * RATE);
    assert_eq!((t.protocol.experiment, t.mode), (0, ControlMode::Run));
}

/// The console's verdict of each outcome: refusals (an unknown kind,
/// an invalid value, a refusal in the present state) are refused, a
/// repeated seq is a repeat, everything else (nothing left to do
/// included) accepted.
#[test]
fn each_outcome_answers_the_console_with_its_verdict() {
    use exo_messages::OperatorVerdict::{Accepted, Refused, Repeated};
    let k = OperatorCommandKind::StartProtocol;
    for (outcome, verdict) in [
        (OperatorOutcome::Repeated { seq: 3 }, Repeated),
        (OperatorOutcome::UnknownKind { code: 99 }, Refused),
        (
            OperatorOutcome::InvalidValue {
                kind: k,
                value: 12.0,
            },
            Refused,
        ),
        (
            OperatorOutcome::Refused {
                kind: k,
                reason: OperatorRefusal::ProtocolOver,
            },
            Refused,
        ),
        (OperatorOutcome::FaultReset { cleared: None }, Accepted),
        (OperatorOutcome::AlreadyStopped, Accepted),
        (
            OperatorOutcome::Starting {
                experiment: 7,
                period: 1,
                after_s: 0.0,
            },
            Accepted,
        ),
    ] {
        assert_eq!(outcome.verdict(), verdict, "{outcome:?}");
    }
}

#[test]
fn operator_start_refusals_change_nothing() {
    let mut k = controller_of(&[1, 7]);
    ticks(&mut k, 0, 100);
    let refused = |out: OperatorOutcome, reason: OperatorRefusal| {
        assert_eq!(
            out,
            OperatorOutcome::Refused {
                kind: K::StartProtocol,
                reason
            }
        );
        assert!(out.is_refusal());
        out.to_string()
    };
    let text = refused(
        k.on_operator(&op(1, K::StartProtocol, 5.0)),
        OperatorRefusal::NotInRun {
            experiment: 5,
            run_experiments: (1 << 1) | (1 << 7),
        },
    );
    assert!(
        text.contains("experiment 5 is not in this run's protocol (protocol.experiments = [1, 7])"),
        "{text}"
    );
    refused(
        k.on_operator(&op(2, K::StartProtocol, 0.0)),
        OperatorRefusal::AlreadyRunning,
    );
    refused(
        k.on_operator(&op(3, K::StartProtocol, 2.5)),
        OperatorRefusal::NotWhole { value: 2.5 },
    );
    let out = k.on_operator(&op(4, K::StartProtocol, 10.0));
    assert!(matches!(
        out,
        OperatorOutcome::InvalidValue {
            kind: K::StartProtocol,
            ..
        }
    ));
    assert!(
        out.to_string().contains("experiment 10 is outside 1–9"),
        "{out}"
    );
    k.tick(&sample(100, 0.5, f64::NAN));
    refused(
        k.on_operator(&op(5, K::StartProtocol, 7.0)),
        OperatorRefusal::FaultLatched(Fault::NonFiniteSample { field: "tau_c" }),
    );
    // Nothing changed: still running experiment 1 from the start (latched).
    assert_eq!(
        k.protocol_run(),
        ProtocolRun::Running {
            from_step: 0,
            since_tick: 0,
            skipped_ticks: 0
        }
    );
    // Stopped at the last measured period: nothing left to resume.
    let mut k = controller_of(&[1]);
    let period = (k.protocol().period_s() * RATE as f64) as u64;
    ticks(&mut k, 0, 3 * period - RATE / 2); // period 7's rest
    k.on_operator(&op(1, K::StopProtocol, 0.0));
    refused(
        k.on_operator(&op(2, K::StartProtocol, 0.0)),
        OperatorRefusal::NothingToResume,
    );
    // Once over, neither stop nor start.
    let mut k = controller_of(&[1]);
    let t = ticks(&mut k, 0, 3 * period + 10);
    assert_eq!(t.mode, ControlMode::Done);
    assert_eq!(
        k.on_operator(&op(1, K::StopProtocol, 0.0)),
        OperatorOutcome::Refused {
            kind: K::StopProtocol,
            reason: OperatorRefusal::ProtocolOver
        }
    );
    refused(
        k.on_operator(&op(2, K::StartProtocol, 1.0)),
        OperatorRefusal::ProtocolOver,
    );
}

#[test]
fn unknown_kinds_and_repeated_seqs_change_nothing() {
    let mut k = controller_of(&[4]);
    let mut reference = controller_of(&[4]);
    let unknown = OperatorCommand {
        kind: 99,
        ..op(1, K::ResetFault, 0.0)
    };
    let out = k.on_operator(&unknown);
    assert_eq!(out, OperatorOutcome::UnknownKind { code: 99 });
    assert!(out.is_refusal());
    assert_eq!(
        out.to_string(),
        "unknown operator command kind 99 refused (known kinds: 1 ResetFault, \
         2 AdoptFractionalOrder, 3 StartProtocol, 4 StopProtocol); nothing changed"
    );
    assert_eq!(
        k.on_operator(&OperatorCommand { kind: 0, ..unknown }),
        OperatorOutcome::Repeated { seq: 1 },
        "seq 1 was handled (refused) already"
    );
    assert_eq!(
        k.on_operator(&OperatorCommand {
            seq: 2,
            kind: 0,
            ..unknown
        }),
        OperatorOutcome::UnknownKind { code: 0 }
    );
    let mut bits = Vec::new();
    for seq in 0..13 * RATE {
        if seq == 7 * RATE {
            // A stop, sent twice with the same seq, then a start with
            // a seq already used: acted on once, the start not at all.
            assert!(matches!(
                k.on_operator(&op(10, K::StopProtocol, 0.0)),
                OperatorOutcome::Stopping { .. }
            ));
            reference.on_operator(&op(10, K::StopProtocol, 0.0));
            let again = k.on_operator(&op(10, K::StopProtocol, 0.0));
            assert_eq!(again, OperatorOutcome::Repeated { seq: 10 });
            assert!(!again.is_refusal());
        }
        if seq == 9 * RATE {
            assert_eq!(
                k.on_operator(&op(10, K::StartProtocol, 0.0)),
                OperatorOutcome::Repeated { seq: 10 }
            );
        }
        let s = sample(seq, 0.5, (seq as f64 * 0.003).sin());
        let (a, b) = (k.tick(&s), reference.tick(&s));
        bits.push(a.tau_d_nm.to_bits() == b.tau_d_nm.to_bits() && a.protocol == b.protocol);
    }
    assert!(bits.iter().all(|&same| same));
    assert!(matches!(k.protocol_run(), ProtocolRun::Stopped { .. }));
}
