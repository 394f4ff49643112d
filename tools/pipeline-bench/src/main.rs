//! `exo-pipeline-bench`: latency and throughput of the exo control loop,
//! measured side by side in one run with a bare iceoryx2 ping-pong and the
//! same loop over Unix-domain sockets.
//!
//! ```sh
//! cargo build --release -p exo-plant-sim -p exo-sensor-driver -p exo-controller
//! cargo run --release -p exo-pipeline-bench -- --seconds 20
//! ```
//!
//! Rows (each `--seconds` long after `--warmup-seconds`, one after the other):
//!
//! * `pipeline-rt`: the real `exo-plant-sim`, `exo-sensor-driver` and
//!   `exo-controller` in real time at `--rate-hz`, three runs one after the
//!   other:
//!   - `pipeline-rt-round-trip`, the sensor → controller → driver round
//!     trip, measured by the driver itself (`--round-trip-report`): from
//!     just before it publishes a `SensorSample` to just after it receives
//!     the `ActuatorCommand` answering it: the interval the ping-pong
//!     measures, with no observer added to the loop. The target compares
//!     this row's p99 with `iox-pingpong`'s.
//!   - `pipeline-rt-loop`: the plant's frame stamp (taken right before it
//!     publishes the `BusSensorFrame`) to the receipt, by the bench waiting
//!     on that channel's wake-up, of the driver's `BusMotorCommand` for
//!     that frame (the full plant → driver → controller → driver → plant
//!     loop: the simulated bus's two hand-overs as well).
//!   - `pipeline-rt-command`: the same stamp to the controller's
//!     `ActuatorCommand` (plant → driver → controller → subscriber).
//! * `pipeline-lockstep`: the same processes in lockstep, flat out: simulated
//!   time per wall time (the real-time factor) and control ticks per second.
//! * `iox-pingpong`, `iox-loop`: bench ↔ stand-in controller, and bench →
//!   stand-in driver → stand-in controller → driver → bench, over iceoryx2
//!   with the pipeline's channels, payloads and wake-ups (service-kit
//!   `Outbox`/`Inbox`), paced at `--rate-hz` like the plant.
//! * `uds-pingpong`, `uds-loop`: the same over Unix-domain stream sockets
//!   (blocking reads).
//! * `iox-loop-flat`, `uds-loop-flat`: the three-process loops back to back.
//!
//! The run file (`--config`, default `configs/realtime.toml`) gives the
//! pipeline its settings and its real-time placement (`[realtime]`: CPU per
//! process, SCHED_FIFO, locked memory); the paced baselines run under the
//! same placement, the bench's probing thread taking the place of the
//! process it plays (`placement`). The flat-out rows are lockstep's
//! analogues and are not placed.
//!
//! The stand-ins do a few multiplications, not the services' work (see
//! `roles`). Percentiles come from an HDR histogram (3 significant digits);
//! the maximum is exact. Child processes are stopped and reaped after each
//! row, also when it fails, and die with the bench.

mod bare;
mod link;
mod pipeline;
mod placement;
mod procs;
mod roles;
mod stats;

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use clap::{Parser, ValueEnum};
use serde_json::json;

use crate::bare::{Pace, Shape};
use crate::pipeline::Observe;
use crate::placement::Placement;
use crate::roles::{Role, RoleArgs, Transport};
use crate::stats::{fmt_us, load_average_1min, verdict, Goal, Latency, Summary};
use exo_service_kit::RealtimeRequest;

/// Target: pipeline p99 at most this multiple of the bare iceoryx2 ping-pong p99.
const TARGET_P99_RATIO: f64 = 3.0;
/// Target: lockstep at least this many times faster than real time.
const TARGET_REAL_TIME_FACTOR: f64 = 50.0;

/// A group of rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum RowKind {
    /// The real services in real time (two rows: full loop and sensor → controller).
    PipelineRt,
    /// The real services in lockstep, flat out.
    PipelineLockstep,
    /// Bare iceoryx2 ping-pong, paced.
    IoxPingpong,
    /// Bare iceoryx2 three-process loop, paced.
    IoxLoop,
    /// Unix-socket ping-pong, paced.
    UdsPingpong,
    /// Unix-socket three-process loop, paced.
    UdsLoop,
    /// Bare iceoryx2 three-process loop, flat out.
    IoxLoopFlat,
    /// Unix-socket three-process loop, flat out.
    UdsLoopFlat,
}

