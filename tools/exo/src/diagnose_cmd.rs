//! `exo diagnose --model PLANT.toml RECORDING.mcap …`: where the plant model
//! and the recordings differ, which physics the model left out, the model
//! with it, and the fit before and after (crate `exo-diagnose`).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_diagnose::data::{reduce, Dataset, Reduction};
use exo_diagnose::engine::Score;
use exo_diagnose::{diagnose, Diagnosis, Settings, Term};
use exo_plant_sim::PlantModel;
use exo_recording::read_recording;

use exo_report::diagnosis as diagnose_report;

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

fn score_rows(w: &mut String, label: &str, s: &Score) {
    for t in &s.per_tf {
        let _ = writeln!(
            w,
            "  {label:<22} {:<15} {:>6} {:>14.1} {:>9.4} {:>14.1}",
            t.tf.name(),
            t.points,
            t.rss,
            t.r2,
            t.heldout_rss
        );
    }
}

/// The human-readable report.
pub fn text(r: &Diagnosis) -> String {
    let mut w = String::new();
    let _ = writeln!(w, "exo diagnose: {}", r.sources.join(", "));
    let _ = writeln!(
        w,
        "transfer functions compared: {}",
        r.supported
            .iter()
            .map(|t| format!("{} = {}", t.name(), t.signals()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if !r.notes.is_empty() {
        let _ = writeln!(w, "\nnot used ({}):", r.notes.len());
        for n in r.notes.iter().take(12) {
            let _ = writeln!(w, "  - {n}");
        }
        if r.notes.len() > 12 {
            let _ = writeln!(w, "  … and {} more (see --json)", r.notes.len() - 12);
        }
    }
    let _ = writeln!(w, "\n1. Where the model and the data differ");
    for l in &r.location.summary {
        let _ = writeln!(w, "  - {l}");
    }
    for s in &r.location.scaling {
        let _ = writeln!(
            w,
            "  - {} residual after the refit: correlation of its quadrature part with 1/amplitude {:+.2}, of its in-phase part with K_h {:+.2}, of its phase with ω {:+.2} ({} points)",
            s.tf.name(),
            s.with_inverse_amplitude,
            s.with_stiffness,
            s.phase_with_omega,
            s.windows
        );
    }
    let harm: Vec<String> = r
        .location
        .time
        .iter()
        .filter(|t| t.harmonics[1] > 3.0 * t.floor && t.harmonics[1] > 0.01)
        .map(|t| {
            format!(
                "{} in experiment {} (3rd harmonic {:.1} % of the fundamental, floor {:.1} %)",
                t.channel,
                t.experiment,
                100.0 * t.harmonics[1],
                100.0 * t.floor
            )
        })
        .collect();
    if harm.is_empty() {
        let _ = writeln!(
            w,
            "  - time domain: no harmonic of the excitation above the noise floor"
        );
    } else {
        let _ = writeln!(
            w,
            "  - time domain: harmonics of the excitation above the noise: {}",
            harm.join("; ")
        );
    }
    let _ = writeln!(w, "\n2. Parameters of the nominal model, refitted");
    let _ = writeln!(
        w,
        "  {:<36} {:>12} {:>12} {:>10} {:>9}",
        "parameter", "nominal", "fitted", "s.e.", "change"
    );
    for c in &r.parameter_changes {
        let _ = writeln!(
            w,
            "  {:<36} {:>12.4} {:>12.4} {:>10.4} {:>8.1}%",
            c.label, c.nominal, c.fitted, c.std_error, c.change_pct
        );
    }
    let _ = writeln!(w, "\n3. Candidate physics, one term at a time");
    if r.steps.is_empty() {
        let _ = writeln!(
            w,
            "  not searched: after the refit the model is within the measured noise (χ²/dof {:.2}, lack-of-fit p = {:.2})",
            r.refit.chi2_per_dof, r.refit.lack_of_fit_p
        );
    }
    for st in &r.steps {
        let _ = writeln!(
            w,
            "  step {}: {:<44} {:>4} {:>10} {:>8} {:>10} {:>8} {:>9}",
            st.step, "candidate", "+p", "F", "F_crit", "p (Holm)", "ΔAIC", "held-out"
        );
        for c in &st.candidates {
            let _ = writeln!(
                w,
                "  {} {:<50} {:>4} {:>10.2} {:>8.2} {:>10.2e} {:>8.1} {:>8.1}%  {}",
                if c.chosen { "→" } else { " " },
                c.words,
                c.added_parameters,
                c.f,
                c.f_critical,
                c.p_holm,
                c.delta_aic,
                100.0 * c.heldout_change,
                if c.identified {
                    c.description.clone()
                } else {
                    format!("{} (not determined)", c.description)
                }
            );
        }
    }
    let _ = writeln!(w, "\n4. Fit before and after");
    let _ = writeln!(
        w,
        "  {:<22} {:<15} {:>6} {:>14} {:>9} {:>14}",
        "model", "transfer fn", "points", "RSS (χ²)", "R²", "held-out RSS"
    );
    score_rows(&mut w, "nominal as given", &r.nominal);
    score_rows(&mut w, "nominal refitted", &r.refit);
    score_rows(&mut w, "with terms found", &r.final_score);
    let _ = writeln!(w, "\nVerdict");
    for v in &r.verdict {
        let _ = writeln!(w, "  {v}");
    }
    w
}

/// Writes the report, the updated model, the fitted subject and the JSON.
pub fn write_outputs(dir: &Path, nominal: &PlantModel, d: &Dataset, r: &Diagnosis) -> Result<()> {
    exo_recording::files::create_output_dir(dir)
        .with_context(|| format!("creating {}", dir.display()))?;
    let updated = r.updated_plant(nominal);
    let mut plant = format!(
        "# Updated by exo diagnose from {}.\n# Terms added: {}.\n\n",
        r.sources.join(", "),
        if r.found.is_empty() {
            "none".to_string()
        } else {
            r.found
                .iter()
                .map(|f| format!("{} ({}: {})", f.words, f.toml_key, f.description))
                .collect::<Vec<_>>()
                .join("; ")
        }
    );
    plant.push_str(&updated.to_toml_string());
    let p = dir.join("updated-plant.toml");
    exo_recording::files::write_output_file(&p, plant)
        .with_context(|| format!("writing {}", p.display()))?;
    let p = dir.join("updated-subject.toml");
    exo_recording::files::write_output_file(&p, r.final_physics.subject_toml("diagnosed"))
        .with_context(|| format!("writing {}", p.display()))?;
    let p = dir.join("diagnosis.json");
    exo_recording::files::write_output_file(&p, serde_json::to_string_pretty(r)?)
        .with_context(|| format!("writing {}", p.display()))?;
    let p = dir.join("report.html");
    exo_recording::files::write_output_file(&p, diagnose_report::html(d, r)?)
        .with_context(|| format!("writing {}", p.display()))?;
    Ok(())
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
