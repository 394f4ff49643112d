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

mod check;

pub use check::{MAX_PRONY_ELEMENTS, PLANT_RANGES};

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
    /// Several values out of range, one per line.
    #[error("{}", .0.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n"))]
    Several(Vec<PlantModelError>),
}

/// What the subject's posture reference does during a period
/// (`human.posture_reference`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PostureReference {
    /// The subject's spring pulls towards `human.active_angle_rad`
    /// whatever the bias: a bias torque moves the arm by `bias/K`.
    #[default]
    Fixed,
    /// The subject sets its reference so that the arm rests at
    /// `human.active_angle_rad` against the period's bias and what the
    /// controller's gravity compensation leaves of the plant's gravity:
    /// `θ_ref = θ_active − (bias + τ_comp − τ_gravity)/(α K)` at the goal,
    /// `α` the period's amplification (the amplifier's static gain taken as
    /// `α − 1`), `K` the experiment's stiffness (the subject file's, or
    /// `human.stiffness_nm_per_rad`). The independent rig's subject does
    /// this (`tools/python/independent_rig.py`).
    HoldsGoal,
}

/// How hysteretic damping is simulated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HysteresisMode {
    /// `B_eq = H/ω` at the running excitation frequency: exact in single-sine steady state.
    EquivalentViscous,
    /// Causal generalised-Maxwell bank (the simulator's `prony` module).
    Prony,
    /// A Prony bank fitted about the running excitation frequency
    /// (`matched_band_decades`) and scaled to give `K + jH` exactly there
    /// (the simulator's `PronyBank::fit_matched`): causal, passive, damped
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
    /// Default loss factor `c = H/K` (a subject file's H overrides it). Range [0, 10].
    pub loss_factor: f64,
    /// Simulation method.
    pub mode: HysteresisMode,
    /// Band of the Prony bank (rad/s): [low, high], each in [0.001, 10⁵], low < high.
    pub band_rad_s: [f64; 2],
    /// Relaxation times per decade. Range (0, 50], and the bank of the
    /// mode in use (over `band_rad_s`, or `matched_band_decades`, plus half
    /// a decade each side) at most [`MAX_PRONY_ELEMENTS`] elements.
    pub elements_per_decade: f64,
    /// Frequency where `Re K` equals the nominal K (rad/s). Range (0, 10⁵].
    pub reference_rad_s: f64,
    /// `prony_matched`: the band of constant loss factor, in decades below
    /// and above the excitation frequency: each in [0, 3], not both 0.
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
    /// Viscous coefficient (Nm·s/rad). Range [0, 1000].
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
    /// Velocity gain `G` (Nm·s/rad). Range [0, 1000].
    pub gain_nm_s_per_rad: f64,
    /// Pathway delay `δ` (s), e.g. 0.04 for an ankle. Range [0, 1].
    pub delay_s: f64,
    /// Corner of the critically damped second-order low-pass `ω_c` (rad/s).
    /// Range (0, 10 000].
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
    /// Forearm inertia `M_h` (kg·m²). Range [0.001, 10].
    pub inertia_kg_m2: f64,
    /// Default joint stiffness `K_h` (Nm/rad). Range (0, 5000].
    pub stiffness_nm_per_rad: f64,
    /// Hysteretic damping (complex stiffness).
    pub hysteretic_damping: HystereticDamping,
    /// Viscous damping `B_h`.
    pub viscous_damping: ViscousTerm,
    /// Stretch-reflex pathway (off when the section is absent).
    #[serde(default)]
    pub stretch_reflex: StretchReflex,
    /// Cubic stiffness `K₃` of the joint (Nm/rad³): the spring is
    /// `K (θ_h − θ_eq) + K₃ (θ_h − θ_eq)³` about the posture the human
    /// holds; positive stiffens, negative softens; 0 (the default when the
    /// key is absent) is a linear spring. `exo diagnose` writes it when it
    /// discovers a polynomial spring. Range [−1e5, 1e5].
    #[serde(default)]
    pub cubic_stiffness_nm_per_rad3: f64,
    /// Quadratic stiffness `K₂` of the joint (Nm/rad²): a stiffness that
    /// depends on posture, the spring `K d + ½ K₂ d²` with `d = θ_h − θ_eq`
    /// about the posture the human holds, so that `dτ/dθ = K + K₂ d` (stiffer
    /// on one side of the posture, softer on the other). It leaves the
    /// fundamental of a sine about the posture as it is and puts `¼ K₂ Θ₁²`
    /// into the 2nd harmonic of the joint torque (`Θ₁` the angle's
    /// fundamental phasor). `exo diagnose` writes it when it discovers a
    /// posture-dependent stiffness. 0 (the default when the key is absent)
    /// is off. Range [−1e5, 1e5].
    #[serde(default)]
    pub quadratic_stiffness_nm_per_rad2: f64,
    /// Cubic damping `B₃` of the joint (Nm·s³/rad³): a damper
    /// `B₃ (θ̇_h − ω_eq)³` beside the linear terms (about the drive's own
    /// motion, as the linear damper), damping that grows with the speed of
    /// the motion (its describing function adds
    /// `j ¾ B₃ ω³ A²` to the joint's impedance at angle amplitude `A`).
    /// `exo diagnose` writes it when it discovers a cubic damper. 0 (the
    /// default when the key is absent) is off. Range [0, 1e3]: a negative
    /// one would feed energy into the joint.
    #[serde(default)]
    pub cubic_damping_nm_s3_per_rad3: f64,
    /// Drift of the joint stiffness within each experiment (fraction of
    /// `K` per minute): the spring is `K (1 + ρ t/60)`, `t` (s) from the
    /// moment the experiment's impedance is set (the subject file's
    /// experiment start), e.g. fatigue or co-contraction building up; the
    /// hysteretic damping `H` stays. 0 (the default when the key is absent)
    /// is a stiffness constant within the experiment. Range [−0.5, 0.5].
    #[serde(default)]
    pub stiffness_drift_per_min: f64,
    /// Posture the subject holds at rest and during a period (rad). Range [−2π, 2π].
    pub rest_angle_rad: f64,
    /// Posture during a period (the paper: about 45°). Range [−2π, 2π].
    pub active_angle_rad: f64,
    /// What the subject's posture reference does during a period: `fixed`
    /// (the default when the key is absent) or `holds_goal`.
    #[serde(default)]
    pub posture_reference: PostureReference,
}

