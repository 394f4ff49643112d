//! `exo import` of a single CSV: a sine's frequency found when none is
//! given, the time column's unit and holes, and the files it writes (never
//! its input, never half of one). The simulated joint and the helpers are
//! `import.rs`'s.

use std::fmt::Write as _;
use std::path::Path;

use exo_tests::*;

use crate::import::{joint_csv, read, scratch, Noise, INERTIA};

/// A 20 s record at 1 kHz of a joint S_h = K − M ω² + j H (K = 30.08 Nm/rad,
/// M = 0.02 kg·m², H = 2.11 Nm/rad) under a single 2 rad/s sine, 1 % seeded
/// noise on angle and torque; times in s multiplied by `time_scale` (1000
/// for ms) and shifted by `hole_s` from the middle on. Returns the CSV text
/// and the true S_h at 2 rad/s.
fn sine_csv(time_scale: f64, hole_s: f64) -> (String, (f64, f64)) {
    const W: f64 = 2.0;
    let (k, h) = (30.08, 2.11);
    let (re, im) = (k - INERTIA * W * W, h);
    let (gain, arg) = ((re * re + im * im).sqrt(), im.atan2(re));
    let mut noise = Noise(0x5eed_2026);
    let amp = 0.05;
    let mut text = String::from("time_s,position_rad,torque_nm\n");
    for s in 0..20_000 {
        let t = s as f64 / 1000.0;
        let theta = amp * (W * t).sin() + 0.01 * amp * noise.normal();
        let tau = amp * gain * (W * t + arg).sin() + 0.01 * amp * gain * noise.normal();
        let shown = (t + if s >= 10_000 { hole_s } else { 0.0 }) * time_scale;
        writeln!(text, "{shown:.4},{theta:.7},{tau:.6}").unwrap();
    }
    (text, (re, im))
}

