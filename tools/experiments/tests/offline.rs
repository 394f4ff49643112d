//! `exo fit`'s pipeline (`exo_experiments::offline`) on contract recordings
//! written by this test: a human whose complex stiffness is written out
//! here (S_h = K − M_h ω² + jH, the paper's M2 with an inertia), seen
//! through the exoskeleton's physics τ_s − τ_g = τ_c + M_e θ̈, with sensor
//! noise. What `fit` reports is checked against those numbers, and the
//! recordings' defects (no rate, no commands, no protocol, a cuff-only
//! record fitted from the actuator) against the warnings they must give.

use std::collections::BTreeMap;
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use exo_experiments::offline::{fit, FitOptions};
use exo_identifier::FitSource;
use exo_messages::{ActuatorCommand, ProtocolPhase, ProtocolState, SensorSample};
use exo_recording::RecordingWriter;

const RATE_HZ: f64 = 1000.0;
/// Exoskeleton inertia without load, load and lever arm: M_e = 0.1 + 4.5 · 0.45² kg·m².
const ARM_KG_M2: f64 = 0.1;
const LOAD_KG: f64 = 4.5;
const LEVER_M: f64 = 0.45;
const AMP_RAD: f64 = 0.03;
const POSTURE_RAD: f64 = 0.6;
/// Human inertia M_h (kg·m²).
const M_H: f64 = 0.11;
/// Sensor noise (Nm, standard deviation) on τ_c and τ_s.
const NOISE_NM: f64 = 0.02;

/// The experiments: (number, K_h, H_h) in Nm/rad.
const HUMANS: [(u32, f64, f64); 2] = [(1, 30.0, 6.0), (2, 80.0, 12.0)];
/// Five frequencies, 2 · 10^(0.2 k) rad/s.
fn omega(period: u32) -> f64 {
    2.0 * 10f64.powf(0.2 * (period - 1) as f64)
}

/// What the generated recording leaves out.
#[derive(Clone, Copy, Default)]
struct Defects {
    no_rate: bool,
    no_commands: bool,
    no_protocol: bool,
    cuff_only: bool,
}

