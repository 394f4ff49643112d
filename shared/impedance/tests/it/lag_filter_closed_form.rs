//! The lag-filter cascade of eq. Fs with p_1 ≠ 1 against its continuous
//! closed form, and the pre-warped bilinear discretisation at its warping
//! frequencies (issue 23). Every expected value is written in this file:
//!
//! ```text
//!   F(jω) = k_f/p_1^f · Π (1 + jω/z_i)/(1 + jω/p_i),  p_i = p_1 r_pp^(i−1),  z_i = r_pp^f p_i
//! ```
//!
//! and, for the Tustin transform pre-warped at `ω₀ = √(p_i z_i)`
//! (`s ← c (1 − q⁻¹)/(1 + q⁻¹)`, `c = ω₀/tan(ω₀T/2)`), on the unit circle
//! `s = j c tan(ωT/2)`: each discrete section is its continuous section at
//! the warped frequency `ω' = c tan(ωT/2)`, which equals ω at ω = ω₀.

use std::f64::consts::TAU;

use exo_impedance::{Complex64, LagFilter};

/// Continuous section `(1 + jω/z)/(1 + jω/p)`.
fn section(w: f64, p: f64, z: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    (1.0 + s / z) / (1.0 + s / p)
}

fn pole(i: usize, p1: f64, r_pp: f64) -> f64 {
    p1 * r_pp.powi(i as i32)
}

/// Eq. Fs.
fn continuous(w: f64, n: usize, p1: f64, r_pp: f64, f: f64, k_f: f64) -> Complex64 {
    (0..n).fold(Complex64::new(k_f / p1.powf(f), 0.0), |g, i| {
        let p = pole(i, p1, r_pp);
        g * section(w, p, r_pp.powf(f) * p)
    })
}

/// The pre-warped Tustin cascade on the unit circle, written from the
/// transform (not from the crate's coefficients).
fn tustin(w: f64, n: usize, p1: f64, r_pp: f64, f: f64, k_f: f64, rate_hz: f64) -> Complex64 {
    let t = 1.0 / rate_hz;
    (0..n).fold(Complex64::new(k_f / p1.powf(f), 0.0), |g, i| {
        let p = pole(i, p1, r_pp);
        let z = r_pp.powf(f) * p;
        let w0 = (p * z).sqrt();
        let c = w0 / (w0 * t / 2.0).tan();
        g * section(c * (w * t / 2.0).tan(), p, z)
    })
}

fn rel(a: Complex64, b: Complex64) -> f64 {
    (a - b).norm() / b.norm()
}

/// `(n, p_1, r_pp, f, k_f)` with p_1 ≠ 1.
const LAYOUTS: [(usize, f64, f64, f64, f64); 3] = [
    (5, 0.4, 3.1622776601683795, 0.5, 2.3),
    (3, 2.5, 4.0, 0.8, 1.7),
    (1, 3.0, 9.0, 0.3, 5.0),
];

#[test]
fn continuous_response_with_p1_not_one_matches_eq_fs() {
    for (n, p1, r_pp, f, k_f) in LAYOUTS {
        let lf = LagFilter::new(n, p1, r_pp, f, k_f).unwrap();
        let gain = k_f / p1.powf(f);
        assert!(
            (lf.gain() - gain).abs() < 1e-14 * gain,
            "gain {} vs {gain}",
            lf.gain()
        );
        for w in [0.01, 0.3, 1.0, 3.7, 20.0, 150.0] {
            let (got, want) = (lf.response(w), continuous(w, n, p1, r_pp, f, k_f));
            assert!(
                rel(got, want) < 1e-12,
                "n {n} p1 {p1} at {w}: {got} vs {want}"
            );
            let phase: f64 = (0..n)
                .map(|i| {
                    let p = pole(i, p1, r_pp);
                    (w / (r_pp.powf(f) * p)).atan() - (w / p).atan()
                })
                .sum();
            assert!((lf.phase_deg(w) - phase.to_degrees()).abs() < 1e-10);
        }
        // Flat below p_1 at k_f/p_1^f: F(j·1e-6) → the gain.
        assert!(rel(lf.response(1e-6 * p1), Complex64::new(gain, 0.0)) < 1e-5);
    }
}

#[test]
fn discrete_step_response_settles_at_k_f_over_p1_to_the_f() {
    for (n, p1, r_pp, f, k_f) in LAYOUTS {
        let mut d = LagFilter::new(n, p1, r_pp, f, k_f)
            .unwrap()
            .discretize(1000.0)
            .unwrap();
        // 40 slowest time constants 1/p_1.
        let steps = (40.0 / p1 * 1000.0) as usize;
        let mut y = 0.0;
        for _ in 0..steps {
            y = d.step(1.0);
        }
        let gain = k_f / p1.powf(f);
        assert!(
            (y - gain).abs() < 1e-9 * gain,
            "n {n} p1 {p1}: {y} vs {gain}"
        );
        assert!(
            (d.gain() - gain).abs() < 1e-14 * gain,
            "discrete gain {}",
            d.gain()
        );
    }
}

