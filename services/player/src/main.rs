//! `exo-player`: a recording played back onto the run's channels
//! ([`exo_player::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_player::process::PlayerProcess>()
}
