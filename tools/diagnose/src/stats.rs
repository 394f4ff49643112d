//! Distribution functions the tests of several modules share (the
//! diagnosis, [`crate::engine`], and the static equilibrium's check,
//! [`crate::equilibrium`]): one place below them, with no import from the
//! rest of the crate.

use statrs::distribution::{ChiSquared, ContinuousCDF, Normal};

/// The survival function of the χ² distribution with `dof` degrees of
/// freedom at `x` (NaN when `dof ≤ 0` or `x` is not finite).
pub(crate) fn chi2_sf(x: f64, dof: f64) -> f64 {
    if dof <= 0.0 || !x.is_finite() {
        return f64::NAN;
    }
    ChiSquared::new(dof).map_or(f64::NAN, |d| d.sf(x))
}

/// The standard normal distribution's quantile at `p` (clamped into
/// `[1e-300, 1 − 1e-16]`).
pub(crate) fn normal_quantile(p: f64) -> f64 {
    Normal::new(0.0, 1.0).map_or(f64::NAN, |n| n.inverse_cdf(p.clamp(1e-300, 1.0 - 1e-16)))
}
