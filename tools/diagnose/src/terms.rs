//! The catalogue of physics terms the diagnosis can add: each a named term
//! of the plant TOML, with its parameters, the transfer functions it shows
//! in (its signature) and where the simulator implements it.

use serde::Serialize;

use crate::data::Tf;
use crate::model::{Param, Physics};

/// A physics term of the plant model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Term {
    /// Hysteretic damping of the human joint (complex stiffness `K(1 + jc)`), per experiment.
    HystereticDamping,
    /// Viscous damping of the human joint.
    HumanViscousDamping,
    /// Coulomb friction in the exoskeleton joint.
    CoulombFriction,
    /// Viscous friction in the exoskeleton joint.
    JointViscousFriction,
    /// A delay of the encoder (angle).
    EncoderDelay,
    /// A delay of the cuff force/torque sensor.
    CuffSensorDelay,
    /// A delay of the SEA torque sensor.
    SeaSensorDelay,
    /// A delay of the motor command.
    ActuatorDelay,
    /// Series compliance of the cuff.
    CuffCompliance,
    /// The SEA's finite torque bandwidth.
    SeaBandwidth,
    /// An error of the exoskeleton's (arm and load) inertia.
    InertiaError,
    /// A gravity (or gravity-compensation) error.
    GravityError,
    /// A gain error of the cuff force/torque sensor.
    CuffSensorGain,
    /// A gain error of the SEA torque sensor.
    SeaSensorGain,
    /// An offset between the SEA and the cuff torque sensors.
    TorqueSensorOffset,
    /// The stretch-reflex pathway of the human joint.
    StretchReflex,
    /// The drive's torque limit (current limit): the motor torque is the
    /// command clipped at `±τ_max`, so at the peaks the recorded command
    /// exceeds what reaches the SEA.
    ActuatorSaturation,
    /// Generic form: a polynomial (stiffening or softening) spring of the
    /// human joint, `K θ + K₃ θ³`: stiffness that grows with the amplitude.
    CubicStiffness,
    /// Generic form: a cubic damper of the human joint, `B₃ θ̇³`: damping
    /// that grows with the amplitude and the frequency.
    CubicDamping,
    /// Generic form: the human's stiffness drifting within an experiment,
    /// `K_e (1 + ρ t)`.
    StiffnessDrift,
    /// Generic form: a stiffness that depends on posture, the spring
    /// `K θ + ½ K₂ θ²` (`dK/dθ = K₂`), seen in the 2nd harmonic of `τ_c`
    /// ([`crate::posture`]), not in the transfer functions.
    PostureStiffness,
    /// Generic form: backlash (lost motion `2δ`) in the gear mesh between
    /// the drive's output and the arm, seen where the joint's torque
    /// reverses ([`crate::model::Mesh::describing`]).
    Backlash,
}

impl Term {
    /// Every term, in catalogue order.
    pub const ALL: [Term; 17] = [
        Term::HystereticDamping,
        Term::HumanViscousDamping,
        Term::CoulombFriction,
        Term::JointViscousFriction,
        Term::EncoderDelay,
        Term::CuffSensorDelay,
        Term::SeaSensorDelay,
        Term::ActuatorDelay,
        Term::CuffCompliance,
        Term::SeaBandwidth,
        Term::InertiaError,
        Term::GravityError,
        Term::CuffSensorGain,
        Term::SeaSensorGain,
        Term::TorqueSensorOffset,
        Term::StretchReflex,
        Term::ActuatorSaturation,
    ];

    /// The library of generic forms outside the catalogue, tried when no
    /// catalogue term explains the structure that remains at a step.
    pub const FORMS: [Term; 4] = [
        Term::CubicStiffness,
        Term::CubicDamping,
        Term::StiffnessDrift,
        Term::Backlash,
    ];

    /// The generic forms that leave the transfer functions as they are and
    /// show in the harmonics of the excitation: fitted there, after the
    /// search over the transfer functions ([`crate::posture`]).
    pub const HARMONIC_FORMS: [Term; 1] = [Term::PostureStiffness];

