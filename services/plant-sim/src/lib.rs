//! # exo-plant-sim (physics)
//!
//! The physical world the controller acts on, standing in for the hardware:
//! the exoskeleton arm and its load, the human forearm coupled through the
//! cuff, the human joint impedance (stiffness, viscous and hysteretic
//! damping), the series elastic actuator, gravity, joint friction, and the
//! sensors with their gains, offsets, noise, quantisation and delays.
//!
//! The plant model is a TOML file ([`PlantModel`]) in which **every physical
//! effect is a named term**, off or on with its parameters; the mismatch
//! tool reads and writes the same format.
//!
//! Integration: the linear part (inertias, springs, dampers, Prony bank,
//! SEA) is integrated exactly for inputs held over each step (zero-order
//! hold, one matrix exponential computed when the parameters change); the
//! nonlinear terms (gravity `sin θ`, Coulomb friction) enter as inputs held
//! over the step, evaluated at its start. The step (default 0.1 ms) is ten
//! times finer than the 1 kHz control period.
//!
//! The complex stiffness `K(1 + jc)` is made causal by a generalised-Maxwell
//! (Prony) bank ([`prony`]); see its docs for how close it comes.

pub mod expm;
pub mod human;
/// The plant model (`exo-plant-model`), which the simulator runs.
pub use exo_plant_model as model;
pub mod node;
pub mod pace;
pub mod plant;
pub mod process;
pub mod prony;
pub mod rng;

pub use exo_plant_model::{PlantModel, PlantModelError};
pub use human::PostureDrive;
pub use node::{PlantNode, StepMismatch};
pub use plant::{HumanDrive, Plant, PlantTruth, RawSensors};
pub use prony::PronyBank;
