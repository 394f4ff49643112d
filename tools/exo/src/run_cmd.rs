//! `exo run CONFIG`: validates a run configuration, then starts and
//! supervises its processes.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use exo_config::RunConfig;

use std::time::Instant;

use exo_messages::ProtocolState;
use exo_service_kit::channels::Channel;
use exo_service_kit::collect::Collector;

use crate::supervisor::{config_args, sibling_program, supervise, Logs, Role, ServiceSpec};

/// Arguments of `exo run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The run configuration (e.g. configs/default.toml).
    pub config: PathBuf,
}

/// The processes a configuration asks for, in start order.
pub fn services_of(cfg: &RunConfig, config: &std::path::Path) -> Result<Vec<ServiceSpec>> {
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
        (s.plant_sim, "plant-sim", "exo-plant-sim", Role::Critical),
        (
            s.sensor_driver,
            "sensor-driver",
            "exo-sensor-driver",
            Role::Critical,
        ),
        (s.controller, "controller", "exo-controller", Role::EndsRun),
    ];
    for (enabled, name, bin, role) in table {
        if enabled {
            out.push(ServiceSpec {
                name,
                program: sibling_program(bin)?,
                args: config_args(config),
                role,
            });
        }
    }
    Ok(out)
}

/// Prints a line whenever the run enters a new experiment period: which
/// one, simulated time (from the samples' stamps) and wall time.
pub struct Progress {
    protocol: Collector<ProtocolState>,
    seen: usize,
    last: (u32, u32),
    first_stamp_ns: Option<u64>,
    wall: Instant,
}

impl Progress {
    /// Watches the protocol channel of `instance`.
    pub fn start(instance: &str) -> Result<Self> {
        let node = format!("exo_progress_{}", std::process::id());
        Ok(Progress {
            protocol: Collector::start(&node, instance, Channel::Protocol)
                .context("watching the protocol channel for progress")?,
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
            if (p.experiment, p.period) != self.last && p.experiment > 0 {
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

/// Runs `exo run`.
pub fn run(args: &RunArgs) -> Result<()> {
    // Validate everything before any process starts.
    let cfg = RunConfig::from_file(&args.config)?;
    exo_plant_sim::PlantModel::from_file(&cfg.plant_model)?;
    let services = services_of(&cfg, &args.config)?;
    eprintln!(
        "exo: starting {} for {} ({:?} timing at {} Hz)",
        services
            .iter()
            .map(|s| s.name)
            .collect::<Vec<_>>()
            .join(", "),
        args.config.display(),
        cfg.run.timing,
        cfg.run.rate_hz
    );
    let mut progress = Progress::start(&cfg.run.instance)?;
    let outcome = supervise(services, Logs::Forward, || progress.poll())
        .with_context(|| format!("run of {}", args.config.display()));
    progress.poll();
    outcome
}
