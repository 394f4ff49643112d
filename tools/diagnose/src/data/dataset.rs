//! What the reduction gives: the observations ([`Observation`], with
//! [`TransientFree`] and [`LocalNoise`]), the windows' samples
//! ([`WindowSignals`]) and the whole [`Dataset`].

use num_complex::Complex64;
use serde::Serialize;

use super::condition::Condition;
use super::Tf;

/// One measured transfer-function value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Observation {
    /// Which transfer function.
    pub tf: Tf,
    /// Frequency (rad/s).
    pub omega_rad_s: f64,
    /// Measured value: a single-sine line, a broadband bin average, a
    /// static balance's mean.
    pub value: Complex64,
    /// Standard deviation of the real and of the imaginary part (same units
    /// as `value`), from the window's residual taken as white noise (a
    /// static balance's from the noise of its mean near zero frequency,
    /// with [`Self::sigma_dof`]): what the fits weight with.
    pub sigma: [f64; 2],
    /// The line's own σ, without its window's transient (a single-sine
    /// line whose transient the local polynomials estimated holds it in
    /// [`Self::sigma`]); equal to `sigma` elsewhere. A describing function
    /// is judged on these with the forward model's accuracy
    /// ([`Dataset::held_to`]).
    pub line_sigma: [f64; 2],
    /// The same with the window's transient taken out, where the window
    /// allows it: a single-sine line by the local polynomial method
    /// (`exo_impedance::frf::local_polynomial_ratio`; three cycles or more,
    /// neighbours that hold a smooth transient), with the white σ times
    /// √leverage; a static balance with the mean's noise measured at zero
    /// frequency (`exo_impedance::frf::mean_standard_error_beside`). Reported
    /// ([`crate::fit::noise_only_chi2`], the `residuals` example), not
    /// judged by: judged in place of the lines (stop 33) it cleared every
    /// null but lost two strongly nonlinear cases, whose response its
    /// polynomials partly carry (docs/diagnose.md, "The judgement by the
    /// measured noise").
    pub transient_free: Option<TransientFree>,
    /// The systematic uncertainty beyond the noise this value is held to
    /// (fraction of `|value|`): the forward model's accuracy
    /// [`crate::fit::MODEL_ACCURACY`], combined, for a value divided by the
    /// angle, with the encoder quantiser's gain error at the window's
    /// amplitude (`exo_impedance::quantiser::sine_gain_sd`). A physics with
    /// terms whose forward model is coarser holds every value to more
    /// ([`crate::fit::model_accuracy`]).
    pub accuracy: f64,
    /// Index of its window in [`Dataset::conditions`].
    pub window: usize,
    /// The controller's gravity compensation `τ_gravity/θ_e` at ω (Nm/rad), measured.
    pub gravity_comp: Complex64,
    /// For [`Tf::Balance`]: the window's mean `τ_gravity` and mean `τ_c` (Nm).
    pub statics: [f64; 2],
    /// Degrees of freedom of [`Self::sigma`] where it was estimated from so
    /// few values that a residual over it is Student-t distributed rather
    /// than normal: the static balance's mean noise, two per DFT bin it was
    /// measured at less the arm's motion's five regressors fitted there and
    /// the share the trend took (`exo_impedance::frf::mean_standard_error_beside`,
    /// about 6 for two cycles (six bins) to 18 for twelve or more). The
    /// lack-of-fit χ² takes such a residual at its normal equivalent
    /// ([`crate::fit::lack_of_fit_chi2`]). `None` where σ is known well
    /// enough to be taken as exact.
    pub sigma_dof: Option<f64>,
}

/// A line with its window's transient taken out ([`Observation::transient_free`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TransientFree {
    /// The value (units of the observation's).
    pub value: Complex64,
    /// Standard deviation of its real and imaginary part.
    pub sigma: [f64; 2],
    /// The noise beside the line (the local polynomials' own residual,
    /// `LocalPolynomialPoint::residual_sigma`) over what the white σ says
    /// there (`σ_white² · leverage`), with that residual's complex degrees
    /// of freedom: below 1 where the white σ also counted a ringing
    /// transient as noise. `None` for a static balance.
    pub local_noise: Option<LocalNoise>,
}

/// The noise measured beside a line against its white σ
/// ([`TransientFree::local_noise`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LocalNoise {
    /// `residual_sigma² / (σ_white² · leverage)` (1 for white noise).
    pub ratio: f64,
    /// Complex degrees of freedom of the residual.
    pub dof: usize,
}

/// The samples of one analysis window, kept for the time-domain comparison.
#[derive(Debug, Clone, Default)]
pub struct WindowSignals {
    /// Time from the window start (s).
    pub t_s: Vec<f64>,
    /// Measured angle (rad).
    pub theta_rad: Vec<f64>,
    /// Cuff torque (Nm).
    pub tau_c_nm: Vec<f64>,
    /// SEA torque less the controller's gravity compensation (Nm).
    pub tau_s_net_nm: Vec<f64>,
    /// SEA torque as measured (Nm).
    pub tau_s_nm: Vec<f64>,
    /// Motor command (Nm; NaN where the command was not recorded).
    pub tau_d_nm: Vec<f64>,
    /// Excitation frequency (rad/s; 0 for broadband).
    pub omega_rad_s: f64,
}

