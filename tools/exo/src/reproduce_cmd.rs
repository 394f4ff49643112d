//! `exo reproduce`: the paper's modelling study, simulated. Every subject of
//! Table III goes through the nine experiments of Table I in the real
//! processes (plant simulator, sensor driver, controller, recorder, in
//! lockstep); the recordings are fitted as `exo fit` fits them, and what the
//! fit recovers is compared with what was simulated:
//!
//! - M2's `K_h` and `H_h` per subject and experiment within 5 % of the inputs;
//! - the power law of the recovered (K, H) within 0.05 (β0 and β1) of the
//!   power law of the inputs, and that one within 0.08 and 0.06 of the row
//!   Table III prints (which is rounded to two decimals);
//! - `F_{M1−M3}` above its critical value for every subject (hysteretic
//!   damping needed);
//! - the phase-shift table within 3° of the phase of `S_h` the inputs imply
//!   at the same frequencies, `arg(K − M_h ω² + jH)`.
//!
//! The criteria are the issue's; the comparison is computed, never copied.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_config::{ReportedPowerLaw, RunConfig, Subject};
use exo_impedance::{fit_power_law, Complex64};
use exo_messages::{status, ControlMode};
use serde::Serialize;

use exo_identifier::offline::{fit, FitOptions};

use crate::fit_cmd::note;
use crate::tune_cmd::subject_path;
use exo_analysis::study::{group_of, FRow, FitReport};

/// Arguments of `exo reproduce`.
#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// Base run configuration; its subject is replaced by each subject in turn.
    #[arg(long, default_value_os_t = exo_config::configs_dir().join("reproduce.toml"))]
    pub config: PathBuf,
    /// Subjects: names of configs/subjects/*.toml (A–J) or subject files, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "A,B,C,D,E,F,G,H,I,J")]
    pub subjects: Vec<String>,
    /// Directory for the run files and recordings (default: the configuration's run.output_dir).
    #[arg(short = 'o', long, value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// Do not simulate: fit the recordings `DIR/<subject>.mcap` an earlier run left.
    #[arg(long)]
    pub fit_only: bool,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
}

/// The acceptance criteria of the reproduction.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Criteria {
    /// Largest relative error of M2's K_h and H_h.
    pub kh_rel: f64,
    /// Largest |Δβ0| and |Δβ1| between the recovered and the inputs' power law.
    pub beta_abs: f64,
    /// Largest |Δβ0| between the inputs' power law and the printed row.
    pub beta0_vs_reported: f64,
    /// Largest |Δβ1| between the inputs' power law and the printed row.
    pub beta1_vs_reported: f64,
    /// Largest phase-table difference (degrees).
    pub phase_deg: f64,
}

impl Default for Criteria {
    fn default() -> Self {
        Criteria {
            kh_rel: 0.05,
            beta_abs: 0.05,
            beta0_vs_reported: 0.08,
            beta1_vs_reported: 0.06,
            phase_deg: 3.0,
        }
    }
}

/// One subject-experiment: inputs against M2's fit.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentComparison {
    /// Experiment number.
    pub experiment: u32,
    /// Simulated K_h (Nm/rad).
    pub k_input: f64,
    /// Recovered K_h (Nm/rad).
    pub k_fit: f64,
    /// `(fit − input)/input`.
    pub k_rel_error: f64,
    /// Simulated H_h (Nm/rad).
    pub h_input: f64,
    /// Recovered H_h (Nm/rad).
    pub h_fit: f64,
    /// `(fit − input)/input`.
    pub h_rel_error: f64,
}

/// A power law `log10 H = β0 + β1 log10 K`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Law {
    /// Intercept.
    pub beta0: f64,
    /// Slope.
    pub beta1: f64,
    /// R² on the log scale.
    pub r2: f64,
}

/// One cell of the phase-shift table against the inputs' phase.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseComparison {
    /// Experiment group (`1-3`, `4-6`, `7-9`).
    pub experiments: String,
    /// Fitted mean phase of `S_h` (degrees).
    pub fitted_deg: f64,
    /// Its standard error (degrees).
    pub se_deg: f64,
    /// Mean of `arg(K − M_h ω² + jH)` over the same points (degrees).
    pub implied_deg: f64,
    /// `fitted − implied` (degrees).
    pub diff_deg: f64,
}

