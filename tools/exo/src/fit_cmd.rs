//! `exo fit RECORDING.mcap …`: the paper's post-hoc analysis of contract
//! recordings, whoever wrote them. Each recording's samples, commands and
//! protocol states go through the identifier's own code (the same that runs
//! online, [`exo_experiments::offline`]), then [`exo_analysis::study`] makes
//! the paper's tables, printed by [`exo_report::fit`].

use std::path::PathBuf;

use anyhow::Result;
use clap::{Args, ValueEnum};
use exo_analysis::FitSource;
use exo_experiments::offline::{fit, FitOptions};
use exo_impedance::Joint;
use exo_report::fit::{tables, write_csv};

/// Arguments of `exo fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Contract recordings (docs/recording-format.md), or another rig's CSV
    /// files (as `exo import` reads them): CSVs are taken as experiments 1,
    /// 2, 3… of one subject `imported`, in the order given, each labelled
    /// with its file name (use `--study` to say more).
    #[arg(required_unless_present = "study")]
    pub recordings: Vec<PathBuf>,
    /// A study file (see `exo import --study`): its CSV trials, each with
    /// its subject, experiment, condition, α and load, are fitted together.
    #[arg(long, value_name = "STUDY.toml")]
    pub study: Option<PathBuf>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Also write the tables as CSV files into this directory.
    #[arg(long, value_name = "DIR")]
    pub csv: Option<PathBuf>,
    /// False-rejection probability of the F-tests.
    #[arg(long, default_value_t = 0.05)]
    pub level: f64,
    /// Guaranteed phase margin (degrees) for the recommended f (eq. f).
    #[arg(long, default_value_t = 10.8)]
    pub phase_margin_deg: f64,
    /// Stiffness range (Nm/rad) for eq. f, as MIN,MAX (default: each subject's fitted range).
    #[arg(long, value_name = "MIN,MAX", value_delimiter = ',', num_args = 2)]
    pub k_range: Option<Vec<f64>>,
    /// Use the FRF points the online identifier recorded instead of recomputing them.
    #[arg(long)]
    pub recorded_frf: bool,
    /// Exoskeleton inertia without load (kg·m²) when a recording does not say.
    #[arg(long, default_value_t = 0.1)]
    pub arm_inertia_kg_m2: f64,
    /// Load lever arm (m) when a recording does not say.
    #[arg(long, default_value_t = 0.45)]
    pub load_lever_arm_m: f64,
    /// Which measured FRF the parameters are estimated from: `cuff`
    /// (S_h = τ_c/θ_e, the paper's way) or `actuator` ((τ_s − τ_gravity)/θ_e
    /// = S_h + M_e s², the whole M_e removed).
    #[arg(long, value_enum, default_value_t = FitSourceArg::Cuff)]
    pub fit_source: FitSourceArg,
    /// Fit with B ≥ 0 and H ≥ 0 (a passive joint) instead of unconstrained.
    #[arg(long)]
    pub nonneg_damping: bool,
    /// Ordinary least squares, as the paper fitted, instead of weighting
    /// each point by its measured noise.
    #[arg(long)]
    pub unweighted: bool,
    /// The joint (elbow, ankle, knee, wrist), for the plausible human
    /// inertia; default: the recording's `joint` metadata, else unspecified.
    #[arg(long, value_parser = parse_joint)]
    pub joint: Option<Joint>,
}

/// `--fit-source` on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FitSourceArg {
    /// `S_h = τ_c/θ_e` from the cuff (the paper's estimate).
    Cuff,
    /// `(τ_s − τ_gravity)/θ_e` from the SEA torque, the whole `M_e` removed.
    Actuator,
}

impl From<FitSourceArg> for FitSource {
    fn from(a: FitSourceArg) -> Self {
        match a {
            FitSourceArg::Cuff => FitSource::CuffTorque,
            FitSourceArg::Actuator => FitSource::ActuatorTorque,
        }
    }
}

fn parse_joint(s: &str) -> Result<Joint, String> {
    Joint::parse(s)
        .ok_or_else(|| format!("`{s}`: expected elbow, ankle, knee, wrist or unspecified"))
}

impl FitArgs {
    /// The library's options for these arguments.
    pub fn options(&self) -> FitOptions {
        FitOptions {
            recordings: self.recordings.clone(),
            study: self.study.clone(),
            level: self.level,
            phase_margin_deg: self.phase_margin_deg,
            k_range: self.k_range.as_ref().map(|k| [k[0], k[1]]),
            recorded_frf: self.recorded_frf,
            arm_inertia_kg_m2: self.arm_inertia_kg_m2,
            load_lever_arm_m: self.load_lever_arm_m,
            fit_source: self.fit_source.into(),
            nonneg_damping: self.nonneg_damping,
            unweighted: self.unweighted,
            joint: self.joint,
        }
    }
}

/// A progress line of the fit ([`exo_experiments::offline::fit`]), on stderr.
pub fn note(line: String) {
    eprintln!("{line}");
}

/// Runs `exo fit`.
pub fn run(a: &FitArgs) -> Result<()> {
    let (_, report) = fit(&a.options(), &mut note)?;
    if let Some(dir) = &a.csv {
        write_csv(dir, &report)?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", tables(&report));
    }
    Ok(())
}
