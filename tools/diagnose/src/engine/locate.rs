//! Where the data and the nominal model differ ([`Location`]): the cells of
//! the located mismatch per transfer function, experiment and band, how the
//! residual scales across windows, the time-domain residuals and harmonics
//! per experiment and channel, and the summary in words.

use std::collections::BTreeMap;

use num_complex::Complex64;
use serde::Serialize;

use crate::band::band_of;
use crate::data::{Dataset, Observation, Tf};
use crate::fit::sigma_floor;
use crate::model::Physics;
use crate::stats::chi2_sf;

/// One cell of the located mismatch.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// Transfer function.
    pub tf: Tf,
    /// Experiment.
    pub experiment: u32,
    /// Band name.
    pub band: &'static str,
    /// Points.
    pub points: usize,
    /// Mean magnitude error `|data|/|model| − 1` (%).
    pub magnitude_pct: f64,
    /// Mean phase error `arg(data/model)` (degrees).
    pub phase_deg: f64,
    /// Mean squared whitened residual (1 = at the noise).
    pub chi2_per_point: f64,
    /// P-value of the cell's χ² (2 per point).
    pub p_value: f64,
    /// Significant after Bonferroni over the cells.
    pub significant: bool,
}

/// How a transfer function's residual scales across windows.
#[derive(Debug, Clone, Serialize)]
pub struct Scaling {
    /// Transfer function.
    pub tf: Tf,
    /// Correlation of the residual's quadrature part (relative) with `1/A` (angle amplitude).
    pub with_inverse_amplitude: f64,
    /// Correlation of the residual's in-phase part (relative) with `K_h`.
    pub with_stiffness: f64,
    /// Correlation of the residual's phase with ω.
    pub phase_with_omega: f64,
    /// Windows.
    pub windows: usize,
}

/// Time-domain view per experiment and channel.
#[derive(Debug, Clone, Serialize)]
pub struct TimeRow {
    /// Experiment.
    pub experiment: u32,
    /// Channel (`tau_c`, `tau_s_net`, `theta_e`).
    pub channel: &'static str,
    /// Mean of the channel over the analysis windows (Nm or rad).
    pub mean: f64,
    /// RMS of data − model over the windows (model = the channel's mean plus its
    /// transfer function times the measured angle's fundamental), nominal model.
    pub rms_residual_nominal: f64,
    /// Same with the final model.
    pub rms_residual_final: f64,
    /// 2nd and 3rd harmonic amplitude relative to the fundamental.
    pub harmonics: [f64; 2],
    /// Amplitude at 2.5 ω relative to the fundamental (the noise floor for the harmonics).
    pub floor: f64,
}

/// Where the data and the nominal model differ.
#[derive(Debug, Clone, Serialize)]
pub struct Location {
    /// Against the nominal model as given.
    pub nominal_cells: Vec<Cell>,
    /// Against the nominal model with its own parameters refitted.
    pub refit_cells: Vec<Cell>,
    /// Residual scaling after the refit.
    pub scaling: Vec<Scaling>,
    /// Time-domain residuals and harmonics.
    pub time: Vec<TimeRow>,
    /// Plain-words summary.
    pub summary: Vec<String>,
}

