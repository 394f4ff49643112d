//! Frequency-domain least squares of the models M1–M3 to complex FRF
//! points (sections "Models" and "Statistical Analysis").
//!
//! Each complex point `S_k = S(jω_k)` gives two real equations, its real and
//! imaginary parts, stacked into one real system `A p = y` with one column per
//! model term (see [`Term::regressor`]), and `n` complex points count as `2n`
//! real samples, as in the paper's F-statistics.
//!
//! **Weights.** When every point carries its measured noise
//! ([`FrfPoint::std_dev_nm_per_rad`], `σ_k = √E|δS_k|²`, as the identifier
//! measures it in each analysis window), the fit is weighted least squares:
//! each real equation gets the weight `2/σ_k²` (the error is taken as
//! circular, half its variance in each part), so a point known ten times
//! better counts a hundred times more, and `χ² = Σ_k 2|S_k − Ŝ_k|²/σ_k²` is
//! the statistic minimised. Without noise on every point the fit is ordinary
//! least squares (unit weights, `χ²` = RSS), which is what the paper did.
//! A σ below a tenth of the median σ is raised to it, so one point whose noise
//! was underestimated by luck cannot carry the fit alone.
//!
//! **Uncertainty.** Standard errors are `√(s² (AᵀWA)⁻¹)_ii` with
//! `s² = χ²/(2n − p)`: the weights give the points' relative precision, the
//! residual scatter the absolute scale, so a noise estimate that is off by a
//! common factor (or a misfit) widens the intervals instead of hiding. The
//! 95 % intervals use Student's t with `2n − p` degrees of freedom.
//! [`ModelFit::reduced_chi2`] compares the residual with the measured noise:
//! far above 1, the model leaves out something the data show.
//!
//! Numerics: the columns are scaled to unit norm and the `4 × 4` normal
//! equations are solved by Cholesky on the stack, followed by one step of
//! iterative refinement; an unweighted fit makes no heap allocation, a
//! weighted one two vectors of `n` values (the weights and the sorted σ for
//! their median; fits run at the end of analysis windows, never per
//! sample). The scaled Gram
//! matrix of the model's terms has unit diagonal, so its Cholesky pivots
//! measure how independent each term is from the others; a pivot below
//! `1e-10` is reported as a singular design (e.g. fewer distinct frequencies
//! than needed to separate inertia from stiffness).

use nalgebra::{Matrix4, Vector4};
use num_complex::Complex64;
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF, StudentsT};

use crate::error::{finite, positive, Result, ScienceError};
use crate::models::{DynamicStiffness, ImpedanceModel, Term};

/// Coverage of the intervals in [`ModelFit::ci95`].
pub const CONFIDENCE_LEVEL: f64 = 0.95;

/// Points whose σ is below this fraction of the median σ are raised to it.
pub const MIN_RELATIVE_STD_DEV: f64 = 0.1;

/// One point of a measured frequency response function.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrfPoint {
    /// Excitation frequency ω (rad/s).
    pub omega_rad_s: f64,
    /// Complex dynamic stiffness at ω (Nm/rad), e.g. `τ_c/θ_e`.
    pub value: Complex64,
    /// Standard deviation of the point's error, `√E|δS|²` (Nm/rad, both parts
    /// together); 0 when not known (then the fit is unweighted).
    pub std_dev_nm_per_rad: f64,
}

impl FrfPoint {
    /// A point from frequency, real and imaginary parts, noise unknown.
    pub fn new(omega_rad_s: f64, re: f64, im: f64) -> Self {
        FrfPoint {
            omega_rad_s,
            value: Complex64::new(re, im),
            std_dev_nm_per_rad: 0.0,
        }
    }

    /// The same point with its measured noise `σ = √E|δS|²` (Nm/rad).
    pub fn with_std_dev(self, std_dev_nm_per_rad: f64) -> Self {
        FrfPoint {
            std_dev_nm_per_rad,
            ..self
        }
    }
}

/// What the FRF points measure. The fitted parameters are always the
/// human's (eqs. Sh1–Sh3); a known inertia in the data is moved to the
/// left-hand side first.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum FitTarget {
    /// The human alone, `S_h(s) = τ_c/θ_e` (eqs. Sh1–Sh3): the paper's
    /// estimate, from the clean cuff signal.
    Human,
    /// The coupled human and exoskeleton felt through amplification α,
    /// `S_{h-e/α}(s) = S_h(s) + (M_e/α) s²` (eqs. M1–M3).
    Coupled {
        /// Exoskeleton inertia `M_e` (kg·m²).
        m_e_kg_m2: f64,
        /// Amplification factor α (dimensionless, > 0).
        alpha: f64,
    },
    /// The actuator's side, `(τ_s − τ_gravity)/θ_e = S_h(s) + M_e s²`: the
    /// SEA torque moves the human *and the whole exoskeleton*
    /// (`M_e θ̈ = τ_s − τ_c − τ_g`), whatever α is.
    ActuatorSide {
        /// Exoskeleton inertia `M_e` (kg·m²).
        m_e_kg_m2: f64,
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
            FitTarget::ActuatorSide { m_e_kg_m2 } => {
                positive("m_e_kg_m2", m_e_kg_m2)?;
                Ok(m_e_kg_m2)
            }
        }
    }
}