/// Everything the diagnosis uses from a set of recordings.
#[derive(Debug, Clone, Default)]
pub struct Dataset {
    /// Window conditions.
    pub conditions: Vec<Condition>,
    /// Observations (every transfer function of every window).
    pub observations: Vec<Observation>,
    /// Signals per window (same index as `conditions`).
    pub signals: Vec<WindowSignals>,
    /// What could not be used, each naming the file and window.
    pub notes: Vec<String>,
    /// Transfer functions the data supports.
    pub supported: Vec<Tf>,
    /// Sources read.
    pub sources: Vec<String>,
    /// Per window, the noise power of one bin of `τ_c`'s residual spectrum
    /// and the phasors of the fundamental, 2nd and 3rd harmonics of `θ_e`
    /// and of `τ_c` ([`crate::signatures::window_harmonics`]): they depend
    /// on the data only, so they are computed once, when first needed.
    pub(crate) sh_harmonics: std::sync::OnceLock<Vec<Option<ShHarmonics>>>,
    /// The same for `τ_s − τ_gravity` (`S_h-e`'s output) in place of `τ_c`.
    pub(crate) she_harmonics: std::sync::OnceLock<Vec<Option<ShHarmonics>>>,
    /// The change within each window of `S_h` and of `S_h-e`
    /// ([`super::within_window_rates`]), measured once when first needed.
    pub(crate) within_rates: [std::sync::OnceLock<Vec<super::WindowRate>>; 2],
    /// Per window, `τ_s`'s and `τ_d`'s residual noise power per bin and
    /// harmonic phasors ([`crate::signatures::window_harmonics`]), for the
    /// torque limit's check; measured once when first needed.
    pub(crate) sea_harmonics: std::sync::OnceLock<Vec<Option<SeaHarmonics>>>,
}

/// One window's `θ_e` and `τ_c` harmonics (see [`Dataset::sh_harmonics`]):
/// `(noise power of τ_c per bin, θ_e phasors, τ_c phasors)`.
pub(crate) type ShHarmonics = (f64, [Complex64; 3], [Complex64; 3]);

/// One window's `τ_s` and `τ_d` harmonics (see [`Dataset::sea_harmonics`]):
/// `((noise power of τ_s per bin, τ_s phasors), (the same of τ_d))`.
pub(crate) type SeaHarmonics = ((f64, [Complex64; 3]), (f64, [Complex64; 3]));

impl Dataset {
    /// The experiments present, sorted.
    pub fn experiments(&self) -> Vec<u32> {
        sorted_unique(self.conditions.iter().map(|c| c.experiment))
    }

    /// The experiments with a human impedance observation (`S_h` or
    /// `S_h-e`): only their `K_h`, `H_h` can be fitted.
    pub fn impedance_experiments(&self) -> Vec<u32> {
        sorted_unique(
            self.observations
                .iter()
                .filter(|o| matches!(o.tf, Tf::Sh | Tf::She))
                .map(|o| self.conditions[o.window].experiment),
        )
    }

    /// The same data with every dynamic value held to at least `accuracy`
    /// (fraction of `|value|`) and to its line's own σ: what a model whose forward model is a
    /// describing function ([`crate::terms::Term::describing_function`]) is
    /// fitted and tested on.
    pub fn held_to(&self, accuracy: f64) -> Dataset {
        let mut d = self.clone();
        for o in d.observations.iter_mut().filter(|o| o.tf.is_dynamic()) {
            o.sigma = o.line_sigma;
            o.accuracy = o.accuracy.max(accuracy);
        }
        d
    }

    /// Observations of one transfer function.
    pub fn of(&self, tf: Tf) -> impl Iterator<Item = &Observation> {
        self.observations.iter().filter(move |o| o.tf == tf)
    }
}

fn sorted_unique(it: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut e: Vec<u32> = it.collect();
    e.sort_unstable();
    e.dedup();
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Held to an accuracy: every dynamic value to its line's own σ and at
    /// least that accuracy (a coarser one of its own kept), the static
    /// balance as it was; the values themselves unchanged.
    #[test]
    fn data_held_to_an_accuracy_take_their_lines_own_sigma_and_the_floor() {
        let o = |tf: Tf, accuracy: f64| Observation {
            tf,
            omega_rad_s: 3.0,
            value: Complex64::new(10.0, 1.0),
            sigma: [2.0, 3.0],
            line_sigma: [0.5, 0.7],
            transient_free: None,
            accuracy,
            window: 0,
            gravity_comp: Complex64::new(0.0, 0.0),
            statics: [0.0; 2],
            sigma_dof: None,
        };
        let d = Dataset {
            observations: vec![o(Tf::Sh, 0.0), o(Tf::Sea, 0.02), o(Tf::Balance, 0.0)],
            ..Dataset::default()
        };
        let h = d.held_to(0.005);
        assert_eq!(h.observations.len(), 3);
        assert_eq!(h.observations[0].sigma, [0.5, 0.7]);
        assert_eq!(h.observations[0].accuracy, 0.005);
        assert_eq!(h.observations[1].sigma, [0.5, 0.7]);
        assert_eq!(h.observations[1].accuracy, 0.02);
        assert_eq!(h.observations[2], d.observations[2]);
        for (a, b) in h.observations.iter().zip(&d.observations) {
            assert_eq!(a.value, b.value);
        }
    }
}
