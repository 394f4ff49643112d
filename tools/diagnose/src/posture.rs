//! The generic form that shows in the harmonics, not in the transfer
//! functions (issue 15, item 3): a stiffness of the human joint that
//! depends on posture.
//!
//! A spring `K d + ½ K₂ d²` (`d` the angle from the posture the human
//! holds, so that `dτ/dθ = K + K₂ d`) moved at `d = Re(Θ₁ e^{jωt})` puts
//! `¼ K₂ Θ₁²` into the 2nd harmonic of the cuff torque (`cos² x = ½ + ½ cos
//! 2x`) and nothing into its fundamental to first order in `K₂`: the
//! transfer functions do not see it, the 2nd harmonic of `τ_c` does. Per
//! single-sine window with the harmonics of `θ_e` and `τ_c`
//! ([`crate::signatures::window_harmonics`]), the part of `τ_c`'s 2nd
//! harmonic the current model does not explain is
//!
//! `y = T₂ − S_h(2ω) Θ₂ − ¼ K₂⁰ Θ₁²`, and the form predicts `m = ¼ Θ₁²`
//!
//! (`S_h(2ω) Θ₂` the linear human's response to the angle's own 2nd
//! harmonic, e.g. the one gravity's `sin θ` puts in). Both are whitened by
//! the noise of `τ_c`'s spectrum in the window, and `ΔK₂` is the real least
//! squares over the windows beside a nuisance per experiment, `η_e j Θ₂`:
//! the human's loss at 2ω is not measured (hysteretic damping is flat in
//! frequency, viscous grows with it, and the data are at ω), and an error
//! there moves the 2nd harmonic in proportion to the angle's.
//!
//! It is taken with the four criteria of the catalogue:
//! 1. the F-test of `ΔK₂` on the 2n real rows, at the search's level with
//!    Holm over every generic form of the library;
//! 2. the information criterion (BIC) falls;
//! 3. fitted on odd periods it predicts the even ones, and the reverse,
//!    with less misfit than without it (held-out periods);
//! 4. `ΔK₂` is determined (finite standard error, beyond two of them);
//!
//! and where it predicts beyond the fit: with two excitation amplitudes,
//! its `K₂` at the low amplitude and at the high one agree (the harmonic
//! grows as `A²`); one `K₂` holds for every experiment (a posture slope
//! that changes with the operating point is reported, not taken: it is not
//! this form). A difference counts when it is significant and material
//! ([`MATERIAL`]). With one amplitude the `A²` growth is not checked, and the
//! verdict says so.
//!
//! Assumptions: the windows' angle is a sine about the window's mean (the
//! form is fitted about that posture); the noise of the 2nd harmonic is
//! that of the neighbouring bins (white); the second-order change of the
//! fundamental (`K₂ δ`, `δ = −K₂ |Θ₁|² / 4K` the mean posture's shift) is
//! left to the transfer functions' per-experiment `K_h`.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use serde::Serialize;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::data::{Dataset, Tf};
use crate::model::Physics;
use crate::Term;

/// One window's row: the unexplained 2nd harmonic, the form's prediction
/// and the nuisance's regressor, whitened.
#[derive(Debug, Clone, Copy)]
struct Row {
    experiment: u32,
    period: u32,
    /// 0 low amplitude, 1 high; `None` with one amplitude.
    group: Option<u8>,
    y: Complex64,
    m: Complex64,
    /// `j Θ₂`: a loss stiffness of the human at 2ω other than the model's.
    n: Complex64,
}

/// Real least squares of `y` on the form's `m` and, per experiment, the
/// nuisance `η_e j Θ₂` (the human's loss at 2ω is extrapolated from the
/// fundamental's, hysteretic or viscous: its error moves the 2nd harmonic
/// by `j ΔH Θ₂`, in proportion to the form's own effect on the motion):
/// `(ΔK₂, se, RSS without the form, RSS with it, windows)`, the standard
/// error scaled by the scatter when it exceeds the noise's.
fn regress<'a>(rows: impl Iterator<Item = &'a Row> + Clone) -> Option<(f64, f64, f64, f64, usize)> {
    regress_with(rows, false).map(|r| (r.0[0], r.1[0], r.2, r.3, r.4))
}

