//! One received message of any recorded channel, as the recorder writes it
//! and the player replays it.

use std::io::{Seek, Write};

use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};

use crate::{RecordingError, RecordingWriter};

/// One received message of any recorded channel: fixed size, copied out of
/// shared memory by the recorder's receiving thread, written by its writing
/// thread; replayed by the player.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Record {
    /// `exo/sensor`.
    Sensor(SensorSample),
    /// `exo/command`.
    Command(ActuatorCommand),
    /// `exo/protocol`.
    Protocol(ProtocolState),
    /// `exo/identifier/frf`.
    Frf(FrfPoint),
    /// `exo/identifier/estimate`.
    Estimate(ImpedanceEstimate),
    /// `exo/operator`.
    Operator(OperatorCommand),
    /// `exo/bus/sensor`.
    BusSensor(BusSensorFrame),
    /// `exo/bus/motor`.
    BusMotor(BusMotorCommand),
}

impl Record {
    /// Writes the record on its topic.
    pub fn write_to<W: Write + Seek>(
        &self,
        w: &mut RecordingWriter<W>,
    ) -> Result<(), RecordingError> {
        match self {
            Record::Sensor(m) => w.write(m),
            Record::Command(m) => w.write(m),
            Record::Protocol(m) => w.write(m),
            Record::Frf(m) => w.write(m),
            Record::Estimate(m) => w.write(m),
            Record::Operator(m) => w.write(m),
            Record::BusSensor(m) => w.write(m),
            Record::BusMotor(m) => w.write(m),
        }
    }
}
