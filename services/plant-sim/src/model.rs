//! The plant model: a TOML file in which every physical effect is a named
//! term, off or on with its parameters. The simulator reads it; the
//! mismatch tool reads and writes it.
//!
//! ```toml
//! [human]                      # forearm and joint impedance
//! inertia_kg_m2 = 0.11
//! stiffness_nm_per_rad = 30.0  # default; a subject file overrides it per experiment
//! [human.hysteretic_damping]   # complex stiffness K(1 + jc)
//! enabled = true
//! loss_factor = 0.4            # default c; subject files give H = cK per experiment
//! mode = "equivalent_viscous"  # or "prony", "prony_matched"
//! band_rad_s = [0.1, 300.0]    # prony only
//! matched_band_decades = [0.0, 1.0]  # prony_matched only
//! elements_per_decade = 3.0
//! reference_rad_s = 5.48
//! [human.viscous_damping]
//! enabled = false
//! b_nm_s_per_rad = 0.0
//! ...
//! ```
//!
//! See `configs/plants/default.toml` for every term.

use std::path::Path;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// A plant-model error naming the file and the key.
#[derive(Debug, Error)]
pub enum PlantModelError {
    /// Could not read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File.
        file: String,
        /// Cause.
        source: std::io::Error,
    },
    /// Not valid for the schema.
    #[error("{file}: {message}")]
    Parse {
        /// File.
        file: String,
        /// Parser message (names the key, line and column).
        message: String,
    },
    /// A value out of range.
    #[error("{file}: {key}: {message}")]
    Invalid {
        /// File.
        file: String,
        /// Key path.
        key: String,
        /// What is wrong and what is allowed.
        message: String,
    },
}

/// How hysteretic damping is simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HysteresisMode {
    /// `B_eq = H/ω` at the running excitation frequency: exact in single-sine steady state.
    EquivalentViscous,
    /// Causal generalised-Maxwell bank ([`crate::prony`]).
    Prony,
    /// A Prony bank fitted about the running excitation frequency
    /// (`matched_band_decades`) and scaled to give `K + jH` exactly there
    /// ([`crate::prony::PronyBank::fit_matched`]): causal, passive, damped
    /// at every frequency as a complex stiffness is, so transients (posture
    /// moves, bias ramps) decay as they would in a human, with a static
    /// stiffness that stays a large fraction of `K` (so a bias torque does
    /// not creep for long), and exact at the frequency a single-sine period
    /// measures. When the bank changes (a new period's frequency, a new
    /// experiment's K and H) its internal state is set so that the joint
    /// torque is continuous.
    PronyMatched,
}

/// `[human.hysteretic_damping]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HystereticDamping {
    /// On or off.
    pub enabled: bool,
    /// Default loss factor `c = H/K` (a subject file's H overrides it).
    pub loss_factor: f64,
    /// Simulation method.
    pub mode: HysteresisMode,
    /// Band of the Prony bank (rad/s).
    pub band_rad_s: [f64; 2],
    /// Relaxation times per decade.
    pub elements_per_decade: f64,
    /// Frequency where `Re K` equals the nominal K (rad/s).
    pub reference_rad_s: f64,
    /// `prony_matched`: the band of constant loss factor, in decades below
    /// and above the excitation frequency.
    #[serde(default = "default_matched_band_decades")]
    pub matched_band_decades: [f64; 2],
}

/// The default `matched_band_decades`.
pub fn default_matched_band_decades() -> [f64; 2] {
    [0.0, 1.0]
}

/// A term with one coefficient.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViscousTerm {
    /// On or off.
    pub enabled: bool,
    /// Viscous coefficient (Nm·s/rad).
    pub b_nm_s_per_rad: f64,
}

/// `[human.stretch_reflex]`: the stretch-reflex pathway, a torque opposing
/// the joint's delayed, low-passed velocity (the reflex arm of the
/// parallel-cascade model of joint stiffness, Kearney et al. 1997):
/// `τ_r = −G · LP(θ̇_h(t − δ))`, `LP(s) = 1/(1 + s/ω_c)²`; in the frequency
/// domain it adds `G jω e^{−jωδ}/(1 + jω/ω_c)²` to the joint impedance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StretchReflex {
    /// On or off.
    pub enabled: bool,
    /// Velocity gain `G` (Nm·s/rad).
    pub gain_nm_s_per_rad: f64,
    /// Pathway delay `δ` (s), e.g. 0.04 for an ankle.
    pub delay_s: f64,
    /// Corner of the critically damped second-order low-pass `ω_c` (rad/s).
    pub cutoff_rad_s: f64,
}