/// One subject's comparison.
#[derive(Debug, Clone, Serialize)]
pub struct SubjectComparison {
    /// Subject name.
    pub subject: String,
    /// Per experiment.
    pub experiments: Vec<ExperimentComparison>,
    /// Power law of the simulated (K, H).
    pub law_input: Law,
    /// Power law of the recovered (K, H).
    pub law_fit: Option<Law>,
    /// The row the publication printed, when the subject file has it.
    pub law_reported: Option<ReportedPowerLaw>,
    /// `F_{M1−M3}` over the subject's experiments (F^sub).
    pub f_m1_m3: Option<FRow>,
    /// The phase-shift table's row against the inputs.
    pub phase: Vec<PhaseComparison>,
}

/// The whole comparison.
#[derive(Debug, Clone, Serialize)]
pub struct Reproduction {
    /// Criteria applied.
    pub criteria: Criteria,
    /// Per subject.
    pub subjects: Vec<SubjectComparison>,
    /// Every criterion missed, in words (empty: all met).
    pub failures: Vec<String>,
    /// What the fitter could not use.
    pub warnings: Vec<String>,
    /// The recordings fitted.
    pub recordings: Vec<PathBuf>,
}

impl Reproduction {
    /// All criteria met.
    pub fn pass(&self) -> bool {
        self.failures.is_empty()
    }
}

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

/// `|x| ≤ limit`; false for NaN, so a missing number misses the criterion.
fn within(x: f64, limit: f64) -> bool {
    x.abs() <= limit
}

fn law(fit: exo_impedance::PowerLawFit) -> Law {
    Law {
        beta0: fit.law.beta0,
        beta1: fit.law.beta1,
        r2: fit.r2,
    }
}

