//! The amplification torque against a closed form of its transfer function
//! (issue 23): sign, gain and phase at three frequencies.
//!
//! The controller's amplification torque is `τ_amp = −(α(s) − 1) τ_c` with
//! `α(s) − 1 = k_p F(s)` (section "Loop Shaping Methods"), and `F(s)` the
//! lag-filter cascade of eq. Fs:
//!
//! ```text
//!   F(jω) = k_f / p_1^f · Π_{i=1..n} (1 + jω/z_i)/(1 + jω/p_i),
//!   p_i = p_1 r_pp^(i−1),  z_i = r_pp^f p_i,  k_f = ω̂_gc^f  (eq. kf)
//! ```
//!
//! written out again in this file. The discrete amplifier is driven with a
//! sine `τ_c = sin(ωt)` until its transient has died out (30 s, thirty times
//! the slowest time constant 1/p_1), and its output's in-phase and quadrature
//! parts over whole periods are extracted by correlation here:
//! `G = (2/N) Σ y_k (sin ωt_k + j cos ωt_k)`, so that `y = |G| sin(ωt + arg G)`.
//!
//! Tolerance: the bilinear transform maps ω to `(2/T) tan(ωT/2)`, a relative
//! frequency error of `(ωT)²/12 ≤ 2.1e-5` at the highest frequency tested
//! (15.7 rad/s at 1 kHz); each first-order section's log-slope is at most
//! one, so five sections move the gain by at most ~1e-4 and the phase by
//! ~1e-4 rad. The checks use 1e-3 relative and 1e-3 rad (0.057°). A flipped
//! sign moves the phase by π, a gain `k_f` in place of `k_f/p_1^f` (p_1 ≠ 1)
//! moves the magnitude by `p_1^f`.

use std::f64::consts::{PI, TAU};

use exo_config::RunConfig;
use exo_controller::{Amplifier, Controller, TickInput};
use exo_impedance::Complex64;

const RATE_HZ: f64 = 1000.0;
/// Three frequencies with a whole number of samples per period (0.5, 1 and
/// 2.5 Hz: 2000, 1000 and 400 samples), spanning the band of the paper's
/// excitation (Table I, 2 to 16 rad/s).
const FREQS_HZ: [f64; 3] = [0.5, 1.0, 2.5];

/// `F(jω)` of eq. Fs, written here.
fn lag_cascade(w: f64, n: usize, p1: f64, r_pp: f64, f: f64, k_f: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    let mut g = Complex64::new(k_f / p1.powf(f), 0.0);
    for i in 0..n {
        let p = p1 * r_pp.powi(i as i32);
        let z = r_pp.powf(f) * p;
        g *= (1.0 + s / z) / (1.0 + s / p);
    }
    g
}

/// Drives `step` with `sin(2π f_hz t)` and returns the complex gain.
fn measured_gain(f_hz: f64, mut step: impl FnMut(u64, f64) -> f64) -> Complex64 {
    let settle = (30.0 * RATE_HZ) as u64;
    let per_period = (RATE_HZ / f_hz).round() as u64;
    let n = per_period * (f_hz * 10.0).ceil() as u64; // whole periods, ≥ 10 s
    let w = TAU * f_hz;
    let mut acc = Complex64::new(0.0, 0.0);
    for k in 0..settle + n {
        let t = k as f64 / RATE_HZ;
        let y = step(k, (w * t).sin());
        if k >= settle {
            acc += y * Complex64::new((w * t).sin(), (w * t).cos());
        }
    }
    acc * (2.0 / n as f64)
}

fn compare(what: &str, got: Complex64, want: Complex64) {
    let mag = got.norm() / want.norm() - 1.0;
    let dphi = (got / want).arg();
    eprintln!(
        "{what}: |G| {:.6} (closed form {:.6}), arg {:.3}° ({:.3}°)",
        got.norm(),
        want.norm(),
        got.arg().to_degrees(),
        want.arg().to_degrees()
    );
    assert!(mag.abs() < 1e-3, "{what}: gain off by {:.3e}", mag);
    assert!(
        dphi.abs() < 1e-3,
        "{what}: phase off by {:.4}°",
        dphi.to_degrees()
    );
}

