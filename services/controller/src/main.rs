//! `exo-controller`: answers every `SensorSample` with one `ActuatorCommand`
//! and publishes the protocol state ([`exo_controller::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_controller::process::ControllerProcess>()
}
