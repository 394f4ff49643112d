//! The harmonic test against a noise floor that keeps the ringing out
//! (issue 15, item 2): a window with known white noise, a known 3rd
//! harmonic and a decaying ringing at another frequency. Expected values
//! from the construction (the noise power of a DFT bin of white noise is
//! `4σ²/n`), not from the function under test.

use crate::common;

use common::normals;
use exo_diagnose::data::{reduce, Condition, Dataset, Reduction, Tf, WindowSignals};
use exo_diagnose::signatures::{
    cubic_harmonic_check, harmonics, saturation_harmonic_check, window_spectrum,
};
use exo_diagnose::synth::{synthesize, SynthSettings};
use exo_diagnose::Physics;

/// The conditions of a 5 s single-sine window `period` (the `period − 1`-th
/// of its experiment, 5 s apart), 2 Nm excitation, 0.02 rad angle amplitude.
fn condition(experiment: u32, period: u32, bias_nm: f64, sample_period_s: f64) -> Condition {
    Condition {
        experiment,
        period,
        load_kg: 0.0,
        bias_nm,
        alpha: 1.0,
        amplitude_nm: 2.0,
        theta0_rad: 0.0,
        theta_amp_rad: 0.02,
        sin_theta_mean: 0.0,
        tau_s_mean_nm: f64::NAN,
        tau_c_mean_nm: 0.0,
        command: None,
        gravity: None,
        sample_period_s,
        start_s: 5.0 * f64::from(period - 1),
        elapsed_s: 5.0 * f64::from(period - 1),
    }
}

/// 5 s at 500 Hz, ω = 4 rad/s (whole cycles: 3), fundamental 2 Nm, noise σ.
fn window(sigma: f64, third: f64, ringing: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let w = 4.0;
    let t: Vec<f64> = (0..2500).map(|i| i as f64 / 500.0).collect();
    let e = normals(seed, t.len());
    let y = t
        .iter()
        .zip(&e)
        .map(|(t, e)| {
            0.3 + 2.0 * (w * t).sin()
                + third * (3.0 * w * t + 0.4).cos()
                + ringing * (-0.8 * t).exp() * (6.7 * t).sin()
                + sigma * e
        })
        .collect();
    (t, y)
}

#[test]
fn the_noise_floor_is_the_noise_not_the_ringing() {
    let sigma = 0.05;
    let (t, y) = window(sigma, 0.0, 0.4, 3);
    let s = window_spectrum(&t, &y, 4.0).expect("spectrum");
    // Whole cycles of 4 rad/s in 5 s: 3 (4.712 s, 2356 samples).
    let n = 2356.0;
    let expected = 4.0 * sigma * sigma / n;
    assert!(
        (s.noise_power / expected - 1.0).abs() < 0.3,
        "noise power {} against {expected}",
        s.noise_power
    );
    // The ringing is found, at its frequency, and decays.
    let (w, a, ratio, decay) = s.peak.expect("peak");
    assert!((w - 6.7).abs() < 1.4, "peak at {w}");
    assert!(ratio > 100.0 && a > 0.05, "peak {a} ratio {ratio}");
    assert!(decay < 0.5, "decay {decay}");
    // The mean power of a harmonic that is absent is that of a bin.
    assert!((s.fundamental - 2.0).abs() < 0.01, "{}", s.fundamental);
}