    /// Whether its forward model is a describing function (the response at
    /// the excitation's frequency of a nonlinearity, its harmonics left
    /// out): accurate to [`crate::fit::MODEL_ACCURACY`] (Coulomb friction
    /// to [`crate::fit::COULOMB_ACCURACY`]), not to the noise, so it is
    /// fitted and tested with every value held to that accuracy
    /// ([`crate::data::Dataset::held_to`]).
    pub fn describing_function(self) -> bool {
        matches!(
            self,
            Term::CoulombFriction
                | Term::ActuatorSaturation
                | Term::CubicStiffness
                | Term::CubicDamping
                | Term::Backlash
                | Term::PostureStiffness
        )
    }

    /// A delay of a sensor or of the motor command: every parameter of the
    /// term is a delay ([`Param::is_delay`]).
    pub fn is_delay(self) -> bool {
        let params = self.params(&[]);
        !params.is_empty() && params.iter().all(|q| q.is_delay())
    }

    /// A generic form (not a named term of the catalogue).
    pub fn generic(self) -> bool {
        Term::FORMS.contains(&self) || Term::HARMONIC_FORMS.contains(&self)
    }

    /// Whether its fit also starts from the model before the nominal
    /// refit: the torque limit's effect, a gain in `τ_s/τ_d` below 1 where
    /// the command peaks, is what the refit's SEA bandwidth bends to absorb
    /// (on our simulator with 26.5 Nm it went to ω_n = 10⁶ rad/s, ζ = 14 000,
    /// a first-order lag), from where the limit's fit does not find its way
    /// back.
    pub fn refits_from_nominal(self) -> bool {
        self == Term::ActuatorSaturation
    }

    /// Whether it is taken only on its own signature beyond the transfer
    /// functions it is fitted to (every generic form, and the torque limit,
    /// whose one real gain in `τ_s/τ_d` a gain or bandwidth error could
    /// also give): untested where that signature cannot be measured.
    pub fn needs_own_signature(self) -> bool {
        self.generic() || self == Term::ActuatorSaturation
    }

