//! Distribution functions the tests of several modules share (the
//! diagnosis, [`crate::engine`], and the static equilibrium's check,
//! [`crate::equilibrium`]): one place below them, with no import from the
//! rest of the crate.

use statrs::distribution::{ChiSquared, ContinuousCDF, Normal, StudentsT};

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

/// The standard normal deviate with the same tail probability as `t` has
/// under Student's t with `dof` degrees of freedom: a residual divided by a
/// σ estimated from `dof` values, made comparable with a normal one (its
/// square then has the χ² distribution's one degree of freedom). `t` itself
/// when `dof` is not positive and finite.
pub(crate) fn t_as_normal(t: f64, dof: f64) -> f64 {
    if !(dof > 0.0 && dof.is_finite() && t.is_finite()) {
        return t;
    }
    let Ok(d) = StudentsT::new(0.0, 1.0, dof) else {
        return t;
    };
    // From the tail on the residual's side, so a large |t| keeps its
    // precision.
    let tail = d.sf(t.abs());
    (-normal_quantile(tail)).copysign(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Student's t quantiles from the tables (two-sided 5 % and 1 % at 6 and
    /// 8 degrees of freedom: 2.447, 3.707, 2.306, 3.355) map onto the
    /// normal's 1.960 and 2.576, with their sign; a huge number of degrees
    /// of freedom changes nothing; none leaves `t` as it is.
    #[test]
    fn a_t_residual_is_taken_at_the_normal_quantile_of_its_tail() {
        for (t, dof, z) in [
            (2.447, 6.0, 1.960),
            (3.707, 6.0, 2.576),
            (2.306, 8.0, 1.960),
            (3.355, 8.0, 2.576),
        ] {
            assert!((t_as_normal(t, dof) - z).abs() < 2e-3, "t {t}, dof {dof}");
            assert!((t_as_normal(-t, dof) + z).abs() < 2e-3, "t −{t}, dof {dof}");
        }
        assert!((t_as_normal(1.5, 1e7) - 1.5).abs() < 1e-5);
        assert_eq!(t_as_normal(0.0, 6.0), 0.0);
        assert_eq!(t_as_normal(2.0, 0.0), 2.0);
        assert_eq!(t_as_normal(2.0, f64::INFINITY), 2.0);
        // Far in the tail the precision holds: t(6) at 20 has tail 5.9e-7.
        let far = t_as_normal(20.0, 6.0);
        assert!(far > 4.8 && far < 5.0, "{far}");
    }
}
