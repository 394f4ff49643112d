//! The real pipeline: `exo-plant-sim`, `exo-sensor-driver` and
//! `exo-controller` started as processes on a run file derived from the
//! bench's (`configs/realtime.toml` by default), observed through iceoryx2
//! like any subscriber, or, for the round trip, by the driver itself.
//!
//! Time stamps: in real time the plant stamps each `BusSensorFrame` with
//! `CLOCK_MONOTONIC` (`exo_service_kit::monotonic_ns`) immediately before
//! publishing it; the driver copies that stamp into the `SensorSample` and
//! the `BusMotorCommand` it writes for the frame, and the controller copies
//! the sample's stamp into its `ActuatorCommand`. No process stamps its own
//! receive or send time, so the bench measures the end of each interval
//! itself: `monotonic_ns()` (the same clock, same machine) right after its
//! subscriber hands it the answer.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use exo_config::{ProtocolMode, RunConfig, ServiceSet, TimingMode};
use exo_messages::ControlMode;
use exo_service_kit::channels::{BUS_MOTOR, COMMAND, PROTOCOL};
use exo_service_kit::ipc::Ipc;
use exo_service_kit::monotonic_ns;
use serde::Deserialize;

use crate::procs::Fleet;
use crate::stats::{Latency, Summary};

/// The service binaries, in start order.
pub const SERVICES: [&str; 3] = ["exo-controller", "exo-sensor-driver", "exo-plant-sim"];

/// How long the pipeline may take to produce its first answer.
const START_PATIENCE: Duration = Duration::from_secs(60);
/// How often the observers check that the services are still running.
const LIVENESS_EVERY: Duration = Duration::from_millis(100);
/// Poll interval of the lockstep progress observer.
const LOCKSTEP_POLL: Duration = Duration::from_millis(2);

/// The service binaries next to the bench's own executable.
pub fn service_binaries() -> Result<Vec<PathBuf>> {
    let exe = std::env::current_exe().context("locating the bench executable")?;
    let dir = exe
        .parent()
        .context("the bench executable has no parent directory")?;
    SERVICES
        .iter()
        .map(|name| {
            let p = dir.join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
            if p.is_file() {
                Ok(p)
            } else {
                bail!(
                    "{} not found: build the services first with \
                     `cargo build --release -p exo-plant-sim -p exo-sensor-driver -p exo-controller`",
                    p.display()
                )
            }
        })
        .collect()
}

/// Safety deadlines (ms) of the real-time rows (see [`bench_config`]).
const BENCH_DEADLINE_MS: f64 = 50.0;

/// The bench's run configuration, derived from the run file `base`: timing
/// `timing` at `rate_hz` on the iceoryx2 instance `instance`, only the three
/// loop services, and the paper's full identification protocol (every
/// experiment of Table I the subject has, all ten periods, the table's rest)
/// so that no measurement runs out of protocol; no `max_sim_time_s`.
/// Paths become absolute (`base` is canonicalised before loading, and the
/// loader resolves the paths inside against its directory).
pub fn bench_config(
    base: &Path,
    instance: &str,
    timing: TimingMode,
    rate_hz: f64,
    output_dir: &Path,
) -> Result<RunConfig> {
    let base = base
        .canonicalize()
        .with_context(|| format!("run file {}", base.display()))?;
    let mut cfg = RunConfig::from_file(&base)?;
    cfg.run.timing = timing;
    cfg.run.rate_hz = rate_hz;
    cfg.run.instance = instance.to_string();
    cfg.run.max_sim_time_s = None;
    cfg.run.output_dir = output_dir.to_path_buf();
    cfg.services = ServiceSet {
        plant_sim: true,
        sensor_driver: true,
        controller: true,
        identifier: false,
        recorder: false,
        player: false,
        live: false,
        tunnel: false,
    };
    let subject = cfg.subject();
    let experiments: Vec<u32> = cfg
        .experiment_table()
        .experiment
        .iter()
        .map(|e| e.number)
        .filter(|n| subject.get(*n).is_some())
        .collect();
    if experiments.is_empty() {
        bail!(
            "{}: the subject {} has none of the experiments of {}",
            base.display(),
            cfg.subject_file.display(),
            cfg.protocol.experiments_file.display()
        );
    }
    // This shared two-core VM stalls for up to ~5 ms now and then (see the
    // max column of the bare rows), which trips the 5 ms safety deadlines and
    // would measure the latched safe state instead of normal operation; the
    // bench widens them (the loop is the same code either way).
    if timing == TimingMode::Realtime {
        cfg.safety.command_deadline_ms = cfg.safety.command_deadline_ms.max(BENCH_DEADLINE_MS);
        cfg.safety.sample_deadline_ms = cfg.safety.sample_deadline_ms.max(BENCH_DEADLINE_MS);
    }
    cfg.protocol.mode = ProtocolMode::Identification;
    cfg.protocol.experiments = experiments;
    cfg.protocol.periods = None;
    cfg.protocol.rest_s = None;
    Ok(cfg)
}

