//! # exo-plant-drive
//!
//! Our plant (the SEA, the arm and the simulated human of `exo-plant-sim`)
//! as the mechanics of an emulated EtherCAT drive. KickCAT's network
//! simulator emulates the drive's ESC from its vendor's ESI and runs its
//! CiA 402 state machine; the C++ program in `cpp/` (built by `build.sh`
//! against the vendored KickCAT sources) gives that drive a device
//! behaviour of ours, which steps the plant through the C ABI below once
//! per cyclic frame.
//!
//! The simulated human follows the protocol as it does with the simulated
//! bus: the plant subscribes to the run's `<instance>/protocol` channel
//! (the subject's K and H per experiment, the running sine's frequency,
//! the load, the posture), exactly as the `exo-plant-sim` process does.
//!
//! The boundary: every function takes a handle made by
//! [`exo_plant_drive_open`] (null is refused), a non-finite torque is
//! refused (the plant is not stepped), and no panic crosses it (a panic is
//! caught and reported as [`EXO_PLANT_DRIVE_PANIC`]).

use std::ffi::{c_char, CStr};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use exo_config::RunConfig;
use exo_messages::{BusMotorCommand, ProtocolState};
use exo_plant_sim::{PlantModel, PlantNode};
use exo_service_kit::channels::PROTOCOL;
use exo_service_kit::ipc::{Inbox, Ipc};

/// Success.
pub const EXO_PLANT_DRIVE_OK: i32 = 0;
/// A null handle or output pointer.
pub const EXO_PLANT_DRIVE_NULL: i32 = -1;
/// A torque that is NaN or infinite: refused, the plant not stepped.
pub const EXO_PLANT_DRIVE_NOT_FINITE: i32 = -2;
/// The protocol channel could not be read.
pub const EXO_PLANT_DRIVE_IPC: i32 = -3;
/// A panic inside the plant (a bug): caught at the boundary.
pub const EXO_PLANT_DRIVE_PANIC: i32 = -4;

/// The node name of the plant inside the emulated drive.
const NODE_NAME: &str = "plant-drive";

/// What the drive's sensors read after a step (`#[repr(C)]`, `ExoPlantReadings`
/// in `cpp/exo_plant_drive.h`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ExoPlantReadings {
    /// Joint encoder counts (`sensors.encoder.counts_per_rev` of the plant model).
    pub encoder_counts: i64,
    /// SEA spring-deflection encoder counts.
    pub sea_deflection_counts: i64,
    /// Cuff wrench `[f_x, f_y, f_z, t_x, t_y, t_z]` (N, Nm).
    pub cuff_wrench: [f64; 6],
    /// The motor torque the drive applies now (Nm): the command when
    /// enabled and within the plant's limit, else 0.
    pub tau_motor_nm: f64,
    /// Simulated time (s).
    pub t_s: f64,
    /// One step of the plant: the run's control period (s).
    pub period_s: f64,
}

/// The plant of a run, and the protocol channel it follows.
pub struct ExoPlantDrive {
    node: PlantNode,
    protocol_in: Inbox<ProtocolState>,
    _ipc: Ipc,
}

impl ExoPlantDrive {
    /// The plant of run file `run_file`: its plant model and subject, one
    /// step per control period (`run.rate_hz`), following the protocol of
    /// `run.instance`.
    pub fn open(run_file: &Path) -> Result<Self, String> {
        let cfg = RunConfig::from_file(run_file).map_err(|e| format!("{e:#}"))?;
        let model = PlantModel::from_file(&cfg.plant_model).map_err(|e| e.to_string())?;
        let node = PlantNode::new(&cfg, &model, None).map_err(|e| e.to_string())?;
        let ipc = Ipc::open(NODE_NAME, &cfg.run.instance, None).map_err(|e| e.to_string())?;
        let protocol_in = ipc.inbox(PROTOCOL, 64).map_err(|e| e.to_string())?;
        Ok(ExoPlantDrive {
            node,
            protocol_in,
            _ipc: ipc,
        })
    }