/// Compares what the fit recovered with the simulated subjects, which went
/// through `experiments` (each must have been fitted).
pub fn compare(
    subjects: &[Subject],
    experiments: &[u32],
    report: &FitReport,
    c: Criteria,
) -> Result<Reproduction> {
    let mut out = Vec::new();
    let mut failures = Vec::new();
    for subject in subjects {
        let name = &subject.name;
        let Some(fitted) = report.subjects.iter().find(|s| &s.subject == name) else {
            failures.push(format!("subject {name}: no fitted data"));
            continue;
        };
        for n in experiments {
            if !fitted.experiments.iter().any(|e| e.experiment == *n) {
                failures.push(format!(
                    "subject {name} experiment {n}: simulated but not fitted (no usable data)"
                ));
            }
        }
        let mut experiments = Vec::new();
        let (mut k_in, mut h_in) = (Vec::new(), Vec::new());
        // Phase of S_h the inputs imply, over the same points the table keeps.
        let mut implied: BTreeMap<u32, Vec<f64>> = BTreeMap::new();
        for e in &fitted.experiments {
            let Some(input) = subject.get(e.experiment) else {
                failures.push(format!(
                    "subject {name} experiment {}: not in the subject file",
                    e.experiment
                ));
                continue;
            };
            let (k, h) = (
                input.stiffness_nm_per_rad,
                input.hysteretic_damping_nm_per_rad,
            );
            k_in.push(k);
            h_in.push(h);
            let keep = e.points.len().saturating_sub(3);
            implied
                .entry(group_of(e.experiment))
                .or_default()
                .extend(e.points[..keep].iter().map(|p| {
                    Complex64::new(k - subject.inertia_kg_m2 * p.omega * p.omega, h)
                        .arg()
                        .to_degrees()
                }));
            let Some(m2) = e.models.get("M2") else {
                failures.push(format!(
                    "subject {name} experiment {}: M2 not fitted",
                    e.experiment
                ));
                continue;
            };
            let row = ExperimentComparison {
                experiment: e.experiment,
                k_input: k,
                k_fit: m2.k,
                k_rel_error: (m2.k - k) / k,
                h_input: h,
                h_fit: m2.h,
                h_rel_error: (m2.h - h) / h,
            };
            for (what, err) in [("K_h", row.k_rel_error), ("H_h", row.h_rel_error)] {
                if !within(err, c.kh_rel) {
                    failures.push(format!(
                        "subject {name} experiment {}: {what} off by {:+.1} % (limit {:.0} %)",
                        e.experiment,
                        100.0 * err,
                        100.0 * c.kh_rel
                    ));
                }
            }
            experiments.push(row);
        }
        let law_input = law(fit_power_law(&k_in, &h_in)
            .with_context(|| format!("subject {name}: power law of the inputs"))?);
        let law_fit = match (fitted.beta0, fitted.beta1, fitted.r2) {
            (Some(beta0), Some(beta1), Some(r2)) => Some(Law { beta0, beta1, r2 }),
            _ => None,
        };
        match law_fit {
            Some(f) => {
                for (what, d) in [
                    ("β0", f.beta0 - law_input.beta0),
                    ("β1", f.beta1 - law_input.beta1),
                ] {
                    if !within(d, c.beta_abs) {
                        failures.push(format!(
                            "subject {name}: recovered {what} off the inputs' by {d:+.3} (limit {})",
                            c.beta_abs
                        ));
                    }
                }
            }
            None => failures.push(format!("subject {name}: no power law fitted")),
        }
        if let Some(r) = &subject.reported_power_law {
            for (what, d, limit) in [
                ("β0", law_input.beta0 - r.beta0, c.beta0_vs_reported),
                ("β1", law_input.beta1 - r.beta1, c.beta1_vs_reported),
            ] {
                if !within(d, limit) {
                    failures.push(format!(
                        "subject {name}: the inputs' {what} is {d:+.3} off the printed row (limit {limit})"
                    ));
                }
            }
        }
        let f_m1_m3 = report
            .f_tests
            .per_subject
            .iter()
            .find(|p| &p.group == name)
            .map(|p| p.m1_m3);
        match f_m1_m3 {
            Some(f) if f.statistic > f.critical => {}
            Some(f) => failures.push(format!(
                "subject {name}: F_M1−M3 = {:.2} not above its critical {:.2}",
                f.statistic, f.critical
            )),
            None => failures.push(format!("subject {name}: no F^sub test")),
        }
        let mut phase = Vec::new();
        if let Some(row) = report.phase_table.iter().find(|r| &r.subject == name) {
            for cell in &row.groups {
                let Some(v) = implied.get(&cell.group).filter(|v| !v.is_empty()) else {
                    continue;
                };
                let implied_deg = v.iter().sum::<f64>() / v.len() as f64;
                let diff = cell.mean_deg - implied_deg;
                if !within(diff, c.phase_deg) {
                    failures.push(format!(
                        "subject {name} experiments {}: phase {:.1}° against the inputs' {:.1}° (limit {}°)",
                        cell.experiments, cell.mean_deg, implied_deg, c.phase_deg
                    ));
                }
                phase.push(PhaseComparison {
                    experiments: cell.experiments.clone(),
                    fitted_deg: cell.mean_deg,
                    se_deg: cell.se_deg,
                    implied_deg,
                    diff_deg: diff,
                });
            }
        }
        out.push(SubjectComparison {
            subject: name.clone(),
            experiments,
            law_input,
            law_fit,
            law_reported: subject.reported_power_law.clone(),
            f_m1_m3,
            phase,
        });
    }
    Ok(Reproduction {
        criteria: c,
        subjects: out,
        failures,
        warnings: report.warnings.clone(),
        recordings: Vec::new(),
    })
}

