//! A window's transient: whether the local polynomials can tell it from
//! the noise beside a line ([`smooth_transient`]), and its variance added
//! to each single-sine line's σ, pooled over the lines of an experiment
//! (`pool_transients`).

use std::collections::BTreeMap;

use exo_impedance::frf::LocalPolynomialPoint;

use super::dataset::{Dataset, Observation};
use super::Tf;

/// Whether what the neighbouring frequencies hold is a linear transient:
/// smooth in frequency, so that the local polynomials leave only the white
/// noise (their residual's variance within the 99th percentile of
/// `χ²_{2ν}/2ν` over the white σ's, ν the fit's complex degrees of
/// freedom). A nonlinearity's non-periodic response (the impacts of a
/// backlash, ringing the arm's mode) or coloured noise is not, and the
/// polynomials would carry it into the line: no transient-free value then.
/// A fit with no degree of freedom cannot be checked and is not taken.
pub fn smooth_transient(l: &LocalPolynomialPoint, line_sigma: [f64; 2]) -> bool {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    if l.dof == 0 || !l.residual_sigma.is_finite() {
        return false;
    }
    let dof = 2.0 * l.dof as f64;
    let Ok(chi) = ChiSquared::new(dof) else {
        return false;
    };
    let white = 0.5 * (line_sigma[0].powi(2) + line_sigma[1].powi(2)) * l.leverage.max(1.0);
    white > 0.0 && l.residual_sigma.powi(2) / white <= chi.inverse_cdf(0.99) / dof
}

/// The smallest share of a line's white variance taken as noise
/// ([`pool_transients`]). On null recordings of both generators the share
/// measured beside the lines is 0.8–0.95 on average (docs/diagnose.md,
/// "The static balance by its own noise"); a relation with no noise at all
/// (a signal written as another's copy) measures 0, and its σ would vanish
/// against any imperfection of the forward model. An assumption: the white
/// σ is never taken below √0.5 of itself.
const MIN_NOISE_SHARE: f64 = 0.5;

/// A line's own transient beyond which it keeps its own estimate rather
/// than its experiment's pooled one: its squared leak over the estimate's
/// own noise beyond χ²₁'s 99th percentile (a window that clearly rang
/// more than the others of its experiment).
const OWN_TRANSIENT_CHI2: f64 = 6.635;

/// Whether a line's component keeps its own transient `d² − v` (its
/// squared leak `d2` beyond [`OWN_TRANSIENT_CHI2`] times the estimate's
/// own noise `v`) rather than its experiment's pooled one.
fn keeps_own_transient(d2: f64, v: f64) -> bool {
    d2 > OWN_TRANSIENT_CHI2 * v
}

