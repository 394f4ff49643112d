//! # exo-controller (logic)
//!
//! Everything the controller process decides, as plain structs testable
//! without IPC: the protocol clock ([`protocol`]), the amplification law
//! ([`amplification`]), limits and the fault latch ([`safety`]), and the
//! per-tick composition of the desired actuator torque ([`controller`]):
//!
//! ```text
//! τ_d = τ_gravity(θ_e) + τ_amplification + τ_bias(t) + τ_excitation(t),
//! τ_amplification = −(α(s) − 1) τ_c,   α(s) − 1 = k_p F(s)  (or α − 1 constant)
//! ```
//!
//! Sign convention (the paper's, section "Models"): `τ_c` is the torque the
//! cuff applies to the human, so `S_h = τ_c/θ_e = M_h s² + K(1 + cj)`, and the
//! amplification feeds `−(α − 1)τ_c` to the actuator (Fig. 2).
//!
//! Operator commands (`exo op`, `exo_messages::OperatorCommand`) are
//! decided by [`controller::Controller::on_operator`]: reset the fault
//! latch, adopt a fractional order f, stop the protocol (ramp out, then hold
//! gravity compensation in mode `Run`, no fault) or (re)start it at an
//! experiment; the protocol's position is a [`controller::ProtocolRun`].
//!
//! `main.rs` (the process) only moves samples and operator commands between
//! iceoryx2 and [`controller::Controller::tick`] and
//! [`controller::Controller::on_operator`], which make no heap allocation.

pub mod amplification;
pub mod controller;
pub mod node;
pub mod process;
pub mod protocol;
pub mod safety;

pub use amplification::Amplifier;
pub use controller::{
    Controller, ControllerError, OperatorOutcome, OperatorRefusal, ProtocolRun, Tick, TickInput,
};
pub use protocol::{Protocol, ProtocolPoint};
pub use safety::{Fault, FaultLatch, Limits};
