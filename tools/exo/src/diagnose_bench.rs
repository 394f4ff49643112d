//! `exo diagnose-bench`: the mismatch finder proven on concealed effects.
//!
//! Each case is a true plant model (the default plant with one effect, two
//! effects, or only parameter changes and another noise seed) and a nominal
//! model. The case's subject runs through the real processes in lockstep
//! with the true plant (`configs/diagnose-bench.toml`), is recorded, and
//! `exo diagnose` compares the recording with the nominal model. The table
//! is the confusion of the true effects against the named ones, with the
//! fit improvement. Everything is generated from seeds; nothing large is
//! committed.

//!
//! The cases are [`exo_diagnose::bench`]'s, the table
//! [`exo_report::diagnosis::bench_table`]'s.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_config::{RunConfig, Subject};
use exo_diagnose::bench::{cases, Case, Outcome};
use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::{diagnose, Settings};
use exo_experiments::simulate::{default_workers, simulate_each, Job};
use exo_plant_sim::PlantModel;
use exo_recording::read_recording;
use exo_report::diagnosis::bench_table as table;

/// Arguments of `exo diagnose-bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The bench's run file (subject, experiments, timing).
    #[arg(long, default_value_os_t = exo_config::configs_dir().join("diagnose-bench.toml"))]
    pub config: PathBuf,
    /// Cases to run (default: all); see `--list`.
    #[arg(long, value_delimiter = ',')]
    pub cases: Vec<String>,
    /// List the cases and exit.
    #[arg(long)]
    pub list: bool,
    /// Directory for the cases' plant models, recordings and reports.
    #[arg(short = 'o', long = "output", value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Diagnose the recordings already in the output directory.
    #[arg(long)]
    pub diagnose_only: bool,
    /// Added to every case's noise seed (the plant's `integration.seed`), to
    /// repeat the bench on other noise.
    #[arg(long, default_value_t = 0)]
    pub seed_offset: u64,
    /// Scales every effect's size (Coulomb torque, delay, cuff compliance,
    /// gravity error), to find the smallest the diagnosis still names.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
}

fn write_plant(m: &PlantModel, path: &Path, what: &str) -> Result<()> {
    let text = format!("# exo diagnose-bench: {what}\n\n{}", m.to_toml_string());
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Runs the bench.
pub fn run(a: &BenchArgs) -> Result<()> {
    let all = cases();
    if a.list {
        for c in &all {
            println!("{:<13} {}", c.name, c.what);
        }
        return Ok(());
    }
    for n in &a.cases {
        if !all.iter().any(|c| c.name == n) {
            bail!(
                "--cases: no case {n:?} (cases: {})",
                all.iter().map(|c| c.name).collect::<Vec<_>>().join(", ")
            );
        }
    }
    let chosen: Vec<&Case> = all
        .iter()
        .filter(|c| a.cases.is_empty() || a.cases.iter().any(|n| n == c.name))
        .collect();
    if !(a.scale.is_finite() && a.scale > 0.0) {
        bail!("--scale = {}: must be a positive number", a.scale);
    }
    let base = RunConfig::from_file(&a.config)?;
    let subject = Subject::from_file(&base.subject_file)?;
    let default_plant = PlantModel::from_file(&base.plant_model)?;
    let dir = a.output.clone().unwrap_or(base.run.output_dir.clone());
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut outcomes = Vec::new();
    // Each case's true and nominal plant files, then the simulations (one
    // per core), then each diagnosis.
    let mut jobs = Vec::new();
    let mut nominals = Vec::new();
    for c in &chosen {
        let mut truth = default_plant;
        (c.truth)(&mut truth, &subject, a.scale);
        truth.integration.seed = truth.integration.seed.wrapping_add(a.seed_offset);
        let mut nominal = default_plant;
        (c.nominal)(&mut nominal, &subject);
        let truth_file = dir.join(format!("{}-truth.toml", c.name));
        let nominal_file = dir.join(format!("{}-nominal.toml", c.name));
        write_plant(&truth, &truth_file, c.what)?;
        write_plant(&nominal, &nominal_file, "the nominal model")?;
        jobs.push(Job {
            subject: base.subject_file.clone(),
            name: c.name.to_string(),
            plant: Some(truth_file),
            // A true plant without gravity is a horizontal rig: its
            // controller compensates none.
            rig_gravity_m_s2: (!truth.gravity.enabled).then_some(0.0),
        });
        nominals.push(nominal);
    }
    let recordings: Vec<PathBuf> = if a.diagnose_only {
        let mut out = Vec::new();
        for c in &chosen {
            let r = dir.join(format!("{}.mcap", c.name));
            if !r.is_file() {
                bail!("--diagnose-only: {} does not exist", r.display());
            }
            out.push(r);
        }
        out
    } else {
        let announce = |i: usize| {
            eprintln!(
                "exo diagnose-bench: case {} ({}/{}): {}",
                chosen[i].name,
                i + 1,
                chosen.len(),
                chosen[i].what
            );
        };
        simulate_each(&base, &jobs, &dir, default_workers(), &announce)
            .into_iter()
            .collect::<Result<Vec<_>>>()?
    };
    for ((c, nominal), recording) in chosen.iter().zip(&nominals).zip(&recordings) {
        let rec = read_recording(recording)
            .with_context(|| format!("reading {}", recording.display()))?;
        let d = reduce(&[rec], &Reduction::default());
        let r = diagnose(&d, nominal, &Settings::default())
            .with_context(|| format!("diagnosing case {}", c.name))?;
        exo_report::diagnosis::write_outputs(
            &dir.join(format!("{}-diagnosis", c.name)),
            nominal,
            &d,
            &r,
        )?;
        outcomes.push(Outcome::new(c, &r));
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&outcomes)?);
    } else {
        print!("{}", table(&outcomes));
    }
    let wrong: Vec<&str> = outcomes
        .iter()
        .filter(|o| !o.correct)
        .map(|o| o.case.as_str())
        .collect();
    if !wrong.is_empty() {
        bail!("the diagnosis missed in: {}", wrong.join(", "));
    }
    Ok(())
}
