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

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_config::{RunConfig, Subject};
use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::{diagnose, Settings, Term};
use exo_plant_sim::PlantModel;
use exo_recording::read_recording;
use serde::Serialize;

use crate::reproduce_cmd::simulate;

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

/// One benchmark case.
pub struct Case {
    /// Name.
    pub name: &'static str,
    /// What is concealed and how.
    pub what: &'static str,
    /// Terms the truth has and the nominal model lacks.
    pub expected: Vec<Term>,
    /// Makes the true plant from the default one.
    /// Makes the true plant from the default one, the effect's size times
    /// the scale (`--scale`; hysteresis, the subject's own, is not scaled).
    pub truth: fn(&mut PlantModel, &Subject, f64),
    /// Makes the nominal model from the default one.
    pub nominal: fn(&mut PlantModel, &Subject),
}

fn same(_: &mut PlantModel, _: &Subject) {}

fn same_truth(_: &mut PlantModel, _: &Subject, _: f64) {}

fn viscous_truth(m: &mut PlantModel, s: &Subject, _: f64) {
    viscous_tuned(m, s)
}

/// A viscous human whose damping matches the subject's hysteretic damping
/// at the coupled system's resonance: the Bode magnitude peak agrees, only
/// the phase away from it (mostly at low frequency) betrays the difference.
fn viscous_tuned(m: &mut PlantModel, s: &Subject) {
    let n = s.experiment.len().max(1) as f64;
    let k = s
        .experiment
        .iter()
        .map(|e| e.stiffness_nm_per_rad)
        .sum::<f64>()
        / n;
    let h = s
        .experiment
        .iter()
        .map(|e| e.hysteretic_damping_nm_per_rad)
        .sum::<f64>()
        / n;
    let inertia = m.human.inertia_kg_m2 + m.exo_inertia_kg_m2(m.exo.load_kg);
    let w_r = (k / inertia).sqrt();
    m.human.hysteretic_damping.enabled = false;
    m.human.viscous_damping.enabled = true;
    m.human.viscous_damping.b_nm_s_per_rad = h / w_r;
}

/// Every case.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "hysteresis",
            what: "hysteretic damping behind a viscous nominal model tuned to the resonance peak",
            expected: vec![Term::HystereticDamping],
            truth: same_truth,
            nominal: viscous_tuned,
        },
        Case {
            name: "coulomb",
            what: "0.3 Nm Coulomb friction in the exoskeleton joint (like hysteresis at one amplitude)",
            expected: vec![Term::CoulombFriction],
            truth: |m, _, scale| {
                m.joint_friction.coulomb.enabled = true;
                m.joint_friction.coulomb.torque_nm = 0.3 * scale;
            },
            nominal: same,
        },
        Case {
            name: "delay",
            what: "a 5 ms encoder delay (a phase error of 0.6° at 2 rad/s)",
            expected: vec![Term::EncoderDelay],
            truth: |m, _, scale| m.sensors.encoder.terms.delay_s = 0.005 * scale,
            nominal: same,
        },
        Case {
            name: "cuff",
            what: "cuff compliance of 600 Nm/rad (visible near the top of the band)",
            expected: vec![Term::CuffCompliance],
            truth: |m, _, scale| {
                m.cuff.compliance.enabled = true;
                m.cuff.compliance.stiffness_nm_per_rad = 600.0 / scale;
                m.cuff.compliance.damping_nm_s_per_rad = 2.0;
            },
            nominal: same,
        },
        Case {
            name: "gravity",
            what: "the arm 30 % heavier than model and controller assume (a gravity-compensation error, shifting with posture under bias)",
            expected: vec![Term::GravityError],
            truth: |m, _, scale| m.gravity.arm_mass_kg *= 1.0 + 0.3 * scale,
            nominal: same,
        },
        Case {
            name: "two",
            what: "hysteretic damping behind a tuned viscous model, and a 5 ms encoder delay",
            expected: vec![Term::HystereticDamping, Term::EncoderDelay],
            truth: |m, _, scale| m.sensors.encoder.terms.delay_s = 0.005 * scale,
            nominal: viscous_tuned,
        },
        Case {
            name: "null-seed",
            what: "no missing physics: the nominal model, another noise seed",
            expected: vec![],
            truth: |m, _, _| m.integration.seed = 7,
            nominal: same,
        },
        Case {
            name: "null-params",
            what: "no missing physics: forearm inertia +15 %, SEA bandwidth 8 Hz, another seed",
            expected: vec![],
            truth: |m, _, _| {
                m.human.inertia_kg_m2 *= 1.15;
                m.sea.dynamics.natural_frequency_hz = 8.0;
                m.integration.seed = 11;
            },
            nominal: same,
        },
        Case {
            name: "null-viscous",
            what: "no missing physics: a viscous human with a viscous nominal model",
            expected: vec![],
            truth: viscous_truth,
            nominal: viscous_tuned,
        },
    ]
}

