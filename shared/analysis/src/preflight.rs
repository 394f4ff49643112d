//! The amplification controller's loop checked at a run's operating points
//! before it starts (`exo run`'s check): the model loop `(α(s) − 1) P(s)`
//! (eqs. kp, kf, f; `exo_impedance::loop_shaping`) at the stiffness the
//! subject holds in each experiment and at the design range's bounds.

use std::path::Path;

use exo_config::{ProtocolMode, RunConfig};

/// The controller's loop margins at the run's operating points.
pub struct Margins {
    /// One line for `exo run --check`.
    pub summary: String,
    /// Margins below [`REFUSE_BELOW_MARGIN_DEG`], naming the key.
    pub errors: Vec<String>,
    /// Negative margins above it.
    pub warnings: Vec<String>,
}

/// Below this phase margin (degrees) of the model loop `exo run` refuses a
/// controller; between it and 0° it warns. The model (complex stiffness
/// with a constant loss factor, the SEA, rigid cuff) is conservative: the
/// paper's own tuned design for subject B (k_p = 3.2, f = 0.60, Table IV),
/// stable on the rig and in the simulator (`tests/tests/it/amplification.rs`),
/// has −10.8° at the lower stiffness bound and −5.1° at the stiffness B
/// holds in experiment 4; a design clearly past the edge (f = 0.9 for B:
/// −30° and −33°) is far below.
pub const REFUSE_BELOW_MARGIN_DEG: f64 = -15.0;

