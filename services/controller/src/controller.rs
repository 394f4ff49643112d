//! One controller tick: validate the sample, advance the protocol clock,
//! compose and limit the desired torque, latch faults into the safe state.

use exo_config::{
    ExperimentSpec, ExperimentTable, ProtocolMode, ProtocolTiming, RigSettings, RunConfig,
    SafeState,
};
use exo_impedance::loop_shaping::FractionalLayout;
use exo_messages::operator::{KnownKinds, SeenSeqs};
use exo_messages::{ControlMode, MessageError, OperatorCommand, OperatorCommandKind};
use thiserror::Error;

use crate::amplification::Amplifier;
use crate::protocol::{Protocol, ProtocolPoint};
use crate::safety::{Fault, FaultLatch, Limits};

/// Errors building a controller from a configuration.
#[derive(Debug, Error)]
pub enum ControllerError {
    /// The science core refused a design parameter.
    #[error("controller design: {0}")]
    Design(#[from] exo_impedance::ScienceError),
    /// A value the configuration must provide is missing.
    #[error("{0}")]
    Config(String),
}

/// One sensor sample, in physical units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TickInput {
    /// Sample sequence number; time is `(seq − first seq)/rate`.
    pub seq: u64,
    /// θ_e (rad).
    pub theta_e_rad: f64,
    /// ω_e (rad/s).
    pub omega_e_rad_s: f64,
    /// τ_c (Nm), the torque the cuff applies to the human.
    pub tau_c_nm: f64,
    /// τ_s (Nm), the SEA spring torque.
    pub tau_s_nm: f64,
    /// The sample's status bits (`exo_messages::status`): a fault bit
    /// ([`status::FAULT_MASK`](exo_messages::status::FAULT_MASK)) or the
    /// driver's `SAFE_STATE` latches the controller's safe state, so the
    /// two never disagree.
    pub status: u32,
}

/// The controller's answer to one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// The sample answered.
    pub sensor_seq: u64,
    /// Protocol time (s).
    pub t_s: f64,
    /// Desired actuator torque after limits (Nm).
    pub tau_d_nm: f64,
    /// Gravity compensation part (Nm).
    pub tau_gravity_nm: f64,
    /// Amplification part (Nm).
    pub tau_amplification_nm: f64,
    /// Bias part (Nm).
    pub tau_bias_nm: f64,
    /// Excitation part (Nm).
    pub tau_excitation_nm: f64,
    /// What the controller is doing: `Run`, `SafeGravityOnly`,
    /// `SafeZeroTorque` or `Done` (it never answers a sample in `Idle` or
    /// `FaultLatched`); the wire's `ActuatorCommand::mode` as is.
    pub mode: ControlMode,
    /// The latched fault, if any.
    pub fault: Option<Fault>,
    /// Protocol state.
    pub protocol: ProtocolPoint,
}

impl Tick {
    /// Whether the protocol's time is over: in `Done`, or past its end with
    /// a fault latched (which holds the safe state instead of `Done`, and
    /// would otherwise keep the run going with nothing left to do; the
    /// driver holds its own safe state once the controller stops).
    pub fn protocol_over(&self) -> bool {
        self.protocol.done && self.mode != ControlMode::Run
    }
}

/// Where the protocol is, as the operator left it
/// ([`Controller::on_operator`]). Times are counted in ticks of the run
/// (samples since the first), so a restart lands exactly on a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProtocolRun {
    /// The protocol runs from the beginning of step `from_step` (index
    /// into the run's sequence of experiment and period), started at tick
    /// `since_tick`. A run starts as `Running { from_step: 0, since_tick: 0 }`:
    /// the protocol runs on its own from the first sample.
    Running {
        /// The step the protocol (re)started at.
        from_step: usize,
        /// The tick it (re)started at.
        since_tick: u64,
    },
    /// Ramping out after an operator stop, or before an operator start
    /// that came in the middle of a period: bias and excitation of step
    /// `step`, stopped `tau_s` into its period at tick `since_tick`, fade
    /// over the protocol's ramp-out ([`Protocol::stopping`]); then the
    /// protocol starts at step `then`, or is held stopped (`None`).
    RampingOut {
        /// The step that was running.
        step: usize,
        /// Time into its period at the stop (s).
        tau_s: f64,
        /// The tick of the stop.
        since_tick: u64,
        /// The step to start at once ramped out, if a start is pending.
        then: Option<usize>,
    },
    /// Stopped: gravity compensation only (mode `Run`, no bias, excitation
    /// or amplification), until an operator start or the end of the run.
    Stopped {
        /// The step that was running (its load stays on the arm).
        step: usize,
        /// Where a start with experiment 0 resumes: the interrupted step if
        /// it stopped before the end of its analysis window, else the next.
        resume: usize,
    },
}

/// Why an operator command was refused (it changed nothing).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OperatorRefusal {
    /// A start while a fault is latched: reset it first.
    FaultLatched(Fault),
    /// The protocol is over; the run is ending.
    ProtocolOver,
    /// A start with experiment 0 while the protocol runs.
    AlreadyRunning,
    /// A start with experiment 0 after a stop at the protocol's last measured period.
    NothingToResume,
    /// A start at an experiment the run's protocol does not have.
    NotInRun {
        /// The experiment asked for.
        experiment: u32,
        /// The run's experiments (bit `n` = experiment `n`).
        run_experiments: u32,
    },
    /// A start whose experiment number is not a whole number.
    NotWhole {
        /// The value.
        value: f64,
    },
    /// The fractional amplifier could not be designed with this f.
    DesignRejected {
        /// f, after clamping.
        f: f64,
    },
}

