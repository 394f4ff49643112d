//! `exo diagnose` and `exo diagnose-bench` end to end: concealed effects
//! in recordings of the real processes, in recordings an independent Python
//! script wrote, and the real ankle recording; bad input refused by name.

use std::path::{Path, PathBuf};

use exo_tests::*;
use serde_json::Value;

fn scratch(tag: &str) -> ScratchDir {
    exo_tests::scratch_dir(&format!("diag-{tag}"))
}

/// The default plant with some of its text replaced, written to `dir`.
fn plant_variant(dir: &Path, name: &str, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(configs_dir().join("plants/default.toml")).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from:?} not in the default plant");
        text = text.replace(from, to);
    }
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn diagnose_json(model: &Path, recordings: &[&Path], extra: &[&str]) -> Value {
    let mut args = vec!["diagnose", "--json", "--model", model.to_str().unwrap()];
    args.extend(extra);
    for r in recordings {
        args.push(r.to_str().unwrap());
    }
    let out = exo(&args);
    assert!(
        out.status.success(),
        "exo diagnose failed:\n{}",
        stderr(&out)
    );
    serde_json::from_str(&stdout(&out)).unwrap()
}

fn found(v: &Value) -> Vec<String> {
    v["found"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["term"].as_str().unwrap().to_string())
        .collect()
}

