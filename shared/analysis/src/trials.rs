//! What one imported trial is: its subject, experiment number, condition
//! label, α and load, and how to read its CSV ([`TrialSpec`]); a study file
//! listing several trials ([`load_study`]); and the numbering of CSVs given
//! on a command line ([`default_trials`]).
//!
//! A study file (TOML; file paths relative to the study file's directory):
//!
//! ```toml
//! subject = "S1"            # default for every trial
//! flip_torque = true        # defaults too: flip_angle, time_col, time_unit,
//!                           # angle_col, torque_col, actuator_col
//! time_unit = "ms"          # unit of the time column: "s" (default), "ms", "us"
//! [[trial]]
//! file = "relaxed.csv"
//! experiment = 1            # required, ≥ 1, one per subject
//! condition = "relaxed"     # default: the file stem
//! alpha = 1.0               # optional (≥ 1); metadata alpha_assumed otherwise
//! load_kg = 0.0             # optional (≥ 0); metadata load_assumed otherwise
//! # optional per trial: subject, omega, flip_torque, flip_angle,
//! # time_col, time_unit, angle_col, torque_col, actuator_col
//! ```
//!
//! Unknown keys are refused, and every bad value is named with the study
//! file, the trial's number (1 = the first `[[trial]]`) and the key.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use serde::Deserialize;

/// The unit of a CSV's time column.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
pub enum TimeUnit {
    /// Seconds.
    #[default]
    #[serde(rename = "s")]
    S,
    /// Milliseconds.
    #[serde(rename = "ms")]
    Ms,
    /// Microseconds.
    #[serde(rename = "us")]
    Us,
}

impl TimeUnit {
    /// Every unit, coarsest first.
    pub const ALL: [TimeUnit; 3] = [TimeUnit::S, TimeUnit::Ms, TimeUnit::Us];

    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::S => 1.0,
            TimeUnit::Ms => 1e-3,
            TimeUnit::Us => 1e-6,
        }
    }

    /// The unit's spelling (`s`, `ms`, `us`).
    pub fn name(self) -> &'static str {
        match self {
            TimeUnit::S => "s",
            TimeUnit::Ms => "ms",
            TimeUnit::Us => "us",
        }
    }
}

impl fmt::Display for TimeUnit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// How to import one CSV: who and which experiment it is, and its columns.
#[derive(Debug, Clone, PartialEq)]
pub struct TrialSpec {
    /// Subject name (metadata `subject`).
    pub subject: String,
    /// Experiment number, ≥ 1 (`ProtocolState.experiment`); one per
    /// condition of a subject.
    pub experiment: u32,
    /// Free condition label, e.g. `MVC 20%` (metadata `condition`).
    pub condition: String,
    /// Constant amplification α (≥ 1) if known; the recording then says
    /// `alpha_assumed = false`, otherwise α = 1 and `alpha_assumed = true`.
    pub alpha: Option<f64>,
    /// Load on the arm (kg, ≥ 0) if known; otherwise 0 and `load_assumed = true`.
    pub load_kg: Option<f64>,
    /// Excitation frequency (rad/s) if the record is one sine period; broadband otherwise.
    pub omega: Option<f64>,
    /// Multiply the torque by −1 (e.g. a recorded reaction torque).
    pub flip_torque: bool,
    /// Multiply the angle by −1.
    pub flip_angle: bool,
    /// Column of the time.
    pub time_col: String,
    /// Unit of the time column (s, ms or us).
    pub time_unit: TimeUnit,
    /// Column of the joint angle (rad).
    pub angle_col: String,
    /// Column of the human joint torque (Nm).
    pub torque_col: String,
    /// Column of the actuator torque (Nm), if the rig recorded one.
    pub actuator_col: Option<String>,
}

/// Subject name of CSVs imported without one.
pub const DEFAULT_SUBJECT: &str = "imported";

/// The condition label of a CSV nobody labelled: its file stem.
pub fn file_stem(csv: &Path) -> String {
    csv.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .filter(|s| !s.trim().is_empty())
        .unwrap_or_else(|| csv.display().to_string())
}

impl TrialSpec {
    /// The defaults for `csv` as experiment `experiment`: subject
    /// `imported`, condition = the file stem, α and load unknown, broadband,
    /// columns `time_s`, `position_rad`, `torque_nm`, no actuator column.
    pub fn new(csv: &Path, experiment: u32) -> Self {
        TrialSpec {
            subject: DEFAULT_SUBJECT.to_string(),
            experiment,
            condition: file_stem(csv),
            alpha: None,
            load_kg: None,
            omega: None,
            flip_torque: false,
            flip_angle: false,
            time_col: "time_s".to_string(),
            time_unit: TimeUnit::S,
            angle_col: "position_rad".to_string(),
            torque_col: "torque_nm".to_string(),
            actuator_col: None,
        }
    }

