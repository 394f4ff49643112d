//! `exo import DATA.csv -o OUT.mcap`: another rig's CSV (time, angle,
//! torque, optional actuator torque) as a contract recording, so `exo fit`,
//! `exo report` and the replay backend take it like any exo run.
//! `exo import --study STUDY.toml -o DIR`: several trials of a lab's subjects
//! (one CSV per condition), one recording per trial, `DIR/<subject>-exp<N>.mcap`.
//!
//! The CSV's reading, the sine detection and the recording are
//! [`exo_analysis::import`]'s (its documentation says what is refused and
//! what the recording carries); the trial and study file are
//! [`exo_analysis::trials`]'s. This command writes the recording:
//!
//! The output is refused when it is the input CSV itself (same device and
//! inode), or, with `--study`, any of the study's CSVs or the study file.
//! The recording is built in memory, written to a temporary file (mode
//! 0640) in the output's directory, synced, and renamed over the output
//! only when complete: a failure (no space, no permission, a bad cell)
//! leaves any earlier file at that path intact and no partial file behind,
//! and the error names the path and the OS error.

use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use exo_analysis::import::build;
use exo_analysis::trials::{self, load_study, TimeUnit, TrialSpec};

/// Arguments of `exo import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The CSV file (a header row, then one row per sample).
    #[arg(required_unless_present = "study")]
    pub csv: Option<PathBuf>,
    /// The recording to write (with --study: the directory of the recordings).
    #[arg(short = 'o', long = "out", value_name = "OUT.mcap|DIR")]
    pub out: PathBuf,
    /// Import every trial a study file lists (TOML: `subject`, then
    /// `[[trial]]` tables with `file`, `experiment`, `condition`, `alpha`,
    /// `load_kg`, …), one recording per trial into the -o directory.
    #[arg(long, value_name = "STUDY.toml", conflicts_with_all = [
        "csv", "experiment", "condition", "alpha", "load_kg", "omega", "subject",
        "flip_torque", "flip_angle", "time_col", "time_unit", "angle_col", "torque_col", "actuator_col",
    ])]
    pub study: Option<PathBuf>,
    /// Experiment number of this trial (≥ 1): one per condition of a subject.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 1,
        allow_hyphen_values = true
    )]
    pub experiment: u32,
    /// Condition label, e.g. "MVC 20%" [default: the CSV's file stem].
    #[arg(long, value_name = "TEXT")]
    pub condition: Option<String>,
    /// Constant amplification α of the trial (≥ 1) [default: unknown; 1 is
    /// written and the metadata says alpha_assumed = true].
    #[arg(long, value_name = "A", allow_hyphen_values = true, value_parser = crate::args::finite)]
    pub alpha: Option<f64>,
    /// Load on the exoskeleton arm (kg, ≥ 0) [default: unknown; 0 is written
    /// and the metadata says load_assumed = true].
    #[arg(long, value_name = "KG", allow_hyphen_values = true, value_parser = crate::args::finite)]
    pub load_kg: Option<f64>,
    /// Column of the time (in --time-unit).
    #[arg(long, default_value = "time_s")]
    pub time_col: String,
    /// Unit of the time column.
    #[arg(long, value_enum, default_value_t = TimeUnitArg::S)]
    pub time_unit: TimeUnitArg,
    /// Column of the joint angle (rad).
    #[arg(long, default_value = "position_rad")]
    pub angle_col: String,
    /// Column of the human joint torque (Nm).
    #[arg(long, default_value = "torque_nm")]
    pub torque_col: String,
    /// Column of the actuator torque (Nm), if the rig recorded one.
    #[arg(long)]
    pub actuator_col: Option<String>,
    /// Multiply the torque by −1 (e.g. a recorded reaction torque).
    #[arg(long)]
    pub flip_torque: bool,
    /// Multiply the angle by −1.
    #[arg(long)]
    pub flip_angle: bool,
    /// Subject name stored in the recording.
    #[arg(long, default_value = trials::DEFAULT_SUBJECT)]
    pub subject: String,
    /// Excitation frequency (rad/s) if the record is one sine period; broadband otherwise.
    #[arg(long, allow_hyphen_values = true)]
    pub omega: Option<f64>,
}

/// `--time-unit` on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum TimeUnitArg {
    /// Seconds.
    #[value(name = "s")]
    S,
    /// Milliseconds.
    #[value(name = "ms")]
    Ms,
    /// Microseconds.
    #[value(name = "us")]
    Us,
}

impl From<TimeUnitArg> for TimeUnit {
    fn from(a: TimeUnitArg) -> Self {
        match a {
            TimeUnitArg::S => TimeUnit::S,
            TimeUnitArg::Ms => TimeUnit::Ms,
            TimeUnitArg::Us => TimeUnit::Us,
        }
    }
}

