//! The designed multisine (issue 34 item 1) against sums written here: the
//! DFT of its period by direct summation (`f64::cos`/`sin`, not the
//! crate's table), its peak and RMS from the samples, the grid from
//! `2π b fs / N`.

use exo_impedance::multisine::{log_spaced_bins, Multisine};

const TAU: f64 = std::f64::consts::TAU;

/// The DFT of `x` at bin `b` by direct summation.
fn dft(x: &[f64], b: usize) -> (f64, f64) {
    let n = x.len() as f64;
    x.iter().enumerate().fold((0.0, 0.0), |(re, im), (k, v)| {
        let t = TAU * b as f64 * k as f64 / n;
        (re + v * t.cos(), im - v * t.sin())
    })
}

fn peak_rms(x: &[f64]) -> (f64, f64) {
    let peak = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rms = (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt();
    (peak, rms)
}

/// 20 lines over the sine-step protocol's 2–32 rad/s with a 20 s period
/// at 1 kHz: every line on the period's grid (`2π b / 20 s`), in the band,
/// distinct and increasing, the consecutive ratios near the geometric
/// step `(31.73/2.20)^(1/19)` = 1.151 (a bin is 0.314 rad/s: at 2.2 rad/s
/// one bin moves the ratio by 14 %).
#[test]
fn the_lines_lie_on_the_periods_grid_log_spaced_within_the_band() {
    let bins = log_spaced_bins(1000.0, 20_000, [2.0, 32.0], 20).unwrap();
    assert_eq!(bins.len(), 20);
    let d = TAU * 1000.0 / 20_000.0;
    assert_eq!(bins[0], 7, "the first bin at or above 2 rad/s: 7 · {d}");
    assert_eq!(bins[19], 101, "the last at or below 32 rad/s");
    let step = (101.0f64 / 7.0).powf(1.0 / 19.0);
    for w in bins.windows(2) {
        assert!(w[1] > w[0], "{bins:?}");
        let r = w[1] as f64 / w[0] as f64;
        assert!(
            (r / step - 1.0).abs() < 0.15,
            "{bins:?}: ratio {r}, step {step}"
        );
    }
    let ms = Multisine::schroeder(1000.0, 20_000, &bins, &[1.0; 20]).unwrap();
    for (l, &b) in ms.lines().iter().zip(&bins) {
        assert_eq!(l.bin, b);
        assert!((l.omega_rad_s - TAU * b as f64 / 20.0).abs() < 1e-12);
        assert!((2.0..=32.0).contains(&l.omega_rad_s));
    }
    assert!((ms.period_s() - 20.0).abs() < 1e-12);
    assert_eq!((ms.rate_hz(), ms.period_samples()), (1000.0, 20_000));
}

/// Crowded at the low end (a 4 s period: 1.57 rad/s a bin, 12 lines over
/// 2–32 rad/s where log spacing would put several in one bin): the lines
/// stay distinct and in the band; asking more lines than the band has bins
/// is refused.
#[test]
fn crowded_lines_stay_distinct_and_too_many_are_refused() {
    let bins = log_spaced_bins(500.0, 2_000, [2.0, 32.0], 12).unwrap();
    let d = TAU * 500.0 / 2_000.0;
    assert!(bins.windows(2).all(|w| w[1] > w[0]), "{bins:?}");
    assert!(
        bins.iter().all(|&b| (2.0..=32.0).contains(&(b as f64 * d))),
        "{bins:?}"
    );
    // 2–32 rad/s at 1.5708 rad/s a bin: bins 2 … 20, 19 of them.
    assert_eq!(
        log_spaced_bins(500.0, 2_000, [2.0, 32.0], 19).unwrap(),
        (2..=20).collect::<Vec<_>>()
    );
    let err = log_spaced_bins(500.0, 2_000, [2.0, 32.0], 20)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("holds 19 resolved frequencies") && err.contains("20 lines"),
        "{err}"
    );
}