    /// The readings of the current step, without stepping.
    pub fn readings(&mut self) -> ExoPlantReadings {
        let frame = self.node.frame(0);
        ExoPlantReadings {
            encoder_counts: frame.encoder_counts,
            sea_deflection_counts: frame.sea_deflection_counts,
            cuff_wrench: frame.cuff_wrench,
            tau_motor_nm: self.node.tau_motor_nm(),
            t_s: self.node.truth().t_s,
            period_s: self.node.period_ns() as f64 * 1e-9,
        }
    }

    /// Takes the protocol states that have arrived, holds motor torque
    /// `tau_motor_nm` (0 unless `enabled`) over one control period, and
    /// returns the readings at its end. A non-finite torque is refused.
    pub fn step(&mut self, tau_motor_nm: f64, enabled: bool) -> Result<ExoPlantReadings, i32> {
        if !tau_motor_nm.is_finite() {
            return Err(EXO_PLANT_DRIVE_NOT_FINITE);
        }
        loop {
            match self.protocol_in.try_recv() {
                Ok(Some(p)) => self.node.on_protocol(&p),
                Ok(None) => break,
                Err(_) => return Err(EXO_PLANT_DRIVE_IPC),
            }
        }
        // Held whatever frame it answers (the real-time path of the plant
        // process), so no frame number.
        self.node.hold_motor(&BusMotorCommand {
            tau_motor_nm,
            enable: u32::from(enabled),
            ..Default::default()
        });
        self.node.advance();
        Ok(self.readings())
    }
}

/// Writes `message` into the caller's buffer `err` of `err_len` bytes,
/// cut to fit and NUL-terminated.
///
/// # Safety
/// `err` is null or points to `err_len` writable bytes.
unsafe fn write_error(err: *mut c_char, err_len: usize, message: &str) {
    if err.is_null() || err_len == 0 {
        return;
    }
    let n = message.len().min(err_len - 1);
    // SAFETY: the caller's buffer holds err_len bytes, n + 1 <= err_len.
    unsafe {
        std::ptr::copy_nonoverlapping(message.as_ptr(), err.cast::<u8>(), n);
        *err.add(n) = 0;
    }
}

/// Opens the plant of run file `run_file` (a NUL-terminated path). Returns
/// the handle, or null with the reason in `err` (`err_len` bytes, may be null).
///
/// # Safety
/// `run_file` is null or a NUL-terminated string; `err` is null or points
/// to `err_len` writable bytes.
#[no_mangle]
pub unsafe extern "C" fn exo_plant_drive_open(
    run_file: *const c_char,
    err: *mut c_char,
    err_len: usize,
) -> *mut ExoPlantDrive {
    if run_file.is_null() {
        // SAFETY: as the caller promised.
        unsafe { write_error(err, err_len, "exo_plant_drive_open: run_file is null") };
        return std::ptr::null_mut();
    }
    // SAFETY: as the caller promised.
    let path = unsafe { CStr::from_ptr(run_file) }
        .to_string_lossy()
        .into_owned();
    let opened = catch_unwind(|| ExoPlantDrive::open(Path::new(&path)));
    match opened {
        Ok(Ok(plant)) => Box::into_raw(Box::new(plant)),
        Ok(Err(message)) => {
            // SAFETY: as the caller promised.
            unsafe { write_error(err, err_len, &message) };
            std::ptr::null_mut()
        }
        Err(_) => {
            // SAFETY: as the caller promised.
            unsafe { write_error(err, err_len, "exo_plant_drive_open: panic in the plant") };
            std::ptr::null_mut()
        }
    }
}

/// The readings of the current step into `out`, without stepping.
///
/// # Safety
/// `plant` is null or a handle of [`exo_plant_drive_open`] not yet closed;
/// `out` is null or points to a writable `ExoPlantReadings`.
#[no_mangle]
pub unsafe extern "C" fn exo_plant_drive_read(
    plant: *mut ExoPlantDrive,
    out: *mut ExoPlantReadings,
) -> i32 {
    // SAFETY: as the caller promised.
    let (Some(plant), Some(out)) = (unsafe { plant.as_mut() }, unsafe { out.as_mut() }) else {
        return EXO_PLANT_DRIVE_NULL;
    };
    match catch_unwind(AssertUnwindSafe(|| plant.readings())) {
        Ok(r) => {
            *out = r;
            EXO_PLANT_DRIVE_OK
        }
        Err(_) => EXO_PLANT_DRIVE_PANIC,
    }
}