/// [`regress`], with `quadrature` also a second form column `j m` (a 2nd
/// harmonic out of phase with `Θ₁²`, which no spring makes): the
/// coefficients `[in phase, quadrature]` and their standard errors (the
/// quadrature's 0 and NaN without it), the RSS without the form's columns
/// and with them, and the windows.
#[allow(clippy::type_complexity)]
fn regress_with<'a>(
    rows: impl Iterator<Item = &'a Row> + Clone,
    quadrature: bool,
) -> Option<([f64; 2], [f64; 2], f64, f64, usize)> {
    let rows: Vec<&Row> = rows.collect();
    let n = rows.len();
    let mut experiments: Vec<u32> = rows.iter().map(|r| r.experiment).collect();
    experiments.sort_unstable();
    experiments.dedup();
    let forms = if quadrature { 2 } else { 1 };
    let p = forms + experiments.len();
    if 2 * n <= p {
        return None;
    }
    let col = |e: u32| forms + experiments.iter().position(|&x| x == e).unwrap_or(0);
    let mut x = DMatrix::<f64>::zeros(2 * n, p);
    let mut y = DVector::<f64>::zeros(2 * n);
    for (i, r) in rows.iter().enumerate() {
        x[(2 * i, 0)] = r.m.re;
        x[(2 * i + 1, 0)] = r.m.im;
        if quadrature {
            // j m = (−m.im, m.re).
            x[(2 * i, 1)] = -r.m.im;
            x[(2 * i + 1, 1)] = r.m.re;
        }
        x[(2 * i, col(r.experiment))] = r.n.re;
        x[(2 * i + 1, col(r.experiment))] = r.n.im;
        y[2 * i] = r.y.re;
        y[2 * i + 1] = r.y.im;
    }
    let solve = |x: &DMatrix<f64>| -> Option<(DVector<f64>, f64, DMatrix<f64>)> {
        let inv = (x.transpose() * x).try_inverse()?;
        let b = &inv * (x.transpose() * &y);
        let rss = (&y - x * &b).norm_squared();
        Some((b, rss, inv))
    };
    let (b, rss1, inv) = solve(&x)?;
    let nuisance = x.columns(forms, p - forms).into_owned();
    let rss0 = solve(&nuisance).map_or(y.norm_squared(), |s| s.1);
    let dof = (2 * n - p) as f64;
    let scatter = rss1 / dof;
    let se = |k: usize| (scatter.max(1.0) * inv[(k, k)]).sqrt();
    let (coef, ses) = if quadrature {
        ([b[0], b[1]], [se(0), se(1)])
    } else {
        ([b[0], 0.0], [se(0), f64::NAN])
    };
    (coef[0].is_finite() && ses[0].is_finite()).then_some((coef, ses, rss0, rss1, n))
}

/// A difference between two fits of `K₂` that counts against the form:
/// beyond `tolerance` (its standard errors times z) and material, more than
/// [`MATERIAL`] of the larger value. The forward model's own second-order
/// errors (the cross terms with the 3rd harmonic, `½ K₂ Θ̄₁ Θ₂`) move a `K₂`
/// fitted on part of the windows by more than its noise-only standard
/// error, as the amplitude check of the transfer functions' forms found.
fn differs(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() > tolerance && (a - b).abs() > MATERIAL * a.abs().max(b.abs())
}

/// The materiality of a difference between fits of `K₂`: a fifth of the
/// larger value (the transfer-function forms' amplitude check uses
/// `1 − 1/√r`, 21 % for the protocol's amplitude ratio `r = 10^0.2`).
pub const MATERIAL: f64 = 0.2;

