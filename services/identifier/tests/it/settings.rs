//! The identifier's settings: taken from the run file where the run file
//! says (`IdentifierSettings::of_run`), and refused at each boundary by
//! name (`IdentifierSettings::validate`). Each boundary value is written
//! here from the rule the error message states, not read from the code.

use exo_config::RunConfig;
use exo_identifier::{IdentifierSettings, SettingsError};

fn field_of(s: &IdentifierSettings) -> Option<&'static str> {
    s.validate().err().map(|SettingsError { field, .. }| field)
}

/// Sets one setting of the identifier's.
type Set = fn(&mut IdentifierSettings, f64);

/// Each setting of `cases`, set alone to each of `bad`, is refused naming
/// it; set to `good`, the defaults with it pass `validate`'s check of it
/// (`Ok`, or another field's complaint when `good` breaks a pair).
fn refused_by_name(cases: &[(&str, Set)], bad: &[f64], good: f64) {
    for &(field, set) in cases {
        for &v in bad {
            let mut s = IdentifierSettings::default();
            set(&mut s, v);
            assert_eq!(field_of(&s), Some(field), "{field} = {v}");
        }
        let mut s = IdentifierSettings::default();
        set(&mut s, good);
        assert_ne!(field_of(&s), Some(field), "{field} = {good} is allowed");
    }
}

/// The run's rate, arm, load lever, design range and f bounds reach the
/// identifier: each set here to a value none of the defaults has.
#[test]
fn the_run_file_sets_the_rate_arm_range_and_f_bounds() {
    let mut cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml"))
        .expect("default run file");
    cfg.run.rate_hz = 733.0;
    cfg.rig.arm_inertia_kg_m2 = 0.137;
    cfg.rig.load_lever_arm_m = 0.391;
    cfg.controller.k_range_nm_per_rad = [12.5, 97.0];
    cfg.controller.f_bounds = [0.05, 0.71];
    let s = IdentifierSettings::of_run(&cfg);
    assert_eq!(s.rate_hz, 733.0);
    assert_eq!(s.arm_inertia_kg_m2, 0.137);
    assert_eq!(s.load_lever_arm_m, 0.391);
    assert_eq!(s.k_range_nm_per_rad, [12.5, 97.0]);
    assert_eq!(s.f_bounds, [0.05, 0.71]);
    // The rest is the identifier's own default.
    let d = IdentifierSettings::default();
    assert_eq!(s.max_window_s, d.max_window_s);
    assert_eq!(s.welch_segment, d.welch_segment);
    assert_eq!(s.validate(), Ok(()));
}

/// "A finite number above zero": zero and infinity are refused by name,
/// the smallest positive number is not.
#[test]
fn positive_settings_refuse_zero_and_infinity_by_name() {
    let cases: [(&str, Set); 6] = [
        ("rate_hz", |s, v| s.rate_hz = v),
        ("max_window_s", |s, v| s.max_window_s = v),
        ("arm_inertia_kg_m2", |s, v| s.arm_inertia_kg_m2 = v),
        ("phase_margin_deg", |s, v| s.phase_margin_deg = v),
        ("k_range_nm_per_rad[0]", |s, v| s.k_range_nm_per_rad[0] = v),
        ("broadband_band_rad_s[1]", |s, v| {
            s.broadband_band_rad_s = [0.0, v]
        }),
    ];
    refused_by_name(&cases, &[0.0, -1.0, f64::INFINITY, f64::NAN], 1e-9);
}

/// "A finite number, not negative": zero is taken, a negative number and
/// infinity are refused by name.
#[test]
fn non_negative_settings_take_zero_and_refuse_infinity_by_name() {
    let cases: [(&str, Set); 3] = [
        ("load_lever_arm_m", |s, v| s.load_lever_arm_m = v),
        ("min_rel_power", |s, v| s.min_rel_power = v),
        ("broadband_band_rad_s[0]", |s, v| {
            s.broadband_band_rad_s[0] = v
        }),
    ];
    refused_by_name(&cases, &[-1e-9, f64::INFINITY, f64::NAN], 0.0);
    for (field, set) in cases {
        let mut s = IdentifierSettings::default();
        set(&mut s, 0.0);
        assert_eq!(s.validate(), Ok(()), "{field} = 0");
    }
}

/// The ordered ranges and the window's size at their edges: a window of
/// exactly 1e8 samples is taken (the rule refuses more), a stiffness range
/// of zero width is refused, an f range of zero width is taken,
/// `f_bounds[0] = 0` is taken and anything below it refused.
#[test]
fn ranges_and_the_window_are_refused_at_their_edges() {
    let mut s = IdentifierSettings {
        rate_hz: 1000.0,
        max_window_s: 1e5,
        ..IdentifierSettings::default()
    };
    assert_eq!(s.validate(), Ok(()), "1e8 samples exactly");
    s.max_window_s = 1.0001e5;
    assert_eq!(field_of(&s), Some("max_window_s"));

    let mut s = IdentifierSettings {
        k_range_nm_per_rad: [40.0, 40.0],
        ..IdentifierSettings::default()
    };
    assert_eq!(field_of(&s), Some("k_range_nm_per_rad[1]"));
    s.k_range_nm_per_rad = [40.0, f64::INFINITY];
    assert_eq!(field_of(&s), Some("k_range_nm_per_rad[1]"));

    let mut s = IdentifierSettings {
        f_bounds: [0.4, 0.4],
        ..IdentifierSettings::default()
    };
    assert_eq!(s.validate(), Ok(()));
    s.f_bounds = [0.0, 0.5];
    assert_eq!(s.validate(), Ok(()));
    for bad in [-1e-9, f64::NEG_INFINITY, f64::NAN] {
        s.f_bounds = [bad, 0.5];
        assert_eq!(field_of(&s), Some("f_bounds[0]"), "{bad}");
    }
    s.f_bounds = [0.2, 1.0];
    assert_eq!(field_of(&s), Some("f_bounds[1]"));
    s.f_bounds = [0.2, 0.1];
    assert_eq!(field_of(&s), Some("f_bounds[1]"));
}

/// A multisine's analysis window may be longer than the default ring
/// (60 s): the ring then holds the whole window and 5 s more for its
/// closing samples (100 s analysed → 105 s); a shorter one keeps the
/// default.
#[test]
fn the_ring_holds_a_long_analysis_window_whole() {
    let mut cfg = RunConfig::from_file(&exo_config::configs_dir().join("multisine.toml"))
        .expect("multisine run file");
    assert_eq!(
        IdentifierSettings::of_run(&cfg).max_window_s,
        IdentifierSettings::default().max_window_s
    );
    cfg.experiments.as_mut().unwrap().timing.analysis_s = 100.0;
    assert_eq!(IdentifierSettings::of_run(&cfg).max_window_s, 105.0);
}
