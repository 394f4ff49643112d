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
    ActuatorCommand, ControlMode, ImpedanceEstimate, OperatorCommand, ProtocolPhase, ProtocolState,
    SensorSample,
};
use tracing::{error, info, warn};

use crate::controller::{OperatorOutcome, StopNews};
use crate::{Controller, ControllerError, Fault, TickInput};

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
    /// (experiment, period, phase) of the last protocol state published; `None` before the first.
    last_protocol: Option<(u32, u32, ProtocolPhase)>,
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
            last_protocol: None,
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

    /// Takes the identifier's estimate: with `protocol.stop_when`, whether
    /// its experiment's K and H are known ([`crate::Controller::on_estimate`];
    /// logged when that changes), and adopts its recommended f when the
    /// run asks for it (`controller.adopt_recommended_f`).
    pub fn on_estimate(&mut self, e: &ImpedanceEstimate) {
        match self.controller.on_estimate(e) {
            Some(StopNews::Known) => info!(
                "controller: experiment {}: K = {:.2} ± {:.2}, H = {:.2} ± {:.2} Nm/rad (standard errors, {} lines) within protocol.stop_when: its analysis ends a whole period after these data",
                e.experiment, e.k_h, e.k_h_se, e.h_h, e.h_h_se, e.n_points
            ),
            Some(StopNews::NoLongerKnown) => info!(
                "controller: experiment {}: K and H no longer within protocol.stop_when; its analysis goes on",
                e.experiment
            ),
            Some(StopNews::Unchanged { .. }) | None => {}
        }
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
            stamp_ns: s.stamp_ns,
            theta_e_rad: s.theta_e,
            omega_e_rad_s: s.omega_e,
            tau_c_nm: s.tau_c,
            tau_s_nm: s.tau_s,
            status: s.status,
        });
        let p = tick.protocol;
        let key = (p.experiment, p.period, p.phase);
        let changed = self.last_protocol != Some(key);
        let mut protocol = None;
        if changed || s.seq >= self.last_protocol_tick + self.rate_hz as u64 {
            protocol = Some(ProtocolState {
                experiment: p.experiment,
                period: p.period,
                phase: p.phase.as_u32(),
                omega: p.omega_rad_s,
                amplitude: p.amplitude_nm,
                alpha: p.alpha,
                load_kg: p.load_kg,
                grip_kg: p.grip_kg,
                bias_nm: p.bias_nm,
                stamp_ns: s.stamp_ns,
                ..Default::default()
            });
            if changed && p.experiment == 0 && !p.done {
                info!(
                    "controller: protocol stopped; holding gravity compensation (sim {:.1} s)",
                    tick.t_s
                );
            }
            let new_period = self.last_protocol.map(|l| (l.0, l.1)) != Some((key.0, key.1));
            if new_period && p.experiment > 0 {
                info!(
                    "controller: experiment {} period {} (ω = {:.2} rad/s, {:.1} Nm, α = {}), sim {:.1} s",
                    p.experiment, p.period, p.omega_rad_s, p.amplitude_nm, p.alpha, tick.t_s
                );
            }
            self.last_protocol = Some(key);
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
            mode: tick.mode.as_u32(),
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
                    (ControlMode::Done, _) | (_, None) => {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> RunConfig {
        let mut c = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        c.protocol.experiments = vec![1];
        c.protocol.periods = Some(vec![1]);
        c
    }

    fn sample(seq: u64) -> SensorSample {
        SensorSample {
            seq,
            stamp_ns: seq * 1_000_000,
            theta_e: 0.3,
            ..Default::default()
        }
    }

    #[test]
    fn the_protocol_goes_out_when_it_changes_and_once_a_second_and_commands_number_the_samples() {
        let c = cfg();
        let mut n = ControllerNode::new(&c).unwrap();
        let end = (n.controller().protocol().duration_s() * c.run.rate_hz) as u64;
        let mut published = Vec::new();
        for seq in 0..end + 500 {
            let a = n.on_sample(&sample(seq));
            assert_eq!(a.command.seq, seq, "one command per sample, numbered");
            assert_eq!(a.command.sensor_seq, seq);
            assert_eq!(a.command.stamp_ns, seq * 1_000_000);
            assert_eq!(n.last_command(), Some(a.command));
            assert_eq!(n.answered(), seq + 1);
            if let Some(p) = a.protocol {
                assert_eq!(p.stamp_ns, a.command.stamp_ns);
                published.push((seq, p));
            }
            if n.finished() {
                // Finished 0.1 s (100 ticks) after the protocol is over.
                let done_at = published
                    .iter()
                    .find(|(_, p)| {
                        p.experiment == 0 && p.protocol_phase() == Some(ProtocolPhase::Idle)
                    })
                    .map(|(s, _)| *s);
                assert!(done_at.is_some_and(|d| seq >= d + 99), "{seq} {done_at:?}");
                break;
            }
        }
        assert!(n.finished(), "the protocol never finished");
        // Every phase change went out at the sample it happened, and
        // between changes a repeat at least once a second, never more often.
        for w in published.windows(2) {
            let ((s0, p0), (s1, p1)) = (w[0], w[1]);
            let same = (p0.experiment, p0.period, p0.phase) == (p1.experiment, p1.period, p1.phase);
            if same {
                assert_eq!(s1 - s0, 1000, "a repeat is a second after the last");
            } else {
                assert!(s1 - s0 <= 1000);
            }
        }
        let phases: Vec<_> = published.iter().map(|(_, p)| p.protocol_phase()).collect();
        for phase in [
            ProtocolPhase::RampIn,
            ProtocolPhase::Settling,
            ProtocolPhase::Analysis,
            ProtocolPhase::RampOut,
        ] {
            assert!(phases.contains(&Some(phase)), "{phase:?} never published");
        }
        let analysis = published
            .iter()
            .find(|(_, p)| p.protocol_phase() == Some(ProtocolPhase::Analysis))
            .unwrap()
            .1;
        assert_eq!(
            (analysis.omega, analysis.amplitude, analysis.alpha),
            (2.0, 2.0, 1.0)
        );
        // The run file's one experiment and period, named in what goes out
        // (the recorder and the identifier key their windows by them).
        assert_eq!((analysis.experiment, analysis.period), (1, 1));
        for (_, p) in &published {
            let phase = p.protocol_phase();
            if phase != Some(ProtocolPhase::Idle) {
                assert_eq!((p.experiment, p.period), (1, 1), "{phase:?}");
            }
        }
    }

    #[test]
    fn a_fault_is_commanded_in_the_safe_mode_and_a_reset_clears_it() {
        let mut n = ControllerNode::new(&cfg()).unwrap();
        n.on_sample(&sample(0));
        n.raise(Fault::SampleTimeout);
        let a = n.on_sample(&sample(1));
        assert_eq!(a.command.control_mode(), Some(ControlMode::SafeGravityOnly));
        let outcome = n.on_operator(&OperatorCommand {
            seq: 1,
            kind: exo_messages::OperatorCommandKind::ResetFault.as_u32(),
            ..Default::default()
        });
        assert_eq!(
            outcome,
            OperatorOutcome::FaultReset {
                cleared: Some(Fault::SampleTimeout)
            }
        );
        assert_eq!(
            n.on_sample(&sample(2)).command.control_mode(),
            Some(ControlMode::Run)
        );
    }

    fn fractional(n: &ControllerNode) -> bool {
        matches!(
            n.controller().amplifier(),
            crate::Amplifier::Fractional { .. }
        )
    }

    #[test]
    fn an_estimate_is_adopted_only_when_the_run_asks() {
        let estimate = ImpedanceEstimate {
            recommended_f: 0.3,
            ..Default::default()
        };
        let mut c = cfg();
        c.controller.adopt_recommended_f = false;
        let mut n = ControllerNode::new(&c).unwrap();
        n.on_estimate(&estimate);
        assert!(!fractional(&n));
        c.controller.adopt_recommended_f = true;
        let mut n = ControllerNode::new(&c).unwrap();
        n.on_estimate(&ImpedanceEstimate {
            recommended_f: 0.0,
            ..Default::default()
        });
        assert!(!fractional(&n), "f = 0 is no recommendation");
        n.on_estimate(&estimate);
        assert!(fractional(&n));
    }

    #[test]
    fn the_wire_code_of_each_mode() {
        // The wire layout: the modes the controller answers with, as raw codes.
        assert_eq!(ControlMode::Run.as_u32(), 1);
        assert_eq!(ControlMode::SafeGravityOnly.as_u32(), 2);
        assert_eq!(ControlMode::SafeZeroTorque.as_u32(), 3);
        assert_eq!(ControlMode::Done.as_u32(), 5);
    }
}
