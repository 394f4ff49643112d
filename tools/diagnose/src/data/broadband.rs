//! A broadband window's bands: Welch's H1 estimate averaged into bands.

use exo_impedance::frf::{average_bins, band_groups, welch_h1};
use num_complex::Complex64;

use super::condition::Condition;
use super::dataset::{Dataset, Observation, WindowSignals};
use super::{Reduction, Tf};

#[allow(clippy::too_many_arguments)]
pub(super) fn broadband(
    what: &str,
    sig: &WindowSignals,
    tau_d: &[f64],
    tau_s_raw: &[f64],
    tau_g: &[f64],
    has_command: bool,
    window: usize,
    s: &Reduction,
    cond: &mut Condition,
    d: &mut Dataset,
) {
    let n = sig.t_s.len();
    let rate = 1.0 / cond.sample_period_s;
    let seg = s.welch_segment.min(n.next_power_of_two() / 2).max(16);
    let h_c = match welch_h1(&sig.theta_rad, &sig.tau_c_nm, rate, seg) {
        Ok(h) => h,
        Err(e) => {
            d.notes.push(format!("{what}: broadband estimate: {e}"));
            return;
        }
    };
    let mean = sig.theta_rad.iter().sum::<f64>() / n as f64;
    let var = sig
        .theta_rad
        .iter()
        .map(|x| (x - mean).powi(2))
        .sum::<f64>()
        / n as f64;
    cond.theta_amp_rad = (2.0 * var).sqrt();
    let [lo, hi] = s.broadband_band_rad_s;
    let groups = band_groups(&h_c, s.min_coherence, 1e-3, lo, hi, s.broadband_points);
    if groups.is_empty() {
        d.notes.push(format!(
            "{what}: no band of {lo}–{hi} rad/s with coherence ≥ {}",
            s.min_coherence
        ));
        return;
    }
    let extra = if has_command {
        let td: Vec<f64> = tau_d
            .iter()
            .map(|v| if v.is_finite() { *v } else { 0.0 })
            .collect();
        match (
            welch_h1(&sig.theta_rad, &sig.tau_s_net_nm, rate, seg),
            welch_h1(&td, tau_s_raw, rate, seg),
            welch_h1(&sig.theta_rad, tau_g, rate, seg),
        ) {
            (Ok(a), Ok(b), Ok(c)) => Some((a, b, c)),
            _ => None,
        }
    } else {
        None
    };
    let zero = Complex64::new(0.0, 0.0);
    for g in &groups {
        let Some(b) = average_bins(&h_c, g) else {
            continue;
        };
        let sd = |bin: &exo_impedance::frf::H1Bin| {
            let e = bin.noise_rel() * bin.h.norm() / std::f64::consts::SQRT_2;
            [e, e]
        };
        d.observations.push(Observation {
            tf: Tf::Sh,
            omega_rad_s: b.omega_rad_s,
            value: b.h,
            sigma: sd(&b),
            line_sigma: sd(&b),
            transient_free: None,
            accuracy: crate::fit::MODEL_ACCURACY,
            window,
            gravity_comp: zero,
            statics: [0.0; 2],
            sigma_dof: None,
        });
        if let Some((h_s, h_sea, h_g)) = &extra {
            let gravity_comp = average_bins(h_g, g).map_or(zero, |b| b.h);
            for (tf, h) in [(Tf::She, h_s), (Tf::Sea, h_sea)] {
                if let Some(bb) = average_bins(h, g) {
                    if bb.coherence >= s.min_coherence {
                        d.observations.push(Observation {
                            tf,
                            omega_rad_s: bb.omega_rad_s,
                            value: bb.h,
                            sigma: sd(&bb),
                            line_sigma: sd(&bb),
                            transient_free: None,
                            accuracy: crate::fit::MODEL_ACCURACY,
                            window,
                            gravity_comp,
                            statics: [0.0; 2],
                            sigma_dof: None,
                        });
                    }
                }
            }
        }
    }
}