/// Every step of the spectrum is linear in the samples (least squares, the
/// ringing's fit, the residual's DFT), so scaling a window by `s` scales
/// the noise power by `s²` and every amplitude by `s`, the ringing's
/// frequency and decay unchanged: checked at `s = 10⁻³` with the ringing
/// fitted out. A residual formed with any term not scaled with the data
/// (a stray unit coefficient) breaks it (cargo-mutants, stop 44).
#[test]
fn the_spectrum_scales_with_the_window() {
    let (t, y) = window(0.05, 0.02, 0.4, 5);
    let s = 1e-3;
    let ys: Vec<f64> = y.iter().map(|v| v * s).collect();
    let a = window_spectrum(&t, &y, 4.0).expect("spectrum");
    let b = window_spectrum(&t, &ys, 4.0).expect("scaled spectrum");
    let rel = |x: f64, y: f64| (x - y).abs() / x.abs().max(1e-300);
    assert!(
        rel(a.noise_power * s * s, b.noise_power) < 1e-9,
        "{a:?} {b:?}"
    );
    assert!(rel(a.fundamental * s, b.fundamental) < 1e-9);
    for h in 0..2 {
        assert!(
            rel(a.harmonics[h] * s, b.harmonics[h]) < 1e-9,
            "harmonic {}",
            h + 2
        );
    }
    let (pa, pb) = (a.peak.expect("peak"), b.peak.expect("peak"));
    assert!(pa.2 > 10.0, "the ringing is fitted out: {pa:?}");
    assert!(rel(pa.0, pb.0) < 1e-12 && rel(pa.1 * s, pb.1) < 1e-9);
    assert!(rel(pa.2, pb.2) < 1e-9 && rel(pa.3, pb.3) < 1e-9);
    assert_eq!(a.bins, b.bins);
}

#[test]
fn a_ringing_in_any_phase_is_kept_out_of_the_harmonics() {
    // A ringing at 10.5 rad/s, between the 2nd (8) and the 3rd harmonic
    // (12 rad/s) of ω = 4, and no harmonic: fitted out (its cosine and sine
    // parts), the harmonics are the noise's, about a bin's amplitude.
    let sigma: f64 = 0.05;
    let bin = (4.0 * sigma * sigma / 2356.0).sqrt();
    let w = 4.0;
    let t: Vec<f64> = (0..2500).map(|i| i as f64 / 500.0).collect();
    for phase in [0.0, std::f64::consts::FRAC_PI_2, 1.0] {
        let e = normals(11, t.len());
        let y: Vec<f64> = t
            .iter()
            .zip(&e)
            .map(|(t, e)| {
                2.0 * (w * t).sin() + 0.4 * (-0.8 * t).exp() * (10.5 * t + phase).cos() + sigma * e
            })
            .collect();
        let s = window_spectrum(&t, &y, w).expect("spectrum");
        // A bin's noise amplitude is Rayleigh, E|X|² = bin²: P(|X| > 4 bins)
        // = e^{−16}. Measured: at most 2.0 bins; with the ringing's cosine
        // part not fitted, the 3rd harmonic's is 21–43 bins.
        for (h, a) in [2, 3].iter().zip(s.harmonics) {
            assert!(
                a < 4.0 * bin,
                "φ = {phase}: harmonic {h} amplitude {a} is not noise (a bin: {bin})"
            );
        }
    }
}

#[test]
fn a_third_harmonic_stands_out_of_the_noise_and_noise_alone_does_not() {
    let sigma: f64 = 0.05;
    let n = 2356.0;
    let bin = (4.0 * sigma * sigma / n).sqrt();
    // A 3rd harmonic of 4 bins' noise amplitude, beside the ringing.
    let (t, y) = window(sigma, 4.0 * bin, 0.4, 5);
    let s = window_spectrum(&t, &y, 4.0).expect("spectrum");
    let r3 = s.harmonics[1].powi(2) / s.noise_power;
    assert!(r3 > 5.0, "3rd harmonic power ratio {r3}");
    assert!((s.harmonics[1] / (4.0 * bin) - 1.0).abs() < 0.5);
    // Noise alone over 40 windows: the summed ratio is χ²(2n)/2, mean n.
    let total: f64 = (0..40)
        .map(|k| {
            let (t, y) = window(sigma, 0.0, 0.4, 100 + k);
            let s = window_spectrum(&t, &y, 4.0).expect("spectrum");
            s.harmonics[1].powi(2) / s.noise_power
        })
        .sum();
    // Mean 40, standard deviation √40 ≈ 6.3 (plus the floor's own error).
    assert!((total - 40.0).abs() < 20.0, "summed ratio {total}");
}