/// `[exo]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Exo {
    /// Arm inertia without load (kg·m²); the paper: 0.1. Range (0, 10].
    pub arm_inertia_kg_m2: f64,
    /// Load lever arm (m); the paper: 0.45. Range [0, 2].
    pub load_lever_arm_m: f64,
    /// Default load (kg); the protocol's load overrides it. Range [0, 50].
    pub load_kg: f64,
    /// Backlash (lost motion) in the joint's drive, between the motor side
    /// (the SEA's output) and the arm; off when the section is absent.
    #[serde(default)]
    pub backlash: Backlash,
}

/// `[exo.backlash]`: lost motion in the exoskeleton joint's gear mesh,
/// between the drive's output (motor side) and the arm. The SEA's torque
/// acts on the motor side's inertia `J_m`; the mesh passes
/// `k_g dz(θ_m − θ_e) + b_g (ω_m − ω_e)` (the damping only in contact) to
/// the arm, `dz` a dead zone of half-width `lash_rad/2`. `J_m` is a part of
/// `exo.arm_inertia_kg_m2` (the arm keeps the rest), so with the mesh closed
/// the joint's total inertia is the nominal one. Where the SEA's torque
/// does not reverse (an arm held up against gravity) the mesh never opens
/// and the backlash has no effect. Off while `lash_rad` is 0.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Backlash {
    /// Total lost motion (rad). Range [0, 0.2]; 0 is off.
    pub lash_rad: f64,
    /// Motor-side (drive output) inertia `J_m` (kg·m²), taken out of
    /// `exo.arm_inertia_kg_m2`. Range (0, 10], below the arm's inertia.
    pub motor_inertia_kg_m2: f64,
    /// Mesh stiffness `k_g` in contact (Nm/rad). Range (0, 10⁷], and
    /// `√(k_g/J_m) · integration.step_s` ≤ 0.5.
    pub mesh_stiffness_nm_per_rad: f64,
    /// Mesh damping `b_g` in contact (Nm·s/rad). Range [0, 10⁴].
    pub mesh_damping_nm_s_per_rad: f64,
}

