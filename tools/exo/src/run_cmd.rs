//! `exo run CONFIG`: validates a run configuration, then starts and
//! supervises its processes.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use exo_config::{RunConfig, TimingMode};

use std::time::Instant;

use exo_messages::ProtocolState;
use exo_service_kit::channels::Channel;
use exo_service_kit::collect::Collector;
use exo_service_kit::KeptOff;

use crate::supervisor::{
    config_args, sibling_program, supervise, Logs, Ready, ReadyProbe, Role, ServiceSpec,
};

/// Arguments of `exo run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The run configuration (e.g. configs/default.toml).
    pub config: PathBuf,
    /// Do not fit the recording and write the report after the run.
    #[arg(long)]
    pub no_report: bool,
}

/// The processes a configuration asks for, in start order; the recorder
/// writes `recording` when given.
pub fn services_of(
    cfg: &RunConfig,
    config: &std::path::Path,
    recording: Option<&std::path::Path>,
) -> Result<Vec<ServiceSpec>> {
    let s = cfg.services;
    let mut out = Vec::new();
    let table: [(bool, &'static str, &'static str, Role); 5] = [
        (s.recorder, "recorder", "exo-recorder", Role::Restartable),
        (
            s.identifier,
            "identifier",
            "exo-identifier",
            Role::Restartable,
        ),
        (
            s.plant_sim,
            "plant-sim",
            "exo-plant-sim",
            // With run.max_sim_time_s the simulator's normal exit is the end.
            if cfg.run.max_sim_time_s.is_some() {
                Role::EndsRun
            } else {
                Role::Critical
            },
        ),
        (
            s.sensor_driver,
            "sensor-driver",
            "exo-sensor-driver",
            // Without a controller (a replay) the driver ends the run.
            if s.controller {
                Role::Critical
            } else {
                Role::EndsRun
            },
        ),
        (s.controller, "controller", "exo-controller", Role::EndsRun),
    ];
    for (enabled, name, bin, role) in table {
        if enabled {
            let mut args = config_args(config);
            if let (Some(r), "recorder") = (recording, name) {
                args.push("--output".into());
                args.push(r.display().to_string());
            }
            let probe = match name {
                "recorder" => Some(ReadyProbe::SubscribesBusMotor),
                "identifier" => Some(ReadyProbe::PublishesEstimate),
                _ => None,
            };
            out.push(ServiceSpec {
                name,
                program: sibling_program(bin)?,
                args,
                role,
                ready: probe.map(|probe| Ready {
                    instance: cfg.run.instance.clone(),
                    probe,
                }),
            });
        }
    }
    Ok(out)
}

/// Prints a line whenever the run enters a new experiment period: which
/// one, simulated time (from the samples' stamps) and wall time.
pub struct Progress {
    protocol: Collector<ProtocolState>,
    every_period: bool,
    seen: usize,
    last: (u32, u32),
    first_stamp_ns: Option<u64>,
    wall: Instant,
}

impl Progress {
    /// Watches the protocol channel of `instance`; a line per period.
    pub fn start(instance: &str) -> Result<Self> {
        Self::watch(instance, true)
    }

    /// A line per experiment only (long runs).
    pub fn per_experiment(instance: &str) -> Result<Self> {
        Self::watch(instance, false)
    }

    fn watch(instance: &str, every_period: bool) -> Result<Self> {
        let node = format!("exo_progress_{}", std::process::id());
        Ok(Progress {
            protocol: Collector::start(&node, instance, Channel::Protocol)
                .context("watching the protocol channel for progress")?,
            every_period,
            seen: 0,
            last: (0, 0),
            first_stamp_ns: None,
            wall: Instant::now(),
        })
    }

    /// Prints what is new since the last call.
    pub fn poll(&mut self) {
        let states = self.protocol.snapshot();
        for p in &states[self.seen.min(states.len())..] {
            let first = *self.first_stamp_ns.get_or_insert(p.stamp_ns);
            let new = if self.every_period {
                (p.experiment, p.period) != self.last
            } else {
                p.experiment != self.last.0
            };
            if new && p.experiment > 0 {
                let sim_s = p.stamp_ns.saturating_sub(first) as f64 * 1e-9;
                let wall_s = self.wall.elapsed().as_secs_f64();
                eprintln!(
                    "exo: experiment {} period {} (ω = {:.2} rad/s, {:.2} Nm, α = {}): sim {:.1} s, wall {:.1} s ({:.1}× real time)",
                    p.experiment,
                    p.period,
                    p.omega,
                    p.amplitude,
                    p.alpha,
                    sim_s,
                    wall_s,
                    sim_s / wall_s.max(1e-9)
                );
            }
            self.last = (p.experiment, p.period);
        }
        self.seen = states.len();
    }
}

