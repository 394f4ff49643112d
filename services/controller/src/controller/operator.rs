//! The operator's commands ([`Controller::on_operator`]): what each does
//! to the protocol's position ([`ProtocolRun`]), and the outcome that
//! answers the console ([`OperatorOutcome`], [`OperatorRefusal`]).

use exo_messages::operator::KnownKinds;
use exo_messages::{MessageError, OperatorCommand, OperatorCommandKind};

use super::Controller;
use crate::protocol::ProtocolPoint;
use crate::safety::Fault;

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
        /// Ticks of analysis skipped since then because K and H were known
        /// (`protocol.stop_when`): the protocol's time is the ticks since
        /// `since_tick` plus these.
        skipped_ticks: u64,
    },
    /// Ramping out after an operator stop, or before an operator start
    /// that came in the middle of a period: bias and excitation of step
    /// `step`, stopped `tau_s` into its period at tick `since_tick`, fade
    /// over the protocol's ramp-out
    /// ([`Protocol::stopping`](crate::protocol::Protocol::stopping)); then
    /// the protocol starts at step `then`, or is held stopped (`None`).
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

impl Controller {
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
    fn running_at(
        &self,
        from_step: usize,
        since_tick: u64,
        skipped_ticks: u64,
        tick: u64,
    ) -> Option<(usize, f64)> {
        let rel_s = (tick.saturating_sub(since_tick) + skipped_ticks) as f64 / self.rate_hz;
        self.protocol.locate_from(from_step, rel_s)
    }

    fn stop(&mut self) -> OperatorOutcome {
        let now = self.next_tick();
        match self.run {
            ProtocolRun::Running {
                from_step,
                since_tick,
                skipped_ticks,
            } => {
                let Some((step, tau_s)) =
                    self.running_at(from_step, since_tick, skipped_ticks, now)
                else {
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
                skipped_ticks,
            } => Some(
                self.running_at(from_step, since_tick, skipped_ticks, now)
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
            skipped_ticks: 0,
        };
        // A window started again is measured afresh: an estimate of an
        // earlier one does not end it (`protocol.stop_when`).
        self.known = None;
        self.amplifier.reset();
    }

    /// The protocol's state at tick `tick` (its sample stamped `stamp_ns`),
    /// after the transitions due by then (a ramp-out that has ended, an
    /// analysis ended by `protocol.stop_when`); and whether it is held
    /// stopped.
    pub(super) fn protocol_at(&mut self, tick: u64, stamp_ns: u64) -> (ProtocolPoint, bool) {
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
                skipped_ticks,
            } => {
                let mut rel = tick.saturating_sub(since_tick) + skipped_ticks;
                if let Some(skip) = self.analysis_skip(from_step, rel, stamp_ns) {
                    rel += skip;
                    self.run = ProtocolRun::Running {
                        from_step,
                        since_tick,
                        skipped_ticks: skipped_ticks + skip,
                    };
                }
                (
                    self.protocol.at_from(from_step, rel as f64 / self.rate_hz),
                    false,
                )
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
}

#[cfg(test)]
mod tests;
