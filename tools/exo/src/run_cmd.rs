//! `exo run CONFIG`: validates a run configuration, then starts and
//! supervises its processes.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use exo_config::RunConfig;

use crate::supervisor::{config_args, sibling_program, supervise, Role, ServiceSpec};

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
    supervise(services, || {}).with_context(|| format!("run of {}", args.config.display()))
}