/// `exo fit --json`'s FRF points of one recording: (ω, Re S_h, Im S_h).
fn fitted_points(rec: &Path) -> Vec<(f64, f64, f64)> {
    let out = exo(&["fit", rec.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    v["subjects"][0]["experiments"][0]["points"]
        .as_array()
        .unwrap_or_else(|| panic!("no points: {v}"))
        .iter()
        .map(|p| {
            (
                p["omega"].as_f64().unwrap(),
                p["s_h"][0].as_f64().unwrap(),
                p["s_h"][1].as_f64().unwrap(),
            )
        })
        .collect()
}

/// The single point of `rec` is S_h = `want` at 2 rad/s, both within 2 %.
fn assert_sine_at_2(rec: &Path, want: (f64, f64)) {
    let points = fitted_points(rec);
    assert_eq!(points.len(), 1, "{points:?}");
    let (w, re, im) = points[0];
    assert!((w - 2.0).abs() < 0.02 * 2.0, "ω = {w} rad/s, not 2");
    let err = ((re - want.0).powi(2) + (im - want.1).powi(2)).sqrt();
    let size = (want.0 * want.0 + want.1 * want.1).sqrt();
    assert!(
        err < 0.02 * size,
        "S_h = {re} + {im}j, want {} + {}j",
        want.0,
        want.1
    );
}

#[test]
fn importing_a_csv_onto_itself_is_refused_and_leaves_it_unchanged() {
    let dir = scratch("self");
    let csv = dir.join("trial.csv");
    std::fs::write(&csv, joint_csv(30.0, 2.0, 3)).unwrap();
    let before = std::fs::read(&csv).unwrap();
    // The same path, and the same file by another name (a hard link).
    let link = dir.join("link.csv");
    std::fs::hard_link(&csv, &link).unwrap();
    for out_path in [&csv, &link] {
        let out = exo(&[
            "import",
            csv.to_str().unwrap(),
            "-o",
            out_path.to_str().unwrap(),
        ]);
        assert!(!out.status.success(), "{}", out_path.display());
        let e = stderr(&out);
        assert!(
            e.contains("is the input CSV") && e.contains("overwrite"),
            "{e}"
        );
        assert_eq!(std::fs::read(&csv).unwrap(), before, "the input changed");
    }
    // With --study: a recording whose name is one of the study's CSVs.
    std::fs::write(dir.join("S1-exp1.mcap"), joint_csv(30.0, 2.0, 4)).unwrap();
    let study = dir.join("study.toml");
    std::fs::write(
        &study,
        "subject = \"S1\"\n[[trial]]\nfile = \"S1-exp1.mcap\"\nexperiment = 1\n",
    )
    .unwrap();
    let before = std::fs::read(dir.join("S1-exp1.mcap")).unwrap();
    let out = exo(&[
        "import",
        "--study",
        study.to_str().unwrap(),
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("trial 1") && e.contains("overwrite"), "{e}");
    assert_eq!(std::fs::read(dir.join("S1-exp1.mcap")).unwrap(), before);
}

#[test]
fn a_single_sine_without_omega_is_labelled_at_its_frequency() {
    let dir = scratch("sine");
    let (text, want) = sine_csv(1.0, 0.0);
    let csv = dir.join("sine.csv");
    std::fs::write(&csv, text).unwrap();
    let rec = dir.join("sine.mcap");
    let out = exo(&["import", csv.to_str().unwrap(), "-o", rec.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("single sine"), "{}", stderr(&out));
    assert_eq!(read(&rec).meta("omega_detected"), Some("true"));
    assert_sine_at_2(&rec, want);
    // `exo fit` of the CSV itself gives the same.
    let out = exo(&["fit", csv.to_str().unwrap(), "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let w = v["subjects"][0]["experiments"][0]["points"][0]["omega"]
        .as_f64()
        .unwrap();
    assert!((w - 2.0).abs() < 0.04, "{w}");
}

#[test]
fn time_in_ms_is_refused_as_s_and_imported_with_time_unit_ms() {
    let dir = scratch("ms");
    let (text, want) = sine_csv(1000.0, 0.0);
    let csv = dir.join("sine_ms.csv");
    std::fs::write(&csv, text).unwrap();
    let rec = dir.join("sine_ms.mcap");
    let out = exo(&["import", csv.to_str().unwrap(), "-o", rec.to_str().unwrap()]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("1 Hz in s") && e.contains("--time-unit ms"),
        "{e}"
    );
    assert!(!rec.exists(), "a refused import wrote {}", rec.display());
    let out = exo(&[
        "import",
        csv.to_str().unwrap(),
        "--time-unit",
        "ms",
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("1000.0 Hz"), "{}", stderr(&out));
    assert_sine_at_2(&rec, want);
    // The study file's `time_unit`, at the top level.
    let study = dir.join("study.toml");
    std::fs::write(
        &study,
        "time_unit = \"ms\"\n[[trial]]\nfile = \"sine_ms.csv\"\nexperiment = 1\n",
    )
    .unwrap();
    let recs = dir.join("recs");
    let out = exo(&[
        "import",
        "--study",
        study.to_str().unwrap(),
        "-o",
        recs.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_sine_at_2(&recs.join("imported-exp1.mcap"), want);
    // A unit that is not s, ms or us is refused by name.
    let out = exo(&[
        "import",
        csv.to_str().unwrap(),
        "--time-unit",
        "min",
        "-o",
        "x.mcap",
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--time-unit"), "{}", stderr(&out));
}

#[test]
fn a_hole_in_the_time_column_is_refused_naming_its_line_and_size() {
    let dir = scratch("hole");
    let (text, _) = sine_csv(1.0, 100.0);
    let csv = dir.join("hole.csv");
    std::fs::write(&csv, text).unwrap();
    let rec = dir.join("hole.mcap");
    let out = exo(&["import", csv.to_str().unwrap(), "-o", rec.to_str().unwrap()]);
    assert!(!out.status.success());
    let e = stderr(&out);
    // Sample 10 000 is on line 10 002 (the header is line 1).
    assert!(
        e.contains("line 10002")
            && e.contains("from 9.999 to 110")
            && e.contains("gap of 100 s")
            && e.contains("split"),
        "{e}"
    );
    assert!(!rec.exists());
    // `exo fit` of the CSV refuses it alike.
    let out = exo(&["fit", csv.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("line 10002"), "{}", stderr(&out));
}

#[test]
fn a_failed_import_leaves_the_earlier_recording_intact() {
    let dir = scratch("atomic");
    let (text, _) = sine_csv(1.0, 0.0);
    let csv = dir.join("sine.csv");
    std::fs::write(&csv, &text).unwrap();
    let rec = dir.join("sine.mcap");
    std::fs::write(&rec, b"an earlier recording").unwrap();
    // A bad cell halfway through: refused, the earlier file as it was.
    let mut bad = text.clone();
    let at = bad.match_indices('\n').nth(12_000).unwrap().0 + 1;
    bad.insert_str(at, "12.0,oops,1.0\n");
    let bad_csv = dir.join("bad.csv");
    std::fs::write(&bad_csv, bad).unwrap();
    let out = exo(&[
        "import",
        bad_csv.to_str().unwrap(),
        "-o",
        rec.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("not a number"), "{}", stderr(&out));
    assert_eq!(std::fs::read(&rec).unwrap(), b"an earlier recording");
    let leftovers = |d: &Path| -> Vec<String> {
        std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".tmp"))
            .collect()
    };
    assert!(leftovers(&dir).is_empty(), "{:?}", leftovers(&dir));
    // A good import replaces it, mode 0640 (or stricter).
    let out = exo(&["import", csv.to_str().unwrap(), "-o", rec.to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    read(&rec);
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(&rec).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode & !0o640, 0, "mode {mode:o}");
    // A directory without write permission: refused naming the path and
    // the OS error, the earlier file intact, nothing left behind.
    let ro = dir.join("read-only");
    std::fs::create_dir_all(&ro).unwrap();
    let target = ro.join("sine.mcap");
    std::fs::write(&target, b"kept").unwrap();
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o500)).unwrap();
    let out = exo(&[
        "import",
        csv.to_str().unwrap(),
        "-o",
        target.to_str().unwrap(),
    ]);
    // SAFETY: geteuid has no preconditions.
    let root = unsafe { libc::geteuid() } == 0;
    if root {
        eprintln!(
            "running as root: permissions are not enforced, so the refusal of a read-only \
             directory is not checked here"
        );
    } else {
        assert!(!out.status.success());
        let e = stderr(&out);
        assert!(
            e.contains(target.to_str().unwrap()) && e.contains("Permission denied"),
            "{e}"
        );
    }
    std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o700)).unwrap();
    if !root {
        assert_eq!(std::fs::read(&target).unwrap(), b"kept");
    }
    assert!(leftovers(&ro).is_empty(), "{:?}", leftovers(&ro));
}