/// `exo diagnose-bench --cases CASES -o DIR --json`, which must succeed.
fn bench_json(dir: &Path, cases: &str) -> Value {
    let out = exo(&[
        "diagnose-bench",
        "--cases",
        cases,
        "-o",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "exo diagnose-bench failed:\n{}\n{}",
        stdout(&out),
        stderr(&out)
    );
    serde_json::from_str(&stdout(&out)).unwrap()
}

/// A case whose true plant has no gravity is a horizontal rig: its run
/// file compensates none (`rig.gravity_m_s2 = 0`), the SEA's torque
/// reverses where no bias holds it, and the backlash form finds the lost
/// motion; the horizontal null case gets nothing.
#[test]
fn the_bench_runs_a_horizontal_rig_and_finds_its_backlash() {
    let dir = scratch("bench-horizontal");
    let v = bench_json(&dir, "backlash-horizontal-wide,null-horizontal");
    let cases = v.as_array().unwrap();
    assert_eq!(cases[0]["named"], serde_json::json!(["backlash"]), "{v:#}");
    assert_eq!(cases[1]["named"], serde_json::json!([]), "{v:#}");
    for case in ["backlash-horizontal-wide", "null-horizontal"] {
        let run = std::fs::read_to_string(dir.join(format!("{case}.toml"))).unwrap();
        assert!(run.contains("gravity_m_s2 = 0.0"), "{case}:\n{run}");
    }
}

/// The drive's torque limit (issue 30, item 6) on our simulator, through
/// the real processes, at two sizes: 28 Nm clips the peaks of experiment
/// 7's larger amplitude, 26.5 Nm every period of it. Each is named alone,
/// within 0.2 % of the true limit, with the rest within the noise, and
/// written into the updated plant, which the simulator accepts.
#[test]
fn the_bench_names_the_drives_torque_limit_at_two_sizes() {
    let dir = scratch("bench-saturation");
    let v = bench_json(&dir, "saturation,saturation-deep");
    let cases = v.as_array().unwrap();
    for (case, truth_nm) in cases.iter().zip([28.0_f64, 26.5]) {
        assert_eq!(
            case["named"],
            serde_json::json!(["actuator_saturation"]),
            "{v:#}"
        );
        let name = case["case"].as_str().unwrap();
        let updated = exo_plant_model::PlantModel::from_file(
            &dir.join(format!("{name}-diagnosis/updated-plant.toml")),
        )
        .unwrap();
        let truth = exo_plant_model::PlantModel::from_file(&dir.join(format!("{name}-truth.toml")))
            .unwrap();
        assert_eq!(truth.sea.torque_limit_nm, truth_nm);
        let found = updated.sea.torque_limit_nm;
        assert!(
            (found - truth_nm).abs() < 0.002 * truth_nm,
            "{name}: found {found} Nm, true {truth_nm} Nm"
        );
        // With the limit the rest is within the noise (started from the
        // refitted model alone, the deep case stopped at 26.63 Nm with
        // structure remaining: `Term::refits_from_nominal`).
        let verdict = case["verdict"].to_string();
        assert!(
            verdict.contains("the rest is within the measured noise"),
            "{name}: {verdict}"
        );
    }
}

/// A posture offset (issue 30, item 5) on our simulator, through the real
/// processes: the subject's neutral angle 0.05 rad above the model's is
/// located in every experiment and nothing is named; a subject that holds
/// its goal against the bias (the rig's strategy, simulated) with a model
/// that says so locates nothing: its arm rests at the goal within 0.005 rad
/// at every bias.
#[test]
fn the_bench_locates_a_posture_offset_and_names_nothing() {
    let dir = scratch("bench-posture");
    let v = bench_json(&dir, "posture-shift,null-holds-goal");
    let cases = v.as_array().unwrap();
    for case in cases {
        assert_eq!(case["named"], serde_json::json!([]), "{v:#}");
    }
    let equilibrium = |name: &str| -> Value {
        let text =
            std::fs::read_to_string(dir.join(format!("{name}-diagnosis/diagnosis.json"))).unwrap();
        serde_json::from_str::<Value>(&text).unwrap()["equilibrium"].clone()
    };
    let shifted = equilibrium("posture-shift");
    assert_eq!(shifted["quantity"], "the subject's neutral angle");
    let holding = equilibrium("null-holds-goal");
    assert_eq!(holding["quantity"], "the arm's mean angle");
    for (e, truth) in [(shifted, 0.05), (holding, 0.0)] {
        let rows = e["experiments"].as_array().unwrap();
        assert_eq!(rows.len(), 3, "{e:#}");
        for r in rows {
            let d = r["difference_rad"].as_f64().unwrap();
            assert!((d - truth).abs() < 0.005, "{r:#}");
            assert_eq!(r["differs"], serde_json::json!(truth != 0.0), "{r:#}");
        }
    }
}

#[test]
fn the_bench_names_a_concealed_gravity_error_and_nothing_in_a_null_case() {
    let dir = scratch("bench");
    let v = bench_json(&dir, "gravity,null-params");
    let cases = v.as_array().unwrap();
    assert_eq!(cases.len(), 2);
    assert_eq!(cases[0]["case"], "gravity");
    assert_eq!(
        cases[0]["named"],
        serde_json::json!(["gravity_error"]),
        "{v:#}"
    );
    assert!(cases[0]["heldout_change"].as_f64().unwrap() < -0.5, "{v:#}");
    assert_eq!(cases[1]["case"], "null-params");
    assert_eq!(cases[1]["named"], serde_json::json!([]), "{v:#}");
    // The report and the updated model were written, and the updated model
    // is a plant model the simulator accepts, with the gravity it found.
    let d = dir.join("gravity-diagnosis");
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(
        html.matches("<svg").count() >= 3,
        "Bode overlays and a time overlay"
    );
    let updated = exo_plant_model::PlantModel::from_file(&d.join("updated-plant.toml")).unwrap();
    let nominal =
        exo_plant_model::PlantModel::from_file(&dir.join("gravity-nominal.toml")).unwrap();
    let truth = exo_plant_model::PlantModel::from_file(&dir.join("gravity-truth.toml")).unwrap();
    let found_mass = updated.gravity.arm_mass_kg;
    let (n, t) = (nominal.gravity.arm_mass_kg, truth.gravity.arm_mass_kg);
    assert!(
        (found_mass - t).abs() < 0.25 * (t - n),
        "arm mass: nominal {n}, true {t}, found {found_mass}"
    );
}

#[test]
fn a_python_written_recording_with_a_sensor_delay_and_complex_stiffness_is_diagnosed() {
    let dir = scratch("py");
    let write = |name: &str, extra: &[&str]| {
        let rec = dir.join(name);
        stdout_of(
            python_script("write_recording.py")
                .arg(&rec)
                .args(["--k", "40", "--c", "0.4", "--noise", "0.02"])
                .args(extra),
        );
        rec
    };
    let clean = write("clean.mcap", &[]);
    let delayed = write("delayed.mcap", &["--tau-c-delay-ms", "5"]);
    // The script's world has no gravity (τ_gravity = 0, τ_s balances τ_c).
    let grav_off = [("[gravity]\nenabled = true", "[gravity]\nenabled = false")];
    let hysteretic = plant_variant(&dir, "hysteretic.toml", &grav_off);
    let viscous = plant_variant(
        &dir,
        "viscous.toml",
        &[
            grav_off[0],
            (
                "[human.hysteretic_damping]     # complex stiffness K(1 + jc)\nenabled = true",
                "[human.hysteretic_damping]\nenabled = false",
            ),
            (
                "[human.viscous_damping]\nenabled = false",
                "[human.viscous_damping]\nenabled = true",
            ),
        ],
    );
    // The right model: nothing is missing.
    let v = diagnose_json(&hysteretic, &[&clean], &[]);
    assert!(found(&v).is_empty(), "{:#}", v["verdict"]);
    // A 5 ms delay of the cuff torque.
    let v = diagnose_json(&hysteretic, &[&delayed], &[]);
    assert_eq!(found(&v), ["cuff_sensor_delay"], "{:#}", v["verdict"]);
    let d = v["final_physics"]["delay_s"][1].as_f64().unwrap();
    assert!((d - 0.005).abs() < 0.0005, "delay {d}");
    // The paper's finding on someone else's data: a viscous model misses
    // hysteretic damping, H = cK = 16 Nm/rad.
    let v = diagnose_json(&viscous, &[&clean], &[]);
    assert_eq!(found(&v), ["hysteretic_damping"], "{:#}", v["verdict"]);
    let h = v["final_physics"]["h"]["1"].as_f64().unwrap();
    assert!((h - 16.0).abs() < 0.5, "H = {h}");
}

#[test]
fn the_real_ankle_recording_is_diagnosed_against_an_m1_model() {
    let dir = scratch("ankle");
    let rec = import_ankle(&dir);
    let model = configs_dir().join("plants/ankle-m1.toml");
    let v = diagnose_json(&model, &[&rec], &[]);
    // Only τ/θ exists in a position-perturbation record.
    assert_eq!(v["supported"], serde_json::json!(["S_h"]));
    assert!(v["location"]["nominal_cells"].as_array().unwrap().len() >= 2);
    // What it finds, it says in words, with the fit before and after.
    assert!(!v["verdict"].as_array().unwrap().is_empty());
    // README ("Finding what a model leaves out"): first a stretch reflex,
    // G = 6.7 ± 1.1 Nm·s/rad, δ = 62 ± 3 ms, ω_c = 9.9 ± 1.0 rad/s (F = 47
    // against 4.6, held-out −19 %); then hysteretic damping H = 9.4 ± 3.3
    // Nm/rad, c = 0.10 (F = 8.6 against a Holm-corrected 7.0, held-out
    // −28 %), which the tool itself reports as partial (it explains 27 %
    // of the misfit left at its step); R² 0.78 → 0.97, χ²/dof 25 → 4.1.
    // Each figure to the precision README prints it.
    let f = v["found"].as_array().unwrap();
    assert_eq!(
        found(&v),
        ["stretch_reflex", "hysteretic_damping"],
        "{:#}",
        v["verdict"]
    );
    let reflex = &v["final_physics"]["reflex"];
    let (g, delay_s, omega_c) = (
        reflex[0].as_f64().unwrap(),
        reflex[1].as_f64().unwrap(),
        reflex[2].as_f64().unwrap(),
    );
    // The stated band: a human ankle's stretch-reflex delay, 40–60 ms for
    // the reflex's onset as reported for the ankle, lengthened by the
    // low-pass (README), so 40–80 ms; the gain positive (a velocity
    // feedback that resists stretch) and determined (its 1σ error under a
    // fifth of it); and README's values within their stated ±.
    assert!((0.040..=0.080).contains(&delay_s), "δ = {delay_s} s");
    let desc = f[0]["description"].as_str().unwrap();
    let pm = |name: &str| -> (f64, f64) {
        let rest = desc.split(&format!("{name} = ")).nth(1).unwrap();
        let mut it = rest.split_whitespace();
        let value: f64 = it.next().unwrap().parse().unwrap();
        assert_eq!(it.next(), Some("±"), "{desc}");
        let se: f64 = it.next().unwrap().trim_end_matches(',').parse().unwrap();
        (value, se)
    };
    let (g_printed, g_se) = pm("G");
    assert!(g > 0.0 && g_se < 0.2 * g, "G = {g} ± {g_se}");
    assert!((g - g_printed).abs() < 0.01, "{desc}");
    assert!((g - 6.7).abs() <= 1.1, "G = {g}: README 6.7 ± 1.1");
    assert!(
        (delay_s * 1e3 - 62.0).abs() <= 3.0,
        "δ = {delay_s}: README 62 ± 3 ms"
    );
    assert!(
        (omega_c - 9.9).abs() <= 1.0,
        "ω_c = {omega_c}: README 9.9 ± 1.0"
    );
    let printed = |value: f64, p: &str, what: &str| {
        let decimals = p.split('.').nth(1).map_or(0, str::len);
        let half = 0.5 * 10f64.powi(-(decimals as i32));
        let want: f64 = p.parse().unwrap();
        assert!(
            (value - want).abs() <= half * (1.0 + 1e-9),
            "{what}: {value}, README {p}"
        );
    };
    printed(g, "6.7", "G");
    printed(g_se, "1.1", "G's error");
    printed(delay_s * 1e3, "62", "δ (ms)");
    printed(pm("δ").1, "3", "δ's error (ms)");
    printed(omega_c, "9.9", "ω_c");
    printed(pm("ω_c").1, "1.0", "ω_c's error");
    let num = |x: &Value, k: &str| x[k].as_f64().unwrap();
    printed(num(&f[0], "f"), "47", "the reflex's F");
    printed(num(&f[0], "f_critical"), "4.6", "its critical value");
    printed(
        num(&f[0], "heldout_change") * 100.0,
        "-19",
        "its held-out change (%)",
    );
    assert_eq!(f[0]["partial"], false);
    assert_eq!(f[0]["marginal"], false, "{:#}", f[0]);
    let h = v["final_physics"]["h"]["1"].as_f64().unwrap();
    printed(h, "9.4", "H");
    printed(
        h / v["final_physics"]["k"]["1"].as_f64().unwrap(),
        "0.10",
        "c = H/K",
    );
    printed(num(&f[1], "f"), "8.6", "the hysteresis's F");
    printed(
        num(&f[1], "f_critical"),
        "7.0",
        "its Holm-corrected critical value",
    );
    printed(
        num(&f[1], "heldout_change") * 100.0,
        "-28",
        "its held-out change (%)",
    );
    // Marginal (F 8.6 against 7.0, explaining a quarter of what was left):
    // reported by the tool itself as marginal (Holm-adjusted p ≥ 0.001)
    // and as partial, not as a finding on its own.
    assert_eq!(f[1]["marginal"], true, "{:#}", f[1]);
    assert!(
        f[1]["sentence"]
            .as_str()
            .unwrap()
            .contains("marginal: not significant at 0.001"),
        "{:#}",
        f[1]
    );
    assert_eq!(f[1]["partial"], true, "{:#}", f[1]);
    assert!(
        f[1]["sentence"]
            .as_str()
            .unwrap()
            .starts_with("partly explained by hysteretic damping"),
        "{:#}",
        f[1]
    );
    printed(
        v["refit"]["per_tf"][0]["r2"].as_f64().unwrap(),
        "0.78",
        "refit R²",
    );
    printed(
        v["final_score"]["per_tf"][0]["r2"].as_f64().unwrap(),
        "0.97",
        "final R²",
    );
    printed(
        v["refit"]["chi2_per_dof"].as_f64().unwrap(),
        "25",
        "refit χ²/dof",
    );
    printed(
        v["final_score"]["chi2_per_dof"].as_f64().unwrap(),
        "4.1",
        "final χ²/dof",
    );
    let r2 = v["final_score"]["per_tf"][0]["r2"].as_f64().unwrap();
    let r2_refit = v["refit"]["per_tf"][0]["r2"].as_f64().unwrap();
    assert!(r2 >= r2_refit - 1e-9 && r2 <= 1.0, "R² {r2_refit} → {r2}");
    // Anything it adds must also predict the held-out bands better.
    let ho = v["final_score"]["heldout_rss"].as_f64().unwrap();
    let ho_refit = v["refit"]["heldout_rss"].as_f64().unwrap();
    assert!(ho <= ho_refit * (1.0 + 1e-9), "held-out {ho_refit} → {ho}");
    eprintln!("ankle: {:#}", v["verdict"]);
}

#[test]
fn bad_input_is_refused_by_name() {
    let dir = scratch("bad");
    let rec = dir.join("nothing.mcap");
    let out = exo(&[
        "diagnose",
        "--model",
        dir.join("missing.toml").to_str().unwrap(),
        rec.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("missing.toml"), "{}", stderr(&out));
    let out = exo(&[
        "diagnose",
        "--model",
        configs_dir().join("plants/default.toml").to_str().unwrap(),
        rec.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("nothing.mcap"), "{}", stderr(&out));
    let bad_plant = plant_variant(&dir, "bad.toml", &[("delay_s = 0.0", "delay_s = nan")]);
    let out = exo(&[
        "diagnose",
        "--model",
        bad_plant.to_str().unwrap(),
        rec.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("bad.toml"), "{}", stderr(&out));
    let out = exo(&[
        "diagnose",
        "--level",
        "2",
        "--model",
        configs_dir().join("plants/default.toml").to_str().unwrap(),
        rec.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--level"), "{}", stderr(&out));
    let out = exo(&["diagnose-bench", "--cases", "nonsense"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("nonsense"), "{}", stderr(&out));
}

/// The false-alarm bench (`--nulls N`) through the CLI on the independent
/// rig's first two generators (a viscous and a two-point human, seeds 0
/// and 1): each null is diagnosed and reported under its generator, and
/// nothing is named (the 108- and 216-null runs are in docs/diagnose.md
/// §5). Bad arguments are refused by name.
#[test]
fn the_null_bench_reports_each_generator_and_names_nothing() {
    let dir = scratch("nulls");
    let out = exo(&[
        "diagnose-bench",
        "--nulls",
        "2",
        "--generators",
        "rig",
        "-o",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
    let nulls = v.as_array().unwrap();
    let generators: Vec<&str> = nulls
        .iter()
        .map(|n| n["generator"].as_str().unwrap())
        .collect();
    assert_eq!(generators, ["rig viscous human", "rig two-point human"]);
    for n in nulls {
        assert_eq!(n["named"], serde_json::json!([]), "{n:#}");
        assert!(n["chi2_per_dof"].as_f64().unwrap() > 0.0, "{n:#}");
    }
    for (args, names) in [
        (&["--nulls", "2", "--generators", "rigs"][..], "\"rigs\""),
        (&["--nulls", "0"][..], "--nulls 0"),
    ] {
        let out = exo(&[&["diagnose-bench"][..], args].concat());
        assert!(!out.status.success(), "{args:?} accepted");
        assert!(stderr(&out).contains(names), "{args:?}: {}", stderr(&out));
    }
}