/// At each section's warping frequency ω₀ = √(p_i z_i) the discrete section
/// equals the continuous one (to rounding), at a low rate (50 Hz) where an
/// unwarped Tustin transform (c = 2/T) would be off by ~(ω₀T)²/12 (3e-4 and
/// more, checked below so this test can tell the difference).
#[test]
fn each_section_is_exact_at_its_warping_frequency() {
    let rate = 50.0;
    let t = 1.0 / rate;
    for (n, p1, r_pp, f, k_f) in LAYOUTS {
        let d = LagFilter::new(n, p1, r_pp, f, k_f)
            .unwrap()
            .discretize(rate)
            .unwrap();
        assert_eq!(d.sections().len(), n);
        for (i, s) in d.sections().iter().enumerate() {
            let p = pole(i, p1, r_pp);
            let z = r_pp.powf(f) * p;
            let w0 = (p * z).sqrt();
            let got = s.response(w0, t);
            let want = section(w0, p, z);
            assert!(
                rel(got, want) < 1e-12,
                "section {i} of n {n} p1 {p1} at ω₀ {w0}: {got} vs {want}"
            );
            // Without the pre-warp (c = 2/T) the section would differ here.
            let unwarped = section((2.0 / t) * (w0 * t / 2.0).tan(), p, z);
            assert!(
                rel(unwarped, want) > 1e-6,
                "the rate is too high to see the warp"
            );
        }
    }
}

/// The whole discrete cascade against the pre-warped Tustin closed form at
/// frequencies off the warping points, both from its `response` and from
/// `step` driven by a sine (gain and phase by correlation over whole periods).
#[test]
fn discrete_cascade_matches_the_tustin_closed_form_in_the_time_domain() {
    let rate = 50.0;
    for (n, p1, r_pp, f, k_f) in LAYOUTS {
        let lf = LagFilter::new(n, p1, r_pp, f, k_f).unwrap();
        let Ok(d0) = lf.discretize(rate) else {
            continue;
        };
        // 50, 20 and 10 samples per period: 6.28, 15.7 and 31.4 rad/s.
        for per in [50u64, 20, 10] {
            let w = TAU * rate / per as f64;
            let want = tustin(w, n, p1, r_pp, f, k_f, rate);
            assert!(rel(d0.response(w), want) < 1e-12, "response at {w}");
            let mut d = d0;
            let settle = (40.0 / p1 * rate) as u64 / per * per + per;
            let total = settle + 40 * per;
            let mut acc = Complex64::new(0.0, 0.0);
            for k in 0..total {
                let ph = w * k as f64 / rate;
                let y = d.step(ph.sin());
                if k >= settle {
                    acc += y * Complex64::new(ph.sin(), ph.cos());
                }
            }
            let got = acc * (2.0 / (40 * per) as f64);
            assert!(
                rel(got, want) < 1e-9,
                "n {n} p1 {p1} at {w}: {got} vs {want}"
            );
            // Off the warping points the discrete and continuous responses
            // differ at this rate: the closed form above is not the trivial one.
            if w > 10.0 {
                assert!(rel(want, continuous(w, n, p1, r_pp, f, k_f)) > 1e-6);
            }
        }
    }
}

/// The discretisation refuses a section centred at or above 0.9 of the
/// Nyquist frequency (π · rate): at 50 Hz (Nyquist 157.08 rad/s) one
/// section with `p = ω₀/√r_zp`, `r_zp = 4^0.5 = 2`, centred at 0.95 of it
/// is refused and one at 0.85 is accepted.
#[test]
fn a_section_near_nyquist_is_refused() {
    let rate = 50.0;
    let nyquist = std::f64::consts::PI * rate;
    for (frac, ok) in [(0.95, false), (0.85, true)] {
        let p1 = frac * nyquist / 2f64.sqrt();
        let lf = LagFilter::new(1, p1, 4.0, 0.5, 1.0).unwrap();
        assert!(((lf.pole_rad_s(0) * lf.zero_rad_s(0)).sqrt() - frac * nyquist).abs() < 1e-9);
        assert_eq!(
            lf.discretize(rate).is_ok(),
            ok,
            "section at {frac} of Nyquist"
        );
    }
}

/// The zeros and the band by hand: three sections from p₁ = 0.1 rad/s with
/// r_pp = 10 and f = 0.5 have r_zp = √10, poles 0.1, 1, 10 rad/s, zeros
/// 0.1√10, √10, 10√10 rad/s, and act as `s^(−f)` over [p₁, z₃] =
/// [0.1, 31.62…] rad/s.
#[test]
fn the_zeros_and_the_band_by_hand() {
    let lf = LagFilter::new(3, 0.1, 10.0, 0.5, 2.0).unwrap();
    let root10 = 10f64.sqrt();
    let want = [0.1 * root10, root10, 10.0 * root10];
    let zeros = lf.zeros_rad_s();
    assert_eq!(zeros.len(), 3);
    for (z, w) in zeros.iter().zip(want) {
        assert!((z - w).abs() <= 1e-12 * w, "{z} against {w}");
    }
    let (lo, hi) = lf.band_rad_s();
    assert!((lo - 0.1).abs() <= 1e-15, "{lo}");
    assert!((hi - 10.0 * root10).abs() <= 1e-12 * hi, "{hi}");
}
