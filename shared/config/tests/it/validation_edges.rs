//! Edges of the run file's validation that the numeric walk
//! (`bad_values.rs`) does not reach: checks across keys, text keys, a
//! missing table, the bound of a closed range, and the gravity torque the
//! controller and the driver's safe state use (issue 23: each was a
//! surviving mutant of the cargo-mutants sample of exo-config).

use crate::common::{accepted, load_edited, load_edited_in, refused_naming};
use exo_config::RigSettings;

#[test]
fn f_bounds_out_of_order_are_refused_naming_the_upper_bound() {
    refused_naming(
        "fb",
        &[("f_bounds = [0.0, 0.9]", "f_bounds = [0.8, 0.2]")],
        "controller.f_bounds[1]",
    );
    accepted(
        "fb-ok",
        &[("f_bounds = [0.0, 0.9]", "f_bounds = [0.3, 0.3]")],
    );
}

#[test]
fn an_instance_name_outside_letters_digits_dash_underscore_is_refused() {
    for (i, bad) in ["\"\"", "\"two words\"", "\"a/b\""].iter().enumerate() {
        refused_naming(
            &format!("inst{i}"),
            &[("instance = \"exo\"", &format!("instance = {bad}"))],
            "run.instance",
        );
    }
    let long = format!("instance = \"{}\"", "x".repeat(65));
    refused_naming(
        "inst-long",
        &[("instance = \"exo\"", &long)],
        "run.instance",
    );
    let c = accepted(
        "inst-ok",
        &[("instance = \"exo\"", "instance = \"lab_2-b\"")],
    );
    assert_eq!(c.run.instance, "lab_2-b");
}

#[test]
fn a_voluntary_protocol_needs_its_table() {
    refused_naming(
        "vol",
        &[("mode = \"identification\"", "mode = \"voluntary\"")],
        "voluntary",
    );
}

#[test]
fn the_last_period_of_the_table_is_a_valid_period_the_next_is_not() {
    accepted("p10", &[("periods = [1, 4, 7]", "periods = [1, 10]")]);
    refused_naming(
        "p11",
        &[("periods = [1, 4, 7]", "periods = [1, 11]")],
        "protocol.periods[1]",
    );
}

/// `g (m_a l_a + m_L l_L) sin θ` with the numbers written out here.
#[test]
fn the_gravity_torque_is_the_arm_and_load_moments_times_g_sin_theta() {
    let c = accepted("grav", &[]);
    let rig = RigSettings {
        arm_mass_kg: 2.0,
        arm_com_m: 0.3,
        load_lever_arm_m: 0.45,
        ..c.rig
    };
    // 9.80665 · (2 · 0.3 + 1.5 · 0.45) · sin 0.7
    let expected = 9.80665 * (0.6 + 0.675) * 0.644_217_687_237_691;
    assert!((rig.gravity_torque_nm(0.7, 1.5) - expected).abs() < 1e-12);
    assert_eq!(rig.gravity_torque_nm(0.0, 1.5), 0.0);
    // The moment, written once: 9.80665 · (2 · 0.3 + 1.5 · 0.45) Nm, and the
    // torque is it times sin θ, bit for bit.
    let moment = exo_config::gravity_moment_nm(9.80665, 2.0, 0.3, 1.5, 0.45);
    assert!((moment - 9.80665 * 1.275).abs() < 1e-12);
    assert_eq!(rig.gravity_moment_nm(1.5).to_bits(), moment.to_bits());
    assert_eq!(
        rig.gravity_torque_nm(0.7, 1.5).to_bits(),
        (moment * 0.7f64.sin()).to_bits()
    );
    assert_eq!(exo_config::gravity_moment_nm(0.0, 2.0, 0.3, 1.5, 0.45), 0.0);
}

