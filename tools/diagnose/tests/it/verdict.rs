//! The verdict's "same physics, other parameters": a refitted parameter is
//! named as moved when its change exceeds twice its relative standard
//! error, and at least 2 % (the rule, applied here to the diagnosis's own
//! parameter changes), and a parameter the nominal model got wrong is found
//! back at the truth. And the amplitude groups of a found term's amplitude
//! check at the 5 % margin.

use crate::common;

use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::synth::{synthesize, SynthSettings};
use exo_diagnose::terms::determined;
use exo_diagnose::{diagnose, Settings};

#[test]
fn a_parameter_is_named_moved_by_the_rule() {
    let truth = common::default_plant();
    let periods = common::protocol(&[(1, 30.0, 12.0, 0.0, 0.0), (2, 45.0, 18.0, 4.5, 0.0)]);
    let mut nominal = truth;
    // K_h, H_h per experiment are refitted from the plant's defaults; the
    // forearm's inertia is OFF_PCT low.
    nominal.human.inertia_kg_m2 = truth.human.inertia_kg_m2 / (1.0 + OFF_PCT / 100.0);
    let d = reduce(
        &[synthesize(&truth, &periods, &SynthSettings::default())],
        &Reduction::default(),
    );
    let r = diagnose(&d, &nominal, &Settings::default()).expect("diagnosis");
    let line = r
        .verdict
        .iter()
        .find(|v| v.starts_with("same physics, other parameters"))
        .cloned()
        .unwrap_or_default();
    for c in &r.parameter_changes {
        let m = (100.0 * c.std_error / c.nominal.abs()).max(1.0);
        let moved = determined(c.fitted, c.std_error) && c.change_pct.abs() > 2.0 * m;
        eprintln!(
            "{} {:+.2} % (2·{m:.2} = {:.2}): {moved}",
            c.label,
            c.change_pct,
            2.0 * m
        );
        assert_eq!(line.contains(&c.label), moved, "{}: {line}", c.label);
    }
    eprintln!("{line}");
    // M_h found back at the truth and named, moved by 2.5 %.
    let mh = r
        .parameter_changes
        .iter()
        .find(|c| c.label.starts_with("M_h"))
        .expect("M_h refitted");
    let m_true = truth.human.inertia_kg_m2;
    assert!(
        (mh.fitted - m_true).abs() < 3.0 * mh.std_error,
        "M_h {} ± {} against {m_true}",
        mh.fitted,
        mh.std_error
    );
    assert!(100.0 * mh.std_error / mh.nominal < 1.0);
    assert!((mh.change_pct - OFF_PCT).abs() < 0.2, "{}", mh.change_pct);
    assert!(line.contains("M_h"), "{line}");
}

/// Between the rule's 2 % floor and 3 %: M_h's relative standard error is
/// well below 1 % here (measured), so its threshold is the floor.
const OFF_PCT: f64 = 2.5;

#[test]
fn an_amplitude_at_the_five_percent_margin_counts_with_the_lowest() {
    // Hysteresis behind a viscous nominal model (as in tests/it/statistics.rs),
    // the protocol's amplitudes 2 Nm (periods 1–7), 2·1.05 Nm (period 8:
    // exactly at the 5 % margin) and 2·10^0.2 Nm (periods 9–10). The
    // amplitude groups put an amplitude within 5 % of the lowest, the margin
    // included, with the lowest (as no groups are formed when the highest is
    // within it): the found term's amplitude check compares periods 1–8
    // with periods 9–10.
    let truth = common::default_plant();
    let mut nominal = truth;
    nominal.human.hysteretic_damping.enabled = false;
    nominal.human.viscous_damping.enabled = true;
    nominal.human.viscous_damping.b_nm_s_per_rad = 1.0;
    let mut periods = common::protocol(&[(1, 15.0, 5.0, 0.0, 0.0), (2, 30.0, 10.0, 4.5, 0.0)]);
    for p in &mut periods {
        if p.period == 8 {
            p.amplitude_nm = 2.0 * 1.05;
        }
    }
    let d = reduce(
        &[synthesize(&truth, &periods, &SynthSettings::default())],
        &Reduction::default(),
    );
    let r = diagnose(&d, &nominal, &Settings::default()).expect("diagnosis");
    let chosen = r
        .steps
        .iter()
        .flat_map(|s| &s.candidates)
        .find(|c| c.chosen)
        .expect("a term found");
    let check = chosen
        .amplitude_check
        .as_ref()
        .expect("its amplitude check");
    eprintln!(
        "{:?}: {:?} {:?}",
        chosen.term, check.periods, check.amplitudes_nm
    );
    assert_eq!(check.periods, ["1–8".to_string(), "9–10".to_string()]);
    // Mean of seven 2 Nm windows and one 2.1 Nm window per experiment.
    assert!((check.amplitudes_nm[0] - (7.0 * 2.0 + 2.1) / 8.0).abs() < 1e-12);
}

/// Too few analysis windows (issue 30, bad input): with two windows the
/// model's own parameters take up nearly every value, so the lack-of-fit
/// measures the degrees of freedom left, not physics. Even with a 5 ms
/// encoder delay in the truth, nothing is named and the verdict says why;
/// with three windows the search runs.
#[test]
fn too_few_windows_name_nothing_and_say_so() {
    let nominal = common::default_plant();
    let mut truth = nominal;
    truth.sensors.encoder.terms.delay_s = 0.005;
    let all = common::protocol(&[(1, 30.0, 12.0, 4.5, 0.0)]);
    let run = |n: usize| {
        let d = reduce(
            &[synthesize(&truth, &all[..n], &SynthSettings::default())],
            &Reduction::default(),
        );
        diagnose(&d, &nominal, &Settings::default()).expect("diagnosis")
    };
    let r = run(2);
    assert!(r.found.is_empty(), "{:#?}", r.verdict);
    assert!(
        r.verdict
            .iter()
            .any(|l| l.starts_with("too few analysis windows") && l.contains("(2; at least 3)")),
        "{:#?}",
        r.verdict
    );
    let r = run(exo_diagnose::engine::MIN_WINDOWS);
    assert!(
        !r.verdict.iter().any(|l| l.starts_with("too few")),
        "{:#?}",
        r.verdict
    );
}
