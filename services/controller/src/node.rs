//! The controller as a node: a plain type stepped sample by sample, with no
//! IPC inside. The process (`main.rs`) and the in-process simulation
//! (`exo-sim`) drive it the same way:
//!
//! 1. [`ControllerNode::on_operator`] and [`ControllerNode::on_estimate`]
//!    for what has arrived;
//! 2. [`ControllerNode::on_sample`] for each fresh sample: the protocol
//!    state to publish (when it changed, or once a second) and the command,
//!    which go out in that order (the plant applies the protocol state when
//!    the command's motor torque reaches it, so in lockstep it takes effect
//!    at the same tick in every run);
//! 3. [`ControllerNode::finished`]: the protocol is over (0.1 s after its
//!    end), and the process exits.

use exo_config::RunConfig;
use exo_messages::{
    ActuatorCommand, ControlMode, ImpedanceEstimate, OperatorCommand, ProtocolState, SensorSample,
};
use tracing::{error, info, warn};

use crate::controller::{Mode, OperatorOutcome};
use crate::{Controller, ControllerError, Fault, TickInput};

/// The wire code of a controller mode (`exo_messages::ControlMode`).
pub fn mode_code(m: Mode) -> ControlMode {
    match m {
        Mode::Run => ControlMode::Run,
        Mode::SafeGravityOnly => ControlMode::SafeGravityOnly,
        Mode::SafeZeroTorque => ControlMode::SafeZeroTorque,
        Mode::Done => ControlMode::Done,
    }
}

/// What the controller publishes for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Answer {
    /// The protocol state, when it changed or a second has passed since it
    /// was last published; goes out before the command.
    pub protocol: Option<ProtocolState>,
    /// The command answering the sample.
    pub command: ActuatorCommand,
    /// Protocol time (s).
    pub t_s: f64,
}

/// The controller with its publishing bookkeeping, one sample per step.
pub struct ControllerNode {
    controller: Controller,
    adopt_recommended_f: bool,
    rate_hz: f64,
    last: Option<ActuatorCommand>,
    last_protocol: (u32, u32, u32),
    last_protocol_tick: u64,
    reported: Option<Fault>,
    latched_at: Option<u64>,
    done_ticks: u64,
    finished: bool,
}

impl ControllerNode {
    /// The controller of run `cfg`.
    pub fn new(cfg: &RunConfig) -> Result<Self, ControllerError> {
        Ok(ControllerNode {
            controller: Controller::from_config(cfg)?,
            adopt_recommended_f: cfg.controller.adopt_recommended_f,
            rate_hz: cfg.run.rate_hz,
            last: None,
            last_protocol: (u32::MAX, u32::MAX, u32::MAX),
            last_protocol_tick: 0,
            reported: None,
            latched_at: None,
            done_ticks: 0,
            finished: false,
        })
    }

    /// The controller itself.
    pub fn controller(&self) -> &Controller {
        &self.controller
    }

    /// The last command sent (to answer a re-sent sample again).
    pub fn last_command(&self) -> Option<ActuatorCommand> {
        self.last
    }

    /// Samples answered so far.
    pub fn answered(&self) -> u64 {
        self.last.map_or(0, |c| c.seq + 1)
    }

    /// Whether the protocol is over and the process should exit.
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// Raises a fault found outside a sample (e.g. samples stopped).
    pub fn raise(&mut self, fault: Fault) {
        self.controller.raise(fault);
    }

    /// Takes an operator command ([`Controller::on_operator`] decides); logs
    /// the outcome, a refusal as a warning.
    pub fn on_operator(&mut self, op: &OperatorCommand) -> OperatorOutcome {
        let outcome = self.controller.on_operator(op);
        if outcome.is_refusal() {
            warn!("controller: operator command seq {}: {outcome}", op.seq);
        } else {
            info!("controller: operator command seq {}: {outcome}", op.seq);
        }
        if let OperatorOutcome::FaultReset { cleared: Some(_) } = outcome {
            self.reported = None;
        }
        outcome
    }

    /// Takes the identifier's estimate: adopts its recommended f when the
    /// run asks for it (`controller.adopt_recommended_f`).
    pub fn on_estimate(&mut self, e: &ImpedanceEstimate) {
        if self.adopt_recommended_f
            && e.recommended_f > 0.0
            && self.controller.adopt_fractional_order(e.recommended_f)
        {
            info!(
                "controller: adopted the identifier's recommended f = {:.3}",
                e.recommended_f
            );
        }
    }

    /// Answers one fresh sample.
    pub fn on_sample(&mut self, s: &SensorSample) -> Answer {
        let tick = self.controller.tick(&TickInput {
            seq: s.seq,
            theta_e_rad: s.theta_e,
            omega_e_rad_s: s.omega_e,
            tau_c_nm: s.tau_c,
            tau_s_nm: s.tau_s,
            status: s.status,
        });
        let p = tick.protocol;
        let key = (p.experiment, p.period, p.phase as u32);
        let mut protocol = None;
        if key != self.last_protocol || s.seq >= self.last_protocol_tick + self.rate_hz as u64 {
            protocol = Some(ProtocolState {
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
            });
            if key != self.last_protocol && p.experiment == 0 && !p.done {
                info!(
                    "controller: protocol stopped; holding gravity compensation (sim {:.1} s)",
                    tick.t_s
                );
            }
            if (key.0, key.1) != (self.last_protocol.0, self.last_protocol.1) && p.experiment > 0 {
                info!(
                    "controller: experiment {} period {} (ω = {:.2} rad/s, {:.1} Nm, α = {}), sim {:.1} s",
                    p.experiment, p.period, p.omega_rad_s, p.amplitude_nm, p.alpha, tick.t_s
                );
            }
            self.last_protocol = key;
            self.last_protocol_tick = s.seq;
        }
        let command = ActuatorCommand {
            seq: self.last.map_or(0, |c| c.seq + 1),
            stamp_ns: s.stamp_ns,
            sensor_seq: s.seq,
            tau_d: tick.tau_d_nm,
            tau_gravity: tick.tau_gravity_nm,
            tau_amplification: tick.tau_amplification_nm,
            tau_bias: tick.tau_bias_nm,
            tau_excitation: tick.tau_excitation_nm,
            mode: mode_code(tick.mode).as_u32(),
            ..Default::default()
        };
        self.last = Some(command);
        if tick.fault != self.reported {
            if let Some(f) = tick.fault {
                error!("controller: safe state latched at sample {}: {f}", s.seq);
                self.latched_at = Some(s.seq);
            }
            self.reported = tick.fault;
        }
        if tick.protocol_over() {
            self.done_ticks += 1;
            if self.done_ticks >= (self.rate_hz / 10.0) as u64 && !self.finished {
                self.finished = true;
                match (tick.mode, self.latched_at) {
                    (Mode::Done, _) | (_, None) => {
                        info!("controller: protocol done at sim {:.1} s", tick.t_s)
                    }
                    (_, Some(at)) => warn!(
                        "controller: protocol over at sim {:.1} s with the safe state latched since sample {at}: what came after ran without excitation or amplification",
                        tick.t_s
                    ),
                }
            }
        }
        Answer {
            protocol,
            command,
            t_s: tick.t_s,
        }
    }
}