    /// The first value out of range, named by its key (`alpha`, `load_kg`, …).
    pub fn validate(&self) -> std::result::Result<(), SpecError> {
        let err = |key: &'static str, value: String, need: &'static str| {
            Err(SpecError { key, value, need })
        };
        if self.subject.trim().is_empty() {
            return err(
                "subject",
                format!("{:?}", self.subject),
                "must not be empty",
            );
        }
        if self.experiment == 0 {
            return err("experiment", "0".into(), "must be an experiment number ≥ 1");
        }
        if self.condition.trim().is_empty() {
            return err(
                "condition",
                format!("{:?}", self.condition),
                "must not be empty",
            );
        }
        if let Some(a) = self.alpha {
            if !(a.is_finite() && a >= 1.0) {
                return err("alpha", format!("{a}"), "must be a finite number ≥ 1");
            }
        }
        if let Some(l) = self.load_kg {
            if !(l.is_finite() && l >= 0.0) {
                return err("load_kg", format!("{l}"), "must be a finite mass ≥ 0 (kg)");
            }
        }
        if let Some(w) = self.omega {
            if !(w.is_finite() && w > 0.0) {
                return err(
                    "omega",
                    format!("{w}"),
                    "must be a positive finite frequency (rad/s)",
                );
            }
        }
        for (key, col) in [
            ("time_col", Some(&self.time_col)),
            ("angle_col", Some(&self.angle_col)),
            ("torque_col", Some(&self.torque_col)),
            ("actuator_col", self.actuator_col.as_ref()),
        ] {
            if col.is_some_and(|c| c.trim().is_empty()) {
                return err(key, "\"\"".into(), "must name a column");
            }
        }
        Ok(())
    }

    /// The recording's file name in a study's output directory:
    /// `<subject>-exp<N>.mcap`, the subject's characters other than ASCII
    /// letters, digits, `-`, `_` and `.` replaced by `_`.
    pub fn recording_name(&self) -> String {
        let subject: String = self
            .subject
            .trim()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        format!("{subject}-exp{}.mcap", self.experiment)
    }
}

/// A value of a [`TrialSpec`] out of range: its key (the study file's
/// spelling, e.g. `load_kg`), the value and what it must be.
#[derive(Debug, Clone, PartialEq)]
pub struct SpecError {
    /// The key, as a study file spells it.
    pub key: &'static str,
    /// The value given.
    pub value: String,
    /// What it must be.
    pub need: &'static str,
}

impl SpecError {
    /// The command-line option of the key (`load_kg` → `--load-kg`).
    pub fn option(&self) -> String {
        format!("--{}", self.key.replace('_', "-"))
    }

    /// The message with the key as a command-line option.
    pub fn as_option(&self) -> String {
        format!("{} = {}: {}", self.option(), self.value, self.need)
    }
}