impl Default for Backlash {
    fn default() -> Self {
        Self {
            lash_rad: 0.0,
            motor_inertia_kg_m2: 0.02,
            mesh_stiffness_nm_per_rad: 2e4,
            mesh_damping_nm_s_per_rad: 8.0,
        }
    }
}

impl Backlash {
    /// On (a lash above zero).
    pub fn enabled(&self) -> bool {
        self.lash_rad > 0.0
    }

    /// The torque (Nm) the mesh passes from the motor side to the arm at
    /// the motor side's lead `d = θ_m − θ_e` (rad) and its rate `v` (rad/s):
    /// none inside the lash, `k_g (d ∓ lash/2) + b_g v` in contact.
    pub fn mesh_torque_nm(&self, d: f64, v: f64) -> f64 {
        let half = 0.5 * self.lash_rad;
        if d > half {
            self.mesh_stiffness_nm_per_rad * (d - half) + self.mesh_damping_nm_s_per_rad * v
        } else if d < -half {
            self.mesh_stiffness_nm_per_rad * (d + half) + self.mesh_damping_nm_s_per_rad * v
        } else {
            0.0
        }
    }
}

/// `[gravity]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gravity {
    /// On or off.
    pub enabled: bool,
    /// Arm mass (kg). Range [0, 50].
    pub arm_mass_kg: f64,
    /// Arm centre of mass from the joint (m). Range [0, 2].
    pub arm_com_m: f64,
    /// Gravitational acceleration (m/s²). Range [0, 20].
    pub g_m_s2: f64,
}

/// `[joint_friction.coulomb]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Coulomb {
    /// On or off.
    pub enabled: bool,
    /// Friction torque magnitude (Nm). Range [0, 100].
    pub torque_nm: f64,
    /// Velocity (rad/s) over which `tanh` smooths the sign change. Range (0, 100].
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
    /// Stiffness (Nm/rad); the paper measured > 1000. Range (0, 10⁶], and
    /// `√(stiffness/human.inertia_kg_m2) · integration.step_s` ≤ 0.5.
    pub stiffness_nm_per_rad: f64,
    /// Damping (Nm·s/rad). Range [0, 10 000].
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
    /// Natural frequency (Hz); the paper: 10. Range (0, 1000], and
    /// `2π · natural_frequency_hz · integration.step_s` ≤ 0.5.
    pub natural_frequency_hz: f64,
    /// Damping ratio. Range (0, 10].
    pub damping_ratio: f64,
}

/// `[sea]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sea {
    /// Torque dynamics.
    pub dynamics: SeaDynamics,
    /// Motor torque saturation (Nm). Range (0, 1000].
    pub torque_limit_nm: f64,
    /// Spring stiffness (Nm/rad), for the deflection sensor. Range (0, 10⁶].
    pub spring_stiffness_nm_per_rad: f64,
}

/// `[actuator]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Actuator {
    /// Pure delay on the motor command (s). Range [0, 1].
    pub delay_s: f64,
}

/// One sensor's error terms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorTerms {
    /// Gain (1 = exact). Range [0.1, 10].
    pub gain: f64,
    /// Offset (sensor units: rad or Nm). Range [−10, 10].
    pub offset: f64,
    /// Gaussian noise standard deviation (rad or Nm). Range [0, 10].
    pub noise_std: f64,
    /// Pure delay (s). Range [0, 1].
    pub delay_s: f64,
}

