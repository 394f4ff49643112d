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
use exo_diagnose::bench::{
    cases, null_generators, rate_upper_95, Case, NullGenerator, NullOutcome, Outcome,
};
use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::{diagnose, Settings};
use exo_experiments::simulate::{default_workers, simulate_each, Job};
use exo_plant_model::PlantModel;
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
    /// Instead of the cases, the false-alarm rate: N recordings with nothing
    /// missing, from generators whose physics is the nominal one but whose
    /// implementation differs (our simulator's null cases at 1 kHz and
    /// 500 Hz, the independent rig's variants), each diagnosed against its
    /// nominal model; any term named is a false alarm.
    #[arg(long, value_name = "N")]
    pub nulls: Option<usize>,
    /// The nulls' generators: `sim`, `rig` or both.
    #[arg(long, value_delimiter = ',', default_value = "sim,rig")]
    pub generators: Vec<String>,
}

fn write_plant(m: &PlantModel, path: &Path, what: &str) -> Result<()> {
    let text = format!("# exo diagnose-bench: {what}\n\n{}", m.to_toml_string());
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}

/// Runs the bench.
pub fn run(a: &BenchArgs) -> Result<()> {
    if let Some(n) = a.nulls {
        return nulls(a, n);
    }
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
            .collect::<Result<Vec<_>, _>>()?
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

/// The false-alarm rate over `n` null recordings (`--nulls N`): generated
/// (our simulator's in lockstep, one per core; the rig's in turn), each
/// diagnosed against its nominal model, and the table of what was named.
fn nulls(a: &BenchArgs, n: usize) -> Result<()> {
    let (sim, rig) = (
        a.generators.iter().any(|g| g == "sim"),
        a.generators.iter().any(|g| g == "rig"),
    );
    if let Some(bad) = a.generators.iter().find(|g| *g != "sim" && *g != "rig") {
        bail!("--generators: {bad:?} is neither sim nor rig");
    }
    let generators = null_generators(sim, rig);
    if n == 0 || generators.is_empty() {
        bail!(
            "--nulls {n} --generators {}: nothing to run",
            a.generators.join(",")
        );
    }
    let base = RunConfig::from_file(&a.config)?;
    let default_plant = PlantModel::from_file(&base.plant_model)?;
    let all = cases();
    let dir = a
        .output
        .clone()
        .unwrap_or(base.run.output_dir.join("nulls"));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let settings = Settings::default();
    // (generator, recording, nominal model) of each null.
    let mut todo: Vec<(NullGenerator, PathBuf, PlantModel)> = Vec::new();
    let mut sim_jobs: Vec<(f64, Job, PlantModel)> = Vec::new();
    for i in 0..n {
        let g = generators[i % generators.len()];
        let seed = a.seed_offset + i as u64;
        let name = format!("null{i:04}");
        match g {
            NullGenerator::Simulator { case, rate_hz } => {
                let c = all
                    .iter()
                    .find(|c| c.name == case)
                    .with_context(|| format!("no null case {case}"))?;
                let subject = Subject::from_file(&base.subject_file)?;
                let mut truth = default_plant;
                (c.truth)(&mut truth, &subject, 1.0);
                truth.integration.seed = truth.integration.seed.wrapping_add(1000 + seed);
                let mut nominal = default_plant;
                (c.nominal)(&mut nominal, &subject);
                let truth_file = dir.join(format!("{name}-truth.toml"));
                write_plant(&truth, &truth_file, c.what)?;
                sim_jobs.push((
                    rate_hz,
                    Job {
                        subject: base.subject_file.clone(),
                        name: name.clone(),
                        plant: Some(truth_file),
                        rig_gravity_m_s2: (!truth.gravity.enabled).then_some(0.0),
                    },
                    nominal,
                ));
                todo.push((g, dir.join(format!("{name}.mcap")), nominal));
            }
            NullGenerator::Rig { args, .. } => {
                let rec = dir.join(format!("{name}.mcap"));
                if !a.diagnose_only {
                    eprintln!("exo diagnose-bench: null {}/{n}: {}", i + 1, g.name());
                    run_rig(&rec, seed, args)?;
                }
                let mut nominal = default_plant;
                exo_diagnose::bench::independent_rig(&mut nominal, args.contains(&"--horizontal"));
                todo.push((g, rec, nominal));
            }
        }
    }
    if !a.diagnose_only {
        for rate_hz in [1000.0, 500.0] {
            let jobs: Vec<Job> = sim_jobs
                .iter()
                .filter(|j| j.0 == rate_hz)
                .map(|j| j.1.clone())
                .collect();
            if jobs.is_empty() {
                continue;
            }
            let mut cfg = base.clone();
            cfg.run.rate_hz = rate_hz;
            let announce = |i: usize| {
                eprintln!(
                    "exo diagnose-bench: {} at {rate_hz:.0} Hz ({}/{})",
                    jobs[i].name,
                    i + 1,
                    jobs.len()
                );
            };
            for r in simulate_each(&cfg, &jobs, &dir, default_workers(), &announce) {
                r?;
            }
        }
    }
    let mut outcomes = Vec::new();
    for (g, rec, nominal) in &todo {
        let r = read_recording(rec).with_context(|| format!("reading {}", rec.display()))?;
        let d = reduce(&[r], &Reduction::default());
        let r = diagnose(&d, nominal, &settings)
            .with_context(|| format!("diagnosing {}", rec.display()))?;
        outcomes.push(NullOutcome::new(
            g.name(),
            rec.display().to_string(),
            &r,
            settings.level,
        ));
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&outcomes)?);
    } else {
        print!("{}", null_table(&generators, &outcomes));
    }
    Ok(())
}