/// The loop `(α(s) − 1) P(s)` of the amplification controller (the plant's
/// SEA, the rig's inertias with each experiment's load, the subject's
/// inertia) at the stiffness and loss factor the subject holds in every
/// experiment of the run, and — for a fractional-order controller — at
/// both bounds of `controller.k_range_nm_per_rad` (loss factor there from
/// the power law of the subject's experiments). A phase margin below
/// [`REFUSE_BELOW_MARGIN_DEG`] is an error naming the key that sets the
/// gain (`controller.f` with `controller.kp`, or an experiment's constant
/// α) and the margin; a negative one above it, a warning.
///
/// `sea_hz` and `sea_zeta` are the plant model's SEA natural frequency (Hz)
/// and damping ratio (`sea.dynamics`); errors name the key, without the run
/// file (the caller prefixes it).
pub fn controller_margins(
    config: &Path,
    cfg: &RunConfig,
    sea_hz: f64,
    sea_zeta: f64,
) -> Result<Margins, String> {
    use exo_impedance::{fit_power_law, AmplificationPlant, SeaModel, StiffnessRange};
    let science = |key: &str, e: exo_impedance::ScienceError| format!("{key}: {e}");
    let table = cfg.experiment_table();
    let subject = cfg.subject();
    let sea = SeaModel::new(sea_hz, sea_zeta).map_err(|e| science("sea.dynamics", e))?;
    let held: Vec<u32> = match cfg.protocol.mode {
        ProtocolMode::Identification | ProtocolMode::Multisine => cfg.protocol.experiments.clone(),
        ProtocolMode::Voluntary => cfg.voluntary.map(|v| v.experiment).into_iter().collect(),
        ProtocolMode::Release => cfg.release.map(|r| r.experiment).into_iter().collect(),
    };
    let c = &cfg.controller;
    let [k_lo, k_hi] = c.k_range_nm_per_rad;
    StiffnessRange::new(k_lo, k_hi).map_err(|e| science("controller.k_range_nm_per_rad", e))?;
    // The subject's loss factor at any stiffness, for the design range.
    let ks: Vec<f64> = subject
        .experiment
        .iter()
        .map(|x| x.stiffness_nm_per_rad)
        .collect();
    let hs: Vec<f64> = subject
        .experiment
        .iter()
        .map(|x| x.hysteretic_damping_nm_per_rad)
        .collect();
    let law = fit_power_law(&ks, &hs).ok().map(|fit| fit.law);
    // (margin, where, which key sets the gain)
    let mut found: Vec<(f64, String, String)> = Vec::new();
    let mut seen = Vec::new();
    for n in held {
        if seen.contains(&n) {
            continue;
        }
        seen.push(n);
        let (Some(spec), Some(e)) = (table.get(n), subject.get(n)) else {
            continue;
        };
        let m_e = cfg.exo_inertia_kg_m2(spec.load_kg);
        let m_h = subject.inertia_kg_m2;
        let at = AmplificationPlant::new(
            m_e,
            m_h,
            e.stiffness_nm_per_rad,
            e.hysteretic_damping_nm_per_rad / e.stiffness_nm_per_rad,
            sea,
        )
        .map_err(|e| science("subject_file", e))?;
        let holds = format!(
            "the stiffness subject {} holds in experiment {n} (K = {} Nm/rad, H = {} Nm/rad)",
            subject.name, e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad
        );
        match c.f {
            Some(f) => {
                let layout = c.layout(m_e, m_h).map_err(|e| science(e.key, e.source))?;
                let kp = layout.kp;
                // The controller discretises this filter at start: refuse
                // here what it would refuse there.
                layout
                    .loop_at(f, at)
                    .and_then(|l| l.filter.discretize(cfg.run.rate_hz))
                    .map_err(|e| science("controller.p1_rad_s", e))?;
                let key = if c.kp.is_some() {
                    format!(
                        "{}: controller.f: f = {f} with controller.kp = {kp}",
                        config.display()
                    )
                } else {
                    format!(
                        "{}: controller.f: f = {f} with k_p = {kp:.3} (eq. kp)",
                        config.display()
                    )
                };
                let m = layout
                    .min_phase_margin_deg(f, &[at])
                    .map_err(|e| science("controller.f", e))?;
                found.push((m, holds, key.clone()));
                for k in [k_lo, k_hi] {
                    let loss = match law {
                        Some(l) => l.loss_factor(k).ok(),
                        None => Some(e.hysteretic_damping_nm_per_rad / e.stiffness_nm_per_rad),
                    };
                    let Some(loss) = loss.filter(|l| l.is_finite() && *l >= 0.0) else {
                        continue;
                    };
                    let Ok(bound) = AmplificationPlant::new(m_e, m_h, k, loss, sea) else {
                        continue;
                    };
                    let mb = layout
                        .min_phase_margin_deg(f, &[bound])
                        .map_err(|e| science("controller.f", e))?;
                    found.push((
                        mb,
                        format!(
                            "K = {k} Nm/rad, a bound of controller.k_range_nm_per_rad (loss factor {loss:.3} from subject {}'s power law, load {} kg)",
                            subject.name, spec.load_kg
                        ),
                        key.clone(),
                    ));
                }
            }
            None if cfg.protocol.mode.identifies() && spec.alpha > 1.0 => {
                // Constant α: the loop is (α − 1) P(s), the filter flat (f = 0).
                let layout = exo_impedance::loop_shaping::FractionalLayout {
                    kp: spec.alpha - 1.0,
                    omega_gc_hat_rad_s: 1.0,
                    filters: 1,
                    p1_rad_s: 1.0,
                    r_pp: 10.0,
                };
                let m = layout
                    .min_phase_margin_deg(0.0, &[at])
                    .map_err(|e| science("experiment alpha", e))?;
                let idx = table.index_of(n).unwrap_or(0);
                found.push((
                    m,
                    holds,
                    format!(
                        "{}: experiment[{idx}].alpha: constant α = {}",
                        cfg.protocol.experiments_file.display(),
                        spec.alpha
                    ),
                ));
            }
            None => {}
        }
    }
    let mut errors = Vec::new();
    let mut warnings = Vec::new();
    for (m, at, key) in &found {
        if *m < REFUSE_BELOW_MARGIN_DEG {
            errors.push(format!(
                "{key} leaves the amplification loop a phase margin of {m:.1}° at {at}, below {REFUSE_BELOW_MARGIN_DEG}°: it would oscillate; lower the gain"
            ));
        } else if *m < 0.0 {
            warnings.push(format!(
                "{key} leaves the model loop a phase margin of {m:.1}° at {at} (refused below {REFUSE_BELOW_MARGIN_DEG}°; the model is conservative, but watch for oscillation)"
            ));
        }
    }
    let worst = found.iter().map(|(m, ..)| *m).fold(f64::INFINITY, f64::min);
    let summary = match (c.f, found.is_empty()) {
        (Some(f), false) => format!(
            "α(s) = k_p F(s) + 1, f = {f}: smallest phase margin {worst:.1}° (at the subject's stiffness and the bounds of controller.k_range_nm_per_rad)"
        ),
        (None, false) => format!(
            "constant α per experiment: smallest phase margin {worst:.1}° at the subject's stiffness"
        ),
        (Some(f), true) => format!("α(s) = k_p F(s) + 1, f = {f}"),
        (None, true) => "constant α per experiment, no amplification loop (α ≤ 1)".into(),
    };
    Ok(Margins {
        summary,
        errors,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use exo_config::VoluntarySettings;

    fn default_run() -> (std::path::PathBuf, RunConfig) {
        let file = exo_config::configs_dir().join("default.toml");
        let cfg = RunConfig::from_file(&file).unwrap();
        (file, cfg)
    }

    /// The constant α of Table I closes an amplification loop only where
    /// α > 1 and only in the modes that run the table's experiments (the
    /// sine steps and the multisine): experiments 2 and 3 (α = 2, 4) are
    /// judged, experiment 1 (α = 1) has no loop, and a voluntary-motion run
    /// (its own protocol, α 1) none either, whichever experiment's load it
    /// borrows.
    #[test]
    fn constant_alpha_is_judged_where_it_closes_a_loop_in_the_identifying_modes() {
        let (file, mut cfg) = default_run();
        let no_loop = "constant α per experiment, no amplification loop (α ≤ 1)";
        for mode in [ProtocolMode::Identification, ProtocolMode::Multisine] {
            cfg.protocol.mode = mode;
            cfg.protocol.experiments = vec![2, 3];
            let m = controller_margins(&file, &cfg, 10.0, 0.7).unwrap();
            assert!(
                m.summary
                    .starts_with("constant α per experiment: smallest phase margin"),
                "{mode:?}: {}",
                m.summary
            );
            cfg.protocol.experiments = vec![1];
            let m = controller_margins(&file, &cfg, 10.0, 0.7).unwrap();
            assert_eq!(m.summary, no_loop, "{mode:?}");
        }
        cfg.protocol.mode = ProtocolMode::Voluntary;
        cfg.voluntary = Some(VoluntarySettings {
            amplitude_rad: 0.2,
            omega_rad_s: 2.0,
            duration_s: 10.0,
            grip_kg: 0.0,
            bias_nm: 0.0,
            experiment: 3,
        });
        let m = controller_margins(&file, &cfg, 10.0, 0.7).unwrap();
        assert_eq!(m.summary, no_loop);
    }
}
