//! FRF estimation: single-frequency correlation (streaming and block) with
//! its noise estimate, and Welch H1 with coherence, against systems whose
//! response is known.

use exo_impedance::frf::*;
use exo_impedance::{Complex64, DynamicStiffness};

/// Allocations `f` makes on this thread (the binary's allocator is the
/// counting one, `tests/it.rs`).
fn allocations_in(f: impl FnOnce()) -> usize {
    exo_test_support::allocations_on_this_thread(f).1
}

/// Deterministic Gaussian noise (xorshift64* and Box–Muller).
struct Noise(u64);

impl Noise {
    /// The raw xorshift state (the lag data below were drawn this way).
    fn raw(state: u64) -> Self {
        Noise(state)
    }
    fn new(seed: u64) -> Self {
        // splitmix64 of the seed: nearby seeds give unrelated streams.
        let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        Noise((z ^ (z >> 31)) | 1)
    }
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

/// The brief's human: M2 with K = 40, H = 10 Nm/rad, M = 0.11 kg·m².
fn m2() -> DynamicStiffness {
    DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0])
}

const RATE_HZ: f64 = 1000.0;
const THETA_AMP_RAD: f64 = 0.03;

/// A recorded window starting at 0.3 s: θ = 0.8 rad + drift + A sin(ωt + φ),
/// τ = S(jω)·(θ's sinusoid) + 1.5 Nm + drift + white noise (Nm).
struct Record {
    t: Vec<f64>,
    theta: Vec<f64>,
    tau: Vec<f64>,
}

fn record(omega: f64, dur_s: f64, noise_nm: f64, drift_per_s: f64, seed: u64) -> Record {
    let s = m2().response(omega);
    let mut n = Noise::new(seed);
    let mut r = Record {
        t: Vec::new(),
        theta: Vec::new(),
        tau: Vec::new(),
    };
    for k in 0..(dur_s * RATE_HZ).round() as usize {
        let tk = 0.3 + k as f64 / RATE_HZ;
        let z = Complex64::from_polar(THETA_AMP_RAD, omega * tk + 0.4);
        r.t.push(tk);
        r.theta.push(0.8 + 0.1 * drift_per_s * tk + z.im);
        r.tau
            .push(1.5 + drift_per_s * tk + (s * z).im + noise_nm * n.gauss());
    }
    r
}

fn ratio(r: &Record, omega: f64, detrend: bool) -> SinePoint {
    let x = sine_amplitude(&r.t, &r.theta, omega, detrend).unwrap();
    let y = sine_amplitude(&r.t, &r.tau, omega, detrend).unwrap();
    sine_ratio(&x, &y).unwrap()
}

#[test]
fn correlation_recovers_the_response_despite_offset_drift_and_a_partial_cycle() {
    // 5 s holds 1.59, 2.52, 6.33 and 12.65 cycles of these: the remainders
    // are dropped; the offsets and drifts (0.005 rad/s, 0.05 Nm/s) removed.
    for omega in [2.0, 3.17, 7.96, 15.9] {
        let r = record(omega, 5.0, 0.0, 0.05, 1);
        let p = ratio(&r, omega, true);
        let truth = m2().response(omega);
        assert!(
            (p.ratio - truth).norm() < 1e-9 * truth.norm(),
            "ω = {omega}: {} vs {truth}",
            p.ratio
        );
        assert!(p.coherence > 1.0 - 1e-12, "{}", p.coherence);
        assert!(p.noise_rel < 1e-6);
        // Without the trend column the drift leaks into the sinusoid
        // (τ·sin ωτ does not average out over whole cycles): the trend
        // column is what removes it.
        let biased = ratio(&r, omega, false);
        assert!(
            (biased.ratio - truth).norm() > 1e-3 * truth.norm(),
            "ω = {omega}: drift without detrend should bias, got {}",
            biased.ratio
        );
        // Without drift, the mean alone suffices.
        let flat = record(omega, 5.0, 0.0, 0.0, 1);
        let p = ratio(&flat, omega, false);
        assert!((p.ratio - truth).norm() < 1e-9 * truth.norm());
    }
}

