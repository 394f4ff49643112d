//! FRF estimation: single-frequency correlation with its noise estimate, and
//! Welch H1 with coherence, against systems whose response is known.

use exo_impedance::frf::*;
use exo_impedance::{Complex64, DynamicStiffness};

/// Deterministic Gaussian noise (xorshift64* and Box–Muller).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn m2() -> DynamicStiffness {
    DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0])
}

/// θ = 0.8 + drift + A sin(ωt + φ), τ = S(jω)·(θ sinusoid) + offset + noise.
fn record(omega: f64, dur_s: f64, noise_nm: f64, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let s = m2().response(omega);
    let mut n = Noise(seed);
    let (mut t, mut th, mut tau) = (Vec::new(), Vec::new(), Vec::new());
    let amp = 0.03;
    for k in 0..(dur_s * 1000.0) as usize {
        let tk = 0.3 + k as f64 * 1e-3;
        let z = Complex64::from_polar(amp, omega * tk + 0.4);
        t.push(tk);
        th.push(0.8 + 0.002 * tk + z.im);
        tau.push(1.5 + (s * z).im + noise_nm * n.gauss());
    }
    (t, th, tau)
}

#[test]
fn correlation_recovers_the_response_despite_offset_drift_and_a_partial_cycle() {
    for omega in [2.0, 3.17, 7.96, 15.9] {
        let (t, th, tau) = record(omega, 5.0, 0.0, 1);
        let x = sine_amplitude(&t, &th, omega, true).unwrap();
        let y = sine_amplitude(&t, &tau, omega, true).unwrap();
        let p = sine_ratio(&x, &y).unwrap();
        let truth = m2().response(omega);
        assert!(
            (p.ratio - truth).norm() < 1e-6 * truth.norm(),
            "ω = {omega}: {} vs {truth}",
            p.ratio
        );
        assert!(p.coherence > 0.999_999, "{}", p.coherence);
        assert!(p.noise_rel < 1e-6);
    }
}

#[test]
fn the_noise_estimate_is_calibrated() {
    // Over many seeds, |error|/|S| should fall within the reported relative
    // standard error (a Rayleigh-distributed modulus: P(r < σ√2·…)) — check
    // that about 86 % lie within 2σ_rel/√2·… by comparing mean squares.
    let omega = 3.17;
    let truth = m2().response(omega);
    let (mut err2, mut pred2) = (0.0, 0.0);
    let mut within = 0;
    let trials = 200;
    for seed in 1..=trials {
        let (t, th, tau) = record(omega, 5.0, 0.05, seed);
        let x = sine_amplitude(&t, &th, omega, true).unwrap();
        let y = sine_amplitude(&t, &tau, omega, true).unwrap();
        let p = sine_ratio(&x, &y).unwrap();
        let e = ((p.ratio - truth) / truth).norm();
        err2 += e * e;
        pred2 += p.noise_rel * p.noise_rel;
        if e < 2.0 * p.noise_rel / std::f64::consts::SQRT_2 {
            within += 1;
        }
        assert!(p.coherence < 1.0 && p.coherence > 0.5);
    }
    let ratio = (err2 / pred2).sqrt();
    assert!(
        (0.85..1.15).contains(&ratio),
        "rms error / predicted = {ratio}"
    );
    // A complex Gaussian error with E|e|² = σ²: P(|e| < √2 σ) = 1 − e^{−2} ≈ 0.865.
    let frac = within as f64 / trials as f64;
    assert!((0.78..0.94).contains(&frac), "{frac}");
}

#[test]
fn less_than_one_cycle_or_bad_samples_are_errors() {
    let (t, th, _) = record(0.5, 2.0, 0.0, 1);
    assert!(sine_amplitude(&t, &th, 0.5, true).is_err());
    let (t, mut th, _) = record(5.0, 2.0, 0.0, 1);
    th[100] = f64::NAN;
    assert!(sine_amplitude(&t, &th, 5.0, true).is_err());
    assert!(sine_amplitude(&t, &th[..10], 5.0, true).is_err());
    assert!(sine_amplitude(&t, &th, -1.0, true).is_err());
}

