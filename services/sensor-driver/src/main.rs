//! `exo-sensor-driver`: owns the actuator; raw bus frames in, calibrated
//! samples out, the controller's torque (or the safe state's) back to the
//! bus ([`exo_sensor_driver::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_sensor_driver::process::DriverProcess>()
}