impl fmt::Display for SpecError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` = {}: {}", self.key, self.value, self.need)
    }
}

impl std::error::Error for SpecError {}

/// CSVs named on a command line (e.g. `exo fit a.csv b.csv`), in order:
/// experiments 1, 2, 3…, condition = each file stem, subject `imported`,
/// α and load unknown, the default columns.
pub fn default_trials(paths: &[PathBuf]) -> Vec<TrialSpec> {
    paths
        .iter()
        .enumerate()
        .map(|(i, p)| TrialSpec::new(p, u32::try_from(i + 1).unwrap_or(u32::MAX)))
        .collect()
}

/// The top level of a study file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StudyToml {
    subject: Option<String>,
    flip_torque: Option<bool>,
    flip_angle: Option<bool>,
    time_col: Option<String>,
    time_unit: Option<TimeUnit>,
    angle_col: Option<String>,
    torque_col: Option<String>,
    actuator_col: Option<String>,
    /// Deserialized one by one, so that errors name the trial.
    #[serde(default)]
    trial: Vec<toml::Value>,
}

/// One `[[trial]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrialToml {
    file: String,
    experiment: u32,
    condition: Option<String>,
    alpha: Option<f64>,
    load_kg: Option<f64>,
    subject: Option<String>,
    omega: Option<f64>,
    flip_torque: Option<bool>,
    flip_angle: Option<bool>,
    time_col: Option<String>,
    time_unit: Option<TimeUnit>,
    angle_col: Option<String>,
    torque_col: Option<String>,
    actuator_col: Option<String>,
}

/// Reads a study file: each trial's CSV (resolved against the study file's
/// directory; absolute paths as given) and its [`TrialSpec`], in file order.
///
/// Refused, naming the study file, the trial's number and the key: a TOML
/// syntax error, an unknown key, a value of the wrong type, a missing
/// `file` or `experiment`, NaN or ±∞, α < 1, a negative load, a
/// non-positive `omega`, an empty subject or condition, a CSV that does not
/// exist, two trials of one subject with the same experiment number (or
/// whose recordings would get the same file name), and a study without
/// trials.
pub fn load_study(path: &Path) -> Result<Vec<(PathBuf, TrialSpec)>> {
    let refuse = |detail: String| Error::Study {
        file: path.to_path_buf(),
        detail,
    };
    let text = std::fs::read_to_string(path).map_err(|source| Error::ReadStudy {
        file: path.to_path_buf(),
        source,
    })?;
    let doc: toml::Table = toml::from_str(&text).map_err(|source| Error::StudySyntax {
        file: path.to_path_buf(),
        source,
    })?;
    let top = StudyToml::deserialize(toml::Value::Table(doc))
        .map_err(|e| refuse(one_line(&e.to_string())))?;
    if top.trial.is_empty() {
        return Err(refuse(
            "no [[trial]]: list each CSV as a [[trial]] with `file` and `experiment`".into(),
        ));
    }
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut out: Vec<(PathBuf, TrialSpec)> = Vec::with_capacity(top.trial.len());
    // (subject, experiment) and output file name → trial number.
    let mut seen: BTreeMap<(String, u32), usize> = BTreeMap::new();
    let mut names: BTreeMap<String, usize> = BTreeMap::new();
    for (i, value) in top.trial.into_iter().enumerate() {
        let n = i + 1;
        let t = TrialToml::deserialize(value)
            .map_err(|e| refuse(format!("trial {n}: {}", one_line(&e.to_string()))))?;
        // The trial, after the study file's name.
        let at = format!("trial {n} ({})", t.file);
        if t.file.trim().is_empty() {
            return Err(refuse(format!(
                "trial {n}: `file` = \"\": must name a CSV file"
            )));
        }
        let csv = dir.join(&t.file);
        if !csv.is_file() {
            return Err(refuse(format!(
                "{at}: `file` = {:?}: no such file ({})",
                t.file,
                csv.display()
            )));
        }
        let mut spec = TrialSpec::new(&csv, t.experiment);
        if let Some(c) = t.condition {
            spec.condition = c;
        }
        spec.alpha = t.alpha;
        spec.load_kg = t.load_kg;
        spec.omega = t.omega;
        if let Some(s) = t.subject.or_else(|| top.subject.clone()) {
            spec.subject = s;
        }
        spec.flip_torque = t.flip_torque.or(top.flip_torque).unwrap_or(false);
        spec.flip_angle = t.flip_angle.or(top.flip_angle).unwrap_or(false);
        for (field, own, default) in [
            (&mut spec.time_col, t.time_col, &top.time_col),
            (&mut spec.angle_col, t.angle_col, &top.angle_col),
            (&mut spec.torque_col, t.torque_col, &top.torque_col),
        ] {
            if let Some(c) = own.or_else(|| default.clone()) {
                *field = c;
            }
        }
        spec.actuator_col = t.actuator_col.or_else(|| top.actuator_col.clone());
        spec.time_unit = t.time_unit.or(top.time_unit).unwrap_or_default();
        spec.validate().map_err(|e| refuse(format!("{at}: {e}")))?;
        if let Some(first) = seen.insert((spec.subject.clone(), spec.experiment), n) {
            return Err(refuse(format!(
                "{at}: `experiment` = {}: subject {:?} already has experiment {} in trial {first} ({}); \
                 each condition of a subject needs its own experiment number",
                spec.experiment,
                spec.subject,
                spec.experiment,
                out[first - 1].0.display()
            )));
        }
        if let Some(first) = names.insert(spec.recording_name(), n) {
            return Err(refuse(format!(
                "{at}: `subject` = {:?}: its recording {} would overwrite trial {first}'s \
                 (subject {:?}); name the subjects apart",
                spec.subject,
                spec.recording_name(),
                out[first - 1].1.subject
            )));
        }
        out.push((csv, spec));
    }
    Ok(out)
}

/// A serde message on one line (the value deserializer appends `\nin `key``).
fn one_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn study(tag: &str, toml_text: &str, files: &[&str]) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("exo-study-unit-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for f in files {
            std::fs::write(dir.join(f), "time_s,position_rad,torque_nm\n").unwrap();
        }
        let p = dir.join("study.toml");
        std::fs::write(&p, toml_text).unwrap();
        p
    }

    #[test]
    fn a_study_fills_defaults_and_resolves_files_against_its_directory() {
        let p = study(
            "ok",
            "subject = \"S1\"\nflip_torque = true\n\
             [[trial]]\nfile = \"a.csv\"\nexperiment = 2\nalpha = 2\n\
             [[trial]]\nfile = \"b.csv\"\nexperiment = 1\ncondition = \"MVC 20%\"\nload_kg = 4.5\nflip_torque = false\nsubject = \"S2\"\n",
            &["a.csv", "b.csv"],
        );
        let t = load_study(&p).unwrap();
        assert_eq!(t.len(), 2);
        assert_eq!(t[0].0, p.parent().unwrap().join("a.csv"));
        assert_eq!(t[0].1.subject, "S1");
        assert_eq!(t[0].1.condition, "a");
        assert_eq!(t[0].1.alpha, Some(2.0));
        assert_eq!(t[0].1.load_kg, None);
        assert!(t[0].1.flip_torque);
        assert_eq!(t[1].1.subject, "S2");
        assert_eq!(t[1].1.condition, "MVC 20%");
        assert_eq!(t[1].1.load_kg, Some(4.5));
        assert!(!t[1].1.flip_torque);
        assert_eq!(t[1].1.recording_name(), "S2-exp1.mcap");
    }

    #[test]
    fn bad_studies_name_the_trial_and_key() {
        let cases = [
            (
                "[[trial]]\nfile = \"a.csv\"\nexperiment = 1\nalpah = 1\n",
                "alpah",
            ),
            (
                "[[trial]]\nfile = \"a.csv\"\nexperiment = 1\nalpha = nan\n",
                "`alpha` = NaN",
            ),
            (
                "[[trial]]\nfile = \"a.csv\"\nexperiment = 1\nalpha = 0.5\n",
                "`alpha` = 0.5",
            ),
            (
                "[[trial]]\nfile = \"a.csv\"\nexperiment = 1\nload_kg = -inf\n",
                "`load_kg` = -inf",
            ),
            (
                "[[trial]]\nfile = \"a.csv\"\nexperiment = 0\n",
                "`experiment` = 0",
            ),
            (
                "[[trial]]\nfile = \"a.csv\"\nexperiment = \"one\"\n",
                "experiment",
            ),
            (
                "[[trial]]\nfile = \"a.csv\"\n",
                "missing field `experiment`",
            ),
            (
                "[[trial]]\nfile = \"zzz.csv\"\nexperiment = 1\n",
                "`file` = \"zzz.csv\"",
            ),
            (
                "subjct = \"x\"\n[[trial]]\nfile = \"a.csv\"\nexperiment = 1\n",
                "subjct",
            ),
            ("subject = \"x\"\n", "no [[trial]]"),
        ];
        for (i, (text, needle)) in cases.iter().enumerate() {
            let p = study(&format!("bad{i}"), text, &["a.csv"]);
            let e = format!("{:#}", load_study(&p).unwrap_err());
            assert!(e.contains("study.toml") && e.contains(needle), "{e}");
            if !needle.contains("subjct") && !needle.contains("no [[trial]]") {
                assert!(e.contains("trial 1"), "{e}");
            }
        }
        let p = study(
            "dup",
            "[[trial]]\nfile = \"a.csv\"\nexperiment = 3\n[[trial]]\nfile = \"b.csv\"\nexperiment = 3\n",
            &["a.csv", "b.csv"],
        );
        let e = format!("{:#}", load_study(&p).unwrap_err());
        assert!(
            e.contains("trial 2") && e.contains("`experiment` = 3") && e.contains("trial 1"),
            "{e}"
        );
    }

    #[test]
    fn command_line_csvs_are_numbered_in_order() {
        let t = default_trials(&[PathBuf::from("x/relaxed.csv"), PathBuf::from("mvc20.csv")]);
        assert_eq!((t[0].experiment, t[0].condition.as_str()), (1, "relaxed"));
        assert_eq!((t[1].experiment, t[1].condition.as_str()), (2, "mvc20"));
        assert!(t
            .iter()
            .all(|s| s.subject == "imported" && s.alpha.is_none()));
        assert!(t.iter().all(|s| s.validate().is_ok()));
    }
}
