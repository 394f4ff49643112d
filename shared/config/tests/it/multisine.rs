//! `[protocol] mode = "multisine"` (issue 34 items 1 and "Bad input"): the
//! run file's multisine design, the timing it sets, and every key at fault
//! refused by name. Expected values follow from the keys' documented
//! meaning (a period of `period_s · rate_hz` samples resolves
//! `2π · rate_hz / N` rad/s), never from the code under test.

use crate::common::{accepted, load_edited, refused_naming};

const MODE: (&str, &str) = ("mode = \"identification\"", "mode = \"multisine\"");
/// default.toml names periods 1, 4 and 7, which multisine mode sets itself.
const NO_PERIODS: (&str, &str) = ("periods = [1, 4, 7]\n", "");

fn with_section(section: &str) -> (&'static str, String) {
    ("[controller]\n", format!("{section}\n[controller]\n"))
}

#[test]
fn multisine_mode_with_its_defaults_is_one_period_per_experiment_of_whole_multisine_periods() {
    let cfg = accepted("ms-defaults", &[MODE, NO_PERIODS]);
    let m = cfg
        .protocol
        .multisine()
        .expect("multisine mode has a design");
    // The documented defaults.
    assert_eq!(m.band_rad_s, [2.0, 32.0]);
    assert_eq!((m.lines, m.period_s), (12, 10.0));
    assert_eq!((m.settling_periods, m.periods), (1, 3));
    assert_eq!(m.peak_nm, None);
    let table = cfg.experiment_table();
    assert_eq!(cfg.periods_run(table), vec![1]);
    // Settling one period, analysis three, the rest as the file says.
    assert_eq!(table.timing.settling_s, 10.0);
    assert_eq!(table.timing.analysis_s, 30.0);
    assert_eq!(table.timing.rest_s, 1.0);
    assert_eq!(table.timing.ramp_in_s, 5.0);
    // The default peak is each experiment's largest sine amplitude:
    // 2 Nm raised by 10^0.2 from period 8 on (configs/experiments.toml).
    let e1 = table.get(1).unwrap();
    assert!((m.peak_nm_of(table, e1) - 2.0 * 10f64.powf(0.2)).abs() < 1e-12);
}

#[test]
fn the_design_has_its_lines_on_the_periods_grid_log_spaced_over_the_band_at_unit_peak() {
    let cfg = accepted("ms-design", &[MODE, NO_PERIODS]);
    let m = cfg.protocol.multisine().unwrap();
    let design = m.design(cfg.run.rate_hz).unwrap();
    assert_eq!(design.period_samples(), 10_000);
    let d_omega = std::f64::consts::TAU / 10.0; // 2π / period_s
    let lines = design.lines();
    assert_eq!(lines.len(), 12);
    for l in lines {
        assert!((l.omega_rad_s - l.bin as f64 * d_omega).abs() < 1e-9);
        assert!(
            l.omega_rad_s >= 2.0 - 1e-9 && l.omega_rad_s <= 32.0 + 1e-9,
            "{l:?}"
        );
    }
    // Log-spaced: twelve lines over a factor of 16 are 16^(1/11) ≈ 1.287
    // apart, give or take half a bin of rounding (and the low end, where
    // the grid's 0.628 rad/s is coarser than the spacing, pushed apart).
    let ratios: Vec<f64> = lines
        .windows(2)
        .map(|w| w[1].omega_rad_s / w[0].omega_rad_s)
        .collect();
    let upper = &ratios[ratios.len() / 2..];
    for r in upper {
        assert!(
            (r / 16f64.powf(1.0 / 11.0) - 1.0).abs() < 0.12,
            "{ratios:?}"
        );
    }
    // Unit peak, measured on the samples.
    let peak = design.period().iter().fold(0.0f64, |a, x| a.max(x.abs()));
    assert!((peak - 1.0).abs() < 1e-9, "{peak}");
    // The same file gives the same design (every process builds its own).
    assert_eq!(m.design(cfg.run.rate_hz).unwrap(), design);
}

#[test]
fn a_multisine_table_outside_multisine_mode_is_refused() {
    let (from, to) = with_section("[protocol.multisine]\nlines = 8\n");
    refused_naming("ms-wrong-mode", &[(from, &to)], "protocol.multisine");
}