struct Noise(u64);
impl Noise {
    fn gauss(&mut self) -> f64 {
        let mut u = || {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (a, b) = (u(), u());
        (-2.0 * a.ln()).sqrt() * (TAU * b).cos()
    }
}

fn write_recording(dir: &Path, name: &str, d: Defects) -> PathBuf {
    let path = dir.join(format!("{name}.mcap"));
    let mut w = RecordingWriter::create(&path).unwrap();
    w.register_contract().unwrap();
    let mut meta = BTreeMap::from([
        ("subject".to_string(), "synthetic".to_string()),
        ("arm_inertia_kg_m2".to_string(), ARM_KG_M2.to_string()),
        ("load_lever_arm_m".to_string(), LEVER_M.to_string()),
    ]);
    if !d.no_rate {
        meta.insert("rate_hz".into(), RATE_HZ.to_string());
    }
    if d.cuff_only {
        meta.insert("fit_target".into(), "human".into());
    }
    w.write_run_info(&meta, "# written by services/identifier/tests/offline.rs\n")
        .unwrap();
    let m_e = ARM_KG_M2 + LOAD_KG * LEVER_M * LEVER_M;
    let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
    let mut tick: u64 = 0;
    let schedule = [
        (ProtocolPhase::RampIn, 0.5),
        (ProtocolPhase::Settling, 2.0),
        (ProtocolPhase::Analysis, 6.0),
        (ProtocolPhase::RampOut, 0.5),
        (ProtocolPhase::Rest, 0.5),
    ];
    for (experiment, k, h) in HUMANS {
        for period in 1..=5 {
            let w_rad_s = omega(period);
            let s_h_re = k - M_H * w_rad_s * w_rad_s;
            let mut start = 0;
            for (phase, secs) in schedule {
                if phase == ProtocolPhase::Settling {
                    start = tick;
                }
                let state = ProtocolState {
                    experiment,
                    period,
                    phase: phase.as_u32(),
                    omega: w_rad_s,
                    amplitude: 1.0,
                    alpha: 1.0,
                    load_kg: LOAD_KG,
                    stamp_ns: tick * 1_000_000,
                    ..Default::default()
                };
                if !d.no_protocol {
                    w.write(&state).unwrap();
                }
                for _ in 0..(secs * RATE_HZ) as u64 {
                    let stamp_ns = tick * 1_000_000;
                    let excited =
                        matches!(phase, ProtocolPhase::Settling | ProtocolPhase::Analysis);
                    let t = (tick - start) as f64 / RATE_HZ;
                    let (sin, cos) = if excited {
                        (w_rad_s * t).sin_cos()
                    } else {
                        (0.0, 0.0)
                    };
                    // θ = θ0 + A sin ωt; τ_c = Im(S_h A e^{jωt}).
                    let theta = POSTURE_RAD + AMP_RAD * sin;
                    let theta_ddot = -w_rad_s * w_rad_s * AMP_RAD * sin;
                    let tau_c_true = AMP_RAD * (s_h_re * sin + h * cos);
                    let tau_g = 20.0 * theta.sin();
                    let tau_s_true = tau_c_true + m_e * theta_ddot + tau_g;
                    let s = SensorSample {
                        seq: tick,
                        stamp_ns,
                        theta_e: theta,
                        omega_e: w_rad_s * AMP_RAD * cos,
                        tau_c: tau_c_true + NOISE_NM * noise.gauss(),
                        tau_s: tau_s_true + NOISE_NM * noise.gauss(),
                        ..Default::default()
                    };
                    w.write(&s).unwrap();
                    if !d.no_commands && !d.cuff_only {
                        w.write(&ActuatorCommand {
                            seq: tick,
                            stamp_ns,
                            sensor_seq: tick,
                            tau_d: tau_s_true,
                            tau_gravity: tau_g,
                            ..Default::default()
                        })
                        .unwrap();
                    }
                    tick += 1;
                }
            }
        }
    }
    w.finish().unwrap();
    path
}

fn scratch(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("exo-offline-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn warnings_of(path: &Path, source: FitSource) -> (exo_analysis::study::FitReport, Vec<String>) {
    let options = FitOptions {
        fit_source: source,
        ..FitOptions::for_recordings(vec![path.into()])
    };
    let (loaded, report) =
        fit(&options, &mut |_| {}).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
    let mut w: Vec<String> = report.warnings.clone();
    for l in &loaded {
        w.extend(l.recording.warnings.iter().cloned());
    }
    (report, w)
}

#[test]
fn fit_recovers_the_written_human_from_either_side() {
    let dir = scratch("whole");
    let path = write_recording(&dir, "whole", Defects::default());
    // The cuff's S_h (the paper's choice, the default) and the actuator
    // side with M_e removed see the same human.
    for (source, name) in [
        (FitSource::CuffTorque, "cuff"),
        (FitSource::ActuatorTorque, "actuator"),
    ] {
        fits_the_written_human(&path, source, name);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn fits_the_written_human(path: &Path, source: FitSource, name: &str) {
    let (report, warnings) = warnings_of(path, source);
    assert_eq!(report.subjects.len(), 1, "{warnings:?}");
    let subject = &report.subjects[0];
    assert_eq!(subject.subject, "synthetic");
    assert_eq!(subject.experiments.len(), 2);
    for ((n, k, h), e) in HUMANS.iter().zip(&subject.experiments) {
        assert_eq!(e.experiment, *n);
        assert_eq!(e.fit_source, name);
        assert_eq!(e.points.len(), 5, "experiment {n}: one point per period");
        // M_e from the recording's rig metadata and the protocol's load.
        assert!((e.m_e_kg_m2 - (ARM_KG_M2 + LOAD_KG * LEVER_M * LEVER_M)).abs() < 1e-12);
        let m3 = &e.models["M3"];
        let se = m3.std_errors.expect("standard errors");
        for (param, got, want, se) in [
            ("K", m3.k, *k, se[0]),
            ("H", m3.h, *h, se[1]),
            ("M", m3.m, M_H, se[3]),
        ] {
            assert!(
                (got - want).abs() < 4.0 * se && se < 0.05 * want.abs(),
                "{name}, experiment {n}: {param} = {got} ± {se}, written {want}"
            );
        }
    }
    // The power law through the two experiments' M2 (K, H): the slope of
    // log H against log K, written out from the numbers above.
    let beta1_true = (12.0f64 / 6.0).ln() / (80.0f64 / 30.0).ln();
    let beta1 = subject.beta1.expect("a power law from two experiments");
    assert!(
        (beta1 - beta1_true).abs() < 0.05,
        "β1 = {beta1}, written {beta1_true}"
    );
    assert!(
        !warnings
            .iter()
            .any(|w| w.contains("missing") || w.contains("assumed")),
        "a whole recording gives no such warning: {warnings:?}"
    );
}

#[test]
fn each_defect_of_a_recording_is_named_and_the_rest_still_fits() {
    // Without its rate the rate comes from the stamps, and the fit is the
    // same as with it.
    let dir = scratch("defects");
    let whole = write_recording(&dir, "whole", Defects::default());
    let no_rate = write_recording(
        &dir,
        "norate",
        Defects {
            no_rate: true,
            ..Defects::default()
        },
    );
    let (a, _) = warnings_of(&whole, FitSource::ActuatorTorque);
    let (b, _) = warnings_of(&no_rate, FitSource::ActuatorTorque);
    for (x, y) in a.subjects[0]
        .experiments
        .iter()
        .zip(&b.subjects[0].experiments)
    {
        assert_eq!(x.models["M2"].k, y.models["M2"].k);
        assert_eq!(x.models["M2"].h, y.models["M2"].h);
    }

    // No commands: fitted from the actuator side, which then keeps τ_s's
    // gravity part; said so.
    let p = write_recording(
        &dir,
        "nocmd",
        Defects {
            no_commands: true,
            ..Defects::default()
        },
    );
    let (_, w) = warnings_of(&p, FitSource::ActuatorTorque);
    assert!(
        w.iter().any(|w| w.contains("topic exo/command is missing")),
        "{w:?}"
    );

    // A cuff-only record: fitted from the cuff's S_h, and said so.
    let p = write_recording(
        &dir,
        "cuff",
        Defects {
            cuff_only: true,
            ..Defects::default()
        },
    );
    let (r, w) = warnings_of(&p, FitSource::ActuatorTorque);
    assert!(
        w.iter().any(|w| w.contains("fitted from the cuff's S_h")),
        "{w:?}"
    );
    for ((n, k, _), e) in HUMANS.iter().zip(&r.subjects[0].experiments) {
        assert_eq!(e.fit_source, "cuff", "experiment {n}");
        let m3 = &e.models["M3"];
        assert!((m3.k - k).abs() < 0.05 * k, "experiment {n}: K = {}", m3.k);
    }

    // No protocol: no analysis window can be found, and that is named.
    let p = write_recording(
        &dir,
        "noproto",
        Defects {
            no_protocol: true,
            ..Defects::default()
        },
    );
    let options = FitOptions {
        fit_source: FitSource::ActuatorTorque,
        ..FitOptions::for_recordings(vec![p.clone()])
    };
    let w = match fit(&options, &mut |_| {}) {
        Ok((loaded, report)) => {
            let mut w = report.warnings;
            for l in &loaded {
                w.extend(l.recording.warnings.iter().cloned());
            }
            w
        }
        Err(e) => vec![format!("{e:#}")],
    };
    assert!(
        w.iter()
            .any(|w| w.contains("topic exo/protocol is missing or empty")),
        "{w:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_options_are_refused_naming_the_flag() {
    let base = FitOptions::for_recordings(vec![PathBuf::from("/nonexistent.mcap")]);
    let cases: Vec<(&str, FitOptions)> = vec![
        (
            "--level",
            FitOptions {
                level: 0.0,
                ..base.clone()
            },
        ),
        (
            "--level",
            FitOptions {
                level: 1.0,
                ..base.clone()
            },
        ),
        (
            "--level",
            FitOptions {
                level: f64::NAN,
                ..base.clone()
            },
        ),
        (
            "--phase-margin-deg",
            FitOptions {
                phase_margin_deg: 0.0,
                ..base.clone()
            },
        ),
        (
            "--phase-margin-deg",
            FitOptions {
                phase_margin_deg: 90.0,
                ..base.clone()
            },
        ),
        (
            "--k-range",
            FitOptions {
                k_range: Some([0.0, 10.0]),
                ..base.clone()
            },
        ),
        (
            "--k-range",
            FitOptions {
                k_range: Some([10.0, 10.0]),
                ..base.clone()
            },
        ),
        (
            "--k-range",
            FitOptions {
                k_range: Some([10.0, f64::INFINITY]),
                ..base.clone()
            },
        ),
    ];
    for (flag, o) in cases {
        let e = fit(&o, &mut |_| {}).err().map(|e| format!("{e:#}"));
        let e = e.unwrap_or_else(|| panic!("{flag} not refused"));
        assert!(e.starts_with(flag), "{flag}: {e}");
    }
    // Inside the ranges, the options pass and the missing file is named.
    let e = format!("{:#}", fit(&base, &mut |_| {}).err().unwrap());
    assert!(e.contains("/nonexistent.mcap"), "{e}");
}
