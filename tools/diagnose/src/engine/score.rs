//! A model's scores: the weighted RSS, complex R², two-fold held-out RSS
//! and lack-of-fit χ² per transfer function and in all ([`Score`]), and the
//! folds the held-out error is computed over.

use std::collections::BTreeMap;

use num_complex::Complex64;
use serde::Serialize;

use crate::data::{Dataset, Observation, Tf};
use crate::fit::{fit, lack_of_fit, lack_of_fit_chi2, rss};
use crate::model::{Param, Physics};

/// Fit quality of a model for one transfer function.
#[derive(Debug, Clone, Serialize)]
pub struct TfScore {
    /// Transfer function.
    pub tf: Tf,
    /// Observations.
    pub points: usize,
    /// Weighted residual sum of squares (χ² with the measured noise).
    pub rss: f64,
    /// Complex R² (1 − Σ|data − model|² / Σ|data − mean|²).
    pub r2: f64,
    /// Weighted RSS on held-out periods (two-fold over periods).
    pub heldout_rss: f64,
    /// Lack-of-fit χ² per real residual against the measured noise and the
    /// model's accuracy (1 when both are right; the model's own parameters
    /// are not subtracted here).
    pub chi2_per_residual: f64,
    /// The same of the transient-free values against their own noise
    /// alone (`Observation::transient_free`), no accuracy floor: reported
    /// for calibrating the noise model, not judged by (null in JSON when no
    /// window allows a transient-free value).
    pub noise_only_chi2_per_residual: f64,
}

/// A model's scores.
#[derive(Debug, Clone, Serialize)]
pub struct Score {
    /// Per transfer function.
    pub per_tf: Vec<TfScore>,
    /// Total weighted RSS.
    pub rss: f64,
    /// Total held-out RSS.
    pub heldout_rss: f64,
    /// χ² per degree of freedom against the measured noise and the model's accuracy.
    pub chi2_per_dof: f64,
    /// P-value of the lack-of-fit χ² test (per transfer function, Bonferroni
    /// over them) of the transfer functions whose misfit beyond the noise is
    /// larger than the forward model's accuracy ([`crate::fit::lack_of_fit`]):
    /// what the materiality rule judges.
    pub lack_of_fit_p: f64,
    /// The same test by the noise alone, every transfer function counted.
    pub noise_p: f64,
    /// The largest misfit beyond the noise, relative to the values
    /// (`fit::excess_relative`; the static balance left out).
    pub excess: f64,
    /// Free parameters.
    pub parameters: usize,
}

impl Score {
    /// Why a model's misfit is no missing physics: within the measured noise,
    /// or beyond it by less than the forward model's accuracy (the materiality
    /// rule, [`crate::fit::lack_of_fit`]).
    pub fn within_words(&self, level: f64, what: &str) -> String {
        let sc = self;
        if sc.noise_p < level {
            format!(
                "{what} is beyond the measured noise (χ²/dof {:.2}, p = {:.1e}) by {:.2} % of the values, within the forward model's accuracy ({:.1} %)",
                sc.chi2_per_dof,
                sc.noise_p,
                100.0 * sc.excess,
                100.0 * crate::fit::MODEL_ACCURACY
            )
        } else {
            format!(
                "{what} is within the measured noise (χ²/dof {:.2}, lack-of-fit p = {:.2})",
                sc.chi2_per_dof, sc.noise_p
            )
        }
    }
}

pub(super) fn score(d: &Dataset, start: &Physics, fitted: &Physics, free: &[Param]) -> Score {
    let mut per_tf = Vec::new();
    let folds = heldout(d, start, free);
    for &tf in &d.supported {
        let sel = |_: usize, o: &Observation| o.tf == tf;
        let (r, _) = rss(d, fitted, &sel);
        let obs: Vec<&Observation> = d.of(tf).collect();
        let mean = obs.iter().map(|o| o.value).sum::<Complex64>() / obs.len().max(1) as f64;
        let (mut ss_res, mut ss_tot) = (0.0, 0.0);
        for o in &obs {
            ss_res += (fitted.predict(o, &d.conditions[o.window]) - o.value).norm_sqr();
            ss_tot += (o.value - mean).norm_sqr();
        }
        per_tf.push(TfScore {
            tf,
            points: obs.len(),
            rss: r,
            r2: if ss_tot > 0.0 {
                1.0 - ss_res / ss_tot
            } else {
                f64::NAN
            },
            heldout_rss: folds.get(&tf).copied().unwrap_or(f64::NAN),
            chi2_per_residual: {
                let (chi, n) = crate::fit::lack_of_fit_chi2_of(d, fitted, Some(tf));
                chi / n.max(1) as f64
            },
            noise_only_chi2_per_residual: crate::fit::noise_only_chi2(d, fitted, tf),
        });
    }
    let (total, _) = rss(d, fitted, &|_, _| true);
    let (chi, n) = lack_of_fit_chi2(d, fitted);
    let dof = n as f64 - free.len() as f64;
    let lof = lack_of_fit(d, fitted, free.len(), 0.0);
    Score {
        rss: total,
        heldout_rss: per_tf.iter().map(|t| t.heldout_rss).sum(),
        chi2_per_dof: chi / dof.max(1.0),
        lack_of_fit_p: lof.p_value,
        noise_p: lof.noise_p,
        excess: lof.excess,
        parameters: free.len(),
        per_tf,
    }
}

/// Two-fold held-out RSS per transfer function: fit on odd periods, predict
/// even ones, and the reverse. With no free parameters it is the plain RSS.
pub(super) fn heldout(d: &Dataset, start: &Physics, free: &[Param]) -> BTreeMap<Tf, f64> {
    let folds = folds(d);
    let mut out: BTreeMap<Tf, f64> = BTreeMap::new();
    for fold in 0..2u8 {
        let train = |i: usize, _: &Observation| folds[i] != fold;
        let f = fit(d, start, free, &train);
        for &tf in &d.supported {
            let test = |i: usize, o: &Observation| o.tf == tf && folds[i] == fold;
            *out.entry(tf).or_default() += rss(d, &f.physics, &test).0;
        }
    }
    out
}

/// The fold (0 or 1) of every observation: the parity of its period when
/// its experiment has two periods or more; otherwise (one broadband
/// window) the parity of its rank in frequency within its window and
/// transfer function, so the held-out points interleave the band.
fn folds(d: &Dataset) -> Vec<u8> {
    let mut periods: BTreeMap<u32, std::collections::BTreeSet<u32>> = BTreeMap::new();
    for c in &d.conditions {
        periods.entry(c.experiment).or_default().insert(c.period);
    }
    let mut rank: BTreeMap<(usize, Tf), Vec<(f64, usize)>> = BTreeMap::new();
    for (i, o) in d.observations.iter().enumerate() {
        rank.entry((o.window, o.tf))
            .or_default()
            .push((o.omega_rad_s, i));
    }
    let mut by_rank = vec![0u8; d.observations.len()];
    for v in rank.values_mut() {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (r, &(_, i)) in v.iter().enumerate() {
            by_rank[i] = (r % 2) as u8;
        }
    }
    d.observations
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let c = &d.conditions[o.window];
            if periods.get(&c.experiment).is_some_and(|p| p.len() >= 2) {
                (c.period % 2) as u8
            } else {
                by_rank[i]
            }
        })
        .collect()
}
