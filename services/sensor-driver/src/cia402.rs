//! The CiA 402 drive profile's power state machine as the master sees it
//! (IEC 61800-7-201 / CiA 402-2, figure "state machine"): the state read
//! from the statusword (0x6041), the controlword (0x6040) that moves the
//! drive towards Operation Enabled, and the supervision of a running drive:
//! any departure from Operation Enabled is a fault, after which the motor
//! is powered down in a defined way (quick stop, then disable voltage) and
//! held off until the operator asks for it again.
//!
//! Pure logic, one call per cycle, no allocation: the EtherCAT backend
//! (`ethercat.rs`) feeds it the statusword it read and writes the
//! controlword it returns.

/// Modes of operation (0x6060): cyclic synchronous torque.
pub const MODE_CST: i8 = 10;

/// Controlword commands (CiA 402, bits 0–3 and 7).
pub mod controlword {
    /// Shutdown: → Ready to Switch On (transitions 2, 6, 8).
    pub const SHUTDOWN: u16 = 0x0006;
    /// Switch on: → Switched On (transition 3).
    pub const SWITCH_ON: u16 = 0x0007;
    /// Enable operation: → Operation Enabled (transition 4).
    pub const ENABLE_OPERATION: u16 = 0x000F;
    /// Quick stop (enable voltage set, quick stop bit clear): → Quick Stop
    /// Active (transition 11).
    pub const QUICK_STOP: u16 = 0x0002;
    /// Disable voltage: → Switch On Disabled (transitions 7, 9, 10, 12).
    pub const DISABLE_VOLTAGE: u16 = 0x0000;
    /// Fault reset, on its rising edge: Fault → Switch On Disabled (15).
    pub const FAULT_RESET: u16 = 0x0080;
}

/// The drive's power state, decoded from the statusword.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveState {
    /// Not Ready to Switch On (self-test).
    NotReadyToSwitchOn,
    /// Switch On Disabled.
    SwitchOnDisabled,
    /// Ready to Switch On.
    ReadyToSwitchOn,
    /// Switched On (power stage on, no torque).
    SwitchedOn,
    /// Operation Enabled: the drive follows the set-points.
    OperationEnabled,
    /// Quick Stop Active.
    QuickStopActive,
    /// Fault Reaction Active.
    FaultReactionActive,
    /// Fault.
    Fault,
}

impl DriveState {
    /// Decodes the statusword (CiA 402 table of statusword bits 0–3, 5, 6).
    pub fn from_statusword(sw: u16) -> DriveState {
        match (sw & 0x004F, sw & 0x006F) {
            (0x0000, _) => DriveState::NotReadyToSwitchOn,
            (0x0040, _) => DriveState::SwitchOnDisabled,
            (0x000F, _) => DriveState::FaultReactionActive,
            (0x0008, _) => DriveState::Fault,
            (_, 0x0021) => DriveState::ReadyToSwitchOn,
            (_, 0x0023) => DriveState::SwitchedOn,
            (_, 0x0027) => DriveState::OperationEnabled,
            (_, 0x0007) => DriveState::QuickStopActive,
            // Bit patterns the table does not name: treat as a fault.
            _ => DriveState::Fault,
        }
    }

    /// Whether the power stage may be producing torque.
    pub fn is_powered(self) -> bool {
        matches!(
            self,
            DriveState::OperationEnabled
                | DriveState::QuickStopActive
                | DriveState::FaultReactionActive
        )
    }

    /// Whether the drive reports a fault.
    pub fn is_fault(self) -> bool {
        matches!(self, DriveState::Fault | DriveState::FaultReactionActive)
    }
}

/// Where the master is taking the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Walking the drive up to Operation Enabled.
    Enabling,
    /// Operation Enabled, supervised.
    Enabled,
    /// Powering down: quick stop, `cycles_left` more cycles at most.
    QuickStop {
        /// Cycles of quick stop left before disable voltage.
        cycles_left: u32,
    },
    /// Powered down (disable voltage), until the operator enables again.
    Off,
}

/// Why the supervision powered the drive down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Departure {
    /// The drive reports Fault or Fault Reaction Active.
    Fault {
        /// Its statusword.
        statusword: u16,
    },
    /// It left Operation Enabled for another state without being asked.
    UnexpectedState {
        /// Its statusword.
        statusword: u16,
    },
}

