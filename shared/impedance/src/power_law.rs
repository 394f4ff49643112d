//! The stiffness–hysteresis power law (section "Complex Stiffness Results").
//!
//! `log10 H = β0 + β1 log10 K`, i.e. `H = 10^β0 · K^β1`, so the hysteretic loss
//! factor is `c = H/K = 10^β0 · K^(β1−1)` (eq. ch), the damping ratio of M2 is
//! `ζ = c/2` and its low-frequency phase `φ = atan(c)` (eq. zt-m2).

use serde::Serialize;

use crate::error::{finite, positive, Result, ScienceError};

/// A subject's power law `H = 10^β0 · K^β1` (K and H in Nm/rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PowerLaw {
    /// Intercept β0 of the log-log regression.
    pub beta0: f64,
    /// Slope β1 of the log-log regression.
    pub beta1: f64,
}

impl PowerLaw {
    /// A power law with finite coefficients.
    pub fn new(beta0: f64, beta1: f64) -> Result<Self> {
        finite("beta0", beta0)?;
        finite("beta1", beta1)?;
        Ok(PowerLaw { beta0, beta1 })
    }

    /// Hysteretic damping `H = 10^β0 K^β1` (Nm/rad) at stiffness `K` (Nm/rad).
    pub fn hysteretic_damping(&self, k_nm_per_rad: f64) -> Result<f64> {
        positive("k_nm_per_rad", k_nm_per_rad)?;
        Ok(10f64.powf(self.beta0) * k_nm_per_rad.powf(self.beta1))
    }

    /// Loss factor `c = 10^β0 · K^(β1−1)` (eq. ch).
    pub fn loss_factor(&self, k_nm_per_rad: f64) -> Result<f64> {
        positive("k_nm_per_rad", k_nm_per_rad)?;
        Ok(10f64.powf(self.beta0) * k_nm_per_rad.powf(self.beta1 - 1.0))
    }

    /// Damping ratio `ζ = c/2` of M2 at stiffness `K` (eq. zt-m2).
    pub fn damping_ratio(&self, k_nm_per_rad: f64) -> Result<f64> {
        Ok(damping_ratio(self.loss_factor(k_nm_per_rad)?))
    }

    /// Low-frequency phase `φ = atan(c)` (degrees) of M2 at stiffness `K` (eq. zt-m2).
    pub fn low_frequency_phase_deg(&self, k_nm_per_rad: f64) -> Result<f64> {
        Ok(low_frequency_phase_deg(self.loss_factor(k_nm_per_rad)?))
    }
}

/// Damping ratio `ζ = c/2` of a complex-stiffness resonance (eq. zt-m2).
pub fn damping_ratio(loss_factor: f64) -> f64 {
    loss_factor / 2.0
}

/// Low-frequency phase `atan(c)` in degrees (eq. zt-m2).
pub fn low_frequency_phase_deg(loss_factor: f64) -> f64 {
    loss_factor.atan().to_degrees()
}

/// An ordinary least-squares fit of `log10 H` on `log10 K`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PowerLawFit {
    /// The fitted law.
    pub law: PowerLaw,
    /// Coefficient of determination on the log scale.
    pub r2: f64,
    /// Number of (K, H) pairs.
    pub n: usize,
    /// Standard error of β0 (`None` with fewer than three pairs).
    pub beta0_std_error: Option<f64>,
    /// Standard error of β1 (`None` with fewer than three pairs).
    pub beta1_std_error: Option<f64>,
}

