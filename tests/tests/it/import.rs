//! `exo import` of a lab's trials: one subject's CSVs under several
//! conditions, labelled on the command line or by a study file, become
//! recordings whose metadata and protocol states say which subject,
//! experiment and condition each is; bad values are refused by name.
//! The single-CSV tests (a sine's frequency, the time column, the files
//! written) are in `import_csv.rs`; the simulated joint and the helpers
//! both use are here.

use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use exo_messages::ProtocolPhase;
use exo_recording::{read_recording, Recording};
use exo_tests::*;

/// A fresh scratch directory for one test.
pub(crate) fn scratch(tag: &str) -> ScratchDir {
    exo_tests::scratch_dir(&format!("import-{tag}"))
}

/// The simulated joint's inertia (kg·m²).
pub(crate) const INERTIA: f64 = 0.02;

/// Seeded noise: xorshift64*, summed uniforms for a roughly normal value.
pub(crate) struct Noise(pub(crate) u64);

impl Noise {
    pub(crate) fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
    pub(crate) fn normal(&mut self) -> f64 {
        (0..12).map(|_| self.uniform()).sum::<f64>() - 6.0
    }
}

/// One trial of a simulated human joint, S_h(jω) = K − M ω² + j H (mass,
/// spring and hysteretic damping), under a broadband position perturbation
/// (a multisine of 0.2–12 Hz with seeded phases), sampled at 200 Hz for
/// 20 s, with 1 % torque and angle noise. Returns the CSV text.
pub(crate) fn joint_csv(k: f64, h: f64, seed: u64) -> String {
    const RATE: f64 = 200.0;
    const SPAN: f64 = 20.0;
    let mut noise = Noise(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1);
    // Frequencies on the record's grid (k / SPAN Hz), so the multisine is periodic.
    let comps: Vec<(f64, f64, f64, f64)> = (4..=240)
        .step_by(4)
        .map(|i| {
            let w = 2.0 * PI * i as f64 / SPAN;
            let phase = 2.0 * PI * noise.uniform();
            let (re, im) = (k - INERTIA * w * w, h);
            let gain = (re * re + im * im).sqrt();
            (w, phase, gain, im.atan2(re))
        })
        .collect();
    let amp = 0.004; // rad per component
    let n = (RATE * SPAN) as usize;
    let mut text = String::from("time_s,position_rad,torque_nm\n");
    for s in 0..n {
        let t = s as f64 / RATE;
        let (mut theta, mut tau) = (0.0, 0.0);
        for &(w, ph, g, arg) in &comps {
            theta += amp * (w * t + ph).sin();
            tau += amp * g * (w * t + ph + arg).sin();
        }
        theta += 0.01 * 0.03 * noise.normal();
        tau += 0.01 * 0.03 * k * noise.normal();
        writeln!(text, "{t:.4},{theta:.7},{tau:.6}").unwrap();
    }
    text
}

/// The three conditions of the simulated subject: (file, K, H) with H on a
/// power law of K, as the paper finds.
fn conditions() -> Vec<(&'static str, f64, f64)> {
    [("relaxed", 20.0), ("mvc20", 45.0), ("mvc40", 80.0)]
        .into_iter()
        .map(|(f, k)| (f, k, 10f64.powf(-0.6) * f64::powf(k, 1.1)))
        .collect()
}

/// Writes the three conditions' CSVs into `dir/data/`.
fn write_conditions(dir: &Path) -> Vec<PathBuf> {
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    conditions()
        .iter()
        .enumerate()
        .map(|(i, (f, k, h))| {
            let p = data.join(format!("{f}.csv"));
            std::fs::write(&p, joint_csv(*k, *h, 7 + i as u64)).unwrap();
            p
        })
        .collect()
}