impl Default for StretchReflex {
    fn default() -> Self {
        Self {
            enabled: false,
            gain_nm_s_per_rad: 0.0,
            delay_s: 0.04,
            cutoff_rad_s: 15.0,
        }
    }
}

/// `[human]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Human {
    /// Forearm inertia `M_h` (kg·m²).
    pub inertia_kg_m2: f64,
    /// Default joint stiffness `K_h` (Nm/rad).
    pub stiffness_nm_per_rad: f64,
    /// Hysteretic damping (complex stiffness).
    pub hysteretic_damping: HystereticDamping,
    /// Viscous damping `B_h`.
    pub viscous_damping: ViscousTerm,
    /// Stretch-reflex pathway (off when the section is absent).
    #[serde(default)]
    pub stretch_reflex: StretchReflex,
    /// Posture the subject holds at rest and during a period (rad).
    pub rest_angle_rad: f64,
    /// Posture during a period (the paper: about 45°).
    pub active_angle_rad: f64,
}

/// `[exo]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Exo {
    /// Arm inertia without load (kg·m²); the paper: 0.1.
    pub arm_inertia_kg_m2: f64,
    /// Load lever arm (m); the paper: 0.45.
    pub load_lever_arm_m: f64,
    /// Default load (kg); the protocol's load overrides it.
    pub load_kg: f64,
}

/// `[gravity]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// On or off.
    pub enabled: bool,
    /// Arm mass (kg).
    pub arm_mass_kg: f64,
    /// Arm centre of mass from the joint (m).
    pub arm_com_m: f64,
    /// Gravitational acceleration (m/s²).
    pub g_m_s2: f64,
}

/// `[joint_friction.coulomb]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coulomb {
    /// On or off.
    pub enabled: bool,
    /// Friction torque magnitude (Nm).
    pub torque_nm: f64,
    /// Velocity (rad/s) over which `tanh` smooths the sign change.
    pub smoothing_rad_s: f64,
}

/// `[joint_friction]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointFriction {
    /// Coulomb friction.
    pub coulomb: Coulomb,
    /// Viscous friction.
    pub viscous: ViscousTerm,
}

/// `[cuff.compliance]`: spring and damper between forearm and exoskeleton.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuffCompliance {
    /// On (compliant) or off (rigid).
    pub enabled: bool,
    /// Stiffness (Nm/rad); the paper measured > 1000.
    pub stiffness_nm_per_rad: f64,
    /// Damping (Nm·s/rad).
    pub damping_nm_s_per_rad: f64,
}

/// `[cuff]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cuff {
    /// Compliance.
    pub compliance: CuffCompliance,
}

/// `[sea.dynamics]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeaDynamics {
    /// On (second order) or off (ideal: τ_s = τ_d).
    pub enabled: bool,
    /// Natural frequency (Hz); the paper: 10.
    pub natural_frequency_hz: f64,
    /// Damping ratio.
    pub damping_ratio: f64,
}

/// `[sea]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sea {
    /// Torque dynamics.
    pub dynamics: SeaDynamics,
    /// Motor torque saturation (Nm).
    pub torque_limit_nm: f64,
    /// Spring stiffness (Nm/rad), for the deflection sensor.
    pub spring_stiffness_nm_per_rad: f64,
}

/// `[actuator]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    /// Pure delay on the motor command (s).
    pub delay_s: f64,
}

/// One sensor's error terms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorTerms {
    /// Gain (1 = exact).
    pub gain: f64,
    /// Offset (sensor units: rad or Nm).
    pub offset: f64,
    /// Gaussian noise standard deviation (rad or Nm).
    pub noise_std: f64,
    /// Pure delay (s).
    pub delay_s: f64,
}

/// `[sensors.encoder]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Encoder {
    /// Counts per revolution (quantisation).
    pub counts_per_rev: f64,
    /// Error terms (offset in rad).
    #[serde(flatten)]
    pub terms: SensorTerms,
}

/// `[sensors.cuff_ft]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuffFt {
    /// Sensor distance from the joint (m).
    pub lever_arm_m: f64,
    /// Force quantisation (N).
    pub force_resolution_n: f64,
    /// Error terms on τ_c (offset, noise in Nm).
    #[serde(flatten)]
    pub terms: SensorTerms,
}

/// `[sensors.sea_deflection]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeaDeflection {
    /// Counts per revolution (quantisation).
    pub counts_per_rev: f64,
    /// Error terms on τ_s (offset, noise in Nm).
    #[serde(flatten)]
    pub terms: SensorTerms,
}