/// What [`Controller::on_operator`] did with a command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OperatorOutcome {
    /// The `seq` was handled before; nothing done (receivers act on each `seq` once).
    Repeated {
        /// The sequence number.
        seq: u64,
    },
    /// An unknown kind code; nothing done.
    UnknownKind {
        /// The code.
        code: u32,
    },
    /// A known kind whose `value` is invalid for it (NaN, f outside [0, 1),
    /// experiment outside 0–9); nothing done.
    InvalidValue {
        /// The kind.
        kind: OperatorCommandKind,
        /// The value.
        value: f64,
    },
    /// A valid command refused in the present state; nothing done.
    Refused {
        /// The kind.
        kind: OperatorCommandKind,
        /// Why.
        reason: OperatorRefusal,
    },
    /// The fault latch was cleared.
    FaultReset {
        /// The fault that was latched, if any.
        cleared: Option<Fault>,
    },
    /// The fractional amplifier now runs with order `f`.
    FractionalOrderAdopted {
        /// f as asked.
        asked: f64,
        /// f adopted (clamped to `bounds`).
        f: f64,
        /// The run's `controller.f_bounds`.
        bounds: [f64; 2],
    },
    /// The protocol stops: bias and excitation ramp out over `ramp_out_s`
    /// (0: nothing was applied to ramp out), then gravity compensation is held.
    Stopping {
        /// Experiment that was running.
        experiment: u32,
        /// Its period.
        period: u32,
        /// Ramp-out duration (s).
        ramp_out_s: f64,
    },
    /// The protocol was already stopped (or stopping); nothing to do.
    AlreadyStopped,
    /// The protocol starts at the beginning of `experiment`'s `period`,
    /// after the running period ramps out over `after_s` (0: at once).
    Starting {
        /// Experiment.
        experiment: u32,
        /// Period.
        period: u32,
        /// Ramp-out of the running period first (s).
        after_s: f64,
    },
}

impl OperatorOutcome {
    /// The verdict the operator's console is answered with
    /// ([`exo_messages::OperatorReply`]): a refusal is refused, a repeat a
    /// repeat, everything else (a stop of a stopped protocol included)
    /// accepted.
    pub fn verdict(&self) -> exo_messages::OperatorVerdict {
        use exo_messages::OperatorVerdict;
        match self {
            OperatorOutcome::Repeated { .. } => OperatorVerdict::Repeated,
            o if o.is_refusal() => OperatorVerdict::Refused,
            _ => OperatorVerdict::Accepted,
        }
    }

    /// Whether the command was refused (a warning for the log): an unknown
    /// kind, an invalid value or a refusal. Repeats and "already stopped"
    /// are not warnings.
    pub fn is_refusal(&self) -> bool {
        matches!(
            self,
            OperatorOutcome::UnknownKind { .. }
                | OperatorOutcome::InvalidValue { .. }
                | OperatorOutcome::Refused { .. }
        )
    }
}

/// The experiment numbers of a bit set, e.g. `1, 7`.
struct ExperimentList(u32);

impl std::fmt::Display for ExperimentList {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut first = true;
        for n in (0..32).filter(|n| self.0 & (1 << n) != 0) {
            write!(f, "{}{n}", if first { "" } else { ", " })?;
            first = false;
        }
        Ok(())
    }
}

impl std::fmt::Display for OperatorRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            OperatorRefusal::FaultLatched(fault) => write!(
                f,
                "a fault is latched ({fault}): reset it first (ResetFault)"
            ),
            OperatorRefusal::ProtocolOver => write!(f, "the protocol is over; the run is ending"),
            OperatorRefusal::AlreadyRunning => write!(
                f,
                "the protocol is running; experiment 0 (\"next\") continues a stopped protocol, give an experiment number to restart at one"
            ),
            OperatorRefusal::NothingToResume => write!(
                f,
                "the protocol was stopped after its last measured period: nothing left to resume; give an experiment number to run one again"
            ),
            OperatorRefusal::NotInRun {
                experiment,
                run_experiments,
            } => write!(
                f,
                "experiment {experiment} is not in this run's protocol (protocol.experiments = [{}])",
                ExperimentList(run_experiments)
            ),
            OperatorRefusal::NotWhole { value } => {
                write!(f, "experiment {value} is not a whole number")
            }
            OperatorRefusal::DesignRejected { f: order } => write!(
                f,
                "the fractional amplifier cannot be designed with f = {order}"
            ),
        }
    }
}