/// The form's fit and every criterion, for the report and the JSON.
#[derive(Debug, Clone, Serialize)]
pub struct PostureFit {
    /// Windows with the harmonics.
    pub windows: usize,
    /// The fitted `K₂` (Nm/rad²) in the model after it.
    pub k2_nm_per_rad2: f64,
    /// Standard error of the change of `K₂`.
    pub std_error: f64,
    /// Whitened RSS of the 2nd harmonic before and after.
    pub rss_before: f64,
    /// After.
    pub rss_after: f64,
    /// F and its Holm-corrected critical value.
    pub f: f64,
    /// Critical F.
    pub f_critical: f64,
    /// p-value times the library's size (Holm's first step).
    pub p_holm: f64,
    /// Change of the BIC.
    pub bic_change: f64,
    /// Relative change of the held-out RSS (odd periods predict even and back).
    pub heldout_change: f64,
    /// Share of the misfit beyond the noise it removes (NaN when the
    /// misfit was within the noise's expectation).
    pub explained_share: f64,
    /// Lack-of-fit p after it (the whitened RSS against χ² with 2n real
    /// rows less the form and one nuisance per experiment).
    pub lack_of_fit_p: f64,
    /// `K₂ ± se` per experiment.
    pub per_experiment: Vec<(u32, f64, f64)>,
    /// `K₂ ± se` at the low and the high amplitude, when there are two.
    pub per_amplitude: Option<[(f64, f64); 2]>,
    /// Taken: every criterion holds.
    pub accepted: bool,
    /// Why not, in words.
    pub rejected_because: Vec<String>,
    /// What the 2nd harmonic says, in words (also when rejected).
    pub finding: String,
}