/// One period's DFT holds each line in its own bin with its amplitude and
/// phase (`N A / 2 · e^{jφ}`) and nothing elsewhere: no leakage; and
/// `sample(n)` is the period's sample `n mod N` over two periods.
#[test]
fn the_period_holds_exactly_the_designed_lines() {
    let n = 3_000; // not a power of two
    let bins = log_spaced_bins(1000.0, n, [2.0, 32.0], 8).unwrap();
    let amps: Vec<f64> = (0..8).map(|i| 0.5 + 0.25 * i as f64).collect();
    let ms = Multisine::schroeder(1000.0, n, &bins, &amps).unwrap();
    let x = ms.period();
    assert_eq!(x.len(), n);
    for l in ms.lines() {
        let (re, im) = dft(&x, l.bin);
        let (want_re, want_im) = (
            n as f64 / 2.0 * l.amplitude * l.phase_rad.cos(),
            n as f64 / 2.0 * l.amplitude * l.phase_rad.sin(),
        );
        assert!(
            (re - want_re).abs() < 1e-8 * n as f64,
            "bin {}: {re} vs {want_re}",
            l.bin
        );
        assert!(
            (im - want_im).abs() < 1e-8 * n as f64,
            "bin {}: {im} vs {want_im}",
            l.bin
        );
    }
    for b in 0..60 {
        if !bins.contains(&b) {
            let (re, im) = dft(&x, b);
            assert!(re.hypot(im) < 1e-8 * n as f64, "bin {b} holds {re} {im}");
        }
    }
    for k in 0..2 * n as u64 {
        let want = x[(k % n as u64) as usize];
        assert!((ms.sample(k) - want).abs() < 1e-9, "sample {k}");
    }
    let (peak, rms) = peak_rms(&x);
    assert!((ms.rms() - rms).abs() < 1e-12 * rms.max(1.0));
    assert!((ms.peak() - peak).abs() < 1e-12);
    assert!((ms.crest_factor() - peak / rms).abs() < 1e-12);
}

/// Schroeder's formula by hand for three lines: bins 2, 3, 5, amplitudes
/// 1, 1, √2 (powers ¼, ¼, ½): φ = 0, −2π·¼, −2π(3·¼ + 2·¼) = −2.5π ≡ −π/2.
#[test]
fn schroeders_phases_by_hand() {
    let ms = Multisine::schroeder(100.0, 64, &[2, 3, 5], &[1.0, 1.0, 2f64.sqrt()]).unwrap();
    let phases: Vec<f64> = ms.lines().iter().map(|l| l.phase_rad).collect();
    let want = [
        0.0,
        -std::f64::consts::FRAC_PI_2,
        -std::f64::consts::FRAC_PI_2,
    ];
    for (p, w) in phases.iter().zip(want) {
        assert!((p - w).abs() < 1e-12, "{phases:?}");
    }
}

