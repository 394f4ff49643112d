//! The noise measured beside the line (`data::local_ratio_sigma`), checked by
//! Monte Carlo against a known ratio: a window of a sine through a known
//! `H`, on an offset and a drift, with white noise on both signals, and with a lightly damped mode
//! ringing through the window (a transient whose own ratio is not `H`).

mod common;

use exo_diagnose::data::{local_or_white, local_ratio_sigma};
use exo_impedance::frf::{sine_amplitude, sine_ratio};
use num_complex::Complex64;

/// RMS over `trials` windows of the ratio's error over the white estimate
/// and over the one measured beside the line (per component), with a
/// transient of amplitude `ring` (0: none), and the mean of the local
/// variance over the white one.
fn trial(ring: f64, trials: u64) -> (f64, f64, f64) {
    let (w, wn, zeta) = (6.0_f64, 4.3_f64, 0.03_f64);
    let h = Complex64::new(30.0, 6.0);
    let h_ring = Complex64::new(12.0, -4.0);
    let dt = 1e-3;
    let cycles = 6.0;
    // Six whole cycles by the correlator's own rule, as the reduction cuts
    // its windows.
    let longer: Vec<f64> = (0..(cycles * std::f64::consts::TAU / w / dt) as usize + 500)
        .map(|k| k as f64 * dt)
        .collect();
    let n = exo_impedance::frf::whole_cycles(&longer[..longer.len() - 400], w).expect("cycles");
    let t = longer[..n].to_vec();
    let (mut zw, mut zl, mut ratio, mut m) = (0.0, 0.0, 0.0, 0.0);
    for s in 0..trials {
        let nx = common::normals((1000 + s).wrapping_mul(0x9E37_79B9_7F4A_7C15), n);
        let ny = common::normals((5000 + s).wrapping_mul(0x9E37_79B9_7F4A_7C15), n);
        let phase = 0.7 * s as f64;
        let x: Vec<f64> = t
            .iter()
            .zip(&nx)
            .map(|(t, e)| {
                // A posture and a slow drift, as a measured angle has.
                0.8 + 0.05 * t
                    + (w * t).cos()
                    + ring * (-zeta * wn * t).exp() * (wn * t + phase).cos()
                    + 0.02 * e
            })
            .collect();
        let y: Vec<f64> = t
            .iter()
            .zip(&ny)
            .map(|(t, e)| {
                let line = (h * Complex64::from_polar(1.0, w * t)).re;
                let tr = (h_ring
                    * Complex64::from_polar(ring * (-zeta * wn * t).exp(), wn * t + phase))
                .re;
                3.0 - 0.2 * t + line + tr + 0.5 * e
            })
            .collect();
        let (ax, ay) = (
            sine_amplitude(&t, &x, w, true).expect("x"),
            sine_amplitude(&t, &y, w, true).expect("y"),
        );
        let p = sine_ratio(&ax, &ay).expect("ratio");
        let white = [p.cov[0][0].sqrt(), p.cov[1][1].sqrt()];
        let local = local_ratio_sigma(&t, &x, &y, w, p.ratio, ax.amplitude).expect("bins");
        let judged = local_or_white(white, local);
        let err = p.ratio - h;
        zw += (err.re / white[0]).powi(2) + (err.im / white[1]).powi(2);
        zl += (err.re / judged[0]).powi(2) + (err.im / judged[1]).powi(2);
        ratio += local.0 * local.0 / (0.5 * (white[0] * white[0] + white[1] * white[1]));
        m += 2.0;
    }
    ((zw / m).sqrt(), (zl / m).sqrt(), ratio / trials as f64)
}

/// White noise alone: the local estimate's variance is the white one's on
/// average (both estimate the same thing), and the estimate taken (the
/// white one unless the local one is beyond its own 99th percentile) keeps
/// the ratio's error at one standard error.
#[test]
fn with_white_noise_the_local_and_the_white_estimate_agree() {
    let (z_white, z_taken, ratio) = trial(0.0, 200);
    eprintln!("white noise: RMS z white {z_white:.2}, taken {z_taken:.2}, local/white {ratio:.2}");
    assert!((0.85..1.15).contains(&z_white), "RMS z {z_white}");
    assert!((0.85..1.15).contains(&z_taken), "RMS z {z_taken}");
    assert!((0.85..1.2).contains(&ratio), "local/white variance {ratio}");
}

