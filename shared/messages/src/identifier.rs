//! The identifier's outputs: identifier → controller, operator, recorder.
//!
//! One [`FrfPoint`] per analysed period (one excitation frequency), and an
//! [`ImpedanceEstimate`] refitted after every new point. Parameters a model
//! does not have are sent as 0 (with standard error 0), never NaN, so the
//! messages stay finite.

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

use crate::error::{check_finite, check_range, MessageError};

/// One frequency-response point, from one analysis window at one frequency.
///
/// Three transfer functions at ω, each named for what it is:
/// - `s_h`: the human alone, `S_h = τ_c/θ_e`, measured (the cuff);
/// - `s_hea`: the paper's `S_{h-e/α} = S_h + (M_e/α) s²`, **re-created** from
///   `S_h` with the known `M_e/α` (text after eq. Sh3), not measured;
/// - `s_he`: the actuator's side, `(τ_s − τ_gravity)/θ_e = S_h + M_e s²`,
///   measured from the SEA torque (the *whole* `M_e`, whatever α is).
///
/// 120 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "ipc", derive(ZeroCopySend), type_name("exo.FrfPoint.v2"))]
#[repr(C)]
pub struct FrfPoint {
    /// Sequence number (count) of this point.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock of the end of the analysis window.
    pub stamp_ns: u64,
    /// Experiment number (1–9) the window belongs to.
    pub experiment: u32,
    /// Period number (1–10) the window belongs to.
    pub period: u32,
    /// Excitation angular frequency ω (rad/s) at which the FRF is evaluated.
    pub omega: f64,
    /// Human dynamic stiffness `S_h(jω) = τ_c/θ_e`, real part (Nm/rad).
    pub s_h_re: f64,
    /// Human dynamic stiffness `S_h(jω) = τ_c/θ_e`, imaginary part (Nm/rad).
    pub s_h_im: f64,
    /// `S_{h-e/α}(jω) = S_h(jω) − (M_e/α) ω²`, re-created from `S_h` (eqs. M1–M3), real part (Nm/rad).
    pub s_hea_re: f64,
    /// `S_{h-e/α}(jω)`, re-created from `S_h`, imaginary part (Nm/rad).
    pub s_hea_im: f64,
    /// SEA torque tracking `τ_s/τ_d` at ω, real part (dimensionless).
    pub sea_re: f64,
    /// SEA torque tracking `τ_s/τ_d` at ω, imaginary part (dimensionless).
    pub sea_im: f64,
    /// Magnitude-squared coherence of `τ_c` and `θ_e` at ω (dimensionless, 0–1).
    pub coherence: f64,
    /// Relative noise of `S_h` (dimensionless): its standard error divided by `|S_h|`.
    pub noise_rel: f64,
    /// Actuator side `(τ_s − τ_gravity)/θ_e = S_h + M_e s²`, measured, real part (Nm/rad).
    pub s_he_re: f64,
    /// Actuator side `(τ_s − τ_gravity)/θ_e`, measured, imaginary part (Nm/rad).
    pub s_he_im: f64,
    /// Relative noise of `s_he` (dimensionless): its standard error divided by its magnitude.
    pub s_he_noise_rel: f64,
}

crate::impl_message!(FrfPoint, "exo.FrfPoint.v2", |p| [
    "omega" => p.omega,
    "s_h_re" => p.s_h_re,
    "s_h_im" => p.s_h_im,
    "s_hea_re" => p.s_hea_re,
    "s_hea_im" => p.s_hea_im,
    "sea_re" => p.sea_re,
    "sea_im" => p.sea_im,
    "coherence" => p.coherence,
    "noise_rel" => p.noise_rel,
    "s_he_re" => p.s_he_re,
    "s_he_im" => p.s_he_im,
    "s_he_noise_rel" => p.s_he_noise_rel,
]);

