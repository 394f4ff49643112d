//! One subject of a study run through a base run configuration in one
//! process ([`exo_sim`], in lockstep: the same recording the five processes
//! would write), bounded in simulated time and stopped at a latched safe
//! state: `exo reproduce`'s subjects and `exo diagnose-bench`'s cases.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use exo_config::RunConfig;
use exo_messages::{status, ControlMode};

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).with_context(|| format!("resolving {}", p.display()))
}

/// Simulates one subject through the base configuration (with another
/// plant model if `plant` is given); returns the recording.
pub fn simulate(
    base: &RunConfig,
    subject: &Path,
    plant: Option<&Path>,
    name: &str,
    dir: &Path,
) -> Result<PathBuf> {
    let mut cfg = base.clone();
    cfg.subject_file = absolute(subject)?;
    cfg.plant_model = absolute(plant.unwrap_or(&cfg.plant_model))?;
    cfg.protocol.experiments_file = absolute(&cfg.protocol.experiments_file)?;
    cfg.run.output_dir = absolute(dir)?;
    cfg.run.instance = format!("{}-{name}-{}", cfg.run.instance, std::process::id());
    cfg.services.recorder = true;
    // The run's bound: the plant simulator stops at the protocol's simulated
    // duration plus a margin, so a run whose controller never finishes (a
    // latched safe state keeps it answering forever) cannot hang.
    let bound_s = protocol_duration_s(base) + BOUND_MARGIN_S;
    cfg.run.max_sim_time_s = Some(bound_s);
    let run_file = dir.join(format!("{name}.toml"));
    let text = toml::to_string(&cfg).context("writing the subject's run file")?;
    std::fs::write(&run_file, text).with_context(|| format!("writing {}", run_file.display()))?;
    // Validate as `exo run` would.
    let cfg = RunConfig::from_file(&run_file)?;
    let model = exo_plant_sim::PlantModel::from_file(&cfg.plant_model)?;
    let recording = dir.join(format!("{name}.mcap"));
    let mut sim = exo_sim::Sim::new(&cfg, &model)
        .with_context(|| format!("simulating subject {name} ({})", run_file.display()))?;
    let mut file = exo_sim::FileSink::create(&recording, &cfg, &run_file)?;
    let mut latched = None;
    let ended = sim.run(|r| -> Result<()> {
        file.write(r)?;
        latched = latched.or_else(|| Latched::of(&r));
        match latched {
            Some(_) => bail!("safe state"),
            None => Ok(()),
        }
    });
    file.finish()
        .with_context(|| format!("finishing {}", recording.display()))?;
    if let Some(what) = latched {
        bail!(
            "subject {name}: {what}, {}; the run is stopped (the recording so far is {})",
            locate(&cfg, what.sim_s),
            recording.display()
        );
    }
    match ended.with_context(|| format!("simulating subject {name} ({})", run_file.display()))? {
        exo_sim::Ended::ControllerFinished => Ok(recording),
        exo_sim::Ended::Bound => bail!(
            "subject {name}: the run reached its bound of {bound_s:.1} s simulated before the controller finished the protocol ({})",
            run_file.display()
        ),
    }
}

/// Simulated time (s) a run gets beyond its protocol before it counts as hung.
const BOUND_MARGIN_S: f64 = 10.0;

/// The protocol's simulated duration (s) of a run configuration.
fn protocol_duration_s(cfg: &RunConfig) -> f64 {
    let table = cfg.experiment_table();
    let periods = cfg
        .protocol
        .periods
        .as_ref()
        .map_or(table.periods as usize, Vec::len);
    (cfg.protocol.experiments.len() * periods) as f64 * table.timing.period_s()
}

/// "experiment E period P" of a protocol time (s) of a run configuration.
fn locate(cfg: &RunConfig, t_s: f64) -> String {
    let table = cfg.experiment_table();
    let all: Vec<u32> = (1..=table.periods).collect();
    let periods = cfg.protocol.periods.as_deref().unwrap_or(&all);
    let index = (t_s / table.timing.period_s()).floor().max(0.0) as usize;
    match (
        cfg.protocol.experiments.get(index / periods.len().max(1)),
        periods.get(index % periods.len().max(1)),
    ) {
        (Some(e), Some(p)) => format!("in experiment {e} period {p}"),
        _ => "after the protocol".into(),
    }
}

/// A latched safe state seen on the run's channels.
#[derive(Debug, Clone, Copy)]
struct Latched {
    who: &'static str,
    mode: &'static str,
    sim_s: f64,
}

impl std::fmt::Display for Latched {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the {} latched its safe state ({}) at {:.3} s simulated",
            self.who, self.mode, self.sim_s
        )
    }
}

impl Latched {
    /// The safe state a published message shows: a command in a safe-state
    /// mode (the controller's), or a sample with the driver's `SAFE_STATE`
    /// bit.
    fn of(r: &exo_sim::Record) -> Option<Latched> {
        match r {
            exo_sim::Record::Command(c) => ControlMode::from_u32(c.mode)
                .filter(|m| m.is_safe_state())
                .map(|m| Latched {
                    who: "controller",
                    mode: m.name(),
                    sim_s: c.stamp_ns as f64 * 1e-9,
                }),
            exo_sim::Record::Sensor(s) if s.status & status::SAFE_STATE != 0 => Some(Latched {
                who: "sensor driver",
                mode: "status bit SAFE_STATE",
                sim_s: s.stamp_ns as f64 * 1e-9,
            }),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bound_covers_the_protocol_and_a_time_names_its_period() {
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("reproduce.toml")).unwrap();
        // Nine experiments of ten periods of 5 + 5 + 5 + 1 + 0.5 s.
        let t = cfg.experiment_table().timing;
        assert_eq!(t.period_s(), 16.5);
        assert_eq!(protocol_duration_s(&cfg), 90.0 * 16.5);
        // The 66th period (index 65): experiment 7, period 6.
        assert_eq!(locate(&cfg, 65.0 * 16.5 + 3.0), "in experiment 7 period 6");
        assert_eq!(locate(&cfg, 0.0), "in experiment 1 period 1");
        assert_eq!(locate(&cfg, 90.0 * 16.5 + 1.0), "after the protocol");
    }
}
