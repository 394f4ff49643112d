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
    /// Negative margins above it, and multisine lines the loop amplifies
    /// beyond [`LINE_GAIN_WARN`].
    pub warnings: Vec<String>,
    /// In a multisine run with an amplification loop, the loop's gain on
    /// the excitation at every excited line of every experiment.
    pub line_gains: Vec<LineGain>,
}

/// How much the amplification loop amplifies a multisine's line (issue 34
/// item 6): the closed loop's sensitivity `|1 / (1 + L(jω))|` at the line,
/// `L = (α(s) − 1) P(s)` the model loop at the stiffness the subject holds
/// in the experiment. 1 where the loop leaves the line alone; the inverse
/// of the loop's distance from −1 there, so a line near a crossover with
/// little phase margin is amplified most.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineGain {
    /// Experiment.
    pub experiment: u32,
    /// The line's frequency (rad/s).
    pub omega_rad_s: f64,
    /// `|1 / (1 + L(jω))|` (dimensionless).
    pub gain: f64,
    /// `∠L(jω)` (degrees), continuous from `ω → 0`.
    pub loop_phase_deg: f64,
}

/// Above this gain on a multisine's line `exo run --check` warns: a
/// sensitivity peak of 2 (6 dB) is the usual robustness bound (it keeps a
/// phase margin of at least 29° and a gain margin of 6 dB; Åström and
/// Murray, *Feedback Systems*, 2nd ed., section 13.3). Not refused: the
/// loop's stability is judged by the phase margin.
pub const LINE_GAIN_WARN: f64 = 2.0;

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
    let mut line_gains = Vec::new();
    // A multisine's excited lines (rad/s), whose gain through each loop is judged.
    let lines: Vec<f64> = match cfg.protocol.multisine() {
        Some(m) => {
            let rate = cfg.run.rate_hz;
            let (n, bins) = m
                .bins(rate)
                .map_err(|e| format!("protocol.multisine: {e}"))?;
            bins.iter()
                .map(|&b| std::f64::consts::TAU * b as f64 * rate / n as f64)
                .collect()
        }
        None => Vec::new(),
    };
    let mut gains_of = |n: u32, l: &exo_impedance::loop_shaping::AmplificationLoop| {
        for &w in &lines {
            line_gains.push(LineGain {
                experiment: n,
                omega_rad_s: w,
                gain: 1.0 / (1.0 + l.response(w)).norm(),
                loop_phase_deg: l.phase_deg(w),
            });
        }
    };
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
                gains_of(
                    n,
                    &layout
                        .loop_at(f, at)
                        .map_err(|e| science("controller.f", e))?,
                );
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
                gains_of(
                    n,
                    &layout
                        .loop_at(0.0, at)
                        .map_err(|e| science("experiment alpha", e))?,
                );
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
    for g in line_gains.iter().filter(|g| g.gain > LINE_GAIN_WARN) {
        warnings.push(format!(
            "experiment {}: the amplification loop amplifies the multisine's line at {:.2} rad/s ×{:.2} (|1 + L| = {:.2}, ∠L = {:.0}°; warned above ×{LINE_GAIN_WARN}): that line's torque and motion grow with it; move protocol.multisine.band_rad_s or lower the gain",
            g.experiment,
            g.omega_rad_s,
            g.gain,
            1.0 / g.gain,
            g.loop_phase_deg
        ));
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
    let summary = match line_gains.iter().max_by(|a, b| a.gain.total_cmp(&b.gain)) {
        Some(g) => format!(
            "{summary}; multisine lines: the loop amplifies them at most ×{:.2} ({:.2} rad/s, experiment {})",
            g.gain, g.omega_rad_s, g.experiment
        ),
        None => summary,
    };
    Ok(Margins {
        summary,
        errors,
        warnings,
        line_gains,
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

    /// A multisine run's lines through each experiment's loop (issue 34
    /// item 6), against the loop written here from the paper: `L(jω) =
    /// (α − 1) S_h/S_h-e · G_SEA` with `S_h = K + jH − M_h ω²`, `S_h-e =
    /// S_h − M_e ω²`, `G_SEA = ω_n² / (ω_n² − ω² + 2jζω_n ω)`; the gain is
    /// `1/|1 + L|`. Experiments with α = 1 have no loop and no gains; the
    /// sine steps have no lines.
    #[test]
    fn a_multisines_lines_are_judged_through_each_experiments_loop() {
        use exo_impedance::Complex64;
        let file = exo_config::configs_dir().join("multisine.toml");
        let mut cfg = RunConfig::from_file(&file).unwrap();
        cfg.protocol.experiments = vec![1, 2, 3];
        let (sea_hz, zeta) = (10.0, 0.7);
        let m = controller_margins(&file, &cfg, sea_hz, zeta).unwrap();
        let (n, bins) = cfg
            .protocol
            .multisine()
            .unwrap()
            .bins(cfg.run.rate_hz)
            .unwrap();
        assert_eq!(
            m.line_gains.len(),
            2 * bins.len(),
            "experiments 2 and 3 only"
        );
        let wn = std::f64::consts::TAU * sea_hz;
        let mut worst = 0.0f64;
        for g in &m.line_gains {
            let spec = cfg.experiment_table().get(g.experiment).unwrap();
            let e = cfg.subject().get(g.experiment).unwrap();
            assert!(spec.alpha > 1.0);
            let w = g.omega_rad_s;
            assert!(bins
                .iter()
                .any(
                    |&b| (w - std::f64::consts::TAU * b as f64 * cfg.run.rate_hz / n as f64).abs()
                        < 1e-9
                ));
            let kc = Complex64::new(e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad);
            let s_h = kc - cfg.subject().inertia_kg_m2 * w * w;
            let s_he = s_h - cfg.exo_inertia_kg_m2(spec.load_kg) * w * w;
            let sea = wn * wn / Complex64::new(wn * wn - w * w, 2.0 * zeta * wn * w);
            let l = (spec.alpha - 1.0) * s_h / s_he * sea;
            let want = 1.0 / (1.0 + l).norm();
            assert!((g.gain - want).abs() < 1e-9 * want, "{g:?}: {want}");
            worst = worst.max(g.gain);
        }
        assert!(
            m.summary
                .contains("multisine lines: the loop amplifies them at most"),
            "{}",
            m.summary
        );
        let warned = m
            .warnings
            .iter()
            .filter(|w| w.contains("multisine's line"))
            .count();
        assert_eq!(
            warned,
            m.line_gains
                .iter()
                .filter(|g| g.gain > LINE_GAIN_WARN)
                .count(),
            "{:?} (largest gain {worst})",
            m.warnings
        );
        // A slower SEA (3 Hz, ζ 0.5) puts the loop's crossover among the
        // lines: some are amplified beyond ×2 and each is warned about,
        // naming its experiment and frequency; the run is not refused.
        let slow = controller_margins(&file, &cfg, 3.0, 0.5).unwrap();
        let loud: Vec<&LineGain> = slow
            .line_gains
            .iter()
            .filter(|g| g.gain > LINE_GAIN_WARN)
            .collect();
        assert!(!loud.is_empty());
        for g in &loud {
            let named = format!("experiment {}: the amplification loop amplifies the multisine's line at {:.2} rad/s", g.experiment, g.omega_rad_s);
            assert!(
                slow.warnings.iter().any(|w| w.starts_with(&named)),
                "{named}: {:?}",
                slow.warnings
            );
        }
        assert_eq!(
            slow.warnings
                .iter()
                .filter(|w| w.contains("multisine's line"))
                .count(),
            loud.len()
        );
        assert!(slow.errors.is_empty(), "{:?}", slow.errors);
        // With a fractional-order controller every experiment has a loop
        // (α(s) − 1 = k_p F(s) whatever Table I's α): every line of each.
        let mut frac = cfg.clone();
        frac.controller.f = Some(0.3);
        let m = controller_margins(&file, &frac, sea_hz, zeta).unwrap();
        assert_eq!(m.line_gains.len(), 3 * bins.len());
        assert!(m
            .line_gains
            .iter()
            .all(|g| g.gain.is_finite() && g.gain > 0.0));
        // The sine steps excite no designed lines.
        let (file, cfg) = default_run();
        assert!(controller_margins(&file, &cfg, sea_hz, zeta)
            .unwrap()
            .line_gains
            .is_empty());
    }
}