#[test]
fn the_window_is_trimmed_to_whole_cycles_and_the_remainder_dropped() {
    let omega = 3.17; // period 1.982 s
    let r = record(omega, 5.0, 0.0, 0.0, 1);
    let n = whole_cycles(&r.t, omega).unwrap();
    let period = std::f64::consts::TAU / omega;
    assert!(((n as f64 / RATE_HZ) - 2.0 * period).abs() <= 1.0 / RATE_HZ);
    let a = sine_amplitude(&r.t, &r.theta, omega, true).unwrap();
    assert_eq!((a.n, a.cycles), (n, 2));
    // The remainder does not enter: garbage in it changes nothing.
    let mut junk = r.theta.clone();
    for v in &mut junk[n..] {
        *v += 5.0;
    }
    assert_eq!(sine_amplitude(&r.t, &junk, omega, true).unwrap(), a);
    // Exactly 4 periods of samples (ω = 2π rad/s, 4000 samples) use all of them.
    let r = record(std::f64::consts::TAU, 4.0, 0.0, 0.0, 1);
    let a = sine_amplitude(&r.t, &r.theta, std::f64::consts::TAU, true).unwrap();
    assert_eq!((a.n, a.cycles), (4000, 4));
}

#[test]
fn streaming_matches_the_block_form_and_allocates_nothing() {
    let omega = 7.96;
    let r = record(omega, 5.0, 0.05, 0.02, 3);
    let mut c = SineCorrelator::<2>::new(omega, r.t[0], true)
        .unwrap()
        .with_names(["theta_e_rad", "tau_c_nm"]);
    let pushes = allocations_in(|| {
        for k in 0..r.t.len() {
            c.push(r.t[k], &[r.theta[k], r.tau[k]]).unwrap();
        }
    });
    assert_eq!(pushes, 0, "push must not allocate");
    let end = r.t[r.t.len() - 1] + 1.0 / RATE_HZ;
    let [x, y] = c.finish(Some(end)).unwrap();
    let bx = sine_amplitude(&r.t, &r.theta, omega, true).unwrap();
    let by = sine_amplitude(&r.t, &r.tau, omega, true).unwrap();
    assert_eq!((x.n, y.n), (bx.n, by.n));
    assert!((x.amplitude - bx.amplitude).norm() < 1e-12);
    assert!((y.amplitude - by.amplitude).norm() < 1e-12);
    assert_eq!(c.whole_cycles(), 6);
    assert_eq!(c.samples_in_whole_cycles(), x.n);
    // Without a window end the last completed boundary is used.
    let [x2, _] = c.finish(None).unwrap();
    assert_eq!(x2.n, x.n);
    // Errors name the channel and the sample; the correlator is unchanged.
    let e = c.push(9.0, &[0.8, f64::NAN]).unwrap_err().to_string();
    assert!(e.contains("tau_c_nm") && e.contains("5000"), "{e}");
    assert!(c.push(1.0, &[0.8, 1.0]).is_err(), "time going backwards");
    assert_eq!(c.samples_pushed(), 5000);
    // Restart reuses the same correlator for another window.
    c.restart(2.0, 100.0).unwrap();
    assert_eq!((c.samples_pushed(), c.whole_cycles()), (0, 0));
    assert!(c.finish(None).is_err(), "less than one cycle");
}

#[test]
fn uneven_and_missing_samples_do_not_bias_it() {
    let omega = 5.0;
    let r = record(omega, 5.0, 0.0, 0.05, 1);
    let mut n = Noise::new(9);
    let keep: Vec<usize> = (0..r.t.len()).filter(|_| n.uniform() > 0.1).collect();
    let pick = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let (t, th, tau) = (pick(&r.t), pick(&r.theta), pick(&r.tau));
    let x = sine_amplitude(&t, &th, omega, true).unwrap();
    let y = sine_amplitude(&t, &tau, omega, true).unwrap();
    let p = sine_ratio(&x, &y).unwrap();
    let truth = m2().response(omega);
    assert!(
        (p.ratio - truth).norm() < 1e-9 * truth.norm(),
        "{}",
        p.ratio
    );
}