    /// Plain words.
    pub fn words(self) -> &'static str {
        match self {
            Term::HystereticDamping => "hysteretic damping (complex stiffness)",
            Term::HumanViscousDamping => "viscous damping of the human joint",
            Term::CoulombFriction => "Coulomb friction in the exoskeleton joint",
            Term::JointViscousFriction => "viscous friction in the exoskeleton joint",
            Term::EncoderDelay => "a delay of the encoder",
            Term::CuffSensorDelay => "a delay of the cuff force/torque sensor",
            Term::SeaSensorDelay => "a delay of the SEA torque sensor",
            Term::ActuatorDelay => "a delay of the motor command",
            Term::CuffCompliance => "series compliance of the cuff",
            Term::SeaBandwidth => "the SEA's torque bandwidth",
            Term::InertiaError => "an exoskeleton inertia error",
            Term::GravityError => "a gravity-compensation error",
            Term::CuffSensorGain => "a gain error of the cuff force/torque sensor",
            Term::SeaSensorGain => "a gain error of the SEA torque sensor",
            Term::TorqueSensorOffset => "an offset between the SEA and cuff torque sensors",
            Term::StretchReflex => "a stretch reflex (delayed velocity feedback)",
            Term::ActuatorSaturation => "the drive's torque limit (saturation)",
            Term::CubicStiffness => {
                "an amplitude-dependent stiffness of the human joint (polynomial spring K θ + K₃ θ³)"
            }
            Term::CubicDamping => {
                "an amplitude-dependent damping of the human joint (cubic damper B₃ θ̇³)"
            }
            Term::StiffnessDrift => "the human's stiffness drifting within each experiment",
            Term::PostureStiffness => {
                "a stiffness of the human joint that depends on posture (spring K θ + ½ K₂ θ², dK/dθ = K₂)"
            }
            Term::Backlash => "backlash (lost motion) in the exoskeleton joint's drive",
        }
    }

    /// The plant TOML key that holds it.
    pub fn toml_key(self) -> &'static str {
        match self {
            Term::HystereticDamping => "human.hysteretic_damping",
            Term::HumanViscousDamping => "human.viscous_damping",
            Term::CoulombFriction => "joint_friction.coulomb",
            Term::JointViscousFriction => "joint_friction.viscous",
            Term::EncoderDelay => "sensors.encoder.delay_s",
            Term::CuffSensorDelay => "sensors.cuff_ft.delay_s",
            Term::SeaSensorDelay => "sensors.sea_deflection.delay_s",
            Term::ActuatorDelay => "actuator.delay_s",
            Term::CuffCompliance => "cuff.compliance",
            Term::SeaBandwidth => "sea.dynamics",
            Term::InertiaError => "exo.arm_inertia_kg_m2",
            Term::GravityError => "gravity.arm_mass_kg",
            Term::CuffSensorGain => "sensors.cuff_ft.gain",
            Term::SeaSensorGain => "sensors.sea_deflection.gain",
            Term::TorqueSensorOffset => "sensors.sea_deflection.offset",
            Term::StretchReflex => "human.stretch_reflex",
            Term::ActuatorSaturation => "sea.torque_limit_nm",
            Term::CubicStiffness => "human.cubic_stiffness_nm_per_rad3",
            Term::StiffnessDrift => "human.stiffness_drift_per_min",
            Term::CubicDamping => "human.cubic_damping_nm_s3_per_rad3",
            Term::PostureStiffness => "human.quadratic_stiffness_nm_per_rad2",
            Term::Backlash => "exo.backlash.lash_rad",
        }
    }

    /// Its parameters for the experiments present.
    pub fn params(self, experiments: &[u32]) -> Vec<Param> {
        match self {
            Term::HystereticDamping => experiments.iter().map(|&e| Param::H(e)).collect(),
            Term::HumanViscousDamping => vec![Param::Bh],
            Term::CoulombFriction => vec![Param::Coulomb],
            Term::JointViscousFriction => vec![Param::Bf],
            Term::EncoderDelay => vec![Param::DelayTheta],
            Term::CuffSensorDelay => vec![Param::DelayTauC],
            Term::SeaSensorDelay => vec![Param::DelayTauS],
            Term::ActuatorDelay => vec![Param::DelayAct],
            Term::CuffCompliance => vec![Param::CuffCompliance],
            Term::SeaBandwidth => vec![Param::SeaWn, Param::SeaZeta],
            Term::InertiaError => vec![Param::InertiaError],
            Term::GravityError => vec![Param::GravityError],
            Term::CuffSensorGain => vec![Param::GainTauC],
            Term::SeaSensorGain => vec![Param::GainTauS],
            Term::TorqueSensorOffset => vec![Param::TorqueOffset],
            Term::StretchReflex => vec![Param::ReflexGain, Param::ReflexDelay, Param::ReflexCutoff],
            Term::ActuatorSaturation => vec![Param::Saturation],
            Term::CubicStiffness => vec![Param::CubicStiffness],
            Term::CubicDamping => vec![Param::CubicDamping],
            Term::StiffnessDrift => vec![Param::StiffnessDrift],
            Term::PostureStiffness => vec![Param::QuadraticStiffness],
            Term::Backlash => vec![Param::Backlash],
        }
    }

    /// The transfer functions it changes (its signature).
    pub fn shows_in(self) -> &'static [Tf] {
        match self {
            Term::HystereticDamping
            | Term::HumanViscousDamping
            | Term::CuffCompliance
            | Term::EncoderDelay
            | Term::StretchReflex
            | Term::CubicStiffness
            | Term::CubicDamping
            | Term::StiffnessDrift => &[Tf::Sh, Tf::She],
            Term::CuffSensorDelay => &[Tf::Sh],
            Term::CuffSensorGain => &[Tf::Sh, Tf::Balance],
            Term::CoulombFriction
            | Term::JointViscousFriction
            | Term::InertiaError
            | Term::Backlash => &[Tf::She],
            Term::GravityError => &[Tf::She, Tf::Balance],
            Term::TorqueSensorOffset => &[Tf::Balance],
            Term::SeaSensorDelay => &[Tf::She, Tf::Sea],
            Term::SeaSensorGain => &[Tf::She, Tf::Sea, Tf::Balance],
            Term::ActuatorDelay | Term::SeaBandwidth | Term::ActuatorSaturation => &[Tf::Sea],
            // Its 2nd harmonic, not a transfer function: never tried by the
            // search over them.
            Term::PostureStiffness => &[],
        }
    }

    /// Whether the nominal model already has it (then its parameters are
    /// refitted with the nominal ones rather than tried as missing physics).
    /// Errors and gains are never part of the nominal refit: a rig's
    /// calibration is what the nominal model asserts.
    pub fn in_nominal(self, p: &Physics) -> bool {
        match self {
            Term::HystereticDamping => p.h.values().any(|&h| h > 0.0),
            Term::HumanViscousDamping => p.b_h > 0.0,
            Term::CoulombFriction => p.coulomb_nm > 0.0,
            Term::JointViscousFriction => p.b_f > 0.0,
            Term::EncoderDelay => p.delay_s[0] > 0.0,
            Term::CuffSensorDelay => p.delay_s[1] > 0.0,
            Term::SeaSensorDelay => p.delay_s[2] > 0.0,
            Term::ActuatorDelay => p.delay_s[3] > 0.0,
            Term::CuffCompliance => p.cuff_compliance > 0.0,
            Term::SeaBandwidth => p.sea.is_some(),
            Term::InertiaError
            | Term::GravityError
            | Term::CuffSensorGain
            | Term::SeaSensorGain => false,
            // The nominal plant's limit is asserted (a drive's data sheet);
            // where it is reached the search tries a lower one.
            Term::ActuatorSaturation => false,
            Term::TorqueSensorOffset => p.torque_offset_nm != 0.0,
            Term::StretchReflex => p.reflex[0] > 0.0,
            Term::CubicStiffness => p.k3 != 0.0,
            Term::CubicDamping => p.b3 != 0.0,
            Term::StiffnessDrift => p.k_drift_per_min != 0.0,
            Term::PostureStiffness => p.k2 != 0.0,
            Term::Backlash => p.lash_half_rad > 0.0,
        }
    }

    /// Whether the term's own effect depends on the excitation amplitude
    /// (Coulomb friction's describing function falls as 1/amplitude): then
    /// the amplitude check must confirm its parameters at each amplitude,
    /// not merely fail to refute them.
    pub fn amplitude_dependent(self) -> bool {
        matches!(self, Term::CoulombFriction | Term::Backlash)
    }

    /// A generic form defined by how it changes with the excitation's
    /// amplitude (its describing function grows with A²): at one amplitude
    /// the polynomial spring is a constant on K, the cubic damper a damping
    /// growing as ω³ and backlash an inertia-like `ω²` term, i.e. a
    /// frequency dependence, so such a form is only taken from recordings
    /// with at least two amplitudes.
    pub fn needs_two_amplitudes(self) -> bool {
        matches!(
            self,
            Term::CubicStiffness | Term::CubicDamping | Term::Backlash
        )
    }

    /// Starting values when the term is added to `p`.
    pub fn start(self, p: &mut Physics) {
        match self {
            Term::HystereticDamping => {
                let ks: Vec<(u32, f64)> = p.k.iter().map(|(e, k)| (*e, *k)).collect();
                for (e, k) in ks {
                    p.h.insert(e, 0.1 * k);
                }
            }
            Term::HumanViscousDamping => p.b_h = 0.1,
            Term::CoulombFriction => p.coulomb_nm = 0.05,
            Term::JointViscousFriction => p.b_f = 0.05,
            Term::EncoderDelay => p.delay_s[0] = 5e-4,
            Term::CuffSensorDelay => p.delay_s[1] = 5e-4,
            Term::SeaSensorDelay => p.delay_s[2] = 5e-4,
            Term::ActuatorDelay => p.delay_s[3] = 5e-4,
            Term::CuffCompliance => p.cuff_compliance = 2e-4,
            Term::SeaBandwidth => p.sea = Some((std::f64::consts::TAU * 10.0, 0.7)),
            Term::InertiaError => p.inertia_error = 0.0,
            Term::GravityError => p.gravity_error = 0.0,
            Term::CuffSensorGain => p.gain[1] = 1.0,
            Term::SeaSensorGain => p.gain[2] = 1.0,
            Term::TorqueSensorOffset => p.torque_offset_nm = 0.0,
            Term::StretchReflex => p.reflex = [1.0, 0.04, 15.0],
            // Set from the recorded commands ([`Term::start_variant`]).
            Term::ActuatorSaturation => {}
            Term::CubicStiffness => p.k3 = 0.0,
            Term::CubicDamping => p.b3 = 0.0,
            Term::StiffnessDrift => p.k_drift_per_min = 0.0,
            Term::PostureStiffness => p.k2 = 0.0,
            Term::Backlash => p.lash_half_rad = 0.005,
        }
    }

    /// The parameters of which at least one must differ from its "absent"
    /// value (0, or 1 for a gain) by more than two standard errors for the
    /// term to count as identified (hysteresis: any experiment's H; the
    /// reflex: its gain and its delay both; the SEA's bandwidth is never
    /// absent).
    pub fn identified(
        self,
        p: &Physics,
        se: &dyn Fn(Param) -> Option<f64>,
        experiments: &[u32],
    ) -> bool {
        let beyond = |q: Param| match se(q) {
            Some(s) if s.is_finite() => (p.get(q) - q.absent()).abs() > 2.0 * s,
            _ => false,
        };
        match self {
            Term::SeaBandwidth => true,
            // A reflex needs both its gain and its delay: with the delay
            // undetermined it is a low-passed viscous damping, not a reflex.
            Term::StretchReflex => beyond(Param::ReflexGain) && beyond(Param::ReflexDelay),
            t => t.params(experiments).into_iter().any(beyond),
        }
    }

    /// Starting point `i` of the term's fit on `d`: 0 is [`Term::start`];
    /// the reflex, whose fit is not convex in its delay, has four more
    /// (delays of 20, 60, 80, 100 ms); the torque limit starts below the
    /// largest magnitude of the recorded commands, at 0.97, 0.9 and 0.8 of
    /// it (a limit above every peak has no effect, so no gradient to start
    /// from). False past the last.
    pub fn start_variant(self, i: usize, p: &mut Physics, d: &crate::data::Dataset) -> bool {
        if self == Term::ActuatorSaturation {
            let peak = d
                .conditions
                .iter()
                .filter_map(|c| c.command.as_ref().map(|x| x.peak_nm()))
                .filter(|x| x.is_finite() && *x > 0.0)
                .fold(0.0, f64::max);
            let Some(&f) = [0.97, 0.9, 0.8].get(i) else {
                return false;
            };
            if peak <= 0.0 {
                return false;
            }
            p.saturation_per_nm = 1.0 / (f * peak);
            return true;
        }
        if i == 0 {
            self.start(p);
            return true;
        }
        match (self, i) {
            (Term::StretchReflex, 1..=4) => {
                p.reflex = [1.0, [0.02, 0.06, 0.08, 0.1][i - 1], 15.0];
                true
            }
            _ => false,
        }
    }

    /// Its value in plain words with the fitted parameters, e.g.
    /// "H = 12.3 ± 0.8 Nm/rad (c = 0.43)". A parameter whose standard error
    /// is not determined ([`determined`]) is printed as "not determined",
    /// never with a ± that claims precision.
    pub fn describe(self, p: &Physics, se: &dyn Fn(Param) -> Option<f64>) -> String {
        let pm = |q: Param, scale: f64, digits: usize, unit: &str| {
            value_pm(p.get(q) * scale, se(q).map(|s| s * scale), digits, unit)
        };
        match self {
            Term::HystereticDamping => {
                let n = p.h.len().max(1) as f64;
                let h_mean = p.h.values().sum::<f64>() / n;
                let c: f64 =
                    p.h.iter()
                        .map(|(e, h)| h / p.k.get(e).copied().unwrap_or(f64::INFINITY))
                        .sum::<f64>()
                        / n;
                let per: Vec<String> =
                    p.h.keys()
                        .map(|&e| format!("exp {e}: {}", pm(Param::H(e), 1.0, 2, "")))
                        .collect();
                format!(
                    "H = {h_mean:.2} Nm/rad on average (c = {c:.2}); {}",
                    per.join(", ")
                )
            }
            Term::HumanViscousDamping => format!("B_h = {}", pm(Param::Bh, 1.0, 3, " Nm·s/rad")),
            Term::CoulombFriction => format!("F_c = {}", pm(Param::Coulomb, 1.0, 3, " Nm")),
            Term::JointViscousFriction => format!("b_f = {}", pm(Param::Bf, 1.0, 3, " Nm·s/rad")),
            Term::EncoderDelay => format!("d = {}", pm(Param::DelayTheta, 1e3, 2, " ms")),
            Term::CuffSensorDelay => format!("d = {}", pm(Param::DelayTauC, 1e3, 2, " ms")),
            Term::SeaSensorDelay => format!("d = {}", pm(Param::DelayTauS, 1e3, 2, " ms")),
            Term::ActuatorDelay => format!("d = {}", pm(Param::DelayAct, 1e3, 2, " ms")),
            Term::CuffCompliance => inverse_pm(
                "k_c",
                "compliance",
                p.cuff_compliance,
                se(Param::CuffCompliance),
                (0, " Nm/rad", "rad/Nm"),
            ),
            Term::SeaBandwidth => format!(
                "ω_n = {} ({:.2} Hz), ζ = {}",
                pm(Param::SeaWn, 1.0, 1, " rad/s"),
                p.get(Param::SeaWn) / std::f64::consts::TAU,
                pm(Param::SeaZeta, 1.0, 2, "")
            ),
            Term::InertiaError => {
                format!("ΔM_e = {}", pm(Param::InertiaError, 1.0, 4, " kg·m²"))
            }
            Term::GravityError => format!("Δ(mgl) = {}", pm(Param::GravityError, 1.0, 3, " Nm")),
            Term::CuffSensorGain => format!("gain = {}", pm(Param::GainTauC, 1.0, 3, "")),
            Term::SeaSensorGain => format!("gain = {}", pm(Param::GainTauS, 1.0, 3, "")),
            Term::TorqueSensorOffset => {
                format!("Δ = {}", pm(Param::TorqueOffset, 1.0, 3, " Nm"))
            }
            Term::StretchReflex => format!(
                "G = {}, δ = {}, ω_c = {}",
                pm(Param::ReflexGain, 1.0, 2, " Nm·s/rad"),
                pm(Param::ReflexDelay, 1e3, 1, " ms"),
                pm(Param::ReflexCutoff, 1.0, 1, " rad/s")
            ),
            Term::CubicStiffness => {
                let sense = if p.k3 >= 0.0 {
                    "stiffening"
                } else {
                    "softening"
                };
                format!(
                    "{sense} spring, K₃ = {}",
                    pm(Param::CubicStiffness, 1.0, 0, " Nm/rad³")
                )
            }
            Term::CubicDamping => {
                format!("B₃ = {}", pm(Param::CubicDamping, 1.0, 3, " Nm·s³/rad³"))
            }
            Term::StiffnessDrift => format!(
                "ρ = {} of K_h per minute",
                pm(Param::StiffnessDrift, 100.0, 2, " %")
            ),
            Term::PostureStiffness => format!(
                "dK/dθ = K₂ = {}",
                pm(Param::QuadraticStiffness, 1.0, 0, " Nm/rad²")
            ),
            Term::ActuatorSaturation => inverse_pm(
                "τ_max",
                "1/τ_max",
                p.saturation_per_nm,
                se(Param::Saturation),
                (2, " Nm", "1/Nm"),
            ),
            Term::Backlash => format!(
                "lost motion 2δ = {} (motor side J_m = {:.3} kg·m², the model's)",
                pm(Param::Backlash, 2.0, 4, " rad"),
                p.motor_inertia
            ),
        }
    }
}

