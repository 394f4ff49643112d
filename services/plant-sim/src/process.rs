//! `exo-plant-sim` as a process: the physical world, [`PlantNode`], on the
//! simulated bus, stepped by the one runner (`exo_service_kit::runner`).
//! Publishes raw bus frames (`<instance>/bus/sensor`), applies the motor
//! commands it receives (`<instance>/bus/motor`), follows the protocol state
//! (the subject's impedance per experiment, the load, the posture).
//!
//! Timing: in *lockstep* each step advances one control period only once
//! the motor command answering its frame has arrived (same seed ⇒ identical
//! run), re-sending the frame when an answer is slow (a start-up race) and
//! giving up after 20 s; in *real time* it advances on the wall clock with
//! absolute deadlines, holds the latest command, counts missed deadlines,
//! and the drive's watchdog (`safety.drive_watchdog_ms`) turns the torque
//! off when commands stop.
//!
//! `--inject-fault-at N` (tests): from tick N the cuff sensor reads NaN.

use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use exo_config::TimingMode;
use exo_messages::channels::ProcessName;
use exo_messages::{BusMotorCommand, BusSensorFrame, ProtocolState};
use exo_service_kit::channels::{BUS_MOTOR, BUS_SENSOR, PROTOCOL};
use exo_service_kit::ipc::{Connect, Inbox, Outbox, REALTIME_SETTLE_PLANT};
use exo_service_kit::runner::{Context, Flow, Process};
use exo_service_kit::{monotonic_ns, sleep_until_ns, RealtimeProcess, ServiceArgs, StopFlag};
use tracing::{info, warn};

use crate::{PlantModel, PlantNode};

const RESEND_AFTER: Duration = Duration::from_millis(200);
const GIVE_UP_AFTER: Duration = Duration::from_secs(20);

/// The plant simulator process.
pub struct PlantProcess {
    node: PlantNode,
    bus_out: Outbox<BusSensorFrame>,
    motor_in: Inbox<BusMotorCommand>,
    protocol_in: Inbox<ProtocolState>,
    realtime: bool,
    log_every: u64,
    missed_deadlines: u64,
    /// The next frame is sent past its deadline.
    late: bool,
    wall_start: Option<u64>,
}

impl Process for PlantProcess {
    type Args = ServiceArgs;
    const NAME: ProcessName = ProcessName::PlantSim;
    const REALTIME: Option<RealtimeProcess> = Some(RealtimeProcess::PlantSim);
    const SETTLE: Duration = REALTIME_SETTLE_PLANT;

    fn open(cx: Context<'_, ServiceArgs>) -> Result<Self> {
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
            realtime: cfg.run.timing == TimingMode::Realtime,
            log_every: cfg.run.rate_hz as u64 * 10,
            missed_deadlines: 0,
            late: false,
            wall_start: None,
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        vec![&self.bus_out, &self.motor_in, &self.protocol_in]
    }

    fn step(&mut self, stop: &StopFlag) -> Result<Flow> {
        if self.node.finished() {
            return Ok(Flow::Done);
        }
        let wall_start = *self.wall_start.get_or_insert_with(monotonic_ns);
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
                    bail!("no motor command for frame {k} within {GIVE_UP_AFTER:?}: is the sensor driver running?");
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

    fn finish(self) -> Result<()> {
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