/// Over 200 seeds per frequency: the error lies inside the reported 95 %
/// ellipse in 85–99 % of windows, and the rms error matches the reported
/// `noise_rel` within 15 %. At 2 rad/s the 5 s window holds one whole
/// cycle, where the trend column costs precision that a plain `2σ²/N`
/// would not report.
#[test]
fn the_noise_estimate_is_calibrated() {
    let trials = 200;
    for omega in [2.0, 3.17, 15.9] {
        let truth = m2().response(omega);
        let (mut err2, mut pred2, mut inside, mut within_2se) = (0.0, 0.0, 0, 0);
        for seed in 1..=trials {
            let r = record(omega, 5.0, 0.1, 0.05, seed);
            let p = ratio(&r, omega, true);
            let e = p.ratio - truth;
            let [[a, b], [c, d]] = p.cov;
            let det = a * d - b * c;
            // eᵀ cov⁻¹ e, χ² with 2 degrees of freedom: 95 % below 5.991.
            let chi2 = (d * e.re * e.re - (b + c) * e.re * e.im + a * e.im * e.im) / det;
            inside += usize::from(chi2 < 5.991);
            let rel = e.norm() / truth.norm();
            within_2se += usize::from(rel < 2.0 * p.noise_rel);
            err2 += rel * rel;
            pred2 += p.noise_rel * p.noise_rel;
        }
        let frac = inside as f64 / trials as f64;
        assert!((0.85..=0.99).contains(&frac), "ω = {omega}: {frac} inside");
        let frac2 = within_2se as f64 / trials as f64;
        assert!(
            (0.85..=1.0).contains(&frac2),
            "ω = {omega}: {frac2} within 2 se"
        );
        let ratio = (err2 / pred2).sqrt();
        assert!(
            (0.85..1.15).contains(&ratio),
            "ω = {omega}: rms error / predicted = {ratio}"
        );
    }
}

#[test]
fn coherence_is_the_explained_fraction_of_output_power() {
    let omega = 7.96;
    let truth = m2().response(omega);
    for noise in [0.05, 0.3, 1.0] {
        // Output power of the sinusoid over the noise power.
        let q = (truth.norm() * THETA_AMP_RAD).powi(2) / 2.0 / (noise * noise);
        let mean: f64 = (1..=40)
            .map(|seed| ratio(&record(omega, 5.0, noise, 0.0, seed), omega, true).coherence)
            .sum::<f64>()
            / 40.0;
        let expected = q / (1.0 + q);
        assert!(
            (mean - expected).abs() < 0.01,
            "noise {noise}: coherence {mean} vs q/(1+q) = {expected}"
        );
    }
}

#[test]
fn less_than_one_cycle_or_bad_samples_are_errors() {
    let r = record(0.5, 2.0, 0.0, 0.0, 1);
    assert!(sine_amplitude(&r.t, &r.theta, 0.5, true).is_err());
    let mut r = record(5.0, 2.0, 0.0, 0.0, 1);
    r.theta[100] = f64::NAN;
    assert!(sine_amplitude(&r.t, &r.theta, 5.0, true).is_err());
    assert!(sine_amplitude(&r.t, &r.theta[..10], 5.0, true).is_err());
    assert!(sine_amplitude(&r.t, &r.tau, -1.0, true).is_err());
    assert!(sine_amplitude(&r.t, &r.tau, f64::NAN, true).is_err());
    // 400 rad/s sampled at 100 Hz: aliased, the columns cannot be told apart.
    let t: Vec<f64> = (0..500).map(|k| k as f64 * 0.01).collect();
    let y: Vec<f64> = t.iter().map(|t| (400.0 * t).sin()).collect();
    let omega = std::f64::consts::TAU * 100.0; // exactly the sample rate
    assert!(sine_amplitude(&t, &y, omega, true).is_err());
    // An input without a component at ω.
    let zero = SineAmplitude::default();
    assert!(sine_ratio(&zero, &zero).is_err());
}

fn naive_dft(x: &[Complex64]) -> Vec<Complex64> {
    let n = x.len();
    (0..n)
        .map(|k| {
            x.iter()
                .enumerate()
                .map(|(i, xi)| {
                    xi * Complex64::from_polar(
                        1.0,
                        -std::f64::consts::TAU * ((i * k) % n) as f64 / n as f64,
                    )
                })
                .sum()
        })
        .collect()
}

