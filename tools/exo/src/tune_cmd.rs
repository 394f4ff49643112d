//! `exo tune SUBJECT`: the paper's tuning experiment (section "Loop Shaping
//! Experiments"), automated on the simulated subject: each trial steps the
//! run's nodes in one process (`exo-sim`), which records what the five
//! processes would (tests/tests/it/determinism.rs).
//!
//! [`exo_experiments::tune`] runs it (its documentation says how); this command checks the arguments
//! and prints the outcome.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use clap::Args;
use exo_experiments::tune::{tune, Outcome, TuneOptions, Tuning, PAPER_MARGIN_F};

/// Arguments of `exo tune`.
#[derive(Debug, Args)]
pub struct TuneArgs {
    /// The subject: a letter of Table III (A–J, read from configs/subjects/)
    /// or the path of a subject file.
    pub subject: String,
    /// Run file the trials derive from (rig, plant model, controller layout, limits).
    #[arg(long, default_value_os_t = exo_config::configs_dir().join("default.toml"))]
    pub config: PathBuf,
    /// Experiment of Table I the subject holds for the low stiffness.
    #[arg(long, default_value_t = 1)]
    pub low_experiment: u32,
    /// Experiment of Table I the subject holds for the high stiffness.
    #[arg(long, default_value_t = 7)]
    pub high_experiment: u32,
    /// Step (dimensionless) by which f is raised.
    #[arg(long, default_value_t = 0.05)]
    pub step: f64,
    /// Width (dimensionless) to which the boundary is bisected.
    #[arg(long, default_value_t = 0.01)]
    pub resolution: f64,
    /// Torque (Nm) of the test springs on the joint before release.
    #[arg(long, default_value_t = 4.0)]
    pub spring_torque_nm: f64,
    /// Time (s) the springs stay attached after the bias has ramped in.
    #[arg(long, default_value_t = 2.0)]
    pub hold_s: f64,
    /// Time (s) observed after the release.
    #[arg(long, default_value_t = 4.0)]
    pub observe_s: f64,
    /// Instead of searching, run one release test at each of these f (at both
    /// stiffnesses) and report the verdicts. Repeatable.
    #[arg(long = "check", value_name = "F")]
    pub check: Vec<f64>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Keep each trial's run files in this directory (default: a temporary one, removed).
    #[arg(long)]
    pub work_dir: Option<PathBuf>,
}

/// A subject argument: a file, or a name of `configs/subjects/*.toml` (A–J).
pub fn subject_path(subject: &str) -> PathBuf {
    let p = Path::new(subject);
    if p.exists() || subject.contains('/') || subject.ends_with(".toml") {
        p.to_path_buf()
    } else {
        exo_config::configs_dir()
            .join("subjects")
            .join(format!("{}.toml", subject.to_ascii_uppercase()))
    }
}

fn check_args(a: &TuneArgs) -> Result<()> {
    for (name, v, lo, hi) in [
        ("--step", a.step, 1e-3, 0.5),
        ("--resolution", a.resolution, 1e-4, 0.5),
        ("--hold-s", a.hold_s, 0.1, 600.0),
        ("--observe-s", a.observe_s, 1.0, 600.0),
        ("--spring-torque-nm", a.spring_torque_nm.abs(), 0.01, 100.0),
    ] {
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            bail!("{name} = {v}: must lie in [{lo}, {hi}]");
        }
    }
    for &v in &a.check {
        let (name, lo, hi) = ("--check", 0.0, 0.99);
        if !(v.is_finite() && (lo..=hi).contains(&v)) {
            bail!("{name} = {v}: must lie in [{lo}, {hi}]");
        }
    }
    Ok(())
}

/// Runs `exo tune`.
pub fn run(args: &TuneArgs) -> Result<()> {
    check_args(args)?;
    let options = TuneOptions {
        subject_file: subject_path(&args.subject),
        subject: args.subject.clone(),
        config: args.config.clone(),
        low_experiment: args.low_experiment,
        high_experiment: args.high_experiment,
        step: args.step,
        resolution: args.resolution,
        spring_torque_nm: args.spring_torque_nm,
        hold_s: args.hold_s,
        observe_s: args.observe_s,
        check: args.check.clone(),
        work_dir: args.work_dir.clone(),
    };
    let json = args.json;
    let outcome = tune(&options, &mut |line| {
        if !json {
            eprintln!("{line}");
        }
    })?;
    match outcome {
        Outcome::Checks {
            subject,
            kp,
            checks,
        } => {
            let out = serde_json::json!({
                "subject": subject,
                "kp": kp,
                "checks": checks,
            });
            if args.json {
                println!("{}", serde_json::to_string_pretty(&out)?);
            } else {
                for c in &checks {
                    for t in &c.trials {
                        println!(
                            "experiment {} (model boundary {:.3}), f = {:.3}: {}",
                            c.experiment, c.f_marginal_model, t.f, t.evidence
                        );
                    }
                }
            }
        }
        Outcome::Tuning(tuning) => {
            if args.json {
                println!("{}", serde_json::to_string_pretty(&tuning)?);
            } else {
                print_tuning(&tuning);
            }
        }
    }
    Ok(())
}

fn print_tuning(t: &Tuning) {
    println!("Tuning of subject {} (kp = {:.3})", t.subject, t.kp);
    println!(
        "{:>10} {:>10} {:>10} {:>22} {:>14}",
        "experiment", "K Nm/rad", "H Nm/rad", "measured boundary f", "model boundary"
    );
    for c in &t.cases {
        println!(
            "{:>10} {:>10.2} {:>10.2} {:>10.3} ({:.3}–{:.3}) {:>14.3}",
            c.experiment,
            c.k_nm_per_rad,
            c.h_nm_per_rad,
            c.f_marginal,
            c.f_stable,
            c.f_oscillating,
            c.f_marginal_model
        );
    }
    println!(
        "marginal f: measured {:.3}, model {:.3}",
        t.f_marginal, t.f_marginal_model
    );
    println!(
        "tuned f (marginal − {PAPER_MARGIN_F}): measured {:.3}, model {:.3}",
        t.f_tuned, t.f_tuned_model
    );
}