/// The comparison as Markdown tables (readable in a terminal, pasted in the README).
pub fn tables(r: &Reproduction) -> String {
    let mut s = String::new();
    let c = r.criteria;
    let _ = writeln!(
        s,
        "M2 parameters recovered against the simulated inputs (worst of 9 experiments; limit {:.0} %)\n",
        100.0 * c.kh_rel
    );
    let _ = writeln!(
        s,
        "| subject | worst K_h error | worst H_h error | β0 fit / inputs / Table III | β1 fit / inputs / Table III | F_M1−M3 (critical) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for sub in &r.subjects {
        let worst = |f: fn(&ExperimentComparison) -> f64| {
            sub.experiments
                .iter()
                .map(f)
                .fold(0.0_f64, |a, e| if e.abs() > a.abs() { e } else { a })
        };
        let (fb0, fb1) = sub.law_fit.map_or(("–".into(), "–".into()), |l| {
            (format!("{:.3}", l.beta0), format!("{:.3}", l.beta1))
        });
        let (rb0, rb1) = sub
            .law_reported
            .as_ref()
            .map_or(("–".into(), "–".into()), |l| {
                (format!("{:.2}", l.beta0), format!("{:.2}", l.beta1))
            });
        let f = sub.f_m1_m3.map_or("–".into(), |f| {
            format!("{:.1} ({:.2})", f.statistic, f.critical)
        });
        let _ = writeln!(
            s,
            "| {} | {:+.2} % | {:+.2} % | {fb0} / {:.3} / {rb0} | {fb1} / {:.3} / {rb1} | {f} |",
            sub.subject,
            100.0 * worst(|e| e.k_rel_error),
            100.0 * worst(|e| e.h_rel_error),
            sub.law_input.beta0,
            sub.law_input.beta1,
        );
    }
    let _ = writeln!(
        s,
        "\nPhase of S_h (degrees), mean ± SE over each group's periods but the last three, against arg(K − M_h ω² + jH) of the inputs (limit {}°)\n",
        c.phase_deg
    );
    let labels: Vec<String> = {
        let mut l: Vec<String> = r
            .subjects
            .iter()
            .flat_map(|s| s.phase.iter().map(|p| p.experiments.clone()))
            .collect();
        l.sort();
        l.dedup();
        l
    };
    let _ = writeln!(
        s,
        "| subject | {} |",
        labels
            .iter()
            .map(|l| format!("exp {l}: fit / inputs"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|---|{}", "---|".repeat(labels.len()));
    for sub in &r.subjects {
        let cells: Vec<String> = labels
            .iter()
            .map(|l| {
                sub.phase
                    .iter()
                    .find(|p| &p.experiments == l)
                    .map_or("–".into(), |p| {
                        format!(
                            "{:.1} ± {:.1} / {:.1}",
                            p.fitted_deg, p.se_deg, p.implied_deg
                        )
                    })
            })
            .collect();
        let _ = writeln!(s, "| {} | {} |", sub.subject, cells.join(" | "));
    }
    if r.pass() {
        let _ = writeln!(s, "\nAll criteria met.");
    } else {
        let _ = writeln!(s, "\nCriteria missed:");
        for f in &r.failures {
            let _ = writeln!(s, "  {f}");
        }
    }
    s
}

/// Runs `exo reproduce`.
pub fn run(a: &ReproduceArgs) -> Result<()> {
    if a.subjects.is_empty() {
        bail!("--subjects: give at least one subject");
    }
    let base = RunConfig::from_file(&a.config)?;
    let dir = a.output.clone().unwrap_or(base.run.output_dir.clone());
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut subjects = Vec::new();
    let mut recordings = Vec::new();
    for (i, s) in a.subjects.iter().enumerate() {
        let file = subject_path(s);
        let subject = Subject::from_file(&file)?;
        let name = subject.name.clone();
        for n in &base.protocol.experiments {
            if subject.get(*n).is_none() {
                bail!("{}: no impedance for experiment {n}", file.display());
            }
        }
        let recording = if a.fit_only {
            let r = dir.join(format!("{name}.mcap"));
            if !r.is_file() {
                bail!(
                    "--fit-only: {} does not exist (run without --fit-only first)",
                    r.display()
                );
            }
            r
        } else {
            eprintln!(
                "exo reproduce: subject {name} ({}/{})",
                i + 1,
                a.subjects.len()
            );
            simulate(&base, &file, None, &name, &dir)?
        };
        recordings.push(recording);
        subjects.push(subject);
    }
    let (_, report) = fit(&FitOptions::for_recordings(recordings.clone()), &mut note)?;
    let mut r = compare(
        &subjects,
        &base.protocol.experiments,
        &report,
        Criteria::default(),
    )?;
    r.recordings = recordings;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", tables(&r));
    }
    if !r.pass() {
        bail!(
            "the reproduction missed {} criteria (listed above)",
            r.failures.len()
        );
    }
    Ok(())
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
