//! `exo reproduce` (the paper's modelling study simulated) through the real
//! processes: one subject, all nine experiments of Table I, ten periods
//! each. The test reads the subject file itself and checks the recovered M2
//! parameters against it, then checks that the comparison does fail when
//! the inputs it compares with are not the ones simulated, and that `exo
//! diagnose` finds the hysteretic damping a viscous model leaves out.

use exo_config::Subject;
use exo_tests::*;
use serde_json::Value;

fn scratch(tag: &str) -> ScratchDir {
    exo_tests::scratch_dir(&format!("repro-{tag}"))
}

#[test]
fn subject_b_is_recovered_and_a_wrong_input_is_caught() {
    let dir = scratch("b");
    let out = exo(&[
        "reproduce",
        "--subjects",
        "B",
        "-o",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "exo reproduce failed:\n{}\n{}",
        stdout(&out),
        stderr(&out)
    );
    let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["failures"].as_array().unwrap().len(), 0, "{v:#}");

    // Independent check against the subject file: nine experiments, M2's K
    // and H within 5 %.
    let b = Subject::from_file(&configs_dir().join("subjects/B.toml")).unwrap();
    let sub = &v["subjects"][0];
    assert_eq!(sub["subject"], "B");
    let rows = sub["experiments"].as_array().unwrap();
    assert_eq!(rows.len(), 9);
    for row in rows {
        let n = row["experiment"].as_u64().unwrap() as u32;
        let input = b.get(n).unwrap();
        let k = row["k_fit"].as_f64().unwrap();
        let h = row["h_fit"].as_f64().unwrap();
        assert!(
            (k / input.stiffness_nm_per_rad - 1.0).abs() < 0.05,
            "experiment {n}: K {k} against {}",
            input.stiffness_nm_per_rad
        );
        assert!(
            (h / input.hysteretic_damping_nm_per_rad - 1.0).abs() < 0.05,
            "experiment {n}: H {h} against {}",
            input.hysteretic_damping_nm_per_rad
        );
    }
    let f = &sub["f_m1_m3"];
    assert!(f["statistic"].as_f64().unwrap() > f["critical"].as_f64().unwrap());
    assert_eq!(sub["phase"].as_array().unwrap().len(), 3);

    // The same recording compared with inputs that were not simulated
    // (experiment 4's K raised by 8 %) must miss the criterion, by name.
    let text = std::fs::read_to_string(configs_dir().join("subjects/B.toml")).unwrap();
    let wrong = text.replacen(
        "stiffness_nm_per_rad = 45.01",
        "stiffness_nm_per_rad = 48.61",
        1,
    );
    assert_ne!(wrong, text, "experiment 4's K of subject B moved");
    let other = scratch("b-wrong");
    let wrong_file = other.join("B.toml");
    std::fs::write(&wrong_file, wrong).unwrap();
    let out = exo(&[
        "reproduce",
        "--fit-only",
        "--subjects",
        wrong_file.to_str().unwrap(),
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let text = stdout(&out);
    assert!(
        text.contains("subject B experiment 4: K_h off by"),
        "{text}\n{}",
        stderr(&out)
    );

    // Issue 5 item 5: the mismatch finder, starting from the paper's viscous
    // M1 elbow, names hysteretic damping in the same recording and recovers
    // the simulated H of every experiment.
    let out = exo(&[
        "diagnose",
        "--json",
        "--model",
        configs_dir().join("plants/elbow-m1.toml").to_str().unwrap(),
        dir.join("B.mcap").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let d: Value = serde_json::from_str(&stdout(&out)).unwrap();
    let named: Vec<&str> = d["found"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["term"].as_str().unwrap())
        .collect();
    assert_eq!(named, ["hysteretic_damping"], "{:#}", d["verdict"]);
    for e in &b.experiment {
        let h = d["final_physics"]["h"][e.number.to_string()]
            .as_f64()
            .unwrap();
        assert!(
            (h / e.hysteretic_damping_nm_per_rad - 1.0).abs() < 0.05,
            "experiment {}: diagnosed H {h} against {}",
            e.number,
            e.hysteretic_damping_nm_per_rad
        );
    }
}
