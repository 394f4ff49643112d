//! `exo import DATA.csv -o OUT.mcap`: another rig's CSV (time, angle,
//! torque, optional actuator torque) as a contract recording, so `exo fit`,
//! `exo report` and the replay backend take it like any exo run.
//! `exo import --study STUDY.toml -o DIR`: several trials of a lab's subjects
//! (one CSV per condition), one recording per trial, `DIR/<subject>-exp<N>.mcap`.
//!
//! Each trial says which subject and which experiment (condition) it is, so
//! fitting the recordings together gives the per-condition table, the
//! F-tests across conditions and the power law across them. Its
//! `ProtocolState`s carry the experiment number, α and the load; the `exo`
//! metadata record carries `subject`, `condition`, `experiment`, and
//! `alpha_assumed` / `load_assumed` (`true` when the user did not give the
//! value: then α = 1 and the load 0 kg were written).
//!
//! The whole record becomes one analysis window of a broadband period
//! (`ProtocolState.omega = 0`) unless `--omega` names a sine frequency.
//! Without an actuator-torque column there is no `S_h-e/α`: the recording's
//! metadata says `fit_target = human`, and the fitter fits `S_h = τ/θ`.
//!
//! [`recording_from_csv`] does the same in memory, for tools that take CSVs
//! directly (`exo fit a.csv b.csv` with [`default_trials`]).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::io::{Cursor, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::rc::Rc;

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_messages::{ActuatorCommand, ProtocolState, SensorSample};
use exo_recording::{Recording, RecordingWriter, DEFAULT_CHUNK_BYTES};

pub use crate::study::{load_study, TrialSpec};

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
        "flip_torque", "flip_angle", "time_col", "angle_col", "torque_col", "actuator_col",
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
    /// Column of the time (s).
    #[arg(long, default_value = "time_s")]
    pub time_col: String,
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
    #[arg(long, default_value = crate::study::DEFAULT_SUBJECT)]
    pub subject: String,
    /// Excitation frequency (rad/s) if the record is one sine period; broadband otherwise.
    #[arg(long, allow_hyphen_values = true)]
    pub omega: Option<f64>,
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
                .unwrap_or_else(|| crate::study::file_stem(csv)),
            alpha: self.alpha,
            load_kg: self.load_kg,
            omega: self.omega,
            flip_torque: self.flip_torque,
            flip_angle: self.flip_angle,
            time_col: self.time_col.clone(),
            angle_col: self.angle_col.clone(),
            torque_col: self.torque_col.clone(),
            actuator_col: self.actuator_col.clone(),
        }
    }
}

fn column(header: &[&str], name: &str, file: &Path) -> Result<usize> {
    header
        .iter()
        .position(|h| h.trim() == name)
        .with_context(|| {
            format!(
                "{}: no column `{name}`; the header has {:?}",
                file.display(),
                header.iter().map(|h| h.trim()).collect::<Vec<_>>()
            )
        })
}

/// Parsed columns: time (s), angle (rad), torque (Nm), actuator torque (Nm).
struct Columns {
    t: Vec<f64>,
    theta: Vec<f64>,
    tau: Vec<f64>,
    actuator: Option<Vec<f64>>,
}

fn parse_csv(csv: &Path, spec: &TrialSpec) -> Result<Columns> {
    let name = csv.display();
    let text = std::fs::read_to_string(csv).with_context(|| format!("reading {name}"))?;
    // A spreadsheet's byte-order mark is not part of the first column's name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, head) = lines
        .next()
        .with_context(|| format!("{name}: empty file"))?;
    let header: Vec<&str> = head.split(',').collect();
    let (ct, ca, cq) = (
        column(&header, &spec.time_col, csv)?,
        column(&header, &spec.angle_col, csv)?,
        column(&header, &spec.torque_col, csv)?,
    );
    let cs = spec
        .actuator_col
        .as_deref()
        .map(|c| column(&header, c, csv))
        .transpose()?;
    let sign = |flip: bool| if flip { -1.0 } else { 1.0 };
    let mut c = Columns {
        t: Vec::new(),
        theta: Vec::new(),
        tau: Vec::new(),
        actuator: cs.map(|_| Vec::new()),
    };
    let mut line_no = Vec::new();
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').collect();
        let get = |col: usize, key: &str| -> Result<f64> {
            let raw = cells
                .get(col)
                .with_context(|| format!("{name} line {}: no value for column `{key}`", i + 1))?;
            let v: f64 = raw.trim().parse().with_context(|| {
                format!("{name} line {}: `{key}` = {raw:?} is not a number", i + 1)
            })?;
            if !v.is_finite() {
                bail!("{name} line {}: `{key}` = {v} is not finite", i + 1);
            }
            Ok(v)
        };
        c.t.push(get(ct, &spec.time_col)?);
        c.theta
            .push(get(ca, &spec.angle_col)? * sign(spec.flip_angle));
        c.tau
            .push(get(cq, &spec.torque_col)? * sign(spec.flip_torque));
        if let (Some(col), Some(v)) = (cs, c.actuator.as_mut()) {
            v.push(get(
                col,
                spec.actuator_col.as_deref().unwrap_or("actuator"),
            )?);
        }
        line_no.push(i + 1);
    }
    if c.t.len() < 16 {
        bail!("{name}: only {} samples", c.t.len());
    }
    if let Some(k) = c.t.windows(2).position(|w| w[1] <= w[0]) {
        bail!(
            "{name} line {}: time {} does not increase (previous {})",
            line_no[k + 1],
            c.t[k + 1],
            c.t[k]
        );
    }
    Ok(c)
}