#[test]
fn a_polynomial_springs_third_harmonic_is_found_at_its_predicted_size() {
    // Our simulator's human with K₃ = 120 Nm/rad³ (two experiments, K_h, H_h
    // 20, 8 and 40, 16): a model with the true linear part and K₃ = 0
    // against one with K₃ = 120. The data show the whole predicted 3rd
    // harmonic ¼ K₃ Θ₁³: β = 1 within its standard error.
    let periods = common::protocol(&[(1, 20.0, 8.0, 4.5, 0.0), (2, 40.0, 16.0, 4.5, 4.0)]);
    let mut truth = common::default_plant();
    truth.human.cubic_stiffness_nm_per_rad3 = 120.0;
    let d = reduce(
        &[synthesize(&truth, &periods, &SynthSettings::default())],
        &Reduction::default(),
    );
    let mut before = Physics::from_plant(&common::default_plant(), &[1, 2]);
    before.k = [(1, 20.0), (2, 40.0)].into_iter().collect();
    before.h = [(1, 8.0), (2, 16.0)].into_iter().collect();
    let mut after = before.clone();
    after.k3 = 120.0;
    let (mm, beta, se, windows) = cubic_harmonic_check(&d, &before, &after).expect("a check");
    eprintln!("|m|² {mm}, β {beta} ± {se}, {windows} windows");
    assert_eq!(windows, 20, "every single-sine window has its harmonics");
    assert!(se > 0.0 && se < 0.2, "β's standard error {se}");
    assert!((beta - 1.0).abs() < 3.0 * se, "β = {beta} ± {se}, truth 1");
    // No change of K₃, no check.
    assert!(cubic_harmonic_check(&d, &before, &before).is_none());
}

#[test]
fn a_steady_non_harmonic_tone_is_sized_against_the_fundamental() {
    // Four windows of τ_c = 2 sin 4t + 0.3 sin(ω_b t) + noise, ω_b =
    // 16π/4.712 = 10.667 rad/s, near the 8th DFT bin of the 3-cycle window
    // (3·2π/4 = 4.712 s), between the 2nd and 3rd harmonics: found at its
    // bin (within 0.01 rad/s), its size 0.3/2 = 15 % of the fundamental
    // (within 0.5 %: the bin's scalloping), not decaying (second half over
    // first 1).
    let w = 4.0;
    let wb = 16.0 * std::f64::consts::PI / 4.712;
    let mut d = Dataset::default();
    d.supported = vec![Tf::Sh];
    for k in 0..4u32 {
        let t: Vec<f64> = (0..2500).map(|i| i as f64 / 500.0).collect();
        let e = normals(40 + u64::from(k), t.len());
        let y: Vec<f64> = t
            .iter()
            .zip(&e)
            .map(|(t, e)| 2.0 * (w * t).sin() + 0.3 * (wb * t).sin() + 0.05 * e)
            .collect();
        d.signals.push(WindowSignals {
            omega_rad_s: w,
            theta_rad: y.iter().map(|v| 0.01 * v).collect(),
            tau_s_net_nm: y.clone(),
            tau_s_nm: Vec::new(),
            tau_d_nm: Vec::new(),
            tau_c_nm: y,
            t_s: t,
        });
        d.conditions.push(condition(1, k + 1, 0.0, 0.002));
    }
    let h = harmonics(&d, 0.05);
    assert_eq!(h.len(), 1, "one experiment, one supported channel");
    let nh = h[0].non_harmonic.as_ref().expect("the tone is found");
    eprintln!("{nh:?}");
    assert_eq!((nh.windows, nh.of), (4, 4));
    assert!(
        (nh.omega_rad_s - wb).abs() < 0.01,
        "at {} rad/s",
        nh.omega_rad_s
    );
    assert!((nh.size_pct - 15.0).abs() < 0.5, "size {} %", nh.size_pct);
    assert!(
        (nh.decay - 1.0).abs() < 0.1 && !nh.transient,
        "decay {}",
        nh.decay
    );
}

