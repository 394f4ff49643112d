//! The dynamic-stiffness models of the paper (section "Models").
//!
//! All three are special cases of one four-term dynamic stiffness
//!
//! ```text
//! S(s) = M s² + B s + K + j H          (eq. M3; M1 has H = 0, M2 has B = 0)
//! ```
//!
//! evaluated on the imaginary axis, `s = jω`:
//! `S(jω) = (K − M ω²) + j (B ω + H sgn ω)`. The hysteretic term `jH` is
//! written with `sgn ω` so that the response of a real signal stays
//! conjugate-symmetric, `S(−jω) = conj S(jω)`; the paper only uses `ω > 0`.

use num_complex::Complex64;
use serde::Serialize;

use crate::error::{positive, Result};
use crate::power_law::PowerLaw;

/// One term of the dynamic stiffness, i.e. one column of the design matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Term {
    /// `M s²`, inertia in kg·m².
    Inertia,
    /// `B s`, viscous damping in Nm·s/rad.
    ViscousDamping,
    /// `K`, real stiffness in Nm/rad.
    Stiffness,
    /// `j H`, hysteretic damping in Nm/rad.
    HystereticDamping,
}

impl Term {
    /// All four terms, in the order used for parameter vectors.
    pub const ALL: [Term; 4] = [
        Term::Inertia,
        Term::ViscousDamping,
        Term::Stiffness,
        Term::HystereticDamping,
    ];

    /// Index of the term in a four-entry parameter vector.
    pub const fn index(self) -> usize {
        match self {
            Term::Inertia => 0,
            Term::ViscousDamping => 1,
            Term::Stiffness => 2,
            Term::HystereticDamping => 3,
        }
    }

    /// The regressor of this term at frequency `omega_rad_s`:
    /// its contribution per unit parameter to (real part, imaginary part).
    pub fn regressor(self, omega_rad_s: f64) -> (f64, f64) {
        match self {
            Term::Inertia => (-omega_rad_s * omega_rad_s, 0.0),
            Term::ViscousDamping => (0.0, omega_rad_s),
            Term::Stiffness => (1.0, 0.0),
            Term::HystereticDamping => (0.0, sign(omega_rad_s)),
        }
    }
}

fn sign(x: f64) -> f64 {
    if x < 0.0 {
        -1.0
    } else {
        1.0
    }
}

/// The three candidate models of the paper.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum ImpedanceModel {
    /// Eq. M1: `M s² + B s + K`, mass, spring and viscous damper.
    M1,
    /// Eq. M2: `M s² + K + jH`, mass and complex stiffness (hysteretic damping).
    M2,
    /// Eq. M3: `M s² + B s + K + jH`, both kinds of damping.
    M3,
}

impl ImpedanceModel {
    /// The three models in the paper's order.
    pub const ALL: [ImpedanceModel; 3] =
        [ImpedanceModel::M1, ImpedanceModel::M2, ImpedanceModel::M3];

    /// The terms of the model (the columns of its design matrix).
    pub fn terms(self) -> &'static [Term] {
        match self {
            ImpedanceModel::M1 => &[Term::Inertia, Term::ViscousDamping, Term::Stiffness],
            ImpedanceModel::M2 => &[Term::Inertia, Term::Stiffness, Term::HystereticDamping],
            ImpedanceModel::M3 => &Term::ALL,
        }
    }

    /// Number of real parameters.
    pub fn n_params(self) -> usize {
        self.terms().len()
    }

    /// Whether the model contains `term`.
    pub fn has(self, term: Term) -> bool {
        self.terms().contains(&term)
    }

    /// Short name, `"M1"`, `"M2"` or `"M3"`.
    pub fn name(self) -> &'static str {
        match self {
            ImpedanceModel::M1 => "M1",
            ImpedanceModel::M2 => "M2",
            ImpedanceModel::M3 => "M3",
        }
    }
}

impl std::fmt::Display for ImpedanceModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Parameters of the dynamic stiffness `S(s) = M s² + B s + K + jH` (eq. M3;
/// M1 and M2 set `h` or `b` to zero).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct DynamicStiffness {
    /// Inertia `M` (kg·m²).
    pub m_kg_m2: f64,
    /// Viscous damping `B` (Nm·s/rad).
    pub b_nm_s_per_rad: f64,
    /// Real stiffness `K` (Nm/rad).
    pub k_nm_per_rad: f64,
    /// Hysteretic damping `H` (Nm/rad), the imaginary part of the complex stiffness.
    pub h_nm_per_rad: f64,
}

impl DynamicStiffness {
    /// Builds the parameters from a four-entry vector in [`Term::ALL`] order.
    pub fn from_array(p: [f64; 4]) -> Self {
        DynamicStiffness {
            m_kg_m2: p[0],
            b_nm_s_per_rad: p[1],
            k_nm_per_rad: p[2],
            h_nm_per_rad: p[3],
        }
    }