/// Each single-sine line's σ (per component) with its window's transient
/// added as a variance (issue 30 item 3, stop 35). The transient at a line
/// is `d`, the line less its transient-free value (the local polynomials'
/// estimate, where its neighbours hold a smooth transient), whose own
/// noise is `v = σ²(leverage − 1)`; its variance is estimated by
/// `d² − v`, relative to the line's white `σ²`, **pooled** over the lines
/// of one experiment and transfer function and then clipped at zero. A
/// line-by-line clip (stop 34) is biased up: under pure noise
/// `E[max(d² − v, 0)] ≈ 0.48 v`, which left the nulls' χ²/dof at 0.65–0.79.
/// A line whose own `d²` exceeds [`OWN_TRANSIENT_CHI2`]·`v` keeps its own
/// `d² − v` when that is larger, and is left out of the pool (stop 37:
/// counted in both, one ringing window raised every quiet line's σ of its
/// experiment, and the nulls' χ²/dof sat at 0.6 where a few windows rang,
/// the rig's `S_h-e` at 1 kHz most). The line stays the value (a nonlinear
/// form's describing function); the transient is its uncertainty.
pub(super) fn pool_transients(d: &mut Dataset) {
    // The white σ's share that is noise, pooled per experiment and
    // transfer function: the local polynomials' residual over the white
    // σ, weighted by its degrees of freedom, at least MIN_NOISE_SHARE and
    // not capped at 1 (stop 46: a cap at 1 biased the share low where the
    // noise is white, whose pooled ratio scatters about 1, and where it is
    // coloured above the white level near the lines; dev nulls' χ²/dof
    // 1.042 → 1.018 (simulator), 1.097 → 1.073 (rig)).
    let mut noise: BTreeMap<(u32, Tf), (f64, f64)> = BTreeMap::new();
    for o in &d.observations {
        let Some(l) = o.transient_free.and_then(|t| t.local_noise) else {
            continue;
        };
        // (Only single-sine lines carry one; a line with no degree of
        // freedom weighs nothing.)
        if l.ratio.is_finite() {
            let g = noise
                .entry((d.conditions[o.window].experiment, o.tf))
                .or_default();
            g.0 += l.dof as f64 * l.ratio;
            g.1 += l.dof as f64;
        }
    }
    let share = |e: u32, tf: Tf| {
        noise
            .get(&(e, tf))
            .filter(|g| g.1 > 0.0)
            .map_or(1.0, |g| (g.0 / g.1).max(MIN_NOISE_SHARE))
    };
    // Per component: the line's noise variance, the estimate's own noise,
    // the leak.
    let parts = |o: &Observation, q: f64| -> Option<[(f64, f64, f64); 2]> {
        let t = o.transient_free.as_ref().filter(|_| o.tf.is_dynamic())?;
        let leak = o.value - t.value;
        let part = |k: usize, dk: f64| {
            let s2 = o.line_sigma[k].powi(2);
            (q * s2, q * (t.sigma[k].powi(2) - s2).max(0.0), dk * dk)
        };
        Some([part(0, leak.re), part(1, leak.im)])
    };
    let mut pooled: BTreeMap<(u32, Tf), (f64, usize)> = BTreeMap::new();
    for o in &d.observations {
        let e = d.conditions[o.window].experiment;
        let Some(ps) = parts(o, share(e, o.tf)) else {
            continue;
        };
        let g = pooled.entry((e, o.tf)).or_default();
        // A component that keeps its own transient is not pooled: counted
        // in both, its ring would be charged again to every quiet line.
        for (s2, v, d2) in ps
            .into_iter()
            .filter(|&(s2, v, d2)| s2 > 0.0 && !keeps_own_transient(d2, v))
        {
            g.0 += (d2 - v) / s2;
            g.1 += 1;
        }
    }
    for i in 0..d.observations.len() {
        let o = &d.observations[i];
        let e = d.conditions[o.window].experiment;
        let Some(ps) = parts(o, share(e, o.tf)) else {
            continue;
        };
        let (sum, n) = pooled[&(e, o.tf)];
        let r = if n > 0 {
            (sum / n as f64).max(0.0)
        } else {
            0.0
        };
        let sigma = ps.map(|(s2, v, d2)| {
            let own = if keeps_own_transient(d2, v) {
                d2 - v
            } else {
                0.0
            };
            (s2 + (r * s2).max(own)).sqrt()
        });
        d.observations[i].sigma = sigma;
    }
}

#[cfg(test)]
mod tests {
    use num_complex::Complex64;

    use super::*;
    use crate::data::{Condition, LocalNoise, TransientFree};

    /// An empty dataset with one window in experiment 1 (index 0) and one
    /// in experiment 2 (index 1).
    fn two_experiments() -> Dataset {
        let mut second = Condition::test_window(0.0, 0.1, 1e-3);
        second.experiment = 2;
        Dataset {
            conditions: vec![Condition::test_window(0.0, 0.1, 1e-3), second],
            ..Dataset::default()
        }
    }

    /// A line of white σ `s`, whose transient-free value lies `leak` from
    /// it with σ `s·√leverage`, in experiment `experiment`'s window.
    fn line(tf: Tf, window: usize, s: f64, leak: Complex64, leverage: f64) -> Observation {
        let value = Complex64::new(100.0, 10.0);
        Observation {
            tf,
            omega_rad_s: 2.0,
            value,
            sigma: [s, s],
            line_sigma: [s, s],
            transient_free: Some(TransientFree {
                value: value - leak,
                sigma: [s * leverage.sqrt(); 2],
                local_noise: None,
            }),
            accuracy: 0.0,
            window,
            gravity_comp: Complex64::new(0.0, 0.0),
            statics: [0.0; 2],
            sigma_dof: None,
        }
    }

