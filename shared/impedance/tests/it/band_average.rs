//! Band averaging of H1 bins (`average_bins`, `band_groups`, `select_band`)
//! on values computed by hand (issue 23).

use exo_impedance::frf::{average_bins, band_groups, select_band, H1Bin};
use exo_impedance::Complex64;

fn bin(omega: f64, re: f64, im: f64, coherence: f64, s_xx: f64) -> H1Bin {
    H1Bin {
        omega_rad_s: omega,
        h: Complex64::new(re, im),
        coherence,
        s_xx,
        segments: 7,
    }
}

fn near(what: &str, got: f64, want: f64) {
    assert!(
        (got - want).abs() <= 1e-12 * want.abs().max(1.0),
        "{what}: {got} vs {want}"
    );
}

#[test]
fn average_bins_weights_h_and_omega_by_input_power() {
    let bins = [
        bin(2.0, 1.0, 1.0, 0.9, 1.0),
        bin(3.0, 3.0, -1.0, 0.5, 3.0),
        bin(5.0, 0.0, 2.0, 0.4, 4.0),
    ];
    // Two bins, weights 1 and 3 (Σ = 4):
    // ω = (2·1 + 3·3)/4 = 2.75; H = ((1 + j) + 3(3 − j))/4 = 2.5 − 0.5j;
    // coherence (0.9 + 0.5)/2 = 0.7; S_xx 4/2 = 2.
    let a = average_bins(&bins, &[0, 1]).unwrap();
    near("ω", a.omega_rad_s, 2.75);
    near("Re H", a.h.re, 2.5);
    near("Im H", a.h.im, -0.5);
    near("coherence", a.coherence, 0.7);
    near("S_xx", a.s_xx, 2.0);
    assert_eq!(a.segments, 7);
    // Three bins (Σ = 8): ω = (2 + 9 + 20)/8 = 3.875;
    // H = ((1 + j) + (9 − 3j) + 8j)/8 = 1.25 + 0.75j; coherence 1.8/3 = 0.6;
    // S_xx 8/3.
    let a = average_bins(&bins, &[0, 1, 2]).unwrap();
    near("ω", a.omega_rad_s, 3.875);
    near("Re H", a.h.re, 1.25);
    near("Im H", a.h.im, 0.75);
    near("coherence", a.coherence, 0.6);
    near("S_xx", a.s_xx, 8.0 / 3.0);
    // The order of the group does not matter; an index past the end is ignored.
    let b = average_bins(&bins, &[2, 1, 0, 99]).unwrap();
    near("ω reordered", b.omega_rad_s, 3.875);
    near("coherence reordered", b.coherence, 0.6);
    // Nothing to average.
    assert!(average_bins(&bins, &[]).is_none());
    assert!(average_bins(&[bin(2.0, 1.0, 0.0, 1.0, 0.0)], &[0]).is_none());
}

/// An FRF linear in ω across the band is unbiased at the reported
/// (power-weighted) frequency: Σ w (a + b ω)/Σ w = a + b ω̄.
#[test]
fn a_linear_frf_is_unbiased_at_the_reported_frequency() {
    let (a, b) = (Complex64::new(4.0, -1.0), Complex64::new(0.5, 0.25));
    let weights = [0.2, 5.0, 1.0, 0.7, 3.3];
    let bins: Vec<H1Bin> = weights
        .iter()
        .enumerate()
        .map(|(i, &w)| {
            let om = 6.0 + 0.4 * i as f64;
            let h = a + b * om;
            bin(om, h.re, h.im, 0.95, w)
        })
        .collect();
    let avg = average_bins(&bins, &[0, 1, 2, 3, 4]).unwrap();
    let sw: f64 = weights.iter().sum();
    let om_bar: f64 = weights
        .iter()
        .enumerate()
        .map(|(i, w)| w * (6.0 + 0.4 * i as f64))
        .sum::<f64>()
        / sw;
    near("ω̄", avg.omega_rad_s, om_bar);
    let want = a + b * om_bar;
    near("Re H", avg.h.re, want.re);
    near("Im H", avg.h.im, want.im);
}

/// Twelve bins at ω = 0.5 k (k = 0..11). The two lowest are skipped; bin 5
/// fails the coherence threshold and bin 9 the relative power threshold.
/// The kept range [1.0, 5.5] rad/s split into three log-equal bands has
/// edges 1, 5.5^(1/3) = 1.765, 5.5^(2/3) = 3.116 and 5.5:
/// {1.0, 1.5}, {2.0, 3.0}, {3.5, 4.0, 5.0, 5.5}.
#[test]
fn band_groups_and_select_band_by_hand() {
    let bins: Vec<H1Bin> = (0..12)
        .map(|k| {
            let coh = if k == 5 { 0.1 } else { 0.9 };
            let sxx = if k == 9 { 0.01 } else { 1.0 + k as f64 };
            bin(0.5 * k as f64, k as f64, 0.0, coh, sxx)
        })
        .collect();
    let g = band_groups(&bins, 0.5, 0.05, 0.0, 100.0, 3);
    assert_eq!(g, vec![vec![2, 3], vec![4, 6], vec![7, 8, 10, 11]]);
    // A frequency window: [1.6, 4.2] keeps bins 4, 6, 7, 8 (ω 2, 3, 3.5, 4);
    // two bands with edges 2, √(2·4) = 2.83, 4: {2}, {3, 3.5, 4}.
    let g = band_groups(&bins, 0.5, 0.05, 1.6, 4.2, 2);
    assert_eq!(g, vec![vec![4], vec![6, 7, 8]]);
    // select_band averages each group: the second band's weights are
    // S_xx = 7, 8, 9 at ω 3, 3.5, 4 with H = k = 6, 7, 8:
    // ω = (21 + 28 + 36)/24 = 85/24, H = (42 + 56 + 72)/24 = 170/24.
    let s = select_band(&bins, 0.5, 0.05, 1.6, 4.2, 2);
    assert_eq!(s.len(), 2);
    near("band 1 ω", s[0].omega_rad_s, 2.0);
    near("band 2 ω", s[1].omega_rad_s, 85.0 / 24.0);
    near("band 2 H", s[1].h.re, 170.0 / 24.0);
    near("band 2 coherence", s[1].coherence, 0.9);
    near("band 2 S_xx", s[1].s_xx, 8.0);
}

/// A bin without input power is never kept, even with no relative power
/// threshold (its H = S_xy/S_xx is undefined).
#[test]
fn a_bin_without_input_power_is_never_kept() {
    let bins: Vec<H1Bin> = (0..6)
        .map(|k| {
            bin(
                1.0 + k as f64,
                1.0,
                0.0,
                0.9,
                if k == 3 { 0.0 } else { 1.0 },
            )
        })
        .collect();
    let g = band_groups(&bins, 0.0, 0.0, 0.0, 100.0, 1);
    assert_eq!(g, vec![vec![2, 4, 5]]);
}
