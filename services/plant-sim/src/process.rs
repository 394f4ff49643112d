//! `exo-plant-sim` as a process: the physical world, [`PlantNode`], on the
//! simulated bus, stepped by the one runner (`exo_service_kit::runner`).
//! Publishes raw bus frames (`<instance>/bus/sensor`), applies the motor
//! commands it receives (`<instance>/bus/motor`), follows the protocol state
//! (the subject's impedance per experiment, the load, the posture).
//!
//! Timing: in *lockstep* each step advances one control period only once
//! the motor command answering its frame has arrived (same seed ⇒ identical
//! run), re-sending the frame when an answer is slow (a start-up race) and
//! giving up after 20 s; it also holds each frame while the recorder (and,
//! when its estimates feed the controller, the identifier) is more than its
//! margin behind (`exo/recorder/progress`, `exo/identifier/progress`,
//! [`OffPathPace`]),
//! waiting at most [`HOLD_PATIENCE`] in 20 ms waits, so that a stalled or
//! slow recorder loses nothing; in *real time* it advances on the wall clock with
//! absolute deadlines, holds the latest command, counts missed deadlines,
//! and the drive's watchdog (`safety.drive_watchdog_ms`) turns the torque
//! off when commands stop.
//!
//! `--inject-fault-at N` (tests): from tick N the cuff sensor reads NaN.

use std::time::{Duration, Instant};

use exo_config::TimingMode;
use exo_messages::channels::ProcessName;
use exo_messages::{BusMotorCommand, BusSensorFrame, OffPathProgress, ProtocolState};
use exo_service_kit::channels::{
    BUS_MOTOR, BUS_SENSOR, IDENTIFIER_PROGRESS, PROTOCOL, RECORDER_PROGRESS,
};
use exo_service_kit::ipc::{Connect, Inbox, IpcError, Outbox, REALTIME_SETTLE_PLANT};
use exo_service_kit::runner::{Context, Flow, Process};
use exo_service_kit::{monotonic_ns, sleep_until_ns, RealtimeProcess, ServiceArgs, StopFlag};
use tracing::{info, warn};

use crate::pace::{OffPathPace, Pace};
use crate::{PlantModel, PlantModelError, PlantNode, StepMismatch};

const RESEND_AFTER: Duration = Duration::from_millis(200);
const GIVE_UP_AFTER: Duration = Duration::from_secs(20);
/// The longest the plant holds one frame for a process that is behind
/// (lockstep). Below the controller's 60 s without a sample, after which it
/// gives up on the run; the driver waits for frames without a bound in
/// lockstep, and no sample is waiting for its command while a frame is
/// held, so no lockstep time-out (`safety.lockstep_timeout_ms`) runs.
pub const HOLD_PATIENCE: Duration = Duration::from_secs(30);
/// Each wait of a hold, between looks at the stop flag and the patience.
const HOLD_WAIT: Duration = Duration::from_millis(20);
/// Holds logged one by one; the rest are summed at the end.
const HOLDS_LOGGED: u64 = 5;
/// How often a hold looks whether the process it waits for still lives.
const ALIVE_EVERY: Duration = Duration::from_millis(500);