pub(crate) fn read(p: &Path) -> Recording {
    read_recording(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The protocol states' experiment, α and load of the analysis window.
fn window(r: &Recording) -> (u32, f64, f64) {
    let p = r
        .protocol
        .iter()
        .find(|p| p.protocol_phase() == Some(ProtocolPhase::Analysis))
        .unwrap_or_else(|| panic!("{}: no analysis window", r.source));
    (p.experiment, p.alpha, p.load_kg)
}

#[test]
fn a_study_of_three_conditions_writes_one_labelled_recording_per_trial() {
    let dir = scratch("study");
    let csvs = write_conditions(&dir);
    let study = dir.join("s1.toml");
    std::fs::write(
        &study,
        r#"
subject = "S1"

[[trial]]
file = "data/relaxed.csv"
experiment = 1
condition = "relaxed"
alpha = 1.0
load_kg = 0.0

[[trial]]
file = "data/mvc20.csv"
experiment = 2
condition = "MVC 20%"
alpha = 2

[[trial]]
file = "data/mvc40.csv"
experiment = 3
condition = "MVC 40%"
"#,
    )
    .unwrap();
    let out_dir = dir.join("recordings");
    // Run from elsewhere: trial files are relative to the study file.
    let out = exo(&[
        "import",
        "--study",
        study.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let printed: Vec<PathBuf> = stdout(&out).lines().map(PathBuf::from).collect();
    let expected: Vec<PathBuf> = (1..=3)
        .map(|n| out_dir.join(format!("S1-exp{n}.mcap")))
        .collect();
    assert_eq!(printed, expected, "{}", stdout(&out));
    let want = [
        ("relaxed", 1, Some(1.0), Some(0.0)),
        ("MVC 20%", 2, Some(2.0), None),
        ("MVC 40%", 3, None, None),
    ];
    let rows = 4000; // 20 s at 200 Hz
    for (p, (csv, (condition, n, alpha, load))) in printed.iter().zip(csvs.iter().zip(want)) {
        let r = read(p);
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        assert_eq!(r.meta("subject"), Some("S1"));
        assert_eq!(r.meta("condition"), Some(condition));
        assert_eq!(r.meta("experiment"), Some(n.to_string().as_str()));
        let assumed = |v: Option<f64>| Some(if v.is_none() { "true" } else { "false" });
        assert_eq!(r.meta("alpha_assumed"), assumed(alpha));
        assert_eq!(r.meta("load_assumed"), assumed(load));
        assert_eq!(r.meta("fit_target"), Some("human"), "no actuator column");
        assert!(r
            .meta("imported_from")
            .unwrap()
            .ends_with(csv.file_name().unwrap().to_str().unwrap()));
        // Every protocol state of the window carries the experiment, α and load.
        assert_eq!(
            window(&r),
            (n, alpha.unwrap_or(1.0), load.unwrap_or(0.0)),
            "{}",
            p.display()
        );
        assert!(r.protocol.iter().all(|s| s.experiment == n
            || (s.protocol_phase() == Some(ProtocolPhase::Idle) && s.experiment == 0)));
        assert!(r.protocol.iter().all(|s| s.omega == 0.0), "broadband");
        assert_eq!(r.sensor.len(), rows);
        assert!((r.meta("rate_hz").unwrap().parse::<f64>().unwrap() - 200.0).abs() < 1e-6);
    }
    // The imported samples are the simulated joint's: at the excitation's
    // lowest frequency (0.2 Hz, four whole periods in the record) τ/θ is
    // K − M ω² + j H of each condition.
    for (p, (_, k, h)) in printed.iter().zip(conditions()) {
        let r = read(p);
        let w = 2.0 * PI * 0.2;
        let (mut tau, mut theta) = ((0.0, 0.0), (0.0, 0.0));
        for s in &r.sensor {
            let t = s.stamp_ns as f64 * 1e-9;
            let (c, d) = ((w * t).cos(), -(w * t).sin());
            tau = (tau.0 + s.tau_c * c, tau.1 + s.tau_c * d);
            theta = (theta.0 + s.theta_e * c, theta.1 + s.theta_e * d);
        }
        let den = theta.0 * theta.0 + theta.1 * theta.1;
        let re = (tau.0 * theta.0 + tau.1 * theta.1) / den;
        let im = (tau.1 * theta.0 - tau.0 * theta.1) / den;
        let k_true = k - INERTIA * w * w;
        assert!(
            (re / k_true - 1.0).abs() < 0.03,
            "{}: Re S = {re}, K − Mω² = {k_true}",
            p.display()
        );
        assert!(
            (im / h - 1.0).abs() < 0.15,
            "{}: Im S = {im}, H = {h}",
            p.display()
        );
    }
}

#[test]
fn one_csv_takes_its_experiment_condition_alpha_and_load_from_the_command_line() {
    let dir = scratch("single");
    let csvs = write_conditions(&dir);
    let rec = dir.join("mvc20.mcap");
    let out = exo(&[
        "import",
        csvs[1].to_str().unwrap(),
        "--subject",
        "S7",
        "--experiment",
        "4",
        "--condition",
        "MVC 20%",
        "--alpha",
        "2.5",
        "--load-kg",
        "4.5",
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r = read(&rec);
    assert_eq!(r.meta("subject"), Some("S7"));
    assert_eq!(r.meta("condition"), Some("MVC 20%"));
    assert_eq!(r.meta("experiment"), Some("4"));
    assert_eq!(r.meta("alpha_assumed"), Some("false"));
    assert_eq!(r.meta("load_assumed"), Some("false"));
    assert_eq!(window(&r), (4, 2.5, 4.5));
    // Without the new options: experiment 1, condition = file stem, α and load assumed.
    let rec = dir.join("relaxed.mcap");
    let out = exo(&[
        "import",
        csvs[0].to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r = read(&rec);
    assert_eq!(r.meta("subject"), Some("imported"));
    assert_eq!(r.meta("condition"), Some("relaxed"));
    assert_eq!(r.meta("experiment"), Some("1"));
    assert_eq!(r.meta("alpha_assumed"), Some("true"));
    assert_eq!(r.meta("load_assumed"), Some("true"));
    assert_eq!(window(&r), (1, 1.0, 0.0));
    assert_eq!(r.meta("fit_target"), Some("human"));
}

#[test]
fn bad_study_files_are_refused_naming_the_trial_and_key() {
    let dir = scratch("badstudy");
    write_conditions(&dir);
    let good = "[[trial]]\nfile = \"data/relaxed.csv\"\nexperiment = 1\n";
    let cases: &[(&str, String, &[&str])] = &[
        (
            "unknown key",
            format!("subject = \"S1\"\n{good}[[trial]]\nfile = \"data/mvc20.csv\"\nexperiment = 2\nalpah = 2.0\n"),
            &["trial 2", "unknown field `alpah`"],
        ),
        (
            "unknown top-level key",
            format!("subjects = \"S1\"\n{good}"),
            &["unknown field `subjects`"],
        ),
        (
            "NaN alpha",
            format!("{good}[[trial]]\nfile = \"data/mvc20.csv\"\nexperiment = 2\nalpha = nan\n"),
            &["trial 2", "`alpha` = NaN"],
        ),
        (
            "infinite load",
            format!("{good}load_kg = inf\n"),
            &["trial 1", "`load_kg` = inf"],
        ),
        (
            "alpha below 1",
            format!("{good}alpha = 0.5\n"),
            &["trial 1", "`alpha` = 0.5"],
        ),
        (
            "experiment 0",
            "[[trial]]\nfile = \"data/relaxed.csv\"\nexperiment = 0\n".to_string(),
            &["trial 1", "`experiment` = 0"],
        ),
        (
            "experiment not a number",
            "[[trial]]\nfile = \"data/relaxed.csv\"\nexperiment = \"one\"\n".to_string(),
            &["trial 1", "experiment"],
        ),
        (
            "missing experiment",
            "[[trial]]\nfile = \"data/relaxed.csv\"\n".to_string(),
            &["trial 1", "missing field `experiment`"],
        ),
        (
            "duplicate experiment",
            format!(
                "subject = \"S1\"\n{good}[[trial]]\nfile = \"data/mvc20.csv\"\nexperiment = 2\n\
                 [[trial]]\nfile = \"data/mvc40.csv\"\nexperiment = 1\n"
            ),
            &["trial 3", "`experiment` = 1", "trial 1", "S1"],
        ),
        (
            "missing file",
            format!("{good}[[trial]]\nfile = \"data/mvc60.csv\"\nexperiment = 2\n"),
            &["trial 2", "`file`", "mvc60.csv"],
        ),
        ("no trials", "subject = \"S1\"\n".to_string(), &["no [[trial]]"]),
        (
            "TOML syntax",
            "[[trial]\nfile = \"x\"\n".to_string(),
            &["line 1"],
        ),
    ];
    for (i, (what, text, needles)) in cases.iter().enumerate() {
        let study = dir.join(format!("bad{i}.toml"));
        std::fs::write(&study, text).unwrap();
        let out_dir = dir.join(format!("out{i}"));
        let out = exo(&[
            "import",
            "--study",
            study.to_str().unwrap(),
            "-o",
            out_dir.to_str().unwrap(),
        ]);
        let e = stderr(&out);
        assert!(!out.status.success(), "{what}: accepted");
        assert!(
            e.contains(&format!("bad{i}.toml")),
            "{what}: the study file is not named: {e}"
        );
        for n in *needles {
            assert!(e.contains(n), "{what}: `{n}` not in: {e}");
        }
        assert!(!e.contains("panicked"), "{what}: {e}");
        assert!(!out_dir.exists(), "{what}: nothing is written");
    }
    // Two subjects in one study may share experiment numbers.
    let study = dir.join("two-subjects.toml");
    std::fs::write(
        &study,
        format!("subject = \"S1\"\n{good}[[trial]]\nfile = \"data/mvc20.csv\"\nexperiment = 1\nsubject = \"S2\"\n"),
    )
    .unwrap();
    let out = exo(&[
        "import",
        "--study",
        study.to_str().unwrap(),
        "-o",
        dir.join("two").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(dir.join("two/S1-exp1.mcap").is_file() && dir.join("two/S2-exp1.mcap").is_file());
    // A CSV that fails mid-study: named, and the recordings already written removed.
    std::fs::write(
        dir.join("data/broken.csv"),
        "time_s,position_rad,torque_nm\n0,1,x\n",
    )
    .unwrap();
    let study = dir.join("broken.toml");
    std::fs::write(
        &study,
        format!("{good}[[trial]]\nfile = \"data/broken.csv\"\nexperiment = 2\n"),
    )
    .unwrap();
    let out_dir = dir.join("broken-out");
    let out = exo(&[
        "import",
        "--study",
        study.to_str().unwrap(),
        "-o",
        out_dir.to_str().unwrap(),
    ]);
    let e = stderr(&out);
    assert!(!out.status.success());
    assert!(
        e.contains("trial 2") && e.contains("broken.csv") && e.contains("line 2"),
        "{e}"
    );
    assert_eq!(std::fs::read_dir(&out_dir).unwrap().count(), 0, "{e}");
}

#[test]
fn bad_command_line_values_are_refused_naming_the_option() {
    let dir = scratch("badcli");
    let csvs = write_conditions(&dir);
    let csv = csvs[0].to_str().unwrap();
    let rec = dir.join("x.mcap");
    for (args, option) in [
        (&["--alpha", "NaN"][..], "--alpha"),
        (&["--alpha", "inf"][..], "--alpha"),
        (&["--alpha", "0.5"][..], "--alpha"),
        (&["--load-kg", "-1"][..], "--load-kg"),
        (&["--load-kg", "nan"][..], "--load-kg"),
        (&["--experiment", "0"][..], "--experiment"),
        (&["--experiment", "-2"][..], "--experiment"),
        (&["--condition", " "][..], "--condition"),
        (&["--study", "s.toml"][..], "--study"),
    ] {
        let mut a = vec!["import", csv, "-o", rec.to_str().unwrap()];
        a.extend_from_slice(args);
        let out = exo(&a);
        let e = stderr(&out);
        assert!(!out.status.success(), "{args:?} accepted");
        assert!(e.contains(option), "{args:?}: {e}");
        assert!(!rec.exists(), "{args:?}: a recording was written");
    }
}

#[test]
fn the_real_ankle_recording_imports_through_a_study_file() {
    let csv = ankle_csv();
    let csv = csv.canonicalize().unwrap();
    let dir = scratch("ankle");
    let study = dir.join("ankle.toml");
    // An absolute path, and a study-wide flip_torque.
    std::fs::write(
        &study,
        format!(
            "subject = \"ankle\"\nflip_torque = true\n[[trial]]\nfile = {:?}\nexperiment = 1\n",
            csv.display().to_string()
        ),
    )
    .unwrap();
    let out = exo(&[
        "import",
        "--study",
        study.to_str().unwrap(),
        "-o",
        dir.join("out").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r = read(&dir.join("out/ankle-exp1.mcap"));
    assert_eq!(r.meta("condition"), Some("ankle_position_torque"));
    assert_eq!(r.meta("alpha_assumed"), Some("true"));
    assert_eq!(r.sensor.len(), 60_000);
    assert_eq!(window(&r), (1, 1.0, 0.0));
    // The reaction torque was flipped: torque and angle now move together.
    let corr: f64 = r.sensor.iter().map(|s| s.tau_c * s.theta_e).sum();
    assert!(corr > 0.0, "{corr}");
}

/// `exo fit a.csv b.csv c.csv`: a lab's trials of one subject, fitted as one
/// study: a table per condition, the F-tests across them and the power law
/// H = 10^β0 K^β1 across conditions, and no warning about actuator torque
/// the records never had. The truth is the simulated joint's K and H.
#[test]
fn csv_trials_are_fitted_as_one_study() {
    let dir = scratch("fit");
    let csvs = write_conditions(&dir);
    let mut args = vec![
        "fit".to_string(),
        "--json".into(),
        "--joint".into(),
        "ankle".into(),
    ];
    args.extend(csvs.iter().map(|p| p.display().to_string()));
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = exo(&argv);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let subjects = v["subjects"].as_array().unwrap();
    assert_eq!(subjects.len(), 1, "one subject: {v}");
    let s = &subjects[0];
    assert_eq!(s["subject"], "imported");
    let exps = s["experiments"].as_array().unwrap();
    assert_eq!(exps.len(), 3);
    for (e, (name, k, h)) in exps.iter().zip(conditions()) {
        assert_eq!(e["condition"], name, "{e}");
        assert_eq!(e["fit_source"], "cuff");
        let m2 = &e["models"]["M2"];
        let (kf, hf) = (m2["K"].as_f64().unwrap(), m2["H"].as_f64().unwrap());
        assert!((kf / k - 1.0).abs() < 0.03, "{name}: K {kf} vs {k}");
        assert!((hf / h - 1.0).abs() < 0.05, "{name}: H {hf} vs {h}");
    }
    // The power law across the three conditions: log10 H = −0.6 + 1.1 log10 K.
    let (b0, b1) = (s["beta0"].as_f64().unwrap(), s["beta1"].as_f64().unwrap());
    assert!(
        (b0 + 0.6).abs() < 0.1 && (b1 - 1.1).abs() < 0.05,
        "β0 {b0}, β1 {b1}"
    );
    // F-tests across the conditions: one F^sub over three experiments.
    let fsub = &v["f_tests"]["per_subject"][0]["m1_m3"];
    assert_eq!(fsub["df"][0].as_f64().unwrap(), 3.0, "{fsub}");
    assert!(fsub["significant"].as_bool().unwrap(), "hysteresis: {fsub}");
    // The phase table names the experiments present, not a paper group.
    let cell = &v["phase_table"][0]["groups"][0];
    assert_eq!(cell["experiments"], "1-3", "{cell}");
    let warnings: Vec<&str> = v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        warnings
            .iter()
            .all(|w| !w.contains("command") && !w.contains("τ_s/τ_d")),
        "{warnings:?}"
    );
    // α and load were not given: said once per record, naming what was assumed.
    assert_eq!(
        warnings
            .iter()
            .filter(|w| w.contains("α of experiment"))
            .count(),
        3,
        "{warnings:?}"
    );
    // Two conditions only: the phase table says which.
    let out = exo(&["fit", "--json", &args[4], &args[6]]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["phase_table"][0]["groups"][0]["experiments"], "1, 2");
}
