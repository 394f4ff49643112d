//! The paper's tuning experiment (`exo tune SUBJECT`) (section "Loop Shaping
//! Experiments"), automated on the simulated subject: each trial steps the
//! run's nodes in one process (`exo-sim`), which records what the five
//! processes would (tests/tests/it/determinism.rs).
//!
//! For the subject's low stiffness (Table I experiment 1: 10 kg grip, 0 Nm
//! bias) and high stiffness (experiment 7: 27 kg, 8 Nm), the fractional
//! order f is raised in steps of `--step` from 0 until a spring-release test
//! ([`exo_analysis::stability`]) oscillates, then the boundary is bisected to
//! `--resolution`. The marginal f is the lower of the two boundaries; the
//! tuned f subtracts 0.12 from it (the paper's margin of about 10.8°). Beside
//! it the tool prints the model's prediction: the same boundary computed from
//! the subject's K and H with the science core's loop analysis
//! ([`exo_impedance::loop_shaping::marginal_fractional_order`]).
//!
//! Assumptions: the simulated hysteresis runs in its causal Prony mode (the
//! equivalent-viscous mode is only exact for a running sine, not for a
//! transient); a release test lasts 1 s bias ramp-in + `--hold-s` +
//! `--observe-s` + 1 s ramp-out of simulated time, in lockstep.

use std::path::PathBuf;

use exo_config::{ProtocolMode, ReleaseSettings, RunConfig, TimingMode};
use exo_impedance::loop_shaping::marginal_fractional_order;
use exo_impedance::{AmplificationPlant, SeaModel};
use exo_messages::{ControlMode, ProtocolPhase};
use exo_plant_model::HysteresisMode;
use exo_plant_model::PlantModel;
use exo_sim::Record;
use serde::Serialize;

use exo_analysis::stability::{Detector, StabilityReport, Verdict};

use crate::error::{Error, Result};

/// [`Error::File`]'s "writing `path`".
fn writing(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Error + '_ {
    move |source| Error::File {
        action: "writing",
        path: path.to_path_buf(),
        source,
    }
}

/// The paper's margin below the marginal order (section "Tuning Results").
pub const PAPER_MARGIN_F: f64 = 0.12;

/// What to tune: `exo tune`'s options (checked by the caller).
#[derive(Debug, Clone)]
pub struct TuneOptions {
    /// The subject's file (Table III row).
    pub subject_file: PathBuf,
    /// The subject as the user named it, for errors.
    pub subject: String,
    /// Run file the trials derive from (rig, plant model, controller layout, limits).
    pub config: PathBuf,
    /// Experiment of Table I the subject holds for the low stiffness.
    pub low_experiment: u32,
    /// Experiment of Table I the subject holds for the high stiffness.
    pub high_experiment: u32,
    /// Step (dimensionless) by which f is raised.
    pub step: f64,
    /// Width (dimensionless) to which the boundary is bisected.
    pub resolution: f64,
    /// Torque (Nm) of the test springs on the joint before release.
    pub spring_torque_nm: f64,
    /// Time (s) the springs stay attached after the bias has ramped in.
    pub hold_s: f64,
    /// Time (s) observed after the release.
    pub observe_s: f64,
    /// Instead of searching, one release test at each of these f (at both
    /// stiffnesses).
    pub check: Vec<f64>,
    /// Keep each trial's run files in this directory (`None`: a temporary
    /// one, removed).
    pub work_dir: Option<PathBuf>,
}

/// What [`tune`] found.
#[derive(Debug, Clone)]
pub enum Outcome {
    /// The verdicts at the f of [`TuneOptions::check`].
    Checks {
        /// Subject name.
        subject: String,
        /// k_p used.
        kp: f64,
        /// Per stiffness.
        checks: Vec<StiffnessCheck>,
    },
    /// The search's result.
    Tuning(Tuning),
}

/// One release trial.
#[derive(Debug, Clone, Serialize)]
pub struct Trial {
    /// Fractional order tried.
    pub f: f64,
    /// Whether it oscillated.
    pub oscillates: bool,
    /// The detector's evidence, in words.
    pub evidence: String,
}