/// Why the plant simulator process stops with an error.
#[derive(Debug, thiserror::Error)]
pub enum PlantProcessError {
    /// The plant model file could not be read or is invalid.
    #[error(transparent)]
    Model(#[from] PlantModelError),
    /// The model's integration step does not divide the control period.
    #[error(transparent)]
    Step(#[from] StepMismatch),
    /// A channel could not be opened, sent on or received from.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// Lockstep: no motor command answered frame `frame` in time.
    #[error("no motor command for frame {frame} within {GIVE_UP_AFTER:?}: is the sensor driver running?")]
    NoMotorCommand {
        /// The frame's tick.
        frame: u64,
    },
}

/// The plant simulator process.
pub struct PlantProcess {
    node: PlantNode,
    bus_out: Outbox<BusSensorFrame>,
    motor_in: Inbox<BusMotorCommand>,
    protocol_in: Inbox<ProtocolState>,
    /// In lockstep: the recorder's progress (and the identifier's, when its
    /// estimates feed the controller), for which frames are held.
    watches: Vec<Watch>,
    realtime: bool,
    log_every: u64,
    missed_deadlines: u64,
    /// The next frame is sent past its deadline.
    late: bool,
    wall_start: Option<u64>,
}

impl Process for PlantProcess {
    type Args = ServiceArgs;
    type Error = PlantProcessError;
    const NAME: ProcessName = ProcessName::PlantSim;
    const REALTIME: Option<RealtimeProcess> = Some(RealtimeProcess::PlantSim);
    const SETTLE: Duration = REALTIME_SETTLE_PLANT;

    fn open(cx: Context<'_, ServiceArgs>) -> Result<Self, PlantProcessError> {
        let (cfg, ipc) = (cx.cfg, cx.ipc);
        let model = PlantModel::from_file(&cfg.plant_model)?;
        let node = PlantNode::new(cfg, &model, cx.args.inject_fault_at)?;
        info!(
            "plant-sim: {:?} at {} Hz, step {} s, subject {}, model {}",
            cfg.run.timing,
            cfg.run.rate_hz,
            model.integration.step_s,
            cfg.subject().name,
            cfg.plant_model.display()
        );
        Ok(PlantProcess {
            node,
            bus_out: ipc.outbox(BUS_SENSOR)?,
            motor_in: ipc.inbox(BUS_MOTOR, 64)?.with_spin(cfg.lockstep_spin()),
            protocol_in: ipc.inbox(PROTOCOL, 64)?,
            // In real time control never waits for them.
            watches: match cfg.run.timing {
                TimingMode::Lockstep => {
                    let mut w = vec![Watch::new(
                        ProcessName::Recorder,
                        ipc.inbox(RECORDER_PROGRESS, 16)?,
                    )];
                    if cfg.controller_hears_identifier() {
                        w.push(Watch::new(
                            ProcessName::Identifier,
                            ipc.inbox(IDENTIFIER_PROGRESS, 16)?,
                        ));
                    }
                    w
                }
                TimingMode::Realtime => Vec::new(),
            },
            realtime: cfg.run.timing == TimingMode::Realtime,
            log_every: cfg.run.rate_hz as u64 * 10,
            missed_deadlines: 0,
            late: false,
            wall_start: None,
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        let mut ports: Vec<&dyn Connect> = vec![&self.bus_out, &self.motor_in, &self.protocol_in];
        for w in &self.watches {
            ports.push(&w.inbox);
        }
        ports
    }

    fn step(&mut self, stop: &StopFlag) -> Result<Flow, PlantProcessError> {
        if self.node.finished() {
            return Ok(Flow::Done);
        }
        let wall_start = *self.wall_start.get_or_insert_with(monotonic_ns);
        for w in &mut self.watches {
            w.hold(self.node.tick(), &self.bus_out, stop)?;
        }
        while let Some(p) = self.protocol_in.try_recv()? {
            self.node.on_protocol(&p);
        }
        let k = self.node.tick();
        let mut frame = self.node.frame(if self.realtime {
            monotonic_ns()
        } else {
            self.node.lockstep_stamp_ns()
        });
        if std::mem::take(&mut self.late) {
            frame.status |= exo_messages::bus_status::LATE;
        }
        self.bus_out.send(frame)?;
        if self.realtime {
            let period_ns = self.node.period_ns();
            let deadline = wall_start + (k + 1) * period_ns;
            if monotonic_ns() > deadline + period_ns {
                self.missed_deadlines += 1;
                // The next frame goes out past its deadline: flag it.
                self.late = true;
            } else {
                sleep_until_ns(deadline);
            }
            while let Some(cmd) = self.motor_in.try_recv()? {
                self.node.hold_motor(&cmd);
            }
        } else {
            let started = Instant::now();
            let mut last_send = started;
            while !stop.requested() {
                match self.motor_in.recv_timeout(Duration::from_millis(20))? {
                    Some(cmd) if self.node.on_motor(&cmd) => break,
                    Some(_) => continue,
                    None => {}
                }
                if last_send.elapsed() > RESEND_AFTER {
                    self.bus_out.send(frame)?;
                    last_send = Instant::now();
                }
                if started.elapsed() > GIVE_UP_AFTER {
                    return Err(PlantProcessError::NoMotorCommand { frame: k });
                }
            }
        }
        self.node.advance();
        if self.node.tick().is_multiple_of(self.log_every) {
            let t = self.node.truth();
            info!(
                "plant-sim: sim {:.1} s, wall {:.1} s, θ = {:.3} rad, missed deadlines {}",
                t.t_s,
                (monotonic_ns() - wall_start) as f64 * 1e-9,
                t.theta_e_rad,
                self.missed_deadlines
            );
        }
        Ok(Flow::Continue)
    }

    fn finish(self) -> Result<(), PlantProcessError> {
        for r in self.watches.iter().filter(|r| r.holds > 0) {
            info!(
                "plant-sim: simulated time held {} times for the {}, {:.1} s in all{}",
                r.holds,
                r.who,
                r.held.as_secs_f64(),
                if r.given_up > 0 {
                    format!("; {} times it went on without it", r.given_up)
                } else {
                    String::new()
                }
            );
        }
        if self.missed_deadlines > 0 {
            warn!(
                "plant-sim: {} missed real-time deadlines",
                self.missed_deadlines
            );
        }
        info!("plant-sim: stopped after {} ticks", self.node.tick());
        Ok(())
    }
}

/// A process's progress and the holds it caused (lockstep).
struct Watch {
    who: ProcessName,
    inbox: Inbox<OffPathProgress>,
    pace: OffPathPace,
    holds: u64,
    held: Duration,
    given_up: u64,
}

impl Watch {
    fn new(who: ProcessName, inbox: Inbox<OffPathProgress>) -> Self {
        Watch {
            who,
            inbox,
            pace: OffPathPace::new(),
            holds: 0,
            held: Duration::ZERO,
            given_up: 0,
        }
    }

    /// Holds frame `next_frame` while the process is more than its margin
    /// behind: waits of [`HOLD_WAIT`] on its progress, at most
    /// [`HOLD_PATIENCE`] in all, ended early by a stop request. Between
    /// waits `frames_out` is connected to peers that appeared meanwhile: a
    /// restarted recorder is handed the frames' history only then (see
    /// `exo_service_kit::runner::Flow::Idle`; the driver and controller connect
    /// theirs while they wait for the held frame).
    fn hold(
        &mut self,
        next_frame: u64,
        frames_out: &dyn Connect,
        stop: &StopFlag,
    ) -> Result<(), IpcError> {
        while let Some(p) = self.inbox.try_recv()? {
            self.pace.on_progress(&p);
        }
        let Pace::Hold { lag } = self.pace.check(next_frame) else {
            return Ok(());
        };
        let started = Instant::now();
        self.holds += 1;
        if self.holds <= HOLDS_LOGGED {
            info!(
                "plant-sim: holding simulated time at frame {next_frame}: the {} is {lag} frames behind (at most {} may be)",
                self.who,
                OffPathProgress::MAX_LAG_FRAMES
            );
        }
        let mut looked = Instant::now();
        while !stop.requested() {
            frames_out.connect()?;
            if looked.elapsed() >= ALIVE_EVERY {
                looked = Instant::now();
                if let Some(pid) = self.pace.last().map(|p| p.pid) {
                    if !exo_service_kit::child::process_alive(pid) {
                        self.pace.forget();
                        warn!(
                            "plant-sim: the {} (pid {pid}) has died: simulated time goes on without it (a restarted one is waited for again)",
                            self.who
                        );
                        break;
                    }
                }
            }
            if let Some(p) = self.inbox.recv_timeout(HOLD_WAIT)? {
                self.pace.on_progress(&p);
                while let Some(p) = self.inbox.try_recv()? {
                    self.pace.on_progress(&p);
                }
            }
            let Pace::Hold { lag } = self.pace.check(next_frame) else {
                break;
            };
            if started.elapsed() >= HOLD_PATIENCE {
                self.pace.give_up();
                self.given_up += 1;
                warn!(
                    "plant-sim: the {} is still {lag} frames behind after {HOLD_PATIENCE:?} at frame {next_frame}: simulated time goes on without it (what it misses it counts)",
                    self.who
                );
                break;
            }
        }
        self.held += started.elapsed();
        Ok(())
    }
}
