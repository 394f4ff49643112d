//! The bench of `exo diagnose-bench`: the mismatch finder proven on
//! concealed effects. This module has the cases and what a case's diagnosis
//! scores; the tool simulates, diagnoses and prints.
//!
//! Each case is a true plant model (the default plant with one effect, two
//! effects, or only parameter changes and another noise seed) and a nominal
//! model. The case's subject runs through the real processes in lockstep
//! with the true plant (`configs/diagnose-bench.toml`), is recorded, and
//! `exo diagnose` compares the recording with the nominal model. The table
//! is the confusion of the true effects against the named ones, with the
//! fit improvement. Everything is generated from seeds; nothing large is
//! committed.

use exo_config::Subject;
use exo_plant_model::PlantModel;
use serde::Serialize;

use crate::{Diagnosis, Term};

/// One benchmark case.
pub struct Case {
    /// Name.
    pub name: &'static str,
    /// What is concealed and how.
    pub what: &'static str,
    /// Terms the truth has and the nominal model lacks.
    pub expected: Vec<Term>,
    /// Makes the true plant from the default one.
    /// Makes the true plant from the default one, the effect's size times
    /// the scale (`--scale`; hysteresis, the subject's own, is not scaled).
    pub truth: fn(&mut PlantModel, &Subject, f64),
    /// Makes the nominal model from the default one.
    pub nominal: fn(&mut PlantModel, &Subject),
}

fn same(_: &mut PlantModel, _: &Subject) {}

fn same_truth(_: &mut PlantModel, _: &Subject, _: f64) {}

/// A horizontal rig: no gravity turns the joint (`exo diagnose-bench` runs
/// a case whose true plant has none with `rig.gravity_m_s2 = 0`).
fn horizontal(m: &mut PlantModel, _: &Subject) {
    m.gravity.enabled = false;
}

/// A subject that holds the arm at its goal against the bias, as the
/// independent rig's does (`tools/python/independent_rig.py`: a goal of 45°
/// on average): the nominal model of the rig's recordings.
pub fn holds_goal(m: &mut PlantModel) {
    m.human.posture_reference = exo_plant_model::PostureReference::HoldsGoal;
    m.human.active_angle_rad = std::f64::consts::FRAC_PI_4;
}

/// The independent rig's gravitational acceleration (m/s²): its own
/// constant (`G` in `tools/python/independent_rig.py`), not the standard
/// 9.80665 of `configs/plants/default.toml`. 0.034 % of the arm's gravity
/// moment (16 Nm at 45° with experiment 1's load) is 5 mNm, ten times the
/// static balance's noise.
pub const INDEPENDENT_RIG_G_M_S2: f64 = 9.81;

/// The nominal model of the independent rig's recordings from the default
/// plant: its subject's posture strategy ([`holds_goal`]), its gravity
/// ([`INDEPENDENT_RIG_G_M_S2`]) or none for a horizontal rig.
pub fn independent_rig(m: &mut PlantModel, horizontal: bool) {
    holds_goal(m);
    m.gravity.g_m_s2 = INDEPENDENT_RIG_G_M_S2;
    m.gravity.enabled = !horizontal;
}

fn viscous_truth(m: &mut PlantModel, s: &Subject, _: f64) {
    viscous_tuned(m, s)
}

/// A viscous human whose damping matches the subject's hysteretic damping
/// at the coupled system's resonance: the Bode magnitude peak agrees, only
/// the phase away from it (mostly at low frequency) betrays the difference.
fn viscous_tuned(m: &mut PlantModel, s: &Subject) {
    let n = s.experiment.len().max(1) as f64;
    let k = s
        .experiment
        .iter()
        .map(|e| e.stiffness_nm_per_rad)
        .sum::<f64>()
        / n;
    let h = s
        .experiment
        .iter()
        .map(|e| e.hysteretic_damping_nm_per_rad)
        .sum::<f64>()
        / n;
    let inertia = m.human.inertia_kg_m2 + m.exo_inertia_kg_m2(m.exo.load_kg);
    let w_r = (k / inertia).sqrt();
    m.human.hysteretic_damping.enabled = false;
    m.human.viscous_damping.enabled = true;
    m.human.viscous_damping.b_nm_s_per_rad = h / w_r;
}

