//! Post-hoc analysis as in the paper's "Modeling Results": from the FRF
//! points of each subject and experiment, the M1/M2/M3 fits — parameters
//! estimated from `S_h = τ_c/θ_e` as the paper does (eqs. Sh1–Sh3), each
//! point weighted by its measured noise, with `S_{h-e/α}` re-created by
//! adding the known `M_e/α` for the tables and figures — `F^sub`, `F^exp` and
//! `F^all` (eq. ft) with exact critical values, the phase-shift table of
//! `S_h` (Table II layout: mean and standard error per experiment group, the
//! last three frequencies excluded), the M2 parameter table (Table III
//! layout), the power law of M2's (K, H) per subject, and the fractional
//! order eq. f recommends.
//!
//! Pure: no file I/O; `exo fit` reads the recordings and prints.

use std::collections::BTreeMap;

use crate::error::{Error, Result};
use crate::refit::{fit_models, FitSource, ModelFitError};
use exo_impedance::{
    check_fit, fit_power_law, fractional_order, paper_f_tests, recreate_coupled, Complex64,
    DampingSign, FTest, ImpedanceModel, Implausibility, Joint, ModelComparison, ModelFit,
    StiffnessRange,
};
use serde::Serialize;

/// The FRF points of one subject in one experiment, with what the fit needs.
#[derive(Debug, Clone)]
pub struct ExperimentData {
    /// Experiment number (Table I).
    pub experiment: u32,
    /// Constant amplification α of the experiment.
    pub alpha: f64,
    /// Load on the exoskeleton (kg).
    pub load_kg: f64,
    /// Exoskeleton inertia with that load, `M_e` (kg·m²).
    pub m_e_kg_m2: f64,
    /// One point per analysed period (or per selected broadband bin).
    pub points: Vec<exo_messages::FrfPoint>,
    /// The recording has no actuator torque (e.g. an imported record): only
    /// the cuff's `S_h` can be fitted, whatever the settings ask.
    pub human_only: bool,
    /// The lab's name for the condition (e.g. "MVC 20 %"), when given.
    pub condition: Option<String>,
}

/// One subject's data.
#[derive(Debug, Clone)]
pub struct SubjectData {
    /// Subject name.
    pub subject: String,
    /// By experiment number.
    pub experiments: BTreeMap<u32, ExperimentData>,
}

/// Settings of the analysis.
#[derive(Debug, Clone, Copy)]
pub struct AnalysisSettings {
    /// False-rejection probability of the F-tests.
    pub level: f64,
    /// Guaranteed phase margin φ (degrees) for eq. f.
    pub phase_margin_deg: f64,
    /// Stiffness range (Nm/rad) for eq. f; the subject's fitted M2 range when `None`.
    pub k_range_nm_per_rad: Option<[f64; 2]>,
    /// Highest frequencies left out of the phase table (the paper: 3).
    pub phase_table_exclude_last: usize,
    /// Which measured FRF the parameters are estimated from.
    pub fit_source: FitSource,
    /// Sign constraint on the damping terms.
    pub damping: DampingSign,
    /// The joint, for the plausible human inertia.
    pub joint: Joint,
    /// Weight each point by its measured noise (false: the paper's
    /// ordinary least squares).
    pub weighted: bool,
}

impl Default for AnalysisSettings {
    fn default() -> Self {
        AnalysisSettings {
            level: 0.05,
            phase_margin_deg: 10.8,
            k_range_nm_per_rad: None,
            phase_table_exclude_last: 3,
            fit_source: FitSource::CuffTorque,
            damping: DampingSign::Free,
            joint: Joint::Unspecified,
            weighted: true,
        }
    }
}