/// The order rows run in: the compared rows close together in time.
const ALL_ROWS: [RowKind; 8] = [
    RowKind::IoxPingpong,
    RowKind::PipelineRt,
    RowKind::IoxLoop,
    RowKind::UdsPingpong,
    RowKind::UdsLoop,
    RowKind::PipelineLockstep,
    RowKind::IoxLoopFlat,
    RowKind::UdsLoopFlat,
];

#[derive(Debug, Parser)]
#[command(
    name = "exo-pipeline-bench",
    about = "Latency and throughput of the exo pipeline against a bare iceoryx2 ping-pong and a Unix-socket loop"
)]
struct Cli {
    /// Measured seconds per row (after the warm-up).
    #[arg(long, default_value_t = 20.0)]
    seconds: f64,
    /// Warm-up seconds per row (not recorded).
    #[arg(long, default_value_t = 1.0)]
    warmup_seconds: f64,
    /// Control rate (Hz) of the paced rows and the pipeline.
    #[arg(long, default_value_t = 1000.0)]
    rate_hz: f64,
    /// Print the results as JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// The run file the pipeline's configuration is derived from; its
    /// `[realtime]` placement is also given to the paced baselines
    /// (default: configs/realtime.toml; configs/default.toml places nothing).
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Keep the run files and the processes' logs (in the temporary directory printed at the end).
    #[arg(long)]
    keep_logs: bool,
    /// Only these rows (comma-separated; default: all).
    #[arg(long, value_enum, value_delimiter = ',')]
    rows: Vec<RowKind>,
    /// `run.lockstep_spin_us` of the second lockstep row (the first uses 0, the default).
    #[arg(long, default_value_t = 200.0)]
    lockstep_spin_us: f64,

    /// Internal: run as a stand-in process of a bare loop.
    #[arg(long, value_enum, hide = true)]
    role: Option<Role>,
    /// Internal: the stand-in's transport.
    #[arg(long, value_enum, hide = true)]
    transport: Option<Transport>,
    /// Internal: the stand-in's iceoryx2 instance.
    #[arg(long, hide = true)]
    instance: Option<String>,
    /// Internal: the socket the stand-in connects to.
    #[arg(long, hide = true)]
    connect: Option<PathBuf>,
    /// Internal: the socket the stand-in driver listens on.
    #[arg(long, hide = true)]
    listen: Option<PathBuf>,
    /// Internal: pin the stand-in to this CPU.
    #[arg(long, hide = true)]
    cpu: Option<usize>,
    /// Internal: run the stand-in in SCHED_FIFO at this priority.
    #[arg(long, hide = true)]
    fifo_priority: Option<i32>,
    /// Internal: lock the stand-in's memory.
    #[arg(long, hide = true)]
    lock_memory: bool,
}

/// One line of the result table.
struct Row {
    key: &'static str,
    what: &'static str,
    interval: &'static str,
    summary: Option<Summary>,
    rate_per_s: Option<f64>,
    real_time_factor: Option<f64>,
    load_before: Option<f64>,
    load_after: Option<f64>,
    notes: Vec<String>,
    /// Why the numbers do not measure what the row says (they are still shown).
    invalid: Option<String>,
    error: Option<String>,
}

impl Row {
    fn new(key: &'static str, what: &'static str, interval: &'static str) -> Self {
        Row {
            key,
            what,
            interval,
            summary: None,
            rate_per_s: None,
            real_time_factor: None,
            load_before: None,
            load_after: None,
            notes: Vec::new(),
            invalid: None,
            error: None,
        }
    }

    fn latency(self, l: &Latency, rate: f64) -> Self {
        self.summary(l.summary(), rate)
    }

    fn summary(mut self, s: Option<Summary>, rate: f64) -> Self {
        self.summary = s;
        self.rate_per_s = Some(rate);
        self
    }

