//! `exo-recorder`: every channel of the run into one contract MCAP
//! ([`exo_recorder::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_recorder::process::RecorderProcess>()
}
