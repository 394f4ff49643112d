//! The stepwise search: every candidate of a step fitted with the current
//! model and judged ([`StepContext`]: Holm's correction, Akaike's criterion,
//! the held-out error and the checks of [`super::checks`]), the rows of a
//! step ([`Candidate`], [`Step`]) with the reasons against each in words,
//! the nominal model's own free parameters, and the verdict's entry for each
//! term taken ([`Found`]) or not named.

use exo_impedance::ftest::f_survival;
use serde::Serialize;

use crate::data::{Dataset, Tf};
use crate::fit::{fit, lack_of_fit, Fitted};
use crate::model::{Param, Physics};
use crate::terms::Term;

use super::checks::{amplitude_check, harmonic_check, tf_checks, window_check, AmpGroups};
use super::score::heldout;
use super::{AmplitudeCheck, TfCheck, WindowCheck, MARGINAL_P};

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

/// The significant candidates of the last step that were not added, each
/// with the first reason: what the data contradict.
pub(super) fn not_named(steps: &[Step]) -> Vec<String> {
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

/// One row of a step: the candidate's statistics, its fit, its starting
/// model and its free parameters.
type Row = (Candidate, Fitted, Physics, Vec<Param>);

/// What every candidate of one step is fitted and judged against.
pub(super) struct StepContext<'a> {
    pub(super) d: &'a Dataset,
    /// `d` held to the forward model's accuracy: where a describing
    /// function is fitted and tested ([`Term::describing_function`]).
    pub(super) d_floor: &'a Dataset,
    /// Whether the model holds a describing function already: then every
    /// candidate is fitted and tested on [`Self::d_floor`].
    pub(super) describing_in_model: bool,
    pub(super) current: &'a Fitted,
    pub(super) current_start: &'a Physics,
    pub(super) current_ho: f64,
    pub(super) experiments: &'a [u32],
    pub(super) z_tf: f64,
    pub(super) amp_groups: Option<&'a AmpGroups>,
    pub(super) level: f64,
}

impl StepContext<'_> {
    /// Fits each term of `tried` with the current model.
    pub(super) fn evaluate(&self, tried: &[Term]) -> Vec<Row> {
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
    pub(super) fn select(&self, rows: &mut [Row]) -> Option<usize> {
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
pub(super) struct Evidence {
    pub(super) f: f64,
    pub(super) f_critical: f64,
    pub(super) p_holm: f64,
    pub(super) heldout_change: f64,
    pub(super) explained_share: f64,
}

/// The verdict's entry for a term taken on `ev`: its sentence (a generic
/// form "discovered" or "partly explained", a catalogue term "left out" or
/// "partly explained by"), flagged marginal at [`MARGINAL_P`]. A generic
/// form's sentence has `context` before its share of the misfit, `detail`
/// after it and `tail` after the statistics.
pub(super) fn found_entry(
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