pub(super) fn cells(d: &Dataset, phys: &Physics, level: f64) -> Vec<Cell> {
    let mut groups: BTreeMap<(Tf, u32, &'static str), Vec<&Observation>> = BTreeMap::new();
    for o in &d.observations {
        let c = &d.conditions[o.window];
        groups
            .entry((o.tf, c.experiment, band_of(o.omega_rad_s)))
            .or_default()
            .push(o);
    }
    let m = groups.len().max(1) as f64;
    groups
        .into_iter()
        .map(|((tf, experiment, band), obs)| {
            let (mut mag, mut ph, mut chi) = (0.0, 0.0, 0.0);
            for o in &obs {
                let pred = phys.predict(o, &d.conditions[o.window]);
                let ratio = o.value / pred;
                mag += ratio.norm() - 1.0;
                ph += ratio.arg().to_degrees();
                let r = pred - o.value;
                chi += (r.re / sigma_floor(o, 0)).powi(2);
                if o.tf.is_dynamic() {
                    chi += (r.im / sigma_floor(o, 1)).powi(2);
                }
            }
            let n = obs.len() as f64;
            let per = if tf.is_dynamic() { 2.0 } else { 1.0 };
            let p_value = chi2_sf(chi, per * n);
            Cell {
                tf,
                experiment,
                band,
                points: obs.len(),
                magnitude_pct: 100.0 * mag / n,
                phase_deg: ph / n,
                chi2_per_point: chi / n,
                p_value,
                significant: p_value < level / m,
            }
        })
        .collect()
}

fn pearson(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    if x.len() < 3 {
        return f64::NAN;
    }
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    if sxx > 0.0 && syy > 0.0 {
        sxy / (sxx * syy).sqrt()
    } else {
        f64::NAN
    }
}

pub(super) fn scaling(d: &Dataset, phys: &Physics) -> Vec<Scaling> {
    d.supported
        .iter()
        .map(|&tf| {
            let (mut inv_a, mut quad, mut k, mut inph, mut w, mut ph) =
                (vec![], vec![], vec![], vec![], vec![], vec![]);
            for o in d.of(tf) {
                let c = &d.conditions[o.window];
                let pred = phys.predict(o, c);
                let rel = (o.value - pred) / pred.norm().max(1e-12);
                let rot = rel * (pred.conj() / pred.norm().max(1e-12));
                inv_a.push(1.0 / c.theta_amp_rad.max(1e-9));
                quad.push(rot.im);
                k.push(phys.k.get(&c.experiment).copied().unwrap_or(0.0));
                inph.push(rot.re);
                w.push(o.omega_rad_s);
                ph.push((o.value / pred).arg());
            }
            Scaling {
                tf,
                with_inverse_amplitude: pearson(&inv_a, &quad),
                with_stiffness: pearson(&k, &inph),
                phase_with_omega: pearson(&w, &ph),
                windows: quad.len(),
            }
        })
        .collect()
}

fn harmonic(t: &[f64], y: &[f64], w: f64) -> f64 {
    exo_impedance::frf::sine_amplitude(t, y, w, true).map_or(f64::NAN, |a| a.amplitude.norm())
}

pub(super) fn time_rows(d: &Dataset, nominal: &Physics, fin: &Physics) -> Vec<TimeRow> {
    let mut acc: BTreeMap<(u32, &'static str), Vec<[f64; 6]>> = BTreeMap::new();
    for (i, s) in d.signals.iter().enumerate() {
        let c = &d.conditions[i];
        let w = s.omega_rad_s;
        if w <= 0.0 || s.t_s.len() < 16 {
            continue;
        }
        let Ok(th) = exo_impedance::frf::sine_amplitude(&s.t_s, &s.theta_rad, w, true) else {
            continue;
        };
        let gravity = d
            .observations
            .iter()
            .find(|o| o.window == i && o.tf == Tf::She)
            .map_or(Complex64::new(0.0, 0.0), |o| o.gravity_comp);
        for (name, y, tf) in [
            ("tau_c", &s.tau_c_nm, Some(Tf::Sh)),
            ("tau_s_net", &s.tau_s_net_nm, Some(Tf::She)),
            ("theta_e", &s.theta_rad, None),
        ] {
            if tf.is_some_and(|tf| !d.supported.contains(&tf)) {
                continue;
            }
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            let fund = harmonic(&s.t_s, y, w);
            let rms = |p: &Physics| match tf {
                None => f64::NAN,
                Some(tf) => {
                    let g = p.predict_tf(tf, w, c, gravity);
                    let a = g * th.amplitude;
                    let mut e2 = 0.0;
                    for (t, v) in s.t_s.iter().zip(y.iter()) {
                        let m = mean + (a * Complex64::from_polar(1.0, w * t)).re;
                        e2 += (v - m).powi(2);
                    }
                    (e2 / y.len() as f64).sqrt()
                }
            };
            let row = [
                mean,
                rms(nominal),
                rms(fin),
                harmonic(&s.t_s, y, 2.0 * w) / fund,
                harmonic(&s.t_s, y, 3.0 * w) / fund,
                harmonic(&s.t_s, y, 2.5 * w) / fund,
            ];
            acc.entry((c.experiment, name)).or_default().push(row);
        }
    }
    acc.into_iter()
        .map(|((experiment, channel), rows)| {
            let avg = |k: usize| {
                let v: Vec<f64> = rows
                    .iter()
                    .map(|r| r[k])
                    .filter(|x| x.is_finite())
                    .collect();
                if v.is_empty() {
                    f64::NAN
                } else {
                    v.iter().sum::<f64>() / v.len() as f64
                }
            };
            TimeRow {
                experiment,
                channel,
                mean: avg(0),
                rms_residual_nominal: avg(1),
                rms_residual_final: avg(2),
                harmonics: [avg(3), avg(4)],
                floor: avg(5),
            }
        })
        .collect()
}

pub(super) fn summary_of(cells: &[Cell], what: &str) -> Vec<String> {
    let mut sig: Vec<&Cell> = cells.iter().filter(|c| c.significant).collect();
    if sig.is_empty() {
        return vec![format!(
            "{what}: no transfer function, band or experiment differs beyond the measured noise"
        )];
    }
    sig.sort_by(|a, b| b.chi2_per_point.total_cmp(&a.chi2_per_point));
    let mut by_tf: BTreeMap<(Tf, &'static str), Vec<&Cell>> = BTreeMap::new();
    for c in &sig {
        by_tf.entry((c.tf, c.band)).or_default().push(c);
    }
    let mut out: Vec<(f64, String)> = by_tf
        .into_iter()
        .map(|((tf, band), cs)| {
            let exps: Vec<String> = cs.iter().map(|c| c.experiment.to_string()).collect();
            let n = cs.len() as f64;
            let mag = cs.iter().map(|c| c.magnitude_pct).sum::<f64>() / n;
            let ph = cs.iter().map(|c| c.phase_deg).sum::<f64>() / n;
            let chi = cs.iter().map(|c| c.chi2_per_point).sum::<f64>() / n;
            let p = cs.iter().map(|c| c.p_value).fold(1.0, f64::min);
            (
                chi,
                format!(
                    "{what}: {} ({}) in the {band} band, experiments {}: magnitude {mag:+.1} %, phase {ph:+.2}°, {:.1}× the noise variance (p = {p:.1e}, {} cells)",
                    tf.name(),
                    tf.signals(),
                    exps.join(", "),
                    chi / if tf.is_dynamic() { 2.0 } else { 1.0 },
                    cs.len()
                ),
            )
        })
        .collect();
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out.into_iter().map(|(_, s)| s).collect()
}

#[cfg(test)]
mod tests {
    use super::pearson;

    /// Pearson's r by hand: a line up is 1, down −1; (1, 3, 2, 4) against
    /// (1, 2, 3, 4) is 0.8 (Σdxdy 4 over √(5·5)); three points are enough,
    /// two are not; a constant has no correlation.
    #[test]
    fn the_correlation_by_hand() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert!((pearson(&x, &[2.0, 4.0, 6.0, 8.0]) - 1.0).abs() < 1e-15);
        assert!((pearson(&x, &[8.0, 6.0, 4.0, 2.0]) + 1.0).abs() < 1e-15);
        assert!((pearson(&x, &[1.0, 3.0, 2.0, 4.0]) - 0.8).abs() < 1e-15);
        assert!((pearson(&x[..3], &[1.0, 3.0, 2.0]) - 0.5).abs() < 1e-15);
        assert!(pearson(&x[..2], &[1.0, 2.0]).is_nan());
        assert!(pearson(&x, &[3.0; 4]).is_nan());
        assert!(pearson(&[3.0; 4], &x).is_nan());
    }
}
