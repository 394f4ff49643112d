//! `exo-controller`: answers every `SensorSample` with one `ActuatorCommand`
//! and publishes the protocol state; all decisions are in
//! [`exo_controller::Controller::tick`]. It sleeps in the kernel until a
//! sample's wake-up (bounded wait, no busy spin) and exits 0 when the
//! protocol is done.
//!
//! In real time, no sample within `safety.sample_deadline_ms` latches the
//! safe state, once the stream is established (0.1 s of samples answered); in lockstep a stalled loop is the plant's
//! or driver's to report.
//!
//! Operator commands (`<instance>/operator`, e.g. from `exo op`) are taken
//! before each sample is answered and handed to
//! [`exo_controller::Controller::on_operator`], which decides; this file
//! only logs the outcome (a refusal as a warning). A stopped protocol holds
//! gravity compensation and does not end the run.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use exo_config::{RunConfig, TimingMode};
use exo_controller::controller::{Mode, OperatorOutcome};
use exo_controller::{Controller, Fault, TickInput};
use exo_messages::{
    ActuatorCommand, ControlMode, ImpedanceEstimate, OperatorCommand, ProtocolState, SensorSample,
};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{settle_connections, Ipc, REALTIME_SETTLE};
use exo_service_kit::{
    init_logging, request_realtime, RealtimeProcess, RealtimeRequest, ServiceArgs, StopFlag,
};
use tracing::{error, info, warn};

/// `status` bits meaning "do not act on this sample" (`exo_messages::status`).
const FAULT_MASK: u32 = 0b1111;

fn main() {
    init_logging("controller");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        error!("{e:#}");
        std::process::exit(1);
    }
}

/// The wire code of a controller mode (`exo_messages::ControlMode`).
fn mode_code(m: Mode) -> u32 {
    match m {
        Mode::Run => ControlMode::Run,
        Mode::SafeGravityOnly => ControlMode::SafeGravityOnly,
        Mode::SafeZeroTorque => ControlMode::SafeZeroTorque,
        Mode::Done => ControlMode::Done,
    }
    .as_u32()
}