impl std::fmt::Display for OperatorOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            OperatorOutcome::Repeated { seq } => {
                write!(f, "already handled (seq {seq}); ignored")
            }
            OperatorOutcome::UnknownKind { code } => write!(
                f,
                "unknown operator command kind {code} refused (known kinds: {KnownKinds}); nothing changed"
            ),
            OperatorOutcome::InvalidValue { kind, value } => {
                let why = match kind {
                    _ if !value.is_finite() => format!("value {value} is not finite"),
                    OperatorCommandKind::AdoptFractionalOrder => {
                        format!("f = {value} is outside [0, 1)")
                    }
                    OperatorCommandKind::StartProtocol => format!(
                        "experiment {value} is outside 1–9 (0 = the next)"
                    ),
                    _ => format!("value {value} is invalid"),
                };
                write!(f, "{kind} refused: {why}; nothing changed")
            }
            OperatorOutcome::Refused { kind, reason } => {
                write!(f, "{kind} refused: {reason}; nothing changed")
            }
            OperatorOutcome::FaultReset { cleared: Some(fault) } => write!(
                f,
                "fault latch reset (was: {fault}); control resumes from the protocol's present state"
            ),
            OperatorOutcome::FaultReset { cleared: None } => {
                write!(f, "fault latch reset (no fault was latched)")
            }
            OperatorOutcome::FractionalOrderAdopted { asked, f: order, bounds } => {
                write!(f, "adopted f = {order}")?;
                if order != asked {
                    write!(
                        f,
                        " (asked {asked}, clamped to controller.f_bounds [{}, {}])",
                        bounds[0], bounds[1]
                    )?;
                }
                Ok(())
            }
            OperatorOutcome::Stopping {
                experiment,
                period,
                ramp_out_s,
            } => {
                write!(f, "protocol stopped at experiment {experiment} period {period}: ")?;
                if ramp_out_s > 0.0 {
                    write!(f, "bias and excitation ramp out over {ramp_out_s} s, then ")?;
                }
                write!(
                    f,
                    "gravity compensation is held (mode Run, no fault) until a StartProtocol or the end of the run"
                )
            }
            OperatorOutcome::AlreadyStopped => write!(f, "the protocol is already stopped"),
            OperatorOutcome::Starting {
                experiment,
                period,
                after_s,
            } => {
                write!(f, "protocol starts at experiment {experiment} period {period}")?;
                if after_s > 0.0 {
                    write!(f, " once the running period has ramped out ({after_s} s)")?;
                }
                Ok(())
            }
        }
    }
}

/// The controller.
#[derive(Debug, Clone)]
pub struct Controller {
    protocol: Protocol,
    run: ProtocolRun,
    operator_seqs: SeenSeqs,
    amplifier: Amplifier,
    limits: Limits,
    latch: FaultLatch,
    /// Whether the last sample carried the driver's `SAFE_STATE`.
    driver_was_safe: bool,
    rig: RigSettings,
    safe_state: SafeState,
    rate_hz: f64,
    first_seq: Option<u64>,
    /// Ticks (samples since the first) of the last tick answered.
    last_tick: Option<u64>,
    previous_tau_d_nm: f64,
    f_bounds: [f64; 2],
    /// What is needed to rebuild the fractional amplifier with a new f.
    design: FractionalLayout,
    gravity_compensation: bool,
}

impl Controller {
    /// Builds the controller of a run configuration.
    pub fn from_config(cfg: &RunConfig) -> Result<Self, ControllerError> {
        let subject = cfg.subject();
        let (protocol, load_kg) = match cfg.protocol.mode {
            ProtocolMode::Identification => {
                let table = cfg.experiment_table();
                let load = cfg
                    .protocol
                    .experiments
                    .first()
                    .and_then(|n| table.get(*n))
                    .map_or(0.0, |e| e.load_kg);
                (
                    Protocol::new(
                        table,
                        &cfg.protocol.experiments,
                        cfg.protocol.periods.as_deref(),
                    ),
                    load,
                )
            }
            ProtocolMode::Voluntary => {
                let v = cfg.voluntary.ok_or_else(|| {
                    ControllerError::Config("voluntary mode needs [voluntary]".into())
                })?;
                let load = cfg
                    .experiment_table()
                    .get(v.experiment)
                    .map_or(4.5, |e| e.load_kg);
                let table = one_period_table(
                    v.duration_s / 2.0,
                    v.duration_s / 2.0,
                    v.grip_kg,
                    v.bias_nm,
                    load,
                    v.experiment,
                );
                (Protocol::new(&table, &[v.experiment], None), load)
            }
            ProtocolMode::Release => {
                let r = cfg.release.ok_or_else(|| {
                    ControllerError::Config("release mode needs [release]".into())
                })?;
                let spec = cfg
                    .experiment_table()
                    .get(r.experiment)
                    .copied()
                    .ok_or_else(|| {
                        ControllerError::Config(format!(
                            "release.experiment {} is not in the experiment table",
                            r.experiment
                        ))
                    })?;
                let table = one_period_table(
                    r.hold_s,
                    r.observe_s,
                    spec.grip_kg,
                    spec.bias_nm,
                    spec.load_kg,
                    r.experiment,
                );
                (Protocol::new(&table, &[r.experiment], None), spec.load_kg)
            }
        };
        let m_e = cfg.exo_inertia_kg_m2(load_kg);
        let design = cfg
            .controller
            .layout(m_e, subject.inertia_kg_m2)
            .map_err(|e| ControllerError::Design(e.source))?;
        let kp = design.kp;
        let amplifier = match cfg.controller.f {
            Some(f) => Amplifier::fractional(
                kp,
                f,
                design.omega_gc_hat_rad_s,
                design.filters,
                design.p1_rad_s,
                design.r_pp,
                cfg.run.rate_hz,
            )?,
            None => Amplifier::Constant { alpha: 1.0 },
        };
        Ok(Controller {
            protocol,
            run: ProtocolRun::Running {
                from_step: 0,
                since_tick: 0,
            },
            operator_seqs: SeenSeqs::default(),
            amplifier,
            limits: Limits::new(&cfg.controller.limits, cfg.run.rate_hz),
            latch: FaultLatch::default(),
            driver_was_safe: false,
            rig: cfg.rig,
            safe_state: cfg.safety.safe_state,
            rate_hz: cfg.run.rate_hz,
            first_seq: None,
            last_tick: None,
            previous_tau_d_nm: 0.0,
            f_bounds: cfg.controller.f_bounds,
            design,
            gravity_compensation: cfg.controller.gravity_compensation,
        })
    }

