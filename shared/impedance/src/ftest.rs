//! Nested-model F-tests (section "Statistical Analysis", eq. ft) and exact
//! critical values of the F distribution.
//!
//! For a reduced model with `p_r` parameters nested in a full model with
//! `p_f`, fitted to `G` groups of `n_g` complex points each (every complex
//! point two real samples), the paper's statistic is
//!
//! ```text
//!        Σ_g RSS_r,g − Σ_g RSS_f,g      Σ_g (2 n_g − p_f)
//! F  =  ─────────────────────────── · ──────────────────────
//!             Σ_g RSS_f,g              Σ_g (p_f − p_r)
//! ```
//!
//! with `(Σ(p_f − p_r), Σ(2n_g − p_f))` degrees of freedom. With one group per
//! experiment this is `F^sub`, with one per subject `F^exp`, with all of them
//! `F^all`; for M1 or M2 against M3 and `n = 10` this gives the paper's
//! `(9, 144)`, `(10, 160)` and `(90, 1440)`.

use serde::Serialize;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::error::{finite, Result, ScienceError};
use crate::fit::ModelComparison;
use crate::models::ImpedanceModel;

/// The default false-rejection probability of the paper.
pub const DEFAULT_LEVEL: f64 = 0.05;

/// Upper-tail critical value `F_crit` with `P(F > F_crit) = level` for an F
/// distribution with `(df_num, df_den)` degrees of freedom, from the exact
/// inverse of the regularised incomplete beta function.
pub fn f_critical(df_num: f64, df_den: f64, level: f64) -> Result<f64> {
    let dist = f_distribution(df_num, df_den)?;
    finite("level", level)?;
    if !(level > 0.0 && level < 1.0) {
        return Err(ScienceError::OutOfRange {
            name: "level",
            value: level,
            allowed: "(0, 1)",
        });
    }
    Ok(dist.inverse_cdf(1.0 - level))
}

/// Upper-tail probability `P(F > statistic)` (the p-value).
pub fn f_survival(statistic: f64, df_num: f64, df_den: f64) -> Result<f64> {
    let dist = f_distribution(df_num, df_den)?;
    finite("statistic", statistic)?;
    Ok(dist.sf(statistic))
}

fn f_distribution(df_num: f64, df_den: f64) -> Result<FisherSnedecor> {
    for (name, v) in [("df_num", df_num), ("df_den", df_den)] {
        finite(name, v)?;
        if v <= 0.0 {
            return Err(ScienceError::NotPositive { name, value: v });
        }
    }
    FisherSnedecor::new(df_num, df_den).map_err(|_| ScienceError::OutOfRange {
        name: "degrees of freedom",
        value: df_num,
        allowed: "(0, ∞)",
    })
}

/// The outcome of one nested-model F-test.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FTest {
    /// The F statistic (≥ 0).
    pub statistic: f64,
    /// Numerator degrees of freedom.
    pub df_num: f64,
    /// Denominator degrees of freedom.
    pub df_den: f64,
    /// Critical value at `level`.
    pub critical: f64,
    /// `P(F > statistic)`.
    pub p_value: f64,
    /// The false-rejection probability used.
    pub level: f64,
    /// Whether the extra terms of the full model are significant (`statistic > critical`).
    pub significant: bool,
}

/// Residual sums of squares of one group (one subject-experiment) for a
/// reduced and a full model, with the group's number of complex points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NestedRss {
    /// RSS of the reduced model.
    pub rss_reduced: f64,
    /// RSS of the full model.
    pub rss_full: f64,
    /// Number of complex FRF points in the group.
    pub n_points: usize,
}

