//! Unit tests of the engine's pieces: the words of a score, the "not named"
//! lines, a delay within one tick, and the signature rule.

use exo_plant_model::PlantModel;

use crate::data::{Condition, Dataset};
use crate::model::{Param, Physics};
use crate::terms::Term;

use super::checks::{longest_sample_period_s, per_tf_critical_z, within_a_tick};
use super::search::not_named;
use super::{Candidate, Score, Step, WindowCheck};

/// Why a misfit is no missing physics, in words: within the noise
/// (its test's p at or above the level), or beyond it by less than the
/// forward model's accuracy (the excess and the accuracy in %).
#[test]
fn a_misfit_within_the_noise_or_the_accuracy_is_said_so() {
    let score = |noise_p: f64| Score {
        per_tf: Vec::new(),
        rss: 1.0,
        heldout_rss: 1.0,
        chi2_per_dof: 1.14,
        lack_of_fit_p: 1.0,
        noise_p,
        excess: 0.0021,
        parameters: 3,
    };
    assert_eq!(
        score(0.2).within_words(0.05, "the rest"),
        "the rest is within the measured noise (χ²/dof 1.14, lack-of-fit p = 0.20)"
    );
    assert_eq!(
        score(0.01).within_words(0.05, "the model"),
        "the model is beyond the measured noise (χ²/dof 1.14, p = 1.0e-2) by 0.21 % of the values, within the forward model's accuracy (0.5 %)"
    );
    // At the level itself: not beyond.
    assert!(score(0.05)
        .within_words(0.05, "x")
        .starts_with("x is within"));
}

/// The verdict's "not named" lines: of the last step only, up to three
/// of each family tried there (four significant, rejected catalogue
/// terms and two such forms give 3 + 2 lines), never a chosen one, one
/// not significant or one without a reason.
#[test]
fn not_named_lists_three_of_each_family_of_the_last_step() {
    let cand = |term: Term, significant: bool, chosen: bool, why: &[&str]| Candidate {
        term,
        words: term.words(),
        added_parameters: 1,
        f: 10.0,
        f_critical: 5.0,
        p_value: 1e-3,
        p_holm: 1e-3,
        delta_aic: -5.0,
        heldout_change: -0.1,
        description: String::new(),
        identified: true,
        tf_checks: Vec::new(),
        within_window_check: None,
        harmonic_check: None,
        explained_share: 0.5,
        amplitude_check: None,
        significant,
        rejected_because: why.iter().map(|w| w.to_string()).collect(),
        untested: false,
        chosen,
        held_to_model_accuracy: false,
    };
    let catalogue = [
        Term::EncoderDelay,
        Term::CuffCompliance,
        Term::InertiaError,
        Term::GravityError,
    ];
    let step = |n: usize, forms: bool, c: Vec<Candidate>| Step {
        step: n,
        forms,
        candidates: c,
    };
    let steps = vec![
        // An earlier step: never listed.
        step(
            1,
            false,
            vec![cand(Term::SeaSensorGain, true, false, &["earlier"])],
        ),
        step(
            2,
            false,
            // The ones never listed first, so that the three taken
            // are the right three.
            [
                cand(Term::ActuatorDelay, true, true, &["chosen"]),
                cand(Term::CuffSensorGain, false, false, &["not significant"]),
                cand(Term::SeaSensorDelay, true, false, &[]),
            ]
            .into_iter()
            .chain(catalogue.iter().map(|&t| cand(t, true, false, &["why"])))
            .collect(),
        ),
        step(
            2,
            true,
            vec![
                cand(Term::CubicStiffness, true, false, &["harmonic"]),
                cand(Term::Backlash, true, false, &["amplitude"]),
            ],
        ),
    ];
    let lines = not_named(&steps);
    let want: Vec<String> = catalogue[..3]
        .iter()
        .map(|t| (t, "why"))
        .chain([
            (&Term::CubicStiffness, "harmonic"),
            (&Term::Backlash, "amplitude"),
        ])
        .map(|(t, why)| {
            format!(
                "not named: {} (F = 10.0, would explain 50 % of the misfit): {why}",
                t.words()
            )
        })
        .collect();
    assert_eq!(lines, want);
    assert!(not_named(&[]).is_empty());
}

