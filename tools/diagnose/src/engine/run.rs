//! [`diagnose`]: the whole run. The refit of the nominal model's own
//! parameters ([`ParamChange`]), the search loop over the catalogue and the
//! library of generic forms, the posture form in the 2nd harmonic, the
//! location, what remains and the verdict.

use exo_plant_model::PlantModel;
use serde::Serialize;

use crate::data::Dataset;
use crate::fit::{fit, lack_of_fit_p, Fitted};
use crate::model::{Param, Physics};
use crate::stats::normal_quantile;
use crate::terms::Term;

use super::checks::{amplitude_groups, per_tf_critical_z, plain_pm, within_a_tick};
use super::locate::{cells, scaling, summary_of, time_rows};
use super::score::score;
use super::search::{found_entry, not_named, Evidence, StepContext};
use super::timing::{implementation_timing, score_with};
use super::{
    nominal_free, Candidate, DiagnoseError, Diagnosis, Found, Location, Settings, Step, MIN_WINDOWS,
};

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
    let mut free0 = nominal_free(&p0, &experiments, &d.supported);
    let nominal_score = score(d, &p0, &p0, &[]);
    let mut base = fit(d, &p0, &free0, &|_, _| true);
    let mut refit_score = score(d, &p0, &base.physics, &free0);
    let z_tf = per_tf_critical_z(s.level, d.supported.len());
    let d_floor = d.held_to(crate::fit::MODEL_ACCURACY);
    // The rig's timing within a tick, when only the noise sees it: part of
    // the refitted nominal model ([`implementation_timing`]).
    let timing = implementation_timing(
        &StepContext {
            d,
            d_floor: &d_floor,
            describing_in_model: false,
            current: &base,
            current_start: &p0,
            current_ho: refit_score.heldout_rss,
            experiments: &experiments,
            z_tf,
            amp_groups: None,
            level: s.level,
        },
        &refit_score,
        &s.candidates,
    );
    if let Some(t) = &timing {
        refit_score = score_with(d, &p0, t);
        base = t.fitted.clone();
        free0 = base.free.clone();
    }

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
        .chain(timing.as_ref().map(|t| t.term))
        .collect();
    let mut steps = Vec::new();
    let mut found: Vec<(Term, Candidate, bool)> = Vec::new();
    // Delays within a tick taken into the model ([`within_a_tick`]).
    let mut within_tick: Vec<String> = timing.iter().map(|t| t.words.clone()).collect();
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
