//! The time dependences: the change within a window from its first half
//! to its second (measured by [`crate::data::within_window_rates`]) and the
//! drift across the periods of an experiment.

use nalgebra::DVector;

use crate::data::{within_window_rates, Dataset, Tf};

use super::regress::{last_coefficient, matrix, trend, weighted_mean, Row};
use super::{TimeDependence, WithinWindow};

/// The change of `tf` within its single-sine windows: each window with at
/// least four whole cycles split into two halves of equal whole cycles.
pub(super) fn within_window(d: &Dataset, tf: Tf, alpha: f64) -> Option<WithinWindow> {
    let (mut y, mut sd): ([Vec<f64>; 2], [Vec<f64>; 2]) = Default::default();
    for r in within_window_rates(d, tf) {
        for k in 0..2 {
            y[k].push(r.rate[k]);
            sd[k].push(r.sd);
        }
    }
    if y[0].len() < 3 {
        return None;
    }
    let in_phase = weighted_mean(&y[0], &sd[0]);
    let quadrature = weighted_mean(&y[1], &sd[1]);
    Some(WithinWindow {
        windows: y[0].len(),
        significant: in_phase.p_value < alpha || quadrature.p_value < alpha,
        in_phase,
        quadrature,
    })
}

/// The residual's dependence on the time within an experiment (start time
/// of the window less that of the experiment's first window, in minutes).
pub(super) fn over_time(
    d: &Dataset,
    rs: &[Row],
    tf: Tf,
    exps: &[u32],
    alpha: f64,
    misfit: bool,
) -> Option<TimeDependence> {
    let exp_of = |r: &Row| d.conditions[r.o.window].experiment;
    let minutes: Vec<f64> = rs
        .iter()
        .map(|r| d.conditions[r.o.window].elapsed_s / 60.0)
        .collect();
    let mut base = Vec::new();
    for &e in exps {
        let sel = |r: &Row| exp_of(r) == e;
        if tf.is_dynamic() {
            base.extend(trend(rs, &sel));
        } else {
            base.push(rs.iter().map(|r| f64::from(u8::from(sel(r)))).collect());
        }
    }
    // The share of the time column the trend does not explain (ordinary
    // least squares), against its spread about each experiment's mean.
    let x0 = matrix(&base);
    let tv = DVector::from_column_slice(&minutes);
    let inv = (x0.transpose() * &x0).try_inverse()?;
    let resid = &tv - &x0 * (&inv * (x0.transpose() * &tv));
    let spread: f64 = exps
        .iter()
        .map(|&e| {
            let v: Vec<f64> = rs
                .iter()
                .zip(&minutes)
                .filter(|(r, _)| exp_of(r) == e)
                .map(|(_, m)| *m)
                .collect();
            let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
            v.iter().map(|m| (m - mean).powi(2)).sum::<f64>()
        })
        .sum();
    if spread.is_nan() || spread <= 0.0 {
        return None;
    }
    let share = (resid.norm_squared() / spread).sqrt();
    if share < 0.05 {
        return Some(TimeDependence {
            independent_share: share,
            confounded_with_frequency: true,
            in_phase: None,
            quadrature: None,
            significant: false,
        });
    }
    let mut cols = base;
    cols.push(minutes);
    let x = matrix(&cols);
    let fit_part = |k: usize| last_coefficient(rs, &x, k);
    let ip = fit_part(0);
    let q = if tf.is_dynamic() { fit_part(1) } else { None };
    let significant =
        misfit && (ip.is_some_and(|e| e.p_value < alpha) || q.is_some_and(|e| e.p_value < alpha));
    Some(TimeDependence {
        independent_share: share,
        confounded_with_frequency: false,
        in_phase: ip,
        quadrature: q,
        significant,
    })
}