/// Writes `cfg` to `path` as TOML and loads it back (validating it as the
/// services will).
pub fn write_config(cfg: &RunConfig, path: &Path) -> Result<RunConfig> {
    let text = toml::to_string(cfg).context("serialising the bench run file")?;
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))?;
    Ok(RunConfig::from_file(path)?)
}

/// Starts the services on `config`; the sensor driver also gets `driver_extra`.
fn spawn_services(
    fleet: &mut Fleet,
    bins: &[PathBuf],
    config: &Path,
    driver_extra: &[&OsStr],
) -> Result<()> {
    for (name, bin) in SERVICES.iter().zip(bins) {
        let mut args: Vec<&OsStr> = vec!["--config".as_ref(), config.as_os_str()];
        if *name == "exo-sensor-driver" {
            args.extend_from_slice(driver_extra);
        }
        fleet.spawn(name, bin, &args)?;
    }
    Ok(())
}

/// WARN and ERROR lines of the services' logs (what went wrong during a row).
fn log_findings(fleet: &Fleet) -> Vec<String> {
    let mut out = Vec::new();
    for name in SERVICES {
        let text = std::fs::read_to_string(fleet.log_path(name)).unwrap_or_default();
        for line in text.lines() {
            if line.contains("WARN") || line.contains("ERROR") {
                out.push(format!("{name}: {}", line.trim()));
            }
        }
    }
    out
}

/// What the real-time run measures, and how.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Observe {
    /// The driver's own round trip, sample published → its command
    /// received (`exo-sensor-driver --round-trip-report`): sensor →
    /// controller → driver, the interval a ping-pong measures. No bench
    /// subscriber is in the loop; the bench only polls `ProtocolState`
    /// (no wake-up) to see the loop start.
    DriverRoundTrip,
    /// The driver's `BusMotorCommand` (the full loop, as the plant sees it).
    MotorCommand,
    /// The controller's `ActuatorCommand` (as the driver sees it).
    ActuatorCommand,
}

/// What one real-time run of the pipeline measured.
pub struct RealtimeResult {
    /// The measured interval's percentiles (ns); `None` if none was measured.
    pub latency: Option<Summary>,
    /// Answers per second in the window.
    pub rate_per_s: f64,
    /// Frames in the window whose answer the observer never saw (not
    /// counted for [`Observe::DriverRoundTrip`]).
    pub frames_unanswered: u64,
    /// Commands in the window not in normal operation (command observer).
    pub commands_not_running: u64,
    /// Whether the sensor driver latched its safe state (it then stops
    /// waiting for the controller, so later motor commands skip the loop).
    pub driver_latched: bool,
    /// WARN/ERROR lines of the services' logs and trouble stopping them.
    pub findings: Vec<String>,
}