/// Every case.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "hysteresis",
            what: "hysteretic damping behind a viscous nominal model tuned to the resonance peak",
            expected: vec![Term::HystereticDamping],
            truth: same_truth,
            nominal: viscous_tuned,
        },
        Case {
            name: "coulomb",
            what: "0.3 Nm Coulomb friction in the exoskeleton joint (like hysteresis at one amplitude)",
            expected: vec![Term::CoulombFriction],
            truth: |m, _, scale| {
                m.joint_friction.coulomb.enabled = true;
                m.joint_friction.coulomb.torque_nm = 0.3 * scale;
            },
            nominal: same,
        },
        Case {
            name: "delay",
            what: "a 5 ms encoder delay (a phase error of 0.6° at 2 rad/s)",
            expected: vec![Term::EncoderDelay],
            truth: |m, _, scale| m.sensors.encoder.terms.delay_s = 0.005 * scale,
            nominal: same,
        },
        Case {
            name: "cuff",
            what: "cuff compliance of 600 Nm/rad (visible near the top of the band)",
            expected: vec![Term::CuffCompliance],
            truth: |m, _, scale| {
                m.cuff.compliance.enabled = true;
                m.cuff.compliance.stiffness_nm_per_rad = 600.0 / scale;
                m.cuff.compliance.damping_nm_s_per_rad = 2.0;
            },
            nominal: same,
        },
        Case {
            name: "gravity",
            what: "the arm 30 % heavier than model and controller assume (a gravity-compensation error, shifting with posture under bias)",
            expected: vec![Term::GravityError],
            truth: |m, _, scale| m.gravity.arm_mass_kg *= 1.0 + 0.3 * scale,
            nominal: same,
        },
        Case {
            name: "two",
            what: "hysteretic damping behind a tuned viscous model, and a 5 ms encoder delay",
            expected: vec![Term::HystereticDamping, Term::EncoderDelay],
            truth: |m, _, scale| m.sensors.encoder.terms.delay_s = 0.005 * scale,
            nominal: viscous_tuned,
        },
        Case {
            name: "stiffening",
            what: "outside the catalogue: a stiffening human spring, K₃ = 120 Nm/rad³ about the held posture (the library's polynomial spring)",
            expected: vec![Term::CubicStiffness],
            truth: |m, _, scale| m.human.cubic_stiffness_nm_per_rad3 = 120.0 * scale,
            nominal: same,
        },
        Case {
            name: "stiffening-strong",
            what: "outside the catalogue: a stiffening human spring, K₃ = 400 Nm/rad³ about the held posture",
            expected: vec![Term::CubicStiffness],
            truth: |m, _, scale| m.human.cubic_stiffness_nm_per_rad3 = 400.0 * scale,
            nominal: same,
        },
        Case {
            name: "cubic-damper",
            what: "outside the catalogue: a cubic human damper, B₃ = 2 Nm·s³/rad³ (the library's cubic damper)",
            expected: vec![Term::CubicDamping],
            truth: |m, _, scale| m.human.cubic_damping_nm_s3_per_rad3 = 2.0 * scale,
            nominal: same,
        },
        Case {
            name: "posture",
            what: "outside the catalogue: a stiffness that depends on posture, dK/dθ = K₂ = 15 Nm/rad² (the library's posture form, in the 2nd harmonic of τ_c)",
            expected: vec![Term::PostureStiffness],
            truth: |m, _, scale| m.human.quadratic_stiffness_nm_per_rad2 = 15.0 * scale,
            nominal: same,
        },
        Case {
            name: "posture-strong",
            what: "outside the catalogue: a stiffness that depends on posture, K₂ = 50 Nm/rad²",
            expected: vec![Term::PostureStiffness],
            truth: |m, _, scale| m.human.quadratic_stiffness_nm_per_rad2 = 50.0 * scale,
            nominal: same,
        },
        Case {
            name: "drift",
            what: "outside the catalogue: the human's stiffness drifting by 5 % per minute within each experiment (the library's drift)",
            expected: vec![Term::StiffnessDrift],
            truth: |m, _, scale| m.human.stiffness_drift_per_min = 0.05 * scale,
            nominal: same,
        },
        Case {
            name: "drift-strong",
            what: "outside the catalogue: the human's stiffness drifting by 10 % per minute within each experiment",
            expected: vec![Term::StiffnessDrift],
            truth: |m, _, scale| m.human.stiffness_drift_per_min = 0.10 * scale,
            nominal: same,
        },
        Case {
            name: "backlash",
            what: "outside the catalogue, no form: 0.02 rad of lost motion in the joint's gear mesh; the arm is held up against gravity, the mesh never opens, nothing to find",
            expected: vec![],
            truth: |m, _, scale| m.exo.backlash.lash_rad = 0.02 * scale,
            nominal: same,
        },
        Case {
            name: "backlash-wide",
            what: "outside the catalogue, no form: 0.1 rad of lost motion in the joint's gear mesh, under the same gravity preload",
            expected: vec![],
            truth: |m, _, scale| m.exo.backlash.lash_rad = 0.1 * scale,
            nominal: same,
        },
        Case {
            name: "backlash-horizontal",
            what: "outside the catalogue: 0.05 rad of lost motion in the joint's gear mesh of a horizontal rig (no gravity, none compensated: the mesh opens where no bias holds it; the library's backlash form)",
            expected: vec![Term::Backlash],
            truth: |m, _, scale| {
                m.gravity.enabled = false;
                m.exo.backlash.lash_rad = 0.05 * scale;
            },
            nominal: horizontal,
        },
        Case {
            name: "backlash-horizontal-wide",
            what: "outside the catalogue: 0.1 rad of lost motion in the joint's gear mesh of a horizontal rig",
            expected: vec![Term::Backlash],
            truth: |m, _, scale| {
                m.gravity.enabled = false;
                m.exo.backlash.lash_rad = 0.1 * scale;
            },
            nominal: horizontal,
        },
        Case {
            name: "saturation",
            what: "the drive's torque limit at 28 Nm, 1 Nm below the largest command of the bench's protocol (experiment 7: bias 8 Nm on 17 Nm of gravity compensation): the peaks of experiment 7's larger amplitude are clipped",
            expected: vec![Term::ActuatorSaturation],
            truth: |m, _, scale| m.sea.torque_limit_nm = 29.0 - scale,
            nominal: same,
        },
        Case {
            name: "saturation-deep",
            what: "the drive's torque limit at 26.5 Nm, 2.5 Nm below the largest command: every period of experiment 7 clipped",
            expected: vec![Term::ActuatorSaturation],
            truth: |m, _, scale| m.sea.torque_limit_nm = 29.0 - 2.5 * scale,
            nominal: same,
        },
        Case {
            name: "posture-shift",
            what: "a static offset, no dynamic term: the subject's neutral angle 0.05 rad above the model's in every experiment (re-seated); nothing to name, the offset to locate",
            expected: vec![],
            truth: |m, _, scale| m.human.active_angle_rad += 0.05 * scale,
            nominal: same,
        },
        Case {
            name: "null-holds-goal",
            what: "no missing physics: a subject that holds the arm at its goal against the bias (`human.posture_reference = \"holds_goal\"`, the independent rig's strategy) and a model that says so, another seed",
            expected: vec![],
            truth: |m, _, _| {
                holds_goal(m);
                m.integration.seed = 17;
            },
            nominal: |m, _| holds_goal(m),
        },
        Case {
            name: "null-horizontal",
            what: "no missing physics: a horizontal rig (no gravity, none compensated) and its nominal model, another seed",
            expected: vec![],
            truth: |m, _, _| {
                m.gravity.enabled = false;
                m.integration.seed = 13;
            },
            nominal: horizontal,
        },
        Case {
            name: "null-seed",
            what: "no missing physics: the nominal model, another noise seed",
            expected: vec![],
            truth: |m, _, _| m.integration.seed = 7,
            nominal: same,
        },
        Case {
            name: "null-params",
            what: "no missing physics: forearm inertia +15 %, SEA bandwidth 8 Hz, another seed",
            expected: vec![],
            truth: |m, _, _| {
                m.human.inertia_kg_m2 *= 1.15;
                m.sea.dynamics.natural_frequency_hz = 8.0;
                m.integration.seed = 11;
            },
            nominal: same,
        },
        Case {
            name: "null-viscous",
            what: "no missing physics: a viscous human with a viscous nominal model",
            expected: vec![],
            truth: viscous_truth,
            nominal: viscous_tuned,
        },
    ]
}

