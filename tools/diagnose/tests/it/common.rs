//! Set-up the diagnosis tests share: the default plant and the protocol's
//! periods for a list of experiments, and deterministic normal samples.
//! Each test module uses some of them.
#![allow(dead_code)]

use std::path::PathBuf;

use exo_diagnose::synth::SynthPeriod;
use exo_plant_model::PlantModel;

/// `configs/plants/default.toml`.
pub fn default_plant() -> PlantModel {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../configs/plants/default.toml");
    PlantModel::from_file(&p).expect("default plant")
}

/// Ten periods per experiment `(number, K_h, H_h, load kg, bias Nm)`, the
/// protocol's: ω from 2 rad/s in steps of 10^0.1, the amplitude 10^0.2×
/// higher at periods 8–10.
pub fn protocol(experiments: &[(u32, f64, f64, f64, f64)]) -> Vec<SynthPeriod> {
    let mut v = Vec::new();
    for &(e, k, h, load, bias) in experiments {
        for n in 0..10 {
            v.push(SynthPeriod {
                experiment: e,
                period: n + 1,
                omega_rad_s: 2.0 * 10f64.powf(0.1 * n as f64),
                amplitude_nm: if n >= 7 { 2.0 * 10f64.powf(0.2) } else { 2.0 },
                k_h: k,
                h_h: h,
                load_kg: load,
                bias_nm: bias,
            });
        }
    }
    v
}

/// Deterministic standard normal samples (xorshift64* and Box–Muller).
pub fn normals(seed: u64, n: usize) -> Vec<f64> {
    let mut x = seed;
    let mut uniform = || {
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        ((x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (u, v) = (uniform(), uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        })
        .collect()
}
