//! `exo-sensor-driver` as a process: owns the actuator. Stepped by the one
//! runner (`exo_service_kit::runner`): each step reads one frame from the
//! bus, publishes the calibrated sample ([`DriverNode`]), waits (bounded)
//! for the controller's command and writes the torque back, or, when none
//! comes within the deadline, the latched safe-state torque.
//!
//! The bus is chosen by `[bus] backend`: the simulator's
//! ([`SimulatorBus`], iceoryx2 channels to `exo-plant-sim`); a hardware
//! backend implements [`HardwareBus`](crate::HardwareBus) (ARCHITECTURE.md).
//! (A recording is played back by `exo-player`, not by the driver.)
//!
//! The command watchdog arms at the first command, so a controller that
//! starts late does not trip it. In real time the deadline is
//! `safety.command_deadline_ms` from the frame, and a bus silent for
//! `safety.bus_deadline_ms` is flagged from the driver's own timer; in
//! lockstep, simulated time stands still while waiting: a controller
//! silent for `safety.lockstep_timeout_ms` of wall time is declared if its
//! process is gone, and waited for up to [`LOCKSTEP_LIVE_PATIENCE`] if it
//! lives (a loaded machine can hold a process for over a second); the safe
//! torque is applied at that same simulated tick.
//!
//! Operator commands (`<instance>/operator`, e.g. from `exo op`): the node
//! acts on `ResetFault`, each `seq` once.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use exo_config::{BusBackend, TimingMode};
use exo_messages::channels::ProcessName;
use exo_messages::{ActuatorCommand, OperatorCommand, ProtocolState, SensorSample};
use exo_service_kit::channels::{COMMAND, OPERATOR, PROTOCOL, SENSOR};
use exo_service_kit::ipc::{Connect, Inbox, IpcError, Outbox};
use exo_service_kit::latency::fmt_us;
use exo_service_kit::runner::{Context as RunContext, Flow, Process};
use exo_service_kit::{monotonic_ns, RealtimeProcess, ServiceArgs, StopFlag};
use tracing::{error, info, warn};

use crate::backends::SimulatorBus;
use crate::ethercat::{EthercatBus, EthercatError};
use crate::{DriverNode, HardwareBus, RoundTrip};

const RESEND_AFTER: Duration = Duration::from_millis(200);
const STARTUP_PATIENCE: Duration = Duration::from_secs(60);
/// In lockstep, how long a controller whose process lives (running or
/// stopped) is waited for before its silence latches the safe state;
/// `safety.lockstep_timeout_ms` after the frame, a controller whose process
/// is gone latches it. Below the plant's 20 s without a motor command.
const LOCKSTEP_LIVE_PATIENCE: Duration = Duration::from_secs(15);