    /// The protocol this controller runs.
    pub fn protocol(&self) -> &Protocol {
        &self.protocol
    }

    /// The latched fault, if any.
    pub fn fault(&self) -> Option<Fault> {
        self.latch.fault()
    }

    /// Latches a fault detected outside a tick (e.g. a sample timeout).
    pub fn raise(&mut self, fault: Fault) {
        self.latch.raise(fault);
    }

    /// Clears a latched fault (operator command); the amplifier restarts from rest.
    pub fn reset_fault(&mut self) {
        self.latch.reset();
        self.amplifier.reset();
    }

    /// Switches to the fractional amplifier with order `f`, if within the
    /// configured bounds; returns whether it was adopted. Allocation-free.
    pub fn adopt_fractional_order(&mut self, f: f64) -> bool {
        if !(f.is_finite() && f >= self.f_bounds[0] && f <= self.f_bounds[1]) {
            return false;
        }
        let d = self.design;
        match Amplifier::fractional(
            d.kp,
            f,
            d.omega_gc_hat_rad_s,
            d.filters,
            d.p1_rad_s,
            d.r_pp,
            self.rate_hz,
        ) {
            Ok(a) => {
                self.amplifier = a;
                true
            }
            Err(_) => false,
        }
    }

    /// The amplifier in use (constant α, or the fractional order adopted).
    pub fn amplifier(&self) -> &Amplifier {
        &self.amplifier
    }

    /// Where the protocol is, as the operator left it.
    pub fn protocol_run(&self) -> ProtocolRun {
        self.run
    }

    /// Acts on one operator command (`main.rs` only forwards them): each
    /// `seq` once; an unknown kind or a value invalid for its kind is
    /// refused and changes nothing. Allocation-free. What each kind does:
    ///
    /// - `ResetFault`: clears the latched fault ([`Controller::reset_fault`]).
    /// - `AdoptFractionalOrder`: `value` = f, valid in [0, 1), clamped to
    ///   the run's `controller.f_bounds`, adopted for the amplifier.
    /// - `StopProtocol`: bias and excitation ramp to zero over the
    ///   protocol's ramp-out (raised cosine, from the values at the stop;
    ///   at once when there is nothing to ramp: in a rest, or the ramp-in
    ///   of an experiment without bias), then gravity
    ///   compensation alone is held, in mode `Run` and without a fault,
    ///   until a start or the end of the run (the controller does not end
    ///   the run while stopped). Refused once the protocol is over.
    /// - `StartProtocol`: `value` = experiment `n` (1–9) restarts the
    ///   protocol at the first period of experiment `n` (which must be in
    ///   the run's `protocol.experiments`), ramp-in first; the protocol
    ///   then goes on through the run's sequence from there. In the middle
    ///   of a period the running period ramps out first, as for a stop.
    ///   `value` = 0 continues a stopped protocol: with the interrupted
    ///   period again if it stopped before the end of its analysis window,
    ///   else with the next one. Refused while a fault is latched.
    pub fn on_operator(&mut self, cmd: &OperatorCommand) -> OperatorOutcome {
        if !self.operator_seqs.first_time(cmd.seq) {
            return OperatorOutcome::Repeated { seq: cmd.seq };
        }
        let Some(kind) = cmd.command_kind() else {
            return OperatorOutcome::UnknownKind { code: cmd.kind };
        };
        match cmd.validate() {
            Ok(()) => {}
            Err(MessageError::UnknownCode { .. }) => {
                return OperatorOutcome::UnknownKind { code: cmd.kind }
            }
            Err(_) => {
                return OperatorOutcome::InvalidValue {
                    kind,
                    value: cmd.value,
                }
            }
        }
        let refuse = |reason| OperatorOutcome::Refused { kind, reason };
        match kind {
            OperatorCommandKind::ResetFault => {
                let cleared = self.fault();
                self.reset_fault();
                OperatorOutcome::FaultReset { cleared }
            }
            OperatorCommandKind::AdoptFractionalOrder => {
                let [lo, hi] = self.f_bounds;
                let f = cmd.value.clamp(lo, hi);
                if self.adopt_fractional_order(f) {
                    OperatorOutcome::FractionalOrderAdopted {
                        asked: cmd.value,
                        f,
                        bounds: self.f_bounds,
                    }
                } else {
                    refuse(OperatorRefusal::DesignRejected { f })
                }
            }
            OperatorCommandKind::StopProtocol => self.stop(),
            OperatorCommandKind::StartProtocol => {
                if cmd.value.fract() != 0.0 {
                    return refuse(OperatorRefusal::NotWhole { value: cmd.value });
                }
                match self.start(cmd.value as u32) {
                    Ok(outcome) => outcome,
                    Err(reason) => refuse(reason),
                }
            }
        }
    }