    /// By hand: the transient's relative variance `(d² − σ²(lev − 1))/σ²`
    /// is averaged over an experiment's lines of one transfer function
    /// (both components), clipped at zero, and added as `r σ²`; a line
    /// whose own `d²` exceeds 6.635 times its estimate's noise keeps its
    /// own excess when larger and is not pooled; other experiments and transfer functions
    /// are pooled apart, and a line without a transient-free value is
    /// left alone.
    #[test]
    fn a_lines_transient_is_pooled_over_its_experiment_less_the_estimates_own() {
        let mut d = two_experiments();
        let c = |re: f64, im: f64| Complex64::new(re, im);
        // Experiment 1, S_h, σ 2, leverage 2 (estimate noise 4): parts
        // (16 − 4)/4, (0 − 4)/4 and (8 − 4)/4, (4 − 4)/4: sum 3 − 1 + 1 + 0
        // = 3 over 4, r = 0.75: σ² = 4 + 0.75·4 = 7. No d² above 6.635·4.
        d.observations.push(line(Tf::Sh, 0, 2.0, c(4.0, 0.0), 2.0));
        d.observations
            .push(line(Tf::Sh, 0, 2.0, c(8f64.sqrt(), 2.0), 2.0));
        // Experiment 1, S_h-e, σ 2, leverage 3 (estimate noise 8): parts
        // (0 − 8)/4 twice and (4 − 8)/4, (0 − 8)/4: sum −7, r clipped to
        // 0: the white σ alone.
        d.observations.push(line(Tf::She, 0, 2.0, c(0.0, 0.0), 3.0));
        d.observations.push(line(Tf::She, 0, 2.0, c(2.0, 0.0), 3.0));
        // Experiment 2, S_h: one line's real part rang clearly, d² = 25 >
        // 6.635·1: its own excess 24 kept, and that component left out of
        // the pool; two lines at d² = 4 in both parts (below 6.635: pooled,
        // +3 each) and nine quiet components (−1 each): the pool is
        // 12 − 9 = 3 over 13 components.
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(5.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(2.0, 2.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(2.0, 2.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        d.observations.push(line(Tf::Sh, 1, 1.0, c(0.0, 0.0), 2.0));
        let mut alone = line(Tf::Sh, 1, 3.0, c(9.0, 9.0), 2.0);
        alone.transient_free = None;
        d.observations.push(alone);
        // A line of σ 0 adds nothing to its pool (its parts would divide
        // by zero) and keeps σ 0.
        d.observations.push(line(Tf::Sh, 1, 0.0, c(0.0, 0.0), 2.0));
        // Experiment 2, S_h-e, σ 2, leverage 2 (estimate noise 4): one real
        // part at d² = 20, between 6.635 + 4 and 6.635·4 = 26.5: not its
        // own; the pool (20 − 4)/4 − 1 − 6·1 = −3 is clipped: σ 2 for all.
        d.observations
            .push(line(Tf::She, 1, 2.0, c(20f64.sqrt(), 0.0), 2.0));
        for _ in 0..3 {
            d.observations.push(line(Tf::She, 1, 2.0, c(0.0, 0.0), 2.0));
        }
        pool_transients(&mut d);
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
        let s = |i: usize| d.observations[i].sigma;
        assert!(close(s(0), [7f64.sqrt(); 2]), "{:?}", s(0));
        assert!(close(s(1), [7f64.sqrt(); 2]), "{:?}", s(1));
        assert!(close(s(2), [2.0; 2]), "{:?}", s(2));
        assert!(close(s(3), [2.0; 2]), "{:?}", s(3));
        let r: f64 = 3.0 / 13.0; // 12 − 9 over 13 components
        assert!(close(s(4), [(1.0 + r).sqrt(); 2]), "{:?}", s(4));
        assert!(close(s(5), [25f64.sqrt(), (1.0 + r).sqrt()]), "{:?}", s(5));
        assert!(close(s(6), [(1.0 + r).sqrt(); 2]), "{:?}", s(6));
        assert!(close(s(7), [(1.0 + r).sqrt(); 2]), "{:?}", s(7));
        assert_eq!(s(11), [3.0, 3.0], "no transient-free value: untouched");
        assert_eq!(s(12), [0.0, 0.0]);
        for i in 13..17 {
            assert!(close(s(i), [2.0, 2.0]), "{i}: {:?}", s(i));
        }
    }

    /// "Beyond" is strict: a leak exactly at 6.635 times its estimate's
    /// noise stays in the pool.
    #[test]
    fn a_leak_keeps_its_own_transient_only_beyond_the_threshold() {
        assert!(!keeps_own_transient(6.635 * 4.0, 4.0));
        assert!(keeps_own_transient(6.635 * 4.0 + 1e-9, 4.0));
        assert!(!keeps_own_transient(1.0, 4.0));
    }

    /// By hand: the white σ's share that is noise is the local noise ratio
    /// pooled over an experiment's lines of one transfer function, weighted
    /// by degrees of freedom ((4·0.5 + 6·0.8)/10 = 0.68), at least 0.5 and
    /// not capped at 1; it
    /// scales the line's noise and its estimate's before the transient is
    /// pooled, also for a line of the experiment without its own measure.
    #[test]
    fn the_white_sigma_is_scaled_by_the_noise_measured_beside_its_lines() {
        let mut d = two_experiments();
        let c = |re: f64| Complex64::new(re, 0.0);
        let with = |mut o: Observation, ratio: f64, dof: usize| {
            if let Some(t) = o.transient_free.as_mut() {
                t.local_noise = Some(LocalNoise { ratio, dof });
            }
            o
        };
        // Experiment 1, σ 2, leverage 3: q = 0.68, noise 2.72, the
        // estimate's 5.44; parts (4 − 5.44)/2.72, −2, (16 − 5.44)/2.72, −2,
        // −2, −2: negative, r = 0: every σ² is 2.72 (without the share it
        // would be 4).
        d.observations
            .push(with(line(Tf::Sh, 0, 2.0, c(2.0), 3.0), 0.5, 4));
        d.observations
            .push(with(line(Tf::Sh, 0, 2.0, c(4.0), 3.0), 0.8, 6));
        d.observations.push(line(Tf::Sh, 0, 2.0, c(0.0), 3.0));
        // Experiment 2: a ratio above 1 is taken as measured (1.5, σ² = 6;
        // its transient's part (0 − 1.5·(8 − 4))/6 is negative, none added).
        d.observations
            .push(with(line(Tf::Sh, 1, 2.0, c(0.0), 2.0), 1.5, 5));
        // Another transfer function of experiment 1: its own pool (none).
        d.observations.push(line(Tf::She, 0, 2.0, c(0.0), 2.0));
        // τ_s/τ_d of experiment 1 measured noiseless beside its line (a
        // copied signal): the share is held at 0.5, σ² = 0.5·4.
        d.observations
            .push(with(line(Tf::Sea, 0, 2.0, c(0.0), 2.0), 0.0, 3));
        // S_h-e of experiment 2 measured with no degree of freedom: it
        // weighs nothing, the share stays 1.
        d.observations
            .push(with(line(Tf::She, 1, 2.0, c(0.0), 2.0), 0.1, 0));
        pool_transients(&mut d);
        let s = |i: usize| d.observations[i].sigma;
        for i in 0..3 {
            assert!((s(i)[0] - 2.72f64.sqrt()).abs() < 1e-12, "{i}: {:?}", s(i));
            assert!((s(i)[1] - 2.72f64.sqrt()).abs() < 1e-12, "{i}: {:?}", s(i));
        }
        assert!((s(3)[0] - 6f64.sqrt()).abs() < 1e-12, "{:?}", s(3));
        assert!((s(3)[1] - 6f64.sqrt()).abs() < 1e-12, "{:?}", s(3));
        assert_eq!(s(4), [2.0, 2.0]);
        assert!((s(5)[0] - 2f64.sqrt()).abs() < 1e-12, "{:?}", s(5));
        assert_eq!(s(6), [2.0, 2.0]);
    }
}
