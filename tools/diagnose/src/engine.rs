//! The diagnosis: locate the mismatch, refit the nominal model's own
//! parameters, then add candidate physics one term at a time while it is
//! significant, and score every model before and after.
//!
//! Selection (each step, every candidate not yet in the model):
//! - nested-model F-test of the model with the candidate against the model
//!   without it, as the paper compares M1 and M2 with M3 (eq. ft):
//!   `F = ((RSS₀ − RSS₁)/Δp) / (RSS₁/(n − p₁))`;
//! - Holm's correction over the candidates tried at the step (the chosen one
//!   is the smallest p-value, so its adjusted p is `m·p`);
//! - Akaike's criterion must fall and the held-out error must fall:
//!   two-fold validation over periods (odd periods fit, even predicted, and
//!   the reverse; within a single broadband window, alternate bands);
//! - the lack-of-fit χ² against the noise measured in each window is
//!   reported before and after: it says whether structure remains.
//!
//! The search runs only while the lack-of-fit test rejects (structure
//! beyond the noise remains); the most significant candidate that the
//! Holm-corrected F-test, Akaike's criterion and the held-out error all
//! accept, and whose parameters are determined (one differs from the
//! term's absence by more than two standard errors), is added; the search stops when none qualifies or nothing is left
//! to explain.

use std::collections::BTreeMap;

use exo_impedance::ftest::f_survival;
use exo_plant_model::PlantModel;
use num_complex::Complex64;
use serde::Serialize;

use crate::band::band_of;
use crate::data::{Dataset, Observation, Tf};
use crate::fit::{fit, lack_of_fit, lack_of_fit_chi2, lack_of_fit_p, rss, sigma_floor, Fitted};
use crate::model::{Param, Physics};
use crate::stats::{chi2_sf, normal_quantile};
use crate::terms::Term;

/// Settings of a diagnosis.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Family-wise false-alarm probability of the tests.
    pub level: f64,
    /// Most terms added.
    pub max_terms: usize,
    /// Nominal `K_h`, `H_h` per experiment (a subject file), if known.
    pub nominal_subject: Option<BTreeMap<u32, (f64, f64)>>,
    /// Candidate terms allowed (default: the whole catalogue).
    pub candidates: Vec<Term>,
    /// Generic forms tried when no catalogue term is accepted (default:
    /// the whole library, [`Term::FORMS`]).
    pub forms: Vec<Term>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            level: 0.05,
            max_terms: 4,
            nominal_subject: None,
            candidates: Term::ALL.to_vec(),
            forms: Term::FORMS.to_vec(),
        }
    }
}

/// Error of a diagnosis.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// Nothing to compare.
    #[error("no usable observations: {0}")]
    NoData(String),
    /// Settings out of range.
    #[error("{0}")]
    Settings(String),
}

/// Fit quality of a model for one transfer function.
#[derive(Debug, Clone, Serialize)]
pub struct TfScore {
    /// Transfer function.
    pub tf: Tf,
    /// Observations.
    pub points: usize,
    /// Weighted residual sum of squares (χ² with the measured noise).
    pub rss: f64,
    /// Complex R² (1 − Σ|data − model|² / Σ|data − mean|²).
    pub r2: f64,
    /// Weighted RSS on held-out periods (two-fold over periods).
    pub heldout_rss: f64,
    /// Lack-of-fit χ² per real residual against the measured noise and the
    /// model's accuracy (1 when both are right; the model's own parameters
    /// are not subtracted here).
    pub chi2_per_residual: f64,
    /// The same of the transient-free values against their own noise
    /// alone (`Observation::transient_free`), no accuracy floor: reported
    /// for calibrating the noise model, not judged by (null in JSON when no
    /// window allows a transient-free value).
    pub noise_only_chi2_per_residual: f64,
}

/// A model's scores.
#[derive(Debug, Clone, Serialize)]
pub struct Score {
    /// Per transfer function.
    pub per_tf: Vec<TfScore>,
    /// Total weighted RSS.
    pub rss: f64,
    /// Total held-out RSS.
    pub heldout_rss: f64,
    /// χ² per degree of freedom against the measured noise and the model's accuracy.
    pub chi2_per_dof: f64,
    /// P-value of the lack-of-fit χ² test (per transfer function, Bonferroni
    /// over them) of the transfer functions whose misfit beyond the noise is
    /// larger than the forward model's accuracy ([`crate::fit::lack_of_fit`]):
    /// what the materiality rule judges.
    pub lack_of_fit_p: f64,
    /// The same test by the noise alone, every transfer function counted.
    pub noise_p: f64,
    /// The largest misfit beyond the noise, relative to the values
    /// (`fit::excess_relative`; the static balance left out).
    pub excess: f64,
    /// Free parameters.
    pub parameters: usize,
}

impl Score {
    /// Why a model's misfit is no missing physics: within the measured noise,
    /// or beyond it by less than the forward model's accuracy (the materiality
    /// rule, [`crate::fit::lack_of_fit`]).
    pub fn within_words(&self, level: f64, what: &str) -> String {
        let sc = self;
        if sc.noise_p < level {
            format!(
                "{what} is beyond the measured noise (χ²/dof {:.2}, p = {:.1e}) by {:.2} % of the values, within the forward model's accuracy ({:.1} %)",
                sc.chi2_per_dof,
                sc.noise_p,
                100.0 * sc.excess,
                100.0 * crate::fit::MODEL_ACCURACY
            )
        } else {
            format!(
                "{what} is within the measured noise (χ²/dof {:.2}, lack-of-fit p = {:.2})",
                sc.chi2_per_dof, sc.noise_p
            )
        }
    }
}

/// One cell of the located mismatch.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// Transfer function.
    pub tf: Tf,
    /// Experiment.
    pub experiment: u32,
    /// Band name.
    pub band: &'static str,
    /// Points.
    pub points: usize,
    /// Mean magnitude error `|data|/|model| − 1` (%).
    pub magnitude_pct: f64,
    /// Mean phase error `arg(data/model)` (degrees).
    pub phase_deg: f64,
    /// Mean squared whitened residual (1 = at the noise).
    pub chi2_per_point: f64,
    /// P-value of the cell's χ² (2 per point).
    pub p_value: f64,
    /// Significant after Bonferroni over the cells.
    pub significant: bool,
}

/// How a transfer function's residual scales across windows.
#[derive(Debug, Clone, Serialize)]
pub struct Scaling {
    /// Transfer function.
    pub tf: Tf,
    /// Correlation of the residual's quadrature part (relative) with `1/A` (angle amplitude).
    pub with_inverse_amplitude: f64,
    /// Correlation of the residual's in-phase part (relative) with `K_h`.
    pub with_stiffness: f64,
    /// Correlation of the residual's phase with ω.
    pub phase_with_omega: f64,
    /// Windows.
    pub windows: usize,
}

/// Time-domain view per experiment and channel.
#[derive(Debug, Clone, Serialize)]
pub struct TimeRow {
    /// Experiment.
    pub experiment: u32,
    /// Channel (`tau_c`, `tau_s_net`, `theta_e`).
    pub channel: &'static str,
    /// Mean of the channel over the analysis windows (Nm or rad).
    pub mean: f64,
    /// RMS of data − model over the windows (model = the channel's mean plus its
    /// transfer function times the measured angle's fundamental), nominal model.
    pub rms_residual_nominal: f64,
    /// Same with the final model.
    pub rms_residual_final: f64,
    /// 2nd and 3rd harmonic amplitude relative to the fundamental.
    pub harmonics: [f64; 2],
    /// Amplitude at 2.5 ω relative to the fundamental (the noise floor for the harmonics).
    pub floor: f64,
}

/// Where the data and the nominal model differ.
#[derive(Debug, Clone, Serialize)]
pub struct Location {
    /// Against the nominal model as given.
    pub nominal_cells: Vec<Cell>,
    /// Against the nominal model with its own parameters refitted.
    pub refit_cells: Vec<Cell>,
    /// Residual scaling after the refit.
    pub scaling: Vec<Scaling>,
    /// Time-domain residuals and harmonics.
    pub time: Vec<TimeRow>,
    /// Plain-words summary.
    pub summary: Vec<String>,
}

/// A nominal parameter that moved in the refit.
#[derive(Debug, Clone, Serialize)]
pub struct ParamChange {
    /// Parameter.
    pub label: String,
    /// Nominal value.
    pub nominal: f64,
    /// Refitted value.
    pub fitted: f64,
    /// Its standard error.
    pub std_error: f64,
    /// Change (%).
    pub change_pct: f64,
}

/// One candidate tried at one step.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// Term.
    pub term: Term,
    /// Plain words.
    pub words: &'static str,
    /// Parameters added.
    pub added_parameters: usize,
    /// F statistic against the current model.
    pub f: f64,
    /// Critical F at the Holm-corrected level for this candidate's rank.
    pub f_critical: f64,
    /// Raw p-value.
    pub p_value: f64,
    /// Holm-adjusted p-value.
    pub p_holm: f64,
    /// Change of Akaike's criterion.
    pub delta_aic: f64,
    /// Relative change of the held-out RSS (negative = better).
    pub heldout_change: f64,
    /// Fitted value in words.
    pub description: String,
    /// Its parameters are determined: one differs from the term's absence
    /// by more than two standard errors.
    pub identified: bool,
    /// What the candidate does to each supported transfer function.
    pub tf_checks: Vec<TfCheck>,
    /// Share of the current model's misfit beyond the noise that the
    /// candidate removes: `(RSS₀ − RSS₁)/(RSS₀ − (n − p₀))`, 0–1.
    pub explained_share: f64,
    /// Its parameters fitted separately at each excitation amplitude
    /// (checked only for a candidate every other criterion accepts).
    pub amplitude_check: Option<AmplitudeCheck>,
    /// Whether the change within a window that it predicts (a drift does)
    /// is in the data; `None` when it predicts none.
    pub within_window_check: Option<WindowCheck>,
    /// Whether the 3rd harmonic of `τ_c` it predicts (a cubic spring or
    /// damper does, [`crate::signatures::cubic_harmonic_check`]) is in the data, by
    /// the same rule; `None` when it predicts none.
    pub harmonic_check: Option<WindowCheck>,
    /// Its F-test is significant after Holm's correction.
    pub significant: bool,
    /// Why it was not accepted (empty when accepted).
    pub rejected_because: Vec<String>,
    /// A generic form that every criterion accepts except that its own
    /// signature is too small to check in these recordings: neither found
    /// nor refuted ("untested").
    pub untested: bool,
    /// Chosen at this step.
    pub chosen: bool,
    /// Fitted and tested with every value held to the forward model's
    /// accuracy, against the current model refitted so: a describing
    /// function ([`Term::describing_function`]), or any term once the model
    /// holds one.
    pub held_to_model_accuracy: bool,
}