    /// The parameters as a four-entry vector in [`Term::ALL`] order.
    pub fn to_array(self) -> [f64; 4] {
        [
            self.m_kg_m2,
            self.b_nm_s_per_rad,
            self.k_nm_per_rad,
            self.h_nm_per_rad,
        ]
    }

    /// The value of one term's parameter.
    pub fn get(&self, term: Term) -> f64 {
        self.to_array()[term.index()]
    }

    /// Complex response `S(jω)` in Nm/rad at `omega_rad_s`.
    pub fn response(&self, omega_rad_s: f64) -> Complex64 {
        let w = omega_rad_s;
        Complex64::new(
            self.k_nm_per_rad - self.m_kg_m2 * w * w,
            self.b_nm_s_per_rad * w + self.h_nm_per_rad * sign(w),
        )
    }

    /// Hysteretic loss factor `c = H / K` (eq. ch). Not finite when `K = 0`.
    pub fn loss_factor(&self) -> f64 {
        self.h_nm_per_rad / self.k_nm_per_rad
    }

    /// `S + ΔM s²`: the same dynamic stiffness with inertia added, e.g.
    /// `S_{h-e/α} = S_h + (M_e/α) s²` (section "Models").
    pub fn with_added_inertia(self, delta_m_kg_m2: f64) -> Self {
        DynamicStiffness {
            m_kg_m2: self.m_kg_m2 + delta_m_kg_m2,
            ..self
        }
    }

    /// Natural frequency `√(K/M)` (rad/s) of the undamped part.
    pub fn natural_frequency_rad_s(&self) -> f64 {
        (self.k_nm_per_rad / self.m_kg_m2).sqrt()
    }
}

/// Exoskeleton inertia `M_e` (kg·m²) with a point load: `arm + load · lever²`
/// (the arm without load, the load in kg at `lever_m` from the joint). The
/// one place this sum is written.
pub fn exo_inertia_kg_m2(arm_kg_m2: f64, load_kg: f64, lever_m: f64) -> f64 {
    arm_kg_m2 + load_kg * lever_m * lever_m
}

/// The paper's `S_{h-e/α}(jω) = S_h(jω) + (M_e/α)(jω)²`, re-created from a
/// measured `S_h` with the known `M_e/α` (text after eq. Sh3): the transfer
/// function the tables, Bode plots and F-tests show, "to avoid various
/// corrupting effects in the τ_s signal". Not a measurement.
pub fn recreate_coupled(s_h: Complex64, omega_rad_s: f64, m_e_kg_m2: f64, alpha: f64) -> Complex64 {
    s_h - Complex64::new(m_e_kg_m2 / alpha * omega_rad_s * omega_rad_s, 0.0)
}

/// Perceived inertia `M_{h-e/α} = M_h + M_e/α` (kg·m²) felt by a subject under
/// amplification `α` (section "Models").
pub fn perceived_inertia(m_h_kg_m2: f64, m_e_kg_m2: f64, alpha: f64) -> Result<f64> {
    positive("m_h_kg_m2", m_h_kg_m2)?;
    positive("m_e_kg_m2", m_e_kg_m2)?;
    positive("alpha", alpha)?;
    Ok(m_h_kg_m2 + m_e_kg_m2 / alpha)
}

/// The reduced one-parameter model of eq. Sh2-new: `S_h(s) = M_h s² + K(1 + c j)`
/// with the loss factor `c = 10^β0 · K^(β1−1)` tied to `K` by the subject's
/// power law (eq. ch).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ReducedModel {
    /// Human inertia `M_h` (kg·m²).
    pub m_h_kg_m2: f64,
    /// The subject's power law `H = 10^β0 K^β1`.
    pub power_law: PowerLaw,
}

impl ReducedModel {
    /// A reduced model, checking that the inertia is positive.
    pub fn new(m_h_kg_m2: f64, power_law: PowerLaw) -> Result<Self> {
        positive("m_h_kg_m2", m_h_kg_m2)?;
        Ok(ReducedModel {
            m_h_kg_m2,
            power_law,
        })
    }

    /// The full parameter set at real stiffness `K` (Nm/rad): `B = 0`, `H = c(K)·K`.
    pub fn at_stiffness(&self, k_nm_per_rad: f64) -> Result<DynamicStiffness> {
        let c = self.power_law.loss_factor(k_nm_per_rad)?;
        Ok(DynamicStiffness {
            m_kg_m2: self.m_h_kg_m2,
            b_nm_s_per_rad: 0.0,
            k_nm_per_rad,
            h_nm_per_rad: c * k_nm_per_rad,
        })
    }