/// Runs the pipeline in real time on a fresh instance and measures, for
/// `measure` after `warmup`, the time from each frame's stamp to the
/// receipt of the `observe`d answer by the bench, which waits on that
/// channel's wake-up (the same `Inbox::wait` as the services). The bench
/// subscribes before the services start and adds one wake-up per tick.
pub fn realtime(
    bins: &[PathBuf],
    base: &Path,
    rate_hz: f64,
    warmup: Duration,
    measure: Duration,
    dir: &Path,
    observe: Observe,
) -> Result<RealtimeResult> {
    let tag = match observe {
        Observe::DriverRoundTrip => "d",
        Observe::MotorCommand => "m",
        Observe::ActuatorCommand => "c",
    };
    let instance = format!("pbrt{tag}{}", std::process::id());
    let config = dir.join(format!("pipeline-realtime-{tag}.toml"));
    write_config(
        &bench_config(base, &instance, TimingMode::Realtime, rate_hz, dir)?,
        &config,
    )?;
    let ipc = Ipc::open("bench_observer", &instance, None)?;
    let (motor_in, command_in) = match observe {
        Observe::DriverRoundTrip => {
            return driver_round_trip(bins, &ipc, &config, warmup, measure, dir)
        }
        Observe::MotorCommand => (Some(ipc.inbox(BUS_MOTOR, 64)?), None),
        Observe::ActuatorCommand => (None, Some(ipc.inbox(COMMAND, 64)?)),
    };
    // (frame seq, frame stamp ns, in normal operation) of the next answer.
    let next = || -> Result<Option<(u64, u64, bool)>> {
        Ok(match (&motor_in, &command_in) {
            (Some(m), _) => m.try_recv()?.map(|m| (m.frame_seq, m.stamp_ns, true)),
            (_, Some(c)) => c.try_recv()?.map(|c| {
                (
                    c.sensor_seq,
                    c.stamp_ns,
                    c.control_mode() == Some(ControlMode::Run),
                )
            }),
            _ => None,
        })
    };
    let wait = |t: Duration| -> Result<()> {
        match (&motor_in, &command_in) {
            (Some(m), _) => m.wait(t)?,
            (_, Some(c)) => c.wait(t)?,
            _ => {}
        }
        Ok(())
    };
    let mut fleet = Fleet::new(dir);
    spawn_services(&mut fleet, bins, &config, &[])?;

    // Started: the first answer observed.
    let t = Instant::now();
    loop {
        wait(LIVENESS_EVERY)?;
        if next()?.is_some() {
            break;
        }
        fleet.check_alive()?;
        if t.elapsed() > START_PATIENCE {
            bail!("the pipeline answered no frame within {START_PATIENCE:?}");
        }
    }

    let mut latency = Latency::new();
    let mut frames_unanswered = 0u64;
    let mut commands_not_running = 0u64;
    let mut last_frame: Option<u64> = None;
    let start = monotonic_ns();
    let record_from = start + warmup.as_nanos() as u64;
    let end = record_from + measure.as_nanos() as u64;
    let mut next_check = start;
    loop {
        let now = monotonic_ns();
        if now >= end {
            break;
        }
        wait(Duration::from_nanos(
            (end - now).min(LIVENESS_EVERY.as_nanos() as u64),
        ))?;
        while let Some((frame, stamp_ns, running)) = next()? {
            let now = monotonic_ns();
            if now < record_from || stamp_ns > now {
                continue;
            }
            latency.record(now - stamp_ns);
            if !running {
                commands_not_running += 1;
            }
            if let Some(prev) = last_frame {
                frames_unanswered += frame.saturating_sub(prev + 1);
            }
            last_frame = Some(frame);
        }
        if now >= next_check {
            fleet.check_alive()?;
            next_check = now + LIVENESS_EVERY.as_nanos() as u64;
        }
    }
    let mut findings = fleet.stop();
    findings.extend(log_findings(&fleet));
    Ok(RealtimeResult {
        rate_per_s: latency.count() as f64 / measure.as_secs_f64(),
        latency: latency.summary(),
        driver_latched: driver_latched(&findings),
        frames_unanswered,
        commands_not_running,
        findings,
    })
}

/// Whether the driver's log says it latched its safe state.
fn driver_latched(findings: &[String]) -> bool {
    findings
        .iter()
        .any(|f| f.starts_with("exo-sensor-driver") && f.contains("latched"))
}

/// The driver's round-trip report (`exo-sensor-driver --round-trip-report`).
#[derive(Debug, Deserialize)]
struct DriverReport {
    window_s: f64,
    #[serde(flatten)]
    latency: Summary,
}