impl FrfPoint {
    /// Checks finiteness, `omega > 0`, `0 <= coherence <= 1` and `noise_rel >= 0`.
    pub fn validate(&self) -> Result<(), MessageError> {
        const M: &str = "FrfPoint";
        check_finite(M, self.first_non_finite())?;
        check_range(M, "omega", self.omega, f64::MIN_POSITIVE, f64::INFINITY)?;
        check_range(M, "coherence", self.coherence, 0.0, 1.0)?;
        check_range(M, "noise_rel", self.noise_rel, 0.0, f64::INFINITY)?;
        check_range(M, "s_he_noise_rel", self.s_he_noise_rel, 0.0, f64::INFINITY)
    }
}

/// The impedance model of an [`ImpedanceEstimate`]; `model` as a `u32`.
/// Same numbering as `exo_impedance::ImpedanceModel`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum FitModel {
    /// Eq. M1: `M s² + B s + K` (viscous damping only; `h_h` = 0).
    M1 = 1,
    /// Eq. M2: `M s² + K + jH` (hysteretic damping only; `b_h` = 0).
    M2 = 2,
    /// Eq. M3: `M s² + B s + K + jH` (both).
    M3 = 3,
}

impl FitModel {
    /// Every model, in code order.
    pub const ALL: [FitModel; 3] = [FitModel::M1, FitModel::M2, FitModel::M3];

    /// The model of a raw code (1–3), or `None`.
    pub fn from_u32(code: u32) -> Option<Self> {
        match code {
            1 => Some(FitModel::M1),
            2 => Some(FitModel::M2),
            3 => Some(FitModel::M3),
            _ => None,
        }
    }

    /// The raw code sent in [`ImpedanceEstimate::model`].
    pub fn as_u32(self) -> u32 {
        self as u32
    }
}

/// The identifier's model fit after the latest [`FrfPoint`] of an experiment.
///
/// `S_h(s) = M_h s² + B_h s + K_h + j H_h`; the loss factor is `c_h = H_h/K_h`;
/// the subject's power law is `H = 10^β0 · K^β1` over the experiments so far.
/// Unknown or absent values are 0.
///
/// 176 bytes, 8-aligned, no implicit padding.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(
    feature = "ipc",
    derive(ZeroCopySend),
    type_name("exo.ImpedanceEstimate.v1")
)]
#[repr(C)]
pub struct ImpedanceEstimate {
    /// Sequence number (count) of this estimate.
    pub seq: u64,
    /// Time stamp (ns) on the monotonic clock when the fit finished.
    pub stamp_ns: u64,
    /// Experiment number (1–9) the fit belongs to.
    pub experiment: u32,
    /// Period number (1–10) of the latest FRF point used.
    pub period: u32,
    /// Number of FRF points in the fit (count).
    pub n_points: u32,
    /// [`FitModel`] code (1–3) of the parameters below.
    pub model: u32,
    /// Stiffness K_h (Nm/rad), real part of the complex stiffness.
    pub k_h: f64,
    /// Standard error of K_h (Nm/rad).
    pub k_h_se: f64,
    /// Hysteretic damping H_h (Nm/rad), imaginary part of the complex stiffness.
    pub h_h: f64,
    /// Standard error of H_h (Nm/rad).
    pub h_h_se: f64,
    /// Viscous damping B_h (Nm·s/rad).
    pub b_h: f64,
    /// Standard error of B_h (Nm·s/rad).
    pub b_h_se: f64,
    /// Inertia M_h (kg·m², i.e. Nm·s²/rad).
    pub m_h: f64,
    /// Standard error of M_h (kg·m²).
    pub m_h_se: f64,
    /// Hysteretic loss factor c_h = H_h/K_h (dimensionless).
    pub c_h: f64,
    /// Standard error of c_h (dimensionless, propagated from K_h and H_h).
    pub c_h_se: f64,
    /// Coefficient of determination R² of the fit (dimensionless, ≤ 1).
    pub r2: f64,
    /// F statistic of M1 against M3 (dimensionless).
    pub f_m1_m3: f64,
    /// F statistic of M2 against M3 (dimensionless).
    pub f_m2_m3: f64,
    /// Critical F value at the 5 % level for these degrees of freedom (dimensionless).
    pub f_critical: f64,
    /// Power-law intercept β0 of `log10 H = β0 + β1 log10 K` (dimensionless, log10 of Nm/rad).
    pub beta0: f64,
    /// Power-law slope β1 (dimensionless).
    pub beta1: f64,
    /// R² of the power-law regression (dimensionless).
    pub power_law_r2: f64,
    /// Fractional order f recommended by eq. f (dimensionless, in [0, 1)); 0 until known.
    pub recommended_f: f64,
}

