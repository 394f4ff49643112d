//! Weighted complex least squares of the forward model (Levenberg–Marquardt
//! with bounds by projection): every observation's real and imaginary
//! residual divided by the noise measured for it.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::data::{Dataset, Observation};
use crate::model::{Param, Physics};

/// A fitted model.
#[derive(Debug, Clone, Serialize)]
pub struct Fitted {
    /// Coefficients at the optimum.
    pub physics: Physics,
    /// The free parameters.
    pub free: Vec<Param>,
    /// Standard errors of the free parameters (residual-variance scaled).
    pub std_errors: Vec<f64>,
    /// Weighted residual sum of squares (χ² with the measured noise).
    pub rss: f64,
    /// Real residuals (two per frequency-response point, one per static balance).
    pub n: usize,
    /// Whether the iteration converged.
    pub converged: bool,
}

impl Fitted {
    /// Number of free parameters.
    pub fn p(&self) -> usize {
        self.free.len()
    }

    /// Akaike's information criterion `n ln(RSS/n) + 2p`.
    pub fn aic(&self) -> f64 {
        let n = self.n as f64;
        n * (self.rss / n).ln() + 2.0 * self.p() as f64
    }

    /// The standard error of `p`, if free.
    pub fn std_error(&self, p: Param) -> Option<f64> {
        self.free
            .iter()
            .position(|&q| q == p)
            .map(|i| self.std_errors[i])
    }
}

/// Accuracy of the linearised forward model relative to the simulator
/// (fraction of `|value|`): the worst disagreement measured over every term
/// of the plant TOML in `tests/it/forward.rs` is below it. Every value is
/// held to it ([`crate::data::Observation::accuracy`]), and it is the size
/// below which a form's signature cannot be told from the model's own
/// error (the amplitude check, the posture form).
pub const MODEL_ACCURACY: f64 = 0.005;

/// Accuracy of the forward model with Coulomb friction in the joint at
/// every dynamic transfer function (fraction of `|value|`): its describing
/// function ignores the harmonics friction makes (measured worst 1.7 % in
/// `tests/it/forward.rs`).
pub const COULOMB_ACCURACY: f64 = 0.025;

/// Accuracy of the forward model of an ideal actuator (no SEA dynamics:
/// the torque is the held command) at every dynamic transfer function
/// (fraction of `|value|`; measured 0.8 % in `tests/it/forward.rs`).
pub const IDEAL_ACTUATOR_ACCURACY: f64 = 0.01;

/// The standard deviation used to weight one component: the noise measured
/// in the window combined with the systematic uncertainty the value is
/// held to ([`crate::data::Observation::accuracy`]).
pub fn sigma_floor(o: &Observation, k: usize) -> f64 {
    o.sigma[k]
        .hypot(o.accuracy * o.value.norm())
        .max(absolute_floor(o.tf))
}

/// The smallest standard deviation of a component: 1 µNm for the static
/// balance (held to its measured noise alone, which a constant signal makes
/// zero; a µNm is far below any joint torque sensor's resolution),
/// otherwise negligible.
fn absolute_floor(tf: crate::data::Tf) -> f64 {
    if tf == crate::data::Tf::Balance {
        1e-6
    } else {
        1e-12
    }
}

/// The systematic uncertainty of `o` for the physics `phys` (fraction of
/// `|value|`): the observation's own ([`crate::data::Observation::accuracy`]),
/// or more where a term's forward model is coarser, as measured against the
/// simulator in `tests/it/forward.rs`: Coulomb friction's describing function
/// ([`COULOMB_ACCURACY`]), an ideal actuator's held torque
/// ([`IDEAL_ACTUATOR_ACCURACY`]).
pub fn model_accuracy(phys: &Physics, o: &Observation) -> f64 {
    if phys.coulomb_nm > 0.0 && o.tf.is_dynamic() {
        // Its describing function leaves out the harmonics friction makes,
        // which reach every transfer function through the loop.
        COULOMB_ACCURACY
    } else if describing_function(phys) && o.tf.is_dynamic() {
        // A nonlinearity's describing function: accurate to the forward
        // model's measured accuracy, not to the noise.
        o.accuracy.max(MODEL_ACCURACY)
    } else if phys.sea.is_none() && o.tf.is_dynamic() {
        // An ideal actuator's stair-shaped torque, sampled at the end of
        // each hold (measured 0.8 %, `tests/it/forward.rs`).
        o.accuracy.max(IDEAL_ACTUATOR_ACCURACY)
    } else {
        o.accuracy
    }
}