/// The master's side of the CiA 402 state machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cia402 {
    phase: Phase,
    quick_stop_cycles: u32,
    fault_reset_asked: bool,
    last_controlword: u16,
}

impl Cia402 {
    /// A master that powers down with `quick_stop_cycles` cycles of quick
    /// stop (0: disable voltage at once). It starts `Off`: nothing is
    /// enabled until [`Cia402::enable`].
    pub fn new(quick_stop_cycles: u32) -> Self {
        Cia402 {
            phase: Phase::Off,
            quick_stop_cycles,
            fault_reset_asked: false,
            last_controlword: controlword::DISABLE_VOLTAGE,
        }
    }

    /// Cycles of quick stop before disable voltage.
    pub fn quick_stop_cycles(&self) -> u32 {
        self.quick_stop_cycles
    }

    /// The current phase.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// Asks for Operation Enabled. With `reset_fault` (the operator's
    /// request, and only then) a drive in Fault is reset on the way;
    /// without, a drive in Fault is a departure and stays off.
    pub fn enable(&mut self, reset_fault: bool) {
        // Also during a quick stop: the operator's reset may come before
        // the disable voltage that ends it.
        if matches!(self.phase, Phase::Off | Phase::QuickStop { .. }) {
            self.phase = Phase::Enabling;
            self.fault_reset_asked = reset_fault;
        }
    }

    /// Powers the drive down (quick stop, then disable voltage) now.
    pub fn power_down(&mut self) {
        if matches!(self.phase, Phase::Enabling | Phase::Enabled) {
            self.phase = if self.quick_stop_cycles == 0 {
                Phase::Off
            } else {
                Phase::QuickStop {
                    cycles_left: self.quick_stop_cycles,
                }
            };
        }
    }

    /// One cycle: the statusword just read; returns the controlword to
    /// write and, when the drive has just left Operation Enabled on its
    /// own, why (the drive is then being powered down).
    pub fn step(&mut self, statusword: u16) -> (u16, Option<Departure>) {
        let state = DriveState::from_statusword(statusword);
        let mut departure = None;
        if self.phase == Phase::Enabled && state != DriveState::OperationEnabled {
            departure = Some(if state.is_fault() {
                Departure::Fault { statusword }
            } else {
                Departure::UnexpectedState { statusword }
            });
            self.power_down();
        }
        if self.phase == Phase::Enabling && state.is_fault() && !self.fault_reset_asked {
            // A fault met on the way up that nobody asked to reset.
            departure = Some(Departure::Fault { statusword });
            self.phase = Phase::Off;
        }
        if self.phase == Phase::Enabling && state == DriveState::OperationEnabled {
            self.phase = Phase::Enabled;
        }
        let cw = match self.phase {
            Phase::Enabled => controlword::ENABLE_OPERATION,
            Phase::Enabling => self.enabling_controlword(state),
            Phase::QuickStop { cycles_left } => {
                // A drive that is not powered (faulted, already disabled)
                // needs no quick stop.
                if cycles_left == 0
                    || !state.is_powered()
                    || (state == DriveState::QuickStopActive
                        && cycles_left < self.quick_stop_cycles)
                {
                    self.phase = Phase::Off;
                    controlword::DISABLE_VOLTAGE
                } else {
                    self.phase = Phase::QuickStop {
                        cycles_left: cycles_left - 1,
                    };
                    controlword::QUICK_STOP
                }
            }
            Phase::Off => controlword::DISABLE_VOLTAGE,
        };
        self.last_controlword = cw;
        (cw, departure)
    }