/// A quantity fitted as its inverse `x` (a compliance for a stiffness, an
/// inverse limit for a limit), in words: `name = 1/x ± se`, its standard
/// error by the delta method (`se/x²`), or "not determined" with `x` as
/// fitted (`fitted`, in `inverse_unit`). `(digits, unit, inverse_unit)`.
fn inverse_pm(
    name: &str,
    fitted: &str,
    x: f64,
    se: Option<f64>,
    (digits, unit, inverse_unit): (usize, &str, &str),
) -> String {
    match se {
        Some(s) if determined(x, s) => {
            let v = 1.0 / x;
            format!("{name} = {}", value_pm(v, Some(v * s / x), digits, unit))
        }
        s => format!(
            "{name} not determined ({fitted} {x:.3e} {inverse_unit}; {})",
            why_undetermined(x, s)
        ),
    }
}

/// Whether a fitted value `v` with standard error `se` is determined: the
/// standard error is finite, positive and no larger than the value itself.
pub fn determined(v: f64, se: f64) -> bool {
    v.is_finite() && se.is_finite() && se > 0.0 && se <= v.abs()
}

/// Why a value is not determined, in words.
pub fn why_undetermined(v: f64, se: Option<f64>) -> String {
    match se {
        None => "not fitted".into(),
        Some(s) if !s.is_finite() => "no finite standard error".into(),
        Some(s) if s <= 0.0 => "standard error zero: the data do not constrain it".into(),
        Some(s) if !v.is_finite() => format!("value {v}, standard error {s:.2e}"),
        Some(s) => format!("standard error {s:.2e} larger than the value"),
    }
}

