//! `exo-sensor-driver`: owns the actuator. Each frame from the bus becomes a
//! calibrated `SensorSample`; the controller's command for that sample goes
//! back to the bus, or, when none comes within the deadline, the latched
//! safe-state torque.
//!
//! The bus is chosen by `[bus] backend` (see [`backends`]): the simulator's
//! (iceoryx2 channels to `exo-plant-sim`) or, once written, a hardware
//! backend implementing `exo_sensor_driver::HardwareBus` (ARCHITECTURE.md).
//!
//! The command watchdog arms at the first command, so a controller that
//! starts late does not trip it. In real time the deadline is
//! `safety.command_deadline_ms` from the frame; in lockstep, simulated time
//! stands still while waiting, so a missing command is declared after
//! `safety.lockstep_timeout_ms` of wall time and the safe torque is applied
//! at that same simulated tick.
//!
//! Operator commands (`<instance>/operator`, e.g. from `exo op`): the
//! driver acts on `ResetFault` (clears its latched safe state), each `seq`
//! once; the other kinds are the controller's, and an unknown kind is
//! refused with a warning naming the known ones.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
mod backends;
mod replay;

use exo_analysis::Played;
use exo_config::{BusBackend, RunConfig, TimingMode};
use exo_messages::{ActuatorCommand, OperatorCommand, ProtocolState, SensorSample};
use exo_sensor_driver::{Calibration, DriverNode, HardwareBus, RoundTrip};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{settle_connections, Inbox, Ipc, Outbox, REALTIME_SETTLE};
use exo_service_kit::latency::fmt_us;

use crate::backends::SimulatorBus;
use crate::replay::ReplayBus;
use clap::Parser;
use exo_service_kit::{
    init_logging, monotonic_ns, request_realtime, RealtimeProcess, RealtimeRequest, ServiceArgs,
    StopFlag,
};
use tracing::{error, info};

const RESEND_AFTER: Duration = Duration::from_millis(200);
const STARTUP_PATIENCE: Duration = Duration::from_secs(60);