/// One case's outcome.
#[derive(Debug, Serialize)]
pub struct Outcome {
    /// Case.
    pub case: String,
    /// What is concealed.
    pub what: String,
    /// Terms expected.
    pub expected: Vec<Term>,
    /// Terms named.
    pub named: Vec<Term>,
    /// The diagnosis' sentences.
    pub verdict: Vec<String>,
    /// Weighted RSS: nominal refitted, with the named terms.
    pub rss: [f64; 2],
    /// Held-out RSS change with the named terms (relative).
    pub heldout_change: f64,
    /// The naive look: the worst R² over the frequency responses of the
    /// nominal model with its own parameters refitted.
    pub r2_refit: f64,
    /// Named exactly the expected terms.
    pub correct: bool,
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
    for (i, c) in chosen.iter().enumerate() {
        let mut truth = default_plant;
        (c.truth)(&mut truth, &subject, a.scale);
        truth.integration.seed = truth.integration.seed.wrapping_add(a.seed_offset);
        let mut nominal = default_plant;
        (c.nominal)(&mut nominal, &subject);
        let truth_file = dir.join(format!("{}-truth.toml", c.name));
        let nominal_file = dir.join(format!("{}-nominal.toml", c.name));
        write_plant(&truth, &truth_file, c.what)?;
        write_plant(&nominal, &nominal_file, "the nominal model")?;
        let recording = if a.diagnose_only {
            let r = dir.join(format!("{}.mcap", c.name));
            if !r.is_file() {
                bail!("--diagnose-only: {} does not exist", r.display());
            }
            r
        } else {
            eprintln!(
                "exo diagnose-bench: case {} ({}/{}): {}",
                c.name,
                i + 1,
                chosen.len(),
                c.what
            );
            simulate(&base, &base.subject_file, Some(&truth_file), c.name, &dir)?
        };
        let rec = read_recording(&recording)
            .with_context(|| format!("reading {}", recording.display()))?;
        let d = reduce(&[rec], &Reduction::default());
        let r = diagnose(&d, &nominal, &Settings::default())
            .with_context(|| format!("diagnosing case {}", c.name))?;
        crate::diagnose_cmd::write_outputs(
            &dir.join(format!("{}-diagnosis", c.name)),
            &nominal,
            &d,
            &r,
        )?;
        let named: Vec<Term> = r.found.iter().map(|f| f.term).collect();
        let mut e = c.expected.clone();
        let mut n = named.clone();
        e.sort();
        n.sort();
        outcomes.push(Outcome {
            case: c.name.into(),
            what: c.what.into(),
            expected: c.expected.clone(),
            correct: e == n,
            named,
            verdict: r.verdict.clone(),
            rss: [r.refit.rss, r.final_score.rss],
            heldout_change: r.final_score.heldout_rss / r.refit.heldout_rss - 1.0,
            r2_refit: r
                .refit
                .per_tf
                .iter()
                .filter(|t| t.tf.is_dynamic())
                .map(|t| t.r2)
                .fold(f64::INFINITY, f64::min),
        });
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

fn names(t: &[Term]) -> String {
    if t.is_empty() {
        "—".into()
    } else {
        t.iter()
            .map(|t| format!("{t:?}"))
            .collect::<Vec<_>>()
            .join(" + ")
    }
}

/// The confusion table.
pub fn table(o: &[Outcome]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n{:<13} {:<34} {:<34} {:>9} {:>12} {:>10} {:>9}  ok",
        "case", "true effect", "named", "R² refit", "RSS refit", "RSS final", "held-out"
    );
    for x in o {
        let _ = writeln!(
            s,
            "{:<13} {:<34} {:<34} {:>9.4} {:>12.1} {:>10.1} {:>8.0}%  {}",
            x.case,
            names(&x.expected),
            names(&x.named),
            x.r2_refit,
            x.rss[0],
            x.rss[1],
            100.0 * x.heldout_change,
            if x.correct { "yes" } else { "NO" }
        );
    }
    let concealed = o.iter().filter(|x| !x.expected.is_empty()).count();
    let named_ok = o
        .iter()
        .filter(|x| !x.expected.is_empty() && x.correct)
        .count();
    let nulls = o.iter().filter(|x| x.expected.is_empty()).count();
    let clean = o
        .iter()
        .filter(|x| x.expected.is_empty() && x.named.is_empty())
        .count();
    let _ = writeln!(
        s,
        "\nconcealed effects named exactly: {named_ok} of {concealed}; null cases with nothing named: {clean} of {nulls}"
    );
    s.push_str(&confusion(o));
    for x in o {
        let _ = writeln!(s, "\n{} — {}", x.case, x.what);
        for v in &x.verdict {
            let _ = writeln!(s, "  {v}");
        }
    }
    s
}

/// The confusion matrix: rows are the true effects (and `none` for the null
/// cases), columns the terms named (and `none`). A true effect counts on
/// the diagonal when it was named, under `none` when it was missed; a term
/// named that the case does not have counts in the row of the case's
/// effect (or `none`), so every off-diagonal number is an error.
pub fn confusion(o: &[Outcome]) -> String {
    let label = |t: Option<Term>| t.map_or("none".to_string(), |t| format!("{t:?}"));
    let mut rows: Vec<Option<Term>> = Vec::new();
    let mut cols: Vec<Option<Term>> = Vec::new();
    let mut cells: std::collections::BTreeMap<(String, String), usize> = Default::default();
    let mut add = |r: Option<Term>,
                   c: Option<Term>,
                   rows: &mut Vec<Option<Term>>,
                   cols: &mut Vec<Option<Term>>| {
        if !rows.contains(&r) {
            rows.push(r);
        }
        if !cols.contains(&c) {
            cols.push(c);
        }
        *cells.entry((label(r), label(c))).or_default() += 1;
    };
    for x in o {
        if x.expected.is_empty() {
            if x.named.is_empty() {
                add(None, None, &mut rows, &mut cols);
            }
            for n in &x.named {
                add(None, Some(*n), &mut rows, &mut cols);
            }
            continue;
        }
        for t in &x.expected {
            let hit = x.named.contains(t);
            add(
                Some(*t),
                if hit { Some(*t) } else { None },
                &mut rows,
                &mut cols,
            );
        }
        for n in x.named.iter().filter(|n| !x.expected.contains(n)) {
            add(Some(x.expected[0]), Some(*n), &mut rows, &mut cols);
        }
    }
    let mut s = String::from(
        "\nconfusion (rows: true effect, columns: named; a case with two effects counts in both rows)\n",
    );
    let _ = write!(s, "{:<20}", "true \\ named");
    for c in &cols {
        let _ = write!(s, " {:>18}", label(*c));
    }
    s.push('\n');
    for r in &rows {
        let _ = write!(s, "{:<20}", label(*r));
        for c in &cols {
            let n = cells.get(&(label(*r), label(*c))).copied().unwrap_or(0);
            let _ = write!(
                s,
                " {:>18}",
                if n == 0 {
                    ".".to_string()
                } else {
                    n.to_string()
                }
            );
        }
        s.push('\n');
    }
    s
}