/// Whether `phys` holds a term whose forward model is a describing function
/// ([`crate::terms::Term::describing_function`]; Coulomb friction has its
/// own accuracy, and a drive's torque limit its exact clipped-sine gain).
fn describing_function(phys: &Physics) -> bool {
    use crate::terms::Term;
    [
        Term::CubicStiffness,
        Term::CubicDamping,
        Term::Backlash,
        Term::PostureStiffness,
    ]
    .into_iter()
    .any(|t| t.in_nominal(phys))
}

/// The lack-of-fit χ² of `phys`: residuals against the measured noise and
/// this model's own accuracy ([`model_accuracy`]). Used to decide whether
/// anything is left to explain.
pub fn lack_of_fit_chi2(d: &Dataset, phys: &Physics) -> (f64, usize) {
    lack_of_fit_chi2_of(d, phys, None)
}

/// [`lack_of_fit_chi2`] of one transfer function's observations, or of all
/// (`None`).
pub fn lack_of_fit_chi2_of(
    d: &Dataset,
    phys: &Physics,
    only: Option<crate::data::Tf>,
) -> (f64, usize) {
    let mut chi = 0.0;
    let mut n = 0;
    for o in d
        .observations
        .iter()
        .filter(|o| only.is_none_or(|t| o.tf == t))
    {
        let acc = model_accuracy(phys, o) * o.value.norm();
        let r = phys.predict(o, &d.conditions[o.window]) - o.value;
        let fl = absolute_floor(o.tf);
        // A residual over a σ estimated with few degrees of freedom is
        // Student-t: taken at the normal quantile of the same probability.
        let z = |x: f64| match o.sigma_dof {
            Some(dof) => crate::stats::t_as_normal(x, dof),
            None => x,
        };
        chi += z(r.re / o.sigma[0].hypot(acc).max(fl)).powi(2);
        n += 1;
        if o.tf.is_dynamic() {
            chi += z(r.im / o.sigma[1].hypot(acc).max(fl)).powi(2);
            n += 1;
        }
    }
    (chi, n)
}

/// χ² per real residual of one transfer function's transient-free values
/// (`Observation::transient_free`: the window's transient out, its own
/// noise) with no accuracy floor: how the noise model compares with the
/// misfit, for calibrating it (docs/diagnose.md, "The noise model").
/// Reported, not judged by. NaN with no transient-free value.
pub fn noise_only_chi2(d: &Dataset, phys: &Physics, tf: crate::data::Tf) -> f64 {
    let (mut chi, mut n) = (0.0, 0usize);
    for o in d.observations.iter().filter(|o| o.tf == tf) {
        let Some(free) = o.transient_free else {
            continue;
        };
        let r = phys.predict(o, &d.conditions[o.window]) - free.value;
        chi += (r.re / free.sigma[0].max(1e-12)).powi(2);
        n += 1;
        if tf.is_dynamic() {
            chi += (r.im / free.sigma[1].max(1e-12)).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        chi / n as f64
    }
}

/// The lack-of-fit p-value of `phys` with `p` free parameters
/// ([`lack_of_fit`]'s).
pub fn lack_of_fit_p(d: &Dataset, phys: &Physics, p: usize) -> f64 {
    lack_of_fit(d, phys, p, 0.0).p_value
}

/// The one materiality rule of the diagnosis: whether the misfit of a model
/// is beyond the measured noise, and by how much.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LackOfFit {
    /// The χ² test ([`lack_of_fit_chi2`]) of each transfer function on its
    /// own (its share of the parameters by its share of the residuals), the
    /// smallest p-value Bonferroni-corrected over the transfer functions, so
    /// a mismatch confined to one of them is not diluted by the others.
    pub p_value: f64,
    /// The misfit beyond the noise's expectation, `Σ (χ²_tf − dof_tf)` over
    /// the transfer functions whose own test rejects at the level divided
    /// over them; 0 when none does. A term is taken only while this is
    /// positive, and the share of the misfit it explains is its fall of
    /// `χ²` over this; "structure remains" is said only when it is
    /// positive: one rule for naming and for "unexplained".
    pub beyond_noise: f64,
    /// The lack-of-fit χ² summed over the transfer functions.
    pub chi2: f64,
    /// The same test as [`Self::p_value`] by the noise alone: every transfer
    /// function counted, however small its misfit beyond the noise.
    pub noise_p: f64,
    /// The largest [`excess_relative`] over the transfer functions with
    /// values that are not near zero (the static balance left out).
    pub excess: f64,
}

