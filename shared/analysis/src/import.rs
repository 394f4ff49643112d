//! Another rig's CSV (time, angle, torque, optional actuator torque) as a
//! contract recording, so `exo fit`, `exo report` and the replay backend
//! take it like any exo run: `exo import` writes [`build`]'s bytes to a
//! file, `exo fit` reads CSVs through [`recording_from_csv`] in memory. What
//! one trial is, and a study file of several, is [`crate::trials`].
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
//! (`ProtocolState.omega = 0`) unless `--omega` names a sine frequency, or
//! the angle is a single sine: without `--omega`, a record whose angle one
//! sinusoid explains (≥ 80 % of its variance about mean and trend, at least
//! two whole cycles) is imported as a sine period at that sinusoid's
//! frequency (least-squares estimate; the metadata says `omega_detected =
//! true`), so its S_h is labelled at the line, not at the FFT bins its
//! leakage reaches.
//!
//! The time column is in `--time-unit` (s, ms or us; default s). It must
//! increase and be uniformly sampled: a step above 1.5× the median step is
//! a gap, refused naming its line, the times either side and its size (split
//! the file there and import each part as its own trial); a median rate
//! under 10 Hz or over 100 kHz in the declared unit is refused naming the
//! unit that would make it plausible (e.g. `use --time-unit ms`).
//!
//! Without an actuator-torque column there is no `S_h-e/α`: the recording's
//! metadata says `fit_target = human`, and the fitter fits `S_h = τ/θ`.
//!
//! [`recording_from_csv`] builds the recording in memory, for tools that
//! take CSVs directly (`exo fit a.csv b.csv` with
//! [`crate::trials::default_trials`]).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::io::{Cursor, Seek, SeekFrom, Write};
use std::path::Path;
use std::rc::Rc;

use exo_messages::{ActuatorCommand, ProtocolState, SensorSample};
use exo_recording::{Recording, RecordingWriter, DEFAULT_CHUNK_BYTES};

use crate::error::{Error, Result};
use crate::trials::{TimeUnit, TrialSpec};

/// A time step above this multiple of the median step is a gap.
const GAP_FACTOR: f64 = 1.5;
/// The plausible sample rates (Hz): outside, the time unit is likely wrong.
const RATE_RANGE_HZ: (f64, f64) = (10.0, 100e3);
/// The fraction of the angle's variance one sinusoid must explain for a
/// record without `--omega` to be imported as a sine period.
const SINE_EXPLAINED: f64 = 0.8;
/// Whole cycles a detected sine must span.
const SINE_MIN_CYCLES: f64 = 2.0;

fn column(header: &[&str], name: &str, file: &Path) -> Result<usize> {
    header
        .iter()
        .position(|h| h.trim() == name)
        .ok_or_else(|| Error::Csv {
            file: file.to_path_buf(),
            detail: format!(
                "no column `{name}`; the header has {:?}",
                header.iter().map(|h| h.trim()).collect::<Vec<_>>()
            ),
        })
}

/// Parsed columns: time (s), angle (rad), torque (Nm), actuator torque (Nm).
pub struct Columns {
    /// Time (s).
    pub t: Vec<f64>,
    /// Joint angle (rad).
    pub theta: Vec<f64>,
    /// Human joint torque (Nm).
    pub tau: Vec<f64>,
    /// Actuator torque (Nm), if the rig recorded one.
    pub actuator: Option<Vec<f64>>,
}

fn parse_csv(csv: &Path, spec: &TrialSpec) -> Result<Columns> {
    let file = || csv.to_path_buf();
    let text = std::fs::read_to_string(csv).map_err(|source| Error::ReadCsv {
        file: file(),
        source,
    })?;
    // A spreadsheet's byte-order mark is not part of the first column's name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, head) = lines.next().ok_or_else(|| Error::Csv {
        file: file(),
        detail: "empty file".into(),
    })?;
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
            let line = i + 1;
            let raw = cells.get(col).ok_or_else(|| Error::CsvLine {
                file: file(),
                line,
                detail: format!("no value for column `{key}`"),
            })?;
            let v: f64 = raw.trim().parse().map_err(|source| Error::CsvNumber {
                file: file(),
                line,
                column: key.to_string(),
                raw: raw.to_string(),
                source,
            })?;
            if !v.is_finite() {
                return Err(Error::CsvLine {
                    file: file(),
                    line,
                    detail: format!("`{key}` = {v} is not finite"),
                });
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
        return Err(Error::Csv {
            file: file(),
            detail: format!("only {} samples", c.t.len()),
        });
    }
    check_time(csv, &c.t, &line_no, spec.time_unit)?;
    let scale = spec.time_unit.seconds();
    for t in &mut c.t {
        *t *= scale;
    }
    Ok(c)
}

/// `v` rounded to four significant digits (for messages).
fn sig4(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let p = 10f64.powi(3 - v.abs().log10().floor() as i32);
    (v * p).round() / p
}