impl ImportArgs {
    /// The single trial the command line describes.
    fn spec(&self, csv: &Path) -> TrialSpec {
        TrialSpec {
            subject: self.subject.clone(),
            experiment: self.experiment,
            condition: self
                .condition
                .clone()
                .unwrap_or_else(|| trials::file_stem(csv)),
            alpha: self.alpha,
            load_kg: self.load_kg,
            omega: self.omega,
            flip_torque: self.flip_torque,
            flip_angle: self.flip_angle,
            time_col: self.time_col.clone(),
            time_unit: self.time_unit.into(),
            angle_col: self.angle_col.clone(),
            torque_col: self.torque_col.clone(),
            actuator_col: self.actuator_col.clone(),
        }
    }
}

/// Whether `a` and `b` are the same existing file (device and inode).
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Writes `bytes` to `out` atomically (`exo_recording::files::write_output_file`:
/// a temporary file renamed into place), creating its directory.
fn write_atomically(out: &Path, bytes: &[u8]) -> Result<()> {
    let shown = out.display();
    if out.file_name().is_none() {
        anyhow::bail!("-o {shown}: names no file");
    }
    let dir = out
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    exo_recording::files::create_output_dir(dir)
        .with_context(|| format!("writing {shown}: creating its directory {}", dir.display()))?;
    exo_recording::files::write_output_file(out, bytes).map_err(anyhow::Error::from)
}

/// Imports one CSV into the recording `out` (see the module documentation).
fn import_file(csv: &Path, spec: &TrialSpec, out: &Path) -> Result<()> {
    if same_file(csv, out) {
        bail!(
            "-o {}: is the input CSV {} itself; importing would overwrite it: name another output, e.g. {}",
            out.display(),
            csv.display(),
            csv.with_extension("mcap").display()
        );
    }
    let (bytes, c, rate, spec, detected) = build(csv, spec)?;
    if let (Some(w), Some(x)) = (spec.omega, detected) {
        eprintln!(
            "exo import: {}: the angle is a single sine at {w:.4} rad/s ({:.1} % of its variance): \
             imported as one sine period at that frequency (--omega overrides)",
            csv.display(),
            100.0 * x
        );
    }
    write_atomically(out, &bytes)?;
    eprintln!(
        "exo import: {} samples at {rate:.1} Hz from {} → {} (subject {}, experiment {}, {:?})",
        c.t.len(),
        csv.display(),
        out.display(),
        spec.subject,
        spec.experiment,
        spec.condition
    );
    Ok(())
}

/// Imports every trial of a study file into `dir`; returns the recordings
/// written. On an error, the recordings this call already wrote are removed;
/// the failed trial's path keeps any earlier file (see [`write_atomically`]).
fn import_study(study: &Path, dir: &Path) -> Result<Vec<PathBuf>> {
    let trials = load_study(study)?;
    if dir.is_file() {
        bail!(
            "-o {}: with --study, -o names a directory for the recordings, not a file",
            dir.display()
        );
    }
    // No recording may replace one of the study's own files.
    for (i, (_, spec)) in trials.iter().enumerate() {
        let out = dir.join(spec.recording_name());
        let inputs = trials.iter().map(|(c, _)| c.as_path());
        if let Some(hit) = inputs
            .chain(std::iter::once(study))
            .find(|p| same_file(p, &out))
        {
            bail!(
                "{}: trial {}: its recording {} is the study's own file {}; importing would \
                 overwrite it: name another -o directory",
                study.display(),
                i + 1,
                out.display(),
                hit.display()
            );
        }
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    for (i, (csv, spec)) in trials.iter().enumerate() {
        let out = dir.join(spec.recording_name());
        if let Err(e) = import_file(csv, spec, &out) {
            for p in &written {
                let _ = std::fs::remove_file(p);
            }
            return Err(e.context(format!(
                "{}: trial {} ({}): not imported{}",
                study.display(),
                i + 1,
                csv.display(),
                if written.is_empty() {
                    String::new()
                } else {
                    format!(
                        "; the {} recording(s) already written were removed",
                        written.len()
                    )
                }
            )));
        }
        written.push(out);
    }
    Ok(written)
}

/// Runs `exo import`.
pub fn run(a: &ImportArgs) -> Result<()> {
    if let Some(study) = &a.study {
        for p in import_study(study, &a.out)? {
            println!("{}", p.display());
        }
        return Ok(());
    }
    let Some(csv) = &a.csv else {
        bail!("exo import needs a CSV file or --study STUDY.toml");
    };
    let spec = a.spec(csv);
    spec.validate()
        .map_err(|e| anyhow::anyhow!(e.as_option()))?;
    import_file(csv, &spec, &a.out)
}