/// The outcome at one stiffness.
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessTuning {
    /// Experiment of Table I held.
    pub experiment: u32,
    /// The subject's K (Nm/rad) in it.
    pub k_nm_per_rad: f64,
    /// The subject's H (Nm/rad) in it.
    pub h_nm_per_rad: f64,
    /// Largest f found stable.
    pub f_stable: f64,
    /// Smallest f found oscillating.
    pub f_oscillating: f64,
    /// The measured boundary: the bracket's middle.
    pub f_marginal: f64,
    /// The model's boundary at this stiffness.
    pub f_marginal_model: f64,
    /// Every trial, in order.
    pub trials: Vec<Trial>,
}

/// Verdicts of `--check` at one stiffness.
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessCheck {
    /// Experiment of Table I held.
    pub experiment: u32,
    /// The subject's K (Nm/rad) in it.
    pub k_nm_per_rad: f64,
    /// The subject's H (Nm/rad) in it.
    pub h_nm_per_rad: f64,
    /// The model's boundary at this stiffness.
    pub f_marginal_model: f64,
    /// One trial per checked f.
    pub trials: Vec<Trial>,
}

/// The whole tuning.
#[derive(Debug, Clone, Serialize)]
pub struct Tuning {
    /// Subject name.
    pub subject: String,
    /// k_p used.
    pub kp: f64,
    /// Low and high stiffness results.
    pub cases: Vec<StiffnessTuning>,
    /// Lower of the measured boundaries.
    pub f_marginal: f64,
    /// `f_marginal − 0.12`.
    pub f_tuned: f64,
    /// Lower of the model's boundaries.
    pub f_marginal_model: f64,
    /// `f_marginal_model − 0.12`.
    pub f_tuned_model: f64,
}

/// The trial harness: one base configuration, one plant model in Prony mode.
pub struct Bench {
    base: RunConfig,
    plant_file: PathBuf,
    plant: PlantModel,
    dir: PathBuf,
    remove_dir: bool,
    args_release: (f64, f64, f64),
    detector: Detector,
    count: u32,
}