/// A frequency that is not finite and positive is refused naming
/// `omega_rad_s` (not left to fail later for another reason, or to pass):
/// the streaming correlator and the block form alike (issue 23: the
/// cargo-mutants sample left `check_omega → Ok(0.0)` alive).
#[test]
fn a_bad_frequency_is_refused_by_name() {
    let r = record(5.0, 2.0, 0.0, 0.0, 1);
    for bad in [0.0, -1.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let named = |e: exo_impedance::error::ScienceError| {
            matches!(
                e,
                exo_impedance::error::ScienceError::OutOfRange {
                    name: "omega_rad_s",
                    ..
                }
            )
        };
        let e = SineCorrelator::<1>::new(bad, 0.0, true).err();
        assert!(e.is_some_and(named), "SineCorrelator::new({bad})");
        let e = sine_amplitude(&r.t, &r.tau, bad, true).err();
        assert!(e.is_some_and(named), "sine_amplitude at {bad}");
    }
    assert!(SineCorrelator::<1>::new(5.0, 0.0, true).is_ok());
}

/// The shortest Welch segment allowed is 16 samples (7 bins); 15 and 8 are
/// refused. A segment need not be a power of two: 20 samples give bins
/// 1 … 9 at `k · rate / 20`.
#[test]
fn the_shortest_welch_segment_is_sixteen() {
    let x: Vec<f64> = (0..64).map(|k| (0.9 * k as f64).sin()).collect();
    let bins = welch_h1(&x, &x, 100.0, 16).unwrap();
    assert_eq!(bins.len(), 7);
    assert!(welch_h1(&x, &x, 100.0, 15).is_err());
    assert!(welch_h1(&x, &x, 100.0, 8).is_err());
    let bins = welch_h1(&x, &x, 100.0, 20).unwrap();
    assert_eq!(bins.len(), 9);
    for (k, b) in bins.iter().enumerate() {
        let expected = std::f64::consts::TAU * (k + 1) as f64 * 100.0 / 20.0;
        assert!((b.omega_rad_s - expected).abs() < 1e-12, "bin {}", k + 1);
    }
}

/// Any length: powers of two, composites, a prime (Rader's or Bluestein's
/// path), one sample; the empty buffer and a buffer of another length
/// than the plan's are refused.
#[test]
fn fft_matches_a_naive_dft() {
    let mut n = Noise::new(7);
    let lengths: Vec<usize> = (0..=9)
        .map(|l| 1usize << l)
        .chain([3, 12, 100, 997, 1000])
        .collect();
    for len in lengths {
        let x: Vec<Complex64> = (0..len)
            .map(|_| Complex64::new(n.gauss(), n.gauss()))
            .collect();
        let mut f = x.clone();
        fft_in_place(&mut f).unwrap();
        for (k, (fk, dk)) in f.iter().zip(naive_dft(&x)).enumerate() {
            assert!(
                (fk - dk).norm() < 1e-10 * (len as f64).sqrt(),
                "n = {len}, bin {k}"
            );
        }
    }
    assert!(fft_in_place(&mut []).is_err());
    let mut plan = Fft::new(12).unwrap();
    assert_eq!(plan.len(), 12);
    assert!(!plan.is_empty());
    assert_eq!(format!("{plan:?}"), "Fft { len: 12 }");
    assert!(plan.forward(&mut [Complex64::new(0.0, 0.0); 16]).is_err());
}

/// The radix-2 FFT exo used before rustfft (issue 34 item 2), kept here as
/// the reference where both apply.
fn radix2_reference(a: &mut [Complex64]) {
    let n = a.len();
    assert!(n.is_power_of_two());
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            a.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let w = Complex64::from_polar(1.0, -std::f64::consts::TAU / len as f64);
        for start in (0..n).step_by(len) {
            let mut wk = Complex64::new(1.0, 0.0);
            for k in 0..len / 2 {
                let u = a[start + k];
                let v = a[start + k + len / 2] * wk;
                a[start + k] = u + v;
                a[start + k + len / 2] = u - v;
                wk *= w;
            }
        }
        len <<= 1;
    }
}

/// rustfft against the former radix-2 transform at the powers of two the
/// Welch segments used (16 … 8192): the same bins to rounding, one plan
/// reused across buffers.
#[test]
fn fft_matches_the_former_radix_2_transform_where_both_apply() {
    let mut noise = Noise::new(11);
    for log2 in 4..=13 {
        let len = 1usize << log2;
        let mut plan = Fft::new(len).unwrap();
        for _ in 0..2 {
            let x: Vec<Complex64> = (0..len)
                .map(|_| Complex64::new(noise.gauss(), noise.gauss()))
                .collect();
            let (mut a, mut b) = (x.clone(), x);
            plan.forward(&mut a).unwrap();
            radix2_reference(&mut b);
            let scale = (len as f64).sqrt();
            for (k, (ak, bk)) in a.iter().zip(&b).enumerate() {
                assert!((ak - bk).norm() < 1e-11 * scale, "n = {len}, bin {k}");
            }
        }
    }
}