/// How a fit treats the sign of the damping terms.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub enum DampingSign {
    /// Unconstrained least squares (the paper's): a negative `B` or `H` is
    /// reported as estimated.
    #[default]
    Free,
    /// `B ≥ 0` and `H ≥ 0` (a passive joint): the least-squares optimum over
    /// the feasible set, found exactly by fitting every face where some
    /// damping terms are held at zero and keeping the best feasible one.
    NonNegative,
}

/// The least-squares fit of one model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModelFit {
    /// Which model.
    pub model: ImpedanceModel,
    /// Fitted human parameters; terms absent from the model are zero.
    pub params: DynamicStiffness,
    /// Standard errors of the parameters, `√(s² (AᵀWA)⁻¹)_ii` with
    /// `s² = χ²/(2n − p)`; absent terms (and terms held at zero) are zero.
    /// `None` when `2n = p` leaves no residual degree of freedom.
    pub std_errors: Option<DynamicStiffness>,
    /// Half-widths of the 95 % confidence intervals (Student's t with
    /// [`ModelFit::dof`] degrees of freedom times the standard error).
    pub ci95: Option<DynamicStiffness>,
    /// Whether the points were weighted by their measured noise.
    pub weighted: bool,
    /// Residual sum of squares `Σ|S_k − Ŝ_k|²` ((Nm/rad)²), unweighted.
    pub rss: f64,
    /// The weighted residual `χ² = Σ 2|S_k − Ŝ_k|²/σ_k²` (equal to `rss`
    /// when unweighted): what the fit minimises and the F-tests compare.
    pub chi2: f64,
    /// `χ²/dof` when weighted: about 1 when the model explains the data to
    /// their measured noise.
    pub reduced_chi2: Option<f64>,
    /// `P(χ²_dof > χ²)` when weighted: the probability of a residual this
    /// large from noise alone.
    pub misfit_p_value: Option<f64>,
    /// Total sum of squares `Σ|S_k − S̄|²` about the complex mean of the data as given.
    pub tss: f64,
    /// Coefficient of determination `1 − RSS/TSS` (unweighted).
    pub r2: f64,
    /// Number of complex points `n`.
    pub n_points: usize,
    /// Residual degrees of freedom `2n − p` (p counts the free parameters).
    pub dof: usize,
    /// Damping terms held at zero by [`DampingSign::NonNegative`], in
    /// [`Term::ALL`] order.
    pub held_at_zero: [bool; 4],
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

/// Checks that every point and the known inertia are finite, and the noise
/// not negative.
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
        if !(p.std_dev_nm_per_rad.is_finite() && p.std_dev_nm_per_rad >= 0.0) {
            return Err(ScienceError::BadSample {
                series: "std_dev_nm_per_rad",
                index,
                value: p.std_dev_nm_per_rad,
                why: "a point's noise must be finite and not negative",
            });
        }
    }
    finite("known inertia", extra_inertia)?;
    Ok(())
}

/// The per-point weight of each real equation, `2/σ_k²` with σ floored at
/// [`MIN_RELATIVE_STD_DEV`] of the median; `None` (unit weights) unless
/// every point has a positive σ.
fn weights(points: &[FrfPoint]) -> Option<Vec<f64>> {
    if points.is_empty() || points.iter().any(|p| p.std_dev_nm_per_rad <= 0.0) {
        return None;
    }
    let mut sorted: Vec<f64> = points.iter().map(|p| p.std_dev_nm_per_rad).collect();
    sorted.sort_by(f64::total_cmp);
    let m = sorted.len();
    let median = if m % 2 == 1 {
        sorted[m / 2]
    } else {
        0.5 * (sorted[m / 2 - 1] + sorted[m / 2])
    };
    let floor = MIN_RELATIVE_STD_DEV * median;
    Some(
        points
            .iter()
            .map(|p| {
                let s = p.std_dev_nm_per_rad.max(floor);
                2.0 / (s * s)
            })
            .collect(),
    )
}

