//! Prints every observation's residual after the nominal refit, against the
//! measured noise alone (no accuracy floor): `experiment period tf ω
//! |data/model|−1 (%) arg(data/model) (°) z_re z_im model−data θ₀ A σ |data|
//! free_z_re free_z_im noise_share share_dof accuracy` (z: the line's residual over its σ, as judged;
//! free_z: the same of the transient-free value over its own σ,
//! `Observation::transient_free`, NaN where the window allows none;
//! noise_share: the noise beside the line over its white σ,
//! `TransientFree::local_noise`, with its degrees of freedom; accuracy: the
//! fraction of `|value|` the refit holds it to, `fit::model_accuracy`). The
//! raw material for calibrating the noise model and for locating a
//! generator's systematic (docs/diagnose.md, "The noise model").
//!
//! `cargo run -p exo-diagnose --example residuals -- PLANT.toml [--holds-goal | --rig | --rig-horizontal] [--horizontal] REC.mcap`

use std::path::Path;

use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::{diagnose, Settings};
use exo_plant_model::PlantModel;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [plant, rest @ ..] = args.as_slice() else {
        return Err("usage: residuals PLANT.toml [--holds-goal | --rig | --rig-horizontal] [--horizontal] REC.mcap".into());
    };
    let mut model = PlantModel::from_file(Path::new(plant)).map_err(|e| format!("{plant}: {e}"))?;
    let mut recs = Vec::new();
    for a in rest {
        match a.as_str() {
            "--holds-goal" => exo_diagnose::bench::holds_goal(&mut model),
            "--rig" => exo_diagnose::bench::independent_rig(&mut model, false),
            "--rig-horizontal" => exo_diagnose::bench::independent_rig(&mut model, true),
            "--horizontal" => model.gravity.enabled = false,
            f => recs.push(
                exo_recording::read_recording(Path::new(f)).map_err(|e| format!("{f}: {e}"))?,
            ),
        }
    }
    let d = reduce(&recs, &Reduction::default());
    let r = diagnose(&d, &model, &Settings::default())?;
    let phys = &r.refit_physics;
    println!("experiment\tperiod\ttf\tomega\tmag_pct\tphase_deg\tz_re\tz_im\tres_re\tres_im\ttheta0\ttheta_amp\tsigma_re\tsigma_im\tabs_value\tfree_z_re\tfree_z_im\tnoise_share\tshare_dof\taccuracy");
    for o in &d.observations {
        let c = &d.conditions[o.window];
        let m = phys.predict(o, c);
        let q = o.value / m;
        let res = o.value - m;
        let free = o
            .transient_free
            .map_or(num_complex::Complex64::new(f64::NAN, f64::NAN), |f| {
                let r = f.value - m;
                num_complex::Complex64::new(r.re / f.sigma[0], r.im / f.sigma[1])
            });
        let share = o
            .transient_free
            .and_then(|t| t.local_noise)
            .map_or((f64::NAN, 0), |l| (l.ratio, l.dof));
        println!(
            "{}\t{}\t{}\t{:.3}\t{:+.3}\t{:+.3}\t{:+.2}\t{:+.2}\t{:+.4}\t{:+.4}\t{:.4}\t{:.4}\t{:.3e}\t{:.3e}\t{:.4e}\t{:+.2}\t{:+.2}\t{:.3}\t{}\t{:.2e}",
            c.experiment,
            c.period,
            o.tf.name(),
            o.omega_rad_s,
            100.0 * (q.norm() - 1.0),
            q.arg().to_degrees(),
            res.re / o.sigma[0].max(1e-12),
            res.im / o.sigma[1].max(1e-12),
            -res.re,
            -res.im,
            c.theta0_rad,
            c.theta_amp_rad,
            o.sigma[0],
            o.sigma[1],
            o.value.norm(),
            free.re,
            free.im,
            share.0,
            share.1,
            exo_diagnose::fit::model_accuracy(phys, o),
        );
    }
    Ok(())
}