#[test]
fn keys_multisine_mode_sets_itself_are_refused_naming_them() {
    refused_naming("ms-periods", &[MODE], "protocol.periods");
    refused_naming(
        "ms-analysis",
        &[
            MODE,
            NO_PERIODS,
            ("rest_s = 1.0", "rest_s = 1.0\nanalysis_s = 4.0"),
        ],
        "protocol.analysis_s",
    );
    refused_naming(
        "ms-settling",
        &[
            MODE,
            NO_PERIODS,
            ("rest_s = 1.0", "rest_s = 1.0\nsettling_s = 4.0"),
        ],
        "protocol.settling_s",
    );
}

#[test]
fn fewer_than_two_analysis_periods_are_refused_no_noise_estimate() {
    let (from, to) = with_section("[protocol.multisine]\nperiods = 1\n");
    refused_naming(
        "ms-one-period",
        &[MODE, NO_PERIODS, (from, &to)],
        "protocol.multisine.periods",
    );
    let (from, to) = with_section("[protocol.multisine]\nperiods = 2\n");
    let cfg = accepted("ms-two-periods", &[MODE, NO_PERIODS, (from, &to)]);
    assert_eq!(cfg.experiment_table().timing.analysis_s, 20.0);
}

#[test]
fn a_band_beyond_nyquist_or_below_the_periods_first_line_is_refused_naming_the_band() {
    // 1 kHz: Nyquist π·1000 ≈ 3141.6 rad/s.
    let (from, to) = with_section("[protocol.multisine]\nband_rad_s = [2.0, 3200.0]\n");
    refused_naming(
        "ms-nyquist",
        &[MODE, NO_PERIODS, (from, &to)],
        "protocol.multisine.band_rad_s",
    );
    // A 10 s period resolves 0.628 rad/s: nothing in [0.1, 0.5].
    let (from, to) = with_section("[protocol.multisine]\nband_rad_s = [0.1, 0.5]\nlines = 1\n");
    refused_naming(
        "ms-below-grid",
        &[MODE, NO_PERIODS, (from, &to)],
        "protocol.multisine.band_rad_s",
    );
    // More lines than the band holds frequencies: 2–32 rad/s at 2π/10
    // rad/s spacing holds bins 4 (2.51 rad/s) to 50 (31.4 rad/s), 47.
    let (from, to) = with_section("[protocol.multisine]\nlines = 48\n");
    let (r, _) = load_edited("ms-crowded", &[MODE, NO_PERIODS, (from, &to)]);
    let err = r.expect_err("48 lines in 47 frequencies").to_string();
    assert!(
        err.contains("protocol.multisine.band_rad_s") && err.contains("47"),
        "{err}"
    );
    let (from, to) = with_section("[protocol.multisine]\nlines = 47\n");
    accepted("ms-full", &[MODE, NO_PERIODS, (from, &to)]);
    // Upper edge not above the lower.
    let (from, to) = with_section("[protocol.multisine]\nband_rad_s = [8.0, 8.0]\n");
    refused_naming(
        "ms-flat-band",
        &[MODE, NO_PERIODS, (from, &to)],
        "protocol.multisine.band_rad_s[1]",
    );
}

/// Every key at fault is named at once: too few periods and a band beyond
/// Nyquist in the same file give both errors.
#[test]
fn each_key_at_fault_is_named_in_one_refusal() {
    let (from, to) =
        with_section("[protocol.multisine]\nperiods = 1\nband_rad_s = [2.0, 4000.0]\n");
    let (r, _) = load_edited("ms-two-faults", &[MODE, NO_PERIODS, (from, &to)]);
    let err = r.expect_err("two faults").to_string();
    assert!(err.contains("protocol.multisine.periods"), "{err}");
    assert!(
        err.contains("protocol.multisine.band_rad_s") && err.contains("Nyquist"),
        "{err}"
    );
}