    fn json(&self) -> serde_json::Value {
        json!({
            "key": self.key,
            "what": self.what,
            "interval": self.interval,
            "count": self.summary.map(|s| s.count),
            "p50_us": self.summary.map(|s| s.p50_ns as f64 / 1e3),
            "p99_us": self.summary.map(|s| s.p99_ns as f64 / 1e3),
            "p999_us": self.summary.map(|s| s.p999_ns as f64 / 1e3),
            "max_us": self.summary.map(|s| s.max_ns as f64 / 1e3),
            "mean_us": self.summary.map(|s| s.mean_ns / 1e3),
            "rate_per_s": self.rate_per_s,
            "real_time_factor": self.real_time_factor,
            "load1_before": self.load_before,
            "load1_after": self.load_after,
            "notes": self.notes,
            "invalid": self.invalid,
            "error": self.error,
        })
    }
}

fn main() {
    let cli = Cli::parse();
    if let Some(role) = cli.role {
        let args = RoleArgs {
            role,
            transport: cli.transport.unwrap_or(Transport::Iox),
            instance: cli.instance.clone(),
            connect: cli.connect.clone(),
            listen: cli.listen.clone(),
            realtime: RealtimeRequest {
                sched_fifo_priority: cli.fifo_priority,
                lock_memory: cli.lock_memory,
                cpu: cli.cpu,
            },
        };
        if let Err(e) = roles::run_role(&args) {
            eprintln!("exo-pipeline-bench --role {role:?}: {e:#}");
            std::process::exit(1);
        }
        return;
    }
    match run(&cli) {
        Ok(all_ok) => std::process::exit(if all_ok { 0 } else { 1 }),
        Err(e) => {
            eprintln!("exo-pipeline-bench: {e:#}");
            std::process::exit(2);
        }
    }
}

fn check_args(cli: &Cli) -> Result<()> {
    if !(cli.seconds.is_finite() && cli.seconds > 0.0) {
        bail!("--seconds must be a positive number, got {}", cli.seconds);
    }
    if !(cli.warmup_seconds.is_finite() && cli.warmup_seconds >= 0.0) {
        bail!(
            "--warmup-seconds must be zero or more, got {}",
            cli.warmup_seconds
        );
    }
    if !(cli.rate_hz.is_finite() && (1.0..=100_000.0).contains(&cli.rate_hz)) {
        bail!("--rate-hz must lie in [1, 100000], got {}", cli.rate_hz);
    }
    Ok(())
}