/// `rig.gravity_m_s2`: standard gravity when the key is absent, none on a
/// horizontal rig (`0`), and a negative or NaN one refused naming the key.
#[test]
fn the_rigs_gravity_defaults_to_standard_and_zero_is_a_horizontal_rig() {
    let c = accepted("grav-default", &[]);
    assert_eq!(c.rig.gravity_m_s2, 9.80665);
    let flat = accepted(
        "grav-zero",
        &[(
            "velocity_cutoff_hz = 50.0",
            "velocity_cutoff_hz = 50.0\ngravity_m_s2 = 0.0",
        )],
    );
    assert_eq!(flat.rig.gravity_torque_nm(0.7, 4.5), 0.0);
    let moon = accepted(
        "grav-moon",
        &[(
            "velocity_cutoff_hz = 50.0",
            "velocity_cutoff_hz = 50.0\ngravity_m_s2 = 1.62",
        )],
    );
    let ratio = moon.rig.gravity_torque_nm(0.7, 4.5) / c.rig.gravity_torque_nm(0.7, 4.5);
    assert!((ratio - 1.62 / 9.80665).abs() < 1e-12, "{ratio}");
    for bad in ["-1.0", "nan"] {
        refused_naming(
            &format!("grav-{bad}"),
            &[(
                "velocity_cutoff_hz = 50.0",
                &format!("velocity_cutoff_hz = 50.0\ngravity_m_s2 = {bad}"),
            )],
            "rig.gravity_m_s2",
        );
    }
}

/// Without `f_bounds` the documented default [0, 0.9] holds.
#[test]
fn f_bounds_default_to_zero_and_nine_tenths() {
    let c = accepted("fb-default", &[("f_bounds = [0.0, 0.9]", "")]);
    assert_eq!(c.controller.f_bounds, [0.0, 0.9]);
}

/// A protocol of more than a day (86 400 s) is refused: nine experiments ×
/// ten periods × (20 s + rest) is 325 800 s with an hour's rest, 82 800 s
/// with 900 s.
#[test]
fn a_protocol_longer_than_a_day_is_refused() {
    let all = [
        (
            "experiments = [1, 7]",
            "experiments = [1, 2, 3, 4, 5, 6, 7, 8, 9]",
        ),
        (
            "periods = [1, 4, 7]",
            "periods = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]",
        ),
    ];
    let (r, dir) = load_edited(
        "day",
        &[all[0], all[1], ("rest_s = 1.0", "rest_s = 3600.0")],
    );
    let _ = std::fs::remove_dir_all(dir);
    let Err(err) = r else {
        panic!("a 90-hour protocol accepted")
    };
    assert!(err.to_string().contains("more than a day"), "{err}");
    accepted(
        "day-ok",
        &[all[0], all[1], ("rest_s = 1.0", "rest_s = 900.0")],
    );
}

/// `amplitude_boost_from_period` may be `periods + 1` (never boosted), the
/// top of its range when `periods` is at its maximum; `periods + 2` is
/// refused naming the key.
#[test]
fn the_amplitude_boost_may_start_one_past_the_last_period_not_two() {
    let max = exo_config::MAX_PERIOD;
    let periods = ("periods = 10".to_string(), format!("periods = {max}"));
    for (boost, ok) in [(max + 1, true), (max + 2, false)] {
        let to = format!("amplitude_boost_from_period = {boost}");
        let (r, dir) = load_edited_in(
            &format!("boost{boost}"),
            "experiments.toml",
            &[
                (&periods.0, &periods.1),
                ("amplitude_boost_from_period = 8", &to),
            ],
        );
        let _ = std::fs::remove_dir_all(dir);
        match (r, ok) {
            (Ok(c), true) => assert_eq!(
                c.experiments.map(|t| t.amplitude_boost_from_period),
                Some(boost)
            ),
            (Err(e), false) => {
                assert!(e.to_string().contains("amplitude_boost_from_period"), "{e}")
            }
            (r, _) => panic!("boost from {boost} with {max} periods: {:?}", r.err()),
        }
    }
}

/// A voluntary protocol's bias may be negative (range [−100, 100] Nm), not
/// below −100.
#[test]
fn a_voluntary_bias_may_be_negative_within_its_range() {
    let table = |bias: f64| {
        format!(
            "[voluntary]\namplitude_rad = 0.3\nomega_rad_s = 2.0\nduration_s = 10.0\ngrip_kg = 14.0\nbias_nm = {bias:?}\nexperiment = 1\n\n[controller]\n"
        )
    };
    let mode = ("mode = \"identification\"", "mode = \"voluntary\"");
    let t = table(-4.0);
    let c = accepted("vol-neg", &[mode, ("[controller]\n", &t)]);
    assert_eq!(c.voluntary.map(|v| v.bias_nm), Some(-4.0));
    let t = table(-100.5);
    refused_naming(
        "vol-low",
        &[mode, ("[controller]\n", &t)],
        "voluntary.bias_nm",
    );
}