    /// The tick the next sample will most likely be (the one after the last).
    fn next_tick(&self) -> u64 {
        self.last_tick.map_or(0, |t| t + 1)
    }

    /// The running step and the time into its period, at tick `tick`
    /// (`None` once the protocol is over).
    fn running_at(&self, from_step: usize, since_tick: u64, tick: u64) -> Option<(usize, f64)> {
        let rel_s = tick.saturating_sub(since_tick) as f64 / self.rate_hz;
        self.protocol.locate_from(from_step, rel_s)
    }

    fn stop(&mut self) -> OperatorOutcome {
        let now = self.next_tick();
        match self.run {
            ProtocolRun::Running {
                from_step,
                since_tick,
            } => {
                let Some((step, tau_s)) = self.running_at(from_step, since_tick, now) else {
                    return OperatorOutcome::Refused {
                        kind: OperatorCommandKind::StopProtocol,
                        reason: OperatorRefusal::ProtocolOver,
                    };
                };
                let (experiment, period) = self.protocol.step(step).unwrap_or((0, 0));
                let quiet = self.protocol.quiet(step, tau_s);
                self.run = if quiet {
                    ProtocolRun::Stopped {
                        step,
                        resume: self.resume_after(step, tau_s),
                    }
                } else {
                    ProtocolRun::RampingOut {
                        step,
                        tau_s,
                        since_tick: now,
                        then: None,
                    }
                };
                OperatorOutcome::Stopping {
                    experiment,
                    period,
                    ramp_out_s: if quiet {
                        0.0
                    } else {
                        self.protocol.ramp_out_s()
                    },
                }
            }
            ProtocolRun::RampingOut {
                step,
                tau_s,
                since_tick,
                then: Some(_),
            } => {
                // A start was pending after this ramp-out: cancel it.
                self.run = ProtocolRun::RampingOut {
                    step,
                    tau_s,
                    since_tick,
                    then: None,
                };
                let (experiment, period) = self.protocol.step(step).unwrap_or((0, 0));
                let elapsed_s = now.saturating_sub(since_tick) as f64 / self.rate_hz;
                OperatorOutcome::Stopping {
                    experiment,
                    period,
                    ramp_out_s: (self.protocol.ramp_out_s() - elapsed_s).max(0.0),
                }
            }
            ProtocolRun::RampingOut { then: None, .. } | ProtocolRun::Stopped { .. } => {
                OperatorOutcome::AlreadyStopped
            }
        }
    }

    fn start(&mut self, experiment: u32) -> Result<OperatorOutcome, OperatorRefusal> {
        if let Some(fault) = self.fault() {
            return Err(OperatorRefusal::FaultLatched(fault));
        }
        let now = self.next_tick();
        // Where the protocol is now: the running step (and the time into
        // it), or the step a start with experiment 0 resumes at.
        let running = match self.run {
            ProtocolRun::Running {
                from_step,
                since_tick,
            } => Some(
                self.running_at(from_step, since_tick, now)
                    .ok_or(OperatorRefusal::ProtocolOver)?,
            ),
            _ => None,
        };
        let target = if experiment == 0 {
            match self.run {
                ProtocolRun::Running { .. } => return Err(OperatorRefusal::AlreadyRunning),
                ProtocolRun::RampingOut { then: Some(t), .. } => t,
                ProtocolRun::RampingOut { step, tau_s, .. } => self.resume_after(step, tau_s),
                ProtocolRun::Stopped { resume, .. } => resume,
            }
        } else {
            self.protocol
                .first_step_of(experiment)
                .ok_or(OperatorRefusal::NotInRun {
                    experiment,
                    run_experiments: self.protocol.experiment_set(),
                })?
        };
        let (experiment, period) = self
            .protocol
            .step(target)
            .ok_or(OperatorRefusal::NothingToResume)?;
        let after_s = match (self.run, running) {
            (_, Some((step, tau_s))) if !self.protocol.quiet(step, tau_s) => {
                self.run = ProtocolRun::RampingOut {
                    step,
                    tau_s,
                    since_tick: now,
                    then: Some(target),
                };
                self.protocol.ramp_out_s()
            }
            (
                ProtocolRun::RampingOut {
                    step,
                    tau_s,
                    since_tick,
                    ..
                },
                _,
            ) => {
                self.run = ProtocolRun::RampingOut {
                    step,
                    tau_s,
                    since_tick,
                    then: Some(target),
                };
                let elapsed_s = now.saturating_sub(since_tick) as f64 / self.rate_hz;
                (self.protocol.ramp_out_s() - elapsed_s).max(0.0)
            }
            _ => {
                self.start_now(target, now);
                0.0
            }
        };
        Ok(OperatorOutcome::Starting {
            experiment,
            period,
            after_s,
        })
    }

    /// Where a start with experiment 0 resumes after a stop `tau_s` into
    /// step `step`: that step again if its analysis window was not over,
    /// else the next.
    fn resume_after(&self, step: usize, tau_s: f64) -> usize {
        step + usize::from(!self.protocol.before_analysis_end(tau_s))
    }

