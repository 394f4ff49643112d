use std::time::Instant;
fn main() {
    let path = std::env::args().nth(1).unwrap();
    let cfg = exo_config::RunConfig::from_file(std::path::Path::new(&path)).unwrap();
    let model = exo_plant_sim::PlantModel::from_file(&cfg.plant_model).unwrap();
    let mut sim = exo_sim::Sim::new(&cfg, &model).unwrap();
    let t = Instant::now();
    let mut n = 0u64;
    sim.run(|_r| -> Result<(), ()> {
        n += 1;
        Ok(())
    })
    .unwrap();
    let wall = t.elapsed().as_secs_f64();
    let sim_s = sim.plant().tick() as f64 * 1e-3;
    println!(
        "null sink: {n} msgs, {sim_s} s in {wall:.3} s = {:.0}x",
        sim_s / wall
    );
}