/// A key at fault is named once: the design and the peak are checked
/// against the table only from values that passed their own ranges, so an
/// inverted band, a band edge, a period or a peak out of range is not
/// reported again as an infeasible design or a peak beyond the limit.
#[test]
fn a_key_out_of_range_is_named_once() {
    for (section, key) in [
        (
            "band_rad_s = [8.0, 8.0]",
            "protocol.multisine.band_rad_s[1]",
        ),
        (
            "band_rad_s = [20000.0, 32.0]",
            "protocol.multisine.band_rad_s[0]",
        ),
        ("period_s = 5000.0", "protocol.multisine.period_s"),
        ("peak_nm = 2000.0", "protocol.multisine.peak_nm"),
    ] {
        let (from, to) = with_section(&format!("[protocol.multisine]\n{section}\n"));
        let (r, _) = load_edited("ms-once", &[MODE, NO_PERIODS, (from, &to)]);
        let err = r.expect_err(section);
        let each: Vec<String> = err.each().iter().map(|e| e.to_string()).collect();
        assert_eq!(each.len(), 1, "{section}: {each:#?}");
        assert!(each[0].contains(key), "{section}: {each:#?}");
    }
}

#[test]
fn a_period_that_is_not_a_whole_number_of_samples_is_refused() {
    let (from, to) = with_section("[protocol.multisine]\nperiod_s = 10.0005\n");
    refused_naming(
        "ms-fraction",
        &[MODE, NO_PERIODS, (from, &to)],
        "protocol.multisine.period_s",
    );
    let (from, to) = with_section("[protocol.multisine]\nperiod_s = 10.001\n");
    let cfg = accepted("ms-whole", &[MODE, NO_PERIODS, (from, &to)]);
    let m = cfg.protocol.multisine().unwrap();
    assert_eq!(m.period_samples(cfg.run.rate_hz), Some(10_001));
}

#[test]
fn a_peak_beyond_the_torque_limit_with_the_bias_is_refused_before_the_run() {
    // controller.limits.torque_nm = 40 in default.toml; experiment 7 holds
    // a bias of 8 Nm (configs/experiments.toml), which counts with the
    // peak: 32 Nm passes, 32.5 Nm does not, though alone it is below 40.
    let (from, to) = with_section("[protocol.multisine]\npeak_nm = 32.5\n");
    refused_naming(
        "ms-peak",
        &[MODE, NO_PERIODS, (from, &to)],
        "protocol.multisine.peak_nm",
    );
    let (from, to) = with_section("[protocol.multisine]\npeak_nm = 32.0\n");
    accepted("ms-peak-limit", &[MODE, NO_PERIODS, (from, &to)]);
    // Without experiment 7, 32.5 Nm is within the limit.
    let (from, to) = with_section("[protocol.multisine]\npeak_nm = 32.5\n");
    accepted(
        "ms-peak-no-bias",
        &[
            MODE,
            NO_PERIODS,
            (from, &to),
            ("experiments = [1, 7]", "experiments = [1]"),
        ],
    );
}

#[test]
fn non_finite_and_out_of_range_multisine_values_are_refused_by_name() {
    for (key, value) in [
        ("band_rad_s", "[2.0, nan]"),
        ("band_rad_s", "[-1.0, 32.0]"),
        ("period_s", "inf"),
        ("period_s", "0.0"),
        ("peak_nm", "nan"),
        ("peak_nm", "-2.0"),
        ("settling_periods", "0"),
        ("lines", "0"),
    ] {
        let (from, to) = with_section(&format!("[protocol.multisine]\n{key} = {value}\n"));
        refused_naming(
            &format!("ms-bad-{key}"),
            &[MODE, NO_PERIODS, (from, &to)],
            &format!("protocol.multisine.{key}"),
        );
    }
}