/// [`Observe::DriverRoundTrip`]: runs the services for the warm-up (which
/// the driver leaves out of its statistics) and the measured window, stops
/// them, and reads the driver's report. The bench adds nothing to the loop:
/// it polls `ProtocolState` (no wake-up event) to see the loop start.
fn driver_round_trip(
    bins: &[PathBuf],
    ipc: &Ipc,
    config: &Path,
    warmup: Duration,
    measure: Duration,
    dir: &Path,
) -> Result<RealtimeResult> {
    let protocol_in = ipc.inbox(PROTOCOL, 64)?;
    let report_path = dir.join("pipeline-realtime-round-trip.json");
    let _ = std::fs::remove_file(&report_path);
    let warmup_s = warmup.as_secs_f64().to_string();
    let mut fleet = Fleet::new(dir);
    spawn_services(
        &mut fleet,
        bins,
        config,
        &[
            "--round-trip-report".as_ref(),
            report_path.as_os_str(),
            "--round-trip-warmup-s".as_ref(),
            warmup_s.as_ref(),
        ],
    )?;
    let t = Instant::now();
    while protocol_in.try_recv()?.is_none() {
        std::thread::sleep(LOCKSTEP_POLL);
        fleet.check_alive()?;
        if t.elapsed() > START_PATIENCE {
            bail!("the pipeline published no protocol state within {START_PATIENCE:?}");
        }
    }
    let end = Instant::now() + warmup + measure;
    while Instant::now() < end {
        std::thread::sleep(LIVENESS_EVERY.min(end.saturating_duration_since(Instant::now())));
        fleet.check_alive()?;
        while protocol_in.try_recv()?.is_some() {}
    }
    let mut findings = fleet.stop();
    findings.extend(log_findings(&fleet));
    let text = std::fs::read_to_string(&report_path).with_context(|| {
        format!(
            "the sensor driver wrote no round-trip report {}",
            report_path.display()
        )
    })?;
    let report: Option<DriverReport> = serde_json::from_str(&text)
        .with_context(|| format!("reading the round-trip report {}", report_path.display()))?;
    let (latency, rate_per_s) = match report {
        Some(r) if r.window_s > 0.0 => (Some(r.latency), r.latency.count as f64 / r.window_s),
        Some(r) => (Some(r.latency), 0.0),
        None => (None, 0.0),
    };
    Ok(RealtimeResult {
        latency,
        rate_per_s,
        frames_unanswered: 0,
        commands_not_running: 0,
        driver_latched: driver_latched(&findings),
        findings,
    })
}

/// What one lockstep run measured.
pub struct LockstepResult {
    /// Simulated seconds per wall-clock second over the window.
    pub real_time_factor: f64,
    /// Control ticks per wall-clock second.
    pub ticks_per_s: f64,
    /// The window's wall-clock length (s).
    pub wall_s: f64,
    /// The simulated time covered in the window (s).
    pub sim_s: f64,
    /// Whether the protocol ended before the window's planned end.
    pub ended_early: bool,
    /// WARN/ERROR lines of the services' logs and trouble stopping them.
    pub findings: Vec<String>,
}

