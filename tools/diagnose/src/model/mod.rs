//! The forward model: what a plant model (the simulator's TOML, every term
//! in it) predicts for each transfer function a recording supports, in the
//! frequency domain, linearised about each window's posture.
//!
//! With phasors at ω (`s = jω`), for each window:
//!
//! ```text
//! Z_imp  = K_e + j H_e + jω B_h                      human joint impedance (paper eq. M1–M3 terms)
//!          + G jω e^{−jωδ}/(1 + jω/ω_c)²              stretch reflex (when on)
//! Z_h    = Z_imp − M_h ω²                             forearm on the cuff
//! S_cuff = Z_c Z_h / (Z_c + Z_h),  Z_c = k_c + jω b_c  (rigid cuff: S_cuff = Z_h)
//! S_exo  = −M_e ω² + S_cuff + m g l cos θ₀ + jω b_f + j 4 F_c/(π A)
//! S_h    = g_c e^{−jω d_c} S_cuff / (g_θ e^{−jω d_θ})
//! S_h-e  = g_s e^{−jω d_s} S_exo / (g_θ e^{−jω d_θ}) − G_comp
//! τ_s/τ_d = g_s e^{−jω d_s} e^{−jω (d_a + h/2)} ω_n² / (ω_n² − ω² + 2jζω_nω)
//!           (ideal actuator: e^{−jω (d_s + d_a + h)}, and S_h-e gains e^{−jω h/2})
//! ```
//!
//! `K_e`, `H_e` per experiment (the subject file's), `M_e = M_arm + m_load
//! l²` (+ an inertia error), `m g l` the plant's gravity (+ an error), `A`
//! the window's angle amplitude (Coulomb friction's describing function),
//! `G_comp` the controller's own gravity compensation measured in the
//! recording, `h` the control period (the command is held over it), `d_*`
//! the sensor and actuator delays, `g_*` the sensor gains. Every symbol is
//! a named term of the plant TOML; [`Physics::from_plant`] reads them and
//! [`Physics::write_plant`] writes them back.
//!
//! Assumptions: the hysteretic damping is `K + jH` exactly at the excitation
//! (the simulator's `equivalent_viscous` and `prony_matched` modes are; the
//! plain `prony` bank differs by its few-per-cent Kramers–Kronig drift);
//! gravity's moment at the fundamental is taken from the window's measured
//! angle (about the centre of its swing, its harmonics included), friction
//! by its describing function; sensor offsets do not enter transfer
//! functions and are not diagnosed.
//!
//! Accuracy against the simulator (`tests/it/forward.rs`, every term alone):
//! linear terms within the measured noise (the fit's floor,
//! `fit::MODEL_ACCURACY`, is 0.5 %);
//! Coulomb friction's describing function within 1.7 % (it ignores the
//! harmonics); an ideal actuator (no SEA dynamics) within 0.8 %.
//!
//! ## Where it lives
//!
//! - this file: nothing but the layout and the re-exports;
//! - `param.rs`: the free parameters ([`Param`]), with their labels,
//!   scales, absent values and bounds;
//! - `physics.rs`: every coefficient ([`Physics`]), read from a plant model
//!   ([`Physics::from_plant`]) and got or set by parameter;
//! - `predict.rs`: the predictions ([`Physics::predict`],
//!   [`Physics::predict_tf`], the static balance, `S_exo`, gravity's gain,
//!   the torque limit's, the gear mesh of a window);
//! - `plant.rs`: the coefficients written back ([`Physics::write_plant`],
//!   [`Physics::subject_toml`]);
//! - `describing.rs`: the describing functions of Coulomb friction and of
//!   gravity ([`coulomb_describing`], [`gravity_describing`]);
//! - `mesh.rs`: a gear mesh with lost motion, backlash ([`Mesh`]).
//!
//! The files depend downwards only: `predict` → `physics`, `mesh`,
//! `describing`; `physics` → `param`; `plant` → `physics`; `param`,
//! `mesh` and `describing` import no other file of it. Of the crate only
//! `predict` imports [`crate::data`].

mod describing;
mod mesh;
mod param;
mod physics;
mod plant;
mod predict;

pub use describing::{coulomb_describing, gravity_describing};
pub use mesh::Mesh;
pub use param::Param;
pub use physics::Physics;
