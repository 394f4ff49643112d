//! Stability in closed loop (the paper's tuning and post-tuning tests,
//! sections "Loop Shaping Experiments" and "Tuning Results"), through the
//! real processes in lockstep.
//!
//! The model's bound is computed here from the subject file with the science
//! core: the largest f with a non-negative phase margin at the subject's low
//! (experiment 1) and high (experiment 7) stiffness, with the 10 Hz SEA.
//! Above it the spring-release test must oscillate (sustained or growing) at
//! the least-damped stiffness; well below it the release must decay at both.
//! `exo tune` must then find the boundary within its resolution plus the
//! causal hysteresis model's own drift.

use exo_config::{RunConfig, Subject};
use exo_impedance::loop_shaping::{marginal_fractional_order, FractionalLayout};
use exo_impedance::{
    nominal_crossover, proportional_gain, AmplificationPlant, SeaModel, StiffnessRange,
};
use exo_tests::*;
use serde_json::Value;

/// The model's boundary at experiments 1 and 7 of `subject`.
fn model_bounds(subject: &str) -> [f64; 2] {
    let cfg = RunConfig::from_file(&configs_dir().join("default.toml")).unwrap();
    let s = Subject::from_file(&configs_dir().join(format!("subjects/{subject}.toml"))).unwrap();
    let load = cfg.experiment_table().get(1).unwrap().load_kg;
    let m_e = cfg.exo_inertia_kg_m2(load);
    let kp = proportional_gain(m_e, s.inertia_kg_m2).unwrap();
    let [lo, hi] = cfg.controller.k_range_nm_per_rad;
    let layout = FractionalLayout {
        kp,
        omega_gc_hat_rad_s: nominal_crossover(
            StiffnessRange::new(lo, hi).unwrap(),
            m_e,
            s.inertia_kg_m2,
        )
        .unwrap(),
        filters: cfg.controller.filters,
        p1_rad_s: cfg.controller.p1_rad_s,
        r_pp: cfg.controller.r_pp,
    };
    [1, 7].map(|n| {
        let e = s.get(n).unwrap();
        let plant = AmplificationPlant::new(
            m_e,
            s.inertia_kg_m2,
            e.stiffness_nm_per_rad,
            e.hysteretic_damping_nm_per_rad / e.stiffness_nm_per_rad,
            SeaModel::new(10.0, 0.7).unwrap(),
        )
        .unwrap();
        marginal_fractional_order(&layout, &[plant]).unwrap()
    })
}

fn tune_json(args: &[&str]) -> Value {
    let out = exo(args);
    assert!(
        out.status.success(),
        "exo {args:?} failed:\n{}",
        stderr(&out)
    );
    serde_json::from_str(&stdout(&out)).unwrap_or_else(|e| panic!("{e}: {}", stdout(&out)))
}

#[test]
fn above_the_model_bound_the_release_oscillates_below_it_it_decays() {
    // Subject B: β1 > 1, so the low stiffness is the least damped.
    let bounds = model_bounds("B");
    let (worst, bound) = if bounds[0] <= bounds[1] {
        (0, bounds[0])
    } else {
        (1, bounds[1])
    };
    let (above, below) = (bound + 0.1, bound - 0.15);
    let v = tune_json(&[
        "tune",
        "B",
        "--check",
        &format!("{above}"),
        "--check",
        &format!("{below}"),
        "--json",
    ]);
    let checks = v["checks"].as_array().unwrap();
    assert_eq!(checks.len(), 2);
    for (i, c) in checks.iter().enumerate() {
        let model = c["f_marginal_model"].as_f64().unwrap();
        assert!(
            (model - bounds[i]).abs() < 1e-9,
            "tool and test disagree on the model bound"
        );
        let trials = c["trials"].as_array().unwrap();
        let (hi, lo) = (&trials[0], &trials[1]);
        assert!(
            !lo["oscillates"].as_bool().unwrap(),
            "experiment {}: f = {below:.3} (model bound {model:.3}) should decay: {}",
            c["experiment"],
            lo["evidence"]
        );
        if i == worst {
            assert!(
                hi["oscillates"].as_bool().unwrap(),
                "experiment {}: f = {above:.3} (model bound {model:.3}) should oscillate: {}",
                c["experiment"],
                hi["evidence"]
            );
        }
    }
}

#[test]
fn exo_tune_finds_the_boundary_the_model_predicts() {
    let bounds = model_bounds("D");
    let v = tune_json(&[
        "tune",
        "D",
        "--step",
        "0.1",
        "--resolution",
        "0.05",
        "--json",
    ]);
    let measured = v["f_marginal"].as_f64().unwrap();
    let model = bounds[0].min(bounds[1]);
    assert!((v["f_marginal_model"].as_f64().unwrap() - model).abs() < 1e-9);
    // Bracket half-width 0.025, plus the Prony bank's frequency-dependent
    // real stiffness (Kramers–Kronig; see exo-plant-sim), which moves the
    // simulated boundary a little.
    assert!(
        (measured - model).abs() < 0.06,
        "measured boundary {measured:.3} vs model {model:.3}"
    );
    let tuned = v["f_tuned"].as_f64().unwrap();
    assert!((tuned - (measured - 0.12)).abs() < 1e-12);
    for c in v["cases"].as_array().unwrap() {
        let trials = c["trials"].as_array().unwrap();
        assert!(
            !trials[0]["oscillates"].as_bool().unwrap(),
            "f = 0 must be stable"
        );
        assert!(trials.iter().any(|t| t["oscillates"].as_bool().unwrap()));
    }
}

#[test]
fn exo_tune_rejects_bad_arguments_by_name() {
    let out = exo(&["tune", "B", "--step=-0.1"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("--step"), "{}", stderr(&out));
    let out = exo(&["tune", "Z"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("Z.toml"), "{}", stderr(&out));
}