/// The independent rig's recording `rec` of experiments 1, 4, 7 (ten
/// periods, the table's subject) with `seed` and `args`, through the
/// project's Python environment (`tools/python/ensure_venv.sh`).
fn run_rig(rec: &Path, seed: u64, args: &[&str]) -> Result<()> {
    let root = exo_config::configs_dir()
        .parent()
        .map(Path::to_path_buf)
        .context("the repository's root (configs/ has no parent)")?;
    let venv = std::process::Command::new("bash")
        .arg(root.join("tools/python/ensure_venv.sh"))
        .output()
        .context("running tools/python/ensure_venv.sh")?;
    if !venv.status.success() {
        bail!(
            "tools/python/ensure_venv.sh failed: {}",
            String::from_utf8_lossy(&venv.stderr)
        );
    }
    let python = String::from_utf8_lossy(&venv.stdout).trim().to_string();
    let out = std::process::Command::new(&python)
        .arg(root.join("tools/python/independent_rig.py"))
        .arg(rec)
        .args(["--seed", &seed.to_string(), "--experiments", "1,4,7"])
        .args(args)
        .output()
        .with_context(|| format!("running {python} independent_rig.py"))?;
    if !out.status.success() {
        bail!(
            "independent_rig.py {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(())
}

/// The false-alarm table: per generator, the nulls run, how many named a
/// term (and which), how many claimed unexplained structure, and the
/// median χ²/dof of the refitted nominal model; then the rates with their
/// one-sided 95 % upper bounds.
fn null_table(generators: &[NullGenerator], outcomes: &[NullOutcome]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<34} {:>5} {:>7} {:>11} {:>12}  named",
        "generator", "nulls", "named", "unexplained", "χ²/dof (med)"
    );
    for g in generators {
        let name = g.name();
        let mine: Vec<&NullOutcome> = outcomes.iter().filter(|o| o.generator == name).collect();
        if mine.is_empty() {
            continue;
        }
        let mut chi: Vec<f64> = mine.iter().map(|o| o.chi2_per_dof).collect();
        chi.sort_by(f64::total_cmp);
        let named: Vec<String> = mine
            .iter()
            .filter(|o| !o.named.is_empty())
            .map(|o| format!("{:?}", o.named))
            .collect();
        let _ = writeln!(
            s,
            "{:<34} {:>5} {:>7} {:>11} {:>12.2}  {}",
            name,
            mine.len(),
            named.len(),
            mine.iter().filter(|o| o.unexplained).count(),
            chi[chi.len() / 2],
            named.join(" ")
        );
    }
    let n = outcomes.len();
    let named = outcomes.iter().filter(|o| !o.named.is_empty()).count();
    let unexplained = outcomes.iter().filter(|o| o.unexplained).count();
    let _ = writeln!(
        s,
        "\nfalse alarms (a term named): {named} of {n} = {:.1} % (95 % upper bound {:.1} %)",
        100.0 * named as f64 / n.max(1) as f64,
        100.0 * rate_upper_95(named, n)
    );
    let _ = writeln!(
        s,
        "unexplained structure claimed with nothing named: {unexplained} of {n} = {:.1} % (95 % upper bound {:.1} %)",
        100.0 * unexplained as f64 / n.max(1) as f64,
        100.0 * rate_upper_95(unexplained, n)
    );
    s
}