crate::impl_message!(ImpedanceEstimate, "exo.ImpedanceEstimate.v1", |e| [
    "k_h" => e.k_h,
    "k_h_se" => e.k_h_se,
    "h_h" => e.h_h,
    "h_h_se" => e.h_h_se,
    "b_h" => e.b_h,
    "b_h_se" => e.b_h_se,
    "m_h" => e.m_h,
    "m_h_se" => e.m_h_se,
    "c_h" => e.c_h,
    "c_h_se" => e.c_h_se,
    "r2" => e.r2,
    "f_m1_m3" => e.f_m1_m3,
    "f_m2_m3" => e.f_m2_m3,
    "f_critical" => e.f_critical,
    "beta0" => e.beta0,
    "beta1" => e.beta1,
    "power_law_r2" => e.power_law_r2,
    "recommended_f" => e.recommended_f,
]);

impl ImpedanceEstimate {
    /// The model, or `None` if `model` holds an unknown code.
    pub fn fit_model(&self) -> Option<FitModel> {
        FitModel::from_u32(self.model)
    }

    /// Checks finiteness, the model code, non-negative standard errors and
    /// `0 <= recommended_f < 1`.
    pub fn validate(&self) -> Result<(), MessageError> {
        const M: &str = "ImpedanceEstimate";
        check_finite(M, self.first_non_finite())?;
        if self.fit_model().is_none() {
            return Err(MessageError::UnknownCode {
                message: M,
                field: "model",
                value: self.model,
            });
        }
        for (field, se) in [
            ("k_h_se", self.k_h_se),
            ("h_h_se", self.h_h_se),
            ("b_h_se", self.b_h_se),
            ("m_h_se", self.m_h_se),
            ("c_h_se", self.c_h_se),
        ] {
            check_range(M, field, se, 0.0, f64::INFINITY)?;
        }
        check_range(
            M,
            "recommended_f",
            self.recommended_f,
            0.0,
            1.0 - f64::EPSILON,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    #[test]
    fn frf_point_layout() {
        assert_eq!(size_of::<FrfPoint>(), 120);
        assert_eq!(align_of::<FrfPoint>(), 8);
        assert_eq!(offset_of!(FrfPoint, seq), 0);
        assert_eq!(offset_of!(FrfPoint, stamp_ns), 8);
        assert_eq!(offset_of!(FrfPoint, experiment), 16);
        assert_eq!(offset_of!(FrfPoint, period), 20);
        assert_eq!(offset_of!(FrfPoint, omega), 24);
        assert_eq!(offset_of!(FrfPoint, s_h_re), 32);
        assert_eq!(offset_of!(FrfPoint, s_h_im), 40);
        assert_eq!(offset_of!(FrfPoint, s_hea_re), 48);
        assert_eq!(offset_of!(FrfPoint, s_hea_im), 56);
        assert_eq!(offset_of!(FrfPoint, sea_re), 64);
        assert_eq!(offset_of!(FrfPoint, sea_im), 72);
        assert_eq!(offset_of!(FrfPoint, coherence), 80);
        assert_eq!(offset_of!(FrfPoint, noise_rel), 88);
        assert_eq!(offset_of!(FrfPoint, s_he_re), 96);
        assert_eq!(offset_of!(FrfPoint, s_he_im), 104);
        assert_eq!(offset_of!(FrfPoint, s_he_noise_rel), 112);
    }

    #[test]
    fn impedance_estimate_layout() {
        assert_eq!(size_of::<ImpedanceEstimate>(), 176);
        assert_eq!(align_of::<ImpedanceEstimate>(), 8);
        assert_eq!(offset_of!(ImpedanceEstimate, seq), 0);
        assert_eq!(offset_of!(ImpedanceEstimate, stamp_ns), 8);
        assert_eq!(offset_of!(ImpedanceEstimate, experiment), 16);
        assert_eq!(offset_of!(ImpedanceEstimate, period), 20);
        assert_eq!(offset_of!(ImpedanceEstimate, n_points), 24);
        assert_eq!(offset_of!(ImpedanceEstimate, model), 28);
        let f64_fields = [
            offset_of!(ImpedanceEstimate, k_h),
            offset_of!(ImpedanceEstimate, k_h_se),
            offset_of!(ImpedanceEstimate, h_h),
            offset_of!(ImpedanceEstimate, h_h_se),
            offset_of!(ImpedanceEstimate, b_h),
            offset_of!(ImpedanceEstimate, b_h_se),
            offset_of!(ImpedanceEstimate, m_h),
            offset_of!(ImpedanceEstimate, m_h_se),
            offset_of!(ImpedanceEstimate, c_h),
            offset_of!(ImpedanceEstimate, c_h_se),
            offset_of!(ImpedanceEstimate, r2),
            offset_of!(ImpedanceEstimate, f_m1_m3),
            offset_of!(ImpedanceEstimate, f_m2_m3),
            offset_of!(ImpedanceEstimate, f_critical),
            offset_of!(ImpedanceEstimate, beta0),
            offset_of!(ImpedanceEstimate, beta1),
            offset_of!(ImpedanceEstimate, power_law_r2),
            offset_of!(ImpedanceEstimate, recommended_f),
        ];
        for (i, off) in f64_fields.into_iter().enumerate() {
            assert_eq!(off, 32 + 8 * i, "f64 field #{i}");
        }
    }

    #[test]
    fn model_codes() {
        for m in FitModel::ALL {
            assert_eq!(FitModel::from_u32(m.as_u32()), Some(m));
        }
        assert_eq!(FitModel::from_u32(0), None);
        assert_eq!(FitModel::from_u32(4), None);
    }

    #[test]
    fn validation() {
        let p = FrfPoint {
            omega: 6.0,
            coherence: 0.9,
            ..Default::default()
        };
        assert_eq!(p.validate(), Ok(()));
        assert_eq!(
            FrfPoint {
                coherence: 1.2,
                ..p
            }
            .validate()
            .unwrap_err()
            .field(),
            "coherence"
        );
        assert_eq!(
            FrfPoint {
                sea_im: f64::NAN,
                ..p
            }
            .validate()
            .unwrap_err()
            .field(),
            "sea_im"
        );
        assert_eq!(
            FrfPoint { omega: 0.0, ..p }.validate().unwrap_err().field(),
            "omega"
        );

        let e = ImpedanceEstimate {
            model: FitModel::M2.as_u32(),
            k_h: 50.0,
            h_h: 10.0,
            c_h: 0.2,
            recommended_f: 0.4,
            ..Default::default()
        };
        assert_eq!(e.validate(), Ok(()));
        assert_eq!(
            ImpedanceEstimate { model: 0, ..e }
                .validate()
                .unwrap_err()
                .field(),
            "model"
        );
        assert_eq!(
            ImpedanceEstimate {
                beta1: f64::INFINITY,
                ..e
            }
            .validate()
            .unwrap_err()
            .field(),
            "beta1"
        );
        assert_eq!(
            ImpedanceEstimate {
                recommended_f: 1.0,
                ..e
            }
            .validate()
            .unwrap_err()
            .field(),
            "recommended_f"
        );
        assert_eq!(
            ImpedanceEstimate { m_h_se: -1.0, ..e }
                .validate()
                .unwrap_err()
                .field(),
            "m_h_se"
        );
    }
}
