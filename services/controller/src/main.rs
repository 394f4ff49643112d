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
use exo_controller::node::ControllerNode;
use exo_controller::Fault;
use exo_messages::{
    ActuatorCommand, ImpedanceEstimate, OperatorCommand, ProtocolState, SensorSample,
};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{settle_connections, Ipc, REALTIME_SETTLE};
use exo_service_kit::{
    init_logging, request_realtime, RealtimeProcess, RealtimeRequest, ServiceArgs, StopFlag,
};
use tracing::{error, info};

fn main() {
    init_logging("controller");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        error!("{e:#}");
        std::process::exit(1);
    }
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
    let mut node = ControllerNode::new(&cfg)?;
    let lockstep = cfg.run.timing == TimingMode::Lockstep;
    if !lockstep {
        request_realtime(
            "controller",
            RealtimeRequest::of(cfg.realtime.as_ref(), RealtimeProcess::Controller),
        );
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
        node.controller().protocol().duration_s()
    );
    let wall_start = Instant::now();
    let mut idle_since = Instant::now();
    // The sample deadline is armed once the stream is established (0.1 s of
    // samples answered): start-up jitter of the other processes is not a fault.
    let arm_after = (cfg.run.rate_hz / 10.0).ceil() as u64;
    let mut t_s = 0.0;
    while !stop.requested() && !node.finished() {
        let Some(s) = sensor_in.recv_timeout(wait)? else {
            if node.answered() >= arm_after && !lockstep {
                node.raise(Fault::SampleTimeout);
            }
            if idle_since.elapsed() > Duration::from_secs(60) {
                bail!("no sensor sample for 60 s: is the sensor driver running?");
            }
            continue;
        };
        idle_since = Instant::now();
        if let Some(prev) = node.last_command() {
            if s.seq == prev.sensor_seq {
                command_out.send(prev)?; // a re-sent sample: answer again
                continue;
            }
            if s.seq < prev.sensor_seq {
                continue; // stale
            }
        }
        while let Some(op) = operator_in.try_recv()? {
            node.on_operator(&op);
        }
        while let Some(e) = estimate_in.try_recv()? {
            node.on_estimate(&e);
        }
        let answer = node.on_sample(&s);
        if let Some(p) = answer.protocol {
            protocol_out.send(p)?;
        }
        command_out.send(answer.command)?;
        t_s = answer.t_s;
    }
    let wall_s = wall_start.elapsed().as_secs_f64();
    info!(
        "controller: stopped at sim {t_s:.1} s (wall {wall_s:.1} s, {:.0}× real time)",
        t_s / wall_s.max(1e-9)
    );
    Ok(())
}