impl LackOfFit {
    /// The share of the misfit beyond the noise that the fall of χ² from
    /// `self` to `after` explains, in [0, 1]; NaN when nothing was beyond
    /// the noise.
    pub fn explained_share(&self, after: &LackOfFit) -> f64 {
        if self.beyond_noise > 0.0 {
            ((self.chi2 - after.chi2) / self.beyond_noise).clamp(0.0, 1.0)
        } else {
            f64::NAN
        }
    }
}

/// [`LackOfFit`] of `phys` with `p` free parameters at `level`.
pub fn lack_of_fit(d: &Dataset, phys: &Physics, p: usize, level: f64) -> LackOfFit {
    let (_, n_all) = lack_of_fit_chi2(d, phys);
    let (mut worst, mut noise_p, mut excess_max): (f64, f64, f64) = (1.0, 1.0, 0.0);
    let (mut beyond, mut total) = (0.0, 0.0);
    let tfs = d.supported.len().max(1) as f64;
    for &tf in &d.supported {
        let (chi, n) = lack_of_fit_chi2_of(d, phys, Some(tf));
        total += chi;
        let dof = n as f64 - p as f64 * n as f64 / n_all.max(1) as f64;
        // Material only beyond the forward model's accuracy in size too (a
        // static balance relative to the SEA's mean torque, its values
        // being near zero; reported apart from the dynamic ones).
        let excess = excess_relative(d, phys, tf);
        if tf.is_dynamic() {
            excess_max = excess_max.max(excess);
        }
        if dof > 0.0 {
            if let Ok(dist) = statrs::distribution::ChiSquared::new(dof) {
                use statrs::distribution::ContinuousCDF;
                let p_tf = (tfs * dist.sf(chi)).min(1.0);
                noise_p = noise_p.min(p_tf);
                if excess <= MODEL_ACCURACY {
                    continue;
                }
                worst = worst.min(p_tf);
                if p_tf < level {
                    beyond += chi - dof;
                }
            }
        }
    }
    LackOfFit {
        p_value: worst,
        beyond_noise: beyond,
        chi2: total,
        noise_p,
        excess: excess_max,
    }
}

