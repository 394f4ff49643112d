//! The channel table, as declared in `exo_messages::channels` (re-exported
//! here so the IPC helpers and their users name one module). A channel's
//! service name has the run's `instance` (from `[run] instance`) as its
//! first segment, so several runs, or parallel tests, do not see each
//! other's samples.

pub use exo_messages::channels::*;
