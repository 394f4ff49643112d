//! A single-sine window's static balance ([`Tf::Balance`]).

use num_complex::Complex64;

use super::condition::Condition;
use super::dataset::{Dataset, Observation, TransientFree, WindowSignals};
use super::Tf;

/// The static balance over the window's whole cycles. Where the window
/// allows the noise of its mean to be measured near zero frequency
/// (`exo_impedance::frf::mean_standard_error_beside`: two cycles or more,
/// at the window's bins 1–12 less what the arm's motion explains there:
/// gravity's moment with sin θ, the damping and inertia with its
/// derivatives, a motion not periodic in the window by its boundary terms;
/// stop 45: before, bins 1–4 less sin θ's slope read the arm's ringing as
/// noise, and the balance's χ² sat at 0.64–0.77 on nulls) every
/// mean of the balance is the Hann-tapered one
/// (`exo_impedance::frf::hann_mean`: the line and a ringing mode's
/// boundary term `M_e Δθ̇/T` left out), judged by that noise times the
/// taper's gain with its few degrees of freedom
/// ([`Observation::sigma_dof`]). A shorter window keeps plain means and the
/// residual's standard error with each cycle counted as one sample
/// (conservative).
pub(super) fn balance(
    what: &str,
    sig: &WindowSignals,
    tau_g: &[f64],
    window: usize,
    cond: &mut Condition,
    d: &mut Dataset,
) {
    use exo_impedance::frf::{hann_mean, mean_standard_error_beside, HANN_MEAN_NOISE_GAIN};
    let w = sig.omega_rad_s;
    let Some(n) = exo_impedance::frf::whole_cycles(&sig.t_s, w) else {
        d.notes
            .push(format!("{what}: static balance: less than one cycle"));
        return;
    };
    let y: Vec<f64> = (0..n)
        .map(|i| sig.tau_s_net_nm[i] - sig.tau_c_nm[i])
        .collect();
    let sin_theta: Vec<f64> = sig.theta_rad[..n].iter().map(|t| t.sin()).collect();
    let (t_s, tau_c) = (&sig.t_s[..n], &sig.tau_c_nm[..n]);
    let plain = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
    // τ_s = its net part + the controller's gravity compensation.
    cond.tau_s_mean_nm = plain(&sig.tau_s_net_nm[..n]) + plain(&tau_g[..n]);
    let Ok(a) = exo_impedance::frf::sine_amplitude(t_s, &y, w, true) else {
        cond.sin_theta_mean = plain(&sin_theta);
        return;
    };
    // Its noise less what follows the arm's motion at those bins: the model
    // takes gravity's moment at the window's own mean sin θ, so a slow
    // wander of the angle is no noise of the residual (stop 37), nor is the
    // inertia's and damping's response to a ringing mode (stop 45).
    let measured = mean_standard_error_beside(t_s, &y, &sin_theta, w).filter(|(se, _)| *se > 0.0);
    let mean: &dyn Fn(&[f64]) -> f64 = if measured.is_some() {
        &hann_mean
    } else {
        &plain
    };
    let value = mean(&y);
    cond.sin_theta_mean = mean(&sin_theta);
    let statics = [mean(&tau_g[..n]), mean(tau_c)];
    let (se, sigma_dof) = match measured {
        Some((se, dof)) => (se * HANN_MEAN_NOISE_GAIN, Some(dof)),
        None => (
            (a.residual_var.max(0.0) / a.cycles.max(1) as f64).sqrt(),
            None,
        ),
    };
    let transient_free = measured.map(|_| TransientFree {
        value: Complex64::new(value, 0.0),
        sigma: [se, se],
        local_noise: None,
    });
    d.observations.push(Observation {
        tf: Tf::Balance,
        omega_rad_s: 0.0,
        value: Complex64::new(value, 0.0),
        sigma: [se, se],
        line_sigma: [se, se],
        transient_free,
        accuracy: 0.0,
        window,
        gravity_comp: Complex64::new(0.0, 0.0),
        statics,
        sigma_dof,
    });
}