/// What a candidate does to one supported transfer function: its weighted
/// RSS before and after, and how far the candidate moves the prediction.
///
/// With `r` the whitened residual of the current model and `m` the whitened
/// change of the prediction the candidate makes, `RSS₁ − RSS₀ = |m|² −
/// 2 r·m`; `β = r·m/|m|²` is the fraction of the predicted change the data
/// follow (1: the data moved exactly as the candidate predicts; 0: the data
/// did not move at all), with standard error `1/|m|` against the measured
/// noise.
#[derive(Debug, Clone, Serialize)]
pub struct TfCheck {
    /// Transfer function.
    pub tf: Tf,
    /// Weighted RSS of the current model.
    pub rss_before: f64,
    /// Weighted RSS with the candidate.
    pub rss_after: f64,
    /// `|m|²`: squared whitened size of the predicted change.
    pub moved: f64,
    /// `β`, the fraction of the predicted change the data confirm.
    pub confirmed: f64,
    /// Standard error of `β` (`1/|m|`).
    pub confirmed_se: f64,
    /// The data contradict the candidate here: it moves the prediction by at
    /// least one noise σ in all (`|m|² ≥ 1`) and `β` lies below ½ by more
    /// than the one-sided critical value (level Bonferroni-divided over the
    /// supported transfer functions) — the fit is worse there beyond its
    /// noise, or a change it predicts is not in the data.
    pub contradicts: bool,
}

/// What a candidate predicts within the windows (the change from the first
/// half of each window to its second, [`crate::remains::within_window_rates`])
/// against what the data show there: with `m` the whitened predicted rate
/// of change (candidate less current model) and `y` the measured one,
/// `β = y·m/|m|²` is the fraction of the predicted change the data follow,
/// its standard error `1/|m|` scaled by the scatter about `β m`.
#[derive(Debug, Clone, Serialize)]
pub struct WindowCheck {
    /// What was compared, in words ("the change within a window", "the 3rd
    /// harmonic of τ_c").
    pub signature: &'static str,
    /// Values compared (windows split in halves, or harmonic phasors).
    pub windows: usize,
    /// `|m|²`.
    pub moved: f64,
    /// `β`.
    pub confirmed: f64,
    /// Its standard error.
    pub confirmed_se: f64,
    /// Contradicted by the same rule as a transfer function: `|m|² ≥ 1`
    /// and `β < ½ − z·se`.
    pub contradicts: bool,
    /// Confirmed at its predicted size: the signature is in the data beyond
    /// the one-sided critical value (`β > z·se`), and the data follow
    /// between half and twice the size predicted (`½ ≤ β ≤ 2`: the form's
    /// idealisation, e.g. backlash's instant impacts, may miss the size by a
    /// few tens of per cent; far more or far less is another cause). A
    /// generic form is taken only when its own signature is confirmed.
    pub confirms: bool,
    /// Large enough to check: had the data followed it exactly (`β = 1`),
    /// it would be in the data beyond the critical value (`z·se < 1`). A
    /// form whose signature is not is "untested", never found.
    pub testable: bool,
}

impl WindowCheck {
    /// The check of `signature` from `(|m|², β, se, values)` at the
    /// one-sided critical value `z`.
    fn new(
        signature: &'static str,
        (moved, beta, se, windows): (f64, f64, f64, usize),
        z: f64,
    ) -> Self {
        WindowCheck {
            signature,
            windows,
            moved,
            confirmed: beta,
            confirmed_se: se,
            contradicts: moved >= 1.0 && beta < 0.5 - z * se,
            confirms: beta > z * se && (0.5..=2.0).contains(&beta),
            testable: z * se < 1.0,
        }
    }

    /// "predicted X σ, the data show β ± se % of it" in words.
    fn words(&self) -> String {
        format!(
            "{} it predicts ({:.1} σ over {} values) is {}: the data show {:.0} ± {:.0} % of it",
            self.signature,
            self.moved.sqrt(),
            self.windows,
            if self.contradicts {
                "not in the data"
            } else if !self.testable {
                "too small to check in these recordings (untested)"
            } else {
                "not confirmed at its predicted size"
            },
            100.0 * self.confirmed,
            100.0 * self.confirmed_se
        )
    }
}

/// The check of [`WindowCheck`] for the change from `before` to `after`;
/// `None` when `after` predicts no change within a window.
fn window_check(d: &Dataset, before: &Physics, after: &Physics, z: f64) -> Option<WindowCheck> {
    let (mut ym, mut mm, mut rows) = (0.0, 0.0, Vec::new());
    for tf in [Tf::Sh, Tf::She] {
        if !d.supported.contains(&tf) {
            continue;
        }
        for r in crate::remains::within_window_rates(d, tf) {
            let o = &r.observation;
            let c = &d.conditions[o.window];
            let mut later = c.clone();
            later.elapsed_s += r.dt_s;
            let rate = |p: &Physics| {
                (p.predict_tf(tf, o.omega_rad_s, &later, o.gravity_comp)
                    - p.predict_tf(tf, o.omega_rad_s, c, o.gravity_comp))
                    * o.value.conj()
                    / o.value.norm_sqr()
                    * (100.0 / r.dt_s)
            };
            let m = rate(after) - rate(before);
            for (k, mk) in [m.re, m.im].into_iter().enumerate() {
                let (y, mw) = (r.rate[k] / r.sd, mk / r.sd);
                ym += y * mw;
                mm += mw * mw;
                rows.push((y, mw));
            }
        }
    }
    if mm.is_nan() || mm <= 1e-12 {
        return None;
    }
    let beta = ym / mm;
    let dof = (rows.len() as f64 - 1.0).max(1.0);
    let scatter = rows
        .iter()
        .map(|(y, m)| (y - beta * m).powi(2))
        .sum::<f64>()
        / dof;
    let se = (scatter.max(1.0) / mm).sqrt();
    Some(WindowCheck::new(
        "the change within a window",
        (mm, beta, se, rows.len() / 2),
        z,
    ))
}

/// A candidate's parameters fitted separately at two excitation amplitudes.
/// Every catalogue term's parameters are amplitude-independent (friction's
/// describing function carries the amplitude), so a parameter that differs
/// between the amplitudes beyond its standard errors (z-test, level
/// Bonferroni-divided over its parameters) and materially (by more than
/// `1 − 1/√r` of the larger value, `r` the ratio of the amplitudes: halfway
/// in ratio to an effect that scales with the amplitude) says the data do
/// not scale as the term predicts.
#[derive(Debug, Clone, Serialize)]
pub struct AmplitudeCheck {
    /// Excitation amplitudes (Nm) of the low and high groups.
    pub amplitudes_nm: [f64; 2],
    /// Periods in each group, in words (e.g. "1–7").
    pub periods: [String; 2],
    /// Per added parameter: label, value and standard error at low and at high amplitude.
    pub params: Vec<(String, [f64; 2], [f64; 2])>,
    /// The parameters differ beyond their standard errors.
    pub inconsistent: bool,
    /// In words.
    pub words: String,
}

/// One step of the search.
#[derive(Debug, Clone, Serialize)]
pub struct Step {
    /// Step number (1-based).
    pub step: usize,
    /// The candidates are the library's generic forms (tried at a step
    /// where no catalogue term was accepted), not catalogue terms.
    pub forms: bool,
    /// Every candidate's statistics, best first.
    pub candidates: Vec<Candidate>,
}

/// A term the diagnosis added.
#[derive(Debug, Clone, Serialize)]
pub struct Found {
    /// Term.
    pub term: Term,
    /// Plant TOML key.
    pub toml_key: &'static str,
    /// Plain words.
    pub words: &'static str,
    /// Fitted value(s) with standard errors, in the final model.
    pub description: String,
    /// F when it was added, and its critical value.
    pub f: f64,
    /// Critical F.
    pub f_critical: f64,
    /// Holm-adjusted p-value.
    pub p_holm: f64,
    /// Held-out RSS change when it was added (relative).
    pub heldout_change: f64,
    /// Share of the misfit beyond the noise it removed when it was added.
    pub explained_share: f64,
    /// It explains less than half of the misfit and structure remains after
    /// it: a part of the answer, not the answer.
    pub partial: bool,
    /// A generic form outside the catalogue (discovered physics).
    pub discovered: bool,
    /// Significant at the search's level but with a Holm-adjusted p-value
    /// of at least [`MARGINAL_P`]: a step another recording of the same
    /// joint may well not confirm, and the sentence says so.
    pub marginal: bool,
    /// The sentence.
    pub sentence: String,
}

/// The Holm-adjusted p-value at and above which an accepted term is
/// reported as marginal ([`Found::marginal`]): significant at the usual
/// 0.05, not at 0.001. (The real ankle record's hysteresis step, F = 8.6
/// against a critical 7.0, is one; every concealed effect of
/// `exo diagnose-bench` is far below it.)
pub const MARGINAL_P: f64 = 1e-3;

/// The fewest analysis windows (a broadband window counts once per band
/// it gives) from which the diagnosis tells structure from noise. Each
/// window's noise comes from its own residual, but with
/// one or two windows the model's own parameters (`K_h`, `H_h`, `M_h`, the
/// SEA's) take up nearly every value, so a lack-of-fit there measures the
/// few degrees of freedom left, not the physics: nothing is named and the
/// verdict says why.
pub const MIN_WINDOWS: usize = 3;

/// The whole result.
#[derive(Debug, Clone, Serialize)]
pub struct Diagnosis {
    /// Recordings read.
    pub sources: Vec<String>,
    /// Transfer functions compared.
    pub supported: Vec<Tf>,
    /// What could not be used.
    pub notes: Vec<String>,
    /// The located mismatch.
    pub location: Location,
    /// Nominal model as given.
    pub nominal: Score,
    /// Nominal model with its own parameters refitted.
    pub refit: Score,
    /// Parameters of the nominal model that moved.
    pub parameter_changes: Vec<ParamChange>,
    /// The search.
    pub steps: Vec<Step>,
    /// Terms found, in the order added.
    pub found: Vec<Found>,
    /// Delays shorter than one sample period that the search took into the
    /// model as the rig's timing within a tick, not as missing physics
    /// (docs/diagnose.md, "The judgement by the measured noise").
    pub within_tick: Vec<String>,
    /// The family-wise false-alarm probability the tests were run at
    /// ([`Settings::level`]).
    pub level: f64,
    /// The final model's score.
    pub final_score: Score,
    /// The verdict in plain words.
    pub verdict: Vec<String>,
    /// Nominal coefficients.
    pub nominal_physics: Physics,
    /// Refitted nominal coefficients.
    pub refit_physics: Physics,
    /// Final coefficients.
    pub final_physics: Physics,
    /// What remains of the final model's misfit, per transfer function.
    pub remains: Vec<crate::remains::Remains>,
    /// The posture-dependent stiffness's fit in the 2nd harmonic of `τ_c`
    /// (taken or not, with why), when the windows have the harmonics.
    pub posture: Option<crate::posture::PostureFit>,
    /// Each experiment's posture against the model's static equilibrium
    /// ([`crate::equilibrium`]).
    pub equilibrium: Option<crate::equilibrium::Equilibrium>,
}

impl Diagnosis {
    /// The updated plant model.
    pub fn updated_plant(&self, base: &PlantModel) -> PlantModel {
        self.final_physics.write_plant(base)
    }
}

