//! The amplification law `α(s) = k_p F(s) + 1` (section "Loop Shaping
//! Methods"), or a constant α (the identification experiments, and the
//! `f = 0` case).

use exo_impedance::{fractional_gain, DiscreteLagFilter, LagFilter, Result};

/// The part `α(s) − 1` of the amplification, acting on `τ_c`.
///
/// The fractional variant holds its filter inline (fixed storage) so that
/// switching amplifiers never touches the heap; hence the size difference.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum Amplifier {
    /// `α − 1` constant.
    Constant {
        /// α.
        alpha: f64,
    },
    /// `α(s) − 1 = k_p F(s)` with the discrete lag-filter cascade.
    Fractional {
        /// `k_p`.
        kp: f64,
        /// `F(s)` discretised.
        filter: DiscreteLagFilter,
    },
}

impl Amplifier {
    /// The fractional-order amplifier of eqs. kp, kf and Fs: `k_f = ω̂_gc^f`
    /// with `ω̂_gc` from the nominal stiffness, discretised at `rate_hz`.
    pub fn fractional(
        kp: f64,
        f: f64,
        omega_gc_hat_rad_s: f64,
        filters: usize,
        p1_rad_s: f64,
        r_pp: f64,
        rate_hz: f64,
    ) -> Result<Self> {
        let kf = fractional_gain(omega_gc_hat_rad_s, f)?;
        let filter = LagFilter::new(filters, p1_rad_s, r_pp, f, kf)?.discretize(rate_hz)?;
        Ok(Amplifier::Fractional { kp, filter })
    }

    /// The amplification torque `−(α(s) − 1) τ_c` (Nm) for this tick.
    #[inline]
    pub fn step(&mut self, tau_c_nm: f64) -> f64 {
        match self {
            Amplifier::Constant { alpha } => -(*alpha - 1.0) * tau_c_nm,
            Amplifier::Fractional { kp, filter } => -*kp * filter.step(tau_c_nm),
        }
    }

    /// Sets a new constant α (ignored by the fractional amplifier, whose α(s) is fixed).
    pub fn set_constant_alpha(&mut self, new_alpha: f64) {
        if let Amplifier::Constant { alpha } = self {
            *alpha = new_alpha;
        }
    }

    /// Clears the filter state (after a fault, before re-enabling).
    pub fn reset(&mut self) {
        if let Amplifier::Fractional { filter, .. } = self {
            filter.reset();
        }
    }
}