/// `[protocol.stop_when]` (issue 34 item 3): accepted in multisine mode with
/// its default `min_periods` (2); its rule met only when both 95 %
/// half-widths are within their fractions of K and H.
#[test]
fn stop_when_is_read_with_its_default_and_judges_both_intervals() {
    let (from, to) = with_section("[protocol.stop_when]\nk_rel_ci = 0.05\nh_rel_ci = 0.10\n");
    let cfg = accepted("sw-ok", &[MODE, NO_PERIODS, (from, &to)]);
    let w = cfg.protocol.stop_when.expect("stop_when read");
    assert_eq!((w.k_rel_ci, w.h_rel_ci, w.min_periods), (0.05, 0.10, 2));
    assert!(cfg.controller_hears_identifier());
    // K 40 ± 2 (5 %) and H 10 ± 1 (10 %): at the limits, met.
    assert!(w.met(40.0, 2.0, 10.0, 1.0));
    assert!(!w.met(40.0, 2.01, 10.0, 1.0));
    assert!(!w.met(40.0, 2.0, 10.0, 1.01));
    // A K or H that is not positive, or an interval that is not finite.
    assert!(!w.met(-40.0, 0.1, 10.0, 0.1));
    assert!(!w.met(40.0, 0.1, 0.0, 0.0));
    assert!(!w.met(40.0, f64::NAN, 10.0, 0.1));
    assert!(!w.met(40.0, 0.1, 10.0, f64::INFINITY));
    // `min_periods` may be the multisine's `periods` (3 by default): the
    // window then runs them all.
    let (from, to) =
        with_section("[protocol.stop_when]\nk_rel_ci = 0.05\nh_rel_ci = 0.10\nmin_periods = 3\n");
    let cfg = accepted("sw-min-all", &[MODE, NO_PERIODS, (from, &to)]);
    assert_eq!(cfg.protocol.stop_when.unwrap().min_periods, 3);
    // Without the table the controller does not listen to the identifier.
    let cfg = accepted("sw-none", &[MODE, NO_PERIODS]);
    assert!(cfg.protocol.stop_when.is_none());
    assert!(!cfg.controller_hears_identifier());
}

/// Bad input: an interval of 0, NaN, ∞ or beyond 1, a `min_periods` below
/// 2 (no noise estimate) or above the multisine's `periods`, a missing
/// key, and the table in another mode: each refused naming its key.
#[test]
fn bad_stop_when_values_are_refused_by_name() {
    for (i, (body, key)) in [
        (
            "k_rel_ci = 0.0\nh_rel_ci = 0.1",
            "protocol.stop_when.k_rel_ci",
        ),
        (
            "k_rel_ci = nan\nh_rel_ci = 0.1",
            "protocol.stop_when.k_rel_ci",
        ),
        (
            "k_rel_ci = 0.05\nh_rel_ci = inf",
            "protocol.stop_when.h_rel_ci",
        ),
        (
            "k_rel_ci = 0.05\nh_rel_ci = 1.5",
            "protocol.stop_when.h_rel_ci",
        ),
        (
            "k_rel_ci = 0.05\nh_rel_ci = -0.1",
            "protocol.stop_when.h_rel_ci",
        ),
        (
            "k_rel_ci = 0.05\nh_rel_ci = 0.1\nmin_periods = 1",
            "protocol.stop_when.min_periods",
        ),
        (
            "k_rel_ci = 0.05\nh_rel_ci = 0.1\nmin_periods = 4",
            "protocol.stop_when.min_periods",
        ),
        ("k_rel_ci = 0.05", "h_rel_ci"),
    ]
    .into_iter()
    .enumerate()
    {
        let (from, to) = with_section(&format!("[protocol.stop_when]\n{body}\n"));
        refused_naming(
            &format!("sw-bad-{i}"),
            &[MODE, NO_PERIODS, (from, &to)],
            key,
        );
    }
    let (from, to) = with_section("[protocol.stop_when]\nk_rel_ci = 0.05\nh_rel_ci = 0.1\n");
    refused_naming("sw-wrong-mode", &[(from, &to)], "protocol.stop_when");
}

/// Which modes excite the subject for identification (their recordings
/// fitted and reported after the run, their experiments the run's list):
/// the sine steps and the multisine, not the voluntary motion or the
/// spring release (`ProtocolMode`'s documented meaning).
#[test]
fn the_sine_steps_and_the_multisine_identify_the_others_do_not() {
    use exo_config::ProtocolMode as M;
    for (mode, identifies) in [
        (M::Identification, true),
        (M::Multisine, true),
        (M::Voluntary, false),
        (M::Release, false),
    ] {
        assert_eq!(mode.identifies(), identifies, "{mode:?}");
    }
}