/// One model's parameters (JSON keys `K`, `H`, `B`, `M`, `r2`).
#[derive(Debug, Clone, Serialize)]
pub struct ModelRow {
    /// Stiffness K_h (Nm/rad).
    #[serde(rename = "K")]
    pub k: f64,
    /// Hysteretic damping H_h (Nm/rad).
    #[serde(rename = "H")]
    pub h: f64,
    /// Viscous damping B_h (Nm·s/rad).
    #[serde(rename = "B")]
    pub b: f64,
    /// Inertia M_h (kg·m²).
    #[serde(rename = "M")]
    pub m: f64,
    /// Standard errors of K, H, B, M (same units), when defined.
    pub std_errors: Option<[f64; 4]>,
    /// Half-widths of the 95 % intervals of K, H, B, M (Student's t), when defined.
    pub ci95: Option<[f64; 4]>,
    /// Coefficient of determination.
    pub r2: f64,
    /// Residual sum of squares ((Nm/rad)²).
    pub rss: f64,
    /// Whether the points were weighted by their measured noise.
    pub weighted: bool,
    /// `χ²/dof` of a weighted fit: about 1 when the model explains the data to their noise.
    pub chi2_per_dof: Option<f64>,
    /// Damping terms held at zero by `--nonneg-damping` (`"B"`, `"H"`).
    pub held_at_zero: Vec<&'static str>,
    /// What is physically implausible about the fit, in words.
    pub findings: Vec<String>,
}

impl ModelRow {
    /// The row of `f`, with the findings of [`check_fit`] for `joint`.
    pub fn new(f: &ModelFit, joint: Joint) -> Self {
        let khbm = |s: exo_impedance::DynamicStiffness| {
            [s.k_nm_per_rad, s.h_nm_per_rad, s.b_nm_s_per_rad, s.m_kg_m2]
        };
        ModelRow {
            k: f.params.k_nm_per_rad,
            h: f.params.h_nm_per_rad,
            b: f.params.b_nm_s_per_rad,
            m: f.params.m_kg_m2,
            std_errors: f.std_errors.map(khbm),
            ci95: f.ci95.map(khbm),
            r2: f.r2,
            rss: f.rss,
            weighted: f.weighted,
            chi2_per_dof: f.reduced_chi2,
            held_at_zero: [(1, "B"), (3, "H")]
                .into_iter()
                .filter(|(i, _)| f.held_at_zero[*i])
                .map(|(_, n)| n)
                .collect(),
            findings: check_fit(f, joint).iter().map(|x| x.to_string()).collect(),
        }
    }
}

/// The findings about `f` worth a warning: those beyond their 95 %
/// interval, and a misfit beyond the noise only for the most general model
/// fitted (a simpler model's misfit is what the F-tests weigh).
fn warned_findings(f: &ModelFit, joint: Joint, most_general: bool) -> Vec<String> {
    check_fit(f, joint)
        .into_iter()
        .filter(|x| x.significant())
        .filter(|x| most_general || !matches!(x, Implausibility::MisfitBeyondNoise { .. }))
        .map(|x| x.to_string())
        .collect()
}

/// One FRF point as reported.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PointRow {
    /// Period of the protocol (1-based).
    pub period: u32,
    /// Frequency (rad/s).
    pub omega: f64,
    /// `S_h = τ_c/θ_e` (Nm/rad), `[re, im]`, measured by the cuff.
    pub s_h: [f64; 2],
    /// The paper's `S_{h-e/α} = S_h + (M_e/α) s²` (Nm/rad), `[re, im]`,
    /// re-created from `S_h` with the known `M_e/α`.
    pub s_h_e_alpha: [f64; 2],
    /// The actuator side `(τ_s − τ_gravity)/θ_e = S_h + M_e s²` (Nm/rad),
    /// `[re, im]`, measured (all zeros when the record has no actuator torque).
    pub s_h_e_actuator: [f64; 2],
    /// Phase of `S_h` (degrees).
    pub s_h_phase_deg: f64,
    /// Coherence (0–1).
    pub coherence: f64,
    /// Relative noise of `S_h`.
    pub noise_rel: f64,
}

/// One subject-experiment.
#[derive(Debug, Clone, Serialize)]
pub struct ExperimentReport {
    /// Experiment number.
    pub experiment: u32,
    /// α.
    pub alpha: f64,
    /// Load (kg).
    pub load_kg: f64,
    /// `M_e` (kg·m²).
    pub m_e_kg_m2: f64,
    /// The lab's name for the condition, when given.
    pub condition: Option<String>,
    /// Which measured FRF the parameters were estimated from (`cuff`, `actuator`).
    pub fit_source: &'static str,
    /// The points, by frequency.
    pub points: Vec<PointRow>,
    /// The fits, keyed `M1`, `M2`, `M3`.
    pub models: BTreeMap<&'static str, ModelRow>,
}