/// `v ± se` with the standard error to two significant digits (at least
/// `digits` decimals), or "not determined (…)" when it is not
/// ([`determined`]).
pub fn value_pm(v: f64, se: Option<f64>, digits: usize, unit: &str) -> String {
    match se {
        Some(s) if determined(v, s) => {
            let d = (1 - s.log10().floor() as i64).clamp(digits as i64, 9) as usize;
            format!("{v:.d$} ± {s:.d$}{unit}")
        }
        _ => format!(
            "not determined ({v:.digits$}{unit}; {})",
            why_undetermined(v, se)
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::Term;

    /// The terms whose forward model is a describing function, by name:
    /// the nonlinearities (friction, the torque limit, the polynomial
    /// spring, the cubic damper, backlash, the posture form); every linear
    /// term of the catalogue and the drift (a linear model per window) not.
    #[test]
    fn the_describing_functions_are_the_nonlinear_terms() {
        let nonlinear = [
            Term::CoulombFriction,
            Term::ActuatorSaturation,
            Term::CubicStiffness,
            Term::CubicDamping,
            Term::Backlash,
            Term::PostureStiffness,
        ];
        for t in Term::ALL
            .iter()
            .chain(&Term::FORMS)
            .chain(&Term::HARMONIC_FORMS)
        {
            assert_eq!(t.describing_function(), nonlinear.contains(t), "{t:?}");
        }
    }

    /// The delays, by name: the encoder's, the cuff sensor's, the SEA
    /// sensor's and the motor command's; not the stretch reflex (a delay
    /// among its gain and corner) nor any other term.
    #[test]
    fn the_delays_are_the_four_timing_terms() {
        let delays = [
            Term::EncoderDelay,
            Term::CuffSensorDelay,
            Term::SeaSensorDelay,
            Term::ActuatorDelay,
        ];
        for t in Term::ALL
            .iter()
            .chain(&Term::FORMS)
            .chain(&Term::HARMONIC_FORMS)
        {
            assert_eq!(t.is_delay(), delays.contains(t), "{t:?}");
        }
    }
}
