//! `exo diagnose --model PLANT.toml RECORDING.mcap …`: where the plant model
//! and the recordings differ, which physics the model left out, the model
//! with it, and the fit before and after (crate `exo-diagnose`; the text
//! and the files written are [`exo_report::diagnosis`]'s).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_diagnose::data::{reduce, Dataset, Reduction};
use exo_diagnose::{diagnose, Diagnosis, Settings, Term};
use exo_plant_model::PlantModel;
use exo_recording::read_recording;

use exo_report::diagnosis::{text, write_outputs};

/// Arguments of `exo diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// The nominal plant model (the simulator's TOML, e.g. configs/plants/default.toml).
    #[arg(long, value_name = "PLANT.toml")]
    pub model: PathBuf,
    /// Contract recordings (docs/recording-format.md), whoever wrote them.
    #[arg(required = true)]
    pub recordings: Vec<PathBuf>,
    /// The nominal human (a subject file, K_h and H_h per experiment); without
    /// it the plant's default stiffness is the nominal for every experiment.
    #[arg(long, value_name = "SUBJECT.toml")]
    pub subject: Option<PathBuf>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Write the report (report.html), the updated plant model
    /// (updated-plant.toml), the fitted human (updated-subject.toml) and
    /// diagnosis.json into this directory.
    #[arg(short = 'o', long = "output", value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// Family-wise false-alarm probability of the tests.
    #[arg(long, default_value_t = 0.05)]
    pub level: f64,
    /// Most terms added.
    #[arg(long, default_value_t = 4)]
    pub max_terms: usize,
    /// Smallest coherence of a point kept (0–1).
    #[arg(long, default_value_t = 0.5)]
    pub min_coherence: f64,
}

/// Parses a subject file into nominal `K_h`, `H_h` per experiment.
fn nominal_subject(path: &Path) -> Result<BTreeMap<u32, (f64, f64)>> {
    let s = exo_config::Subject::from_file(path)
        .with_context(|| format!("--subject {}", path.display()))?;
    Ok(s.experiment
        .iter()
        .map(|e| {
            (
                e.number,
                (e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad),
            )
        })
        .collect())
}

/// Reads the model and the recordings and diagnoses them.
pub fn load_and_diagnose(a: &DiagnoseArgs) -> Result<(PlantModel, Dataset, Diagnosis)> {
    if !(a.min_coherence >= 0.0 && a.min_coherence < 1.0) {
        bail!("--min-coherence = {}: must lie in [0, 1)", a.min_coherence);
    }
    if !(a.level > 0.0 && a.level < 1.0) {
        bail!("--level = {}: must lie in (0, 1)", a.level);
    }
    if a.max_terms == 0 {
        bail!("--max-terms must be at least 1");
    }
    let model = PlantModel::from_file(&a.model).map_err(anyhow::Error::from)?;
    let mut recs = Vec::new();
    for p in &a.recordings {
        recs.push(read_recording(p).with_context(|| format!("reading {}", p.display()))?);
    }
    let d = reduce(
        &recs,
        &Reduction {
            min_coherence: a.min_coherence,
            ..Reduction::default()
        },
    );
    let settings = Settings {
        level: a.level,
        max_terms: a.max_terms,
        nominal_subject: a.subject.as_deref().map(nominal_subject).transpose()?,
        candidates: Term::ALL.to_vec(),
        forms: Term::FORMS.to_vec(),
    };
    let r = diagnose(&d, &model, &settings).map_err(|e| {
        anyhow::anyhow!(
            "{}: {e}",
            a.recordings
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    })?;
    Ok((model, d, r))
}

/// `exo diagnose`.
pub fn run(a: &DiagnoseArgs) -> Result<()> {
    let (model, d, r) = load_and_diagnose(a)?;
    if let Some(dir) = &a.output {
        write_outputs(dir, &model, &d, &r)?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        print!("{}", text(&r));
        if let Some(dir) = &a.output {
            println!(
                "\nwrote {}/report.html, updated-plant.toml, updated-subject.toml, diagnosis.json",
                dir.display()
            );
        }
    }
    Ok(())
}
