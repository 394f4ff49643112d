//! The processes of a run configuration, in start order.

use std::time::Duration;

use exo_config::{RunConfig, TimingMode};
use exo_messages::channels::ProcessName;

use crate::error::Result;
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
    let table: [(bool, ProcessName, Role); 8] = [
        (s.recorder, ProcessName::Recorder, Role::Restartable),
        (s.identifier, ProcessName::Identifier, Role::Restartable),
        // Watchers: the run goes on without them.
        (s.live, ProcessName::Live, Role::Optional),
        (s.tunnel, ProcessName::Tunnel, Role::Optional),
        (
            s.plant_sim,
            ProcessName::PlantSim,
            // With run.max_sim_time_s the simulator's normal exit is the end.
            if cfg.run.max_sim_time_s.is_some() {
                Role::EndsRun
            } else {
                Role::Critical
            },
        ),
        (
            s.sensor_driver,
            ProcessName::SensorDriver,
            // Without a controller the driver ends the run.
            if s.controller {
                Role::Critical
            } else {
                Role::EndsRun
            },
        ),
        (s.controller, ProcessName::Controller, Role::EndsRun),
        // A recording played back: the run ends with it.
        (s.player, ProcessName::Player, Role::EndsRun),
    ];
    for (enabled, process, role) in table {
        if enabled {
            let mut args = config_args(config);
            if let (Some(r), ProcessName::Recorder) = (recording, process) {
                args.push("--output".into());
                args.push(r.display().to_string());
            }
            let probe = match process {
                ProcessName::Recorder => Some(ReadyProbe::SubscribesBusMotor),
                ProcessName::Identifier => Some(ReadyProbe::PublishesEstimate),
                _ => None,
            };
            out.push(ServiceSpec {
                name: process.name(),
                program: sibling_program(process.binary())?,
                args,
                role,
                ready: probe.map(|probe| Ready {
                    instance: cfg.run.instance.clone(),
                    probe,
                }),
                holds_clock: (process == ProcessName::PlantSim
                    && cfg.run.timing == TimingMode::Lockstep)
                    .then(|| {
                        // Half the loop's lockstep time-out: the driver and
                        // the controller wait that long for the plant.
                        Duration::from_secs_f64(cfg.safety.lockstep_timeout_ms * 0.5e-3)
                    }),
            });
        }
    }
    Ok(out)
}
