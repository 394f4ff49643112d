//! The nested F-test's refusals (issue 23: mutants of these checks survived
//! `tools/scripts/mutants.sh`): a residual sum of squares that is NaN,
//! infinite or negative is named with its group, and a group with no
//! residual degree of freedom (`2 n ≤ p_full`) is refused with the number of
//! points it needs, `⌊p_full/2⌋ + 1`, computed here by hand.

use exo_impedance::ftest::{nested_f_test, NestedRss};
use exo_impedance::ScienceError;

fn g(rss_reduced: f64, rss_full: f64, n_points: usize) -> NestedRss {
    NestedRss {
        rss_reduced,
        rss_full,
        n_points,
    }
}

#[test]
fn a_bad_residual_sum_is_refused_with_its_group() {
    for bad in [f64::NAN, f64::INFINITY, -1.0] {
        for (groups, series) in [
            ([g(2.0, 1.0, 10), g(bad, 1.0, 10)], "rss_reduced"),
            ([g(2.0, 1.0, 10), g(2.0, bad, 10)], "rss_full"),
        ] {
            match nested_f_test(&groups, 3, 4, 0.05) {
                Err(ScienceError::BadSample {
                    series: s, index, ..
                }) => {
                    assert_eq!((s, index), (series, 1), "{bad}");
                }
                other => panic!("{bad} in {series}: {other:?}"),
            }
        }
    }
}

#[test]
fn a_group_without_residual_freedom_is_refused_with_what_it_needs() {
    // (p_reduced, p_full, n_points, needed = ⌊p_full/2⌋ + 1): 2n ≤ p_full.
    for (p_r, p_f, n, needed) in [
        (1, 2, 1, 2),
        (3, 4, 2, 3),
        (3, 4, 1, 3),
        (5, 7, 3, 4),
        (1, 2, 0, 2),
    ] {
        match nested_f_test(&[g(2.0, 1.0, 10), g(2.0, 1.0, n)], p_r, p_f, 0.05) {
            Err(ScienceError::TooFewSamples {
                needed: got, given, ..
            }) => {
                assert_eq!((got, given), (needed, n), "p_full {p_f}, n {n}");
            }
            other => panic!("p_full {p_f}, n {n}: {other:?}"),
        }
    }
    // One point more than that is enough: 2n − p_full = 1 or 2 residual dofs.
    for (p_r, p_f, n, df_den) in [(1, 2, 2, 2.0), (3, 4, 3, 2.0), (5, 7, 4, 1.0)] {
        let t = nested_f_test(&[g(2.0, 1.0, n)], p_r, p_f, 0.05).unwrap();
        assert_eq!(t.df_den, df_den);
        assert_eq!(t.df_num, (p_f - p_r) as f64);
    }
}

/// More than one added parameter (p_reduced = 1 in p_full = 4, three added),
/// two groups of 10 points, computed by hand: df_num = 2·(4 − 1) = 6,
/// df_den = 2·(20 − 4) = 32, RSS_r = 1.25 + 1.5 = 2.75, RSS_f = 2,
/// F = 0.75/2 · 32/6 = 2. The paper's tests all add one parameter, where
/// `groups · (p_f − p_r)` and `groups / (p_f − p_r)` agree.
#[test]
fn three_added_parameters_by_hand() {
    let t = nested_f_test(&[g(1.25, 1.0, 10), g(1.5, 1.0, 10)], 1, 4, 0.05).unwrap();
    assert_eq!((t.df_num, t.df_den), (6.0, 32.0));
    assert!((t.statistic - 2.0).abs() < 1e-12, "F = {}", t.statistic);
    let rel = |a: f64, b: f64| ((a - b) / b).abs();
    // scipy.stats.f.sf(2.0, 6, 32)
    assert!(
        rel(t.p_value, 0.09482202731679086) < 1e-6,
        "p = {}",
        t.p_value
    );
    // scipy.stats.f.isf(0.05, 6, 32)
    assert!(
        rel(t.critical, 2.399079630698473) < 1e-6,
        "crit = {}",
        t.critical
    );
    assert!(!t.significant);
}