/// One case's outcome.
#[derive(Debug, Serialize)]
pub struct Outcome {
    /// Case.
    pub case: String,
    /// What is concealed.
    pub what: String,
    /// Terms expected.
    pub expected: Vec<Term>,
    /// Terms named.
    pub named: Vec<Term>,
    /// Of those, the ones named only as partial ("partly explained by …":
    /// under half the misfit, structure remaining). They count as named.
    pub partial: Vec<Term>,
    /// The diagnosis' sentences.
    pub verdict: Vec<String>,
    /// Weighted RSS: nominal refitted, with the named terms.
    pub rss: [f64; 2],
    /// Held-out RSS change with the named terms (relative).
    pub heldout_change: f64,
    /// The naive look: the worst R² over the frequency responses of the
    /// nominal model with its own parameters refitted.
    pub r2_refit: f64,
    /// Named exactly the expected terms.
    pub correct: bool,
}

impl Outcome {
    /// The outcome of `case` diagnosed as `r`.
    pub fn new(c: &Case, r: &Diagnosis) -> Outcome {
        let named: Vec<Term> = r.found.iter().map(|f| f.term).collect();
        let mut e = c.expected.clone();
        let mut n = named.clone();
        e.sort();
        n.sort();
        Outcome {
            case: c.name.into(),
            what: c.what.into(),
            expected: c.expected.clone(),
            correct: e == n,
            named,
            partial: r
                .found
                .iter()
                .filter(|f| f.partial)
                .map(|f| f.term)
                .collect(),
            verdict: r.verdict.clone(),
            rss: [r.refit.rss, r.final_score.rss],
            heldout_change: r.final_score.heldout_rss / r.refit.heldout_rss - 1.0,
            r2_refit: r
                .refit
                .per_tf
                .iter()
                .filter(|t| t.tf.is_dynamic())
                .map(|t| t.r2)
                .fold(f64::INFINITY, f64::min),
        }
    }
}

