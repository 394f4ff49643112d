//! `exo-controller` as a process: its ports around [`ControllerNode`],
//! stepped by the one runner (`exo_service_kit::runner`). Each step waits
//! (bounded, sleeping in the kernel until a sample's wake-up) for a sample
//! and answers it; the process exits 0 when the protocol is done.
//!
//! In real time, no sample within `safety.sample_deadline_ms` latches the
//! safe state once the stream is established (0.1 s of samples answered);
//! in lockstep a stalled loop is the plant's or the driver's to report.
//!
//! Operator commands (`<instance>/operator`, e.g. from `exo op`) and the
//! identifier's estimates are taken before each sample is answered; the
//! node decides. A stopped protocol holds gravity compensation and does
//! not end the run.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use exo_config::TimingMode;
use exo_messages::channels::ProcessName;
use exo_messages::{
    ActuatorCommand, ImpedanceEstimate, OperatorCommand, ProtocolState, SensorSample,
};
use exo_service_kit::channels::{COMMAND, IDENTIFIER_ESTIMATE, OPERATOR, PROTOCOL, SENSOR};
use exo_service_kit::ipc::{Connect, Inbox, Outbox};
use exo_service_kit::runner::{Context, Flow, Process};
use exo_service_kit::{RealtimeProcess, ServiceArgs, StopFlag};
use tracing::info;

use crate::node::ControllerNode;
use crate::Fault;

/// The controller process.
pub struct ControllerProcess {
    node: ControllerNode,
    sensor_in: Inbox<SensorSample>,
    operator_in: Inbox<OperatorCommand>,
    command_out: Outbox<ActuatorCommand>,
    protocol_out: Outbox<ProtocolState>,
    estimate_in: Inbox<ImpedanceEstimate>,
    lockstep: bool,
    wait: Duration,
    arm_after: u64,
    idle_since: Instant,
    wall_start: Instant,
    t_s: f64,
}

impl Process for ControllerProcess {
    type Args = ServiceArgs;
    const NAME: ProcessName = ProcessName::Controller;
    const REALTIME: Option<RealtimeProcess> = Some(RealtimeProcess::Controller);

    fn open(cx: Context<'_, ServiceArgs>) -> Result<Self> {
        let (cfg, ipc) = (cx.cfg, cx.ipc);
        let sensor_in = ipc.inbox(SENSOR, 64)?.with_spin(cfg.lockstep_spin());
        // The operator inbox is opened before the protocol outbox: `exo op`
        // takes a publisher on the protocol channel as the sign that the
        // controller's operator subscriber exists.
        let operator_in = ipc.inbox(OPERATOR, 16)?;
        let command_out = ipc.outbox(COMMAND)?;
        let protocol_out = ipc.outbox(PROTOCOL)?;
        let estimate_in = ipc.inbox(IDENTIFIER_ESTIMATE, 16)?;
        let node = ControllerNode::new(cfg)?;
        let lockstep = cfg.run.timing == TimingMode::Lockstep;
        info!(
            "controller: {} (experiments {:?}), protocol {:.1} s simulated",
            cfg.subject().name,
            cfg.protocol.experiments,
            node.controller().protocol().duration_s()
        );
        Ok(ControllerProcess {
            node,
            sensor_in,
            operator_in,
            command_out,
            protocol_out,
            estimate_in,
            lockstep,
            wait: Duration::from_secs_f64(
                if lockstep {
                    cfg.safety.lockstep_timeout_ms
                } else {
                    cfg.safety.sample_deadline_ms
                } / 1000.0,
            ),
            // The sample deadline is armed once the stream is established
            // (0.1 s of samples answered): start-up jitter of the other
            // processes is not a fault.
            arm_after: (cfg.run.rate_hz / 10.0).ceil() as u64,
            idle_since: Instant::now(),
            wall_start: Instant::now(),
            t_s: 0.0,
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![
            &self.sensor_in,
            &self.command_out,
            &self.protocol_out,
            &self.operator_in,
            &self.estimate_in,
        ]
    }

    fn step(&mut self, _stop: &StopFlag) -> Result<Flow> {
        let Some(s) = self.sensor_in.recv_timeout(self.wait)? else {
            if self.node.answered() >= self.arm_after && !self.lockstep {
                self.node.raise(Fault::SampleTimeout);
            }
            if self.idle_since.elapsed() > Duration::from_secs(60) {
                bail!("no sensor sample for 60 s: is the sensor driver running?");
            }
            return Ok(Flow::Continue);
        };
        self.idle_since = Instant::now();
        if let Some(prev) = self.node.last_command() {
            if s.seq == prev.sensor_seq {
                self.command_out.send(prev)?; // a re-sent sample: answer again
                return Ok(Flow::Continue);
            }
            if s.seq < prev.sensor_seq {
                return Ok(Flow::Continue); // stale
            }
        }
        while let Some(op) = self.operator_in.try_recv()? {
            self.node.on_operator(&op);
        }
        while let Some(e) = self.estimate_in.try_recv()? {
            self.node.on_estimate(&e);
        }
        let answer = self.node.on_sample(&s);
        if let Some(p) = answer.protocol {
            self.protocol_out.send(p)?;
        }
        self.command_out.send(answer.command)?;
        self.t_s = answer.t_s;
        Ok(if self.node.finished() {
            Flow::Done
        } else {
            Flow::Continue
        })
    }

    fn finish(self) -> Result<()> {
        let wall_s = self.wall_start.elapsed().as_secs_f64();
        info!(
            "controller: stopped at sim {:.1} s (wall {wall_s:.1} s, {:.0}× real time)",
            self.t_s,
            self.t_s / wall_s.max(1e-9)
        );
        Ok(())
    }
}