/// Command line of `exo-sensor-driver`: every service's, plus the round-trip report.
#[derive(Debug, Parser)]
#[command(name = "exo-sensor-driver")]
struct DriverArgs {
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

fn main() {
    init_logging("sensor-driver");
    if let Err(e) = run(DriverArgs::parse()) {
        error!("{e:#}");
        std::process::exit(1);
    }
}

fn run(driver_args: DriverArgs) -> Result<()> {
    let args = &driver_args.service;
    if !(driver_args.round_trip_warmup_s.is_finite() && driver_args.round_trip_warmup_s >= 0.0) {
        bail!(
            "--round-trip-warmup-s must be a finite number of seconds ≥ 0, not {}",
            driver_args.round_trip_warmup_s
        );
    }
    let cfg = RunConfig::from_file(&args.config)?;
    let stop = StopFlag::install()?;
    let ipc = Ipc::open(
        "sensor_driver",
        &cfg.run.instance,
        args.iceoryx2_config.as_deref(),
    )?;
    let mut driver = DriverNode::new(&cfg);
    let lockstep = cfg.run.timing == TimingMode::Lockstep;
    let deadline = Duration::from_secs_f64(
        if lockstep {
            cfg.safety.lockstep_timeout_ms
        } else {
            cfg.safety.command_deadline_ms
        } / 1000.0,
    );
    let ports = Ports {
        sample_out: ipc.outbox::<SensorSample>(Channel::Sensor)?,
        command_in: ipc
            .inbox::<ActuatorCommand>(Channel::Command, 64)?
            .with_spin(cfg.lockstep_spin()),
        protocol_in: ipc.inbox::<ProtocolState>(Channel::Protocol, 64)?,
        operator_in: ipc.inbox::<OperatorCommand>(Channel::Operator, 16)?,
    };
    let timing = Timing {
        deadline,
        bus_deadline: Duration::from_secs_f64(cfg.safety.bus_deadline_ms / 1000.0),
        lockstep,
    };
    if cfg.run.timing == TimingMode::Realtime {
        request_realtime(
            "sensor-driver",
            RealtimeRequest::of(cfg.realtime.as_ref(), RealtimeProcess::SensorDriver),
        );
    }
    match cfg.bus.backend {
        BusBackend::Simulator => {
            let mut bus = SimulatorBus::open(&ipc, cfg.lockstep_spin())?;
            if !lockstep {
                let [frames, motor] = bus.ports();
                settle_connections(
                    &[
                        frames,
                        motor,
                        &ports.sample_out,
                        &ports.command_in,
                        &ports.protocol_in,
                        &ports.operator_in,
                    ],
                    REALTIME_SETTLE,
                )?;
            }
            info!(
                "sensor-driver: {} bus, {:?}, command deadline {:?}, safe state {:?}",
                bus.name(),
                cfg.run.timing,
                deadline,
                cfg.safety.safe_state
            );
            let mut round_trip = RoundTrip::new(driver_args.round_trip_warmup_s);
            let served = serve(
                &mut bus,
                &mut driver,
                &ports,
                timing,
                &stop,
                &mut round_trip,
            );
            // The loop's own error comes first; the report's is logged then.
            let reported = report_round_trip(&round_trip, driver_args.round_trip_report.as_deref());
            if let (Err(e), Err(_)) = (&reported, &served) {
                error!("{e:#}");
            }
            served?;
            reported?;
        }
        BusBackend::Replay => {
            let file = cfg
                .bus
                .replay_file
                .clone()
                .context("bus.replay_file is required for the replay backend")?;
            let calibration = Calibration::new(&cfg.rig);
            let mut bus = ReplayBus::open(
                &file,
                &calibration,
                cfg.bus.replay_pace_hz.unwrap_or(5000.0),
            )?;
            info!(
                "sensor-driver: replaying {} frames of {}",
                bus.len(),
                file.display()
            );
            let protocol_out = ipc.outbox::<ProtocolState>(Channel::Protocol)?;
            let command_out = ipc.outbox::<ActuatorCommand>(Channel::Command)?;
            replay(
                &mut bus,
                &mut driver,
                &ports.sample_out,
                &protocol_out,
                &command_out,
                &stop,
            )?;
        }
    }
    info!("sensor-driver: stopped");
    Ok(())
}

/// The driver's channels to the other processes.
struct Ports {
    sample_out: Outbox<SensorSample>,
    command_in: Inbox<ActuatorCommand>,
    protocol_in: Inbox<ProtocolState>,
    operator_in: Inbox<OperatorCommand>,
}

/// The command and bus deadlines and the timing mode.
#[derive(Clone, Copy)]
struct Timing {
    deadline: Duration,
    bus_deadline: Duration,
    lockstep: bool,
}

/// The driver's cycle over any bus: read a frame, publish the sample, wait
/// (bounded) for the controller's command, write the torque back.
fn serve<B: HardwareBus>(
    bus: &mut B,
    driver: &mut DriverNode,
    ports: &Ports,
    timing: Timing,
    stop: &StopFlag,
    round_trip: &mut RoundTrip,
) -> Result<()> {
    let mut armed = false;
    let mut last_frame_at = Instant::now();
    let mut silence_flagged = false;
    while !stop.requested() {
        // In real time, once the stream runs, a silent bus is the driver's
        // to detect: it does not wait for the next frame.
        let watch_bus = armed && !timing.lockstep;
        // Once the silence is flagged there is nothing to time until the
        // next frame: a zero wait here would spin (and, in SCHED_FIFO on
        // the plant's CPU, starve the very plant it waits for).
        let wait = if watch_bus && !silence_flagged {
            timing
                .bus_deadline
                .saturating_sub(last_frame_at.elapsed())
                .min(Duration::from_millis(100))
        } else {
            Duration::from_millis(100)
        };
        let Some(frame) = bus.read(wait)? else {
            if watch_bus && !silence_flagged && last_frame_at.elapsed() >= timing.bus_deadline {
                let sample = driver.on_bus_silent(monotonic_ns());
                ports.sample_out.send(sample)?;
                let out = driver.safe_output();
                driver.report_latch(&out);
                bus.write(
                    sample.seq,
                    sample.stamp_ns,
                    out.tau_motor_nm,
                    driver.motor_enable(),
                )?;
                silence_flagged = true;
            }
            continue;
        };
        last_frame_at = Instant::now();
        silence_flagged = false;
        while let Some(p) = ports.protocol_in.try_recv()? {
            driver.on_protocol(&p);
        }
        while let Some(op) = ports.operator_in.try_recv()? {
            driver.on_operator(&op);
        }
        let sample = driver.on_frame(&frame, 0);
        let was_armed = armed;
        let sent_ns = monotonic_ns();
        ports.sample_out.send(sample)?;
        let started = Instant::now();
        let mut last_send = started;
        let out = loop {
            if let Some(o) = driver.latched_output() {
                // Latched: no need to wait for the controller.
                while ports.command_in.try_recv()?.is_some() {}
                break o;
            }
            let remaining = timing
                .deadline
                .saturating_sub(started.elapsed())
                .min(Duration::from_millis(20));
            if let Some(cmd) = ports.command_in.recv_timeout(remaining)? {
                if cmd.sensor_seq == frame.seq {
                    let received_ns = monotonic_ns();
                    armed = true;
                    if let Some(o) = driver.answer(&cmd) {
                        if was_armed && driver.driver().latched().is_none() {
                            round_trip.record(sent_ns, received_ns);
                        }
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
                    ports.sample_out.send(sample)?;
                    last_send = Instant::now();
                }
                if started.elapsed() > STARTUP_PATIENCE {
                    bail!("no command from the controller within {STARTUP_PATIENCE:?} of start");
                }
                if !timing.lockstep && started.elapsed() >= timing.deadline {
                    // Not armed yet: hold the safe torque without latching.
                    break driver.safe_output();
                }
                continue;
            }
            if started.elapsed() >= timing.deadline {
                break driver.on_deadline();
            }
        };
        driver.report_latch(&out);
        bus.write(
            frame.seq,
            frame.stamp_ns,
            out.tau_motor_nm,
            driver.motor_enable(),
        )?;
    }
    Ok(())
}

/// Logs the round-trip percentiles and, if asked, writes them to `file` (JSON).
fn report_round_trip(round_trip: &RoundTrip, file: Option<&Path>) -> Result<()> {
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
            serde_json::to_string_pretty(&report).context("serialising the round-trip report")?;
        std::fs::write(path, text + "\n")
            .with_context(|| format!("writing the round-trip report {}", path.display()))?;
    }
    Ok(())
}

/// Plays a recording through the driver: per frame, the recorded protocol
/// states and commands up to its time stamp, then the calibrated sample
/// (status `REPLAY`). Ends when the recording does.
fn replay(
    bus: &mut ReplayBus,
    driver: &mut DriverNode,
    sample_out: &Outbox<SensorSample>,
    protocol_out: &Outbox<ProtocolState>,
    command_out: &Outbox<ActuatorCommand>,
    stop: &StopFlag,
) -> Result<()> {
    let (protocol, commands) = (
        std::mem::take(&mut bus.protocol),
        std::mem::take(&mut bus.commands),
    );
    let mut merge = exo_analysis::Merge::new(&protocol, &commands);
    while !stop.requested() {
        let Some(frame) = bus.read(Duration::ZERO)? else {
            break;
        };
        merge.up_to(frame.stamp_ns, |x| match x {
            Played::Protocol(p) => protocol_out.send(*p),
            Played::Command(c) => command_out.send(*c),
        })?;
        sample_out.send(driver.on_frame(&frame, exo_messages::status::REPLAY))?;
    }
    for p in merge.remaining_protocol() {
        protocol_out.send(*p)?;
    }
    // Let the subscribers take the last samples before the process (and its
    // publishers) goes.
    std::thread::sleep(Duration::from_millis(500));
    info!("sensor-driver: replay finished");
    Ok(())
}