/// The crest factor, each measured on the samples: random phases (a fixed
/// seed) above Schroeder's, Schroeder's above the clipped design's; the
/// clipped design keeps every line's amplitude and bin; scaled to a peak
/// of 3 Nm its samples peak at 3 Nm.
#[test]
fn schroeder_then_clipping_lower_the_crest_factor() {
    let (rate, n) = (1000.0, 20_000);
    let bins = log_spaced_bins(rate, n, [2.0, 32.0], 20).unwrap();
    let flat = [1.0; 20];
    let schroeder = Multisine::schroeder(rate, n, &bins, &flat).unwrap();
    // Random phases: the same lines with phases from a seeded LCG.
    let mut s = 0x9E37_79B9_7F4A_7C15u64;
    let random_x: Vec<f64> = {
        let phases: Vec<f64> = (0..20)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                TAU * (s >> 11) as f64 / (1u64 << 53) as f64
            })
            .collect();
        (0..n)
            .map(|k| {
                bins.iter()
                    .zip(&phases)
                    .map(|(&b, p)| (TAU * b as f64 * k as f64 / n as f64 + p).cos())
                    .sum()
            })
            .collect()
    };
    let (p, r) = peak_rms(&random_x);
    let cf_random = p / r;
    let (p, r) = peak_rms(&schroeder.period());
    let cf_schroeder = p / r;
    let clipped = schroeder.clipped(200, 0.8).unwrap();
    let (p, r) = peak_rms(&clipped.period());
    let cf_clipped = p / r;
    assert!(
        cf_schroeder < cf_random,
        "Schroeder {cf_schroeder}, random {cf_random}"
    );
    assert!(
        cf_clipped < 0.95 * cf_schroeder,
        "clipped {cf_clipped}, Schroeder {cf_schroeder}"
    );
    for (a, b) in clipped.lines().iter().zip(schroeder.lines()) {
        assert_eq!((a.bin, a.amplitude), (b.bin, b.amplitude));
    }
    let scaled = clipped.scaled_to_peak(3.0).unwrap();
    let (p, _) = peak_rms(&scaled.period());
    assert!((p - 3.0).abs() < 1e-12, "{p}");
    eprintln!("crest factors: random {cf_random:.3}, Schroeder {cf_schroeder:.3}, clipped {cf_clipped:.3}");
}

/// Bad designs are refused, naming what is wrong.
#[test]
fn impossible_designs_are_refused_by_name() {
    let e = |r: Result<Vec<usize>, exo_impedance::ScienceError>| r.unwrap_err().to_string();
    // Nyquist at 100 Hz is π · 100 = 314.16 rad/s: a band reaching it is
    // refused, one just below it is not.
    let beyond = e(log_spaced_bins(100.0, 1000, [2.0, 315.0], 5));
    assert!(
        beyond.contains("beyond Nyquist (314.16 rad/s at 100 Hz)"),
        "{beyond}"
    );
    assert!(log_spaced_bins(100.0, 1000, [2.0, 314.0], 5).is_ok());
    let at = e(log_spaced_bins(
        100.0,
        1000,
        [2.0, std::f64::consts::PI * 100.0],
        5,
    ));
    assert!(at.contains("beyond Nyquist"), "{at}");
    assert!(e(log_spaced_bins(100.0, 1000, [0.1, 0.5], 1)).contains("no frequency"));
    assert!(e(log_spaced_bins(100.0, 1000, [32.0, 2.0], 5)).contains("upper edge"));
    assert!(e(log_spaced_bins(f64::NAN, 1000, [2.0, 32.0], 5)).contains("rate_hz"));
    assert!(e(log_spaced_bins(100.0, 1000, [2.0, f64::INFINITY], 5)).contains("band_rad_s[1]"));
    assert!(e(log_spaced_bins(100.0, 1000, [2.0, 32.0], 0)).contains("at least one line"));
    assert!(e(log_spaced_bins(100.0, 2, [2.0, 32.0], 1)).contains("2 samples"));
    let m = |bins: &[usize], amps: &[f64]| {
        Multisine::schroeder(100.0, 64, bins, amps)
            .unwrap_err()
            .to_string()
    };
    assert!(m(&[2, 32], &[1.0, 1.0]).contains("bin 32"));
    assert!(m(&[0], &[1.0]).contains("bin 0"));
    assert!(m(&[3, 3], &[1.0, 1.0]).contains("excited twice"));
    assert!(m(&[3], &[f64::NAN]).contains("amplitude"));
    assert!(m(&[3], &[1.0, 2.0]).contains("bins and amplitudes"));
    let ms = Multisine::schroeder(100.0, 64, &[3], &[1.0]).unwrap();
    for clip in [0.0, 1.0, -0.5, f64::NAN] {
        let err = ms.clipped(5, clip).unwrap_err().to_string();
        assert!(err.contains("clip"), "{clip}: {err}");
    }
    assert!(ms
        .scaled_to_peak(-1.0)
        .unwrap_err()
        .to_string()
        .contains("peak"));
}