fn score(d: &Dataset, start: &Physics, fitted: &Physics, free: &[Param]) -> Score {
    let mut per_tf = Vec::new();
    let folds = heldout(d, start, free);
    for &tf in &d.supported {
        let sel = |_: usize, o: &Observation| o.tf == tf;
        let (r, _) = rss(d, fitted, &sel);
        let obs: Vec<&Observation> = d.of(tf).collect();
        let mean = obs.iter().map(|o| o.value).sum::<Complex64>() / obs.len().max(1) as f64;
        let (mut ss_res, mut ss_tot) = (0.0, 0.0);
        for o in &obs {
            ss_res += (fitted.predict(o, &d.conditions[o.window]) - o.value).norm_sqr();
            ss_tot += (o.value - mean).norm_sqr();
        }
        per_tf.push(TfScore {
            tf,
            points: obs.len(),
            rss: r,
            r2: if ss_tot > 0.0 {
                1.0 - ss_res / ss_tot
            } else {
                f64::NAN
            },
            heldout_rss: folds.get(&tf).copied().unwrap_or(f64::NAN),
            chi2_per_residual: {
                let (chi, n) = crate::fit::lack_of_fit_chi2_of(d, fitted, Some(tf));
                chi / n.max(1) as f64
            },
            noise_only_chi2_per_residual: crate::fit::noise_only_chi2(d, fitted, tf),
        });
    }
    let (total, _) = rss(d, fitted, &|_, _| true);
    let (chi, n) = lack_of_fit_chi2(d, fitted);
    let dof = n as f64 - free.len() as f64;
    let lof = lack_of_fit(d, fitted, free.len(), 0.0);
    Score {
        rss: total,
        heldout_rss: per_tf.iter().map(|t| t.heldout_rss).sum(),
        chi2_per_dof: chi / dof.max(1.0),
        lack_of_fit_p: lof.p_value,
        noise_p: lof.noise_p,
        excess: lof.excess,
        parameters: free.len(),
        per_tf,
    }
}

/// Two-fold held-out RSS per transfer function: fit on odd periods, predict
/// even ones, and the reverse. With no free parameters it is the plain RSS.
fn heldout(d: &Dataset, start: &Physics, free: &[Param]) -> BTreeMap<Tf, f64> {
    let folds = folds(d);
    let mut out: BTreeMap<Tf, f64> = BTreeMap::new();
    for fold in 0..2u8 {
        let train = |i: usize, _: &Observation| folds[i] != fold;
        let f = fit(d, start, free, &train);
        for &tf in &d.supported {
            let test = |i: usize, o: &Observation| o.tf == tf && folds[i] == fold;
            *out.entry(tf).or_default() += rss(d, &f.physics, &test).0;
        }
    }
    out
}

/// The fold (0 or 1) of every observation: the parity of its period when
/// its experiment has two periods or more; otherwise (one broadband
/// window) the parity of its rank in frequency within its window and
/// transfer function, so the held-out points interleave the band.
fn folds(d: &Dataset) -> Vec<u8> {
    let mut periods: BTreeMap<u32, std::collections::BTreeSet<u32>> = BTreeMap::new();
    for c in &d.conditions {
        periods.entry(c.experiment).or_default().insert(c.period);
    }
    let mut rank: BTreeMap<(usize, Tf), Vec<(f64, usize)>> = BTreeMap::new();
    for (i, o) in d.observations.iter().enumerate() {
        rank.entry((o.window, o.tf))
            .or_default()
            .push((o.omega_rad_s, i));
    }
    let mut by_rank = vec![0u8; d.observations.len()];
    for v in rank.values_mut() {
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (r, &(_, i)) in v.iter().enumerate() {
            by_rank[i] = (r % 2) as u8;
        }
    }
    d.observations
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let c = &d.conditions[o.window];
            if periods.get(&c.experiment).is_some_and(|p| p.len() >= 2) {
                (c.period % 2) as u8
            } else {
                by_rank[i]
            }
        })
        .collect()
}