/// Runs the pipeline in lockstep, flat out, and measures simulated time
/// against wall time from the `ProtocolState` samples, which the controller
/// publishes at least once per simulated second stamped with the tick's
/// simulated time (`k · period`). The observer polls that channel (it has
/// no wake-up event) every 2 ms, so it adds no wake-up to the loop; the
/// window's ends are each known to within a poll interval.
pub fn lockstep(
    bins: &[PathBuf],
    base: &Path,
    rate_hz: f64,
    warmup: Duration,
    measure: Duration,
    dir: &Path,
    spin_us: f64,
) -> Result<LockstepResult> {
    let instance = format!("pbls{}x{}", std::process::id(), spin_us as u64);
    let config = dir.join(format!("pipeline-lockstep-spin{}.toml", spin_us as u64));
    let mut cfg = bench_config(base, &instance, TimingMode::Lockstep, rate_hz, dir)?;
    cfg.run.lockstep_spin_us = spin_us;
    write_config(&cfg, &config)?;
    let ipc = Ipc::open("bench_observer", &instance, None)?;
    let protocol_in = ipc.inbox(PROTOCOL, 64)?;
    let mut fleet = Fleet::new(dir);
    spawn_services(&mut fleet, bins, &config, &[])?;

    // Latest (wall ns, simulated ns) seen, after draining the subscriber.
    // Sleeps one poll interval first.
    let latest = || -> Result<Option<(u64, u64)>> {
        std::thread::sleep(LOCKSTEP_POLL);
        let mut newest = None;
        while let Some(p) = protocol_in.try_recv()? {
            newest = Some(newest.map_or(p.stamp_ns, |n: u64| n.max(p.stamp_ns)));
        }
        Ok(newest.map(|sim| (monotonic_ns(), sim)))
    };

    let t = Instant::now();
    let first_wall = loop {
        if let Some((wall, _)) = latest()? {
            break wall;
        }
        fleet.check_alive()?;
        if t.elapsed() > START_PATIENCE {
            bail!("the lockstep pipeline published no protocol state within {START_PATIENCE:?}");
        }
    };
    let warm_end = first_wall + warmup.as_nanos() as u64;
    let mut start: Option<(u64, u64)> = None;
    let mut last: Option<(u64, u64)> = None;
    let mut ended_early = false;
    let mut next_check = monotonic_ns();
    loop {
        if let Some(obs) = latest()? {
            if start.is_none() && obs.0 >= warm_end {
                start = Some(obs);
            } else if let Some(s) = start {
                last = Some(obs);
                if obs.0 >= s.0 + measure.as_nanos() as u64 {
                    break;
                }
            }
        }
        let now = monotonic_ns();
        if now >= next_check {
            if !fleet.is_running("exo-controller") {
                // The protocol is over: the window ends at the last sample.
                ended_early = true;
                break;
            }
            fleet.check_alive()?;
            next_check = now + LIVENESS_EVERY.as_nanos() as u64;
        }
    }
    let mut findings = fleet.stop();
    findings.extend(log_findings(&fleet));
    let (Some(a), Some(b)) = (start, last) else {
        bail!("the lockstep window saw fewer than two protocol states (protocol too short?)");
    };
    let wall_s = (b.0 - a.0) as f64 * 1e-9;
    let sim_s = b.1.saturating_sub(a.1) as f64 * 1e-9;
    let real_time_factor = sim_s / wall_s;
    Ok(LockstepResult {
        real_time_factor,
        ticks_per_s: real_time_factor * rate_hz,
        wall_s,
        sim_s,
        ended_early,
        findings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bench_run_file_is_the_default_with_absolute_paths_and_the_full_protocol() {
        let dir = std::env::temp_dir().join(format!("exo-pb-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let base = exo_config::configs_dir().join("default.toml");
        let cfg = bench_config(&base, "pbtest1", TimingMode::Realtime, 500.0, &dir).unwrap();
        // Written elsewhere than configs/: the paths inside must not depend on it.
        let back = write_config(&cfg, &dir.join("run.toml")).unwrap();
        assert_eq!(back.run.timing, TimingMode::Realtime);
        assert_eq!(back.run.instance, "pbtest1");
        assert_eq!(back.run.rate_hz, 500.0);
        assert_eq!(back.run.max_sim_time_s, None);
        assert!(back.plant_model.is_absolute() && back.plant_model.is_file());
        assert!(back.subject_file.is_absolute() && back.subject_file.is_file());
        assert!(back.protocol.experiments_file.is_absolute());
        assert_eq!(back.protocol.experiments, (1..=9).collect::<Vec<u32>>());
        assert_eq!(back.protocol.periods, None);
        // The default's other settings are kept.
        let default = RunConfig::from_file(&base).unwrap();
        assert_eq!(back.controller, default.controller);
        assert_eq!(back.safety.safe_state, default.safety.safe_state);
        assert_eq!(back.safety.command_deadline_ms, BENCH_DEADLINE_MS);
        assert_eq!(back.safety.sample_deadline_ms, BENCH_DEADLINE_MS);
        assert_eq!(back.rig, default.rig);
        assert_eq!(back.run.seed, default.run.seed);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_run_file_is_named() {
        let e = bench_config(
            Path::new("/nonexistent/run.toml"),
            "x",
            TimingMode::Lockstep,
            1000.0,
            Path::new("/tmp"),
        )
        .err()
        .unwrap();
        assert!(format!("{e:#}").contains("/nonexistent/run.toml"), "{e:#}");
    }
}
