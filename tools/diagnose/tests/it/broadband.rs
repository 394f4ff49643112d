//! A broadband window's observations and their standard deviations: a
//! recording written here (white θ_e, τ_c = K θ_e plus white noise), so the
//! truth is S_h(jω) = K at every ω, and the σ each band carries must
//! describe the band's actual scatter about K (z = error/σ standard normal:
//! mean z² near 1).

use crate::common;

use common::normals;
use exo_diagnose::{reduce, Reduction, Tf};
use exo_messages::{ProtocolState, SensorSample};
use exo_recording::Recording;

/// K of the written human (Nm/rad).
const K_NM_PER_RAD: f64 = 50.0;

/// 120 s at 1 kHz, one analysis window (phase 3) from the first sample to
/// the end, amplitude 0 and ω 0 (broadband). θ_e: white, σ 0.05 rad;
/// τ_c = K θ_e + white noise σn 2 Nm: coherence K²σθ²/(K²σθ² + σn²)
/// = 6.25/10.25 = 0.61 at every ω, above the 0.5 floor.
fn recording(seed: u64) -> Recording {
    let n = 120_000;
    let theta = normals(seed, n);
    let noise = normals(seed + 1000, n);
    let mut r = Recording {
        source: "broadband-written".into(),
        ..Default::default()
    };
    r.protocol.push(ProtocolState {
        experiment: 1,
        period: 1,
        phase: 3,
        alpha: 1.0,
        stamp_ns: 0,
        ..Default::default()
    });
    for i in 0..n {
        let th = 0.05 * theta[i];
        r.sensor.push(SensorSample {
            seq: i as u64,
            stamp_ns: i as u64 * 1_000_000,
            theta_e: th,
            tau_c: K_NM_PER_RAD * th + 2.0 * noise[i],
            tau_s: 0.0,
            ..Default::default()
        });
    }
    r
}

#[test]
fn broadband_bands_carry_the_standard_deviation_of_their_scatter() {
    let (mut sum_z2, mut count) = (0.0, 0usize);
    for seed in [3u64, 5, 7] {
        let d = reduce(&[recording(seed)], &Reduction::default());
        let sh: Vec<_> = d.observations.iter().filter(|o| o.tf == Tf::Sh).collect();
        assert!(
            sh.len() >= 10,
            "seed {seed}: {} broadband S_h points (notes: {:?})",
            sh.len(),
            d.notes
        );
        for o in &sh {
            let (re, im) = (o.value.re - K_NM_PER_RAD, o.value.im);
            assert!(
                o.sigma[0] > 0.0 && o.sigma[0] == o.sigma[1],
                "σ per component, equal: {:?}",
                o.sigma
            );
            sum_z2 += (re / o.sigma[0]).powi(2) + (im / o.sigma[1]).powi(2);
            count += 2;
        }
    }
    let mean_z2 = sum_z2 / count as f64;
    eprintln!("mean z² = {mean_z2:.3} over {count} components");
    // z² of a standard normal has mean 1; over ≥ 60 components the mean's
    // standard deviation is ≤ √(2/60) = 0.18. H1's σ counts overlapping
    // segments as independent (about 10 % low), so the band is one-sided wide.
    assert!(
        (0.5..2.0).contains(&mean_z2),
        "mean z² = {mean_z2} over {count} components: the bands' σ does not describe their scatter"
    );
}