/// The size of `phys`'s misfit on transfer function `tf` beyond what the
/// σ's of the lack-of-fit χ² account for, relative to the values: `√(max(Σ
/// (|r|² − σ_re² − σ_im²), 0) / Σ |value|²)`; for the static balance,
/// whose values are differences near zero, relative to the SEA's mean
/// torque in each window (what the balance's terms are fractions of: the
/// gravity moment, the bias), or to the value where that was not measured.
/// A misfit the noise cannot explain but smaller than the forward model's
/// accuracy ([`MODEL_ACCURACY`]) is no missing physics.
pub fn excess_relative(d: &Dataset, phys: &Physics, tf: crate::data::Tf) -> f64 {
    let (mut excess, mut scale) = (0.0, 0.0);
    for o in d.observations.iter().filter(|o| o.tf == tf) {
        let acc = model_accuracy(phys, o) * o.value.norm();
        let r = phys.predict(o, &d.conditions[o.window]) - o.value;
        let fl = absolute_floor(o.tf);
        excess += r.norm_sqr()
            - o.sigma[0].hypot(acc).max(fl).powi(2)
            - if tf.is_dynamic() {
                o.sigma[1].hypot(acc).max(fl).powi(2)
            } else {
                0.0
            };
        let tau_s = d.conditions[o.window].tau_s_mean_nm;
        scale += if tf == crate::data::Tf::Balance && tau_s.is_finite() {
            tau_s * tau_s
        } else {
            o.value.norm_sqr()
        };
    }
    if scale > 0.0 {
        (excess.max(0.0) / scale).sqrt()
    } else {
        0.0
    }
}

/// Whitened residuals of `phys` on the observations selected by `use_obs`.
pub fn residuals(
    d: &Dataset,
    phys: &Physics,
    use_obs: &dyn Fn(usize, &Observation) -> bool,
    out: &mut Vec<f64>,
) {
    out.clear();
    for (i, o) in d.observations.iter().enumerate() {
        if !use_obs(i, o) {
            continue;
        }
        let c = &d.conditions[o.window];
        let r = phys.predict(o, c) - o.value;
        out.push(r.re / sigma_floor(o, 0));
        // The static balance is real: one residual.
        if o.tf.is_dynamic() {
            out.push(r.im / sigma_floor(o, 1));
        }
    }
}

/// Weighted RSS of `phys` on the selected observations.
pub fn rss(
    d: &Dataset,
    phys: &Physics,
    use_obs: &dyn Fn(usize, &Observation) -> bool,
) -> (f64, usize) {
    let mut r = Vec::new();
    residuals(d, phys, use_obs, &mut r);
    (r.iter().map(|x| x * x).sum(), r.len())
}