/// A delay is timing only while every delay the term fits is shorter
/// than the recordings' longest sample period (two windows: 1 ms and
/// 2 ms ticks, so 2 ms is the bound); a term without a delay, or a
/// reflex's delay, is never timing.
#[test]
fn a_delay_is_timing_only_within_the_longest_tick() {
    let plant =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/plants/default.toml");
    let mut p = Physics::from_plant(&PlantModel::from_file(&plant).unwrap(), &[1]);
    let window = |dt: f64| Condition::test_window(0.0, 0.1, dt);
    let d = Dataset {
        conditions: vec![window(0.001), window(0.002)],
        ..Dataset::default()
    };
    assert_eq!(longest_sample_period_s(&d), 0.002);
    p.delay_s = [0.0, 0.0, 0.0, 0.00085];
    let words = within_a_tick(&d, Term::ActuatorDelay, &p).expect("within a tick");
    assert!(
        words.contains("0.85 ms") && words.contains("(2.0 ms)"),
        "{words}"
    );
    // A negative delay of the same size is as much within the tick.
    p.delay_s[3] = -0.00085;
    assert!(within_a_tick(&d, Term::ActuatorDelay, &p).is_some());
    // Beyond the longest tick (but within the shorter one's double).
    p.delay_s[3] = 0.0021;
    assert_eq!(within_a_tick(&d, Term::ActuatorDelay, &p), None);
    // Exactly one tick is not within it.
    p.delay_s[3] = 0.002;
    assert_eq!(within_a_tick(&d, Term::ActuatorDelay, &p), None);
    // Each catalogue delay reads its own parameter.
    p.delay_s = [0.0005, 0.003, 0.003, 0.003];
    assert!(within_a_tick(&d, Term::EncoderDelay, &p).is_some());
    assert_eq!(within_a_tick(&d, Term::CuffSensorDelay, &p), None);
    p.delay_s = [0.003, 0.0005, 0.003, 0.003];
    assert!(within_a_tick(&d, Term::CuffSensorDelay, &p).is_some());
    p.delay_s = [0.003, 0.003, 0.0005, 0.003];
    assert!(within_a_tick(&d, Term::SeaSensorDelay, &p).is_some());
    // A term with no delay, and a reflex (its delay is physiology).
    assert_eq!(within_a_tick(&d, Term::CuffCompliance, &p), None);
    p.reflex = [1.0, 0.0005, 15.0];
    assert_eq!(within_a_tick(&d, Term::StretchReflex, &p), None);
    assert!(Param::DelayAct.is_delay() && !Param::ReflexDelay.is_delay());
}

/// The signature rule with the numbers written out (z = 2): present
/// beyond the noise (`β > z·se`) and between half and twice the
/// predicted size; too small to check when even `β = 1` would not be
/// beyond the noise (`z·se ≥ 1`); contradicted when it moves the
/// prediction by a noise σ or more and `β < ½ − z·se`.
#[test]
fn a_signature_is_confirmed_present_and_at_its_predicted_size() {
    let check = |beta: f64, se: f64, moved: f64| WindowCheck::new("s", (moved, beta, se, 10), 2.0);
    // The rig's backlash (β = 0.83 ± 0.01) and 5 %/min drift (0.88 ± 0.22).
    for (b, se) in [(0.83, 0.01), (0.88, 0.22), (0.5, 0.2), (2.0, 0.1)] {
        let c = check(b, se, 100.0);
        assert!(c.confirms && c.testable && !c.contradicts, "{b} ± {se}");
    }
    // Present but too small, or far too large: not at its size.
    for (b, se) in [(0.45, 0.01), (2.05, 0.01)] {
        assert!(!check(b, se, 100.0).confirms, "{b} ± {se}");
    }
    // At its size but not beyond the noise: β = 0.8 ± 0.41 (z·se = 0.82).
    assert!(!check(0.8, 0.41, 100.0).confirms);
    // Testable up to z·se < 1.
    assert!(check(0.8, 0.49, 100.0).testable);
    assert!(!check(0.73, 0.54, 5.0).testable);
    // Contradicted: β = 0 ± 0.1 against ½ − 0.2; not below a σ moved.
    assert!(check(0.0, 0.1, 100.0).contradicts);
    assert!(!check(0.0, 0.1, 0.9).contradicts);
    assert!(!check(0.31, 0.1, 100.0).contradicts);
    assert!(check(0.29, 0.1, 100.0).contradicts);
}

/// The reason a form is not taken names its signature, the size it
/// predicted and what the data showed, in each of the three cases.
#[test]
fn a_signatures_words_say_what_was_predicted_and_seen() {
    let w = |beta: f64, se: f64| {
        WindowCheck::new("the 3rd harmonic of τ_c", (400.0, beta, se, 30), 2.0).words()
    };
    assert_eq!(
        w(0.0, 0.05),
        "the 3rd harmonic of τ_c it predicts (20.0 σ over 30 values) is not in the data: the data show 0 ± 5 % of it"
    );
    assert!(w(0.73, 0.54).contains("too small to check in these recordings (untested)"));
    assert!(w(0.4, 0.05).contains("not confirmed at its predicted size: the data show 40 ± 5 %"));
}

/// The per-transfer-function checks' critical value, Bonferroni over the
/// supported transfer functions: at level 0.01 over four, the normal
/// quantile of 1 − 0.0025, 2.807 (scipy.stats.norm.ppf(0.9975) =
/// 2.8070337683); over one, of 0.99, 2.326 (2.3263478740); none counts as
/// one.
#[test]
fn the_per_tf_checks_are_bonferroni_over_the_supported_transfer_functions() {
    assert!((per_tf_critical_z(0.01, 4) - 2.807_033_768_3).abs() < 1e-6);
    assert!((per_tf_critical_z(0.01, 1) - 2.326_347_874_0).abs() < 1e-6);
    assert_eq!(per_tf_critical_z(0.01, 0), per_tf_critical_z(0.01, 1));
}