/// Writes one trial's recording; returns the sample rate (Hz).
fn write_trial<W: Write + Seek>(
    mut w: RecordingWriter<W>,
    csv: &Path,
    spec: &TrialSpec,
    c: &Columns,
) -> Result<f64> {
    let t = &c.t;
    let n = t.len();
    let stamp = |k: usize| ((t[k] - t[0]) * 1e9).round() as u64;
    let rate = (n - 1) as f64 / (t[n - 1] - t[0]);
    w.register_contract()?;
    let flag = |assumed: bool| if assumed { "true" } else { "false" }.to_string();
    let mut meta = BTreeMap::new();
    meta.insert("subject".to_string(), spec.subject.clone());
    meta.insert("software_version".into(), exo_recording::SOFTWARE.into());
    meta.insert("imported_from".into(), csv.display().to_string());
    meta.insert("rate_hz".into(), format!("{rate}"));
    meta.insert("condition".into(), spec.condition.clone());
    meta.insert("experiment".into(), spec.experiment.to_string());
    meta.insert("alpha_assumed".into(), flag(spec.alpha.is_none()));
    meta.insert("load_assumed".into(), flag(spec.load_kg.is_none()));
    if c.actuator.is_none() {
        meta.insert("fit_target".into(), "human".into());
    }
    w.write_metadata(exo_recording::RUN_METADATA, &meta)?;
    let state = |phase: u32, stamp_ns: u64| ProtocolState {
        experiment: spec.experiment,
        period: 1,
        phase,
        omega: spec.omega.unwrap_or(0.0),
        amplitude: 1.0,
        alpha: spec.alpha.unwrap_or(1.0),
        load_kg: spec.load_kg.unwrap_or(0.0),
        stamp_ns,
        ..Default::default()
    };
    w.write(&state(3, 0))?;
    for k in 0..n {
        let tau_s = c.actuator.as_ref().map_or(c.tau[k], |v| v[k]);
        w.write(&SensorSample {
            seq: k as u64,
            stamp_ns: stamp(k),
            theta_e: c.theta[k],
            tau_c: c.tau[k],
            tau_s,
            ..Default::default()
        })?;
        if c.actuator.is_some() {
            w.write(&ActuatorCommand {
                seq: k as u64,
                stamp_ns: stamp(k),
                sensor_seq: k as u64,
                tau_d: tau_s,
                mode: 1,
                ..Default::default()
            })?;
        }
    }
    let end = stamp(n - 1) + 1;
    w.write(&ProtocolState {
        experiment: 0,
        period: 0,
        ..state(0, end)
    })?;
    w.finish()?;
    Ok(rate)
}