/// The torque limit's signature on data built by hand: an ideal actuator
/// (no SEA dynamics; the sampled torque is the previous control period's
/// held command) whose drive clips `τ_d = 24 + 3 sin 4t` (plus a little
/// 2nd harmonic and noise) at 26 Nm. What the clip leaves in the 2nd and
/// 3rd harmonics of `τ_s` is in the data at the size a 26 Nm limit
/// predicts (β = 1 within its error) and at 1/1.6 of it for a limit the
/// data do not have (24.5 Nm predicts far more); on the same command
/// without a clip, a 26 Nm limit's harmonics are absent (β ≈ 0).
#[test]
fn the_torque_limits_harmonics_are_where_the_drive_clipped() {
    let w = 4.0;
    let dt = 0.002;
    let dataset = |limit: f64| {
        let mut d = Dataset::default();
        d.supported = vec![Tf::Sea];
        for k in 0..4u32 {
            let t: Vec<f64> = (0..2500).map(|i| f64::from(i) * dt).collect();
            let e = normals(70 + u64::from(k), t.len());
            let command = |t: f64| 24.0 + 3.0 * (w * t).sin() + 0.2 * (2.0 * w * t + 0.5).cos();
            let tau_d: Vec<f64> = t.iter().map(|&t| command(t)).collect();
            // The sample reads the previous period's hold.
            let tau_s: Vec<f64> = t
                .iter()
                .zip(&e)
                .map(|(&t, e)| command(t - dt).min(limit) + 0.01 * e)
                .collect();
            let zero = vec![0.0; t.len()];
            d.signals.push(WindowSignals {
                omega_rad_s: w,
                theta_rad: zero.clone(),
                tau_s_net_nm: zero.clone(),
                tau_c_nm: zero,
                tau_s_nm: tau_s,
                tau_d_nm: tau_d,
                t_s: t,
            });
            d.conditions.push(condition(7, k + 1, 8.0, dt));
        }
        d
    };
    let plant =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/plants/default.toml");
    let mut before = Physics::from_plant(
        &exo_plant_model::PlantModel::from_file(&plant).unwrap(),
        &[7],
    );
    before.sea = None;
    let with_limit = |l: f64| {
        let mut p = before.clone();
        p.saturation_per_nm = 1.0 / l;
        p
    };
    let mut clipped = dataset(26.0);
    // A window whose command was not recorded in every sample (a NaN where
    // no answer came) is left out, not read as a clip.
    let mut gap = clipped.signals[0].clone();
    gap.tau_d_nm[100] = f64::NAN;
    clipped.signals.push(gap);
    clipped.conditions.push(clipped.conditions[0].clone());
    let (_, beta, se, windows) =
        saturation_harmonic_check(&clipped, &before, &with_limit(26.0)).expect("a check");
    assert_eq!(
        windows, 8,
        "two harmonics in each of four windows, none in the fifth"
    );
    assert!(beta.is_finite() && se.is_finite());
    assert!(se < 0.05, "β's standard error {se}");
    assert!(
        (beta - 1.0).abs() < 3.0 * se + 0.02,
        "β = {beta} ± {se}, truth 1"
    );
    let (_, beta_wrong, _, _) =
        saturation_harmonic_check(&clipped, &before, &with_limit(24.5)).expect("a check");
    assert!(
        beta_wrong < 0.6,
        "a deeper limit predicts more: β = {beta_wrong}"
    );
    let free = dataset(f64::INFINITY);
    let (_, beta_free, se_free, _) =
        saturation_harmonic_check(&free, &before, &with_limit(26.0)).expect("a check");
    assert!(
        beta_free.abs() < 3.0 * se_free,
        "β = {beta_free} ± {se_free}, truth 0"
    );
    // No change of the limit, or no τ_s/τ_d: no check.
    assert!(saturation_harmonic_check(&clipped, &before, &before).is_none());
    let mut no_sea = clipped.clone();
    no_sea.supported = vec![Tf::Sh];
    assert!(saturation_harmonic_check(&no_sea, &before, &with_limit(26.0)).is_none());
}