/// Where a run's recording goes: `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`.
pub fn recording_path(cfg: &RunConfig) -> PathBuf {
    let unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    cfg.run.output_dir.join(format!(
        "{}-{}-{unix_s}.mcap",
        cfg.run.instance,
        cfg.subject().name
    ))
}

/// Validates a run file, then starts and supervises its processes with
/// progress lines; returns the recording's path when the recorder ran.
pub fn run_config(config: &std::path::Path, logs: Logs) -> Result<Option<PathBuf>> {
    // Validate everything before any process starts.
    let cfg = RunConfig::from_file(config)?;
    exo_plant_sim::PlantModel::from_file(&cfg.plant_model)?;
    let recording = cfg.services.recorder.then(|| recording_path(&cfg));
    let services = services_of(&cfg, config, recording.as_deref())?;
    eprintln!(
        "exo: starting {} for {} ({:?} timing at {} Hz)",
        services
            .iter()
            .map(|s| s.name)
            .collect::<Vec<_>>()
            .join(", "),
        config.display(),
        cfg.run.timing,
        cfg.run.rate_hz
    );
    keep_off_the_control_path(&cfg);
    let mut progress = Progress::start(&cfg.run.instance)?;
    let outcome = supervise(services, logs, || progress.poll())
        .with_context(|| format!("run of {}", config.display()));
    progress.poll();
    outcome?;
    if let Some(r) = &recording {
        eprintln!("exo: recording {}", r.display());
    }
    Ok(recording)
}

/// In real time with the driver or the controller pinned (`[realtime]`),
/// confines the launcher, and so every process it starts, to the other
/// CPUs: the identifier, the recorder and the launcher's own log forwarding
/// then never share a CPU with the control path, which pins itself back
/// onto its CPUs. On a kernel that is not preemptible, a process in a long
/// system call holds its CPU whatever the control path's priority
/// (BENCHMARKS.md, "Recorder under load"). Must run before the launcher
/// starts any thread.
fn keep_off_the_control_path(cfg: &RunConfig) {
    let Some(rt) = cfg
        .realtime
        .filter(|_| cfg.run.timing == TimingMode::Realtime)
    else {
        return;
    };
    let mut control: Vec<usize> = [rt.sensor_driver_cpu, rt.controller_cpu]
        .into_iter()
        .flatten()
        .collect();
    control.dedup();
    if control.is_empty() {
        return;
    }
    match exo_service_kit::keep_off_cpus(&control) {
        Ok(KeptOff::Confined(rest)) => eprintln!(
            "exo: control path on CPU {control:?}; launcher, identifier and recorder on CPU {rest:?}"
        ),
        Ok(KeptOff::AlreadyOff) => eprintln!(
            "exo: control path on CPU {control:?}; the launcher was already confined to other CPUs"
        ),
        Ok(KeptOff::NoneLeft) => eprintln!(
            "exo: warning: no CPU left besides the control path's {control:?}; \
             the identifier and the recorder share them"
        ),
        Err(e) => eprintln!(
            "exo: warning: could not keep the launcher off the control path's CPUs {control:?}: {e}"
        ),
    }
}

/// Runs `exo run`: the processes, then (when the run was recorded) the fit
/// and the report of the recording.
pub fn run(args: &RunArgs) -> Result<()> {
    let Some(recording) = run_config(&args.config, Logs::Forward)? else {
        return Ok(());
    };
    // Only the identification protocol excites the subject for a fit (a
    // replay republishes whatever the recording's protocol was).
    let cfg = RunConfig::from_file(&args.config)?;
    let identification = cfg.protocol.mode == exo_config::ProtocolMode::Identification;
    if args.no_report || !identification {
        return Ok(());
    }
    let fit_args = crate::fit_cmd::FitArgs::for_recordings(vec![recording.clone()]);
    let (_, report) = crate::fit_cmd::fit(&fit_args)?;
    print!("{}", crate::fit_cmd::tables(&report));
    let stem = recording
        .file_stem()
        .map_or("run".into(), |s| s.to_string_lossy().into_owned());
    let dir = recording
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .join(format!("{stem}-report"));
    let page = crate::report_cmd::write_report(&fit_args, &dir)?;
    println!("recording: {}", recording.display());
    println!("report:    {}", page.display());
    Ok(())
}
