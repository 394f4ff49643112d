//! `exo-live`: every channel of the run to Foxglove, live
//! ([`exo_live::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_live::process::LiveProcess>()
}
