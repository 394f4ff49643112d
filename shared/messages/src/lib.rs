//! # exo-messages
//!
//! Every sample the exo processes exchange over iceoryx2 shared memory, the
//! one list of service names, and the IPC helpers every process uses.
//!
//! Each message is a `#[repr(C)]`, fixed-size, `Copy` struct with a stable,
//! versioned type name (`exo.<Type>.v<N>`, [`Message::TYPE_NAME`]; bump `N`
//! whenever the layout changes). With the cargo feature `ipc` (off by
//! default) each also derives iceoryx2's `ZeroCopySend` with that name as its
//! `type_name`, so a publisher writes it once into shared memory and every
//! subscriber reads it in place; only the crates that open channels enable it
//! (`exo-service-kit`, `exo-pipeline-bench`), so the crates that only read or
//! write recordings build without iceoryx2. Padding is explicit (`_pad` fields, always
//! 0), so the layout tests pin every byte and the recording contract can
//! mirror it. Every field's doc gives its unit.
//!
//! | message | module | from → to |
//! |---|---|---|
//! | [`SensorSample`] | [`sensor`] | sensor driver → controller, identifier, recorder |
//! | [`ActuatorCommand`] | [`command`] | controller → sensor driver, identifier, recorder |
//! | [`ProtocolState`] | [`protocol`] | controller → plant simulator, identifier, recorder |
//! | [`BusSensorFrame`], [`BusMotorCommand`] | [`bus`] | plant simulator ↔ sensor driver (raw, as hardware) |
//! | [`FrfPoint`], [`ImpedanceEstimate`] | [`identifier`] | identifier → operator, recorder |
//! | [`OperatorCommand`] | [`operator`] | operator console → controller, sensor driver |
//! | [`OperatorReply`] | [`operator`] | controller → operator console |
//! | [`OffPathProgress`] | [`progress`] | recorder, identifier → plant simulator (lockstep: how far each has taken the run) |
//!
//! Sign convention (the paper's): `tau_c` is the torque the cuff applies to
//! the human, so `S_h = τ_c/θ_e`; `tau_s` is the SEA spring torque driving
//! the exoskeleton joint in the direction of `theta_e`.
//!
//! Messages crossing a process boundary are checked with `is_finite()` /
//! `validate(...)`, which name the offending field in a [`MessageError`], so
//! NaN and infinities are stopped at the boundary.
//!
//! The channel table ([`channels`]: every channel's name, payload type,
//! publisher and subscribers, buffer bound, whether it is recorded and its
//! MCAP schema, and the processes' names) is here too, beside the payloads
//! it names; the IPC helpers that open the channels live in
//! `exo-service-kit` (`ipc`), so tools that read recordings need no iceoryx2
//! node (nor, without the feature `ipc`, the iceoryx2 crate).

#![deny(missing_docs)]

pub mod bus;
pub mod channels;
pub mod command;
pub mod error;
pub mod identifier;
pub mod operator;
pub mod progress;
pub mod protocol;
pub mod sensor;

use core::fmt::Debug;

#[cfg(feature = "ipc")]
use iceoryx2::prelude::ZeroCopySend;

pub use bus::{bus_status, wrench, BusLimits, BusMotorCommand, BusSensorFrame, MotorLimits};
pub use channels::{Channel, ChannelInfo, ProcessName, Topic, CHANNELS};
pub use command::{ActuatorCommand, CommandLimits, ControlMode};
pub use error::MessageError;
pub use identifier::{FitModel, FrfPoint, ImpedanceEstimate};
pub use operator::{OperatorCommand, OperatorCommandKind, OperatorReply, OperatorVerdict};
pub use progress::OffPathProgress;
pub use protocol::{ProtocolPhase, ProtocolState};
pub use sensor::{status, SensorLimits, SensorSample};

/// The shared-memory bound of a [`Message`]: iceoryx2's `ZeroCopySend` with
/// the feature `ipc`, no bound without it (every type has it then).
#[cfg(feature = "ipc")]
pub trait Shareable: ZeroCopySend {}
#[cfg(feature = "ipc")]
impl<T: ZeroCopySend> Shareable for T {}

