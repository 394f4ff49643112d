//! The power law's fit (`fit_power_law`) on noisy (K, H) pairs against
//! numpy (issue 23): β0, β1, R² on the log scale and the standard errors of
//! β0 and β1, printed by `tools/python/reference/power_law_values.py`
//! (numpy 2.4.6: `numpy.linalg.lstsq` on `[1, log10 K]`, the covariance from
//! `numpy.linalg.inv(XᵀX)`, not the closed-form sums the crate uses). An
//! exact power law (the crate's own test) cannot tell R² or the errors
//! apart: with no residual both are trivial.

use exo_impedance::power_law::fit_power_law;

fn close(a: f64, b: f64, what: &str) {
    assert!((a - b).abs() <= 1e-9 * b.abs(), "{what}: {a} vs numpy {b}");
}

#[test]
fn a_noisy_power_law_matches_numpy() {
    let k = [20.0, 35.0, 60.0, 110.0, 180.0];
    let h = [5.1, 7.9, 13.0, 20.5, 33.0];
    let f = fit_power_law(&k, &h).unwrap();
    close(f.law.beta0, -0.39854521033748136, "β0");
    close(f.law.beta1, 0.8455388769331217, "β1");
    close(f.r2, 0.9986556716290875, "R²");
    close(f.beta0_std_error.unwrap(), 0.032529085095689456, "SE β0");
    close(f.beta1_std_error.unwrap(), 0.017910914019045092, "SE β1");
    assert_eq!(f.n, 5);
}

#[test]
fn two_pairs_have_no_standard_errors_and_one_h_is_no_spread() {
    let f = fit_power_law(&[10.0, 100.0], &[3.0, 30.0]).unwrap();
    assert!(f.beta0_std_error.is_none() && f.beta1_std_error.is_none());
    close(f.law.beta1, 1.0, "β1");
    // Equal H at every K: no variance to explain, the line (β1 = 0) fits
    // exactly, R² = 1 by convention.
    let f = fit_power_law(&[10.0, 20.0, 40.0], &[5.0, 5.0, 5.0]).unwrap();
    assert_eq!(f.r2, 1.0);
    assert!(f.law.beta1.abs() < 1e-12);
}
