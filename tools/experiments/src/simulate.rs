//! One subject of a study run through a base run configuration in one
//! process ([`exo_sim`], in lockstep: the same recording the five processes
//! would write), bounded in simulated time and stopped at a latched safe
//! state: `exo reproduce`'s subjects and `exo diagnose-bench`'s cases.

use std::path::{Path, PathBuf};

use exo_config::RunConfig;
use exo_messages::{status, ControlMode};
use exo_recording::RecordingError;

use crate::error::{Error, Result};

fn absolute(p: &Path) -> Result<PathBuf> {
    std::path::absolute(p).map_err(|source| Error::File {
        action: "resolving",
        path: p.to_path_buf(),
        source,
    })
}

/// Why a simulation's sink stopped it.
enum Stop {
    /// The recording could not be written.
    Write(RecordingError),
    /// A safe state latched.
    Latched(Latched),
}

/// Simulates one subject through the base configuration (with another
/// plant model if `plant` is given); returns the recording.
pub fn simulate(base: &RunConfig, job: &Job, dir: &Path) -> Result<PathBuf> {
    let name = job.name.as_str();
    let mut cfg = base.clone();
    cfg.subject_file = absolute(&job.subject)?;
    cfg.plant_model = absolute(job.plant.as_deref().unwrap_or(&cfg.plant_model))?;
    if let Some(g) = job.rig_gravity_m_s2 {
        cfg.rig.gravity_m_s2 = g;
    }
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
    let text = toml::to_string(&cfg).map_err(|source| Error::RunFile {
        what: "the subject's run file",
        source,
    })?;
    std::fs::write(&run_file, text).map_err(|source| Error::File {
        action: "writing",
        path: run_file.clone(),
        source,
    })?;
    // Validate as `exo run` would.
    let cfg = RunConfig::from_file(&run_file)?;
    let model = exo_plant_model::PlantModel::from_file(&cfg.plant_model)?;
    let recording = dir.join(format!("{name}.mcap"));
    let simulation = |source: exo_sim::SimError| Error::Simulation {
        subject: name.to_string(),
        run_file: run_file.clone(),
        source: Box::new(source),
    };
    let mut sim = exo_sim::Sim::new(&cfg, &model).map_err(simulation)?;
    let mut file = exo_sim::FileSink::create(&recording, &cfg, &run_file)?;
    // The sink stops the run at the first safe state.
    let ended = sim.run(|r| {
        file.write(r).map_err(Stop::Write)?;
        match Latched::of(&r) {
            Some(what) => Err(Stop::Latched(what)),
            None => Ok(()),
        }
    });
    file.finish().map_err(|source| Error::Finish {
        recording: recording.clone(),
        source: Box::new(source),
    })?;
    match ended {
        Err(Stop::Latched(what)) => Err(Error::SafeState {
            subject: name.to_string(),
            latched: what.to_string(),
            at: locate(&cfg, what.sim_s),
            recording,
        }),
        Err(Stop::Write(e)) => Err(simulation(exo_sim::SimError::Recording(e))),
        Ok(exo_sim::Ended::ControllerFinished) => Ok(recording),
        Ok(exo_sim::Ended::Bound) => Err(Error::Bound {
            subject: name.to_string(),
            bound_s,
            run_file,
        }),
    }
}

/// One run of [`simulate_each`]: the subject file, its name, another plant
/// model if any.
#[derive(Debug, Clone)]
pub struct Job {
    /// The subject file.
    pub subject: PathBuf,
    /// The name of the run (and of its recording, `NAME.mcap`).
    pub name: String,
    /// Another plant model than the base configuration's.
    pub plant: Option<PathBuf>,
    /// Another `rig.gravity_m_s2` than the base configuration's (0: a
    /// horizontal rig, whose controller compensates no gravity).
    pub rig_gravity_m_s2: Option<f64>,
}

/// [`simulate`] for each job, `workers` at a time (each on its own
/// thread, one core each); `on_start` is told each job's index as it
/// starts. The results are in the jobs' order.
pub fn simulate_each(
    base: &RunConfig,
    jobs: &[Job],
    dir: &Path,
    workers: usize,
    on_start: &(dyn Fn(usize) + Sync),
) -> Vec<Result<PathBuf>> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<std::sync::Mutex<Option<Result<PathBuf>>>> =
        jobs.iter().map(|_| std::sync::Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..workers.clamp(1, jobs.len().max(1)) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(job) = jobs.get(i) else { break };
                on_start(i);
                let r = simulate(base, job, dir);
                *results[i]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(r);
            });
        }
    });
    results
        .into_iter()
        .map(|m| {
            m.into_inner()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .unwrap_or(Err(Error::NotRun))
        })
        .collect()
}

/// The number of simulations to run at once: one per available core.
pub fn default_workers() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
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

    #[test]
    fn jobs_run_side_by_side_and_come_back_in_order() {
        // Two short runs (one experiment, one period) and a subject file
        // that does not exist: each result in its job's place.
        let mut cfg =
            RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        cfg.protocol.experiments = vec![1];
        cfg.protocol.periods = Some(vec![1]);
        cfg.services.identifier = false;
        let dir = std::env::temp_dir().join(format!("exo-simulate-each-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let subjects = exo_config::configs_dir().join("subjects");
        let job = |s: &str, name: &str| Job {
            subject: subjects.join(s),
            name: name.into(),
            plant: None,
            rig_gravity_m_s2: None,
        };
        let jobs = [
            job("B.toml", "b"),
            job("missing.toml", "m"),
            job("C.toml", "c"),
        ];
        let started = std::sync::Mutex::new(Vec::new());
        let results = simulate_each(&cfg, &jobs, &dir, 2, &|i| {
            started.lock().unwrap().push(i);
        });
        assert_eq!(results.len(), 3);
        assert_eq!(results[0].as_ref().unwrap(), &dir.join("b.mcap"));
        assert!(format!("{:#}", results[1].as_ref().unwrap_err()).contains("missing.toml"));
        assert_eq!(results[2].as_ref().unwrap(), &dir.join("c.mcap"));
        let mut started = started.into_inner().unwrap();
        started.sort_unstable();
        assert_eq!(started, [0, 1, 2]);
        let b = exo_recording::read_recording(&dir.join("b.mcap")).unwrap();
        assert_eq!(b.meta("subject"), Some("B"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