#[test]
fn fft_matches_a_naive_dft() {
    let mut n = Noise(7);
    let x: Vec<Complex64> = (0..64)
        .map(|_| Complex64::new(n.gauss(), n.gauss()))
        .collect();
    let mut f = x.clone();
    fft_in_place(&mut f).unwrap();
    for (k, fk) in f.iter().enumerate() {
        let d: Complex64 = x
            .iter()
            .enumerate()
            .map(|(i, xi)| {
                xi * Complex64::from_polar(1.0, -std::f64::consts::TAU * (i * k) as f64 / 64.0)
            })
            .sum();
        assert!((fk - d).norm() < 1e-9, "bin {k}");
    }
    assert!(fft_in_place(&mut [Complex64::new(0.0, 0.0); 12]).is_err());
}

/// A discretised first-order lag y' = (x − y)/τ driven by random input:
/// H(jω) = 1/(1 + jωτ) (zero-order hold, exact at the samples up to the
/// hold's half-sample delay, which the test compensates).
fn lag_response(noise: f64) -> (Vec<f64>, Vec<f64>, f64) {
    let tau: f64 = 0.05;
    let h = 1e-3;
    let a = (-h / tau).exp();
    let mut n = Noise(11);
    let (mut x, mut y) = (Vec::new(), Vec::new());
    let mut state = 0.0;
    for _ in 0..60_000 {
        let u = n.gauss();
        x.push(u);
        y.push(state + noise * n.gauss());
        state = a * state + (1.0 - a) * u;
    }
    (x, y, tau)
}

#[test]
fn h1_recovers_a_known_system_with_coherence_near_one() {
    let (x, y, tau) = lag_response(0.0);
    let bins = welch_h1(&x, &y, 1000.0, 1024).unwrap();
    // From the third bin up (the lowest carry the window's leakage of the
    // removed segment mean; select_band leaves them out).
    for b in bins.iter().skip(2).filter(|b| b.omega_rad_s < 100.0) {
        let w = b.omega_rad_s;
        let h = 1e-3;
        // ZOH-discretised lag, output sampled one step after the input.
        let z = Complex64::from_polar(1.0, w * h);
        let a = (-h / tau).exp();
        let truth = (1.0 - a) / (z - a);
        assert!(
            (b.h - truth).norm() < 0.02 * truth.norm(),
            "ω = {w}: {} vs {truth}",
            b.h
        );
        assert!(b.coherence > 0.98, "ω = {w}: γ² = {}", b.coherence);
    }
    let (x, y, _) = lag_response(0.5);
    let noisy = welch_h1(&x, &y, 1000.0, 1024).unwrap();
    let mean_coh = |bs: &[H1Bin]| {
        let v: Vec<f64> = bs
            .iter()
            .filter(|b| b.omega_rad_s > 5.0 && b.omega_rad_s < 50.0)
            .map(|b| b.coherence)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    assert!(mean_coh(&noisy) < mean_coh(&bins) - 0.1);
}

#[test]
fn band_selection_keeps_the_excited_coherent_bins_in_log_spaced_points() {
    let (x, y, _) = lag_response(0.0);
    let bins = welch_h1(&x, &y, 1000.0, 1024).unwrap();
    let pts = select_band(&bins, 0.9, 1e-3, 1.0, 60.0, 12);
    // 6.1 rad/s bins from the third (18 rad/s) to 60 rad/s: ~7 bins, one per non-empty band.
    assert!(pts.len() >= 5 && pts.len() <= 12, "{}", pts.len());
    assert!(pts.windows(2).all(|w| w[1].omega_rad_s > w[0].omega_rad_s));
    assert!(pts
        .iter()
        .all(|p| p.omega_rad_s >= 1.0 && p.omega_rad_s <= 60.0));
    assert!(select_band(&bins, 1.1, 0.0, 1.0, 60.0, 12).is_empty());
    assert!(welch_h1(&x[..100], &y[..100], 1000.0, 1024).is_err());
    assert!(welch_h1(&x, &y, 1000.0, 1000).is_err());
}