/// Imports one CSV into the recording `out` (see the module documentation).
fn import_file(csv: &Path, spec: &TrialSpec, out: &Path) -> Result<()> {
    let c = parse_csv(csv, spec)?;
    let rate = write_trial(RecordingWriter::create(out)?, csv, spec, &c)?;
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

/// An in-memory file the recording writer can seek in, readable after it finished.
#[derive(Clone, Default)]
struct SharedBuffer(Rc<RefCell<Cursor<Vec<u8>>>>);

impl Write for SharedBuffer {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Seek for SharedBuffer {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.0.borrow_mut().seek(pos)
    }
}

/// The recording `exo import` would write for `path` under `spec`, built in
/// memory (no file is written) and read back with the contract reader, so
/// it is exactly what `exo fit` would read from the imported file.
/// `Recording::source` is the CSV's path, so warnings name it.
///
/// Errors name the CSV (missing file or column, a cell that is not a finite
/// number, time not increasing, fewer than 16 samples) or the spec's key
/// out of range (`` `alpha` = NaN: … ``, see [`TrialSpec::validate`]).
pub fn recording_from_csv(path: &Path, spec: &TrialSpec) -> Result<Recording> {
    spec.validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let c = parse_csv(path, spec)?;
    let buf = SharedBuffer::default();
    let w = RecordingWriter::new(buf.clone(), path, DEFAULT_CHUNK_BYTES)?;
    write_trial(w, path, spec, &c)?;
    let bytes = buf.0.take().into_inner();
    Ok(exo_recording::read_recording_bytes(
        &path.display().to_string(),
        &bytes,
    )?)
}

/// Imports every trial of a study file into `dir`; returns the recordings
/// written. On an error, the recordings this call already wrote are removed.
fn import_study(study: &Path, dir: &Path) -> Result<Vec<PathBuf>> {
    let trials = load_study(study)?;
    if dir.is_file() {
        bail!(
            "-o {}: with --study, -o names a directory for the recordings, not a file",
            dir.display()
        );
    }
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut written = Vec::new();
    for (i, (csv, spec)) in trials.iter().enumerate() {
        let out = dir.join(spec.recording_name());
        if let Err(e) = import_file(csv, spec, &out) {
            let _ = std::fs::remove_file(&out);
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

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(tag: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("exo-import-unit-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut text = String::from("\u{feff}time_s,position_rad,torque_nm,sea_nm\n");
        for k in 0..50 {
            let t = k as f64 * 0.01;
            let th = (7.0 * t).sin() * 0.1;
            text.push_str(&format!("{t},{th},{},{}\n", 40.0 * th, 41.0 * th));
        }
        let p = dir.join("MVC 20.csv");
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_csv_becomes_a_recording_in_memory() {
        let p = csv("mem");
        let mut spec = crate::study::default_trials(std::slice::from_ref(&p)).remove(0);
        spec.experiment = 5;
        spec.alpha = Some(2.0);
        let r = recording_from_csv(&p, &spec).unwrap();
        assert_eq!(r.source, p.display().to_string());
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert_eq!(r.sensor.len(), 50);
        assert!(r.command.is_empty());
        assert_eq!(r.meta("subject"), Some("imported"));
        assert_eq!(r.meta("condition"), Some("MVC 20"));
        assert_eq!(r.meta("experiment"), Some("5"));
        assert_eq!(r.meta("alpha_assumed"), Some("false"));
        assert_eq!(r.meta("load_assumed"), Some("true"));
        assert_eq!(r.meta("fit_target"), Some("human"));
        let p0 = r.protocol[0];
        assert_eq!(
            (p0.experiment, p0.phase, p0.alpha, p0.load_kg),
            (5, 3, 2.0, 0.0)
        );
        assert_eq!(r.protocol.last().unwrap().phase, 0);
        // With the actuator column: commands, and no fit_target.
        spec.actuator_col = Some("sea_nm".into());
        spec.flip_angle = true;
        let r = recording_from_csv(&p, &spec).unwrap();
        assert_eq!(r.command.len(), 50);
        assert_eq!(r.meta("fit_target"), None);
        assert!(r.sensor[10].theta_e < 0.0 && r.sensor[10].tau_c > 0.0);
        assert!((r.sensor[10].tau_s / r.sensor[10].tau_c - 41.0 / 40.0).abs() < 1e-9);
    }

    #[test]
    fn a_bad_spec_or_csv_is_named() {
        let p = csv("bad");
        let mut spec = TrialSpec::new(&p, 1);
        spec.alpha = Some(f64::NAN);
        let e = format!("{:#}", recording_from_csv(&p, &spec).unwrap_err());
        assert!(
            e.contains("MVC 20.csv") && e.contains("`alpha` = NaN"),
            "{e}"
        );
        let mut spec = TrialSpec::new(&p, 1);
        spec.torque_col = "tau".into();
        let e = format!("{:#}", recording_from_csv(&p, &spec).unwrap_err());
        assert!(e.contains("no column `tau`"), "{e}");
    }
}