/// Why the sensor-driver process stops with an error.
#[derive(Debug, thiserror::Error)]
pub enum DriverProcessError {
    /// `--round-trip-warmup-s` is not a number of seconds ≥ 0.
    #[error("--round-trip-warmup-s must be a finite number of seconds ≥ 0, not {0}")]
    Warmup(f64),
    /// `bus.backend = "ethercat"` without its table.
    #[error("bus.backend = \"ethercat\" needs a [bus.ethercat] table")]
    NoEthercatTable,
    /// A channel (or the simulator's bus) could not be opened, sent on or
    /// received from.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The EtherCAT bus refused the run file at bring-up, or failed.
    #[error(transparent)]
    Ethercat(#[from] EthercatError),
    /// The controller never answered after the start.
    #[error("no command from the controller within {STARTUP_PATIENCE:?} of start")]
    NoCommand,
    /// The round-trip report could not be serialised.
    #[error("serialising the round-trip report")]
    SerialiseReport(#[source] serde_json::Error),
    /// The round-trip report could not be written.
    #[error("writing the round-trip report {}", path.display())]
    WriteReport {
        /// The file (`--round-trip-report`).
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// Command line of `exo-sensor-driver`: every service's, plus the round-trip report.
#[derive(Debug, clap::Parser)]
#[command(name = "exo-sensor-driver")]
pub struct DriverArgs {
    #[command(flatten)]
    service: ServiceArgs,
    /// On exit, write the control round trip's percentiles (JSON: sample
    /// published → its command received, ns) to FILE.
    #[arg(long, value_name = "FILE")]
    round_trip_report: Option<PathBuf>,
    /// Seconds after the first round trip left out of the round-trip
    /// statistics (connection set-up, page faults, cold caches).
    #[arg(long, value_name = "SECONDS", default_value_t = 2.0)]
    round_trip_warmup_s: f64,
}

impl AsRef<ServiceArgs> for DriverArgs {
    fn as_ref(&self) -> &ServiceArgs {
        &self.service
    }
}

/// The driver's channels to the other processes.
struct Ports {
    sample_out: Outbox<SensorSample>,
    command_in: Inbox<ActuatorCommand>,
    protocol_in: Inbox<ProtocolState>,
    operator_in: Inbox<OperatorCommand>,
}

/// What the bus is.
enum Bus {
    /// The plant simulator's, served in closed loop (boxed: its ports are large).
    Simulator(Box<SimulatorBus>),
    /// A CiA 402 drive on EtherCAT.
    Ethercat(Box<EthercatBus>),
}

/// The sensor-driver process.
pub struct DriverProcess {
    node: DriverNode,
    ports: Ports,
    bus: Bus,
    timing: Timing,
    round_trip: RoundTrip,
    round_trip_report: Option<PathBuf>,
}

impl Process for DriverProcess {
    type Args = DriverArgs;
    type Error = DriverProcessError;
    const NAME: ProcessName = ProcessName::SensorDriver;
    const REALTIME: Option<RealtimeProcess> = Some(RealtimeProcess::SensorDriver);

    fn open(cx: RunContext<'_, DriverArgs>) -> Result<Self, DriverProcessError> {
        let (cfg, ipc, args) = (cx.cfg, cx.ipc, cx.args);
        if !(args.round_trip_warmup_s.is_finite() && args.round_trip_warmup_s >= 0.0) {
            return Err(DriverProcessError::Warmup(args.round_trip_warmup_s));
        }
        let lockstep = cfg.run.timing == TimingMode::Lockstep;
        let deadline = Duration::from_secs_f64(
            if lockstep {
                cfg.safety.lockstep_timeout_ms
            } else {
                cfg.safety.command_deadline_ms
            } / 1000.0,
        );
        let ports = Ports {
            sample_out: ipc.outbox(SENSOR)?,
            command_in: ipc.inbox(COMMAND, 64)?.with_spin(cfg.lockstep_spin()),
            protocol_in: ipc.inbox(PROTOCOL, 64)?,
            operator_in: ipc.inbox(OPERATOR, 16)?,
        };
        let mut deadline = deadline;
        let bus = match cfg.bus.backend {
            BusBackend::Ethercat => {
                let Some(settings) = &cfg.bus.ethercat else {
                    return Err(DriverProcessError::NoEthercatTable);
                };
                let bus = EthercatBus::open(settings, cfg.run.rate_hz)?;
                // The command must come within the cycle it answers, early
                // enough that the next cycle starts on time: half a period.
                deadline = deadline.min(Duration::from_secs_f64(0.5 / cfg.run.rate_hz));
                info!(
                    "sensor-driver: {} bus on {}, {:?}, command deadline {:?}, safe state {:?}",
                    bus.name(),
                    settings.interface,
                    cfg.run.timing,
                    deadline,
                    cfg.safety.safe_state
                );
                Bus::Ethercat(Box::new(bus))
            }
            BusBackend::Simulator => {
                let bus = SimulatorBus::open(ipc, cfg.lockstep_spin())?;
                info!(
                    "sensor-driver: {} bus, {:?}, command deadline {:?}, safe state {:?}",
                    bus.name(),
                    cfg.run.timing,
                    deadline,
                    cfg.safety.safe_state
                );
                Bus::Simulator(Box::new(bus))
            }
        };
        Ok(DriverProcess {
            node: DriverNode::new(cfg),
            ports,
            bus,
            timing: Timing {
                deadline,
                bus_deadline: Duration::from_secs_f64(cfg.safety.bus_deadline_ms / 1000.0),
                lockstep,
                armed: false,
                last_frame_at: Instant::now(),
                silence_flagged: false,
            },
            round_trip: RoundTrip::new(args.round_trip_warmup_s),
            round_trip_report: args.round_trip_report.clone(),
        })
    }

    fn ports(&self) -> Vec<&dyn Connect> {
        let p = &self.ports;
        let mut out: Vec<&dyn Connect> =
            vec![&p.sample_out, &p.command_in, &p.protocol_in, &p.operator_in];
        if let Bus::Simulator(bus) = &self.bus {
            out.extend(bus.ports());
        }
        out
    }

    fn step(&mut self, stop: &StopFlag) -> Result<Flow, DriverProcessError> {
        let DriverProcess {
            node,
            ports,
            bus,
            round_trip,
            timing,
            ..
        } = self;
        let mut cycle = Cycle {
            node,
            ports,
            round_trip,
            timing,
        };
        match bus {
            Bus::Simulator(bus) => cycle.serve_one(bus.as_mut(), stop),
            Bus::Ethercat(bus) => cycle.serve_one(bus.as_mut(), stop),
        }
    }

    fn finish(mut self) -> Result<(), DriverProcessError> {
        if let Bus::Ethercat(bus) = &mut self.bus {
            let c = bus.counters();
            let [exchange, lateness, own] = bus.timing();
            for (what, r) in [
                ("exchange (LRW out → inputs back)", exchange),
                ("wake-up lateness", lateness),
                (
                    "driver's part of the cycle (frame handed over → next read)",
                    own,
                ),
            ] {
                if let Some(r) = r {
                    let l = r.latency;
                    info!(
                        "sensor-driver: EtherCAT {what} over {} cycles: p50 {} µs, p99 {} µs, p99.9 {} µs, max {} µs",
                        l.count,
                        fmt_us(l.p50_ns),
                        fmt_us(l.p99_ns),
                        fmt_us(l.p999_ns),
                        fmt_us(l.max_ns)
                    );
                }
            }
            info!(
                "sensor-driver: EtherCAT {} cycles: {} woke late, {} frames lost, {} commands late (held), {} cycles missed, longest run of misses {} (latching at {}), {} late replies ignored, {} working-counter errors",
                c.cycles,
                c.cycles_late,
                c.frames_lost,
                c.commands_missed,
                c.cycles_missed,
                c.longest_miss_run,
                bus.max_missed_cycles(),
                c.late_replies,
                c.wkc_errors
            );
            let sw = bus.power_down();
            info!(
                "sensor-driver: EtherCAT drive powered down at exit: statusword {sw:#06x} ({:?})",
                crate::cia402::DriveState::from_statusword(sw)
            );
        }
        report_round_trip(&self.round_trip, self.round_trip_report.as_deref())?;
        info!("sensor-driver: stopped");
        Ok(())
    }
}

/// The driver's deadlines and bus watch.
struct Timing {
    deadline: Duration,
    bus_deadline: Duration,
    lockstep: bool,
    armed: bool,
    last_frame_at: Instant,
    silence_flagged: bool,
}

/// What one cycle works on, whatever the bus.
struct Cycle<'a> {
    node: &'a mut DriverNode,
    ports: &'a Ports,
    round_trip: &'a mut RoundTrip,
    timing: &'a mut Timing,
}

impl Cycle<'_> {
    /// One cycle over any bus: read a frame, publish the sample, wait
    /// (bounded) for the controller's command, write the torque back. A
    /// fault the bus found itself latches the safe state before the
    /// frame's sample is made, so that sample already carries it.
    fn serve_one<B: HardwareBus>(
        &mut self,
        bus: &mut B,
        stop: &StopFlag,
    ) -> Result<Flow, DriverProcessError>
    where
        DriverProcessError: From<B::Error>,
    {
        let (node, ports) = (&mut *self.node, self.ports);
        // In real time, once the stream runs, a silent bus is the driver's
        // to detect: it does not wait for the next frame. Once the silence
        // is flagged there is nothing to time until the next frame: a zero
        // wait here would spin (and, in SCHED_FIFO on the plant's CPU,
        // starve the very plant it waits for).
        let watch_bus = self.timing.armed && !self.timing.lockstep;
        let wait = if watch_bus && !self.timing.silence_flagged {
            self.timing
                .bus_deadline
                .saturating_sub(self.timing.last_frame_at.elapsed())
                .min(Duration::from_millis(100))
        } else {
            Duration::from_millis(100)
        };
        let Some(frame) = bus.read(wait)? else {
            if watch_bus
                && !self.timing.silence_flagged
                && self.timing.last_frame_at.elapsed() >= self.timing.bus_deadline
            {
                let sample = node.on_bus_silent(monotonic_ns());
                ports.sample_out.send(sample)?;
                let out = node.safe_output();
                node.report_latch(&out);
                bus.write(
                    sample.seq,
                    sample.stamp_ns,
                    out.tau_motor_nm,
                    node.motor_enable(),
                )?;
                self.timing.silence_flagged = true;
            }
            return Ok(Flow::Idle);
        };
        self.timing.last_frame_at = Instant::now();
        self.timing.silence_flagged = false;
        if let Some(fault) = bus.take_fault() {
            node.on_bus_fault(frame.seq, fault);
        }
        while let Some(p) = ports.protocol_in.try_recv()? {
            node.on_protocol(&p);
        }
        while let Some(op) = ports.operator_in.try_recv()? {
            node.on_operator(&op);
        }
        let sample = node.on_frame(&frame, 0);
        let was_armed = self.timing.armed;
        let sent_ns = monotonic_ns();
        ports.sample_out.send(sample)?;
        let started = Instant::now();
        let mut last_send = started;
        let mut waited_for_living = false;
        let out = loop {
            if let Some(o) = node.latched_output() {
                // Latched: no need to wait for the controller.
                while ports.command_in.try_recv()?.is_some() {}
                break o;
            }
            let remaining = self
                .timing
                .deadline
                .saturating_sub(started.elapsed())
                .min(Duration::from_millis(20));
            if let Some(cmd) = ports.command_in.recv_timeout(remaining)? {
                if cmd.sensor_seq == frame.seq {
                    let received_ns = monotonic_ns();
                    self.timing.armed = true;
                    if let Some(o) = node.answer(&cmd) {
                        if was_armed && node.driver().latched().is_none() {
                            self.round_trip.record(sent_ns, received_ns);
                        }
                        break o;
                    }
                }
                continue;
            }
            if stop.requested() {
                break node.safe_output();
            }
            if !self.timing.armed {
                if last_send.elapsed() > RESEND_AFTER {
                    ports.sample_out.send(sample)?;
                    last_send = Instant::now();
                }
                if started.elapsed() > STARTUP_PATIENCE {
                    return Err(DriverProcessError::NoCommand);
                }
                if !self.timing.lockstep && started.elapsed() >= self.timing.deadline {
                    // Not armed yet: hold the safe torque without latching.
                    break node.safe_output();
                }
                continue;
            }
            if started.elapsed() >= self.timing.deadline {
                // In lockstep simulated time stands still while the driver
                // waits, and a loaded machine can hold a living process for
                // more than a second (CI, stop 33: 1 s passed once in a
                // 126 s run): a controller whose process lives is waited
                // for up to `LOCKSTEP_LIVE_PATIENCE`; one whose process is
                // gone is declared now.
                if self.timing.lockstep
                    && started.elapsed() < LOCKSTEP_LIVE_PATIENCE
                    && ports.command_in.publisher_alive()
                {
                    if !waited_for_living {
                        waited_for_living = true;
                        warn!(
                            "sensor-driver: frame {} unanswered for {:?}, the controller's process lives: waiting (lockstep) up to {LOCKSTEP_LIVE_PATIENCE:?}",
                            frame.seq,
                            self.timing.deadline
                        );
                    }
                    continue;
                }
                // In real time a bus whose drive holds its last set-point
                // (EtherCAT) takes a late command as a missed cycle, up to
                // its limit: nothing is written, the drive holds.
                if !self.timing.lockstep && bus.hold_missed_command() {
                    return Ok(Flow::Continue);
                }
                break node.on_deadline();
            }
        };
        node.report_latch(&out);
        bus.write(
            frame.seq,
            frame.stamp_ns,
            out.tau_motor_nm,
            node.motor_enable(),
        )?;
        Ok(Flow::Continue)
    }
}

/// Logs the round-trip percentiles and, if asked, writes them to `file` (JSON).
fn report_round_trip(
    round_trip: &RoundTrip,
    file: Option<&Path>,
) -> Result<(), DriverProcessError> {
    let report = round_trip.report();
    match &report {
        Some(r) => info!(
            "sensor-driver: control round trip (sample published → its command received) \
             over {} ticks in {:.1} s: p50 {} µs, p99 {} µs, p99.9 {} µs, max {} µs",
            r.latency.count,
            r.window_s,
            fmt_us(r.latency.p50_ns),
            fmt_us(r.latency.p99_ns),
            fmt_us(r.latency.p999_ns),
            fmt_us(r.latency.max_ns)
        ),
        None => info!("sensor-driver: no control round trip recorded after the warm-up"),
    }
    if let Some(path) = file {
        let text =
            serde_json::to_string_pretty(&report).map_err(DriverProcessError::SerialiseReport)?;
        std::fs::write(path, text + "\n").map_err(|source| {
            error!("sensor-driver: writing the round-trip report: {source}");
            DriverProcessError::WriteReport {
                path: path.to_path_buf(),
                source,
            }
        })?;
    }
    Ok(())
}