/// A discretised first-order lag y' = (x − y)/τ driven by random input:
/// H(jω) = 1/(1 + jωτ) (zero-order hold, exact at the samples up to the
/// hold's half-sample delay, which the test compensates).
fn lag_response(noise: f64) -> (Vec<f64>, Vec<f64>, f64) {
    let tau: f64 = 0.05;
    let h = 1e-3;
    let a = (-h / tau).exp();
    let mut n = Noise::raw(11);
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
    // A power of two and a segment of 1000 samples (1 Hz bins, issue 34).
    let mut bins = welch_h1(&x, &y, 1000.0, 1024).unwrap();
    let thousand = welch_h1(&x, &y, 1000.0, 1000).unwrap();
    assert_eq!(thousand.len(), 499);
    assert!((thousand[4].omega_rad_s - std::f64::consts::TAU * 5.0).abs() < 1e-9);
    bins.extend(thousand.into_iter().skip(2));
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

/// A biquad `H(z) = (b0 + b1 z⁻¹ + b2 z⁻²)/(1 + a1 z⁻¹ + a2 z⁻²)` (a lightly
/// damped resonance near 60 rad/s at 1 kHz, gain 0.1–2.5 over the lines),
/// its exact response, and its output.
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

impl Biquad {
    fn resonance() -> Self {
        let (r, th): (f64, f64) = (0.98, 0.06);
        Biquad {
            b: [0.003, 0.002, 0.001],
            a: [-2.0 * r * th.cos(), r * r],
        }
    }
    fn response(&self, omega: f64, rate_hz: f64) -> Complex64 {
        let zi = Complex64::from_polar(1.0, -omega / rate_hz);
        (self.b[0] + self.b[1] * zi + self.b[2] * zi * zi)
            / (1.0 + self.a[0] * zi + self.a[1] * zi * zi)
    }
    fn filter(&self, x: &[f64]) -> Vec<f64> {
        let (mut x1, mut x2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
        x.iter()
            .map(|&u| {
                let y = self.b[0] * u + self.b[1] * x1 + self.b[2] * x2
                    - self.a[0] * y1
                    - self.a[1] * y2;
                (x2, x1, y2, y1) = (x1, u, y1, y);
                y
            })
            .collect()
    }
}

/// A multisine with one line every fourth bin of `segment` samples (so the
/// Hann window's leakage, one bin each side, never mixes two lines), random
/// phases, through the biquad: at the excited bins H1 is exact and γ² = 1;
/// output noise leaves H1 unbiased within its standard error and lowers γ².
#[test]
fn h1_on_a_multisine_is_exact_at_the_excited_bins() {
    let segment = 4096;
    let lines: Vec<usize> = (1..=40).map(|j| 4 * j).collect();
    let mut n = Noise::new(5);
    let phases: Vec<f64> = lines
        .iter()
        .map(|_| std::f64::consts::TAU * n.uniform())
        .collect();
    let len = 20 * segment;
    let x: Vec<f64> = (0..len)
        .map(|i| {
            lines
                .iter()
                .zip(&phases)
                .map(|(&k, ph)| {
                    (std::f64::consts::TAU * (k * i) as f64 / segment as f64 + ph).cos()
                })
                .sum::<f64>()
        })
        .collect();
    let sys = Biquad::resonance();
    // The first 4 segments let the transient die (0.98^16384 ≈ 1e-144).
    let skip = 4 * segment;
    let y = sys.filter(&x);
    let bins = welch_h1(&x[skip..], &y[skip..], RATE_HZ, segment).unwrap();
    for &k in &lines {
        let b = &bins[k - 1]; // bins start at k = 1
        let truth = sys.response(b.omega_rad_s, RATE_HZ);
        assert!(
            (b.h - truth).norm() < 1e-9 * truth.norm(),
            "bin {k}: {} vs {truth}",
            b.h
        );
        assert!(b.coherence > 1.0 - 1e-9, "bin {k}: γ² = {}", b.coherence);
    }
    // The excited band: only bins at or next to a line carry input power.
    let groups = band_groups(&bins, 0.9, 1e-3, 0.0, 1e9, 1000);
    let kept: Vec<usize> = groups.concat();
    assert!(kept.len() >= lines.len() - 1);
    assert!(kept.iter().all(|&i| {
        let k = i + 1;
        k % 4 != 2 && k <= 161
    }));
    // Output noise: H1 stays unbiased within its reported standard error
    // and the coherence falls below 1.
    let mut n = Noise::new(6);
    let noisy: Vec<f64> = y.iter().map(|v| v + n.gauss()).collect();
    let bins = welch_h1(&x[skip..], &noisy[skip..], RATE_HZ, segment).unwrap();
    let (mut z2, mut count) = (0.0, 0);
    for &k in &lines {
        let b = &bins[k - 1];
        let truth = sys.response(b.omega_rad_s, RATE_HZ);
        let rel = (b.h - truth).norm() / truth.norm();
        assert!(
            rel < 3.0 * b.noise_rel(),
            "bin {k}: error {rel} vs {}",
            b.noise_rel()
        );
        assert!(b.coherence < 1.0 - 1e-6);
        z2 += (rel / b.noise_rel()).powi(2);
        count += 1;
    }
    // 1 for independent segments; 50 % overlap correlates neighbours a little.
    let rms = (z2 / count as f64).sqrt();
    assert!((0.8..1.4).contains(&rms), "rms error / noise_rel: {rms}");
    let coh: f64 = lines.iter().map(|&k| bins[k - 1].coherence).sum::<f64>() / lines.len() as f64;
    assert!(coh < 0.99 && coh > 0.5, "mean γ² with noise: {coh}");
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
}

/// A bin at `omega` with input power `s_xx` and `H = h`.
fn bin(omega: f64, s_xx: f64, h: Complex64) -> H1Bin {
    H1Bin {
        omega_rad_s: omega,
        h,
        coherence: 0.9,
        s_xx,
        segments: 8,
    }
}

#[test]
fn a_band_is_labelled_at_its_input_power_weighted_frequency() {
    let width = 0.5; // bin spacing (rad/s)
    let h = |w: f64| Complex64::new(30.0 - 0.02 * w * w, 2.0);
    // One strong line at bin 11 (5.5 rad/s) among weak neighbours across a
    // band of bins 2…14 (centre 4 rad/s): the label is the line's.
    let bins: Vec<H1Bin> = (0..20)
        .map(|k| {
            let w = k as f64 * width;
            let p = if k == 11 { 1.0 } else { 1e-3 };
            bin(w, p, h(w))
        })
        .collect();
    let group: Vec<usize> = (2..=14).collect();
    let centre = (bins[2].omega_rad_s + bins[14].omega_rad_s) / 2.0;
    let b = average_bins(&bins, &group).unwrap();
    let line = bins[11].omega_rad_s;
    assert!(
        (b.omega_rad_s - line).abs() < width,
        "labelled {} rad/s, line at {line}, band centre {centre}",
        b.omega_rad_s
    );
    assert!((b.omega_rad_s - centre).abs() > 1.0, "{}", b.omega_rad_s);
    // Exactly Σ ω S_xx / Σ S_xx.
    let (num, den) = group.iter().fold((0.0, 0.0), |(n, d), &i| {
        (n + bins[i].omega_rad_s * bins[i].s_xx, d + bins[i].s_xx)
    });
    assert!((b.omega_rad_s - num / den).abs() < 1e-12);
    // H weighted alike: the line's H within the weak bins' share.
    assert!((b.h - h(line)).norm() / h(line).norm() < 0.01, "{}", b.h);
    // Coherence and S_xx: plain means; segments kept.
    assert!((b.coherence - 0.9).abs() < 1e-12);
    assert!((b.s_xx - den / group.len() as f64).abs() < 1e-15);
    assert_eq!(b.segments, 8);

    // A flat band: the mean frequency of its bins.
    let flat: Vec<H1Bin> = (0..20)
        .map(|k| bin(k as f64 * width, 2.5, h(k as f64 * width)))
        .collect();
    let b = average_bins(&flat, &group).unwrap();
    let mean = group.iter().map(|&i| flat[i].omega_rad_s).sum::<f64>() / group.len() as f64;
    assert!(
        (b.omega_rad_s - mean).abs() < 1e-12,
        "{} vs {mean}",
        b.omega_rad_s
    );
    assert!((b.s_xx - 2.5).abs() < 1e-12);

    // No input power, or no bins: no point.
    let dead: Vec<H1Bin> = (0..4).map(|k| bin(k as f64, 0.0, h(1.0))).collect();
    assert!(average_bins(&dead, &[1, 2]).is_none());
    assert!(average_bins(&flat, &[]).is_none());
}

/// A window of exactly `k` periods of samples is whole: every sample
/// counts (the block ends one mean spacing after its last stamp); one
/// sample short, only `k − 1` periods' do. The stamps are written as a
/// recorder writes them (`t0 + i·h`, from several starts), so the span
/// over the period falls a rounding error either side of `k`: the
/// boundary's tolerance must take both.
#[test]
fn a_window_of_exactly_whole_cycles_keeps_every_sample() {
    let mut checked = 0;
    for (rate_hz, t0) in [
        (1000.0, 0.0),
        (500.0, 12.345),
        (1000.0, 1234.5678),
        (200.0, 0.1),
    ] {
        let h = 1.0 / rate_hz;
        for per_period in [3usize, 7, 50, 63, 100, 157, 630, 1000, 1571] {
            let omega = std::f64::consts::TAU / (per_period as f64 * h);
            for k in 1..=6usize {
                let n = k * per_period;
                let t: Vec<f64> = (0..n).map(|i| t0 + i as f64 * h).collect();
                let what =
                    format!("{k} periods of {per_period} samples at {rate_hz} Hz from {t0} s");
                assert_eq!(whole_cycles(&t, omega), Some(n), "{what}");
                let short = whole_cycles(&t[..n - 1], omega);
                assert_eq!(
                    short,
                    (k > 1).then_some(n - per_period),
                    "{what}, one short"
                );
                checked += 1;
            }
        }
    }
    assert_eq!(checked, 4 * 9 * 6);
}

/// A sine amplitude written by hand (its noise as given, isotropic).
fn amplitude_by_hand(re: f64, im: f64, var: f64, explained: f64) -> SineAmplitude {
    SineAmplitude {
        amplitude: Complex64::new(re, im),
        amplitude_cov: [[var, 0.0], [0.0, var]],
        residual_var: var,
        total_var: 1.0,
        explained_fraction: explained,
        n: 1000,
        cycles: 2,
    }
}

/// The ratio's covariance by hand from `δR = δY/X − R·δX/X`: with
/// isotropic noise `a` on X and `b` on Y, each component's variance is
/// `b/|X|² + a|R|²/|X|²`. X = 2 + j, Y = 3 − j: R = 1 − j, |X|² = 5,
/// |R|² = 2. Input noise alone (a = 0.01): 0.004; output alone (b =
/// 0.01): 0.002; both: 0.006, uncorrelated components; the relative error
/// `√(2·0.006)/√2`; the coherence the smaller explained fraction. A zero
/// output with no noise anywhere: the ratio 0, its relative error
/// infinite (not 0/0).
#[test]
fn the_ratios_noise_by_hand_from_the_input_and_the_output() {
    let x = |a| amplitude_by_hand(2.0, 1.0, a, 0.9);
    let y = |b| amplitude_by_hand(3.0, -1.0, b, 0.7);
    for (a, b, var) in [(0.01, 0.0, 0.004), (0.0, 0.01, 0.002), (0.01, 0.01, 0.006)] {
        let p = sine_ratio(&x(a), &y(b)).unwrap();
        assert!((p.ratio - Complex64::new(1.0, -1.0)).norm() < 1e-15);
        for (got, want) in [
            (p.cov[0][0], var),
            (p.cov[1][1], var),
            (p.cov[0][1], 0.0),
            (p.cov[1][0], 0.0),
        ] {
            assert!((got - want).abs() < 1e-15, "a {a} b {b}: {:?}", p.cov);
        }
        assert!((p.noise_rel - var.sqrt()).abs() < 1e-12, "{}", p.noise_rel);
        assert_eq!(p.coherence, 0.7);
    }
    let zero = sine_ratio(&x(0.0), &amplitude_by_hand(0.0, 0.0, 0.0, 0.0)).unwrap();
    assert_eq!(zero.ratio, Complex64::new(0.0, 0.0));
    assert_eq!(zero.noise_rel, f64::INFINITY);
}