fn cells(d: &Dataset, phys: &Physics, level: f64) -> Vec<Cell> {
    let mut groups: BTreeMap<(Tf, u32, &'static str), Vec<&Observation>> = BTreeMap::new();
    for o in &d.observations {
        let c = &d.conditions[o.window];
        groups
            .entry((o.tf, c.experiment, band_of(o.omega_rad_s)))
            .or_default()
            .push(o);
    }
    let m = groups.len().max(1) as f64;
    groups
        .into_iter()
        .map(|((tf, experiment, band), obs)| {
            let (mut mag, mut ph, mut chi) = (0.0, 0.0, 0.0);
            for o in &obs {
                let pred = phys.predict(o, &d.conditions[o.window]);
                let ratio = o.value / pred;
                mag += ratio.norm() - 1.0;
                ph += ratio.arg().to_degrees();
                let r = pred - o.value;
                chi += (r.re / sigma_floor(o, 0)).powi(2);
                if o.tf.is_dynamic() {
                    chi += (r.im / sigma_floor(o, 1)).powi(2);
                }
            }
            let n = obs.len() as f64;
            let per = if tf.is_dynamic() { 2.0 } else { 1.0 };
            let p_value = chi2_sf(chi, per * n);
            Cell {
                tf,
                experiment,
                band,
                points: obs.len(),
                magnitude_pct: 100.0 * mag / n,
                phase_deg: ph / n,
                chi2_per_point: chi / n,
                p_value,
                significant: p_value < level / m,
            }
        })
        .collect()
}

fn pearson(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    if x.len() < 3 {
        return f64::NAN;
    }
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    if sxx > 0.0 && syy > 0.0 {
        sxy / (sxx * syy).sqrt()
    } else {
        f64::NAN
    }
}

fn scaling(d: &Dataset, phys: &Physics) -> Vec<Scaling> {
    d.supported
        .iter()
        .map(|&tf| {
            let (mut inv_a, mut quad, mut k, mut inph, mut w, mut ph) =
                (vec![], vec![], vec![], vec![], vec![], vec![]);
            for o in d.of(tf) {
                let c = &d.conditions[o.window];
                let pred = phys.predict(o, c);
                let rel = (o.value - pred) / pred.norm().max(1e-12);
                let rot = rel * (pred.conj() / pred.norm().max(1e-12));
                inv_a.push(1.0 / c.theta_amp_rad.max(1e-9));
                quad.push(rot.im);
                k.push(phys.k.get(&c.experiment).copied().unwrap_or(0.0));
                inph.push(rot.re);
                w.push(o.omega_rad_s);
                ph.push((o.value / pred).arg());
            }
            Scaling {
                tf,
                with_inverse_amplitude: pearson(&inv_a, &quad),
                with_stiffness: pearson(&k, &inph),
                phase_with_omega: pearson(&w, &ph),
                windows: quad.len(),
            }
        })
        .collect()
}

fn harmonic(t: &[f64], y: &[f64], w: f64) -> f64 {
    exo_impedance::frf::sine_amplitude(t, y, w, true).map_or(f64::NAN, |a| a.amplitude.norm())
}

fn time_rows(d: &Dataset, nominal: &Physics, fin: &Physics) -> Vec<TimeRow> {
    let mut acc: BTreeMap<(u32, &'static str), Vec<[f64; 6]>> = BTreeMap::new();
    for (i, s) in d.signals.iter().enumerate() {
        let c = &d.conditions[i];
        let w = s.omega_rad_s;
        if w <= 0.0 || s.t_s.len() < 16 {
            continue;
        }
        let Ok(th) = exo_impedance::frf::sine_amplitude(&s.t_s, &s.theta_rad, w, true) else {
            continue;
        };
        let gravity = d
            .observations
            .iter()
            .find(|o| o.window == i && o.tf == Tf::She)
            .map_or(Complex64::new(0.0, 0.0), |o| o.gravity_comp);
        for (name, y, tf) in [
            ("tau_c", &s.tau_c_nm, Some(Tf::Sh)),
            ("tau_s_net", &s.tau_s_net_nm, Some(Tf::She)),
            ("theta_e", &s.theta_rad, None),
        ] {
            if tf.is_some_and(|tf| !d.supported.contains(&tf)) {
                continue;
            }
            let mean = y.iter().sum::<f64>() / y.len() as f64;
            let fund = harmonic(&s.t_s, y, w);
            let rms = |p: &Physics| match tf {
                None => f64::NAN,
                Some(tf) => {
                    let g = p.predict_tf(tf, w, c, gravity);
                    let a = g * th.amplitude;
                    let mut e2 = 0.0;
                    for (t, v) in s.t_s.iter().zip(y.iter()) {
                        let m = mean + (a * Complex64::from_polar(1.0, w * t)).re;
                        e2 += (v - m).powi(2);
                    }
                    (e2 / y.len() as f64).sqrt()
                }
            };
            let row = [
                mean,
                rms(nominal),
                rms(fin),
                harmonic(&s.t_s, y, 2.0 * w) / fund,
                harmonic(&s.t_s, y, 3.0 * w) / fund,
                harmonic(&s.t_s, y, 2.5 * w) / fund,
            ];
            acc.entry((c.experiment, name)).or_default().push(row);
        }
    }
    acc.into_iter()
        .map(|((experiment, channel), rows)| {
            let avg = |k: usize| {
                let v: Vec<f64> = rows
                    .iter()
                    .map(|r| r[k])
                    .filter(|x| x.is_finite())
                    .collect();
                if v.is_empty() {
                    f64::NAN
                } else {
                    v.iter().sum::<f64>() / v.len() as f64
                }
            };
            TimeRow {
                experiment,
                channel,
                mean: avg(0),
                rms_residual_nominal: avg(1),
                rms_residual_final: avg(2),
                harmonics: [avg(3), avg(4)],
                floor: avg(5),
            }
        })
        .collect()
}

/// What `after` does to each supported transfer function compared with
/// `before` ([`TfCheck`]), `z` the one-sided critical value.
fn tf_checks(d: &Dataset, before: &Physics, after: &Physics, z: f64) -> Vec<TfCheck> {
    d.supported
        .iter()
        .map(|&tf| {
            let (mut r0, mut r1, mut m2) = (0.0, 0.0, 0.0);
            for o in d.of(tf) {
                let c = &d.conditions[o.window];
                let (e0, e1) = (
                    before.predict(o, c) - o.value,
                    after.predict(o, c) - o.value,
                );
                let parts = if tf.is_dynamic() { 2 } else { 1 };
                for k in 0..parts {
                    let part = |v: Complex64| if k == 0 { v.re } else { v.im };
                    let sd = sigma_floor(o, k);
                    let (a, b) = (part(e0) / sd, part(e1) / sd);
                    r0 += a * a;
                    r1 += b * b;
                    m2 += (b - a).powi(2);
                }
            }
            let (confirmed, confirmed_se) = if m2 > 0.0 {
                ((m2 - (r1 - r0)) / (2.0 * m2), 1.0 / m2.sqrt())
            } else {
                (f64::NAN, f64::INFINITY)
            };
            TfCheck {
                tf,
                rss_before: r0,
                rss_after: r1,
                moved: m2,
                confirmed,
                confirmed_se,
                // Only where the candidate moves the prediction by at least
                // one noise σ in all (|m| ≥ 1): below that the change is
                // within the noise of a single point (and, near zero,
                // numerical rounding).
                contradicts: m2 >= 1.0 && confirmed < 0.5 - z * confirmed_se,
            }
        })
        .collect()
}

/// A form's own signature beyond the transfer functions it is fitted to
/// ([`Term::needs_own_signature`]): the change within a window for the
/// drift, the harmonics for the polynomial spring, the cubic damper,
/// backlash and the torque limit; `None` for the rest of the catalogue (its
/// signature is its transfer functions) or where the recordings cannot
/// show it.
fn own_signature(c: &Candidate) -> Option<&WindowCheck> {
    match c.term {
        Term::StiffnessDrift => c.within_window_check.as_ref(),
        Term::CubicStiffness | Term::CubicDamping | Term::Backlash | Term::ActuatorSaturation => {
            c.harmonic_check.as_ref()
        }
        _ => None,
    }
}

/// The harmonic check of the change from `before` to `after`: the 3rd
/// harmonic of `τ_c` for the polynomial spring and the cubic damper, the
/// 2nd and 3rd of the SEA's torque for backlash and, beyond the SEA's
/// response to the command's own, for the torque limit; `None` when
/// `after` predicts no harmonic.
fn harmonic_check(d: &Dataset, before: &Physics, after: &Physics, z: f64) -> Option<WindowCheck> {
    crate::signatures::cubic_harmonic_check(d, before, after)
        .map(|r| WindowCheck::new("the 3rd harmonic of τ_c", r, z))
        .or_else(|| {
            crate::signatures::backlash_harmonic_check(d, before, after)
                .map(|r| WindowCheck::new("the 2nd and 3rd harmonics of the SEA's torque", r, z))
        })
        .or_else(|| {
            crate::signatures::saturation_harmonic_check(d, before, after).map(|r| {
                WindowCheck::new(
                    "the 2nd and 3rd harmonics of the SEA's torque beyond its response to the command's own",
                    r,
                    z,
                )
            })
        })
}

/// The reasons, other than the amplitude check, why a candidate is not
/// accepted (empty: every criterion accepts it).
fn statistical_reasons(c: &Candidate, level: f64) -> Vec<String> {
    let mut why = Vec::new();
    if c.p_holm.is_nan() || c.p_holm >= level {
        why.push(format!(
            "F-test not significant after Holm's correction (p = {:.2e})",
            c.p_holm
        ));
    }
    if c.delta_aic.is_nan() || c.delta_aic >= 0.0 {
        why.push(format!(
            "Akaike's criterion does not fall (Δ = {:+.1})",
            c.delta_aic
        ));
    }
    if c.heldout_change.is_nan() || c.heldout_change >= 0.0 {
        why.push(format!(
            "the held-out RSS does not fall ({:+.1} %)",
            100.0 * c.heldout_change
        ));
    }
    if !c.identified {
        why.push("its parameters are not determined".into());
    }
    // A generic form is taken only on its own signature, confirmed at its
    // predicted size; any other check that is contradicted rejects.
    let own = own_signature(c);
    for w in [&c.within_window_check, &c.harmonic_check]
        .into_iter()
        .flatten()
    {
        let is_own = own.is_some_and(|o| std::ptr::eq(o, w));
        if w.contradicts || (is_own && !w.confirms) {
            why.push(w.words());
        }
    }
    if c.term.needs_own_signature() && own.is_none() {
        why.push(
            "untested: the signature it predicts beyond the transfer functions cannot be measured in these recordings"
                .into(),
        );
    }
    for t in c.tf_checks.iter().filter(|t| t.contradicts) {
        why.push(if t.rss_after > t.rss_before {
            format!(
                "{} contradicts it: the fit there gets worse beyond its noise (RSS {:.1} → {:.1}; the data follow {:.0} ± {:.0} % of the change it predicts there)",
                t.tf.name(),
                t.rss_before,
                t.rss_after,
                100.0 * t.confirmed,
                100.0 * t.confirmed_se
            )
        } else {
            format!(
                "{} contradicts it: it predicts a change there of {:.1} σ and the data follow only {:.0} ± {:.0} % of it (RSS {:.1} → {:.1})",
                t.tf.name(),
                t.moved.sqrt(),
                100.0 * t.confirmed,
                100.0 * t.confirmed_se,
                t.rss_before,
                t.rss_after
            )
        });
    }
    why
}

/// The longest sample period of the recordings (s).
fn longest_sample_period_s(d: &Dataset) -> f64 {
    d.conditions
        .iter()
        .map(|c| c.sample_period_s)
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max)
}

/// Why a fitted delay is not named: shorter than one sample period, it
/// cannot be told from how an implementation times a value within its tick
/// (a set-point held over the tick lags by half of it, one ramped over the
/// next tick by a whole one, a filter discretised by the bilinear transform
/// by none; measured: a Tustin-discretised SEA on the independent rig at
/// 500 Hz fits as a 0.85 ± 0.10 ms delay of the motor command).
/// docs/diagnose.md, "The judgement by the measured noise".
fn within_a_tick(d: &Dataset, term: Term, phys: &Physics) -> Option<String> {
    let tick_s = longest_sample_period_s(d);
    let delays: Vec<f64> = term
        .params(&[])
        .into_iter()
        .filter(|q| q.is_delay())
        .map(|q| phys.get(q))
        .collect();
    (!delays.is_empty() && delays.iter().all(|v| v.abs() < tick_s)).then(|| {
        format!(
            "a delay of {:.2} ms is within one sample period ({:.1} ms): it cannot be told from how the drive or the sensor times its sample within a tick",
            1e3 * delays.iter().fold(0.0f64, |a, v| a.max(v.abs())),
            1e3 * tick_s
        )
    })
}

/// The windows at the lowest excitation amplitude and those above it, when
/// the single-sine windows have at least two amplitudes.
#[derive(Debug, Clone)]
struct AmpGroups {
    /// Per window: 0 low, 1 high, `None` broadband.
    group: Vec<Option<u8>>,
    amplitudes: [f64; 2],
    periods: [String; 2],
}

fn amplitude_groups(d: &Dataset) -> Option<AmpGroups> {
    let amps: Vec<f64> = d
        .conditions
        .iter()
        .map(|c| c.amplitude_nm)
        .filter(|a| *a > 0.0)
        .collect();
    let lo = amps.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = amps.iter().copied().fold(0.0, f64::max);
    if amps.is_empty() || hi <= lo * 1.05 {
        return None;
    }
    let group: Vec<Option<u8>> = d
        .conditions
        .iter()
        .map(|c| (c.amplitude_nm > 0.0).then(|| u8::from(c.amplitude_nm > lo * 1.05)))
        .collect();
    let words = |g: u8| {
        let mut p: Vec<u32> = d
            .conditions
            .iter()
            .zip(&group)
            .filter(|(_, x)| **x == Some(g))
            .map(|(c, _)| c.period)
            .collect();
        p.sort_unstable();
        p.dedup();
        ranges(&p)
    };
    let mean = |g: u8| {
        let v: Vec<f64> = d
            .conditions
            .iter()
            .zip(&group)
            .filter(|(_, x)| **x == Some(g))
            .map(|(c, _)| c.amplitude_nm)
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    Some(AmpGroups {
        amplitudes: [mean(0), mean(1)],
        periods: [words(0), words(1)],
        group,
    })
}

/// `v ± se` to two significant digits of `se` (a comparison, where a value
/// within its standard error of zero is a measurement, not undetermined);
/// "not determined" only when `se` is not finite and positive.
fn plain_pm(v: f64, se: f64) -> String {
    if se.is_finite() && se > 0.0 {
        let d = (1 - se.log10().floor() as i64).clamp(0, 9) as usize;
        format!("{v:.d$} ± {se:.d$}")
    } else {
        format!("{v:.4} (not determined)")
    }
}

/// "1–7, 9" from sorted numbers.
fn ranges(p: &[u32]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < p.len() {
        let mut j = i;
        while j + 1 < p.len() && p[j + 1] == p[j] + 1 {
            j += 1;
        }
        out.push(if j > i {
            format!("{}–{}", p[i], p[j])
        } else {
            p[i].to_string()
        });
        i = j + 1;
    }
    out.join(", ")
}

/// Fits the candidate model (`fitted`, free parameters `free`) on each
/// amplitude group alone and compares the candidate's own parameters
/// (`added`) between the groups.
#[allow(clippy::too_many_arguments)]
fn amplitude_check(
    d: &Dataset,
    fitted: &Fitted,
    g: &AmpGroups,
    free: &[Param],
    added: &[Param],
    must_confirm: bool,
    shows_in_balance: bool,
    hold_shared: bool,
    level: f64,
) -> AmplitudeCheck {
    let mut fits = Vec::new();
    for grp in 0..2u8 {
        let sel = |_: usize, o: &Observation| g.group[o.window] == Some(grp);
        // Per-experiment parameters of experiments absent from the group
        // are not fitted there.
        let present: std::collections::BTreeSet<u32> = d
            .observations
            .iter()
            .filter(|o| g.group[o.window] == Some(grp))
            .map(|o| d.conditions[o.window].experiment)
            .collect();
        let f: Vec<Param> = free
            .iter()
            .copied()
            .filter(|q| match q {
                Param::K(e) | Param::H(e) => present.contains(e),
                // A form defined by its amplitude dependence: within one
                // group the angle amplitude falls with ω², so its
                // parameter trades with the shared ones (M_h above all);
                // those stay at the whole fit's values and only the
                // per-experiment K_h, H_h and the form's own are refitted.
                q if hold_shared => added.contains(q),
                _ => true,
            })
            .collect();
        fits.push(fit(d, &fitted.physics, &f, &sel));
    }
    // A group where the candidate changes the frequency responses by less
    // than the forward model's own accuracy (RMS over the group, relative
    // to each value) cannot test it: its parameter there is set by the
    // model's systematic error, not by the term (a polynomial spring at
    // the high-frequency periods, whose angle amplitude is small). A term
    // that shows in the static balance, and one whose amplitude scaling
    // must be confirmed (Coulomb friction), are always compared.
    let effect_pct: Vec<f64> = (0..2u8)
        .map(|grp| {
            let mut absent = fitted.physics.clone();
            for &q in added {
                absent.set(q, q.absent());
            }
            let rel: Vec<f64> = d
                .observations
                .iter()
                .filter(|o| o.tf.is_dynamic() && g.group[o.window] == Some(grp))
                .map(|o| {
                    let c = &d.conditions[o.window];
                    ((fitted.physics.predict(o, c) - absent.predict(o, c)).norm()
                        / o.value.norm().max(1e-12))
                    .powi(2)
                })
                .collect();
            100.0 * (rel.iter().sum::<f64>() / rel.len().max(1) as f64).sqrt()
        })
        .collect();
    let testable = must_confirm
        || shows_in_balance
        || effect_pct
            .iter()
            .all(|e| *e >= 100.0 * crate::fit::MODEL_ACCURACY);
    if !testable {
        let each: Vec<String> = (0..2)
            .map(|i| {
                format!(
                    "{:.2} % at {:.1} Nm (periods {})",
                    effect_pct[i], g.amplitudes[i], g.periods[i]
                )
            })
            .collect();
        return AmplitudeCheck {
            amplitudes_nm: g.amplitudes,
            periods: g.periods.clone(),
            params: added
                .iter()
                .map(|&q| {
                    (
                        q.label(),
                        [fits[0].physics.get(q), fits[1].physics.get(q)],
                        [
                            fits[0].std_error(q).unwrap_or(f64::NAN),
                            fits[1].std_error(q).unwrap_or(f64::NAN),
                        ],
                    )
                })
                .collect(),
            inconsistent: false,
            words: format!(
                "not compared between amplitudes: its effect on the frequency responses ({}) is within the forward model's accuracy ({:.1} %) in one group, which therefore cannot test it",
                each.join(", "),
                100.0 * crate::fit::MODEL_ACCURACY
            ),
        };
    }
    let z = normal_quantile(1.0 - level / (2.0 * added.len().max(1) as f64));
    // Materiality: the forward model's own systematic error (0.5 %, and
    // 1.7–2.5 % for friction's describing function) moves a parameter
    // fitted on part of the band by more than its noise-only standard
    // error, so a difference must also be material. The alternative to
    // "amplitude-independent" is an effect that scales with the amplitude
    // (ratio r of the groups' excitation amplitudes, or 1/r); halfway in
    // ratio is √r, so a difference counts when it exceeds 1 − 1/√r of the
    // larger value (21 % for the protocol's r = 10^0.2).
    let r = (g.amplitudes[1] / g.amplitudes[0]).max(1.0);
    let material = 1.0 - 1.0 / r.sqrt();
    let mut params = Vec::new();
    let mut inconsistent = Vec::new();
    for &q in added {
        let v = [fits[0].physics.get(q), fits[1].physics.get(q)];
        let se = [
            fits[0].std_error(q).unwrap_or(f64::NAN),
            fits[1].std_error(q).unwrap_or(f64::NAN),
        ];
        let both = se[0].is_finite() && se[1].is_finite() && se[0] > 0.0 && se[1] > 0.0;
        if must_confirm
            && !(crate::terms::determined(v[0], se[0]) && crate::terms::determined(v[1], se[1]))
        {
            inconsistent.push(format!(
                "{} is not determined at both amplitudes ({} at {:.1} Nm, periods {}; {} at {:.1} Nm, periods {}), so its 1/amplitude scaling cannot be confirmed",
                q.label(),
                plain_pm(v[0], se[0]),
                g.amplitudes[0],
                g.periods[0],
                plain_pm(v[1], se[1]),
                g.amplitudes[1],
                g.periods[1]
            ));
            params.push((q.label(), v, se));
            continue;
        }
        let diff = (v[0] - v[1]).abs();
        if both && diff > z * se[0].hypot(se[1]) && diff > material * v[0].abs().max(v[1].abs()) {
            inconsistent.push(format!(
                "{} = {} at {:.1} Nm (periods {}) but {} at {:.1} Nm (periods {})",
                q.label(),
                plain_pm(v[0], se[0]),
                g.amplitudes[0],
                g.periods[0],
                plain_pm(v[1], se[1]),
                g.amplitudes[1],
                g.periods[1]
            ));
        }
        params.push((q.label(), v, se));
    }
    let words = if inconsistent.is_empty() {
        let each: Vec<String> = params
            .iter()
            .map(|(l, v, se)| {
                format!(
                    "{l} {} and {}",
                    plain_pm(v[0], se[0]),
                    plain_pm(v[1], se[1])
                )
            })
            .collect();
        format!(
            "its parameters agree between {:.1} Nm (periods {}) and {:.1} Nm (periods {}): {}",
            g.amplitudes[0],
            g.periods[0],
            g.amplitudes[1],
            g.periods[1],
            each.join("; ")
        )
    } else {
        format!(
            "the data do not show the amplitude scaling it predicts: {} (the higher amplitude is also the higher frequencies)",
            inconsistent.join("; ")
        )
    };
    AmplitudeCheck {
        amplitudes_nm: g.amplitudes,
        periods: g.periods.clone(),
        params,
        inconsistent: !inconsistent.is_empty(),
        words,
    }
}

/// The significant candidates of the last step that were not added, each
/// with the first reason: what the data contradict.
fn not_named(steps: &[Step]) -> Vec<String> {
    let Some(last) = steps.last() else {
        return Vec::new();
    };
    // Up to three of each family tried at the last step (the catalogue,
    // the generic forms): each was its own Holm family.
    steps
        .iter()
        .filter(|s| s.step == last.step)
        .flat_map(|s| {
            s.candidates
                .iter()
                .filter(|c| !c.chosen && c.significant && !c.rejected_because.is_empty())
                .take(3)
        })
        .map(|c| {
            format!(
                "not named: {} (F = {:.1}, would explain {:.0} % of the misfit): {}",
                c.words,
                c.f,
                100.0 * c.explained_share,
                c.rejected_because.join("; ")
            )
        })
        .collect()
}

/// The nominal model's own free parameters: the human's per-experiment
/// stiffness (and hysteretic damping when the model has it), its inertia,
/// and the parameters of every term the model already has.
pub fn nominal_free(p: &Physics, experiments: &[u32], supported: &[Tf]) -> Vec<Param> {
    let mut free: Vec<Param> = experiments.iter().map(|&e| Param::K(e)).collect();
    free.push(Param::Mh);
    for t in Term::ALL.into_iter().chain(Term::FORMS) {
        if t.in_nominal(p) && t.shows_in().iter().any(|tf| supported.contains(tf)) {
            free.extend(t.params(experiments));
        }
    }
    free
}

fn summary_of(cells: &[Cell], what: &str) -> Vec<String> {
    let mut sig: Vec<&Cell> = cells.iter().filter(|c| c.significant).collect();
    if sig.is_empty() {
        return vec![format!(
            "{what}: no transfer function, band or experiment differs beyond the measured noise"
        )];
    }
    sig.sort_by(|a, b| b.chi2_per_point.total_cmp(&a.chi2_per_point));
    let mut by_tf: BTreeMap<(Tf, &'static str), Vec<&Cell>> = BTreeMap::new();
    for c in &sig {
        by_tf.entry((c.tf, c.band)).or_default().push(c);
    }
    let mut out: Vec<(f64, String)> = by_tf
        .into_iter()
        .map(|((tf, band), cs)| {
            let exps: Vec<String> = cs.iter().map(|c| c.experiment.to_string()).collect();
            let n = cs.len() as f64;
            let mag = cs.iter().map(|c| c.magnitude_pct).sum::<f64>() / n;
            let ph = cs.iter().map(|c| c.phase_deg).sum::<f64>() / n;
            let chi = cs.iter().map(|c| c.chi2_per_point).sum::<f64>() / n;
            let p = cs.iter().map(|c| c.p_value).fold(1.0, f64::min);
            (
                chi,
                format!(
                    "{what}: {} ({}) in the {band} band, experiments {}: magnitude {mag:+.1} %, phase {ph:+.2}°, {:.1}× the noise variance (p = {p:.1e}, {} cells)",
                    tf.name(),
                    tf.signals(),
                    exps.join(", "),
                    chi / if tf.is_dynamic() { 2.0 } else { 1.0 },
                    cs.len()
                ),
            )
        })
        .collect();
    out.sort_by(|a, b| b.0.total_cmp(&a.0));
    out.into_iter().map(|(_, s)| s).collect()
}

/// One row of a step: the candidate's statistics, its fit, its starting
/// model and its free parameters.
type Row = (Candidate, Fitted, Physics, Vec<Param>);

/// What every candidate of one step is fitted and judged against.
struct StepContext<'a> {
    d: &'a Dataset,
    /// `d` held to the forward model's accuracy: where a describing
    /// function is fitted and tested ([`Term::describing_function`]).
    d_floor: &'a Dataset,
    /// Whether the model holds a describing function already: then every
    /// candidate is fitted and tested on [`Self::d_floor`].
    describing_in_model: bool,
    current: &'a Fitted,
    current_start: &'a Physics,
    current_ho: f64,
    experiments: &'a [u32],
    z_tf: f64,
    amp_groups: Option<&'a AmpGroups>,
    level: f64,
}

impl StepContext<'_> {
    /// Fits each term of `tried` with the current model.
    fn evaluate(&self, tried: &[Term]) -> Vec<Row> {
        let (d, current, current_start, current_ho, experiments, z_tf) = (
            self.d,
            self.current,
            self.current_start,
            self.current_ho,
            self.experiments,
            self.z_tf,
        );
        let mut rows: Vec<Row> = Vec::new();
        // The current model refitted on the data held to the forward
        // model's accuracy, and its held-out RSS there: what a describing
        // function is compared with (the same weights on both sides).
        let floored = tried
            .iter()
            .any(|t| self.describing_in_model || t.describing_function())
            .then(|| {
                let f = fit(self.d_floor, &current.physics, &current.free, &|_, _| true);
                let ho = heldout(self.d_floor, current_start, &current.free)
                    .values()
                    .sum::<f64>();
                (f, ho)
            });
        for &t in tried {
            let held = self.describing_in_model || t.describing_function();
            let (d, current, current_ho) = match (&floored, held) {
                (Some((f, ho)), true) => (self.d_floor, f, *ho),
                _ => (d, current, current_ho),
            };
            let mut free = current.free.clone();
            let added = t.params(experiments);
            free.extend(added.iter().copied());
            // The best of the term's starting points.
            let mut best: Option<(Fitted, usize)> = None;
            // A term whose effect the refit's parameters bend to absorb is
            // also started from their values before the refit.
            let bases: &[&Physics] = if t.refits_from_nominal() {
                &[&current.physics, current_start]
            } else {
                &[&current.physics]
            };
            for i in 0.. {
                let mut more = false;
                for base in bases {
                    let mut start = (*base).clone();
                    if !t.start_variant(i, &mut start, d) {
                        break;
                    }
                    more = true;
                    let f = fit(d, &start, &free, &|_, _| true);
                    if best.as_ref().is_none_or(|(b, _)| f.rss < b.rss) {
                        best = Some((f, i));
                    }
                }
                if !more {
                    break;
                }
            }
            let Some((f1, variant)) = best else { continue };
            let dp = added.len() as f64;
            let dof = f1.n as f64 - f1.p() as f64;
            let f_stat = if dof > 0.0 && f1.rss > 0.0 {
                ((current.rss - f1.rss) / dp) / (f1.rss / dof)
            } else {
                f64::NAN
            };
            let p_value = if f_stat.is_finite() && f_stat > 0.0 {
                f_survival(f_stat, dp, dof).unwrap_or(1.0)
            } else {
                1.0
            };
            let mut cstart = current_start.clone();
            t.start_variant(variant, &mut cstart, d);
            let ho = heldout(d, &cstart, &free).values().sum::<f64>();
            let se = |q: Param| f1.std_error(q);
            // The share of the misfit beyond the noise, by the rule that
            // decides whether anything is beyond it ([`LackOfFit`]).
            let explained_share = lack_of_fit(d, &current.physics, current.p(), self.level)
                .explained_share(&lack_of_fit(d, &f1.physics, f1.p(), self.level));
            rows.push((
                Candidate {
                    term: t,
                    words: t.words(),
                    added_parameters: added.len(),
                    f: f_stat,
                    f_critical: f64::NAN,
                    p_value,
                    p_holm: f64::NAN,
                    delta_aic: f1.aic() - current.aic(),
                    heldout_change: (ho - current_ho) / current_ho.max(1e-300),
                    description: t.describe(&f1.physics, &se),
                    identified: t.identified(&f1.physics, &se, experiments),
                    tf_checks: tf_checks(d, &current.physics, &f1.physics, z_tf),
                    within_window_check: window_check(d, &current.physics, &f1.physics, z_tf),
                    harmonic_check: harmonic_check(d, &current.physics, &f1.physics, z_tf),
                    explained_share,
                    amplitude_check: None,
                    significant: false,
                    rejected_because: Vec::new(),
                    untested: false,
                    chosen: false,
                    held_to_model_accuracy: held,
                },
                f1,
                cstart,
                free,
            ));
        }
        rows
    }

    /// Holm's correction over `rows`, the reasons against each, and the
    /// most significant candidate every criterion accepts (its index).
    fn select(&self, rows: &mut [Row]) -> Option<usize> {
        let (d, experiments) = (self.d, self.experiments);
        let level = self.level;
        // Holm over the candidates of this step.
        rows.sort_by(|a, b| {
            a.0.p_value
                .total_cmp(&b.0.p_value)
                .then(a.1.rss.total_cmp(&b.1.rss))
        });
        let m = rows.len();
        let mut running: f64 = 0.0;
        for (i, r) in rows.iter_mut().enumerate() {
            let adj = ((m - i) as f64 * r.0.p_value).min(1.0);
            running = running.max(adj);
            r.0.p_holm = running;
            let level_i = level / (m - i) as f64;
            let dof = r.1.n as f64 - r.1.p() as f64;
            r.0.f_critical = exo_impedance::ftest::f_critical(
                r.0.added_parameters as f64,
                dof.max(1.0),
                level_i,
            )
            .unwrap_or(f64::NAN);
        }
        // The most significant candidate that Holm's test, Akaike's
        // criterion and the held-out error all accept, whose parameters are
        // determined, that no supported transfer function contradicts, and
        // whose parameters agree between the excitation amplitudes.
        let mut pick = None;
        for (i, r) in rows.iter_mut().enumerate() {
            r.0.significant = r.0.p_holm < level;
            let mut why = statistical_reasons(&r.0, level);
            r.0.untested = why.len() == 1
                && own_signature(&r.0).is_some_and(|w| !w.testable && !w.contradicts);
            if why.is_empty() && pick.is_none() {
                if let Some(groups) = self.amp_groups {
                    let added = r.0.term.params(experiments);
                    let check = amplitude_check(
                        if r.0.held_to_model_accuracy {
                            self.d_floor
                        } else {
                            d
                        },
                        &r.1,
                        groups,
                        &r.3,
                        &added,
                        r.0.term.amplitude_dependent(),
                        r.0.term.shows_in().contains(&Tf::Balance),
                        r.0.term.needs_two_amplitudes(),
                        level,
                    );
                    if check.inconsistent {
                        why.push(check.words.clone());
                    }
                    r.0.amplitude_check = Some(check);
                } else if r.0.term.needs_two_amplitudes() {
                    why.push(
                        "the recordings have one excitation amplitude: an amplitude-dependent form cannot be told from a frequency dependence there"
                            .into(),
                    );
                }
                if why.is_empty() {
                    pick = Some(i);
                }
            }
            r.0.rejected_because = why;
        }
        if let Some(i) = pick {
            rows[i].0.chosen = true;
        }
        pick
    }
}

/// "explains N % of the misfit left at its step", or, when nothing was
/// beyond the noise ([`crate::fit::LackOfFit`]; no term is taken then), says
/// so.
fn share_words(share: f64) -> String {
    if share.is_finite() {
        format!(
            "explains {:.0} % of the misfit left at its step",
            100.0 * share
        )
    } else {
        "nothing was beyond the noise at its step (no share defined)".into()
    }
}

/// What a term was taken on: its F-test, held-out change and share of the
/// misfit (a catalogue candidate's, or the posture form's in the 2nd
/// harmonic).
struct Evidence {
    f: f64,
    f_critical: f64,
    p_holm: f64,
    heldout_change: f64,
    explained_share: f64,
}

/// The verdict's entry for a term taken on `ev`: its sentence (a generic
/// form "discovered" or "partly explained", a catalogue term "left out" or
/// "partly explained by"), flagged marginal at [`MARGINAL_P`]. A generic
/// form's sentence has `context` before its share of the misfit, `detail`
/// after it and `tail` after the statistics.
fn found_entry(
    t: Term,
    description: String,
    ev: &Evidence,
    partial: bool,
    context: &str,
    detail: &str,
    tail: &str,
) -> Found {
    let marginal = ev.p_holm >= MARGINAL_P;
    let stats = format!(
        "F = {:.1} against a critical {:.2} (Holm-adjusted p = {:.2e}{}); held-out RSS {:+.0} %",
        ev.f,
        ev.f_critical,
        ev.p_holm,
        if marginal {
            ", marginal: not significant at 0.001, another recording may not confirm it"
        } else {
            ""
        },
        100.0 * ev.heldout_change
    );
    let share = share_words(ev.explained_share);
    let sentence = if t.generic() {
        format!(
            "{}: {}, {description}; {context}{share}{}{detail}; {stats}{tail}",
            if partial {
                "partly explained by a form outside the catalogue"
            } else {
                "discovered outside the catalogue"
            },
            t.words(),
            if partial { ", most of it remains" } else { "" }
        )
    } else if partial {
        format!(
            "partly explained by {}, {description}: it {share}; most of it remains ({stats})",
            t.words()
        )
    } else {
        format!("left out: {}, {description}; {share}; {stats}", t.words())
    };
    Found {
        term: t,
        toml_key: t.toml_key(),
        words: t.words(),
        sentence,
        description,
        f: ev.f,
        f_critical: ev.f_critical,
        p_holm: ev.p_holm,
        heldout_change: ev.heldout_change,
        explained_share: ev.explained_share,
        partial,
        discovered: t.generic(),
        marginal,
    }
}

/// Runs the whole diagnosis of `d` against the plant model `nominal`.
pub fn diagnose(
    d: &Dataset,
    nominal: &PlantModel,
    s: &Settings,
) -> Result<Diagnosis, DiagnoseError> {
    if !(s.level > 0.0 && s.level < 1.0) {
        return Err(DiagnoseError::Settings(format!(
            "level = {}: must lie in (0, 1)",
            s.level
        )));
    }
    if d.observations.is_empty() {
        return Err(DiagnoseError::NoData(if d.notes.is_empty() {
            "the recordings have no analysis windows".into()
        } else {
            d.notes.join("; ")
        }));
    }
    let experiments = d.impedance_experiments();
    let mut p0 = Physics::from_plant(nominal, &experiments);
    if let Some(subj) = &s.nominal_subject {
        for (&e, &(k, h)) in subj {
            if let Some(slot) = p0.k.get_mut(&e) {
                *slot = k;
                if nominal.human.hysteretic_damping.enabled {
                    p0.h.insert(e, h);
                }
            }
        }
    }
    let free0 = nominal_free(&p0, &experiments, &d.supported);
    let nominal_score = score(d, &p0, &p0, &[]);
    let base = fit(d, &p0, &free0, &|_, _| true);
    let refit_score = score(d, &p0, &base.physics, &free0);

    let mut changes = Vec::new();
    for (i, &q) in free0.iter().enumerate() {
        let (a, b) = (p0.get(q), base.physics.get(q));
        let pct = if a != 0.0 {
            100.0 * (b - a) / a.abs()
        } else {
            f64::NAN
        };
        changes.push(ParamChange {
            label: q.label(),
            nominal: a,
            fitted: b,
            std_error: base.std_errors[i],
            change_pct: pct,
        });
    }

    let amp_groups = amplitude_groups(d);
    let d_floor = d.held_to(crate::fit::MODEL_ACCURACY);
    // Stepwise search.
    let mut current: Fitted = base.clone();
    let mut current_start = p0.clone();
    let mut current_ho = refit_score.heldout_rss;
    // Single-sine windows, a broadband window counting once per band.
    let windows = {
        let mut w: Vec<(usize, u64)> = d
            .observations
            .iter()
            .filter(|o| o.tf.is_dynamic())
            .map(|o| (o.window, o.omega_rad_s.to_bits()))
            .collect();
        w.sort_unstable();
        w.dedup();
        w.len()
    };
    let too_few = windows < MIN_WINDOWS;
    let mut lack_p = if too_few {
        1.0
    } else {
        refit_score.lack_of_fit_p
    };
    let mut in_model: Vec<Term> = Term::ALL
        .iter()
        .chain(Term::FORMS.iter())
        .copied()
        .filter(|t| t.in_nominal(&p0))
        .collect();
    let mut steps = Vec::new();
    let mut found: Vec<(Term, Candidate, bool)> = Vec::new();
    // Delays within a tick taken into the model ([`within_a_tick`]).
    let mut within_tick: Vec<String> = Vec::new();
    // One-sided critical value of the per-transfer-function checks,
    // Bonferroni over the supported transfer functions.
    let z_tf = normal_quantile(1.0 - s.level / d.supported.len().max(1) as f64);
    for step in 1..=s.max_terms {
        // Nothing left to explain: the model is within the measured noise
        // and its own accuracy.
        if lack_p >= s.level {
            break;
        }
        let ctx = StepContext {
            d,
            d_floor: &d_floor,
            describing_in_model: in_model.iter().any(|t| t.describing_function()),
            current: &current,
            current_start: &current_start,
            current_ho,
            experiments: &experiments,
            z_tf,
            amp_groups: amp_groups.as_ref(),
            level: s.level,
        };
        let eligible = |pool: &[Term]| -> Vec<Term> {
            pool.iter()
                .copied()
                .filter(|t| !in_model.contains(t))
                .filter(|t| t.shows_in().iter().any(|tf| d.supported.contains(tf)))
                .collect()
        };
        // The catalogue, then the library of generic forms with the same
        // criteria (Holm over the forms tried); a form accepted there is
        // taken when it leaves less misfit than the catalogue's term (a
        // small catalogue term must not stand in for a form that explains
        // far more: a weak stretch reflex for a polynomial spring).
        let tried = eligible(&s.candidates);
        let mut rows = ctx.evaluate(&tried);
        let mut pick = ctx.select(&mut rows);
        let searched = !tried.is_empty();
        let catalogue_step = steps.len();
        if searched {
            steps.push(Step {
                step,
                forms: false,
                candidates: rows.iter().map(|r| r.0.clone()).collect(),
            });
        }
        let forms = eligible(&s.forms);
        // The best form every criterion accepts but for its untestable
        // signature: (its words, its RSS).
        let mut untested_form: Option<(&'static str, f64)> = None;
        if !forms.is_empty() {
            let mut form_rows = ctx.evaluate(&forms);
            let form_pick = ctx.select(&mut form_rows);
            untested_form = form_rows
                .iter()
                .filter(|r| r.0.untested)
                .map(|r| (r.0.words, r.1.rss))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let better =
                form_pick.filter(|&j| pick.is_none_or(|i| form_rows[j].1.rss < rows[i].1.rss));
            if let Some(j) = form_pick.filter(|_| better.is_none()) {
                form_rows[j].0.chosen = false;
                form_rows[j]
                    .0
                    .rejected_because
                    .push("the catalogue's term accepted at this step leaves less misfit".into());
            }
            if better.is_some() {
                if let (Some(i), true) = (pick, searched) {
                    let c = &mut steps[catalogue_step].candidates[i];
                    c.chosen = false;
                    c.rejected_because.push(format!(
                        "a generic form leaves less misfit (RSS {:.1} against {:.1})",
                        form_rows[better.unwrap_or(0)].1.rss,
                        rows[i].1.rss
                    ));
                }
                rows = form_rows.clone();
                pick = better;
            }
            steps.push(Step {
                step,
                forms: true,
                candidates: form_rows.iter().map(|r| r.0.clone()).collect(),
            });
        } else if !searched {
            break;
        }
        // A generic form that fits better than the term picked but whose
        // own signature these recordings cannot check: nothing is named at
        // this step (naming the lesser term would put a wrong name on the
        // misfit the form explains); the form is reported "untested".
        if let (Some(i), Some((form, rss))) = (pick, untested_form) {
            let rss_pick = rows[i].1.rss;
            if rss < rss_pick {
                let words = format!(
                    "{form} leaves less misfit (RSS {rss:.1} against {rss_pick:.1}) but cannot be checked by its own signature here (untested): nothing is named at this step"
                );
                for c in steps[catalogue_step..]
                    .iter_mut()
                    .flat_map(|s| s.candidates.iter_mut())
                    .filter(|c| c.chosen)
                {
                    c.chosen = false;
                    c.rejected_because.push(words.clone());
                }
                break;
            }
        }
        let Some(pick) = pick else { break };
        let (cand, f1, cstart, _free) = rows.swap_remove(pick);
        current_ho *= 1.0 + cand.heldout_change;
        in_model.push(cand.term);
        let timing = within_a_tick(d, cand.term, &f1.physics);
        current = f1;
        current_start = cstart;
        lack_p = lack_of_fit_p(d, &current.physics, current.p());
        if let Some(words) = timing {
            // Taken into the model (the rig's own timing, like any
            // parameter), not named as physics the model left out.
            within_tick.push(format!("{}: {words}", cand.words));
            continue;
        }
        // Less than half of the misfit and structure remains: a part of
        // the answer, reported as such.
        let partial =
            (cand.explained_share.is_nan() || cand.explained_share < 0.5) && lack_p < s.level;
        found.push((cand.term, cand, partial));
    }
    // The form the transfer functions cannot see: a posture-dependent
    // stiffness in the 2nd harmonic of τ_c, with the same criteria, on the
    // model the search ended with. Taken, its K₂ goes into the model and
    // the model's own parameters are refitted with it: its second-order
    // shift of the stiffness with the amplitude (`−K₂² A²/4K`) is then
    // predicted, nothing fitted for it.
    let posture = (!too_few)
        .then(|| {
            crate::posture::fit(
                d,
                &current.physics,
                s.level,
                amp_groups.as_ref().map(|g| g.group.as_slice()),
                normal_quantile(1.0 - s.level / 2.0),
            )
        })
        .flatten();
    let posture_taken = posture.as_ref().filter(|p| p.accepted);
    let mut posture_chi2 = None;
    if let Some(p) = posture_taken {
        let before = score(d, &current_start, &current.physics, &current.free);
        current_start.k2 = p.k2_nm_per_rad2;
        let mut start = current.physics.clone();
        start.k2 = p.k2_nm_per_rad2;
        let free = current.free.clone();
        current = fit(d, &start, &free, &|_, _| true);
        let after = score(d, &current_start, &current.physics, &current.free);
        posture_chi2 = Some((before.chi2_per_dof, after.chi2_per_dof));
    }
    let final_score = score(d, &current_start, &current.physics, &current.free);

    let tf_found = found.len();
    let mut found: Vec<Found> = found
        .into_iter()
        .map(|(t, c, partial)| {
            let se = |q: Param| current.std_error(q);
            let evidence = Evidence {
                f: c.f,
                f_critical: c.f_critical,
                p_holm: c.p_holm,
                heldout_change: c.heldout_change,
                explained_share: c.explained_share,
            };
            found_entry(
                t,
                t.describe(&current.physics, &se),
                &evidence,
                partial,
                "",
                "",
                "",
            )
        })
        .collect();

    if let Some(p) = posture_taken {
        let t = Term::PostureStiffness;
        let se = |q: Param| {
            if q == Param::QuadraticStiffness {
                Some(p.std_error)
            } else {
                current.std_error(q)
            }
        };
        let partial =
            (p.explained_share.is_nan() || p.explained_share < 0.5) && p.lack_of_fit_p < s.level;
        let amplitude = match p.per_amplitude {
            Some([(lo, s_lo), (hi, s_hi)]) => format!(
                "; the same at both amplitudes (K₂ {} and {}: its harmonic grows as A²)",
                plain_pm(lo, s_lo),
                plain_pm(hi, s_hi)
            ),
            None => "; one amplitude: its growth as A² not checked".into(),
        };
        let second_order = posture_chi2.map_or(String::new(), |(a, b)| {
            format!(
                "; the shift of the stiffness with the amplitude it predicts (−K₂² A²/4K, nothing fitted for it) takes the transfer functions' χ²/dof from {a:.2} to {b:.2}"
            )
        });
        let evidence = Evidence {
            f: p.f,
            f_critical: p.f_critical,
            p_holm: p.p_holm,
            heldout_change: p.heldout_change,
            explained_share: p.explained_share,
        };
        found.push(found_entry(
            t,
            t.describe(&current.physics, &se),
            &evidence,
            partial,
            "in the 2nd harmonic of τ_c, which the transfer functions do not see: it ",
            &amplitude,
            &second_order,
        ));
    }
    // Structure in the 2nd harmonic that the form does not account for.
    let harmonic_unexplained = posture
        .as_ref()
        .filter(|p| !p.accepted && p.p_holm < s.level && p.f > p.f_critical)
        .map(|p| {
            format!(
                "unexplained in the 2nd harmonic of τ_c: {}; a posture-dependent stiffness not taken: {}",
                p.finding,
                p.rejected_because.join("; ")
            )
        });

    let nominal_cells = cells(d, &p0, s.level);
    let refit_cells = cells(d, &base.physics, s.level);
    let mut summary = summary_of(&nominal_cells, "against the nominal model");
    summary.extend(summary_of(
        &refit_cells,
        "after refitting its own parameters",
    ));
    let location = Location {
        nominal_cells,
        refit_cells,
        scaling: scaling(d, &base.physics),
        time: time_rows(d, &p0, &current.physics),
        summary,
    };

    let mut verdict = Vec::new();
    let moved: Vec<&ParamChange> = changes
        .iter()
        .filter(|c| {
            c.change_pct.is_finite()
                && crate::terms::determined(c.fitted, c.std_error)
                && c.change_pct.abs()
                    > 2.0 * (100.0 * c.std_error / c.nominal.abs().max(1e-300)).max(1.0)
        })
        .collect();
    let improvement = 1.0 - refit_score.rss / nominal_score.rss.max(1e-300);
    if !moved.is_empty() {
        let words: Vec<String> = moved
            .iter()
            .take(6)
            .map(|c| {
                format!(
                    "{} {:+.0} % ({:.4} → {:.4})",
                    c.label, c.change_pct, c.nominal, c.fitted
                )
            })
            .collect();
        verdict.push(format!(
            "same physics, other parameters: {}{}; RSS −{:.0} %",
            words.join(", "),
            if moved.len() > 6 {
                format!(" and {} more", moved.len() - 6)
            } else {
                String::new()
            },
            100.0 * improvement
        ));
    }
    verdict.extend(within_tick.iter().map(|w| {
        format!("the rig's timing, taken into the model and not named as missing physics: {w}")
    }));
    // What remains is described against the lines' own noise and the
    // forward model's accuracy (the materiality rule's size): a strongly
    // nonlinear response that the local polynomials took for a transient
    // would otherwise widen the very values that show it.
    let remains = crate::remains::characterise(&d_floor, &current.physics, s.level);
    // Where structure remains, how it depends on amplitude and operating
    // point (only the significant findings, or that one amplitude cannot tell).
    let remains_words: Vec<String> = remains
        .iter()
        .flat_map(|r| r.findings.iter().cloned())
        .map(|w| format!("what remains: {w}"))
        .collect();
    // Exclusive verdicts: "no missing physics" only when nothing beyond the
    // noise remains; otherwise what remains is said, never both.
    let beyond_noise = |p: f64| p < s.level;
    let harmonic_words: Vec<String> = found[tf_found..]
        .iter()
        .map(|f| f.sentence.clone())
        .chain(harmonic_unexplained)
        .collect();
    let found_tf = &found[..tf_found];
    if too_few {
        verdict.push(format!(
            "too few analysis windows to tell structure from noise ({windows}; at least {MIN_WINDOWS}): nothing is named (the model's own parameters, refitted, are above)"
        ));
    } else if found_tf.is_empty() {
        if beyond_noise(final_score.lack_of_fit_p) {
            verdict.push(format!(
                "unexplained: structure beyond the measured noise remains after the refit (χ²/dof {:.2}, lack-of-fit p = {:.1e}) and no term of the catalogue nor generic form of the library explains it and passes every check (each not named is listed with its reason)",
                final_score.chi2_per_dof, final_score.lack_of_fit_p
            ));
            verdict.extend(not_named(&steps));
            verdict.extend(remains_words.iter().cloned());
        } else {
            verdict.push(format!(
                "no missing physics{}: after the refit {}",
                if harmonic_words.is_empty() {
                    ""
                } else {
                    " in the transfer functions"
                },
                final_score.within_words(s.level, "the model")
            ));
        }
    } else {
        for f in found_tf {
            verdict.push(f.sentence.clone());
        }
        verdict.push(format!(
            "with {} added: RSS {:.1} → {:.1} ({:+.0} %), held-out {:+.0} %, χ²/dof {:.2} → {:.2}; {}",
            found_tf
                .iter()
                .map(|f| f.words)
                .collect::<Vec<_>>()
                .join(" and "),
            refit_score.rss,
            final_score.rss,
            100.0 * (final_score.rss / refit_score.rss - 1.0),
            100.0 * (final_score.heldout_rss / refit_score.heldout_rss - 1.0),
            refit_score.chi2_per_dof,
            final_score.chi2_per_dof,
            if beyond_noise(final_score.lack_of_fit_p) {
                format!(
                    "structure beyond the measured noise remains unexplained (lack-of-fit p = {:.1e})",
                    final_score.lack_of_fit_p
                )
            } else {
                final_score.within_words(s.level, "the rest")
            }
        ));
        if beyond_noise(final_score.lack_of_fit_p) {
            verdict.extend(not_named(&steps));
            verdict.extend(remains_words.iter().cloned());
        }
    }
    verdict.extend(harmonic_words);
    // Where the posture differs: a static offset, said apart from the
    // dynamics (it is no term of the search).
    let equilibrium = (!too_few)
        .then(|| crate::equilibrium::locate(d, &current.physics, s.level))
        .flatten();
    verdict.extend(equilibrium.as_ref().and_then(|e| e.sentence()));

    Ok(Diagnosis {
        sources: d.sources.clone(),
        supported: d.supported.clone(),
        notes: d.notes.clone(),
        location,
        nominal: nominal_score,
        refit: refit_score,
        parameter_changes: changes,
        steps,
        found,
        within_tick,
        level: s.level,
        final_score,
        verdict,
        nominal_physics: p0,
        refit_physics: base.physics,
        remains,
        final_physics: current.physics,
        posture,
        equilibrium,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::Condition;

    /// Why a misfit is no missing physics, in words: within the noise
    /// (its test's p at or above the level), or beyond it by less than the
    /// forward model's accuracy (the excess and the accuracy in %).
    #[test]
    fn a_misfit_within_the_noise_or_the_accuracy_is_said_so() {
        let score = |noise_p: f64| Score {
            per_tf: Vec::new(),
            rss: 1.0,
            heldout_rss: 1.0,
            chi2_per_dof: 1.14,
            lack_of_fit_p: 1.0,
            noise_p,
            excess: 0.0021,
            parameters: 3,
        };
        assert_eq!(
            score(0.2).within_words(0.05, "the rest"),
            "the rest is within the measured noise (χ²/dof 1.14, lack-of-fit p = 0.20)"
        );
        assert_eq!(
            score(0.01).within_words(0.05, "the model"),
            "the model is beyond the measured noise (χ²/dof 1.14, p = 1.0e-2) by 0.21 % of the values, within the forward model's accuracy (0.5 %)"
        );
        // At the level itself: not beyond.
        assert!(score(0.05)
            .within_words(0.05, "x")
            .starts_with("x is within"));
    }

    /// The verdict's "not named" lines: of the last step only, up to three
    /// of each family tried there (four significant, rejected catalogue
    /// terms and two such forms give 3 + 2 lines), never a chosen one, one
    /// not significant or one without a reason.
    #[test]
    fn not_named_lists_three_of_each_family_of_the_last_step() {
        let cand = |term: Term, significant: bool, chosen: bool, why: &[&str]| Candidate {
            term,
            words: term.words(),
            added_parameters: 1,
            f: 10.0,
            f_critical: 5.0,
            p_value: 1e-3,
            p_holm: 1e-3,
            delta_aic: -5.0,
            heldout_change: -0.1,
            description: String::new(),
            identified: true,
            tf_checks: Vec::new(),
            within_window_check: None,
            harmonic_check: None,
            explained_share: 0.5,
            amplitude_check: None,
            significant,
            rejected_because: why.iter().map(|w| w.to_string()).collect(),
            untested: false,
            chosen,
            held_to_model_accuracy: false,
        };
        let catalogue = [
            Term::EncoderDelay,
            Term::CuffCompliance,
            Term::InertiaError,
            Term::GravityError,
        ];
        let step = |n: usize, forms: bool, c: Vec<Candidate>| Step {
            step: n,
            forms,
            candidates: c,
        };
        let steps = vec![
            // An earlier step: never listed.
            step(
                1,
                false,
                vec![cand(Term::SeaSensorGain, true, false, &["earlier"])],
            ),
            step(
                2,
                false,
                // The ones never listed first, so that the three taken
                // are the right three.
                [
                    cand(Term::ActuatorDelay, true, true, &["chosen"]),
                    cand(Term::CuffSensorGain, false, false, &["not significant"]),
                    cand(Term::SeaSensorDelay, true, false, &[]),
                ]
                .into_iter()
                .chain(catalogue.iter().map(|&t| cand(t, true, false, &["why"])))
                .collect(),
            ),
            step(
                2,
                true,
                vec![
                    cand(Term::CubicStiffness, true, false, &["harmonic"]),
                    cand(Term::Backlash, true, false, &["amplitude"]),
                ],
            ),
        ];
        let lines = not_named(&steps);
        let want: Vec<String> = catalogue[..3]
            .iter()
            .map(|t| (t, "why"))
            .chain([
                (&Term::CubicStiffness, "harmonic"),
                (&Term::Backlash, "amplitude"),
            ])
            .map(|(t, why)| {
                format!(
                    "not named: {} (F = 10.0, would explain 50 % of the misfit): {why}",
                    t.words()
                )
            })
            .collect();
        assert_eq!(lines, want);
        assert!(not_named(&[]).is_empty());
    }

    /// A delay is timing only while every delay the term fits is shorter
    /// than the recordings' longest sample period (two windows: 1 ms and
    /// 2 ms ticks, so 2 ms is the bound); a term without a delay, or a
    /// reflex's delay, is never timing.
    #[test]
    fn a_delay_is_timing_only_within_the_longest_tick() {
        let plant = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        let mut p = Physics::from_plant(&PlantModel::from_file(&plant).unwrap(), &[1]);
        let window = |dt: f64| Condition {
            experiment: 1,
            period: 1,
            load_kg: 0.0,
            bias_nm: 0.0,
            alpha: 1.0,
            amplitude_nm: 2.0,
            theta0_rad: 0.0,
            theta_amp_rad: 0.1,
            sin_theta_mean: 0.0,
            tau_s_mean_nm: f64::NAN,
            tau_c_mean_nm: 0.0,
            command: None,
            gravity: None,
            sample_period_s: dt,
            start_s: 0.0,
            elapsed_s: 0.0,
        };
        let d = Dataset {
            conditions: vec![window(0.001), window(0.002)],
            ..Dataset::default()
        };
        assert_eq!(longest_sample_period_s(&d), 0.002);
        p.delay_s = [0.0, 0.0, 0.0, 0.00085];
        let words = within_a_tick(&d, Term::ActuatorDelay, &p).expect("within a tick");
        assert!(
            words.contains("0.85 ms") && words.contains("(2.0 ms)"),
            "{words}"
        );
        // A negative delay of the same size is as much within the tick.
        p.delay_s[3] = -0.00085;
        assert!(within_a_tick(&d, Term::ActuatorDelay, &p).is_some());
        // Beyond the longest tick (but within the shorter one's double).
        p.delay_s[3] = 0.0021;
        assert_eq!(within_a_tick(&d, Term::ActuatorDelay, &p), None);
        // Exactly one tick is not within it.
        p.delay_s[3] = 0.002;
        assert_eq!(within_a_tick(&d, Term::ActuatorDelay, &p), None);
        // Each catalogue delay reads its own parameter.
        p.delay_s = [0.0005, 0.003, 0.003, 0.003];
        assert!(within_a_tick(&d, Term::EncoderDelay, &p).is_some());
        assert_eq!(within_a_tick(&d, Term::CuffSensorDelay, &p), None);
        p.delay_s = [0.003, 0.0005, 0.003, 0.003];
        assert!(within_a_tick(&d, Term::CuffSensorDelay, &p).is_some());
        p.delay_s = [0.003, 0.003, 0.0005, 0.003];
        assert!(within_a_tick(&d, Term::SeaSensorDelay, &p).is_some());
        // A term with no delay, and a reflex (its delay is physiology).
        assert_eq!(within_a_tick(&d, Term::CuffCompliance, &p), None);
        p.reflex = [1.0, 0.0005, 15.0];
        assert_eq!(within_a_tick(&d, Term::StretchReflex, &p), None);
        assert!(Param::DelayAct.is_delay() && !Param::ReflexDelay.is_delay());
    }

    /// The signature rule with the numbers written out (z = 2): present
    /// beyond the noise (`β > z·se`) and between half and twice the
    /// predicted size; too small to check when even `β = 1` would not be
    /// beyond the noise (`z·se ≥ 1`); contradicted when it moves the
    /// prediction by a noise σ or more and `β < ½ − z·se`.
    #[test]
    fn a_signature_is_confirmed_present_and_at_its_predicted_size() {
        let check =
            |beta: f64, se: f64, moved: f64| WindowCheck::new("s", (moved, beta, se, 10), 2.0);
        // The rig's backlash (β = 0.83 ± 0.01) and 5 %/min drift (0.88 ± 0.22).
        for (b, se) in [(0.83, 0.01), (0.88, 0.22), (0.5, 0.2), (2.0, 0.1)] {
            let c = check(b, se, 100.0);
            assert!(c.confirms && c.testable && !c.contradicts, "{b} ± {se}");
        }
        // Present but too small, or far too large: not at its size.
        for (b, se) in [(0.45, 0.01), (2.05, 0.01)] {
            assert!(!check(b, se, 100.0).confirms, "{b} ± {se}");
        }
        // At its size but not beyond the noise: β = 0.8 ± 0.41 (z·se = 0.82).
        assert!(!check(0.8, 0.41, 100.0).confirms);
        // Testable up to z·se < 1.
        assert!(check(0.8, 0.49, 100.0).testable);
        assert!(!check(0.73, 0.54, 5.0).testable);
        // Contradicted: β = 0 ± 0.1 against ½ − 0.2; not below a σ moved.
        assert!(check(0.0, 0.1, 100.0).contradicts);
        assert!(!check(0.0, 0.1, 0.9).contradicts);
        assert!(!check(0.31, 0.1, 100.0).contradicts);
        assert!(check(0.29, 0.1, 100.0).contradicts);
    }

    /// The reason a form is not taken names its signature, the size it
    /// predicted and what the data showed, in each of the three cases.
    #[test]
    fn a_signatures_words_say_what_was_predicted_and_seen() {
        let w = |beta: f64, se: f64| {
            WindowCheck::new("the 3rd harmonic of τ_c", (400.0, beta, se, 30), 2.0).words()
        };
        assert_eq!(
            w(0.0, 0.05),
            "the 3rd harmonic of τ_c it predicts (20.0 σ over 30 values) is not in the data: the data show 0 ± 5 % of it"
        );
        assert!(w(0.73, 0.54).contains("too small to check in these recordings (untested)"));
        assert!(
            w(0.4, 0.05).contains("not confirmed at its predicted size: the data show 40 ± 5 %")
        );
    }
}
