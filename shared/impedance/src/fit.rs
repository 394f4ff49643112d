//! Frequency-domain linear least squares of the models M1–M3 to complex FRF
//! points (sections "Models" and "Statistical Analysis").
//!
//! Each complex point `S_k = S(jω_k)` gives two real equations, its real and
//! imaginary parts, stacked into one real system `A p = y` with one column per
//! model term (see [`Term::regressor`]). The solution minimises
//! `RSS = Σ_k |S_k − Ŝ(jω_k)|²`, and `n` complex points count as `2n` real
//! samples, as in the paper's F-statistics.
//!
//! Numerics: the columns are scaled to unit norm and the `4 × 4` normal
//! equations are solved by Cholesky on the stack, followed by one step of
//! iterative refinement, so a fit makes no heap allocation. The scaled Gram
//! matrix of the model's terms has unit diagonal, so its Cholesky pivots
//! measure how independent each term is from the others; a pivot below
//! `1e-10` is reported as a singular design (e.g. fewer distinct frequencies
//! than needed to separate inertia from stiffness).

use nalgebra::{Matrix4, Vector4};
use num_complex::Complex64;
use serde::Serialize;

use crate::error::{finite, positive, Result, ScienceError};
use crate::models::{DynamicStiffness, ImpedanceModel, Term};

/// One point of a measured frequency response function.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrfPoint {
    /// Excitation frequency ω (rad/s).
    pub omega_rad_s: f64,
    /// Complex dynamic stiffness at ω (Nm/rad), e.g. `τ_c/θ_e`.
    pub value: Complex64,
}

impl FrfPoint {
    /// A point from frequency, real and imaginary parts.
    pub fn new(omega_rad_s: f64, re: f64, im: f64) -> Self {
        FrfPoint {
            omega_rad_s,
            value: Complex64::new(re, im),
        }
    }
}

/// What the FRF points measure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum FitTarget {
    /// The human alone, `S_h(s) = τ_c/θ_e` (eqs. Sh1–Sh3).
    Human,
    /// The coupled human and exoskeleton felt through amplification α,
    /// `S_{h-e/α}(s) = S_h(s) + (M_e/α) s²` (eqs. M1–M3). The fitted
    /// parameters are still the human's: the known `M_e/α` is removed first.
    Coupled {
        /// Exoskeleton inertia `M_e` (kg·m²).
        m_e_kg_m2: f64,
        /// Amplification factor α (dimensionless, > 0).
        alpha: f64,
    },
}

impl FitTarget {
    /// The known inertia (kg·m²) contained in the data besides the human's.
    pub fn known_inertia_kg_m2(&self) -> Result<f64> {
        match *self {
            FitTarget::Human => Ok(0.0),
            FitTarget::Coupled { m_e_kg_m2, alpha } => {
                positive("m_e_kg_m2", m_e_kg_m2)?;
                positive("alpha", alpha)?;
                Ok(m_e_kg_m2 / alpha)
            }
        }
    }
}

/// The least-squares fit of one model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModelFit {
    /// Which model.
    pub model: ImpedanceModel,
    /// Fitted human parameters; terms absent from the model are zero.
    pub params: DynamicStiffness,
    /// Standard errors of the parameters, `√(σ² (AᵀA)⁻¹)_ii` with
    /// `σ² = RSS/(2n − p)`; absent terms are zero. `None` when `2n = p`
    /// leaves no residual degree of freedom.
    pub std_errors: Option<DynamicStiffness>,
    /// Residual sum of squares `Σ|S_k − Ŝ_k|²` ((Nm/rad)²).
    pub rss: f64,
    /// Total sum of squares `Σ|S_k − S̄|²` about the complex mean of the data as given.
    pub tss: f64,
    /// Coefficient of determination `1 − RSS/TSS`.
    pub r2: f64,
    /// Number of complex points `n`.
    pub n_points: usize,
    /// Residual degrees of freedom `2n − p`.
    pub dof: usize,
}

impl ModelFit {
    /// The fitted model's prediction of the data at `omega_rad_s`, including
    /// the known inertia of `target`.
    pub fn predict(&self, omega_rad_s: f64, target: FitTarget) -> Result<Complex64> {
        let extra = target.known_inertia_kg_m2()?;
        Ok(self.params.with_added_inertia(extra).response(omega_rad_s))
    }
}

