//! `exo-sensor-driver`: owns the actuator. Each frame from the bus becomes a
//! calibrated `SensorSample`; the controller's command for that sample goes
//! back to the bus, or, when none comes within the deadline, the latched
//! safe-state torque.
//!
//! The bus here is the simulator's (iceoryx2 channels to `exo-plant-sim`);
//! a hardware backend implements `exo_sensor_driver::HardwareBus` instead
//! and is selected by configuration (see ARCHITECTURE.md).
//!
//! The command watchdog arms at the first command, so a controller that
//! starts late does not trip it. In real time the deadline is
//! `safety.command_deadline_ms` from the frame; in lockstep, simulated time
//! stands still while waiting, so a missing command is declared after
//! `safety.lockstep_timeout_ms` of wall time and the safe torque is applied
//! at that same simulated tick.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use exo_config::{RunConfig, TimingMode};
use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, OperatorCommand, ProtocolState, SensorSample,
};
use exo_sensor_driver::{Driver, RawFrame};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::Ipc;
use exo_service_kit::{init_logging, ServiceArgs, StopFlag};
use tracing::{error, info};

const RESEND_AFTER: Duration = Duration::from_millis(200);
const STARTUP_PATIENCE: Duration = Duration::from_secs(60);
/// `OperatorCommandKind::ResetFault`.
const OPERATOR_RESET_FAULT: u32 = 1;

fn main() {
    init_logging("sensor-driver");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        error!("{e:#}");
        std::process::exit(1);
    }
}

fn run(args: ServiceArgs) -> Result<()> {
    let cfg = RunConfig::from_file(&args.config)?;
    let stop = StopFlag::install()?;
    let ipc = Ipc::open(
        "sensor_driver",
        &cfg.run.instance,
        args.iceoryx2_config.as_deref(),
    )?;
    let bus_in = ipc.inbox::<BusSensorFrame>(Channel::BusSensor, 64)?;
    let motor_out = ipc.outbox::<BusMotorCommand>(Channel::BusMotor)?;
    let sample_out = ipc.outbox::<SensorSample>(Channel::Sensor)?;
    let command_in = ipc.inbox::<ActuatorCommand>(Channel::Command, 64)?;
    let protocol_in = ipc.inbox::<ProtocolState>(Channel::Protocol, 64)?;
    let operator_in = ipc.inbox::<OperatorCommand>(Channel::Operator, 16)?;
    let load = cfg
        .protocol
        .experiments
        .first()
        .and_then(|n| cfg.experiment_table().get(*n))
        .map_or(0.0, |e| e.load_kg);
    let mut driver = Driver::new(
        &cfg.rig,
        cfg.run.rate_hz,
        cfg.safety.safe_state,
        cfg.controller.limits.torque_nm,
        load,
    );
    let lockstep = cfg.run.timing == TimingMode::Lockstep;
    let deadline = Duration::from_secs_f64(
        if lockstep {
            cfg.safety.lockstep_timeout_ms
        } else {
            cfg.safety.command_deadline_ms
        } / 1000.0,
    );
    info!(
        "sensor-driver: {:?}, command deadline {:?}, safe state {:?}",
        cfg.run.timing, deadline, cfg.safety.safe_state
    );
    let mut armed = false;
    let mut reported_latch = false;
    let mut last: Option<BusMotorCommand> = None;
    let mut motor_seq = 0u64;
    while !stop.requested() {
        let Some(frame) = bus_in.recv_timeout(Duration::from_millis(100))? else {
            continue;
        };
        if let Some(m) = last.filter(|m| m.frame_seq == frame.seq) {
            // The plant re-sent a frame we answered (start-up race): answer again.
            motor_out.send(m)?;
            continue;
        }
        while let Some(p) = protocol_in.try_recv()? {
            driver.set_load_kg(p.load_kg);
        }
        while let Some(op) = operator_in.try_recv()? {
            if op.kind == OPERATOR_RESET_FAULT {
                info!("sensor-driver: operator reset of the safe state");
                driver.reset();
                reported_latch = false;
            }
        }
        let s = driver.on_frame(&RawFrame {
            seq: frame.seq,
            stamp_ns: frame.stamp_ns,
            encoder_counts: frame.encoder_counts,
            cuff_wrench: frame.cuff_wrench,
            sea_deflection_counts: frame.sea_deflection_counts,
            status: frame.status,
        });
        let sample = SensorSample {
            seq: s.seq,
            stamp_ns: s.stamp_ns,
            theta_e: s.theta_e,
            omega_e: s.omega_e,
            tau_c: s.tau_c,
            tau_s: s.tau_s,
            status: s.status,
            _pad: 0,
        };
        sample_out.send(sample)?;
        let started = Instant::now();
        let mut last_send = started;
        let out = loop {
            if driver.latched().is_some() {
                // Latched: no need to wait for the controller.
                while command_in.try_recv()?.is_some() {}
                break driver.on_deadline().unwrap_or_else(|| driver.safe_output());
            }
            let remaining = deadline
                .saturating_sub(started.elapsed())
                .min(Duration::from_millis(20));
            if let Some(cmd) = command_in.recv_timeout(remaining)? {
                if cmd.sensor_seq == frame.seq {
                    armed = true;
                    if let Some(o) = driver.on_command(cmd.sensor_seq, cmd.tau_d) {
                        break o;
                    }
                }
                continue;
            }
            if stop.requested() {
                break driver.safe_output();
            }
            if !armed {
                if last_send.elapsed() > RESEND_AFTER {
                    sample_out.send(sample)?;
                    last_send = Instant::now();
                }
                if started.elapsed() > STARTUP_PATIENCE {
                    bail!("no command from the controller within {STARTUP_PATIENCE:?} of start");
                }
                if !lockstep && started.elapsed() >= deadline {
                    // Not armed yet: hold the safe torque without latching.
                    break driver.safe_output();
                }
                continue;
            }
            if started.elapsed() >= deadline {
                break driver.on_deadline().unwrap_or_else(|| driver.safe_output());
            }
        };
        if let (Some(event), false) = (driver.latched(), reported_latch) {
            error!(
                "sensor-driver: safe state latched at frame {}: {event:?} → {:?}",
                frame.seq, out.source
            );
            reported_latch = true;
        }
        let motor = BusMotorCommand {
            seq: motor_seq,
            stamp_ns: frame.stamp_ns,
            frame_seq: frame.seq,
            tau_motor_nm: out.tau_motor_nm,
            enable: 1,
            ..Default::default()
        };
        motor_seq += 1;
        motor_out.send(motor)?;
        last = Some(motor);
    }
    info!("sensor-driver: stopped");
    Ok(())
}