/// A generator of null recordings for the false-alarm rate
/// (`exo diagnose-bench --nulls N`): nominal physics, implementations that
/// differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NullGenerator {
    /// Our simulator through the real processes in lockstep: a null case
    /// of [`cases`] at a sample rate (Hz).
    Simulator {
        /// The null case's name (`null-seed`, `null-params`, …).
        case: &'static str,
        /// `run.rate_hz`.
        rate_hz: f64,
    },
    /// The independent rig (`tools/python/independent_rig.py`, no code
    /// shared with ours) with these arguments, diagnosed against
    /// `configs/plants/default.toml` (gravity off for `--horizontal`).
    Rig {
        /// Short name.
        name: &'static str,
        /// Its arguments besides the output, seed and experiments.
        args: &'static [&'static str],
    },
}

impl NullGenerator {
    /// Its name in the table.
    pub fn name(&self) -> String {
        match self {
            NullGenerator::Simulator { case, rate_hz } => format!("sim {case} {rate_hz:.0} Hz"),
            NullGenerator::Rig { name, .. } => format!("rig {name}"),
        }
    }
}

/// The nulls' generators, taken in turn (null `i` uses generator `i mod
/// len`): our simulator's four null cases at 1 kHz and 500 Hz, and the
/// independent rig with each kind of human damping, 1 kHz, a coarse
/// encoder, another SEA discretisation, off-nominal inertia and SEA, more
/// noise, a horizontal rig, no voluntary twitch in the windows, and a
/// random subject of the seed. Only the generators of the kinds asked for
/// (`sim`, `rig`).
pub fn null_generators(sim: bool, rig: bool) -> Vec<NullGenerator> {
    let mut v = Vec::new();
    if sim {
        for rate_hz in [1000.0, 500.0] {
            for case in [
                "null-seed",
                "null-params",
                "null-viscous",
                "null-horizontal",
            ] {
                v.push(NullGenerator::Simulator { case, rate_hz });
            }
        }
    }
    if rig {
        let rigs: [(&'static str, &'static [&'static str]); 10] = [
            ("viscous human", &["--damping", "viscous"]),
            ("two-point human", &["--damping", "two-point"]),
            ("1 kHz", &["--damping", "viscous", "--rate-hz", "1000"]),
            ("14-bit encoder", &["--encoder-bits", "14"]),
            (
                "Tustin SEA",
                &["--damping", "viscous", "--sea-model", "tustin"],
            ),
            (
                "M_h ×1.2, 8 Hz SEA",
                &["--mass-scale", "1.2", "--sea-hz", "8"],
            ),
            ("noise ×2", &["--damping", "viscous", "--noise-scale", "2"]),
            ("horizontal", &["--horizontal"]),
            ("no twitch", &["--damping", "viscous", "--twitch", "0"]),
            ("random subject", &["--random-subject"]),
        ];
        for (name, args) in rigs {
            v.push(NullGenerator::Rig { name, args });
        }
    }
    v
}

/// What one null recording's diagnosis said.
#[derive(Debug, Clone, Serialize)]
pub struct NullOutcome {
    /// The generator's name ([`NullGenerator::name`]).
    pub generator: String,
    /// The recording.
    pub recording: String,
    /// Terms named (any is a false alarm).
    pub named: Vec<Term>,
    /// "Unexplained: structure beyond the measured noise remains" with
    /// nothing named (a false claim of structure, counted apart).
    pub unexplained: bool,
    /// The refitted nominal model's χ²/dof (1 when the noise model is
    /// calibrated).
    pub chi2_per_dof: f64,
    /// The refitted nominal model's score per transfer function.
    pub per_tf: Vec<crate::engine::TfScore>,
}

impl NullOutcome {
    /// The outcome of a null diagnosed as `r` at `level`.
    pub fn new(generator: String, recording: String, r: &Diagnosis, level: f64) -> Self {
        let named: Vec<Term> = r.found.iter().map(|f| f.term).collect();
        NullOutcome {
            generator,
            recording,
            unexplained: named.is_empty() && r.final_score.lack_of_fit_p < level,
            named,
            chi2_per_dof: r.refit.chi2_per_dof,
            per_tf: r.refit.per_tf.clone(),
        }
    }
}

/// The upper end of the one-sided 95 % interval of a rate seen `k` times in
/// `n` (Clopper–Pearson: `p` with `P(X ≤ k | n, p) = 0.05`), by bisection.
pub fn rate_upper_95(k: usize, n: usize) -> f64 {
    if n == 0 {
        return 1.0;
    }
    if k >= n {
        return 1.0;
    }
    let cdf = |p: f64| {
        // P(X ≤ k) for Binomial(n, p), summed in logs.
        let (nf, lp, lq) = (n as f64, p.ln(), (1.0 - p).ln());
        let mut total = 0.0;
        let mut log_c = 0.0; // ln C(n, 0)
        for i in 0..=k {
            if i > 0 {
                log_c += ((nf - i as f64 + 1.0) / i as f64).ln();
            }
            total += (log_c + i as f64 * lp + (nf - i as f64) * lq).exp();
        }
        total
    };
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) > 0.05 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Clopper–Pearson's upper bound against values computed by hand: with
    /// no event in `n`, `1 − 0.05^{1/n}` (the "rule of three" ≈ 3/n); with
    /// one in 100, 0.046 560 (bisection on the exact binomial sum with
    /// Python's `math.comb`, the same as the Beta quantile `B⁻¹(0.95; 2, 99)`).
    #[test]
    fn the_rates_upper_bound_matches_clopper_pearson() {
        for n in [10, 100, 300] {
            let want = 1.0 - 0.05_f64.powf(1.0 / n as f64);
            assert!((rate_upper_95(0, n) - want).abs() < 1e-9, "n = {n}");
        }
        assert!((rate_upper_95(1, 100) - 0.046_560).abs() < 2e-5);
        assert_eq!(rate_upper_95(5, 5), 1.0);
        assert_eq!(rate_upper_95(0, 0), 1.0);
    }

    /// The rig's `g` as its own source sets it (`G = …` in
    /// `tools/python/independent_rig.py`), read from that file; and the
    /// nominal model built from it.
    #[test]
    fn the_independent_rigs_gravity_is_the_one_its_source_uses() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../python/independent_rig.py");
        let src = std::fs::read_to_string(&path).expect("independent_rig.py");
        let g: f64 = src
            .lines()
            .find_map(|l| l.strip_prefix("G = "))
            .and_then(|v| v.split('#').next())
            .and_then(|v| v.trim().parse().ok())
            .expect("a line `G = …`");
        assert_eq!(INDEPENDENT_RIG_G_M_S2, g);
        let plant = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        let mut m = PlantModel::from_file(&plant).expect("default plant");
        m.gravity.enabled = false;
        independent_rig(&mut m, false);
        assert!(m.gravity.enabled);
        assert_eq!(m.gravity.g_m_s2, g);
        assert_eq!(
            m.human.posture_reference,
            exo_plant_model::PostureReference::HoldsGoal
        );
        independent_rig(&mut m, true);
        assert!(!m.gravity.enabled);
    }
}
