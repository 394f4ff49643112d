//! `exo-plant-sim`: the physical world as a process, on the simulated bus
//! ([`exo_plant_sim::process`]).

fn main() {
    exo_service_kit::runner::main::<exo_plant_sim::process::PlantProcess>()
}
