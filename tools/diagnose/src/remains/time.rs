//! The time dependences: the change within a window from its first half
//! to its second ([`within_window_rates`], [`WindowRate`]) and the drift
//! across the periods of an experiment.

use nalgebra::DVector;

use crate::data::{Dataset, Observation, Tf};

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

/// The measured rate of change of a transfer function within one window.
#[derive(Debug, Clone, Copy)]
pub struct WindowRate {
    /// The observation (its window, frequency and value).
    pub observation: Observation,
    /// Rate of change, in phase and in quadrature with the window's value
    /// (% of the value per second): second half less first over the time
    /// between their centres.
    pub rate: [f64; 2],
    /// Standard deviation of each component (% per second).
    pub sd: f64,
    /// Time between the halves' centres (s).
    pub dt_s: f64,
}

/// The change of `tf` (`S_h` or `S_h-e`) within each single-sine window
/// with at least four whole cycles, split into two halves of equal whole
/// cycles, each measured by the window's own correlation.
pub fn within_window_rates(d: &Dataset, tf: Tf) -> Vec<WindowRate> {
    use exo_impedance::frf::{sine_amplitude, sine_ratio, whole_cycles};
    let mut out = Vec::new();
    if !matches!(tf, Tf::Sh | Tf::She) {
        return out;
    }
    for o in d.of(tf) {
        let s = &d.signals[o.window];
        let w = o.omega_rad_s;
        if w <= 0.0 || s.t_s.len() < 32 {
            continue;
        }
        let output = if tf == Tf::Sh {
            &s.tau_c_nm
        } else {
            &s.tau_s_net_nm
        };
        let Some(n) = whole_cycles(&s.t_s, w) else {
            continue;
        };
        let dt = d.conditions[o.window].sample_period_s;
        let period = std::f64::consts::TAU / w;
        let t0 = s.t_s[0];
        let cycles = ((s.t_s[n - 1] - t0 + dt) / period).round() as usize;
        if cycles < 4 {
            continue;
        }
        let m = (cycles / 2) as f64;
        let i1 = s.t_s.partition_point(|t| *t < t0 + m * period - 0.5 * dt);
        let i2 = s
            .t_s
            .partition_point(|t| *t < t0 + 2.0 * m * period - 0.5 * dt);
        let half = |a: usize, b: usize| {
            let th = sine_amplitude(&s.t_s[a..b], &s.theta_rad[a..b], w, true).ok()?;
            let yy = sine_amplitude(&s.t_s[a..b], &output[a..b], w, true).ok()?;
            sine_ratio(&th, &yy).ok()
        };
        let (Some(p1), Some(p2)) = (half(0, i1), half(i1, i2)) else {
            continue;
        };
        let v = o.value;
        let scale = v.norm_sqr();
        if scale.is_nan() || scale <= 0.0 {
            continue;
        }
        let per_s = 100.0 / (m * period);
        let rel = (p2.ratio - p1.ratio) * v.conj() / scale * per_s;
        let var = 0.5 * (p1.cov[0][0] + p1.cov[1][1] + p2.cov[0][0] + p2.cov[1][1]) / scale
            * per_s
            * per_s;
        if !(var.is_finite() && var > 0.0 && rel.re.is_finite() && rel.im.is_finite()) {
            continue;
        }
        out.push(WindowRate {
            observation: *o,
            rate: [rel.re, rel.im],
            sd: var.sqrt(),
            dt_s: m * period,
        });
    }
    out
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
