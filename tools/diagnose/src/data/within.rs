//! The change of `S_h` and `S_h-e` within each single-sine window, from
//! its first half to its second: measured from the data alone, once per
//! dataset ([`within_window_rates`]), for the drift's words
//! (`crate::remains`) and every candidate's signature check (the engine).

use super::{Dataset, Observation, Tf};

/// The change of `tf` (`S_h` or `S_h-e`; empty for the others) within each
/// single-sine window with at least four whole cycles, split into two
/// halves of equal whole cycles, each measured by the window's own
/// correlation. It depends on the signals and the observations' values
/// only (not their σ), so it is measured when first asked and kept with
/// the dataset (a copy held to an accuracy, [`Dataset::held_to`], keeps it).
pub fn within_window_rates(d: &Dataset, tf: Tf) -> &[WindowRate] {
    let k = match tf {
        Tf::Sh => 0,
        Tf::She => 1,
        _ => return &[],
    };
    d.within_rates[k].get_or_init(|| measure(d, tf))
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

fn measure(d: &Dataset, tf: Tf) -> Vec<WindowRate> {
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