/// A lowering spring is a spring too: `release.spring_torque_nm` spans
/// [−100, 100] Nm (the run file's documented range), both signs.
#[test]
fn a_release_springs_torque_may_lower_or_raise_within_100_nm() {
    let section = |torque: &str| {
        format!(
            "[release]\nexperiment = 1\nspring_torque_nm = {torque}\nhold_s = 5.0\nobserve_s = 5.0\n\n[services]\n"
        )
    };
    let mode = ("mode = \"identification\"", "mode = \"release\"");
    for torque in ["-50.0", "-100.0", "100.0"] {
        let s = section(torque);
        let cfg = accepted(
            &format!("rel{}", torque.replace(['-', '.'], "")),
            &[mode, ("[services]\n", s.as_str())],
        );
        assert_eq!(
            cfg.release.map(|r| r.spring_torque_nm),
            Some(torque.parse().unwrap())
        );
    }
    let s = section("-100.5");
    refused_naming(
        "relbeyond",
        &[mode, ("[services]\n", s.as_str())],
        "release.spring_torque_nm",
    );
}

/// The periods asked must exist in the run's experiment table, not only
/// within the largest table allowed (`MAX_PERIOD`, 10): a table of six
/// periods refuses the default protocol's period 7, naming it; one of
/// seven takes it.
#[test]
fn a_period_beyond_the_runs_table_is_refused_naming_it() {
    let table = |n: &'static str, boost: &'static str| {
        [
            ("\nperiods = 10", n),
            ("amplitude_boost_from_period = 8", boost),
        ]
    };
    let (r, dir) = load_edited_in(
        "p7",
        "experiments.toml",
        &table("\nperiods = 7", "amplitude_boost_from_period = 7"),
    );
    let _ = std::fs::remove_dir_all(dir);
    r.unwrap_or_else(|e| panic!("a table of 7 periods with period 7 asked: {e}"));
    let (r, dir) = load_edited_in(
        "p6",
        "experiments.toml",
        &table("\nperiods = 6", "amplitude_boost_from_period = 7"),
    );
    let _ = std::fs::remove_dir_all(dir);
    let err = r
        .expect_err("period 7 of a 6-period table accepted")
        .to_string();
    assert!(
        err.contains("protocol.periods[2]") && err.contains("period 7 is outside 1..=6"),
        "{err}"
    );
}

/// Nyquist is `π · run.rate_hz` rad/s: at 1 kHz (3141.6 rad/s) a protocol
/// whose fastest line is 2004.7 rad/s (experiment 7's 4 rad/s × 10^0.45 in
/// period 7: the frequency step 10^0.45) is accepted; the same at 500 Hz
/// (1570.8 rad/s) is refused naming the experiment's frequency.
#[test]
fn an_excitation_between_the_two_rates_nyquist_frequencies() {
    let step = (
        "frequency_step = 1.2589254117941673",
        "frequency_step = 2.8183829312644537",
    );
    let (r, dir) = load_edited_in("nyq1k", "experiments.toml", &[step]);
    let _ = std::fs::remove_dir_all(dir);
    r.unwrap_or_else(|e| panic!("2004.7 rad/s at 1 kHz: {e}"));
    let (_, dir) = load_edited_in("nyq500", "experiments.toml", &[step]);
    let run = dir.join("default.toml");
    let text =
        std::fs::read_to_string(&run)
            .unwrap()
            .replacen("rate_hz = 1000.0", "rate_hz = 500.0", 1);
    std::fs::write(&run, text).unwrap();
    let r = exo_config::RunConfig::from_file(&run);
    let _ = std::fs::remove_dir_all(dir);
    let err = r.expect_err("2004.7 rad/s at 500 Hz accepted").to_string();
    assert!(
        err.contains("start_omega_rad_s") && err.contains("π·run.rate_hz = 1570.8 rad/s"),
        "{err}"
    );
}