/// Fits `model` to `points` by (weighted) linear least squares, real and
/// imaginary parts stacked, with free damping signs.
///
/// Errors: a non-finite point or noise; fewer real equations (`2n`) than
/// parameters; a design whose terms the frequencies cannot separate.
pub fn fit_model(
    model: ImpedanceModel,
    points: &[FrfPoint],
    target: FitTarget,
) -> Result<ModelFit> {
    fit_model_with(model, points, target, DampingSign::Free)
}

/// [`fit_model`] with a choice of [`DampingSign`].
pub fn fit_model_with(
    model: ImpedanceModel,
    points: &[FrfPoint],
    target: FitTarget,
    damping: DampingSign,
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
    let w = weights(points);
    let w = w.as_deref();
    let free = fit_terms(model, [false; 4], points, extra, w)?;
    if damping == DampingSign::Free || !has_negative_damping(&free) {
        return Ok(free);
    }
    // Every face: each subset of the model's damping terms held at zero.
    let damping_terms: Vec<Term> = model
        .terms()
        .iter()
        .copied()
        .filter(|t| matches!(t, Term::ViscousDamping | Term::HystereticDamping))
        .collect();
    let mut best: Option<ModelFit> = None;
    for mask in 1..(1u32 << damping_terms.len()) {
        let mut held = [false; 4];
        for (bit, t) in damping_terms.iter().enumerate() {
            held[t.index()] = mask & (1 << bit) != 0;
        }
        let Ok(f) = fit_terms(model, held, points, extra, w) else {
            continue;
        };
        if !has_negative_damping(&f) && best.is_none_or(|b| f.chi2 < b.chi2) {
            best = Some(f);
        }
    }
    best.ok_or_else(|| {
        ScienceError::Infeasible(format!(
        "fit of {model} with non-negative damping: no face of the constraint set could be fitted"
    ))
    })
}

fn has_negative_damping(f: &ModelFit) -> bool {
    f.params.b_nm_s_per_rad < 0.0 || f.params.h_nm_per_rad < 0.0
}

