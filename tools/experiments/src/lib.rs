//! # exo-experiments
//!
//! The paper's experiments automated on the in-process simulator
//! ([`exo_sim`]), as libraries the `exo` tool and tests call:
//!
//! - [`simulate`]: one subject through a base run configuration, recorded
//!   to the contract, bounded and stopped at a latched safe state
//!   (`exo reproduce`, `exo diagnose-bench`);
//! - [`tune`]: the tuning experiment (spring-release trials raising f,
//!   the boundary bisected, beside the model's prediction; `exo tune`);
//! - [`offline`]: `exo fit`'s pipeline: recordings and CSVs read, replayed
//!   through the online identifier's node, grouped by subject and analysed
//!   as the paper does (a tool's, so it lives above the identifier service
//!   whose node it steps).
//!
//! A crate of its own rather than modules of `exo-sim`: these write run
//! files and recordings and report errors naming them ([`Error`]),
//! while `exo-sim` is the bare lockstep composition of the nodes.

pub mod error;
pub mod offline;
pub mod simulate;
pub mod tune;

pub use error::{Error, Result};