/// Fits the power law to paired stiffness and hysteretic damping values
/// (Nm/rad), both strictly positive (section "Complex Stiffness Results").
pub fn fit_power_law(k_nm_per_rad: &[f64], h_nm_per_rad: &[f64]) -> Result<PowerLawFit> {
    if k_nm_per_rad.len() != h_nm_per_rad.len() {
        return Err(ScienceError::LengthMismatch {
            what: "power-law fit",
            left: k_nm_per_rad.len(),
            right: h_nm_per_rad.len(),
        });
    }
    let n = k_nm_per_rad.len();
    if n < 2 {
        return Err(ScienceError::TooFewSamples {
            what: "power-law fit".into(),
            needed: 2,
            given: n,
        });
    }
    let x = log10_series("k_nm_per_rad", k_nm_per_rad)?;
    let y = log10_series("h_nm_per_rad", h_nm_per_rad)?;
    let nf = n as f64;
    let mx = x.iter().sum::<f64>() / nf;
    let my = y.iter().sum::<f64>() / nf;
    let sxx: f64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let syy: f64 = y.iter().map(|v| (v - my) * (v - my)).sum();
    if sxx <= f64::EPSILON * nf * (1.0 + mx * mx) {
        return Err(ScienceError::Singular {
            what: "power-law fit".into(),
            why: "all stiffness values are equal",
        });
    }
    let beta1 = sxy / sxx;
    let beta0 = my - beta1 * mx;
    let rss: f64 = x
        .iter()
        .zip(&y)
        .map(|(a, b)| {
            let r = b - (beta0 + beta1 * a);
            r * r
        })
        .sum();
    let r2 = if syy > 0.0 { 1.0 - rss / syy } else { 1.0 };
    let (beta0_std_error, beta1_std_error) = if n > 2 {
        let s2 = rss / (nf - 2.0);
        let se1 = (s2 / sxx).sqrt();
        let se0 = (s2 * (1.0 / nf + mx * mx / sxx)).sqrt();
        (Some(se0), Some(se1))
    } else {
        (None, None)
    };
    Ok(PowerLawFit {
        law: PowerLaw { beta0, beta1 },
        r2,
        n,
        beta0_std_error,
        beta1_std_error,
    })
}

fn log10_series(series: &'static str, values: &[f64]) -> Result<Vec<f64>> {
    values
        .iter()
        .enumerate()
        .map(|(index, &value)| {
            if value.is_finite() && value > 0.0 {
                Ok(value.log10())
            } else {
                Err(ScienceError::BadSample {
                    series,
                    index,
                    value,
                    why: "a log-log fit needs finite, strictly positive values",
                })
            }
        })
        .collect()
}

/// Geometric mean `(Π x_i)^(1/n)` of strictly positive values: the paper's
/// "geometric average (arithmetic average of the logarithms)".
pub fn geometric_mean(values: &[f64]) -> Result<f64> {
    if values.is_empty() {
        return Err(ScienceError::TooFewSamples {
            what: "geometric mean".into(),
            needed: 1,
            given: 0,
        });
    }
    let logs = log10_series("values", values)?;
    Ok(10f64.powf(logs.iter().sum::<f64>() / logs.len() as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_power_law_is_recovered() {
        let law = PowerLaw::new(-0.3, 0.85).unwrap();
        let k = [10.0, 20.0, 40.0, 80.0];
        let h: Vec<f64> = k
            .iter()
            .map(|&k| law.hysteretic_damping(k).unwrap())
            .collect();
        let fit = fit_power_law(&k, &h).unwrap();
        assert!((fit.law.beta0 + 0.3).abs() < 1e-12);
        assert!((fit.law.beta1 - 0.85).abs() < 1e-12);
        assert!((fit.r2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_samples_are_named() {
        let err = fit_power_law(&[10.0, -1.0], &[2.0, 3.0]).unwrap_err();
        assert!(err.to_string().contains("k_nm_per_rad[1]"), "{err}");
        assert!(fit_power_law(&[10.0], &[2.0]).is_err());
        assert!(fit_power_law(&[10.0, 10.0], &[2.0, 3.0]).is_err());
        assert!(geometric_mean(&[]).is_err());
        assert!(geometric_mean(&[1.0, f64::INFINITY]).is_err());
    }
}