    /// `S_h(jω)` at stiffness `K` (eq. Sh2-new).
    pub fn response(&self, k_nm_per_rad: f64, omega_rad_s: f64) -> Result<Complex64> {
        Ok(self.at_stiffness(k_nm_per_rad)?.response(omega_rad_s))
    }

    /// `S_{h-e/α}(jω) = S_h(jω) − (M_e/α) ω²` at stiffness `K` (section "Models").
    pub fn coupled_response(
        &self,
        k_nm_per_rad: f64,
        m_e_kg_m2: f64,
        alpha: f64,
        omega_rad_s: f64,
    ) -> Result<Complex64> {
        let m_pe = perceived_inertia(self.m_h_kg_m2, m_e_kg_m2, alpha)?;
        Ok(self
            .at_stiffness(k_nm_per_rad)?
            .with_added_inertia(m_pe - self.m_h_kg_m2)
            .response(omega_rad_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn response_splits_terms_into_real_and_imaginary_parts() {
        let s = DynamicStiffness {
            m_kg_m2: 0.5,
            b_nm_s_per_rad: 2.0,
            k_nm_per_rad: 30.0,
            h_nm_per_rad: 7.0,
        };
        let r = s.response(4.0);
        assert_eq!(r.re, 30.0 - 0.5 * 16.0);
        assert_eq!(r.im, 2.0 * 4.0 + 7.0);
        // Conjugate symmetry for a real signal.
        assert_eq!(s.response(-4.0), r.conj());
        // At ω = 0 the complex stiffness is K + jH (the paper's S(0)), and
        // H's regressor is +1 there, as for every ω ≥ 0.
        assert_eq!(s.response(0.0), Complex64::new(30.0, 7.0));
        assert_eq!(Term::HystereticDamping.regressor(0.0), (0.0, 1.0));
        assert_eq!(Term::HystereticDamping.regressor(-3.0), (0.0, -1.0));
    }

    /// The parameters in `Term::ALL` order (M, B, K, H), each term's own,
    /// and eq. ch's loss factor `H/K`, written out.
    #[test]
    fn the_parameters_in_term_order_and_the_loss_factor() {
        let s = DynamicStiffness {
            m_kg_m2: 0.5,
            b_nm_s_per_rad: 2.0,
            k_nm_per_rad: 40.0,
            h_nm_per_rad: 6.0,
        };
        assert_eq!(s.to_array(), [0.5, 2.0, 40.0, 6.0]);
        assert_eq!(DynamicStiffness::from_array(s.to_array()), s);
        assert_eq!(s.get(Term::Inertia), 0.5);
        assert_eq!(s.get(Term::ViscousDamping), 2.0);
        assert_eq!(s.get(Term::Stiffness), 40.0);
        assert_eq!(s.get(Term::HystereticDamping), 6.0);
        assert_eq!(s.loss_factor(), 0.15);
    }

    #[test]
    fn each_model_is_named_as_in_the_paper() {
        let names: Vec<String> = ImpedanceModel::ALL.iter().map(|m| m.to_string()).collect();
        assert_eq!(names, ["M1", "M2", "M3"]);
        assert_eq!(ImpedanceModel::M2.name(), "M2");
    }

    #[test]
    fn coupled_response_adds_perceived_exo_inertia() {
        let law = PowerLaw {
            beta0: -0.23,
            beta1: 0.90,
        };
        let m = ReducedModel::new(0.11, law).unwrap();
        let w = 3.0;
        let sh = m.response(20.0, w).unwrap();
        let she = m.coupled_response(20.0, 1.01, 2.0, w).unwrap();
        assert!((she - sh - Complex64::new(-1.01 / 2.0 * w * w, 0.0)).norm() < 1e-12);
        assert!(perceived_inertia(0.11, 1.01, 0.0).is_err());
    }

    #[test]
    fn recreated_coupled_stiffness_adds_the_felt_exo_inertia() {
        // 0.1 + 4.5 · 0.45² = 1.01125 kg·m² (the paper's P0 with its load).
        assert!((exo_inertia_kg_m2(0.1, 4.5, 0.45) - 1.01125).abs() < 1e-12);
        let s_h = Complex64::new(20.0, 6.0);
        let r = recreate_coupled(s_h, 3.0, 1.0, 4.0);
        assert_eq!(r, Complex64::new(20.0 - 9.0 / 4.0, 6.0));
    }

    #[test]
    fn model_terms_are_nested_in_m3() {
        for m in [ImpedanceModel::M1, ImpedanceModel::M2] {
            assert_eq!(m.n_params(), 3);
            assert!(m.terms().iter().all(|t| ImpedanceModel::M3.has(*t)));
        }
        assert!(!ImpedanceModel::M1.has(Term::HystereticDamping));
        assert!(!ImpedanceModel::M2.has(Term::ViscousDamping));
    }
}
