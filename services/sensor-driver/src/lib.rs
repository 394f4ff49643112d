//! # exo-sensor-driver (logic)
//!
//! The driver owns the actuator. Each cycle (ros2_control's `read → update →
//! write`): it reads one raw frame from the hardware bus, converts it to a
//! calibrated sample, hands the sample to the controller, and writes the
//! controller's torque back to the bus, or, when no fresh command has come
//! within the deadline, the safe-state torque, latched until reset.
//!
//! The bus is the [`HardwareBus`] trait. The simulator's bus (iceoryx2
//! channels to `plant-sim`) is implemented in `backends.rs`; a CiA 402
//! drive on EtherCAT (`ethercrab`) in [`ethercat`], with the drive profile's
//! state machine in [`cia402`]; a CAN (`socketcan`) or UDP backend would
//! implement the same trait. The backend is chosen by configuration:
//! nothing in the controller, identifier or recorder changes.

pub mod backends;
pub mod calibration;
pub mod cia402;
pub mod driver;
pub mod ethercat;
pub mod node;
pub mod process;
pub mod round_trip;

pub use calibration::{Calibration, VelocityFilter};
pub use driver::{
    status, BusFault, CalibratedSample, CommandSource, Driver, DriverOutput, RawFrame, SafetyEvent,
};
pub use node::DriverNode;
pub use round_trip::{RoundTrip, RoundTripReport};

/// A hardware bus: where raw frames come from and motor torques go.
///
/// Implementations: the simulator's bus (`backends::SimulatorBus` in the
/// process, iceoryx2 channels to `exo-plant-sim`); a hardware backend
/// (EtherCAT, CAN, UDP) implements the same two calls. Both calls are on the
/// real-time path: bounded, no allocation per call.
pub trait HardwareBus {
    /// Error type of the backend.
    type Error: std::error::Error + Send + Sync + 'static;
    /// A short name for logs, e.g. `simulator`.
    fn name(&self) -> &'static str;
    /// Waits at most `timeout` for the next raw frame; `Ok(None)` on timeout.
    fn read(&mut self, timeout: std::time::Duration) -> Result<Option<RawFrame>, Self::Error>;
    /// Writes the motor torque (Nm) answering frame `frame_seq` (time stamp
    /// `stamp_ns` of that frame); `enable = false` powers the motor down.
    fn write(
        &mut self,
        frame_seq: u64,
        stamp_ns: u64,
        tau_motor_nm: f64,
        enable: bool,
    ) -> Result<(), Self::Error>;
    /// A fault the bus found in the cycle just read (a hardware bus's own
    /// supervision: lost frames, working counter, drive state), named once
    /// when it latches; the driver then latches its safe state in the same
    /// cycle. Default: the bus finds none of its own.
    fn take_fault(&mut self) -> Option<BusFault> {
        None
    }
    /// The controller's command for the cycle just read did not come
    /// within the deadline (real time). A bus whose drive holds its last
    /// set-point (EtherCAT in CST) counts it as a missed cycle and returns
    /// `true` while its run of misses stays below its limit: the driver
    /// then writes nothing this cycle and the drive holds. Default `false`:
    /// the driver latches its safe state now.
    fn hold_missed_command(&mut self) -> bool {
        false
    }
}