/// `groups[i]`: the amplitude group of window `i` (0 low, 1 high), when
/// the single-sine windows have two amplitudes.
pub(crate) fn fit(
    d: &Dataset,
    current: &Physics,
    level: f64,
    groups: Option<&[Option<u8>]>,
    z: f64,
) -> Option<PostureFit> {
    if !d.supported.contains(&Tf::Sh) {
        return None;
    }
    let zero = Complex64::new(0.0, 0.0);
    // Each window's row, and the form's 2nd harmonic per unit K₂ relative
    // to τ_c's fundamental (`|¼ Θ₁²| / |T₁|`, per Nm/rad² of K₂).
    let (rows, relative): (Vec<Row>, Vec<f64>) = d
        .signals
        .iter()
        .zip(crate::signatures::sh_harmonics(d))
        .enumerate()
        .filter_map(|(i, (s, h))| {
            let (noise_power, th, tc) = (*h)?;
            let w = s.omega_rad_s;
            let c = &d.conditions[i];
            let sd = crate::signatures::component_sd(noise_power);
            let square = th[0] * th[0] * 0.25;
            let y =
                tc[1] - current.predict_tf(Tf::Sh, 2.0 * w, c, zero) * th[1] - current.k2 * square;
            Some((
                Row {
                    experiment: c.experiment,
                    period: c.period,
                    group: groups.and_then(|g| g.get(i).copied().flatten()),
                    y: y / sd,
                    m: square / sd,
                    n: Complex64::new(0.0, 1.0) * th[1] / sd,
                },
                square.norm() / tc[0].norm().max(1e-300),
            ))
        })
        .unzip();
    let (dk2, se, rss0, rss1, n) = regress(rows.iter())?;
    if n < 2 {
        return None;
    }
    let k2 = current.k2 + dk2;
    let mut experiments: Vec<u32> = rows.iter().map(|r| r.experiment).collect();
    experiments.sort_unstable();
    experiments.dedup();
    let n_real = (2 * n) as f64;
    let n_nuisance = experiments.len() as f64;
    let dof1 = n_real - 1.0 - n_nuisance;
    let f = (rss0 - rss1) / (rss1 / dof1).max(1e-300);
    let forms = (Term::FORMS.len() + Term::HARMONIC_FORMS.len()) as f64;
    let dist = FisherSnedecor::new(1.0, dof1).ok()?;
    let p_holm = (dist.sf(f.max(0.0)) * forms).min(1.0);
    let f_critical = dist.inverse_cdf(1.0 - level / forms);
    let bic_change = n_real * (rss1 / rss0.max(1e-300)).ln() + n_real.ln();
    // Held-out: K₂ from odd periods predicts the even ones and the reverse
    // (the held-out rows' RSS with their own nuisance, without the form and
    // with the training K₂ taken out).
    let (mut ho0, mut ho1) = (0.0, 0.0);
    for parity in 0..2u32 {
        let train = rows.iter().filter(|r| r.period % 2 != parity);
        let Some((b, ..)) = regress(train) else {
            continue;
        };
        let test: Vec<Row> = rows
            .iter()
            .filter(|r| r.period % 2 == parity)
            .copied()
            .collect();
        let shifted: Vec<Row> = test
            .iter()
            .map(|r| Row {
                y: r.y - b * r.m,
                ..*r
            })
            .collect();
        let (Some(before), Some(after)) = (regress(test.iter()), regress(shifted.iter())) else {
            continue;
        };
        ho0 += before.2;
        ho1 += after.2;
    }
    let heldout_change = if ho0 > 0.0 { ho1 / ho0 - 1.0 } else { f64::NAN };
    let beyond = rss0 - (n_real - n_nuisance);
    let explained_share = if beyond > 0.0 {
        ((rss0 - rss1) / beyond).clamp(0.0, 1.0)
    } else {
        f64::NAN
    };
    let lack_of_fit_p = statrs::distribution::ChiSquared::new(dof1)
        .map(|c| c.sf(rss1))
        .unwrap_or(f64::NAN);
    let per_experiment: Vec<(u32, f64, f64)> = experiments
        .iter()
        .filter_map(|&e| {
            let (b, s, ..) = regress(rows.iter().filter(|r| r.experiment == e))?;
            Some((e, current.k2 + b, s))
        })
        .collect();
    let per_amplitude = (0..2u8)
        .map(|g| {
            regress(rows.iter().filter(|r| r.group == Some(g))).map(|x| (current.k2 + x.0, x.1))
        })
        .collect::<Option<Vec<_>>>()
        .map(|v| [v[0], v[1]]);

    let mut why = Vec::new();
    // The materiality rule of the transfer functions' search
    // ([`crate::fit::LackOfFit`]): nothing is taken while what the linear
    // model leaves in the 2nd harmonic is within the noise.
    let p_before = statrs::distribution::ChiSquared::new(n_real - n_nuisance)
        .map(|c| c.sf(rss0))
        .unwrap_or(f64::NAN);
    if p_before.is_nan() || p_before >= level {
        why.push(format!(
            "the 2nd harmonic the linear model leaves is within the noise (χ²/dof {:.2}, p = {p_before:.2})",
            rss0 / (n_real - n_nuisance)
        ));
    }
    if !(p_holm < level && f > f_critical) {
        why.push(format!(
            "not significant: F = {f:.1} against a critical {f_critical:.2} (Holm over the library's {forms} forms)"
        ));
    }
    // NaN counts as not falling.
    if bic_change.is_nan() || bic_change >= 0.0 {
        why.push(format!("the BIC does not fall ({bic_change:+.1})"));
    }
    if heldout_change.is_nan() || heldout_change >= 0.0 {
        why.push(format!(
            "fitted on odd periods it does not predict the even ones (held-out {:+.0} %)",
            100.0 * heldout_change
        ));
    }
    if !crate::terms::determined(dk2, se) || dk2.abs() <= 2.0 * se {
        why.push(format!(
            "K₂ not determined or within two standard errors of none ({dk2:.1} ± {se:.1})"
        ));
    }
    if let Some([(lo, s_lo), (hi, s_hi)]) = per_amplitude {
        if differs(lo, hi, z * s_lo.hypot(s_hi)) {
            why.push(format!(
                "its 2nd harmonic does not grow as A²: K₂ = {} at the low amplitude, {} at the high one",
                crate::terms::value_pm(lo, Some(s_lo), 0, ""),
                crate::terms::value_pm(hi, Some(s_hi), 0, "")
            ));
        }
    }
    let chi2: f64 = per_experiment
        .iter()
        .map(|&(_, b, s)| ((b - k2) / s).powi(2))
        .sum();
    let (lo, hi) = per_experiment
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x.1), b.max(x.1))
        });
    let differ = per_experiment.len() >= 2
        && statrs::distribution::ChiSquared::new((per_experiment.len() - 1) as f64)
            .map(|c| c.sf(chi2) < level)
            .unwrap_or(false)
        && differs(lo, hi, 0.0);
    let per_words: Vec<String> = per_experiment
        .iter()
        .map(|&(e, b, s)| format!("exp {e}: {}", crate::terms::value_pm(b, Some(s), 0, "")))
        .collect();
    if differ {
        why.push(format!(
            "one K₂ does not hold for every experiment (χ² = {chi2:.1} over {}): the posture slope changes with the operating point ({})",
            per_experiment.len(),
            per_words.join(", ")
        ));
    }
    // Its phase: a spring's 2nd harmonic is in phase with `Θ₁²`; one that
    // leads or lags it (a damper's, a sensor's timing, another source at
    // 2ω) is not this form.
    let phase = regress_with(rows.iter(), true).map(|(b, s, ..)| (b, s));
    if let Some(([k_in, k_quad], [_, se_quad])) = phase {
        if differs(k_quad, 0.0, z * se_quad) && k_quad.abs() > MATERIAL * k_in.abs() {
            why.push(format!(
                "its 2nd harmonic is not in phase with Θ₁² as a spring's is: {:.1} Nm/rad² in phase, {} in quadrature",
                current.k2 + k_in,
                crate::terms::value_pm(k_quad, Some(se_quad), 0, "")
            ));
        }
    }
    // Material: the 2nd harmonic it puts in τ_c (RMS over the windows,
    // relative to the fundamental) must exceed the forward model's accuracy
    // (`fit::MODEL_ACCURACY`), below which it cannot be told from the
    // model's own error (the amplitude check's testability rule). On the
    // independent rig's nulls a K₂ of −0.33 ± 0.10 Nm/rad², 0.1 % of the
    // fundamental, was named before this rule.
    let size_pct = 100.0
        * k2.abs()
        * (relative.iter().map(|r| r * r).sum::<f64>() / relative.len().max(1) as f64).sqrt();
    if size_pct.is_nan() || size_pct < 100.0 * crate::fit::MODEL_ACCURACY {
        why.push(format!(
            "its 2nd harmonic, {size_pct:.2} % of τ_c's fundamental (RMS over the windows), is within the forward model's accuracy ({:.1} %): too small to be told from the model's own error",
            100.0 * crate::fit::MODEL_ACCURACY
        ));
    }
    let accepted = why.is_empty();
    let amplitude_words = match per_amplitude {
        Some([(lo, s_lo), (hi, s_hi)]) => format!(
            "K₂ {} at the low amplitude, {} at the high one",
            crate::terms::value_pm(lo, Some(s_lo), 0, ""),
            crate::terms::value_pm(hi, Some(s_hi), 0, "")
        ),
        None => "one amplitude: its growth as A² not checked (two amplitudes per frequency would check it)".into(),
    };
    let finding = format!(
        "2nd harmonic of τ_c beyond the linear model: {:.1} times the noise's expectation over {n} windows; as a posture slope K₂ = {} Nm/rad² explains {} of it ({amplitude_words}; {})",
        rss0 / n_real,
        crate::terms::value_pm(k2, Some(se), 0, ""),
        if explained_share.is_nan() {
            "none beyond the noise".to_string()
        } else {
            format!("{:.0} %", 100.0 * explained_share)
        },
        per_words.join(", ")
    );
    Some(PostureFit {
        windows: n,
        k2_nm_per_rad2: k2,
        std_error: se,
        rss_before: rss0,
        rss_after: rss1,
        f,
        f_critical,
        p_holm,
        bic_change,
        heldout_change,
        explained_share,
        lack_of_fit_p,
        per_experiment,
        per_amplitude,
        accepted,
        rejected_because: why,
        finding,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(experiment: u32, m: Complex64, n: Complex64, y: Complex64) -> Row {
        Row {
            experiment,
            period: 1,
            group: None,
            y,
            m,
            n,
        }
    }

    /// Five windows of two experiments: (experiment, the form's `m`, the
    /// nuisance's `n`, the experiment's nuisance coefficient `η_e`).
    fn windows() -> [(u32, Complex64, Complex64, f64); 5] {
        let c = |re: f64, im: f64| Complex64::new(re, im);
        [
            (1, c(1.0, 0.5), c(0.0, 1.0), 0.7),
            (1, c(0.3, -1.0), c(0.5, 0.2), 0.7),
            (1, c(-0.8, 0.1), c(0.2, -0.4), 0.7),
            (2, c(0.4, 0.9), c(1.0, 0.0), -1.2),
            (2, c(1.1, 0.2), c(-0.3, 0.6), -1.2),
        ]
    }

    /// A 2nd harmonic out of phase with `Θ₁²`: `y = (3 + 2j) m + η_e n`
    /// exactly; with the quadrature column the coefficients are 3 in phase
    /// and 2 in quadrature, with no residual; without it the in-phase fit
    /// leaves what `2j m` does not share with `m` and the nuisance.
    #[test]
    fn the_phase_of_the_harmonic_is_measured_in_quadrature() {
        let c = |re: f64, im: f64| Complex64::new(re, im);
        let data = windows();
        let rows: Vec<Row> = data
            .iter()
            .map(|&(e, m, n, eta)| row(e, m, n, c(3.0, 2.0) * m + eta * n))
            .collect();
        let ([k_in, k_quad], [_, se_quad], _, rss1, _) = regress_with(rows.iter(), true).unwrap();
        assert!(
            (k_in - 3.0).abs() < 1e-9 && (k_quad - 2.0).abs() < 1e-9,
            "{k_in} {k_quad}"
        );
        assert!(rss1 < 1e-18 && se_quad.is_finite());
        let (_, [_, none], _, rss_in, _) = regress_with(rows.iter(), false).unwrap();
        assert!(none.is_nan() && rss_in > 1e-3, "{rss_in}");
    }

    /// `y = 3 m + η_e n` exactly, with a nuisance of its own per experiment:
    /// the least squares recovers 3 with no residual, and without the form
    /// the residual is what `3 m` leaves after the nuisance's best fit,
    /// computed here by hand (one nuisance column per experiment: its
    /// projection `Re(n̄ r)/|n|²` per experiment).
    #[test]
    fn the_regression_separates_the_form_from_the_nuisance() {
        let data = windows();
        let rows: Vec<Row> = data
            .iter()
            .map(|&(e, m, n, eta)| row(e, m, n, 3.0 * m + eta * n))
            .collect();
        let (k2, _, rss0, rss1, n) = regress(rows.iter()).unwrap();
        assert!((k2 - 3.0).abs() < 1e-9, "{k2}");
        assert!(rss1 < 1e-18, "{rss1}");
        assert_eq!(n, 5);
        // Without the form: per experiment, r = 3 m projected off n.
        let mut expect = 0.0;
        for e in [1, 2] {
            let sel: Vec<&(u32, Complex64, Complex64, f64)> =
                data.iter().filter(|d| d.0 == e).collect();
            let y: Vec<Complex64> = sel.iter().map(|d| 3.0 * d.1 + d.3 * d.2).collect();
            let nn: f64 = sel.iter().map(|d| d.2.norm_sqr()).sum();
            let ny: f64 = sel.iter().zip(&y).map(|(d, y)| (d.2.conj() * y).re).sum();
            let eta = ny / nn;
            expect += sel
                .iter()
                .zip(&y)
                .map(|(d, y)| (y - eta * d.2).norm_sqr())
                .sum::<f64>();
        }
        assert!(
            (rss0 - expect).abs() < 1e-9 * expect,
            "{rss0} against {expect}"
        );
    }

    /// Too few rows for the form and a nuisance per experiment: no fit.
    #[test]
    fn one_window_per_experiment_and_one_real_row_each_is_not_enough() {
        let c = Complex64::new(1.0, 0.0);
        let rows = [row(1, c, c, c)];
        assert!(regress(rows.iter()).is_none());
    }

    /// A difference counts only when it is beyond its tolerance and more
    /// than a fifth of the larger value.
    #[test]
    fn a_difference_must_be_significant_and_material() {
        assert!(!differs(10.0, 11.0, 0.1)); // significant, 9 %: not material
        assert!(!differs(10.0, 14.0, 5.0)); // material, within the tolerance
        assert!(differs(10.0, 14.0, 1.0)); // 29 % beyond a tolerance of 1
        assert!(differs(-10.0, 10.0, 1.0));
        assert!(!differs(10.0, 12.4, 0.0)); // 19 %: just under a fifth
        assert!(differs(10.0, 12.6, 0.0)); // 21 %
    }
}