/// One control period of the plant with motor torque `tau_motor_nm` (Nm)
/// held (0 unless `enabled` is non-zero); the readings at its end into
/// `out`. A NaN or infinite torque is refused
/// ([`EXO_PLANT_DRIVE_NOT_FINITE`]) and the plant not stepped.
///
/// # Safety
/// As [`exo_plant_drive_read`].
#[no_mangle]
pub unsafe extern "C" fn exo_plant_drive_step(
    plant: *mut ExoPlantDrive,
    tau_motor_nm: f64,
    enabled: u8,
    out: *mut ExoPlantReadings,
) -> i32 {
    // SAFETY: as the caller promised.
    let (Some(plant), Some(out)) = (unsafe { plant.as_mut() }, unsafe { out.as_mut() }) else {
        return EXO_PLANT_DRIVE_NULL;
    };
    match catch_unwind(AssertUnwindSafe(|| plant.step(tau_motor_nm, enabled != 0))) {
        Ok(Ok(r)) => {
            *out = r;
            EXO_PLANT_DRIVE_OK
        }
        Ok(Err(code)) => code,
        Err(_) => EXO_PLANT_DRIVE_PANIC,
    }
}

/// Closes a handle of [`exo_plant_drive_open`] (null: nothing).
///
/// # Safety
/// `plant` is null or a handle not yet closed; it is not used afterwards.
#[no_mangle]
pub unsafe extern "C" fn exo_plant_drive_close(plant: *mut ExoPlantDrive) {
    if !plant.is_null() {
        // SAFETY: made by Box::into_raw in exo_plant_drive_open, closed once.
        let _ = catch_unwind(AssertUnwindSafe(|| drop(unsafe { Box::from_raw(plant) })));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_file() -> std::ffi::CString {
        let path = exo_config::configs_dir().join("ethercat-exo.toml");
        std::ffi::CString::new(path.to_str().unwrap()).unwrap()
    }

    fn open() -> *mut ExoPlantDrive {
        let mut err = [0 as c_char; 256];
        // SAFETY: a NUL-terminated path and a buffer of its length.
        let p = unsafe { exo_plant_drive_open(run_file().as_ptr(), err.as_mut_ptr(), err.len()) };
        assert!(!p.is_null(), "{:?}", unsafe {
            CStr::from_ptr(err.as_ptr())
        });
        p
    }

    #[test]
    fn a_step_is_one_control_period_with_the_torque_only_when_enabled() {
        let p = open();
        let mut r = ExoPlantReadings::default();
        // SAFETY: a handle of open, a readings struct.
        unsafe {
            assert_eq!(exo_plant_drive_read(p, &mut r), EXO_PLANT_DRIVE_OK);
            assert_eq!(r.t_s, 0.0);
            assert_eq!(r.period_s, 1e-3, "the run file's 1 kHz");
            assert_eq!(exo_plant_drive_step(p, 2.0, 0, &mut r), EXO_PLANT_DRIVE_OK);
            assert!((r.t_s - 1e-3).abs() < 1e-12);
            assert_eq!(r.tau_motor_nm, 0.0, "disabled: no torque");
            assert_eq!(exo_plant_drive_step(p, 2.0, 1, &mut r), EXO_PLANT_DRIVE_OK);
            assert_eq!(r.tau_motor_nm, 2.0);
            assert!((r.t_s - 2e-3).abs() < 1e-12);
            exo_plant_drive_close(p);
        }
    }

    #[test]
    fn a_torque_that_is_not_finite_is_refused_and_the_plant_not_stepped() {
        let p = open();
        let mut r = ExoPlantReadings::default();
        // SAFETY: a handle of open, a readings struct.
        unsafe {
            assert_eq!(exo_plant_drive_step(p, 1.0, 1, &mut r), EXO_PLANT_DRIVE_OK);
            let before = r;
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                assert_eq!(
                    exo_plant_drive_step(p, bad, 1, &mut r),
                    EXO_PLANT_DRIVE_NOT_FINITE
                );
                assert_eq!(r, before, "out untouched");
            }
            assert_eq!(exo_plant_drive_read(p, &mut r), EXO_PLANT_DRIVE_OK);
            assert_eq!((r.t_s, r.tau_motor_nm), (before.t_s, 1.0), "not stepped");
            exo_plant_drive_close(p);
        }
    }

    #[test]
    fn the_c_header_declares_the_same_codes() {
        let header = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cpp/exo_plant_drive.h"),
        )
        .unwrap();
        let defined = |name: &str| -> i32 {
            let line = header
                .lines()
                .find(|l| l.starts_with(&format!("#define {name} ")))
                .unwrap_or_else(|| panic!("{name} not in the header"));
            let value = line[name.len() + 9..].trim().trim_matches(['(', ')']);
            value.parse().unwrap_or_else(|_| panic!("{line}"))
        };
        assert_eq!(defined("EXO_PLANT_DRIVE_OK"), EXO_PLANT_DRIVE_OK);
        assert_eq!(defined("EXO_PLANT_DRIVE_NULL"), EXO_PLANT_DRIVE_NULL);
        assert_eq!(
            defined("EXO_PLANT_DRIVE_NOT_FINITE"),
            EXO_PLANT_DRIVE_NOT_FINITE
        );
        assert_eq!(defined("EXO_PLANT_DRIVE_IPC"), EXO_PLANT_DRIVE_IPC);
        assert_eq!(defined("EXO_PLANT_DRIVE_PANIC"), EXO_PLANT_DRIVE_PANIC);
    }

    #[test]
    fn null_pointers_are_refused() {
        let mut r = ExoPlantReadings::default();
        let p = open();
        // SAFETY: null pointers are what is tested; the handle is open's.
        unsafe {
            let null = std::ptr::null_mut();
            assert_eq!(
                exo_plant_drive_step(null, 0.0, 1, &mut r),
                EXO_PLANT_DRIVE_NULL
            );
            assert_eq!(exo_plant_drive_read(null, &mut r), EXO_PLANT_DRIVE_NULL);
            assert_eq!(
                exo_plant_drive_step(p, 0.0, 1, std::ptr::null_mut()),
                EXO_PLANT_DRIVE_NULL
            );
            assert_eq!(
                exo_plant_drive_read(p, std::ptr::null_mut()),
                EXO_PLANT_DRIVE_NULL
            );
            assert!(exo_plant_drive_open(std::ptr::null(), std::ptr::null_mut(), 0).is_null());
            exo_plant_drive_close(null);
            exo_plant_drive_close(p);
        }
    }

    #[test]
    fn a_bad_run_file_is_named_in_the_error() {
        let missing = std::ffi::CString::new("/nonexistent/run.toml").unwrap();
        let mut err = [0 as c_char; 256];
        // SAFETY: a NUL-terminated path and a buffer of its length.
        let p = unsafe { exo_plant_drive_open(missing.as_ptr(), err.as_mut_ptr(), err.len()) };
        assert!(p.is_null());
        // SAFETY: write_error NUL-terminated it.
        let text = unsafe { CStr::from_ptr(err.as_ptr()) }
            .to_string_lossy()
            .into_owned();
        assert!(text.contains("/nonexistent/run.toml"), "{text}");
        // A buffer too short for the message gets it cut, NUL-terminated.
        let mut short = [1 as c_char; 8];
        // SAFETY: as above.
        let p = unsafe { exo_plant_drive_open(missing.as_ptr(), short.as_mut_ptr(), short.len()) };
        assert!(p.is_null());
        assert_eq!(short[7], 0);
        // SAFETY: NUL-terminated at 7.
        assert_eq!(
            unsafe { CStr::from_ptr(short.as_ptr()) }.to_bytes().len(),
            7
        );
    }
}