/// The least-squares solve over the model's terms less those `held` at zero.
fn fit_terms(
    model: ImpedanceModel,
    held: [bool; 4],
    points: &[FrfPoint],
    extra: f64,
    weights: Option<&[f64]>,
) -> Result<ModelFit> {
    let n = points.len();
    let active = |t: Term| model.has(t) && !held[t.index()];
    let p = Term::ALL.iter().filter(|t| active(**t)).count();
    let weight = |k: usize| weights.map_or(1.0, |w| w[k]);

    // Column norms (weighted) for scaling.
    let mut col_sq = Vector4::<f64>::zeros();
    for (k, pt) in points.iter().enumerate() {
        for t in Term::ALL {
            let (re, im) = t.regressor(pt.omega_rad_s);
            col_sq[t.index()] += weight(k) * (re * re + im * im);
        }
    }
    let mut scale = Vector4::<f64>::from_element(1.0);
    for t in Term::ALL.into_iter().filter(|t| active(*t)) {
        let s = col_sq[t.index()].sqrt();
        if s == 0.0 {
            return Err(ScienceError::Singular {
                what: format!("fit of {model}"),
                why: "a term has no regressor signal (all frequencies zero?)",
            });
        }
        scale[t.index()] = s;
    }

    // y_k = S_k + M_known ω_k² moves the known inertia to the left-hand side.
    let y_at = |pt: &FrfPoint| {
        (
            pt.value.re + extra * pt.omega_rad_s * pt.omega_rad_s,
            pt.value.im,
        )
    };
    let row = |pt: &FrfPoint| -> (Vector4<f64>, Vector4<f64>) {
        let mut a_re = Vector4::zeros();
        let mut a_im = Vector4::zeros();
        for t in Term::ALL.into_iter().filter(|t| active(*t)) {
            let (re, im) = t.regressor(pt.omega_rad_s);
            a_re[t.index()] = re / scale[t.index()];
            a_im[t.index()] = im / scale[t.index()];
        }
        (a_re, a_im)
    };

    let mut gram = Matrix4::<f64>::zeros();
    let mut rhs = Vector4::<f64>::zeros();
    for (k, pt) in points.iter().enumerate() {
        let (a_re, a_im) = row(pt);
        let (y_re, y_im) = y_at(pt);
        let wk = weight(k);
        gram += (a_re * a_re.transpose() + a_im * a_im.transpose()) * wk;
        rhs += (a_re * y_re + a_im * y_im) * wk;
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
    for t in Term::ALL.into_iter().filter(|t| active(*t)) {
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
    for t in Term::ALL.into_iter().filter(|t| active(*t)) {
        params[t.index()] = x[t.index()] / scale[t.index()];
    }
    let params = DynamicStiffness::from_array(params);

    // Residuals computed directly, not from the normal equations.
    let shifted = params.with_added_inertia(extra);
    let (mut rss, mut chi2) = (0.0, 0.0);
    let mut mean = Complex64::new(0.0, 0.0);
    for (k, pt) in points.iter().enumerate() {
        let r2 = (pt.value - shifted.response(pt.omega_rad_s)).norm_sqr();
        rss += r2;
        chi2 += weight(k) * r2;
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
    let (mut std_errors, mut ci95) = (None, None);
    let (mut reduced_chi2, mut misfit_p_value) = (None, None);
    if dof > 0 {
        let s2 = chi2 / dof as f64;
        let inv = chol.inverse();
        let (mut se, mut ci) = ([0.0; 4], [0.0; 4]);
        for term in Term::ALL.into_iter().filter(|t| active(*t)) {
            let i = term.index();
            se[i] = (s2 * inv[(i, i)]).sqrt() / scale[i];
            ci[i] = ci95_half_width(se[i], dof)?;
        }
        std_errors = Some(DynamicStiffness::from_array(se));
        ci95 = Some(DynamicStiffness::from_array(ci));
        if weights.is_some() {
            reduced_chi2 = Some(s2);
            misfit_p_value = Some(chi_squared_survival(chi2, dof)?);
        }
    }

    Ok(ModelFit {
        model,
        params,
        std_errors,
        ci95,
        weighted: weights.is_some(),
        rss,
        chi2,
        reduced_chi2,
        misfit_p_value,
        tss,
        r2,
        n_points: n,
        dof,
        held_at_zero: held,
    })
}

/// The 95 % half-width (units of `std_error`) of a fitted parameter with
/// standard error `std_error` at `dof` degrees of freedom, as
/// [`ModelFit::ci95`] has it: Student's t quantile times the error.
pub fn ci95_half_width(std_error: f64, dof: usize) -> Result<f64> {
    Ok(interval_quantile(dof)? * std_error)
}

/// Degrees of freedom whose 95 % quantile is kept after its first use.
const CACHED_DOF: usize = 512;

/// Student's t quantile of the 95 % intervals at `dof` degrees of freedom.
/// The inverse CDF costs microseconds (more than a whole fit), so each value
/// up to [`CACHED_DOF`] is computed once per process and kept.
fn interval_quantile(dof: usize) -> Result<f64> {
    use std::sync::OnceLock;
    static CACHE: [OnceLock<f64>; CACHED_DOF] = [const { OnceLock::new() }; CACHED_DOF];
    let q = 0.5 + CONFIDENCE_LEVEL / 2.0;
    match CACHE.get(dof) {
        Some(cell) => {
            if let Some(t) = cell.get() {
                return Ok(*t);
            }
            let t = students_t_quantile(dof, q)?;
            Ok(*cell.get_or_init(|| t))
        }
        None => students_t_quantile(dof, q),
    }
}

/// The `q` quantile of Student's t with `dof` degrees of freedom.
pub fn students_t_quantile(dof: usize, q: f64) -> Result<f64> {
    let t = StudentsT::new(0.0, 1.0, dof as f64).map_err(|_| ScienceError::OutOfRange {
        name: "degrees of freedom",
        value: dof as f64,
        allowed: "(0, ∞)",
    })?;
    Ok(t.inverse_cdf(q))
}

/// `P(χ²_dof > x)`.
pub fn chi_squared_survival(x: f64, dof: usize) -> Result<f64> {
    let d = ChiSquared::new(dof as f64).map_err(|_| ScienceError::OutOfRange {
        name: "degrees of freedom",
        value: dof as f64,
        allowed: "(0, ∞)",
    })?;
    finite("chi2", x)?;
    Ok(d.sf(x))
}

/// Fits M1, M2 and M3 to the same points.
pub fn fit_all(points: &[FrfPoint], target: FitTarget) -> Result<ModelComparison> {
    fit_all_with(points, target, DampingSign::Free)
}

/// [`fit_all`] with a choice of [`DampingSign`].
pub fn fit_all_with(
    points: &[FrfPoint],
    target: FitTarget,
    damping: DampingSign,
) -> Result<ModelComparison> {
    Ok(ModelComparison {
        m1: fit_model_with(ImpedanceModel::M1, points, target, damping)?,
        m2: fit_model_with(ImpedanceModel::M2, points, target, damping)?,
        m3: fit_model_with(ImpedanceModel::M3, points, target, damping)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points_from(s: DynamicStiffness, omegas: &[f64]) -> Vec<FrfPoint> {
        omegas
            .iter()
            .map(|&w| FrfPoint::new(w, s.response(w).re, s.response(w).im))
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
