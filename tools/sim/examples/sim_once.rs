//! One in-process run of a configuration with a sink that only counts, for
//! profiling the nodes (`perf record`, `perf stat`) without the benchmark's
//! other jobs:
//!
//! ```text
//! cargo build --release -p exo-sim --example sim_once
//! perf stat -e instructions target/release/examples/sim_once configs/default.toml
//! ```

use exo_config::RunConfig;
use exo_plant_sim::PlantModel;
use exo_sim::Sim;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: sim_once CONFIG [--no-identifier]")?;
    let mut cfg = RunConfig::from_file(std::path::Path::new(&path))?;
    if std::env::args().any(|a| a == "--no-identifier") {
        cfg.services.identifier = false;
    }
    let model = PlantModel::from_file(&cfg.plant_model)?;
    let started = std::time::Instant::now();
    let mut sim = Sim::new(&cfg, &model)?;
    let mut n = 0u64;
    sim.run(|_| -> Result<(), std::convert::Infallible> {
        n += 1;
        Ok(())
    })?;
    let wall = started.elapsed().as_secs_f64();
    let sim_s = sim.plant().tick() as f64 * sim.plant().period_ns() as f64 * 1e-9;
    println!(
        "{n} records, {sim_s:.1} s simulated in {wall:.3} s: {:.0}× real time",
        sim_s / wall
    );
    Ok(())
}