/// Runs the selected rows; `Ok(false)` when a row failed.
fn run(cli: &Cli) -> Result<bool> {
    check_args(cli)?;
    let measure = Duration::from_secs_f64(cli.seconds);
    let warmup = Duration::from_secs_f64(cli.warmup_seconds);
    let period_ns = (1e9 / cli.rate_hz).round() as u64;
    let base = cli
        .config
        .clone()
        .unwrap_or_else(|| exo_config::configs_dir().join("realtime.toml"));
    let base = base
        .canonicalize()
        .with_context(|| format!("--config {}", base.display()))?;
    let exe = std::env::current_exe().context("locating the bench executable")?;
    let placement = Placement::of(
        &exo_config::RunConfig::from_file(&base)
            .with_context(|| format!("--config {}", base.display()))?,
    );
    let kinds: Vec<RowKind> = if cli.rows.is_empty() {
        ALL_ROWS.to_vec()
    } else {
        ALL_ROWS
            .iter()
            .copied()
            .filter(|k| cli.rows.contains(k))
            .collect()
    };
    let needs_services = kinds
        .iter()
        .any(|k| matches!(k, RowKind::PipelineRt | RowKind::PipelineLockstep));
    let bins = if needs_services {
        pipeline::service_binaries()?
    } else {
        Vec::new()
    };
    let dir = std::env::temp_dir().join(format!("exo-pipeline-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;

    let mut rows: Vec<Row> = Vec::new();
    for kind in kinds {
        eprintln!("exo-pipeline-bench: {kind:?} …");
        let load_before = load_average_1min();
        let mut new_rows = run_kind(
            kind, &exe, &bins, &base, &placement, cli, period_ns, warmup, measure, &dir,
        );
        let load_after = load_average_1min();
        for r in &mut new_rows {
            r.load_before = load_before;
            r.load_after = load_after;
            if let Some(e) = &r.error {
                eprintln!("exo-pipeline-bench: {} failed: {e}", r.key);
            }
        }
        rows.extend(new_rows);
    }
    let all_ok = rows.iter().all(|r| r.error.is_none());
    let targets = targets(&rows);
    if cli.json {
        let v = json!({
            "rate_hz": cli.rate_hz,
            "seconds_per_row": cli.seconds,
            "warmup_seconds": cli.warmup_seconds,
            "cpus": std::thread::available_parallelism().map(|n| n.get()).ok(),
            "run_file": base.display().to_string(),
            "placement": placement.describe(),
            "rows": rows.iter().map(Row::json).collect::<Vec<_>>(),
            "targets": targets.iter().map(|t| json!({
                "name": t.name, "measured": t.measured, "target": t.target,
                "verdict": t.verdict, "detail": t.detail,
            })).collect::<Vec<_>>(),
        });
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print_table(&rows, &targets, cli, &base, &placement);
    }
    if all_ok && !cli.keep_logs {
        let _ = std::fs::remove_dir_all(&dir);
    } else if all_ok {
        eprintln!("exo-pipeline-bench: logs kept in {}", dir.display());
    } else {
        eprintln!(
            "exo-pipeline-bench: logs of the failed rows are in {}",
            dir.display()
        );
    }
    Ok(all_ok)
}

#[allow(clippy::too_many_arguments)]
fn run_kind(
    kind: RowKind,
    exe: &Path,
    bins: &[PathBuf],
    base: &Path,
    placement: &Placement,
    cli: &Cli,
    period_ns: u64,
    warmup: Duration,
    measure: Duration,
    dir: &Path,
) -> Vec<Row> {
    let paced = Pace::Period(period_ns);
    let bare_loop = |transport, shape, pace, placement, tag| {
        let spec = bare::LoopSpec {
            exe,
            shape,
            pace,
            warmup,
            measure,
            dir,
            tag,
        };
        bare::run(transport, &spec, placement)
    };
    let bare = |key: &'static str,
                what: &'static str,
                interval: &'static str,
                result: Result<bare::LoopStats>|
     -> Row {
        let row = Row::new(key, what, interval);
        match result {
            Ok(s) => {
                let mut row = row.latency(&s.round_trip, s.rate_per_s);
                if s.late_ticks > 0 {
                    row.notes.push(format!(
                        "{} ticks started more than a period late",
                        s.late_ticks
                    ));
                }
                if matches!(kind, RowKind::IoxLoopFlat | RowKind::UdsLoopFlat) {
                    row.real_time_factor = Some(s.rate_per_s / cli.rate_hz);
                }
                row
            }
            Err(e) => Row {
                error: Some(format!("{e:#}")),
                ..row
            },
        }
    };
    const PROBE_3P: &str = "bench stamps BusSensorFrame → stand-in driver → stand-in controller → driver → BusMotorCommand received by the bench";
    const PROBE_PP: &str =
        "bench stamps SensorSample → stand-in controller → ActuatorCommand received by the bench";
    match kind {
        RowKind::IoxPingpong => vec![bare(
            "iox-pingpong",
            "bare iceoryx2 ping-pong, 2 processes",
            PROBE_PP,
            bare_loop(Transport::Iox, Shape::PingPong, paced, Some(placement), "ipp"),
        )],
        RowKind::IoxLoop => vec![bare(
            "iox-loop",
            "bare iceoryx2 3-process loop",
            PROBE_3P,
            bare_loop(Transport::Iox, Shape::ThreeProcess, paced, Some(placement), "i3"),
        )],
        RowKind::UdsPingpong => vec![bare(
            "uds-pingpong",
            "Unix-socket ping-pong, 2 processes",
            PROBE_PP,
            bare_loop(Transport::Uds, Shape::PingPong, paced, Some(placement), "upp"),
        )],
        RowKind::UdsLoop => vec![bare(
            "uds-loop",
            "Unix-socket 3-process loop",
            PROBE_3P,
            bare_loop(Transport::Uds, Shape::ThreeProcess, paced, Some(placement), "u3"),
        )],
        RowKind::IoxLoopFlat => vec![bare(
            "iox-loop-flat",
            "bare iceoryx2 3-process loop, flat out",
            PROBE_3P,
            bare_loop(Transport::Iox, Shape::ThreeProcess, Pace::FlatOut, None, "i3f"),
        )],
        RowKind::UdsLoopFlat => vec![bare(
            "uds-loop-flat",
            "Unix-socket 3-process loop, flat out",
            PROBE_3P,
            bare_loop(Transport::Uds, Shape::ThreeProcess, Pace::FlatOut, None, "u3f"),
        )],
        RowKind::PipelineRt => [
            (
                Observe::DriverRoundTrip,
                Row::new(
                    "pipeline-rt-round-trip",
                    "exo pipeline, real time: sensor → controller → driver",
                    "driver stamps before publishing SensorSample → controller → ActuatorCommand for it received by the driver (its own --round-trip-report; no bench subscriber in the loop)",
                ),
            ),
            (
                Observe::MotorCommand,
                Row::new(
                    "pipeline-rt-loop",
                    "exo pipeline, real time: full loop",
                    "plant stamps BusSensorFrame → driver → SensorSample → controller → ActuatorCommand → driver → BusMotorCommand received by a subscriber",
                ),
            ),
            (
                Observe::ActuatorCommand,
                Row::new(
                    "pipeline-rt-command",
                    "exo pipeline, real time: to the controller's command",
                    "plant stamps BusSensorFrame → driver → SensorSample → controller → ActuatorCommand received by a subscriber",
                ),
            ),
        ]
        .into_iter()
        .map(|(observe, row)| {
            match pipeline::realtime(bins, base, cli.rate_hz, warmup, measure, dir, observe) {
                Ok(r) => {
                    let mut row = row.summary(r.latency, r.rate_per_s);
                    if r.frames_unanswered > 0 {
                        row.notes.push(format!(
                            "{} frames whose answer was not seen",
                            r.frames_unanswered
                        ));
                    }
                    if r.commands_not_running > 0 {
                        row.notes.push(format!(
                            "{} commands in a safe state, not normal operation",
                            r.commands_not_running
                        ));
                    }
                    if r.driver_latched && observe != Observe::ActuatorCommand {
                        row.invalid = Some(
                            "the sensor driver latched its safe state: after that it no longer waits for the controller".to_string(),
                        );
                    }
                    row.notes.extend(summarise_findings(&r.findings));
                    row
                }
                Err(e) => Row {
                    error: Some(format!("{e:#}")),
                    ..row
                },
            }
        })
        .collect(),
        RowKind::PipelineLockstep => [0.0, cli.lockstep_spin_us].iter().flat_map(|&spin| {
            let row = Row::new(
                if spin > 0.0 { "pipeline-lockstep-spin" } else { "pipeline-lockstep" },
                if spin > 0.0 { "exo pipeline, lockstep flat out, polling before sleeping (run.lockstep_spin_us)" } else { "exo pipeline, lockstep flat out (default: every wait sleeps on an event)" },
                "simulated time (ProtocolState stamps) per wall-clock time",
            );
            match pipeline::lockstep(bins, base, cli.rate_hz, warmup, measure, dir, spin) {
                Ok(r) => {
                    let mut row = Row {
                        rate_per_s: Some(r.ticks_per_s),
                        real_time_factor: Some(r.real_time_factor),
                        ..row
                    };
                    row.notes.push(format!(
                        "window {:.2} s wall, {:.1} s simulated",
                        r.wall_s, r.sim_s
                    ));
                    if r.ended_early {
                        row.notes
                            .push("the protocol ended before the window did".to_string());
                    }
                    row.notes.extend(summarise_findings(&r.findings));
                    vec![row]
                }
                Err(e) => vec![Row {
                    error: Some(format!("{e:#}")),
                    ..row
                }],
            }
        }).collect(),
    }
}

/// At most three log findings, and how many more there were.
fn summarise_findings(findings: &[String]) -> Vec<String> {
    let mut out: Vec<String> = findings.iter().take(3).cloned().collect();
    if findings.len() > 3 {
        out.push(format!("… and {} more log warnings", findings.len() - 3));
    }
    out
}

/// One target and whether it is met.
struct Target {
    name: &'static str,
    measured: Option<f64>,
    target: f64,
    verdict: &'static str,
    detail: String,
}

fn targets(rows: &[Row]) -> Vec<Target> {
    let p99 = |key: &str| {
        rows.iter()
            .find(|r| r.key == key)
            .and_then(|r| r.summary)
            .map(|s| s.p99_ns as f64)
    };
    let mut out = Vec::new();
    let ratio = match (p99("pipeline-rt-round-trip"), p99("iox-pingpong")) {
        (Some(a), Some(b)) => Some(a / b),
        _ => None,
    };
    let loop_invalid = rows
        .iter()
        .find(|r| r.key == "pipeline-rt-round-trip")
        .is_some_and(|r| r.invalid.is_some());
    out.push(Target {
        name: "pipeline sensor → controller → driver p99 / bare iceoryx2 ping-pong p99",
        measured: ratio,
        target: TARGET_P99_RATIO,
        verdict: match ratio {
            None => "NOT MEASURED",
            Some(_) if loop_invalid => "INVALID",
            Some(r) => verdict(r, TARGET_P99_RATIO, Goal::AtMost),
        },
        detail: match ratio {
            Some(r) => format!("{r:.2} (target ≤ {TARGET_P99_RATIO})"),
            None => "not measured (needs rows pipeline-rt and iox-pingpong)".to_string(),
        },
    });
    for (key, name) in [
        (
            "pipeline-lockstep",
            "lockstep real-time factor (default waits)",
        ),
        (
            "pipeline-lockstep-spin",
            "lockstep real-time factor (lockstep_spin_us)",
        ),
    ] {
        let rtf = rows
            .iter()
            .find(|r| r.key == key)
            .and_then(|r| r.real_time_factor);
        out.push(Target {
            name,
            measured: rtf,
            target: TARGET_REAL_TIME_FACTOR,
            verdict: rtf.map_or("NOT MEASURED", |r| {
                verdict(r, TARGET_REAL_TIME_FACTOR, Goal::AtLeast)
            }),
            detail: match rtf {
                Some(r) => format!("{r:.1}× (target ≥ {TARGET_REAL_TIME_FACTOR}×)"),
                None => format!("not measured (needs row {key})"),
            },
        });
    }
    out
}

fn print_table(rows: &[Row], targets: &[Target], cli: &Cli, base: &Path, placement: &Placement) {
    println!(
        "rate {} Hz, {} s per row after {} s warm-up; latencies in µs",
        cli.rate_hz, cli.seconds, cli.warmup_seconds
    );
    println!(
        "run file {}; real-time placement of the pipeline and the paced baselines: {}",
        base.display(),
        placement.describe()
    );
    println!();
    println!("| row | what | n | p50 | p99 | p99.9 | max | rate /s | ×RT | load1 |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        let dash = || "—".to_string();
        let s = r.summary;
        let load = match (r.load_before, r.load_after) {
            (Some(a), Some(b)) => format!("{a:.2}→{b:.2}"),
            _ => dash(),
        };
        if let Some(e) = &r.error {
            println!(
                "| {} | {} | FAILED: {} | | | | | | | {load} |",
                r.key,
                r.what,
                e.replace('\n', " ")
            );
            continue;
        }
        println!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {load} |",
            r.key,
            r.what,
            s.map_or_else(dash, |s| s.count.to_string()),
            s.map_or_else(dash, |s| fmt_us(s.p50_ns)),
            s.map_or_else(dash, |s| fmt_us(s.p99_ns)),
            s.map_or_else(dash, |s| fmt_us(s.p999_ns)),
            s.map_or_else(dash, |s| fmt_us(s.max_ns)),
            r.rate_per_s.map_or_else(dash, |v| format!("{v:.0}")),
            r.real_time_factor.map_or_else(dash, |v| format!("{v:.1}")),
        );
    }
    println!();
    println!("Intervals:");
    for r in rows {
        println!("- {}: {}", r.key, r.interval);
        if let Some(why) = &r.invalid {
            println!("  - INVALID: {why}");
        }
        for n in &r.notes {
            println!("  - note: {n}");
        }
    }
    println!();
    println!("Targets:");
    for t in targets {
        println!("- {}: {} → {}", t.name, t.detail, t.verdict);
    }
}