impl Drop for Bench {
    fn drop(&mut self) {
        if self.remove_dir {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

impl Bench {
    fn trial(&mut self, experiment: u32, f: f64) -> Result<StabilityReport> {
        self.count += 1;
        let mut cfg = self.base.clone();
        let instance = format!("tune{}x{}", std::process::id(), self.count);
        cfg.run.instance = instance.clone();
        cfg.run.timing = TimingMode::Lockstep;
        cfg.run.max_sim_time_s = None;
        cfg.services.identifier = false;
        cfg.services.recorder = false;
        cfg.plant_model = self.plant_file.clone();
        cfg.protocol.mode = ProtocolMode::Release;
        cfg.protocol.experiments = vec![experiment];
        cfg.protocol.periods = None;
        let (spring, hold, observe) = self.args_release;
        cfg.release = Some(ReleaseSettings {
            experiment,
            spring_torque_nm: spring,
            hold_s: hold,
            observe_s: observe,
        });
        cfg.controller.f = Some(f);
        cfg.controller.adopt_recommended_f = false;
        let path = self.dir.join(format!("trial{:03}.toml", self.count));
        let text = toml::to_string(&cfg).map_err(|source| Error::RunFile {
            what: "a trial run file",
            source,
        })?;
        std::fs::write(&path, text).map_err(writing(&path))?;
        // Validate as `exo run` would.
        let cfg = RunConfig::from_file(&path)?;
        let (mut samples, mut commands, mut states) = (Vec::new(), Vec::new(), Vec::new());
        exo_sim::Sim::new(&cfg, &self.plant)
            .and_then(|mut sim| {
                sim.run(|r| -> Result<(), exo_sim::SimError> {
                    match r {
                        Record::Sensor(s) => samples.push(s),
                        Record::Command(c) => commands.push(c),
                        Record::Protocol(p) => states.push(p),
                        _ => {}
                    }
                    Ok(())
                })
            })
            .map_err(|source| Error::Trial {
                f,
                experiment,
                source: Box::new(source),
            })?;
        let release_ns = states
            .iter()
            .find(|p| p.protocol_phase() == Some(ProtocolPhase::Analysis))
            .map(|p| p.stamp_ns)
            .ok_or(Error::NoRelease { f, experiment })?;
        let end_ns = states
            .iter()
            .find(|p| p.protocol_phase() == Some(ProtocolPhase::RampOut))
            .map_or(u64::MAX, |p| p.stamp_ns);
        let safe = commands
            .iter()
            .any(|c| c.control_mode().is_some_and(ControlMode::is_safe_state))
            || samples
                .iter()
                .any(|s| s.status & exo_messages::sensor::status::SAFE_STATE != 0);
        let (t, th): (Vec<f64>, Vec<f64>) = samples
            .iter()
            .filter(|s| s.stamp_ns < end_ns)
            .map(|s| (s.stamp_ns as f64 * 1e-9, s.theta_e))
            .unzip();
        Ok(self
            .detector
            .classify(&t, &th, release_ns as f64 * 1e-9, safe)?)
    }

    /// One trial, as reported.
    fn report(&mut self, experiment: u32, f: f64, note: &mut dyn FnMut(String)) -> Result<Trial> {
        let r = self.trial(experiment, f)?;
        note(format!(
            "exo tune: experiment {experiment}, f = {f:.4}: {r}"
        ));
        Ok(Trial {
            f,
            oscillates: r.verdict == Verdict::Oscillates,
            evidence: r.to_string(),
        })
    }

    /// Raises f until the release oscillates, then bisects the boundary.
    fn boundary(
        &mut self,
        experiment: u32,
        step: f64,
        resolution: f64,
        note: &mut dyn FnMut(String),
    ) -> Result<(f64, f64, Vec<Trial>)> {
        let mut trials = Vec::new();
        let mut run = |b: &mut Bench, f: f64| -> Result<bool> {
            let t = b.report(experiment, f, note)?;
            let osc = t.oscillates;
            trials.push(t);
            Ok(osc)
        };
        if run(self, 0.0)? {
            return Err(Error::NoBoundary {
                experiment,
                detail:
                    "the release oscillates already at f = 0 (constant amplification); lower kp"
                        .into(),
            });
        }
        let mut stable = 0.0;
        let mut unstable = None;
        let mut f = step;
        while f < 0.99 {
            if run(self, f)? {
                unstable = Some(f);
                break;
            }
            stable = f;
            f += step;
        }
        let Some(mut unstable) = unstable else {
            return Err(Error::NoBoundary {
                experiment,
                detail: format!("no oscillation up to f = {stable:.2}"),
            });
        };
        while unstable - stable > resolution {
            let mid = 0.5 * (stable + unstable);
            if run(self, mid)? {
                unstable = mid;
            } else {
                stable = mid;
            }
        }
        Ok((stable, unstable, trials))
    }
}

/// Runs the tuning experiment (see the module documentation) and, with
/// [`TuneOptions::check`], the release tests at the given f instead.
/// Progress (each trial's verdict, each stiffness's search) goes to `note`.
pub fn tune(args: &TuneOptions, note: &mut dyn FnMut(String)) -> Result<Outcome> {
    let subject_file = args.subject_file.clone();
    let mut base = RunConfig::from_file(&args.config)?;
    base.subject_file = subject_file.clone();
    let mut plant = PlantModel::from_file(&base.plant_model)?;
    plant.human.hysteretic_damping.mode = HysteresisMode::Prony;
    let (dir, remove_dir) = match &args.work_dir {
        Some(d) => (d.clone(), false),
        None => (
            std::env::temp_dir().join(format!("exo-tune-{}", std::process::id())),
            true,
        ),
    };
    std::fs::create_dir_all(&dir).map_err(|source| Error::File {
        action: "creating",
        path: dir.clone(),
        source,
    })?;
    let plant_file = dir.join("plant.toml");
    std::fs::write(&plant_file, plant.to_toml_string()).map_err(writing(&plant_file))?;
    // Validate the subject and both experiments before any process starts.
    let probe = {
        let mut c = base.clone();
        c.protocol.experiments = vec![args.low_experiment, args.high_experiment];
        let p = dir.join("check.toml");
        std::fs::write(
            &p,
            toml::to_string(&c).map_err(|source| Error::RunFile {
                what: "the check run file",
                source,
            })?,
        )
        .map_err(writing(&p))?;
        RunConfig::from_file(&p).map_err(|source| Error::Subject {
            subject: args.subject.clone(),
            source: Box::new(source),
        })?
    };
    let subject = probe.subject().clone();
    let sea_model = SeaModel::new(
        plant.sea.dynamics.natural_frequency_hz,
        plant.sea.dynamics.damping_ratio,
    )?;
    let mut bench = Bench {
        base,
        plant_file,
        plant,
        dir,
        remove_dir,
        args_release: (args.spring_torque_nm, args.hold_s, args.observe_s),
        detector: Detector::default(),
        count: 0,
    };
    let mut cases = Vec::new();
    let mut checks = Vec::new();
    let mut kp_used = 0.0;
    for experiment in [args.low_experiment, args.high_experiment] {
        let spec = *probe
            .experiment_table()
            .get(experiment)
            .ok_or(Error::NotInTable { experiment })?;
        let e = *subject.get(experiment).ok_or_else(|| Error::NotInSubject {
            subject: subject.name.clone(),
            experiment,
        })?;
        let m_e = probe.exo_inertia_kg_m2(spec.load_kg);
        let layout = probe.controller.layout(m_e, subject.inertia_kg_m2)?;
        let kp = layout.kp;
        kp_used = kp;
        let plant_model = AmplificationPlant::new(
            m_e,
            subject.inertia_kg_m2,
            e.stiffness_nm_per_rad,
            e.hysteretic_damping_nm_per_rad / e.stiffness_nm_per_rad,
            sea_model,
        )?;
        let f_model = marginal_fractional_order(&layout, &[plant_model])?;
        if !args.check.is_empty() {
            let mut trials = Vec::new();
            for &f in &args.check {
                trials.push(bench.report(experiment, f, note)?);
            }
            checks.push(StiffnessCheck {
                experiment,
                k_nm_per_rad: e.stiffness_nm_per_rad,
                h_nm_per_rad: e.hysteretic_damping_nm_per_rad,
                f_marginal_model: f_model,
                trials,
            });
            continue;
        }
        note(format!(
            "exo tune: subject {}, experiment {experiment} (K = {} Nm/rad, H = {} Nm/rad): raising f by {} from 0 (model boundary {f_model:.3})",
            subject.name, e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad, args.step
        ));
        let (stable, unstable, trials) =
            bench.boundary(experiment, args.step, args.resolution, note)?;
        cases.push(StiffnessTuning {
            experiment,
            k_nm_per_rad: e.stiffness_nm_per_rad,
            h_nm_per_rad: e.hysteretic_damping_nm_per_rad,
            f_stable: stable,
            f_oscillating: unstable,
            f_marginal: 0.5 * (stable + unstable),
            f_marginal_model: f_model,
            trials,
        });
    }
    if !args.check.is_empty() {
        return Ok(Outcome::Checks {
            subject: subject.name.clone(),
            kp: kp_used,
            checks,
        });
    }
    let f_marginal = cases
        .iter()
        .map(|c| c.f_marginal)
        .fold(f64::INFINITY, f64::min);
    let f_model = cases
        .iter()
        .map(|c| c.f_marginal_model)
        .fold(f64::INFINITY, f64::min);
    let tuning = Tuning {
        subject: subject.name.clone(),
        kp: kp_used,
        cases,
        f_marginal,
        f_tuned: (f_marginal - PAPER_MARGIN_F).max(0.0),
        f_marginal_model: f_model,
        f_tuned_model: (f_model - PAPER_MARGIN_F).max(0.0),
    };
    Ok(Outcome::Tuning(tuning))
}