/// The pooled F-test of eq. ft over `groups`, for a reduced model with
/// `p_reduced` parameters nested in a full one with `p_full`.
pub fn nested_f_test(
    groups: &[NestedRss],
    p_reduced: usize,
    p_full: usize,
    level: f64,
) -> Result<FTest> {
    if p_full <= p_reduced {
        return Err(ScienceError::Infeasible(format!(
            "F-test needs the full model to have more parameters than the reduced one (got {p_full} and {p_reduced})"
        )));
    }
    if groups.is_empty() {
        return Err(ScienceError::TooFewSamples {
            what: "F-test".into(),
            needed: 1,
            given: 0,
        });
    }
    let mut rss_r = 0.0;
    let mut rss_f = 0.0;
    let mut df_den = 0usize;
    for (index, g) in groups.iter().enumerate() {
        for (series, value) in [("rss_reduced", g.rss_reduced), ("rss_full", g.rss_full)] {
            if !value.is_finite() || value < 0.0 {
                return Err(ScienceError::BadSample {
                    series,
                    index,
                    value,
                    why: "a residual sum of squares must be finite and non-negative",
                });
            }
        }
        if 2 * g.n_points <= p_full {
            return Err(ScienceError::TooFewSamples {
                what: format!("F-test group {index} (full model with {p_full} parameters)"),
                needed: p_full / 2 + 1,
                given: g.n_points,
            });
        }
        rss_r += g.rss_reduced;
        rss_f += g.rss_full;
        df_den += 2 * g.n_points - p_full;
    }
    if rss_f <= 0.0 {
        return Err(ScienceError::Infeasible(
            "the full model fits the data exactly (RSS = 0), so the F-statistic is undefined"
                .into(),
        ));
    }
    let df_num = (groups.len() * (p_full - p_reduced)) as f64;
    let df_den = df_den as f64;
    // A least-squares full model can never fit worse than its nested model;
    // a negative difference is rounding, so clamp it at zero.
    let statistic = ((rss_r - rss_f) / rss_f * df_den / df_num).max(0.0);
    let critical = f_critical(df_num, df_den, level)?;
    Ok(FTest {
        statistic,
        df_num,
        df_den,
        critical,
        p_value: f_survival(statistic, df_num, df_den)?,
        level,
        significant: statistic > critical,
    })
}

/// The paper's pair of tests, M1 against M3 and M2 against M3.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperFTests {
    /// `F_{M1−M3}`: significance of the hysteretic term `jH` added to M1.
    pub m1_vs_m3: FTest,
    /// `F_{M2−M3}`: significance of the viscous term `Bs` added to M2.
    pub m2_vs_m3: FTest,
}

/// `F_{M1−M3}` and `F_{M2−M3}` pooled over a set of model comparisons (one per
/// subject-experiment): pass one subject's experiments for `F^sub`, one
/// experiment's subjects for `F^exp`, or all of them for `F^all`.
///
/// The residual sums are the fits' [`crate::ModelFit::chi2`]: the paper's RSS
/// when the points carry no noise estimate, the noise-weighted RSS when they
/// do (a deviation from the paper: each group's residual is then measured
/// in units of its own noise, so experiments with larger torques do not
/// dominate the pooled statistic).
pub fn paper_f_tests(comparisons: &[ModelComparison], level: f64) -> Result<PaperFTests> {
    let groups = |reduced: ImpedanceModel| -> Vec<NestedRss> {
        comparisons
            .iter()
            .map(|c| NestedRss {
                rss_reduced: c.get(reduced).chi2,
                rss_full: c.m3.chi2,
                n_points: c.m3.n_points,
            })
            .collect()
    };
    Ok(PaperFTests {
        m1_vs_m3: nested_f_test(&groups(ImpedanceModel::M1), 3, 4, level)?,
        m2_vs_m3: nested_f_test(&groups(ImpedanceModel::M2), 3, 4, level)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn critical_value_round_trips_through_the_cdf() {
        for (d1, d2, level) in [(1.0, 10.0, 0.05), (9.0, 144.0, 0.01), (3.0, 7.0, 0.2)] {
            let c = f_critical(d1, d2, level).unwrap();
            let p = f_survival(c, d1, d2).unwrap();
            assert!(
                (p - level).abs() < 1e-9,
                "({d1},{d2}) level {level}: sf(crit) = {p}"
            );
        }
    }

    #[test]
    fn bad_levels_and_dofs_are_errors() {
        assert!(f_critical(9.0, 144.0, 0.0).is_err());
        assert!(f_critical(9.0, 144.0, 1.0).is_err());
        assert!(f_critical(0.0, 144.0, 0.05).is_err());
        assert!(f_critical(f64::NAN, 144.0, 0.05).is_err());
    }

    #[test]
    fn exact_full_fit_is_reported_not_divided_by_zero() {
        let g = [NestedRss {
            rss_reduced: 1.0,
            rss_full: 0.0,
            n_points: 10,
        }];
        assert!(matches!(
            nested_f_test(&g, 3, 4, 0.05),
            Err(ScienceError::Infeasible(_))
        ));
    }
}