/// `[sensors.encoder]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Encoder {
    /// Counts per revolution (quantisation). Range [1, 10¹²].
    pub counts_per_rev: f64,
    /// Error terms (offset in rad).
    #[serde(flatten)]
    pub terms: SensorTerms,
}

/// `[sensors.cuff_ft]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuffFt {
    /// Sensor distance from the joint (m). Range (0, 2].
    pub lever_arm_m: f64,
    /// Force quantisation (N). Range [0, 100].
    pub force_resolution_n: f64,
    /// Error terms on τ_c (offset, noise in Nm).
    #[serde(flatten)]
    pub terms: SensorTerms,
}

/// `[sensors.sea_deflection]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeaDeflection {
    /// Counts per revolution (quantisation). Range [1, 10¹²].
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
    /// Fixed step (s); must divide the control period (`exo run` checks it
    /// against `run.rate_hz`). Range (0, 0.001], and at most 0.5 / the
    /// fastest mode (SEA, cuff compliance) in rad/s.
    pub step_s: f64,
    /// Seed of the sensor noise. Any unsigned 64-bit integer.
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
        let m: PlantModel = toml::from_str(text).map_err(|e| {
            let (key, message) = exo_config::describe_toml_error(text, &e);
            PlantModelError::Parse {
                file: file.to_string(),
                message: match key {
                    Some(k) => format!("{k}: {message}"),
                    None => message,
                },
            }
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

    /// Exoskeleton inertia with `load_kg` (kg·m²): the arm's side of the
    /// joint, without the motor side's inertia when there is backlash
    /// (`[exo.backlash]`).
    pub fn arm_side_inertia_kg_m2(&self, load_kg: f64) -> f64 {
        let motor = if self.exo.backlash.enabled() {
            self.exo.backlash.motor_inertia_kg_m2
        } else {
            0.0
        };
        self.exo_inertia_kg_m2(load_kg) - motor
    }

    /// Exoskeleton inertia with `load_kg` (kg·m²).
    pub fn exo_inertia_kg_m2(&self, load_kg: f64) -> f64 {
        exo_impedance::exo_inertia_kg_m2(
            self.exo.arm_inertia_kg_m2,
            load_kg,
            self.exo.load_lever_arm_m,
        )
    }

    /// The plant's gravity moment with `load_kg` (kg) on the arm (Nm),
    /// `g (m_a l_a + m_L l_L)` ([`exo_config::gravity_moment_nm`]) of
    /// `[gravity]` and `exo.load_lever_arm_m`; 0 when `gravity.enabled` is
    /// off. The gravity torque at θ is this times `sin θ`.
    pub fn gravity_moment_nm(&self, load_kg: f64) -> f64 {
        let g = &self.gravity;
        if !g.enabled {
            return 0.0;
        }
        exo_config::gravity_moment_nm(
            g.g_m_s2,
            g.arm_mass_kg,
            g.arm_com_m,
            load_kg,
            self.exo.load_lever_arm_m,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plants_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/plants")
    }

    #[test]
    fn the_gravity_moment_is_the_configs_of_the_plants_values_and_none_when_off() {
        let mut m = PlantModel::from_file(&plants_dir().join("default.toml")).unwrap();
        let g = m.gravity;
        m.gravity.enabled = true;
        let expected = exo_config::gravity_moment_nm(
            g.g_m_s2,
            g.arm_mass_kg,
            g.arm_com_m,
            2.5,
            m.exo.load_lever_arm_m,
        );
        assert!(expected > 0.0);
        assert_eq!(m.gravity_moment_nm(2.5).to_bits(), expected.to_bits());
        m.gravity.enabled = false;
        assert_eq!(m.gravity_moment_nm(2.5), 0.0);
    }
}
