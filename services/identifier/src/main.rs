//! `exo-identifier`: identifies the run online and publishes its FRF points
//! and estimates ([`exo_identifier::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_identifier::process::IdentifierProcess>()
}
