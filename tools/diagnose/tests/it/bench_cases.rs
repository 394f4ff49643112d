//! The bench's cases (`exo diagnose-bench`): a null case's true plant is its
//! nominal plant, and the viscous human matches the hysteretic one at the
//! coupled resonance, checked against the numbers worked by hand.

use crate::common;

use exo_config::{Subject, SubjectExperiment};
use exo_diagnose::bench::cases;

/// Two experiments: mean K_h = (100 + 200)/2 = 150 Nm/rad, mean H_h =
/// (10 + 30)/2 = 20 Nm/rad.
fn subject() -> Subject {
    let e = |number, k, h| SubjectExperiment {
        number,
        stiffness_nm_per_rad: k,
        hysteretic_damping_nm_per_rad: h,
    };
    Subject {
        name: "bench".into(),
        inertia_kg_m2: 0.11,
        experiment: vec![e(1, 100.0, 10.0), e(2, 200.0, 30.0)],
        reported_power_law: None,
    }
}

#[test]
fn the_viscous_null_case_has_the_same_viscous_human_in_truth_and_nominal() {
    let s = subject();
    let all = cases();
    let case = all
        .iter()
        .find(|c| c.name == "null-viscous")
        .expect("a null-viscous case");
    assert!(case.expected.is_empty(), "a null case expects nothing");
    let base = common::default_plant();
    let (mut truth, mut nominal) = (base, base);
    (case.truth)(&mut truth, &s, 1.0);
    (case.nominal)(&mut nominal, &s);

    // By hand, configs/plants/default.toml: M_h 0.11, arm 0.1 kg·m², 4.5 kg
    // at 0.45 m: I = 0.11 + 0.1 + 4.5·0.45² = 1.12125 kg·m²;
    // ω_r = √(150/1.12125) = 11.566298639 rad/s; B = H/ω_r = 20/ω_r
    // = 1.729161646579 Nm·s/rad (python3: 20/math.sqrt(150/1.12125)).
    let b_hand = 1.729_161_646_579;
    for (what, m) in [("truth", &truth), ("nominal", &nominal)] {
        assert!(
            !m.human.hysteretic_damping.enabled,
            "{what}: the hysteretic damping is replaced"
        );
        assert!(m.human.viscous_damping.enabled, "{what}: a viscous human");
        let b = m.human.viscous_damping.b_nm_s_per_rad;
        assert!(
            (b - b_hand).abs() < 1e-9 * b_hand,
            "{what}: B_h = {b}, by hand {b_hand}"
        );
    }
    assert_eq!(truth, nominal, "a null case's truth is its nominal model");
}

#[test]
fn the_hysteresis_case_hides_the_subjects_hysteresis_behind_the_tuned_viscous_model() {
    let s = subject();
    let all = cases();
    let case = all
        .iter()
        .find(|c| c.name == "hysteresis")
        .expect("a hysteresis case");
    let base = common::default_plant();
    let (mut truth, mut nominal) = (base, base);
    (case.truth)(&mut truth, &s, 1.0);
    (case.nominal)(&mut nominal, &s);
    assert_eq!(truth, base, "the truth is the default, hysteretic, plant");
    assert!(truth.human.hysteretic_damping.enabled);
    assert!(!nominal.human.hysteretic_damping.enabled);
    assert!((nominal.human.viscous_damping.b_nm_s_per_rad - 1.729_161_646_579).abs() < 1e-9);
}