/// Checks the time column `t` (in `unit`; `line_no[k]` is sample k's line):
/// increasing, a plausible rate in `unit`, and no gap.
fn check_time(csv: &Path, t: &[f64], line_no: &[usize], unit: TimeUnit) -> Result<()> {
    let at_line = |line: usize, detail: String| Error::CsvLine {
        file: csv.to_path_buf(),
        line,
        detail,
    };
    if let Some(k) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(at_line(
            line_no[k + 1],
            format!("time {} does not increase (previous {})", t[k + 1], t[k]),
        ));
    }
    let steps: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mut sorted = steps.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let (lo, hi) = RATE_RANGE_HZ;
    let rate_in = |u: TimeUnit| 1.0 / (median * u.seconds());
    let rate = rate_in(unit);
    if !(lo..=hi).contains(&rate) {
        // The unit that puts the rate nearest 1 kHz (log scale) within the range.
        let likely = TimeUnit::ALL
            .into_iter()
            .filter(|&u| u != unit && (lo..=hi).contains(&rate_in(u)))
            .min_by(|&a, &b| {
                let d = |u: TimeUnit| (rate_in(u) / 1e3).ln().abs();
                d(a).total_cmp(&d(b))
            });
        let hint = match likely {
            Some(u) => format!(
                "is the time column in {u}? use --time-unit {u} (study file: time_unit = \"{u}\"), \
                 which gives {} Hz",
                sig4(rate_in(u))
            ),
            None => "no time unit (s, ms, us) gives a plausible rate; check the time column".into(),
        };
        return Err(Error::Csv {
            file: csv.to_path_buf(),
            detail: format!(
                "a sample rate of {} Hz in {unit} (median time step {} {unit}) is \
                 implausible (outside {lo} Hz–{} kHz): {hint}",
                sig4(rate),
                sig4(median),
                hi / 1e3
            ),
        });
    }
    if let Some(k) = steps.iter().position(|&d| d > GAP_FACTOR * median) {
        return Err(at_line(
            line_no[k + 1],
            format!(
                "the time jumps from {} to {} {unit}, a gap of {} {unit} \
                 ({}× the median step of {} {unit}): the record is not uniformly sampled; \
                 split the file before line {} and import each part as its own trial",
                t[k],
                t[k + 1],
                sig4(steps[k]),
                sig4(steps[k] / median),
                sig4(median),
                line_no[k + 1]
            ),
        ));
    }
    Ok(())
}

/// Least-squares fit of `x ≈ c0 + c1 τ + a cos ωτ + b sin ωτ` (`τ = t − t0`):
/// the fraction of the variance about mean and trend the sinusoid explains.
fn sine_explained(t: &[f64], x: &[f64], omega: f64, tss: f64) -> f64 {
    let t0 = t[0];
    let mut ata = [[0.0f64; 4]; 4];
    let mut aty = [0.0f64; 4];
    let row = |tau: f64| {
        let (s, c) = (omega * tau).sin_cos();
        [1.0, tau, c, s]
    };
    for (&ti, &xi) in t.iter().zip(x) {
        let r = row(ti - t0);
        for i in 0..4 {
            aty[i] += r[i] * xi;
            for j in 0..4 {
                ata[i][j] += r[i] * r[j];
            }
        }
    }
    let Some(c) = solve4(ata, aty) else {
        return 0.0;
    };
    let rss: f64 = t
        .iter()
        .zip(x)
        .map(|(&ti, &xi)| {
            let r = row(ti - t0);
            let f: f64 = (0..4).map(|i| r[i] * c[i]).sum();
            (xi - f).powi(2)
        })
        .sum();
    1.0 - rss / tss
}

/// Solves the 4 × 4 system `a c = y` (Gaussian elimination, partial pivoting).
fn solve4(mut a: [[f64; 4]; 4], mut y: [f64; 4]) -> Option<[f64; 4]> {
    for col in 0..4 {
        let p = (col..4).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[p][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, p);
        y.swap(col, p);
        for r in col + 1..4 {
            let f = a[r][col] / a[col][col];
            let pivot = a[col];
            for (x, p) in a[r].iter_mut().zip(pivot).skip(col) {
                *x -= f * p;
            }
            y[r] -= f * y[col];
        }
    }
    let mut c = [0.0; 4];
    for r in (0..4).rev() {
        let s: f64 = (r + 1..4).map(|k| a[r][k] * c[k]).sum();
        c[r] = (y[r] - s) / a[r][r];
    }
    c.iter().all(|v| v.is_finite()).then_some(c)
}