fn run(args: ServiceArgs) -> Result<()> {
    let cfg = RunConfig::from_file(&args.config)?;
    let stop = StopFlag::install()?;
    let ipc = Ipc::open(
        "controller",
        &cfg.run.instance,
        args.iceoryx2_config.as_deref(),
    )?;
    let sensor_in = ipc
        .inbox::<SensorSample>(Channel::Sensor, 64)?
        .with_spin(cfg.lockstep_spin());
    // The operator inbox is opened before the protocol outbox: `exo op`
    // takes a publisher on the protocol channel as the sign that the
    // controller's operator subscriber exists.
    let operator_in = ipc.inbox::<OperatorCommand>(Channel::Operator, 16)?;
    let command_out = ipc.outbox::<ActuatorCommand>(Channel::Command)?;
    let protocol_out = ipc.outbox::<ProtocolState>(Channel::Protocol)?;
    let estimate_in = ipc.inbox::<ImpedanceEstimate>(Channel::IdentifierEstimate, 16)?;
    let mut controller = Controller::from_config(&cfg)?;
    if cfg.run.timing == TimingMode::Realtime {
        request_realtime(
            "controller",
            RealtimeRequest::of(cfg.realtime.as_ref(), RealtimeProcess::Controller),
        );
    }
    let lockstep = cfg.run.timing == TimingMode::Lockstep;
    if !lockstep {
        settle_connections(
            &[
                &sensor_in,
                &command_out,
                &protocol_out,
                &operator_in,
                &estimate_in,
            ],
            REALTIME_SETTLE,
        )?;
    }
    let wait = Duration::from_secs_f64(
        if lockstep {
            cfg.safety.lockstep_timeout_ms
        } else {
            cfg.safety.sample_deadline_ms
        } / 1000.0,
    );
    info!(
        "controller: {} (experiments {:?}), protocol {:.1} s simulated",
        cfg.subject().name,
        cfg.protocol.experiments,
        controller.protocol().duration_s()
    );
    let rate = cfg.run.rate_hz;
    let wall_start = Instant::now();
    let mut last: Option<ActuatorCommand> = None;
    let mut last_protocol = (u32::MAX, u32::MAX, u32::MAX);
    let mut last_protocol_tick = 0u64;
    let mut reported: Option<Fault> = None;
    let mut latched_at: Option<u64> = None;
    let mut done_ticks = 0u64;
    let mut idle_since = Instant::now();
    // The sample deadline is armed once the stream is established (0.1 s of
    // samples answered): start-up jitter of the other processes is not a fault.
    let arm_after = (rate / 10.0).ceil() as u64;
    let mut answered = 0u64;
    while !stop.requested() {
        let Some(s) = sensor_in.recv_timeout(wait)? else {
            if answered >= arm_after && !lockstep {
                controller.raise(Fault::SampleTimeout);
            }
            if idle_since.elapsed() > Duration::from_secs(60) {
                bail!("no sensor sample for 60 s: is the sensor driver running?");
            }
            continue;
        };
        idle_since = Instant::now();
        if let Some(prev) = last {
            if s.seq == prev.sensor_seq {
                command_out.send(prev)?; // a re-sent sample: answer again
                continue;
            }
            if s.seq < prev.sensor_seq {
                continue; // stale
            }
        }
        while let Some(op) = operator_in.try_recv()? {
            let outcome = controller.on_operator(&op);
            if outcome.is_refusal() {
                warn!("controller: operator command seq {}: {outcome}", op.seq);
            } else {
                info!("controller: operator command seq {}: {outcome}", op.seq);
            }
            if let OperatorOutcome::FaultReset { cleared: Some(_) } = outcome {
                reported = None;
            }
        }
        while let Some(e) = estimate_in.try_recv()? {
            if cfg.controller.adopt_recommended_f
                && e.recommended_f > 0.0
                && controller.adopt_fractional_order(e.recommended_f)
            {
                info!(
                    "controller: adopted the identifier's recommended f = {:.3}",
                    e.recommended_f
                );
            }
        }
        let tick = controller.tick(&TickInput {
            seq: s.seq,
            theta_e_rad: s.theta_e,
            omega_e_rad_s: s.omega_e,
            tau_c_nm: s.tau_c,
            tau_s_nm: s.tau_s,
            sensor_fault: s.status & FAULT_MASK != 0,
        });
        // The protocol state goes out before the command: the plant applies it
        // when that command's motor command reaches it, so in lockstep it takes
        // effect at the same tick in every run.
        let p = tick.protocol;
        let key = (p.experiment, p.period, p.phase as u32);
        if key != last_protocol || s.seq >= last_protocol_tick + rate as u64 {
            protocol_out.send(ProtocolState {
                experiment: p.experiment,
                period: p.period,
                phase: p.phase as u32,
                omega: p.omega_rad_s,
                amplitude: p.amplitude_nm,
                alpha: p.alpha,
                load_kg: p.load_kg,
                grip_kg: p.grip_kg,
                bias_nm: p.bias_nm,
                stamp_ns: s.stamp_ns,
                ..Default::default()
            })?;
            if key != last_protocol && p.experiment == 0 && !p.done {
                info!(
                    "controller: protocol stopped; holding gravity compensation (sim {:.1} s)",
                    tick.t_s
                );
            }
            if (key.0, key.1) != (last_protocol.0, last_protocol.1) && p.experiment > 0 {
                info!(
                    "controller: experiment {} period {} (ω = {:.2} rad/s, {:.1} Nm, α = {}), sim {:.1} s, wall {:.1} s",
                    p.experiment,
                    p.period,
                    p.omega_rad_s,
                    p.amplitude_nm,
                    p.alpha,
                    tick.t_s,
                    wall_start.elapsed().as_secs_f64()
                );
            }
            last_protocol = key;
            last_protocol_tick = s.seq;
        }
        let cmd = ActuatorCommand {
            seq: last.map_or(0, |c| c.seq + 1),
            stamp_ns: s.stamp_ns,
            sensor_seq: s.seq,
            tau_d: tick.tau_d_nm,
            tau_gravity: tick.tau_gravity_nm,
            tau_amplification: tick.tau_amplification_nm,
            tau_bias: tick.tau_bias_nm,
            tau_excitation: tick.tau_excitation_nm,
            mode: mode_code(tick.mode),
            ..Default::default()
        };
        command_out.send(cmd)?;
        last = Some(cmd);
        answered += 1;
        if tick.fault != reported {
            if let Some(f) = tick.fault {
                error!("controller: safe state latched at sample {}: {f}", s.seq);
                latched_at = Some(s.seq);
            }
            reported = tick.fault;
        }
        if tick.protocol_over() {
            done_ticks += 1;
            if done_ticks >= (rate / 10.0) as u64 {
                match (tick.mode, latched_at) {
                    (Mode::Done, _) | (_, None) => info!(
                        "controller: protocol done at sim {:.1} s (wall {:.1} s, {:.0}× real time)",
                        tick.t_s,
                        wall_start.elapsed().as_secs_f64(),
                        tick.t_s / wall_start.elapsed().as_secs_f64().max(1e-9)
                    ),
                    (_, Some(at)) => warn!(
                        "controller: protocol over at sim {:.1} s with the safe state latched since sample {at}: what came after ran without excitation or amplification",
                        tick.t_s
                    ),
                }
                break;
            }
        }
    }
    Ok(())
}
