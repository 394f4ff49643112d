//! The hardware-bus backends this process can drive, chosen by `[bus]
//! backend` in the run configuration. A new backend (EtherCAT with
//! `ethercrab`, CAN with `socketcan`, UDP) is a type implementing
//! [`HardwareBus`] here plus a variant of `exo_config::BusBackend`; see
//! ARCHITECTURE.md.

use std::time::Duration;

use crate::node::raw_frame;
use crate::{HardwareBus, RawFrame};
use exo_messages::{BusMotorCommand, BusSensorFrame};
use exo_service_kit::channels::{BUS_MOTOR, BUS_SENSOR};
use exo_service_kit::ipc::{Connect, Inbox, Ipc, IpcError, Outbox};

/// The plant simulator's bus: `BusSensorFrame`s in, `BusMotorCommand`s out,
/// over iceoryx2. The simulator re-sends a frame it got no answer to (a
/// start-up race in lockstep); this backend answers such a frame again with
/// the same command without handing it to the driver twice.
pub struct SimulatorBus {
    frames: Inbox<BusSensorFrame>,
    motor: Outbox<BusMotorCommand>,
    last: Option<BusMotorCommand>,
    motor_seq: u64,
}

impl SimulatorBus {
    /// Opens the bus channels of the run.
    /// `spin`: see `Inbox::with_spin` (lockstep only).
    pub fn open(ipc: &Ipc, spin: Duration) -> Result<Self, IpcError> {
        Ok(SimulatorBus {
            frames: ipc.inbox(BUS_SENSOR, 64)?.with_spin(spin),
            motor: ipc.outbox(BUS_MOTOR)?,
            last: None,
            motor_seq: 0,
        })
    }

    /// Its two ports, to connect before real-time control starts.
    pub fn ports(&self) -> [&dyn Connect; 2] {
        [&self.frames, &self.motor]
    }
}

impl HardwareBus for SimulatorBus {
    type Error = IpcError;

    fn name(&self) -> &'static str {
        "simulator"
    }

    fn read(&mut self, timeout: Duration) -> Result<Option<RawFrame>, IpcError> {
        let Some(frame) = self.frames.recv_timeout(timeout)? else {
            return Ok(None);
        };
        if let Some(m) = self.last.filter(|m| m.frame_seq == frame.seq) {
            self.motor.send(m)?;
            return Ok(None);
        }
        Ok(Some(raw_frame(&frame)))
    }

    fn write(
        &mut self,
        frame_seq: u64,
        stamp_ns: u64,
        tau_motor_nm: f64,
        enable: bool,
    ) -> Result<(), IpcError> {
        let m = BusMotorCommand {
            seq: self.motor_seq,
            stamp_ns,
            frame_seq,
            tau_motor_nm,
            enable: u32::from(enable),
            ..Default::default()
        };
        self.motor_seq += 1;
        self.motor.send(m)?;
        self.last = Some(m);
        Ok(())
    }
}
