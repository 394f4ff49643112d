//! `exo design` end to end: the real binary, its JSON contract, its errors.

use exo_impedance::design::{design, DesignInputs};
use exo_tests::{exo, stderr, stdout};
use serde_json::Value;

fn json(args: &[&str]) -> Value {
    let o = exo(args);
    assert!(o.status.success(), "exo {args:?} failed: {}", stderr(&o));
    serde_json::from_str(&stdout(&o)).expect("one JSON object on stdout")
}

#[test]
fn json_has_the_contract_keys_and_agrees_with_the_library() {
    let v = json(&[
        "design", "--kp", "3.2", "--f", "0.44", "--beta0", "-0.21", "--beta1", "1.03", "--json",
    ]);
    for key in ["kp", "omega_gc", "kf", "f", "phase_margin_deg", "predicted"] {
        assert!(v.get(key).is_some(), "missing key {key}");
    }
    assert!(v["phase_margin_deg"]["k_min"].is_f64() && v["phase_margin_deg"]["k_max"].is_f64());
    let mut inputs = DesignInputs::paper_defaults();
    inputs.kp = Some(3.2);
    inputs.f = Some(0.44);
    inputs.power_law = Some(exo_impedance::PowerLaw::new(-0.21, 1.03).unwrap());
    let d = design(&inputs).unwrap();
    assert_eq!(v["kp"].as_f64(), Some(3.2));
    assert_eq!(v["f"].as_f64(), Some(0.44));
    assert_eq!(v["kf"].as_f64(), Some(d.kf));
    let pred = v["predicted"].as_array().unwrap();
    assert_eq!(pred.len(), 2);
    for (p, q) in pred.iter().zip(&d.predicted) {
        assert_eq!(p["omega"].as_f64(), Some(q.omega));
        assert_eq!(p["magnitude"].as_f64(), Some(q.magnitude));
        assert_eq!(p["phase_deg"].as_f64(), Some(q.phase_deg));
    }
    let margins = d.margins.unwrap();
    assert_eq!(
        v["phase_margin_deg"]["k_min"].as_f64(),
        margins[0].analysis.min_phase_margin_deg
    );
    assert_eq!(v["discrete"]["sections"].as_array().unwrap().len(), 5);
}

#[test]
fn eq_f_design_from_a_power_law_and_margin() {
    let v = json(&[
        "design",
        "--beta0",
        "-0.23",
        "--beta1",
        "0.90",
        "--phase-margin-deg",
        "10.8",
        "--json",
    ]);
    // eq. f with β1 < 1 uses K̄ = 108.33: f = (atan(10^β0 K̄^(β1−1)) − φ)/90.
    let c = 10f64.powf(-0.23) * 108.33f64.powf(0.90 - 1.0);
    let expected = (c.atan().to_degrees() - 10.8) / 90.0;
    assert!((v["f"].as_f64().unwrap() - expected).abs() < 1e-12);
    assert_eq!(v["f_source"], "eq_f");
    assert_eq!(format!("{:.2}", v["kp"].as_f64().unwrap()), "3.19");
}

#[test]
fn human_output_names_every_section() {
    let o = exo(&[
        "design",
        "--f",
        "0.6",
        "--kp",
        "3.2",
        "--loss-factor",
        "0.45",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = stdout(&o);
    for needle in [
        "kp",
        "ω̂_gc",
        "kf",
        "pole (rad/s)",
        "b0",
        "phase margin",
        "|τs/τc|",
    ] {
        assert!(s.contains(needle), "missing {needle:?} in:\n{s}");
    }
}

#[test]
fn without_a_loss_factor_margins_are_reported_missing_not_invented() {
    let v = json(&["design", "--f", "0.3", "--json"]);
    assert!(v["phase_margin_deg"]["k_min"].is_null());
    let o = exo(&["design", "--f", "0.3"]);
    assert!(stdout(&o).contains("not computed"));
}

#[test]
fn plot_writes_an_svg_with_margins_marked() {
    let dir = std::env::temp_dir().join(format!("exo-design-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bode.svg");
    let o = exo(&[
        "design",
        "--f",
        "0.44",
        "--kp",
        "3.2",
        "--beta0",
        "-0.21",
        "--beta1",
        "1.03",
        "--plot",
        file.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let svg = std::fs::read_to_string(&file).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.contains("PM "),
        "not an SVG with margins"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_input_is_refused_naming_the_argument() {
    for (args, needle) in [
        (vec!["design", "--f", "0.3", "--me", "nan"], "--me"),
        (vec!["design", "--f", "0.3", "--mh", "-0.1"], "--mh"),
        (vec!["design", "--f", "0.3", "--k-min", "inf"], "--k-min"),
        (
            vec!["design", "--f", "0.3", "--k-min", "100", "--k-max", "10"],
            "--k-min",
        ),
        (vec!["design", "--f", "1.2"], "--f"),
        (vec!["design", "--f", "0"], "--f"),
        (vec!["design", "--f", "0.3", "--rpp", "1"], "--rpp"),
        (vec!["design", "--f", "0.3", "--filters", "0"], "--filters"),
        (vec!["design", "--beta0", "-0.23"], "--beta1"),
        (vec!["design"], "fractional order is undetermined"),
        (
            vec![
                "design",
                "--beta0",
                "-0.23",
                "--beta1",
                "0.9",
                "--phase-margin-deg",
                "40",
            ],
            "eq. f gives",
        ),
        (
            vec!["design", "--f", "0.3", "--p1", "200", "--rate-hz", "100"],
            "Nyquist",
        ),
    ] {
        let o = exo(&args);
        assert!(!o.status.success(), "exo {args:?} should fail");
        let err = stderr(&o);
        assert!(
            err.contains(needle),
            "exo {args:?}: error does not name {needle:?}: {err}"
        );
        assert!(!err.contains("panicked"), "exo {args:?} panicked: {err}");
        assert!(
            stdout(&o).is_empty(),
            "exo {args:?} printed a result despite the error"
        );
    }
}