    /// Starts the protocol at the beginning of step `step` at tick `tick`;
    /// the amplifier starts from rest.
    fn start_now(&mut self, step: usize, tick: u64) {
        self.run = ProtocolRun::Running {
            from_step: step,
            since_tick: tick,
        };
        self.amplifier.reset();
    }

    /// The protocol's state at tick `tick`, after the transitions due by
    /// then (a ramp-out that has ended); and whether it is held stopped.
    fn protocol_at(&mut self, tick: u64) -> (ProtocolPoint, bool) {
        if let ProtocolRun::RampingOut {
            step,
            tau_s,
            since_tick,
            then,
        } = self.run
        {
            let elapsed_s = tick.saturating_sub(since_tick) as f64 / self.rate_hz;
            if elapsed_s >= self.protocol.ramp_out_s() {
                match then {
                    Some(target) => self.start_now(target, tick),
                    None => {
                        self.run = ProtocolRun::Stopped {
                            step,
                            resume: self.resume_after(step, tau_s),
                        };
                    }
                }
            }
        }
        match self.run {
            ProtocolRun::Running {
                from_step,
                since_tick,
            } => {
                let rel_s = tick.saturating_sub(since_tick) as f64 / self.rate_hz;
                (self.protocol.at_from(from_step, rel_s), false)
            }
            ProtocolRun::RampingOut {
                step,
                tau_s,
                since_tick,
                ..
            } => {
                let elapsed_s = tick.saturating_sub(since_tick) as f64 / self.rate_hz;
                (self.protocol.stopping(step, tau_s, elapsed_s), false)
            }
            ProtocolRun::Stopped { step, .. } => (self.protocol.held(step), true),
        }
    }

    /// Answers one sample. Allocation-free; the returned torque is always
    /// finite and within the torque and rate limits.
    pub fn tick(&mut self, s: &TickInput) -> Tick {
        let first = *self.first_seq.get_or_insert(s.seq);
        let tick = s.seq.saturating_sub(first);
        let t_s = tick as f64 / self.rate_hz;
        self.last_tick = Some(tick);
        self.validate(s);
        let (p, held) = self.protocol_at(tick);
        let theta_for_gravity = if s.theta_e_rad.is_finite() {
            s.theta_e_rad
        } else {
            0.0
        };
        let gravity = if self.gravity_compensation {
            self.rig.gravity_torque_nm(theta_for_gravity, p.load_kg)
        } else {
            0.0
        };
        // The driver's latched safe state is followed, not latched here:
        // it lasts exactly as long as the driver's (an operator reset clears
        // both), so the two never disagree whichever hears the reset first.
        let driver_safe = s.status & exo_messages::status::SAFE_STATE != 0;
        if self.driver_was_safe && !driver_safe {
            self.amplifier.reset();
        }
        self.driver_was_safe = driver_safe;
        let (mode, tau_g, tau_a, tau_b, tau_x) = if self.latch.is_latched() || driver_safe {
            match self.safe_state {
                SafeState::GravityOnly => (ControlMode::SafeGravityOnly, gravity, 0.0, 0.0, 0.0),
                SafeState::ZeroTorque => (ControlMode::SafeZeroTorque, 0.0, 0.0, 0.0, 0.0),
            }
        } else if p.done {
            (ControlMode::Done, gravity, 0.0, 0.0, 0.0)
        } else if held {
            // Stopped by the operator: gravity compensation alone, no fault.
            (ControlMode::Run, gravity, 0.0, 0.0, 0.0)
        } else {
            self.amplifier.set_constant_alpha(p.alpha);
            let tau_a = self.amplifier.step(s.tau_c_nm);
            (
                ControlMode::Run,
                gravity,
                tau_a,
                p.tau_bias_nm,
                p.tau_excitation_nm,
            )
        };
        let tau_d = self
            .limits
            .clamp(tau_g + tau_a + tau_b + tau_x, self.previous_tau_d_nm);
        self.previous_tau_d_nm = tau_d;
        Tick {
            sensor_seq: s.seq,
            t_s,
            tau_d_nm: tau_d,
            tau_gravity_nm: tau_g,
            tau_amplification_nm: tau_a,
            tau_bias_nm: tau_b,
            tau_excitation_nm: tau_x,
            mode,
            fault: self
                .latch
                .fault()
                .or(driver_safe.then_some(Fault::DriverSafeState)),
            protocol: p,
        }
    }

    fn validate(&mut self, s: &TickInput) {
        for (field, v) in [
            ("theta_e", s.theta_e_rad),
            ("omega_e", s.omega_e_rad_s),
            ("tau_c", s.tau_c_nm),
            ("tau_s", s.tau_s_nm),
        ] {
            if !v.is_finite() {
                self.latch.raise(Fault::NonFiniteSample { field });
                return;
            }
        }
        if s.status & exo_messages::status::FAULT_MASK != 0 {
            self.latch.raise(Fault::SensorStatus { status: s.status });
        }
        let [lo, hi] = self.limits.theta_rad;
        if s.theta_e_rad < lo || s.theta_e_rad > hi {
            self.latch.raise(Fault::AngleOutOfRange {
                theta_rad: s.theta_e_rad,
            });
        }
        if s.tau_c_nm.abs() > self.limits.tau_c_nm {
            self.latch.raise(Fault::InteractionTorqueOutOfRange {
                tau_c_nm: s.tau_c_nm,
            });
        }
    }
}