    fn enabling_controlword(&mut self, state: DriveState) -> u16 {
        match state {
            DriveState::Fault | DriveState::FaultReactionActive => {
                // The reset acts on a rising edge of bit 7.
                if self.fault_reset_asked
                    && state == DriveState::Fault
                    && self.last_controlword & controlword::FAULT_RESET == 0
                {
                    controlword::FAULT_RESET
                } else {
                    controlword::DISABLE_VOLTAGE
                }
            }
            DriveState::NotReadyToSwitchOn => controlword::DISABLE_VOLTAGE,
            DriveState::SwitchOnDisabled => controlword::SHUTDOWN,
            DriveState::ReadyToSwitchOn => controlword::SWITCH_ON,
            DriveState::SwitchedOn | DriveState::OperationEnabled => controlword::ENABLE_OPERATION,
            // Out of quick stop: disable voltage first (transition 12).
            DriveState::QuickStopActive => controlword::DISABLE_VOLTAGE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::controlword as cw;
    use super::*;

    /// A drive that follows the CiA 402 transitions of the standard's
    /// figure, written from the standard's table, not from the master above:
    /// (state, controlword) → next state.
    fn drive_next(state: DriveState, c: u16) -> DriveState {
        use DriveState::*;
        let disable_voltage = c & 0x0002 == 0;
        let quick_stop = c & 0x0006 == 0x0002;
        match state {
            Fault if c & 0x0080 != 0 => SwitchOnDisabled,
            Fault | FaultReactionActive | NotReadyToSwitchOn => state,
            _ if disable_voltage => SwitchOnDisabled,
            OperationEnabled if quick_stop => QuickStopActive,
            QuickStopActive => QuickStopActive,
            SwitchOnDisabled if c & 0x0087 == 0x0006 => ReadyToSwitchOn,
            ReadyToSwitchOn if c & 0x008F == 0x0007 => SwitchedOn,
            SwitchedOn if c & 0x008F == 0x000F => OperationEnabled,
            SwitchedOn | OperationEnabled if c & 0x0087 == 0x0006 => ReadyToSwitchOn,
            OperationEnabled if c & 0x008F == 0x0007 => SwitchedOn,
            s => s,
        }
    }

    fn statusword(s: DriveState) -> u16 {
        // Bit patterns of the CiA 402 statusword table, with "remote" (bit 9) set.
        0x0200
            | match s {
                DriveState::NotReadyToSwitchOn => 0x0000,
                DriveState::SwitchOnDisabled => 0x0040,
                DriveState::ReadyToSwitchOn => 0x0021,
                DriveState::SwitchedOn => 0x0023,
                DriveState::OperationEnabled => 0x0027,
                DriveState::QuickStopActive => 0x0007,
                DriveState::FaultReactionActive => 0x000F,
                DriveState::Fault => 0x0008,
            }
    }

    #[test]
    fn every_state_is_decoded_from_its_statusword() {
        use DriveState::*;
        for s in [
            NotReadyToSwitchOn,
            SwitchOnDisabled,
            ReadyToSwitchOn,
            SwitchedOn,
            OperationEnabled,
            QuickStopActive,
            FaultReactionActive,
            Fault,
        ] {
            assert_eq!(DriveState::from_statusword(statusword(s)), s);
            // Bits outside the state bits change nothing (voltage, warning, manufacturer).
            assert_eq!(DriveState::from_statusword(statusword(s) | 0xFC10), s);
        }
        // KickCAT's emulated drive: 0x0040, 0x0031, 0x0033, 0x0037.
        assert_eq!(DriveState::from_statusword(0x0031), ReadyToSwitchOn);
        assert_eq!(DriveState::from_statusword(0x0037), OperationEnabled);
    }

    #[test]
    fn a_drive_is_walked_to_operation_enabled_in_three_transitions() {
        let mut m = Cia402::new(5);
        let mut s = DriveState::SwitchOnDisabled;
        let (c, _) = m.step(statusword(s));
        assert_eq!(c, cw::DISABLE_VOLTAGE, "off until asked");
        m.enable(true);
        let mut sent = Vec::new();
        for _ in 0..6 {
            let (c, d) = m.step(statusword(s));
            assert_eq!(d, None);
            sent.push(c);
            s = drive_next(s, c);
        }
        assert_eq!(s, DriveState::OperationEnabled);
        assert_eq!(
            &sent[..3],
            [cw::SHUTDOWN, cw::SWITCH_ON, cw::ENABLE_OPERATION]
        );
        assert_eq!(m.phase(), Phase::Enabled);
    }

    #[test]
    fn a_fault_powers_down_and_is_reset_only_when_asked() {
        let mut m = Cia402::new(3);
        m.enable(true);
        let mut s = DriveState::SwitchOnDisabled;
        for _ in 0..4 {
            s = drive_next(s, m.step(statusword(s)).0);
        }
        assert_eq!(m.phase(), Phase::Enabled);
        // The drive faults: named at once, then disable voltage (no quick
        // stop for an unpowered drive), held for good.
        let (c, d) = m.step(statusword(DriveState::Fault));
        assert_eq!(
            d,
            Some(Departure::Fault {
                statusword: statusword(DriveState::Fault)
            })
        );
        assert_eq!(c, cw::DISABLE_VOLTAGE);
        for _ in 0..100 {
            let (c, d) = m.step(statusword(DriveState::Fault));
            assert_eq!((c, d), (cw::DISABLE_VOLTAGE, None), "no reset unasked");
        }
        // Enabling without the operator's reset: the fault is named, not reset.
        m.enable(false);
        let (c, d) = m.step(statusword(DriveState::Fault));
        assert!(matches!(d, Some(Departure::Fault { .. })));
        assert_eq!(c, cw::DISABLE_VOLTAGE);
        assert_eq!(m.phase(), Phase::Off);
        // The operator asks: one rising edge of fault reset, then the walk up.
        m.enable(true);
        let mut s = DriveState::Fault;
        let mut sent = Vec::new();
        for _ in 0..8 {
            let c = m.step(statusword(s)).0;
            sent.push(c);
            s = drive_next(s, c);
        }
        assert_eq!(sent.iter().filter(|c| **c == cw::FAULT_RESET).count(), 1);
        assert_eq!(s, DriveState::OperationEnabled);
    }

    #[test]
    fn an_unexpected_state_quick_stops_then_disables() {
        let mut m = Cia402::new(3);
        m.enable(true);
        let mut s = DriveState::SwitchOnDisabled;
        for _ in 0..4 {
            s = drive_next(s, m.step(statusword(s)).0);
        }
        // Drops to Switched On by itself (e.g. a drive-side disable input):
        // powered down without quick stop, it is not producing torque.
        let (c, d) = m.step(statusword(DriveState::SwitchedOn));
        assert!(matches!(d, Some(Departure::UnexpectedState { .. })));
        assert_eq!(c, cw::DISABLE_VOLTAGE);
        assert_eq!(m.phase(), Phase::Off);
        // Powered down while enabled by the master's decision (bus fault):
        // quick stop for at most 3 cycles, then disable voltage.
        m.enable(true);
        s = DriveState::SwitchOnDisabled;
        for _ in 0..4 {
            s = drive_next(s, m.step(statusword(s)).0);
        }
        m.power_down();
        // A drive that never reports Quick Stop Active (KickCAT's) still
        // gets disabled after the quick-stop time.
        let sent: Vec<u16> = (0..5)
            .map(|_| m.step(statusword(DriveState::OperationEnabled)).0)
            .collect();
        assert_eq!(
            sent,
            [
                cw::QUICK_STOP,
                cw::QUICK_STOP,
                cw::QUICK_STOP,
                cw::DISABLE_VOLTAGE,
                cw::DISABLE_VOLTAGE
            ]
        );
        // Enabled again during a quick stop (an operator's reset within
        // quick_stop_ms): walked up, not left off.
        m.enable(true);
        s = DriveState::SwitchOnDisabled;
        for _ in 0..4 {
            s = drive_next(s, m.step(statusword(s)).0);
        }
        assert_eq!(m.phase(), Phase::Enabled);
        m.power_down();
        assert_eq!(
            m.step(statusword(DriveState::OperationEnabled)).0,
            cw::QUICK_STOP
        );
        m.enable(true);
        assert_eq!(m.phase(), Phase::Enabling);
        assert_eq!(
            m.step(statusword(DriveState::OperationEnabled)).0,
            cw::ENABLE_OPERATION
        );
        assert_eq!(m.phase(), Phase::Enabled);
        // One that does is disabled as soon as it reports it.
        let mut m = Cia402::new(3);
        m.enable(true);
        s = DriveState::SwitchOnDisabled;
        for _ in 0..4 {
            s = drive_next(s, m.step(statusword(s)).0);
        }
        m.power_down();
        let c = m.step(statusword(s)).0;
        assert_eq!(c, cw::QUICK_STOP);
        s = drive_next(s, c);
        assert_eq!(s, DriveState::QuickStopActive);
        assert_eq!(m.step(statusword(s)).0, cw::DISABLE_VOLTAGE);
    }
}
