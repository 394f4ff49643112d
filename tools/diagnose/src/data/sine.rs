//! A single-sine window's lines: each transfer function's ratio at the
//! excitation frequency with its noise and, where the local polynomials
//! allow, its transient-free value.

use exo_impedance::frf::{local_polynomial_ratio, sine_ratio, SineCorrelator};
use num_complex::Complex64;

use super::balance::balance;
use super::condition::{CommandPeaks, Condition, GravityFundamentals};
use super::dataset::{Dataset, LocalNoise, Observation, TransientFree, WindowSignals};
use super::transient::smooth_transient;
use super::{Reduction, Tf};

fn sigma_of(cov: &[[f64; 2]; 2]) -> [f64; 2] {
    [cov[0][0].max(0.0).sqrt(), cov[1][1].max(0.0).sqrt()]
}

#[allow(clippy::too_many_arguments)]
pub(super) fn single_sine(
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
    let w = sig.omega_rad_s;
    let Ok(corr) = SineCorrelator::<6>::new(w, 0.0, true) else {
        d.notes.push(format!("{what}: ω = {w} is not usable"));
        return;
    };
    let mut corr = corr.with_names(["theta_e", "tau_c", "tau_s_net", "tau_s", "tau_d", "tau_g"]);
    for i in 0..sig.t_s.len() {
        let td = if tau_d[i].is_finite() { tau_d[i] } else { 0.0 };
        if corr
            .push(
                sig.t_s[i],
                &[
                    sig.theta_rad[i],
                    sig.tau_c_nm[i],
                    sig.tau_s_net_nm[i],
                    tau_s_raw[i],
                    td,
                    tau_g[i],
                ],
            )
            .is_err()
        {
            d.notes
                .push(format!("{what}: samples out of order, window skipped"));
            return;
        }
    }
    let end = sig.t_s.last().copied().unwrap_or(0.0) + cond.sample_period_s;
    let amps = match corr.finish(Some(end)) {
        Ok(a) => a,
        Err(e) => {
            d.notes.push(format!("{what}: {e}; window skipped"));
            return;
        }
    };
    let [a_th, a_tc, a_tsn, a_ts, a_td, a_tg] = amps;
    cond.theta_amp_rad = a_th.amplitude.norm();
    let theta_amp_rad = cond.theta_amp_rad;
    let encoder_step_rad = exo_impedance::quantiser::quantum(&sig.theta_rad).unwrap_or(0.0);
    let gravity_comp = if has_command {
        sine_ratio(&a_th, &a_tg).map_or(Complex64::new(0.0, 0.0), |p| p.ratio)
    } else {
        Complex64::new(0.0, 0.0)
    };
    let whole = exo_impedance::frf::whole_cycles(&sig.t_s, w);
    let td_filled: Vec<f64> = tau_d
        .iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect();
    let lines_before = d.observations.len();
    let mut push = |tf: Tf,
                    x: &exo_impedance::frf::SineAmplitude,
                    y: &exo_impedance::frf::SineAmplitude,
                    xs: &[f64],
                    ys: &[f64]| {
        match sine_ratio(x, y) {
            Ok(p)
                if p.coherence >= s.min_coherence
                    && p.ratio.re.is_finite()
                    && p.ratio.im.is_finite() =>
            {
                let line_sigma = sigma_of(&p.cov);
                // The window's transient out of the line; its price (the
                // leverage) on the white noise's σ, which stays the
                // judgement's (docs/diagnose.md, "The noise model").
                let lpm = whole
                    .and_then(|n| local_polynomial_ratio(&sig.t_s[..n], &xs[..n], &ys[..n], w));
                let smooth = lpm.filter(|l| smooth_transient(l, line_sigma));
                let transient_free = smooth.map(|l| {
                    let inflate = l.leverage.max(1.0).sqrt();
                    let white = 0.5 * (line_sigma[0].powi(2) + line_sigma[1].powi(2));
                    TransientFree {
                        value: l.ratio,
                        sigma: [line_sigma[0] * inflate, line_sigma[1] * inflate],
                        local_noise: (white > 0.0).then(|| LocalNoise {
                            ratio: l.residual_sigma.powi(2) / (white * l.leverage.max(1.0)),
                            dof: l.dof,
                        }),
                    }
                });
                // The encoder's quantiser at this amplitude, for the
                // values divided by the angle.
                let quantiser = if tf == Tf::Sea {
                    0.0
                } else {
                    exo_impedance::quantiser::sine_gain_sd(encoder_step_rad, theta_amp_rad)
                };
                // Judged: the line with its white σ, held to the forward
                // model's accuracy (its window's transient may reach it)
                // and the quantiser (docs/diagnose.md, "The judgement by
                // the measured noise").
                // Where the transient was estimated, its variance is added
                // to `sigma` once every window is in (`pool_transients`).
                let floor = match smooth {
                    Some(_) => 0.0,
                    None => crate::fit::MODEL_ACCURACY,
                };
                let sigma = line_sigma;
                d.observations.push(Observation {
                    tf,
                    omega_rad_s: w,
                    value: p.ratio,
                    sigma,
                    line_sigma,
                    transient_free,
                    accuracy: floor.hypot(quantiser),
                    window,
                    gravity_comp,
                    statics: [0.0; 2],
                    sigma_dof: None,
                })
            }
            Ok(p) => d.notes.push(format!(
                "{what}: {} left out: coherence {:.2} below {:.2}",
                tf.signals(),
                p.coherence,
                s.min_coherence
            )),
            Err(e) => d.notes.push(format!("{what}: {}: {e}", tf.signals())),
        }
    };
    push(Tf::Sh, &a_th, &a_tc, &sig.theta_rad, &sig.tau_c_nm);
    if has_command {
        push(Tf::She, &a_th, &a_tsn, &sig.theta_rad, &sig.tau_s_net_nm);
        if a_ts.amplitude.norm() > 0.0 {
            push(Tf::Sea, &a_td, &a_ts, &td_filled, tau_s_raw);
        }
        if let Some(n) = exo_impedance::frf::whole_cycles(&sig.t_s, w) {
            cond.gravity = GravityFundamentals::new(&sig.t_s[..n], &sig.theta_rad[..n], w);
            cond.command =
                CommandPeaks::new(&sig.t_s[..n], &tau_d[..n], w).map(std::sync::Arc::new);
        }
        // The static balance only beside a coherent line: where the arm
        // did not follow the excitation (every line's coherence below the
        // floor: it left its posture, fell or ran away) the window is no
        // identification window, its balance no static one (stop 45: on a
        // fresh null of the rig's random subject the arm was at −4.8 rad in
        // its last periods, every line left out, and the balance 0.17–0.25 Nm
        // off, 56–71 of its σ).
        if d.observations.len() > lines_before {
            balance(what, sig, tau_g, window, cond, d);
        } else {
            d.notes.push(format!(
                "{what}: static balance left out: no line of the window is coherent"
            ));
        }
    }
}