/// An F-test as reported.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct FRow {
    /// The statistic.
    pub statistic: f64,
    /// Critical value at the level.
    pub critical: f64,
    /// Degrees of freedom (numerator, denominator).
    pub df: [f64; 2],
    /// `P(F > statistic)`.
    pub p_value: f64,
    /// `statistic > critical`.
    pub significant: bool,
}

impl From<FTest> for FRow {
    fn from(t: FTest) -> Self {
        FRow {
            statistic: t.statistic,
            critical: t.critical,
            df: [t.df_num, t.df_den],
            p_value: t.p_value,
            significant: t.significant,
        }
    }
}

/// `F_{M1−M3}` and `F_{M2−M3}` over one group.
#[derive(Debug, Clone, Serialize)]
pub struct FPair {
    /// Which group: a subject's name, `exp N`, or `all`.
    pub group: String,
    /// `F_{M1−M3}`.
    pub m1_m3: FRow,
    /// `F_{M2−M3}`.
    pub m2_m3: FRow,
}

/// The F-tests of eq. ft.
#[derive(Debug, Clone, Serialize)]
pub struct FTests {
    /// `F^sub`, one per subject.
    pub per_subject: Vec<FPair>,
    /// `F^exp`, one per experiment.
    pub per_experiment: Vec<FPair>,
    /// `F^all`.
    pub all: Option<FPair>,
}

impl FTests {
    /// Every group: per subject, per experiment, then all.
    pub fn all_groups(&self) -> impl Iterator<Item = &FPair> {
        self.per_subject
            .iter()
            .chain(&self.per_experiment)
            .chain(self.all.iter())
    }
}

/// Mean and standard error of the phase of `S_h` over one experiment group.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseCell {
    /// The group's index (0 for experiments 1–3, 1 for 4–6, …).
    pub group: u32,
    /// The group's experiments present, e.g. `1-3` or `1, 3`.
    pub experiments: String,
    /// Mean phase (degrees).
    pub mean_deg: f64,
    /// Standard error (degrees).
    pub se_deg: f64,
    /// Number of points.
    pub n: usize,
}

/// A subject's row of the phase-shift table.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseRow {
    /// Subject.
    pub subject: String,
    /// One cell per experiment group present.
    pub groups: Vec<PhaseCell>,
}

/// One subject's results.
#[derive(Debug, Clone, Serialize)]
pub struct SubjectReport {
    /// Subject name.
    pub subject: String,
    /// By experiment.
    pub experiments: Vec<ExperimentReport>,
    /// Power-law intercept β0 of M2's (K, H), when at least two experiments.
    pub beta0: Option<f64>,
    /// Power-law slope β1.
    pub beta1: Option<f64>,
    /// R² of the power law (log scale).
    pub r2: Option<f64>,
    /// The fractional order eq. f recommends, or why not.
    pub recommended_f: Option<f64>,
    /// Why no f is recommended, if so.
    pub recommended_f_note: Option<String>,
}

/// Everything `exo fit` reports.
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// Per subject.
    pub subjects: Vec<SubjectReport>,
    /// Eq. ft.
    pub f_tests: FTests,
    /// Table II layout.
    pub phase_table: Vec<PhaseRow>,
    /// What could not be used, and why.
    pub warnings: Vec<String>,
}

/// The source an experiment is fitted from: the settings' choice, or the
/// cuff when the record has no actuator torque.
pub fn source_of(e: &ExperimentData, s: &AnalysisSettings) -> FitSource {
    if e.human_only {
        FitSource::CuffTorque
    } else {
        s.fit_source
    }
}

/// Fits one experiment's points with M1, M2 and M3, each on its own
/// ([`crate::refit::fit_models`]: the online identifier's fit).
pub fn fit_experiment(
    e: &ExperimentData,
    s: &AnalysisSettings,
) -> [Result<ModelFit, ModelFitError>; 3] {
    let source = source_of(e, s);
    let mut points = source.fit_points(&e.points);
    if !s.weighted {
        for p in &mut points {
            p.std_dev_nm_per_rad = 0.0;
        }
    }
    fit_models(&points, source.target(e.m_e_kg_m2), s.damping)
}

/// The experiment group of the phase table (1-3, 4-6, 7-9) as an index.
pub fn group_of(experiment: u32) -> u32 {
    experiment.saturating_sub(1) / 3
}