/// The shared-memory bound of a [`Message`]: iceoryx2's `ZeroCopySend` with
/// the feature `ipc`, no bound without it (every type has it then).
#[cfg(not(feature = "ipc"))]
pub trait Shareable {}
#[cfg(not(feature = "ipc"))]
impl<T> Shareable for T {}

/// What every exo message is: a fixed-layout sample with a stable type name
/// and named floating-point fields (and, with the feature `ipc`,
/// shared-memory-safe: [`Shareable`]).
pub trait Message: Shareable + Copy + Debug + Default + PartialEq + Send + 'static {
    /// The stable type name, e.g. `"exo.SensorSample.v1"`; with the feature
    /// `ipc` it is the `#[type_name]` of its `ZeroCopySend` derive, and
    /// iceoryx2 refuses to connect ports whose type names, sizes or
    /// alignments differ.
    const TYPE_NAME: &'static str;
    /// The Rust type name used in errors, e.g. `"SensorSample"`.
    const NAME: &'static str;

    /// The first floating-point field (name, value) that is NaN or infinite.
    fn first_non_finite(&self) -> Option<(&'static str, f64)>;

    /// Whether every floating-point field is finite.
    fn is_finite(&self) -> bool {
        self.first_non_finite().is_none()
    }

    /// `Err(MessageError::NonFinite)` naming the first non-finite field.
    fn check_finite(&self) -> Result<(), MessageError> {
        error::check_finite(Self::NAME, self.first_non_finite())
    }
}

/// Implements [`Message`] and an inherent `is_finite` for a message whose
/// floating-point fields are listed as `"name" => expr`.
macro_rules! impl_message {
    ($ty:ident, $type_name:literal, |$s:ident| [$($field:literal => $value:expr),+ $(,)?]) => {
        impl $crate::Message for $ty {
            const TYPE_NAME: &'static str = $type_name;
            const NAME: &'static str = stringify!($ty);
            fn first_non_finite(&self) -> Option<(&'static str, f64)> {
                let $s = self;
                $crate::error::first_non_finite([$(($field, $value)),+])
            }
        }

        impl $ty {
            /// Whether every floating-point field is finite (no NaN, no ±∞).
            pub fn is_finite(&self) -> bool {
                <Self as $crate::Message>::is_finite(self)
            }

            /// The first floating-point field (name, value) that is NaN or infinite.
            pub fn first_non_finite(&self) -> Option<(&'static str, f64)> {
                <Self as $crate::Message>::first_non_finite(self)
            }
        }
    };
}
pub(crate) use impl_message;

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(feature = "ipc")]
    fn type_name_of<T: Message>() -> &'static str {
        // SAFETY: `type_name` only returns the string literal of the derive's
        // `#[type_name]` attribute; it has no preconditions for these types.
        unsafe { <T as ZeroCopySend>::type_name() }
    }

    #[test]
    fn derive_type_names_match_the_message_constants() {
        fn check<T: Message>() {
            #[cfg(feature = "ipc")]
            assert_eq!(type_name_of::<T>(), T::TYPE_NAME);
            // exo.<Name>.v<layout version>; FrfPoint is at v2 (fields appended).
            let version = T::TYPE_NAME
                .strip_prefix(&format!("exo.{}.v", T::NAME))
                .unwrap_or_else(|| panic!("{} is not exo.{}.vN", T::TYPE_NAME, T::NAME));
            assert!(
                version.parse::<u32>().is_ok_and(|v| v >= 1),
                "{}",
                T::TYPE_NAME
            );
            assert!(T::default().is_finite());
        }
        check::<SensorSample>();
        check::<ActuatorCommand>();
        check::<ProtocolState>();
        check::<BusSensorFrame>();
        check::<BusMotorCommand>();
        check::<FrfPoint>();
        check::<ImpedanceEstimate>();
        check::<OperatorCommand>();
        check::<OperatorReply>();
        check::<OffPathProgress>();
    }
}
