//! The weighted least squares every dependence is measured by: the rows of
//! a transfer function's relative residual with their noise, the
//! regression and its coefficients' standard errors and p-values, the
//! per-experiment trend in frequency, and the weighted mean.

use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ContinuousCDF, StudentsT};

use crate::data::{Dataset, Observation, Tf};
use crate::fit::sigma_floor;
use crate::model::Physics;

use super::Estimate;

pub(super) struct Row<'a> {
    pub(super) o: &'a Observation,
    pub(super) rel: [f64; 2],
    pub(super) sd: [f64; 2],
}

pub(super) fn rows<'a>(d: &'a Dataset, phys: &Physics, tf: Tf) -> Vec<Row<'a>> {
    d.of(tf)
        .map(|o| {
            let c = &d.conditions[o.window];
            let pred = phys.predict(o, c);
            if tf.is_dynamic() {
                // Relative residual, rotated into the model's phase: real
                // part in phase with the model, imaginary in quadrature.
                let scale = pred.norm().max(1e-12);
                let rel = (o.value - pred) * pred.conj() / (scale * scale);
                // Its standard deviation: the component noise over |model|
                // (the rotation mixes the two; their mean is used for both).
                let s = 0.5 * (sigma_floor(o, 0) + sigma_floor(o, 1)) / scale;
                Row {
                    o,
                    rel: [100.0 * rel.re, 100.0 * rel.im],
                    sd: [100.0 * s, 100.0 * s],
                }
            } else {
                let s = sigma_floor(o, 0);
                Row {
                    o,
                    rel: [o.value.re - pred.re, 0.0],
                    sd: [s, s],
                }
            }
        })
        .collect()
}

/// Weighted least squares: coefficients, their standard errors (scaled by
/// the residual variance when it exceeds 1) and the weighted RSS and dof.
pub(super) fn wls(
    x: &DMatrix<f64>,
    y: &[f64],
    sd: &[f64],
) -> Option<(Vec<f64>, Vec<f64>, f64, f64)> {
    let (n, p) = x.shape();
    if n <= p {
        return None;
    }
    let mut xw = x.clone();
    let mut yw = DVector::zeros(n);
    for i in 0..n {
        let w = 1.0 / sd[i].max(1e-300);
        for j in 0..p {
            xw[(i, j)] *= w;
        }
        yw[i] = y[i] * w;
    }
    let xtx = xw.transpose() * &xw;
    let inv = xtx.try_inverse()?;
    let beta = &inv * (xw.transpose() * &yw);
    let r = &yw - &xw * &beta;
    let dof = (n - p) as f64;
    let rss = r.norm_squared();
    let s2 = (rss / dof).max(1.0);
    let se: Vec<f64> = (0..p)
        .map(|j| {
            let v = inv[(j, j)] * s2;
            if v.is_finite() && v > 0.0 {
                v.sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    Some((beta.iter().copied().collect(), se, rss, dof))
}

pub(super) fn t_p(value: f64, se: f64, dof: f64) -> f64 {
    if !(se.is_finite() && se > 0.0 && dof > 0.0) {
        return f64::NAN;
    }
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |t| 2.0 * t.sf((value / se).abs()))
}

/// The last coefficient of the weighted regression of part `k` (0 in
/// phase, 1 in quadrature) of the rows' residual on the columns of `x`.
pub(super) fn last_coefficient(rs: &[Row], x: &DMatrix<f64>, k: usize) -> Option<Estimate> {
    let y: Vec<f64> = rs.iter().map(|r| r.rel[k]).collect();
    let sd: Vec<f64> = rs.iter().map(|r| r.sd[k]).collect();
    wls(x, &y, &sd).map(|(b, se, _, dof)| {
        let j = b.len() - 1;
        Estimate {
            value: b[j],
            std_error: se[j],
            p_value: t_p(b[j], se[j], dof),
        }
    })
}

/// Smooth trend columns in `ln ω` for the observations of `sel`.
pub(super) fn trend(rows: &[Row], sel: &dyn Fn(&Row) -> bool) -> Vec<Vec<f64>> {
    let xs: Vec<f64> = rows
        .iter()
        .filter(|r| sel(r))
        .map(|r| r.o.omega_rad_s.max(1e-9).ln())
        .collect();
    let n = xs.len().max(1) as f64;
    let m = xs.iter().sum::<f64>() / n;
    let distinct = {
        let mut v: Vec<i64> = xs.iter().map(|x| (x * 1e6) as i64).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    };
    let order = if distinct >= 5 {
        2
    } else if distinct >= 3 {
        1
    } else {
        0
    };
    let mut cols = vec![rows
        .iter()
        .map(|r| if sel(r) { 1.0 } else { 0.0 })
        .collect::<Vec<f64>>()];
    for k in 1..=order {
        cols.push(
            rows.iter()
                .map(|r| {
                    if sel(r) {
                        (r.o.omega_rad_s.max(1e-9).ln() - m).powi(k)
                    } else {
                        0.0
                    }
                })
                .collect(),
        );
    }
    cols
}

pub(super) fn matrix(cols: &[Vec<f64>]) -> DMatrix<f64> {
    let n = cols.first().map_or(0, Vec::len);
    DMatrix::from_fn(n, cols.len(), |i, j| cols[j][i])
}

/// Weighted mean of `y` (standard deviations `sd`), its standard error
/// scaled by the scatter about it when that exceeds the noise.
pub(super) fn weighted_mean(y: &[f64], sd: &[f64]) -> Estimate {
    let (mut sw, mut swy) = (0.0, 0.0);
    for (v, s) in y.iter().zip(sd) {
        let w = 1.0 / (s * s).max(1e-300);
        sw += w;
        swy += w * v;
    }
    let m = swy / sw;
    let dof = y.len() as f64 - 1.0;
    let chi: f64 = y.iter().zip(sd).map(|(v, s)| ((v - m) / s).powi(2)).sum();
    let scale = if dof > 0.0 { (chi / dof).max(1.0) } else { 1.0 };
    let se = (scale / sw).sqrt();
    Estimate {
        value: m,
        std_error: se,
        p_value: t_p(m, se, dof.max(1.0)),
    }
}
