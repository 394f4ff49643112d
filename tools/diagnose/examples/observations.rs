//! Prints every observation the diagnosis reduces a set of recordings to,
//! one line each (`file experiment period tf ω re im σ_re σ_im`): the raw
//! material for checking the per-window noise estimate against the
//! scatter over repeated recordings (docs/diagnose.md, "The noise model").
//!
//! `cargo run --release -p exo-diagnose --example observations -- A.mcap B.mcap …`

use std::path::Path;

use exo_diagnose::data::{reduce, Reduction};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    println!("file\texperiment\tperiod\ttf\tomega\tre\tim\tsigma_re\tsigma_im");
    for arg in std::env::args().skip(1) {
        let rec =
            exo_recording::read_recording(Path::new(&arg)).map_err(|e| format!("{arg}: {e}"))?;
        let d = reduce(&[rec], &Reduction::default());
        for o in &d.observations {
            let c = &d.conditions[o.window];
            println!(
                "{arg}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}",
                c.experiment,
                c.period,
                o.tf.name(),
                o.omega_rad_s,
                o.value.re,
                o.value.im,
                o.sigma[0],
                o.sigma[1]
            );
        }
    }
    Ok(())
}