/// The frequency (rad/s) of a single sine `x` sampled at `t` (s, uniform)
/// and the fraction of its variance (about mean and trend) it explains, if
/// one sinusoid explains at least [`SINE_EXPLAINED`] of it over at least
/// [`SINE_MIN_CYCLES`] whole cycles. The peak of the Hann-windowed,
/// zero-padded spectrum, refined by maximising the least-squares fit.
fn detect_sine(t: &[f64], x: &[f64]) -> Option<(f64, f64)> {
    let n = t.len();
    let dt = (t[n - 1] - t[0]) / (n - 1) as f64;
    let span = dt * n as f64;
    // Mean and trend removed.
    let (tm, xm) = (
        t.iter().sum::<f64>() / n as f64,
        x.iter().sum::<f64>() / n as f64,
    );
    let stt: f64 = t.iter().map(|&ti| (ti - tm).powi(2)).sum();
    let slope = t
        .iter()
        .zip(x)
        .map(|(&ti, &xi)| (ti - tm) * (xi - xm))
        .sum::<f64>()
        / stt;
    let d: Vec<f64> = t
        .iter()
        .zip(x)
        .map(|(&ti, &xi)| xi - xm - slope * (ti - tm))
        .collect();
    let tss: f64 = d.iter().map(|v| v * v).sum();
    if !(tss > 0.0 && tss.is_finite()) {
        return None;
    }
    let m = (n.next_power_of_two() * 4).min(n.next_power_of_two().max(1 << 22));
    let mut a = vec![exo_impedance::Complex64::new(0.0, 0.0); m];
    for (k, (slot, v)) in a.iter_mut().zip(&d).enumerate() {
        let w = 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / n as f64).cos();
        *slot = exo_impedance::Complex64::new(v * w, 0.0);
    }
    exo_impedance::frf::fft_in_place(&mut a).ok()?;
    let peak = (1..m / 2).max_by(|&i, &j| a[i].norm_sqr().total_cmp(&a[j].norm_sqr()))?;
    let bin = std::f64::consts::TAU / (m as f64 * dt);
    let (mut lo, mut hi) = (
        (peak as f64 - 2.0).max(0.5) * bin,
        (peak as f64 + 2.0) * bin,
    );
    // Golden-section search of the explained fraction.
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let f = |w: f64| sine_explained(t, x, w, tss);
    let (mut w1, mut w2) = (hi - g * (hi - lo), lo + g * (hi - lo));
    let (mut f1, mut f2) = (f(w1), f(w2));
    for _ in 0..60 {
        if f1 < f2 {
            lo = w1;
            w1 = w2;
            f1 = f2;
            w2 = lo + g * (hi - lo);
            f2 = f(w2);
        } else {
            hi = w2;
            w2 = w1;
            f2 = f1;
            w1 = hi - g * (hi - lo);
            f1 = f(w1);
        }
    }
    let omega = 0.5 * (lo + hi);
    let explained = f(omega);
    let cycles = omega * span / std::f64::consts::TAU;
    (explained >= SINE_EXPLAINED && cycles >= SINE_MIN_CYCLES && omega < std::f64::consts::PI / dt)
        .then_some((omega, explained))
}

/// `spec` with the detected sine's frequency when it names none (see the
/// module documentation); the detection's explained fraction.
fn with_detected_omega(spec: &TrialSpec, c: &Columns) -> (TrialSpec, Option<f64>) {
    let mut spec = spec.clone();
    if spec.omega.is_some() {
        return (spec, None);
    }
    match detect_sine(&c.t, &c.theta) {
        Some((w, explained)) => {
            spec.omega = Some(w);
            (spec, Some(explained))
        }
        None => (spec, None),
    }
}

/// Writes one trial's recording; returns the sample rate (Hz).
fn write_trial<W: Write + Seek>(
    mut w: RecordingWriter<W>,
    csv: &Path,
    spec: &TrialSpec,
    c: &Columns,
    detected: bool,
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
    if detected {
        meta.insert("omega_detected".into(), "true".into());
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

/// What [`build`] returns: the file's bytes, the parsed columns, the rate
/// (Hz), the spec as written (with a detected sine's ω) and the detected
/// sine's explained fraction.
pub type Built = (Vec<u8>, Columns, f64, TrialSpec, Option<f64>);

/// The recording of `csv` under `spec`, built in memory (see [`Built`]).
pub fn build(csv: &Path, spec: &TrialSpec) -> Result<Built> {
    let c = parse_csv(csv, spec)?;
    let (spec, detected) = with_detected_omega(spec, &c);
    let buf = SharedBuffer::default();
    let w = RecordingWriter::new(buf.clone(), csv, DEFAULT_CHUNK_BYTES)?;
    let rate = write_trial(w, csv, &spec, &c, detected.is_some())?;
    let bytes = buf.0.take().into_inner();
    Ok((bytes, c, rate, spec, detected))
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
    spec.validate().map_err(|error| Error::Spec {
        csv: path.to_path_buf(),
        error,
    })?;
    let (bytes, ..) = build(path, spec)?;
    Ok(exo_recording::read_recording_bytes(
        &path.display().to_string(),
        &bytes,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

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
        let mut spec = crate::trials::default_trials(std::slice::from_ref(&p)).remove(0);
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