/// A label for a set of experiments: `1-3` when all three of a group are
/// there, else the ones present (`1, 3`).
fn experiments_label(present: &std::collections::BTreeSet<u32>) -> String {
    let v: Vec<u32> = present.iter().copied().collect();
    if v.len() == 3 && v[2] == v[0] + 2 {
        format!("{}-{}", v[0], v[2])
    } else {
        v.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
    }
}

/// Runs the whole analysis.
pub fn analyse(data: &[SubjectData], s: &AnalysisSettings) -> Result<FitReport> {
    if data.is_empty() {
        return Err(Error::NothingToAnalyse);
    }
    let mut warnings = Vec::new();
    let mut subjects = Vec::new();
    let mut comparisons: BTreeMap<(String, u32), ModelComparison> = BTreeMap::new();
    let mut phase_table = Vec::new();
    for sd in data {
        let mut experiments = Vec::new();
        let (mut ks, mut hs) = (Vec::new(), Vec::new());
        let mut phase_groups: BTreeMap<u32, (std::collections::BTreeSet<u32>, Vec<f64>)> =
            BTreeMap::new();
        for e in sd.experiments.values() {
            let mut pts = e.points.clone();
            pts.sort_by(|a, b| a.omega.total_cmp(&b.omega));
            let rows: Vec<PointRow> = pts
                .iter()
                .map(|p| {
                    let s_h = Complex64::new(p.s_h_re, p.s_h_im);
                    let hea = recreate_coupled(s_h, p.omega, e.m_e_kg_m2, e.alpha);
                    PointRow {
                        period: p.period,
                        omega: p.omega,
                        s_h: [p.s_h_re, p.s_h_im],
                        s_h_e_alpha: [hea.re, hea.im],
                        s_h_e_actuator: [p.s_he_re, p.s_he_im],
                        s_h_phase_deg: s_h.arg().to_degrees(),
                        coherence: p.coherence,
                        noise_rel: p.noise_rel,
                    }
                })
                .collect();
            let keep = rows.len().saturating_sub(s.phase_table_exclude_last);
            let cell = phase_groups.entry(group_of(e.experiment)).or_default();
            if keep > 0 {
                cell.0.insert(e.experiment);
            }
            cell.1.extend(rows[..keep].iter().map(|r| r.s_h_phase_deg));
            let what = match &e.condition {
                Some(c) => format!("subject {} experiment {} ({c})", sd.subject, e.experiment),
                None => format!("subject {} experiment {}", sd.subject, e.experiment),
            };
            let mut models = BTreeMap::new();
            let fits = fit_experiment(e, s);
            let mut not_fitted = Vec::new();
            let most_general = ImpedanceModel::ALL
                .into_iter()
                .zip(&fits)
                .filter(|(_, f)| f.is_ok())
                .map(|(m, _)| m)
                .next_back();
            for (model, fit) in ImpedanceModel::ALL.into_iter().zip(&fits) {
                match fit {
                    Ok(f) => {
                        for finding in warned_findings(f, s.joint, Some(model) == most_general) {
                            warnings.push(format!("{what}: {model}: {finding}"));
                        }
                        models.insert(model.name(), ModelRow::new(f, s.joint));
                    }
                    Err(err) => not_fitted.push(format!(
                        "{model} ({} parameters) not fitted: {err}",
                        model.n_params()
                    )),
                }
            }
            if !not_fitted.is_empty() {
                warnings.push(format!(
                    "{what}: {} FRF point(s): {}",
                    e.points.len(),
                    not_fitted.join("; ")
                ));
            }
            if let Ok(m2) = &fits[1] {
                if m2.params.k_nm_per_rad > 0.0 && m2.params.h_nm_per_rad > 0.0 {
                    ks.push(m2.params.k_nm_per_rad);
                    hs.push(m2.params.h_nm_per_rad);
                } else {
                    warnings.push(format!(
                        "{what}: M2 gave K = {:.3}, H = {:.3}; not both positive, left out of the power law",
                        m2.params.k_nm_per_rad, m2.params.h_nm_per_rad
                    ));
                }
            }
            if let [Ok(m1), Ok(m2), Ok(m3)] = &fits {
                comparisons.insert(
                    (sd.subject.clone(), e.experiment),
                    ModelComparison {
                        m1: *m1,
                        m2: *m2,
                        m3: *m3,
                    },
                );
            }
            experiments.push(ExperimentReport {
                experiment: e.experiment,
                alpha: e.alpha,
                load_kg: e.load_kg,
                m_e_kg_m2: e.m_e_kg_m2,
                condition: e.condition.clone(),
                fit_source: source_of(e, s).name(),
                points: rows,
                models,
            });
        }
        phase_table.push(PhaseRow {
            subject: sd.subject.clone(),
            groups: phase_groups
                .into_iter()
                .filter(|(_, (_, v))| !v.is_empty())
                .map(|(group, (present, v))| {
                    let label = experiments_label(&present);
                    let n = v.len();
                    let mean = v.iter().sum::<f64>() / n as f64;
                    let se = if n > 1 {
                        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
                            / (n as f64).sqrt()
                    } else {
                        0.0
                    };
                    PhaseCell {
                        group,
                        experiments: label,
                        mean_deg: mean,
                        se_deg: se,
                        n,
                    }
                })
                .collect(),
        });
        let mut report = SubjectReport {
            subject: sd.subject.clone(),
            experiments,
            beta0: None,
            beta1: None,
            r2: None,
            recommended_f: None,
            recommended_f_note: None,
        };
        match fit_power_law(&ks, &hs) {
            Ok(pl) => {
                report.beta0 = Some(pl.law.beta0);
                report.beta1 = Some(pl.law.beta1);
                report.r2 = Some(pl.r2);
                let range = s.k_range_nm_per_rad.unwrap_or([
                    ks.iter().cloned().fold(f64::INFINITY, f64::min),
                    ks.iter().cloned().fold(0.0, f64::max),
                ]);
                match StiffnessRange::new(range[0], range[1])
                    .and_then(|r| fractional_order(pl.law, r, s.phase_margin_deg))
                {
                    Ok(f) => report.recommended_f = Some(f),
                    Err(e) => report.recommended_f_note = Some(e.to_string()),
                }
            }
            Err(e) => {
                report.recommended_f_note = Some(format!("no power law: {e}"));
            }
        }
        subjects.push(report);
    }
    let pair = |group: String, cs: &[ModelComparison]| -> Option<FPair> {
        paper_f_tests(cs, s.level).ok().map(|t| FPair {
            group,
            m1_m3: t.m1_vs_m3.into(),
            m2_m3: t.m2_vs_m3.into(),
        })
    };
    let mut per_subject = Vec::new();
    for sd in data {
        let cs: Vec<ModelComparison> = comparisons
            .iter()
            .filter(|((name, _), _)| *name == sd.subject)
            .map(|(_, c)| *c)
            .collect();
        match pair(sd.subject.clone(), &cs) {
            Some(p) => per_subject.push(p),
            None => warnings.push(format!(
                "subject {}: no F^sub (needs M3 fits with residual degrees of freedom)",
                sd.subject
            )),
        }
    }
    let experiments: std::collections::BTreeSet<u32> =
        comparisons.keys().map(|(_, e)| *e).collect();
    let per_experiment = experiments
        .iter()
        .filter_map(|n| {
            let cs: Vec<ModelComparison> = comparisons
                .iter()
                .filter(|((_, e), _)| e == n)
                .map(|(_, c)| *c)
                .collect();
            pair(format!("exp {n}"), &cs)
        })
        .collect();
    let all: Vec<ModelComparison> = comparisons.values().copied().collect();
    Ok(FitReport {
        subjects,
        f_tests: FTests {
            per_subject,
            per_experiment,
            all: pair("all".into(), &all),
        },
        phase_table,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use exo_impedance::DynamicStiffness;

    /// Noise-free points of an M2 human `K(1 + jc) − M_h ω²` seen through
    /// `M_e/α`, at the paper's ten frequencies from `w0`.
    fn experiment(n: u32, k: f64, h: f64, alpha: f64, wobble: f64) -> ExperimentData {
        let m_e = 1.01125;
        let human = DynamicStiffness::from_array([0.11, 0.0, k, h]);
        let points = (0..10)
            .map(|p| {
                let w = 2.0 * 10f64.powf(0.1 * p as f64);
                // A small deterministic perturbation so the fits have residuals.
                let d = Complex64::new(
                    wobble * (1.3 * p as f64).sin(),
                    wobble * (0.7 * p as f64).cos(),
                );
                let s_h = human.response(w) + d;
                // The actuator side holds the whole M_e, whatever α is.
                let s_he = s_h - m_e * w * w;
                exo_messages::FrfPoint {
                    experiment: n,
                    period: p + 1,
                    omega: w,
                    s_h_re: s_h.re,
                    s_h_im: s_h.im,
                    s_he_re: s_he.re,
                    s_he_im: s_he.im,
                    coherence: 1.0,
                    ..Default::default()
                }
            })
            .collect();
        ExperimentData {
            experiment: n,
            alpha,
            load_kg: 4.5,
            m_e_kg_m2: m_e,
            points,
            human_only: false,
            condition: None,
        }
    }

    #[test]
    fn recovers_m2_parameters_the_power_law_and_significant_hysteresis() {
        // H = 10^-0.3 K^1.1 across three experiments.
        let law = |k: f64| 10f64.powf(-0.3) * k.powf(1.1);
        let mut experiments = BTreeMap::new();
        for (n, k, alpha) in [(1, 20.0, 1.0), (4, 45.0, 1.0), (7, 80.0, 2.0)] {
            experiments.insert(n, experiment(n, k, law(k), alpha, 0.05));
        }
        let data = [SubjectData {
            subject: "T".into(),
            experiments,
        }];
        for source in [FitSource::CuffTorque, FitSource::ActuatorTorque] {
            let settings = AnalysisSettings {
                fit_source: source,
                ..AnalysisSettings::default()
            };
            let r = analyse(&data, &settings).unwrap();
            for e in &r.subjects[0].experiments {
                let m2 = &e.models["M2"];
                assert!((m2.m - 0.11).abs() < 0.01, "{source:?}: M_h {}", m2.m);
            }
        }
        let r = analyse(&data, &AnalysisSettings::default()).unwrap();
        let s = &r.subjects[0];
        for e in &s.experiments {
            let m2 = &e.models["M2"];
            let k_true =
                [20.0, 45.0, 80.0][[1, 4, 7].iter().position(|n| *n == e.experiment).unwrap()];
            assert!((m2.k / k_true - 1.0).abs() < 0.01, "K {} vs {k_true}", m2.k);
            assert!((m2.h / law(k_true) - 1.0).abs() < 0.02, "H {}", m2.h);
        }
        assert!((s.beta0.unwrap() + 0.3).abs() < 0.02, "{:?}", s.beta0);
        assert!((s.beta1.unwrap() - 1.1).abs() < 0.02, "{:?}", s.beta1);
        assert!(s.recommended_f.is_some(), "{:?}", s.recommended_f_note);
        let f = &r.f_tests.per_subject[0];
        assert!(f.m1_m3.significant, "{:?}", f.m1_m3);
        assert!(f.m1_m3.statistic > 10.0 * f.m2_m3.statistic.max(1e-3));
        // Phase table: groups 1-3, 4-6, 7-9, each from the first 7 points.
        let ph = &r.phase_table[0];
        assert_eq!(ph.groups.len(), 3);
        assert!(ph.groups.iter().all(|g| g.n == 7));
        let c = law(20.0) / 20.0;
        assert!((ph.groups[0].mean_deg - c.atan().to_degrees()).abs() < 8.0);
    }

    #[test]
    fn too_few_points_is_a_warning_not_a_failure() {
        let mut e = experiment(1, 30.0, 10.0, 1.0, 0.05);
        e.points.truncate(1);
        let data = [SubjectData {
            subject: "T".into(),
            experiments: BTreeMap::from([(1, e)]),
        }];
        let r = analyse(&data, &AnalysisSettings::default()).unwrap();
        // Said per model: M1 and M2 (3 parameters) need 2 points, M3 needs 3.
        assert!(
            r.warnings.iter().any(|w| w
                .contains("M1 (3 parameters) not fitted: needs 2 FRF points")
                && w.contains("M3 (4 parameters) not fitted: needs 3 FRF points")),
            "{:?}",
            r.warnings
        );
        assert!(r.subjects[0].recommended_f.is_none());
    }
}
