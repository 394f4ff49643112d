//! The processes of a run configuration, in start order.

use anyhow::Result;
use exo_config::RunConfig;

use crate::supervise::{config_args, sibling_program, Ready, ReadyProbe, Role, ServiceSpec};

/// The processes a configuration asks for, in start order; the recorder
/// writes `recording` when given.
pub fn services_of(
    cfg: &RunConfig,
    config: &std::path::Path,
    recording: Option<&std::path::Path>,
) -> Result<Vec<ServiceSpec>> {
    let s = cfg.services;
    let mut out = Vec::new();
    let table: [(bool, &'static str, &'static str, Role); 6] = [
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
            // Without a controller the driver ends the run.
            if s.controller {
                Role::Critical
            } else {
                Role::EndsRun
            },
        ),
        (s.controller, "controller", "exo-controller", Role::EndsRun),
        // A recording played back: the run ends with it.
        (s.player, "player", "exo-player", Role::EndsRun),
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