/// `[sensors]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensors {
    /// Joint encoder.
    pub encoder: Encoder,
    /// Cuff force/torque sensor.
    pub cuff_ft: CuffFt,
    /// SEA spring-deflection encoder.
    pub sea_deflection: SeaDeflection,
}

/// `[integration]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Integration {
    /// Fixed step (s); must divide the control period.
    pub step_s: f64,
    /// Seed of the sensor noise.
    pub seed: u64,
}

/// The whole plant model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantModel {
    /// Human.
    pub human: Human,
    /// Exoskeleton.
    pub exo: Exo,
    /// Gravity.
    pub gravity: Gravity,
    /// Joint friction.
    pub joint_friction: JointFriction,
    /// Cuff.
    pub cuff: Cuff,
    /// SEA.
    pub sea: Sea,
    /// Actuator.
    pub actuator: Actuator,
    /// Sensors.
    pub sensors: Sensors,
    /// Integration.
    pub integration: Integration,
}

impl PlantModel {
    /// Parses and validates TOML text; `file` names it in errors.
    pub fn from_toml_str(text: &str, file: &str) -> Result<Self, PlantModelError> {
        let m: PlantModel = toml::from_str(text).map_err(|e| PlantModelError::Parse {
            file: file.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        m.validate(file)?;
        Ok(m)
    }

    /// Reads and validates a plant model file.
    pub fn from_file(path: &Path) -> Result<Self, PlantModelError> {
        let text = std::fs::read_to_string(path).map_err(|source| PlantModelError::Io {
            file: path.display().to_string(),
            source,
        })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// The model as TOML (round-trips through [`PlantModel::from_toml_str`]).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).unwrap_or_default()
    }

    /// Checks every value, naming the key at fault.
    pub fn validate(&self, file: &str) -> Result<(), PlantModelError> {
        let bad = |key: &str, message: String| PlantModelError::Invalid {
            file: file.to_string(),
            key: key.to_string(),
            message,
        };
        let finite = |key: &str, v: f64| -> Result<(), PlantModelError> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(bad(key, format!("must be a finite number, got {v}")))
            }
        };
        let positive = |key: &str, v: f64| -> Result<(), PlantModelError> {
            finite(key, v)?;
            if v > 0.0 {
                Ok(())
            } else {
                Err(bad(key, format!("must be greater than zero, got {v}")))
            }
        };
        let non_negative = |key: &str, v: f64| -> Result<(), PlantModelError> {
            finite(key, v)?;
            if v >= 0.0 {
                Ok(())
            } else {
                Err(bad(key, format!("must be zero or more, got {v}")))
            }
        };
        let h = &self.human;
        positive("human.inertia_kg_m2", h.inertia_kg_m2)?;
        positive("human.stiffness_nm_per_rad", h.stiffness_nm_per_rad)?;
        non_negative(
            "human.hysteretic_damping.loss_factor",
            h.hysteretic_damping.loss_factor,
        )?;
        positive(
            "human.hysteretic_damping.band_rad_s[0]",
            h.hysteretic_damping.band_rad_s[0],
        )?;
        positive(
            "human.hysteretic_damping.band_rad_s[1]",
            h.hysteretic_damping.band_rad_s[1],
        )?;
        if h.hysteretic_damping.band_rad_s[0] >= h.hysteretic_damping.band_rad_s[1] {
            return Err(bad(
                "human.hysteretic_damping.band_rad_s",
                "must be [low, high] with low < high".into(),
            ));
        }
        positive(
            "human.hysteretic_damping.elements_per_decade",
            h.hysteretic_damping.elements_per_decade,
        )?;
        positive(
            "human.hysteretic_damping.reference_rad_s",
            h.hysteretic_damping.reference_rad_s,
        )?;
        let [below, above] = h.hysteretic_damping.matched_band_decades;
        non_negative("human.hysteretic_damping.matched_band_decades[0]", below)?;
        non_negative("human.hysteretic_damping.matched_band_decades[1]", above)?;
        if below + above <= 0.0 {
            return Err(bad(
                "human.hysteretic_damping.matched_band_decades",
                "must be [below, above] with a band wider than zero".into(),
            ));
        }
        non_negative(
            "human.viscous_damping.b_nm_s_per_rad",
            h.viscous_damping.b_nm_s_per_rad,
        )?;
        non_negative(
            "human.stretch_reflex.gain_nm_s_per_rad",
            h.stretch_reflex.gain_nm_s_per_rad,
        )?;
        non_negative("human.stretch_reflex.delay_s", h.stretch_reflex.delay_s)?;
        if h.stretch_reflex.delay_s > 1.0 {
            return Err(bad(
                "human.stretch_reflex.delay_s",
                format!("must be at most 1 s, got {}", h.stretch_reflex.delay_s),
            ));
        }
        positive(
            "human.stretch_reflex.cutoff_rad_s",
            h.stretch_reflex.cutoff_rad_s,
        )?;
        finite("human.rest_angle_rad", h.rest_angle_rad)?;
        finite("human.active_angle_rad", h.active_angle_rad)?;
        positive("exo.arm_inertia_kg_m2", self.exo.arm_inertia_kg_m2)?;
        non_negative("exo.load_lever_arm_m", self.exo.load_lever_arm_m)?;
        non_negative("exo.load_kg", self.exo.load_kg)?;
        non_negative("gravity.arm_mass_kg", self.gravity.arm_mass_kg)?;
        non_negative("gravity.arm_com_m", self.gravity.arm_com_m)?;
        non_negative("gravity.g_m_s2", self.gravity.g_m_s2)?;
        non_negative(
            "joint_friction.coulomb.torque_nm",
            self.joint_friction.coulomb.torque_nm,
        )?;
        positive(
            "joint_friction.coulomb.smoothing_rad_s",
            self.joint_friction.coulomb.smoothing_rad_s,
        )?;
        non_negative(
            "joint_friction.viscous.b_nm_s_per_rad",
            self.joint_friction.viscous.b_nm_s_per_rad,
        )?;
        positive(
            "cuff.compliance.stiffness_nm_per_rad",
            self.cuff.compliance.stiffness_nm_per_rad,
        )?;
        non_negative(
            "cuff.compliance.damping_nm_s_per_rad",
            self.cuff.compliance.damping_nm_s_per_rad,
        )?;
        positive(
            "sea.dynamics.natural_frequency_hz",
            self.sea.dynamics.natural_frequency_hz,
        )?;
        positive(
            "sea.dynamics.damping_ratio",
            self.sea.dynamics.damping_ratio,
        )?;
        positive("sea.torque_limit_nm", self.sea.torque_limit_nm)?;
        positive(
            "sea.spring_stiffness_nm_per_rad",
            self.sea.spring_stiffness_nm_per_rad,
        )?;
        non_negative("actuator.delay_s", self.actuator.delay_s)?;
        positive(
            "sensors.encoder.counts_per_rev",
            self.sensors.encoder.counts_per_rev,
        )?;
        positive(
            "sensors.cuff_ft.lever_arm_m",
            self.sensors.cuff_ft.lever_arm_m,
        )?;
        non_negative(
            "sensors.cuff_ft.force_resolution_n",
            self.sensors.cuff_ft.force_resolution_n,
        )?;
        positive(
            "sensors.sea_deflection.counts_per_rev",
            self.sensors.sea_deflection.counts_per_rev,
        )?;
        for (name, t) in [
            ("sensors.encoder", self.sensors.encoder.terms),
            ("sensors.cuff_ft", self.sensors.cuff_ft.terms),
            ("sensors.sea_deflection", self.sensors.sea_deflection.terms),
        ] {
            finite(&format!("{name}.gain"), t.gain)?;
            finite(&format!("{name}.offset"), t.offset)?;
            non_negative(&format!("{name}.noise_std"), t.noise_std)?;
            non_negative(&format!("{name}.delay_s"), t.delay_s)?;
        }
        let step = self.integration.step_s;
        positive("integration.step_s", step)?;
        if step > 1e-3 {
            return Err(bad(
                "integration.step_s",
                format!("must be at most 1e-3 s (finer than the control period), got {step}"),
            ));
        }
        let w_max = [
            2.0 * std::f64::consts::PI * self.sea.dynamics.natural_frequency_hz,
            (self.cuff.compliance.stiffness_nm_per_rad / self.human.inertia_kg_m2).sqrt(),
        ]
        .into_iter()
        .fold(0.0, f64::max);
        if w_max * step > 0.5 {
            return Err(bad(
                "integration.step_s",
                format!("{step} s is too coarse for the fastest mode ({w_max:.0} rad/s): use at most {:.2e}", 0.5 / w_max),
            ));
        }
        Ok(())
    }

    /// Exoskeleton inertia with `load_kg` (kg·m²).
    pub fn exo_inertia_kg_m2(&self, load_kg: f64) -> f64 {
        self.exo.arm_inertia_kg_m2 + load_kg * self.exo.load_lever_arm_m * self.exo.load_lever_arm_m
    }
}