/// A one-period protocol without perturbation (amplitude 0), for the
/// voluntary-motion experiments and the spring-release test: the bias ramps
/// in over 1 s, `settling_s` follow (the motion settles, or the spring stays
/// attached), then the `analysis_s` window (the second half of the motion,
/// or the response after the release), and the bias ramps out over 1 s.
fn one_period_table(
    settling_s: f64,
    analysis_s: f64,
    grip_kg: f64,
    bias_nm: f64,
    load_kg: f64,
    number: u32,
) -> ExperimentTable {
    ExperimentTable {
        periods: 1,
        amplitude_boost_from_period: 2,
        amplitude_boost: 1.0,
        frequency_step: 1.0,
        timing: ProtocolTiming {
            ramp_in_s: 1.0,
            settling_s,
            analysis_s,
            ramp_out_s: 1.0,
            rest_s: 0.0,
        },
        experiment: vec![ExperimentSpec {
            number,
            alpha: 1.0,
            load_kg,
            grip_kg,
            bias_nm,
            amplitude_nm: 0.0,
            start_omega_rad_s: 1.0,
        }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> RunConfig {
        RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap()
    }

    fn sample(seq: u64, theta: f64, tau_c: f64) -> TickInput {
        TickInput {
            seq,
            theta_e_rad: theta,
            omega_e_rad_s: 0.0,
            tau_c_nm: tau_c,
            tau_s_nm: 0.0,
            status: 0,
        }
    }

    #[test]
    fn gravity_compensation_cancels_the_rig_model() {
        let c = cfg();
        let mut k = Controller::from_config(&c).unwrap();
        // Run long enough for the rate limiter to reach the target.
        let mut t = None;
        for seq in 0..200 {
            t = Some(k.tick(&sample(seq, 0.5, 0.0)));
        }
        let t = t.unwrap();
        let expected = c.rig.gravity_torque_nm(0.5, 4.5);
        assert!((t.tau_gravity_nm - expected).abs() < 1e-12);
        assert_eq!(t.mode, ControlMode::Run);
    }

    #[test]
    fn nan_sample_latches_the_safe_state_and_torque_stays_finite() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        for seq in 0..10 {
            k.tick(&sample(seq, 0.3, 1.0));
        }
        let t = k.tick(&sample(10, 0.3, f64::NAN));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        assert_eq!(t.fault, Some(Fault::NonFiniteSample { field: "tau_c" }));
        assert!(t.tau_d_nm.is_finite());
        // Latched: a good sample does not clear it.
        let t = k.tick(&sample(11, 0.3, 1.0));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        assert_eq!(t.tau_amplification_nm, 0.0);
        k.reset_fault();
        assert_eq!(k.tick(&sample(12, 0.3, 1.0)).mode, ControlMode::Run);
    }

    #[test]
    fn a_latched_run_is_over_when_the_protocol_is() {
        let c = cfg();
        let mut k = Controller::from_config(&c).unwrap();
        let end = (k.protocol().duration_s() * c.run.rate_hz).ceil() as u64;
        k.tick(&sample(0, 0.3, 0.0));
        let t = k.tick(&sample(1, 0.3, f64::NAN));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        assert!(!t.protocol_over());
        let t = k.tick(&sample(end - 10, 0.3, 0.0));
        assert!(!t.protocol_over(), "before the end");
        let t = k.tick(&sample(end + 10, 0.3, 0.0));
        assert_eq!(t.mode, ControlMode::SafeGravityOnly, "still latched");
        assert!(t.protocol_over());
        // Unlatched, the end is `Done`.
        let mut k = Controller::from_config(&c).unwrap();
        assert!(!k.tick(&sample(0, 0.3, 0.0)).protocol_over());
        let t = k.tick(&sample(end + 10, 0.3, 0.0));
        assert_eq!(t.mode, ControlMode::Done);
        assert!(t.protocol_over());
    }

    #[test]
    fn the_controller_follows_a_fault_bit_and_the_drivers_safe_state() {
        use exo_messages::status;
        // Bits that are not faults (a replayed, stale or skipped-after sample) change nothing.
        let mut k = Controller::from_config(&cfg()).unwrap();
        for (seq, bits) in [status::REPLAY, status::STALE, status::FRAMES_SKIPPED]
            .into_iter()
            .enumerate()
        {
            let mut s = sample(seq as u64, 0.3, 0.0);
            s.status = bits;
            assert_eq!(k.tick(&s).mode, ControlMode::Run, "{bits:#x}");
        }
        for bits in [
            status::ENCODER_FAULT,
            status::FT_FAULT,
            status::SEA_FAULT,
            status::BUS_FAULT,
        ] {
            let mut k = Controller::from_config(&cfg()).unwrap();
            let mut s = sample(0, 0.3, 0.0);
            s.status = bits;
            let t = k.tick(&s);
            assert_eq!(t.fault, Some(Fault::SensorStatus { status: bits }));
            assert_eq!(t.mode, ControlMode::SafeGravityOnly);
        }
        // The driver latched: the controller follows it for as long as its
        // samples say so (an operator reset clears both), never in Run.
        let mut k = Controller::from_config(&cfg()).unwrap();
        k.tick(&sample(0, 0.3, 0.0));
        for seq in 1..50 {
            let mut s = sample(seq, 0.3, 1.0);
            s.status = status::SAFE_STATE;
            let t = k.tick(&s);
            assert_eq!(t.fault, Some(Fault::DriverSafeState));
            assert_eq!(t.mode, ControlMode::SafeGravityOnly);
            assert_eq!(t.tau_amplification_nm, 0.0);
        }
        assert_eq!(k.fault(), None, "followed, not latched here");
        let t = k.tick(&sample(50, 0.3, 0.0));
        assert_eq!((t.mode, t.fault), (ControlMode::Run, None));
    }

    #[test]
    fn the_amplifier_restarts_from_rest_when_the_drivers_safe_state_ends() {
        let fractional = || {
            let mut k = Controller::from_config(&cfg()).unwrap();
            assert!(k.adopt_fractional_order(0.5));
            k
        };
        // A safe state of one sample or of ten.
        for safe_ticks in [1, 10] {
            let mut k = fractional();
            for seq in 0..100 {
                k.tick(&sample(seq, 0.3, 1.0));
            }
            for seq in 100..100 + safe_ticks {
                let mut s = sample(seq, 0.3, 1.0);
                s.status = exo_messages::status::SAFE_STATE;
                k.tick(&s);
            }
            // After the safe state the amplifier answers as a fresh one
            // does, and keeps its state from then on.
            let mut fresh = fractional();
            for i in 0..3 {
                let after = k
                    .tick(&sample(100 + safe_ticks + i, 0.3, 1.0))
                    .tau_amplification_nm;
                let expected = fresh.tick(&sample(i, 0.3, 1.0)).tau_amplification_nm;
                assert_eq!(after, expected, "tick {i} after {safe_ticks} safe");
            }
        }
        let mut once = fractional();
        let first = once.tick(&sample(0, 0.3, 1.0)).tau_amplification_nm;
        let second = once.tick(&sample(1, 0.3, 1.0)).tau_amplification_nm;
        assert_ne!(first, second, "the filter has a state to restart");
    }

    #[test]
    fn out_of_range_angle_and_interaction_torque_fault() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert_eq!(
            k.tick(&sample(0, 3.0, 0.0)).mode,
            ControlMode::SafeGravityOnly
        );
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert!(matches!(
            k.tick(&sample(0, 0.3, 500.0)).fault,
            Some(Fault::InteractionTorqueOutOfRange { .. })
        ));
    }

    #[test]
    fn constant_alpha_amplifies_per_experiment() {
        let mut c = cfg();
        c.protocol.experiments = vec![3];
        let mut k = Controller::from_config(&c).unwrap();
        // Experiment 3 has α = 4: τ_a = −3 τ_c.
        let t = k.tick(&sample(0, 0.0, 0.1));
        assert!((t.tau_amplification_nm + 0.3).abs() < 1e-12, "{t:?}");
    }

    /// The command is gravity compensation + amplification + bias +
    /// excitation, each as published, while neither limit binds; with
    /// gravity and amplification both non-zero (a product or a difference of
    /// two of them would pass a test where one is 0). Issue 23: the
    /// cargo-mutants sample left `τ_g + τ_a` → `τ_g · τ_a` alive.
    #[test]
    fn the_command_is_the_sum_of_its_published_parts() {
        let mut c = cfg();
        c.protocol.experiments = vec![3];
        let mut k = Controller::from_config(&c).unwrap();
        let (step, max) = (k.limits.torque_step_nm, k.limits.torque_nm);
        let mut checked = 0;
        let mut previous = 0.0;
        for seq in 0..2000 {
            let t = k.tick(&sample(seq, 0.5, 0.1));
            // α = 4 in experiment 3: τ_a = −3 τ_c; gravity of the rig at 0.5 rad.
            assert!((t.tau_amplification_nm + 0.3).abs() < 1e-12, "{t:?}");
            assert!(t.tau_gravity_nm.abs() > 0.1, "{t:?}");
            let sum =
                t.tau_gravity_nm + t.tau_amplification_nm + t.tau_bias_nm + t.tau_excitation_nm;
            let within = (sum - previous).abs() < step && sum.abs() < max;
            if within {
                assert!((t.tau_d_nm - sum).abs() < 1e-12, "seq {seq}: {t:?}");
                checked += 1;
            }
            previous = t.tau_d_nm;
        }
        assert!(checked > 1000, "only {checked} ticks within the limits");
    }

    #[test]
    fn adopting_f_respects_bounds() {
        let mut k = Controller::from_config(&cfg()).unwrap();
        assert!(!k.adopt_fractional_order(0.95));
        assert!(!k.adopt_fractional_order(f64::NAN));
        assert!(k.adopt_fractional_order(0.4));
    }

    // ---- operator commands -------------------------------------------

    use exo_messages::ProtocolPhase;
    use exo_messages::{OperatorCommand, OperatorCommandKind as K};

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
            ProtocolRun::Running { from_step: 3, since_tick } if since_tick == start
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
            text.contains(
                "experiment 5 is not in this run's protocol (protocol.experiments = [1, 7])"
            ),
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
                since_tick: 0
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
}