#[test]
fn fractional_amplifier_matches_minus_kp_f_of_s() {
    // p_1 ≠ 1 so that the normalisation k_f/p_1^f matters.
    for (kp, f, w_gc, n, p1, r_pp) in [
        (2.0, 0.5, 6.0, 5, 0.5, 10f64.sqrt()),
        (3.2, 0.3, 9.0, 4, 2.0, 3.0),
    ] {
        let k_f = f64::powf(w_gc, f); // eq. kf
        for f_hz in FREQS_HZ {
            let w = TAU * f_hz;
            let mut amp = Amplifier::fractional(kp, f, w_gc, n, p1, r_pp, RATE_HZ).unwrap();
            let got = measured_gain(f_hz, |_, u| amp.step(u));
            let want = -kp * lag_cascade(w, n, p1, r_pp, f, k_f);
            compare(&format!("kp {kp} f {f} p1 {p1} at {w:.2} rad/s"), got, want);
            // The sign, in words: the amplification torque opposes τ_c, with
            // F's phase lag of about 90 f degrees on top.
            let lag = (got / Complex64::new(-1.0, 0.0)).arg();
            assert!(
                lag < 0.0 && lag > -PI / 2.0,
                "phase relative to −τ_c: {:.1}°",
                lag.to_degrees()
            );
        }
    }
}

#[test]
fn constant_amplifier_is_minus_alpha_minus_one() {
    let mut a = Amplifier::Constant { alpha: 3.0 };
    for u in [1.0, -0.25, 7.5] {
        assert_eq!(a.step(u), -2.0 * u);
    }
    a.set_constant_alpha(0.5);
    assert_eq!(a.step(2.0), 1.0); // α < 1 lightens the amplification: +0.5·2
}

/// Through the whole controller: the published `tau_amplification_nm` of
/// every tick, with the run configuration's k_p, f, filters and p_1 ≠ 1,
/// and ω̂_gc computed here from the paper's eqs. kp and kf:
/// `ω̂_gc = (K̂ / ((M_e + M_h) M_h)^(1/2))^(1/2)`, `K̂ = (K̲ K̄)^(1/2)`.
#[test]
fn controller_publishes_the_closed_form_amplification() {
    let mut cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
    let (kp, f, p1) = (2.5, 0.4, 0.7);
    cfg.controller.kp = Some(kp);
    cfg.controller.f = Some(f);
    cfg.controller.p1_rad_s = p1;
    let (n, r_pp) = (cfg.controller.filters, cfg.controller.r_pp);
    let first = cfg.protocol.experiments[0];
    let load = cfg.experiment_table().get(first).unwrap().load_kg;
    let m_e = cfg.rig.arm_inertia_kg_m2 + load * cfg.rig.load_lever_arm_m.powi(2);
    let m_h = cfg.subject().inertia_kg_m2;
    let [k_lo, k_hi] = cfg.controller.k_range_nm_per_rad;
    let w_gc = ((k_lo * k_hi).sqrt() / ((m_e + m_h) * m_h).sqrt()).sqrt();
    let k_f = w_gc.powf(f);
    for f_hz in FREQS_HZ {
        let w = TAU * f_hz;
        let mut c = Controller::from_config(&cfg).unwrap();
        let got = measured_gain(f_hz, |k, u| {
            let t = c.tick(&TickInput {
                seq: k,
                theta_e_rad: 0.5,
                omega_e_rad_s: 0.0,
                tau_c_nm: u,
                tau_s_nm: 0.0,
                stamp_ns: 0,
                status: 0,
            });
            assert!(c.fault().is_none(), "fault at tick {k}: {:?}", c.fault());
            t.tau_amplification_nm
        });
        let want = -kp * lag_cascade(w, n, p1, r_pp, f, k_f);
        compare(&format!("controller at {w:.2} rad/s"), got, want);
    }
}