/// Fits the `free` parameters of `start` to the selected observations.
pub fn fit(
    d: &Dataset,
    start: &Physics,
    free: &[Param],
    use_obs: &dyn Fn(usize, &Observation) -> bool,
) -> Fitted {
    let mut phys = start.clone();
    let p = free.len();
    let mut r = Vec::new();
    residuals(d, &phys, use_obs, &mut r);
    let n = r.len();
    let mut cost: f64 = r.iter().map(|x| x * x).sum();
    let mut lambda = 1e-3;
    let mut converged = p == 0;
    let mut jac = DMatrix::<f64>::zeros(n, p);
    let mut col = Vec::new();
    // Where each used observation's residuals sit, and which experiment it
    // belongs to: a per-experiment parameter (K_h, H_h) moves only its own
    // experiment's rows, so its column is computed from those alone.
    let mut rows: Vec<(usize, usize)> = Vec::new();
    {
        let mut row = 0;
        for (i, o) in d.observations.iter().enumerate() {
            if use_obs(i, o) {
                rows.push((i, row));
                row += if o.tf.is_dynamic() { 2 } else { 1 };
            }
        }
    }
    let column = |phys: &Physics, q: Param, col: &mut [f64]| {
        let v = phys.get(q);
        let h = 1e-5 * q.scale().max(v.abs() * 1e-3);
        let mut a = phys.clone();
        let mut b = phys.clone();
        a.set(q, v + h);
        b.set(q, v - h);
        let span = (a.get(q) - v) + (v - b.get(q));
        col.fill(0.0);
        if span <= 0.0 {
            return;
        }
        let only = match q {
            Param::K(e) | Param::H(e) => Some(e),
            _ => None,
        };
        for &(i, row) in &rows {
            let o = &d.observations[i];
            let c = &d.conditions[o.window];
            if only.is_some_and(|e| e != c.experiment) {
                continue;
            }
            let dz = (a.predict(o, c) - b.predict(o, c)) / span;
            col[row] = dz.re / sigma_floor(o, 0);
            if o.tf.is_dynamic() {
                col[row + 1] = dz.im / sigma_floor(o, 1);
            }
        }
    };
    let jacobian = |phys: &Physics, jac: &mut DMatrix<f64>, col: &mut Vec<f64>| {
        col.resize(n, 0.0);
        for (k, &q) in free.iter().enumerate() {
            column(phys, q, col);
            jac.column_mut(k).copy_from_slice(col);
        }
    };
    if p > 0 && n > 0 {
        for _ in 0..200 {
            jacobian(&phys, &mut jac, &mut col);
            let jt = jac.transpose();
            let jtj = &jt * &jac;
            let g = &jt * DVector::from_column_slice(&r);
            let mut improved = false;
            for _ in 0..12 {
                let mut a = jtj.clone();
                for i in 0..p {
                    a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
                }
                let Some(step) = a.lu().solve(&(-&g)) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut trial = phys.clone();
                for (k, &q) in free.iter().enumerate() {
                    trial.set(q, phys.get(q) + step[k]);
                }
                let mut rt = Vec::new();
                residuals(d, &trial, use_obs, &mut rt);
                let c: f64 = rt.iter().map(|x| x * x).sum();
                if c.is_finite() && c < cost {
                    let rel = (cost - c) / cost.max(1e-300);
                    phys = trial;
                    r = rt;
                    cost = c;
                    lambda = (lambda / 3.0).max(1e-12);
                    improved = true;
                    if rel < 1e-10 {
                        converged = true;
                    }
                    break;
                }
                lambda *= 8.0;
            }
            if !improved {
                converged = true;
                break;
            }
            if converged {
                break;
            }
        }
    }
    // Standard errors from the Gauss–Newton covariance, scaled by the
    // residual variance (robust to a mis-scaled noise estimate). A variance
    // that is not positive and finite (a singular or numerically indefinite
    // JᵀJ: the parameter is not determined by the data, e.g. held at its
    // bound) is NaN, never 0: a zero standard error would claim precision.
    let mut std_errors = vec![f64::NAN; p];
    if p > 0 && n > p {
        jacobian(&phys, &mut jac, &mut col);
        let jtj = jac.transpose() * &jac;
        if let Some(inv) = jtj.try_inverse() {
            let s2 = cost / (n - p) as f64;
            for (i, e) in std_errors.iter_mut().enumerate() {
                let var = inv[(i, i)] * s2;
                *e = if var.is_finite() && var > 0.0 {
                    var.sqrt()
                } else {
                    f64::NAN
                };
            }
        }
    }
    Fitted {
        physics: phys,
        free: free.to_vec(),
        std_errors,
        rss: cost,
        n,
        converged,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Tf;
    use num_complex::Complex64;

    /// The default plant's physics for experiment 1.
    fn default_physics() -> Physics {
        let plant = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        Physics::from_plant(
            &exo_plant_model::PlantModel::from_file(&plant).unwrap(),
            &[1],
        )
    }

    /// One window of experiment 1 at 0.5 rad, 0.1 rad of swing, 1 kHz.
    fn window() -> crate::data::Condition {
        crate::data::Condition::test_window(0.5, 0.1, 0.001)
    }

    fn observation(tf: Tf, value: f64, sigma: f64, accuracy: f64) -> Observation {
        Observation {
            tf,
            omega_rad_s: 3.0,
            value: Complex64::new(value, 0.0),
            sigma: [sigma; 2],
            line_sigma: [sigma; 2],
            transient_free: None,
            accuracy,
            window: 0,
            gravity_comp: Complex64::new(0.0, 0.0),
            statics: [0.0; 2],
            sigma_dof: None,
        }
    }

    /// The lack-of-fit χ² by hand: an `S_h` value 2 % off the model's
    /// prediction in its real part, 1 % in its imaginary part, with a σ of
    /// 0.3 and the 0.5 % accuracy on |value|; and a static balance 2 mNm
    /// off with σ 0.5 mNm (one residual, no accuracy: 16). Each transfer
    /// function counted on its own, and together. A balance whose σ was
    /// measured with 6 degrees of freedom, off by Student's two-sided 5 %
    /// point (2.447 σ), counts as the normal's (1.960², 3.84).
    #[test]
    fn the_lack_of_fit_chi2_is_the_residuals_over_noise_and_accuracy() {
        let phys = default_physics();
        let c = window();
        let mut sh = observation(Tf::Sh, 0.0, 0.3, MODEL_ACCURACY);
        let p = phys.predict(&sh, &c);
        sh.value = Complex64::new(p.re + 0.02 * p.norm(), p.im + 0.01 * p.norm());
        let mut bal = observation(Tf::Balance, 0.0, 5e-4, 0.0);
        let pb = phys.predict(&bal, &c);
        bal.value = Complex64::new(pb.re + 2e-3, 0.0);
        let d = Dataset {
            conditions: vec![c],
            observations: vec![sh, bal],
            supported: vec![Tf::Sh, Tf::Balance],
            ..Dataset::default()
        };
        let sd = 0.3f64.hypot(MODEL_ACCURACY * sh.value.norm());
        let want_sh = ((0.02 * p.norm()) / sd).powi(2) + ((0.01 * p.norm()) / sd).powi(2);
        let (chi, n) = lack_of_fit_chi2_of(&d, &phys, Some(Tf::Sh));
        assert_eq!(n, 2);
        assert!(
            (chi - want_sh).abs() < 1e-9 * want_sh,
            "{chi} against {want_sh}"
        );
        let (chi_b, n_b) = lack_of_fit_chi2_of(&d, &phys, Some(Tf::Balance));
        assert_eq!(n_b, 1);
        assert!((chi_b - 16.0).abs() < 1e-6, "{chi_b}");
        let (all, n_all) = lack_of_fit_chi2(&d, &phys);
        assert_eq!(n_all, 3);
        assert!((all - want_sh - 16.0).abs() < 1e-6 * all, "{all}");
        let mut t6 = bal;
        t6.sigma_dof = Some(6.0);
        t6.value = Complex64::new(pb.re - 2.447 * 5e-4, 0.0);
        let d6 = Dataset {
            conditions: vec![window()],
            observations: vec![t6],
            supported: vec![Tf::Balance],
            ..Dataset::default()
        };
        let (chi_t, _) = lack_of_fit_chi2_of(&d6, &phys, Some(Tf::Balance));
        assert!((chi_t - 1.960f64.powi(2)).abs() < 1e-2, "{chi_t}");
    }

    /// The materiality rule by hand: 40 `S_h` values of one window, each
    /// `bias` of the prediction's magnitude off it in its real part, with a
    /// σ of 1e-4 of it and no accuracy of their own. A 0.2 % bias is 20 σ:
    /// far beyond the noise (`noise_p` ≈ 0), yet its size beyond the noise,
    /// `√((b² − 2σ²)/1)` of the values, is below the forward model's 0.5 %:
    /// no missing physics (`p_value` 1, nothing beyond). A 1 % bias is
    /// beyond both.
    #[test]
    fn a_misfit_is_material_only_beyond_the_noise_and_the_models_accuracy() {
        let phys = default_physics();
        let c = window();
        let p = phys.predict(&observation(Tf::Sh, 0.0, 1.0, 0.0), &c);
        let data = |bias: f64| {
            let mut o = observation(Tf::Sh, 0.0, 1e-4 * p.norm(), 0.0);
            o.value = Complex64::new(p.re + bias * p.norm(), p.im);
            Dataset {
                conditions: vec![c.clone()],
                observations: vec![o; 40],
                supported: vec![Tf::Sh],
                ..Dataset::default()
            }
        };
        for (bias, material) in [(0.002, false), (0.01, true)] {
            let d = data(bias);
            let v = d.observations[0].value.norm();
            let sigma = 1e-4 * p.norm();
            let want = ((bias * p.norm()).powi(2) - 2.0 * sigma * sigma).sqrt() / v;
            let got = excess_relative(&d, &phys, Tf::Sh);
            assert!(
                (got - want).abs() < 1e-9,
                "bias {bias}: {got} against {want}"
            );
            let l = lack_of_fit(&d, &phys, 0, 0.05);
            assert!(l.noise_p < 1e-12, "bias {bias}: noise p {}", l.noise_p);
            assert_eq!(l.excess, got);
            if material {
                assert!(l.p_value < 1e-12 && l.beyond_noise > 0.0, "{l:?}");
            } else {
                assert_eq!((l.p_value, l.beyond_noise), (1.0, 0.0), "{l:?}");
            }
        }
    }

    /// The static balance's materiality by hand: 30 windows whose SEA
    /// holds 16 Nm on average, each balance `off` Nm from the prediction
    /// with σ 1 mNm. 30 mNm off is 30 σ but √(0.03² − 0.001²)/16 = 0.19 %
    /// of the torque the balance is made of: not material (and no dynamic
    /// excess reported). 0.16 Nm off is 1 %: material.
    #[test]
    fn a_balance_misfit_is_material_only_beyond_its_noise_and_the_accuracy_of_its_torque() {
        let phys = default_physics();
        let mut c = window();
        c.tau_s_mean_nm = 16.0;
        for (off, material) in [(0.03, false), (0.16, true)] {
            let mut o = observation(Tf::Balance, 0.0, 1e-3, 0.0);
            let pb = phys.predict(&o, &c);
            o.value = Complex64::new(pb.re + off, 0.0);
            let d = Dataset {
                conditions: vec![c.clone()],
                observations: vec![o; 30],
                supported: vec![Tf::Balance],
                ..Dataset::default()
            };
            let want = (off * off - 1e-6).sqrt() / 16.0;
            let got = excess_relative(&d, &phys, Tf::Balance);
            assert!((got - want).abs() < 1e-9, "off {off}: {got} against {want}");
            let l = lack_of_fit(&d, &phys, 0, 0.05);
            assert!(l.noise_p < 1e-12, "off {off}: noise p {}", l.noise_p);
            assert_eq!(l.excess, 0.0, "the balance is not a dynamic excess");
            if material {
                assert!(l.p_value < 1e-12 && l.beyond_noise > 0.0, "{l:?}");
            } else {
                assert_eq!((l.p_value, l.beyond_noise), (1.0, 0.0), "{l:?}");
            }
        }
        // Where the SEA's mean torque was not measured, relative to the
        // value itself.
        let mut o = observation(Tf::Balance, 0.0, 1e-3, 0.0);
        let pb = phys.predict(&o, &window());
        o.value = Complex64::new(pb.re + 0.03, 0.0);
        let d = Dataset {
            conditions: vec![window()],
            observations: vec![o],
            supported: vec![Tf::Balance],
            ..Dataset::default()
        };
        let want = (0.03f64.powi(2) - 1e-6).sqrt() / o.value.norm();
        assert!((excess_relative(&d, &phys, Tf::Balance) - want).abs() < 1e-9);
    }

    /// Each value is held to its own systematic uncertainty; a model with
    /// Coulomb friction to 2.5 % at every dynamic transfer function, one
    /// with an ideal actuator to at least 1 %; the static balance to its
    /// measured noise alone, down to the 1 µNm floor.
    #[test]
    fn each_value_is_held_to_its_own_accuracy_or_its_terms() {
        let base = default_physics();
        assert!(base.sea.is_some() && base.coulomb_nm == 0.0);
        let free = observation(Tf::She, 100.0, 0.3, 0.0);
        let line = observation(Tf::Sh, 100.0, 0.3, MODEL_ACCURACY);
        let quantised = observation(Tf::Sh, 100.0, 0.3, 0.002);
        let balance = observation(Tf::Balance, 0.01, 1e-4, 0.0);
        assert_eq!(model_accuracy(&base, &free), 0.0);
        assert_eq!(model_accuracy(&base, &line), MODEL_ACCURACY);
        assert_eq!(model_accuracy(&base, &quantised), 0.002);
        assert_eq!(sigma_floor(&free, 0), 0.3);
        assert!((sigma_floor(&line, 1) - 0.3f64.hypot(0.5)).abs() < 1e-12);
        assert!((sigma_floor(&quantised, 0) - 0.3f64.hypot(0.2)).abs() < 1e-12);
        assert_eq!(sigma_floor(&balance, 0), 1e-4);
        let silent = observation(Tf::Balance, 0.01, 0.0, 0.0);
        assert_eq!(sigma_floor(&silent, 0), 1e-6);
        let mut friction = base.clone();
        friction.coulomb_nm = 0.3;
        for o in [&free, &line, &quantised] {
            assert_eq!(model_accuracy(&friction, o), COULOMB_ACCURACY, "{:?}", o.tf);
        }
        let sea = observation(Tf::Sea, 1.0, 1e-3, 0.0);
        assert_eq!(model_accuracy(&friction, &sea), COULOMB_ACCURACY);
        assert_eq!(model_accuracy(&friction, &balance), 0.0);
        let mut ideal = base.clone();
        ideal.sea = None;
        assert_eq!(model_accuracy(&ideal, &free), IDEAL_ACTUATOR_ACCURACY);
        assert_eq!(model_accuracy(&ideal, &sea), IDEAL_ACTUATOR_ACCURACY);
        let coarse = observation(Tf::Sh, 100.0, 0.3, 0.02);
        assert_eq!(model_accuracy(&ideal, &coarse), 0.02);
        assert_eq!(model_accuracy(&ideal, &balance), 0.0);
        // A describing function's physics: every dynamic value to at least
        // the forward model's accuracy, the balance to its own.
        for set in [
            |p: &mut Physics| p.k3 = 120.0,
            |p: &mut Physics| p.b3 = 0.1,
            |p: &mut Physics| p.lash_half_rad = 0.02,
            |p: &mut Physics| p.k2 = 15.0,
        ] {
            let mut nl = base.clone();
            set(&mut nl);
            assert_eq!(model_accuracy(&nl, &free), MODEL_ACCURACY, "{nl:?}");
            assert_eq!(model_accuracy(&nl, &sea), MODEL_ACCURACY);
            assert_eq!(model_accuracy(&nl, &coarse), 0.02);
            assert_eq!(model_accuracy(&nl, &balance), 0.0);
        }
    }

    /// A term's share is its fall of χ² over the misfit beyond the noise
    /// before it, clamped to [0, 1]; NaN when nothing was beyond the noise.
    #[test]
    fn the_share_is_the_fall_of_chi2_over_the_misfit_beyond_the_noise() {
        let before = LackOfFit {
            p_value: 1e-6,
            beyond_noise: 40.0,
            chi2: 100.0,
            noise_p: 1e-6,
            excess: 0.02,
        };
        let after = |chi2: f64| LackOfFit {
            p_value: 0.5,
            beyond_noise: 0.0,
            chi2,
            noise_p: 0.5,
            excess: 0.0,
        };
        assert_eq!(before.explained_share(&after(90.0)), 0.25);
        assert_eq!(before.explained_share(&after(50.0)), 1.0);
        assert_eq!(before.explained_share(&after(120.0)), 0.0);
        assert!(after(80.0).explained_share(&after(70.0)).is_nan());
    }
}
