//! # exo-supervisor
//!
//! What `exo run` does before and while the processes of a run live:
//!
//! - [`check`]: the run file and every file it names validated before any
//!   process starts, with the checks across them (integration step, output
//!   directory, the controller's loop margins from
//!   [`exo_analysis::preflight`]); every error names its file and key;
//! - [`services`]: the processes a configuration asks for, in start order,
//!   each with its role and readiness probe;
//! - [`supervise`](mod@supervise): starting them, forwarding their logs, reaping them,
//!   restarting those off the real-time path, stopping all on a signal or
//!   the first failure, and saying which one failed.

pub mod check;
pub mod error;
pub mod services;
pub mod supervise;

pub use check::{check_or_fail, check_run, Checked};
pub use error::{Error, Result};
pub use services::services_of;
pub use supervise::{
    config_args, sibling_program, supervise, supervise_checked, Ended, Logs, Ready, ReadyProbe,
    Role, ServiceSpec, Supervised,
};