/// Fits of all three models to the same points.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModelComparison {
    /// Eq. M1.
    pub m1: ModelFit,
    /// Eq. M2.
    pub m2: ModelFit,
    /// Eq. M3.
    pub m3: ModelFit,
}

impl ModelComparison {
    /// The fit of `model`.
    pub fn get(&self, model: ImpedanceModel) -> &ModelFit {
        match model {
            ImpedanceModel::M1 => &self.m1,
            ImpedanceModel::M2 => &self.m2,
            ImpedanceModel::M3 => &self.m3,
        }
    }
}

/// Checks that every point and the known inertia are finite.
fn check_points(points: &[FrfPoint], extra_inertia: f64) -> Result<()> {
    for (index, p) in points.iter().enumerate() {
        if !(p.omega_rad_s.is_finite() && p.value.re.is_finite() && p.value.im.is_finite()) {
            return Err(ScienceError::NonFiniteData {
                index,
                omega: p.omega_rad_s,
                re: p.value.re,
                im: p.value.im,
            });
        }
    }
    finite("known inertia", extra_inertia)?;
    Ok(())
}

/// Fits `model` to `points` by linear least squares (real and imaginary parts
/// stacked). Allocation-free.
///
/// Errors: a non-finite point; fewer real equations (`2n`) than parameters;
/// a design whose terms the frequencies cannot separate.
pub fn fit_model(
    model: ImpedanceModel,
    points: &[FrfPoint],
    target: FitTarget,
) -> Result<ModelFit> {
    let extra = target.known_inertia_kg_m2()?;
    check_points(points, extra)?;
    let p = model.n_params();
    let n = points.len();
    if 2 * n < p {
        return Err(ScienceError::TooFewSamples {
            what: format!("fit of {model} ({p} parameters, 2 real equations per FRF point)"),
            needed: p.div_ceil(2),
            given: n,
        });
    }
    let active = |t: Term| model.has(t);

    // Column norms for scaling.
    let mut col_sq = Vector4::<f64>::zeros();
    for pt in points {
        for t in Term::ALL {
            let (re, im) = t.regressor(pt.omega_rad_s);
            col_sq[t.index()] += re * re + im * im;
        }
    }
    let mut scale = Vector4::<f64>::from_element(1.0);
    for t in model.terms() {
        let s = col_sq[t.index()].sqrt();
        if s == 0.0 {
            return Err(ScienceError::Singular {
                what: format!("fit of {model}"),
                why: "a term has no regressor signal (all frequencies zero?)",
            });
        }
        scale[t.index()] = s;
    }

    // y_k = S_k + (M_e/α) ω_k² moves the known inertia to the left-hand side.
    let y_at = |pt: &FrfPoint| {
        (
            pt.value.re + extra * pt.omega_rad_s * pt.omega_rad_s,
            pt.value.im,
        )
    };
    let row = |pt: &FrfPoint| -> (Vector4<f64>, Vector4<f64>) {
        let mut a_re = Vector4::zeros();
        let mut a_im = Vector4::zeros();
        for t in model.terms() {
            let (re, im) = t.regressor(pt.omega_rad_s);
            a_re[t.index()] = re / scale[t.index()];
            a_im[t.index()] = im / scale[t.index()];
        }
        (a_re, a_im)
    };

    let mut gram = Matrix4::<f64>::zeros();
    let mut rhs = Vector4::<f64>::zeros();
    for pt in points {
        let (a_re, a_im) = row(pt);
        let (y_re, y_im) = y_at(pt);
        gram += a_re * a_re.transpose() + a_im * a_im.transpose();
        rhs += a_re * y_re + a_im * y_im;
    }
    for t in Term::ALL {
        if !active(t) {
            gram[(t.index(), t.index())] = 1.0;
        }
    }
    let chol = gram.cholesky().ok_or_else(|| ScienceError::Singular {
        what: format!("fit of {model}"),
        why: "the frequencies do not separate the model's terms",
    })?;
    let l = chol.l();
    for t in model.terms() {
        let pivot = l[(t.index(), t.index())];
        if pivot * pivot < 1e-10 {
            return Err(ScienceError::Singular {
                what: format!("fit of {model}"),
                why: "the frequencies do not separate the model's terms (too few distinct frequencies?)",
            });
        }
    }
    let mut x = chol.solve(&rhs);
    // One step of iterative refinement on the normal equations.
    let mut resid_rhs = rhs - gram * x;
    for t in Term::ALL {
        if !active(t) {
            resid_rhs[t.index()] = 0.0;
        }
    }
    x += chol.solve(&resid_rhs);

    let mut params = [0.0; 4];
    for t in model.terms() {
        params[t.index()] = x[t.index()] / scale[t.index()];
    }
    let params = DynamicStiffness::from_array(params);

    // Residuals computed directly, not from the normal equations.
    let shifted = params.with_added_inertia(extra);
    let mut rss = 0.0;
    let mut mean = Complex64::new(0.0, 0.0);
    for pt in points {
        rss += (pt.value - shifted.response(pt.omega_rad_s)).norm_sqr();
        mean += pt.value;
    }
    mean /= n as f64;
    let tss: f64 = points.iter().map(|pt| (pt.value - mean).norm_sqr()).sum();
    let r2 = if tss > 0.0 {
        1.0 - rss / tss
    } else if rss == 0.0 {
        1.0
    } else {
        0.0
    };

    let dof = 2 * n - p;
    let std_errors = if dof > 0 {
        let sigma2 = rss / dof as f64;
        let inv = chol.inverse();
        let mut se = [0.0; 4];
        for t in model.terms() {
            let i = t.index();
            se[i] = (sigma2 * inv[(i, i)]).sqrt() / scale[i];
        }
        Some(DynamicStiffness::from_array(se))
    } else {
        None
    };

    Ok(ModelFit {
        model,
        params,
        std_errors,
        rss,
        tss,
        r2,
        n_points: n,
        dof,
    })
}

