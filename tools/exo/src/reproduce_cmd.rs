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

//! The simulation is [`exo_experiments::simulate`], the comparison
//! [`exo_analysis::reproduce`], the tables [`exo_report::reproduction`].

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_analysis::reproduce::{compare, Criteria};
use exo_config::{RunConfig, Subject};
use exo_experiments::offline::{fit, FitOptions};
use exo_experiments::simulate::{default_workers, simulate_each, Job};
use exo_report::reproduction::tables;

use crate::fit_cmd::note;
use crate::tune_cmd::subject_path;

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

/// Runs `exo reproduce`.
pub fn run(a: &ReproduceArgs) -> Result<()> {
    if a.subjects.is_empty() {
        bail!("--subjects: give at least one subject");
    }
    let base = RunConfig::from_file(&a.config)?;
    let dir = a.output.clone().unwrap_or(base.run.output_dir.clone());
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut subjects = Vec::new();
    let mut jobs = Vec::new();
    for s in &a.subjects {
        let file = subject_path(s);
        let subject = Subject::from_file(&file)?;
        for n in &base.protocol.experiments {
            if subject.get(*n).is_none() {
                bail!("{}: no impedance for experiment {n}", file.display());
            }
        }
        jobs.push(Job {
            subject: file,
            name: subject.name.clone(),
            plant: None,
            rig_gravity_m_s2: None,
        });
        subjects.push(subject);
    }
    let recordings = if a.fit_only {
        let mut recordings = Vec::new();
        for job in &jobs {
            let r = dir.join(format!("{}.mcap", job.name));
            if !r.is_file() {
                bail!(
                    "--fit-only: {} does not exist (run without --fit-only first)",
                    r.display()
                );
            }
            recordings.push(r);
        }
        recordings
    } else {
        // The subjects are independent: one simulation per core.
        let announce = |i: usize| {
            eprintln!(
                "exo reproduce: subject {} ({}/{})",
                jobs[i].name,
                i + 1,
                jobs.len()
            );
        };
        simulate_each(&base, &jobs, &dir, default_workers(), &announce)
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?
    };
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
