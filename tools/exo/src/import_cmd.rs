//! `exo import DATA.csv -o OUT.mcap`: another rig's CSV (time, angle,
//! torque, optional actuator torque) as a contract recording, so `exo fit`,
//! `exo report` and the replay backend take it like any exo run.
//!
//! The whole record becomes one analysis window of a broadband period
//! (`ProtocolState.omega = 0`) unless `--omega` names a sine frequency.
//! Without an actuator-torque column there is no `S_h-e/α`: the recording's
//! metadata says `fit_target = human`, and the fitter fits `S_h = τ/θ`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use exo_messages::{ActuatorCommand, ProtocolState, SensorSample};
use exo_recording::RecordingWriter;

/// Arguments of `exo import`.
#[derive(Debug, Args)]
pub struct ImportArgs {
    /// The CSV file (a header row, then one row per sample).
    pub csv: PathBuf,
    /// The recording to write.
    #[arg(short = 'o', long = "out", value_name = "OUT.mcap")]
    pub out: PathBuf,
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
    #[arg(long, default_value = "imported")]
    pub subject: String,
    /// Excitation frequency (rad/s) if the record is one sine period; broadband otherwise.
    #[arg(long)]
    pub omega: Option<f64>,
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
type Columns = (Vec<f64>, Vec<f64>, Vec<f64>, Option<Vec<f64>>);

fn parse(a: &ImportArgs) -> Result<Columns> {
    let text =
        std::fs::read_to_string(&a.csv).with_context(|| format!("reading {}", a.csv.display()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, head) = lines
        .next()
        .with_context(|| format!("{}: empty file", a.csv.display()))?;
    let header: Vec<&str> = head.split(',').collect();
    let (ct, ca, cq) = (
        column(&header, &a.time_col, &a.csv)?,
        column(&header, &a.angle_col, &a.csv)?,
        column(&header, &a.torque_col, &a.csv)?,
    );
    let cs = a
        .actuator_col
        .as_deref()
        .map(|c| column(&header, c, &a.csv))
        .transpose()?;
    let (mut t, mut th, mut q) = (Vec::new(), Vec::new(), Vec::new());
    let mut s = cs.map(|_| Vec::new());
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').collect();
        let get = |c: usize, name: &str| -> Result<f64> {
            let raw = cells.get(c).with_context(|| {
                format!(
                    "{} line {}: no value for column `{name}`",
                    a.csv.display(),
                    i + 1
                )
            })?;
            let v: f64 = raw.trim().parse().with_context(|| {
                format!(
                    "{} line {}: `{name}` = {raw:?} is not a number",
                    a.csv.display(),
                    i + 1
                )
            })?;
            if !v.is_finite() {
                bail!(
                    "{} line {}: `{name}` = {v} is not finite",
                    a.csv.display(),
                    i + 1
                );
            }
            Ok(v)
        };
        t.push(get(ct, &a.time_col)?);
        th.push(get(ca, &a.angle_col)? * if a.flip_angle { -1.0 } else { 1.0 });
        q.push(get(cq, &a.torque_col)? * if a.flip_torque { -1.0 } else { 1.0 });
        if let (Some(c), Some(v)) = (cs, s.as_mut()) {
            v.push(get(c, a.actuator_col.as_deref().unwrap_or("actuator"))?);
        }
    }
    if t.len() < 16 {
        bail!("{}: only {} samples", a.csv.display(), t.len());
    }
    if let Some(i) = t.windows(2).position(|w| w[1] <= w[0]) {
        bail!(
            "{} line {}: time {} does not increase (previous {})",
            a.csv.display(),
            i + 3,
            t[i + 1],
            t[i]
        );
    }
    Ok((t, th, q, s))
}

/// Runs `exo import`.
pub fn run(a: &ImportArgs) -> Result<()> {
    if let Some(w) = a.omega {
        if !(w.is_finite() && w > 0.0) {
            bail!("--omega = {w}: must be a positive frequency (rad/s)");
        }
    }
    let (t, th, q, s) = parse(a)?;
    let stamp = |k: usize| ((t[k] - t[0]) * 1e9).round() as u64;
    let rate = (t.len() - 1) as f64 / (t[t.len() - 1] - t[0]);
    let mut w = RecordingWriter::create(&a.out)?;
    w.register_contract()?;
    let mut meta = BTreeMap::new();
    meta.insert("subject".to_string(), a.subject.clone());
    meta.insert("software_version".into(), exo_recording::SOFTWARE.into());
    meta.insert("imported_from".into(), a.csv.display().to_string());
    meta.insert("rate_hz".into(), format!("{rate}"));
    if s.is_none() {
        meta.insert("fit_target".into(), "human".into());
    }
    w.write_metadata("exo", &meta)?;
    let state = |phase: u32, stamp_ns: u64| ProtocolState {
        experiment: 1,
        period: 1,
        phase,
        omega: a.omega.unwrap_or(0.0),
        amplitude: 1.0,
        alpha: 1.0,
        stamp_ns,
        ..Default::default()
    };
    w.write(&state(3, 0))?;
    for k in 0..t.len() {
        let tau_s = s.as_ref().map_or(q[k], |v| v[k]);
        w.write(&SensorSample {
            seq: k as u64,
            stamp_ns: stamp(k),
            theta_e: th[k],
            tau_c: q[k],
            tau_s,
            ..Default::default()
        })?;
        if s.is_some() {
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
    let end = stamp(t.len() - 1) + 1;
    w.write(&ProtocolState {
        experiment: 0,
        period: 0,
        ..state(0, end)
    })?;
    w.finish()?;
    eprintln!(
        "exo import: {} samples at {:.1} Hz from {} → {}",
        t.len(),
        rate,
        a.csv.display(),
        a.out.display()
    );
    Ok(())
}