/// A mode at 4.3 rad/s ringing through a window at 6 rad/s (a quarter of
/// the line's amplitude at the start, ζ = 0.03): its leakage biases the
/// ratio by many white standard errors (RMS z 5.9); measured beside the
/// line, the noise covers it, conservatively (RMS z 0.5: the neighbouring
/// frequencies at 4 and 5 rad/s, nearer the mode, hold more of it than
/// leaks into the line at 6).
#[test]
fn a_transient_ringing_through_the_window_is_in_the_local_estimate() {
    let (z_white, z_taken, ratio) = trial(0.25, 200);
    eprintln!("ringing: RMS z white {z_white:.2}, taken {z_taken:.2}, local/white {ratio:.2}");
    assert!(
        z_white > 3.0,
        "the transient is not beyond the white noise: RMS z {z_white}"
    );
    assert!((0.3..1.6).contains(&z_taken), "RMS z {z_taken}");
}

/// By hand: over six whole cycles of ω = 6 rad/s the neighbouring
/// frequencies are ω·k/6 for k = 2…10 but 6, eight of them. A disturbance
/// of amplitude D = 0.3 in `y` exactly at ω·7/6, nothing else, with `x` a
/// unit line: the output error is D at that frequency and 0 at the seven
/// others, so the noise per component is `√(½ D²/8)` = D/4, less what the
/// window's linear trend takes of the disturbance (a sine of 7 cycles is
/// not orthogonal to a ramp: measured 1.1 % of its amplitude, 3 %
/// allowed), and the line's ratio moves by less than 0.1 % for the same
/// reason.
#[test]
fn a_disturbance_on_one_neighbouring_frequency_is_measured_at_its_size() {
    let (w, dt) = (6.0_f64, 1e-3);
    let longer: Vec<f64> = (0..7000).map(|k| k as f64 * dt).collect();
    let n = exo_impedance::frf::whole_cycles(&longer, w).expect("cycles");
    let t = &longer[..n];
    let h = Complex64::new(30.0, 6.0);
    let d = 0.3;
    let x: Vec<f64> = t.iter().map(|t| (w * t).cos()).collect();
    let y: Vec<f64> = t
        .iter()
        .map(|t| (h * Complex64::from_polar(1.0, w * t)).re + d * (w * 7.0 / 6.0 * t).sin())
        .collect();
    let (ax, ay) = (
        sine_amplitude(t, &x, w, true).expect("x"),
        sine_amplitude(t, &y, w, true).expect("y"),
    );
    let p = sine_ratio(&ax, &ay).expect("ratio");
    assert!((p.ratio - h).norm() < 1e-3 * h.norm(), "{}", p.ratio);
    let (sd, bins) = local_ratio_sigma(t, &x, &y, w, p.ratio, ax.amplitude).expect("bins");
    assert_eq!(bins, 8);
    assert!(
        (sd - d / 4.0).abs() < 0.03 * d / 4.0,
        "{sd} against {}",
        d / 4.0
    );
}

/// What the line's own ratio relates is mostly not noise: the same
/// disturbance at ω·7/6 in `x` (amplitude 0.3) and through `H` in `y`
/// would leave the output error `Y − H X` at zero there, but the window's
/// trend, taken out of each signal, takes more of a sine than of a cosine
/// and `H` turns one into the other: measured 0.38 of what the disturbance
/// in `y` alone gives (D/4, above). Less than half of that is required
/// (the estimate errs on the side of more noise; a conjugated DFT fails
/// this).
#[test]
fn a_disturbance_the_ratio_relates_in_both_signals_is_not_noise() {
    let (w, dt) = (6.0_f64, 1e-3);
    let longer: Vec<f64> = (0..7000).map(|k| k as f64 * dt).collect();
    let n = exo_impedance::frf::whole_cycles(&longer, w).expect("cycles");
    let t = &longer[..n];
    let h = Complex64::new(30.0, 6.0);
    let d = Complex64::from_polar(0.3, 0.4);
    let w7 = w * 7.0 / 6.0;
    let x: Vec<f64> = t
        .iter()
        .map(|t| (w * t).cos() + (d * Complex64::from_polar(1.0, w7 * t)).re)
        .collect();
    let y: Vec<f64> = t
        .iter()
        .map(|t| {
            (h * Complex64::from_polar(1.0, w * t)).re
                + (h * d * Complex64::from_polar(1.0, w7 * t)).re
        })
        .collect();
    let (ax, ay) = (
        sine_amplitude(t, &x, w, true).expect("x"),
        sine_amplitude(t, &y, w, true).expect("y"),
    );
    let p = sine_ratio(&ax, &ay).expect("ratio");
    let (sd, _) = local_ratio_sigma(t, &x, &y, w, p.ratio, ax.amplitude).expect("bins");
    assert!(sd < 0.5 * 0.3 / 4.0, "{sd}");
}