/// Fits M1, M2 and M3 to the same points.
pub fn fit_all(points: &[FrfPoint], target: FitTarget) -> Result<ModelComparison> {
    Ok(ModelComparison {
        m1: fit_model(ImpedanceModel::M1, points, target)?,
        m2: fit_model(ImpedanceModel::M2, points, target)?,
        m3: fit_model(ImpedanceModel::M3, points, target)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points_from(s: DynamicStiffness, omegas: &[f64]) -> Vec<FrfPoint> {
        omegas
            .iter()
            .map(|&w| FrfPoint {
                omega_rad_s: w,
                value: s.response(w),
            })
            .collect()
    }

    #[test]
    fn too_few_points_is_an_error_not_a_panic() {
        let s = DynamicStiffness {
            m_kg_m2: 0.1,
            k_nm_per_rad: 20.0,
            ..Default::default()
        };
        let pts = points_from(s, &[2.0]);
        let err = fit_model(ImpedanceModel::M3, &pts, FitTarget::Human).unwrap_err();
        assert!(matches!(err, ScienceError::TooFewSamples { .. }), "{err}");
        assert!(matches!(
            fit_model(ImpedanceModel::M3, &[], FitTarget::Human),
            Err(ScienceError::TooFewSamples { .. })
        ));
    }

    #[test]
    fn one_repeated_frequency_is_singular() {
        let s = DynamicStiffness {
            m_kg_m2: 0.1,
            k_nm_per_rad: 20.0,
            ..Default::default()
        };
        let pts = points_from(s, &[3.0, 3.0, 3.0]);
        let err = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap_err();
        assert!(matches!(err, ScienceError::Singular { .. }), "{err}");
    }

    #[test]
    fn nan_point_is_named() {
        let mut pts = points_from(DynamicStiffness::default(), &[1.0, 2.0, 3.0]);
        pts[1].value.im = f64::NAN;
        let err = fit_model(ImpedanceModel::M1, &pts, FitTarget::Human).unwrap_err();
        assert!(
            matches!(err, ScienceError::NonFiniteData { index: 1, .. }),
            "{err}"
        );
    }

    #[test]
    fn exactly_determined_fit_has_no_standard_errors() {
        let s = DynamicStiffness {
            m_kg_m2: 0.1,
            b_nm_s_per_rad: 0.3,
            k_nm_per_rad: 20.0,
            h_nm_per_rad: 4.0,
        };
        let fit = fit_model(
            ImpedanceModel::M3,
            &points_from(s, &[2.0, 5.0]),
            FitTarget::Human,
        )
        .unwrap();
        assert_eq!(fit.dof, 0);
        assert!(fit.std_errors.is_none());
        assert!((fit.params.h_nm_per_rad - 4.0).abs() < 1e-9);
    }
}
