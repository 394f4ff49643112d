//! The implementation's timing within a tick, taken into the nominal model
//! before the search (issue 30 item 3).
//!
//! Our forward model is continuous in time. An implementation times each
//! value within its tick in its own way: a set-point held over the tick lags
//! by half of it, one ramped over the next tick by a whole one, a filter
//! discretised by the bilinear transform by none. That is no physics the
//! model left out ([`super::checks::within_a_tick`]), yet on a recording long
//! enough it is beyond the noise: the independent rig's Tustin-discretised
//! SEA at 500 Hz left the refitted nominal model at χ²/dof 1.3–1.8 (its
//! `τ_s/τ_d` at 2.4 per residual), while its misfit was within the forward
//! model's accuracy, so the search never ran and the noise model looked
//! generous where the model was short.
//!
//! So when the refit is beyond the measured noise but within the forward
//! model's accuracy (the search would not run), the delay the search would
//! take first (every criterion of a step: Holm's F-test, Akaike's
//! criterion, the held-out error, determined, no transfer function
//! contradicting it) is taken into the model when it is shorter than one
//! sample period, and said as the rig's timing. A delay of a tick or more,
//! or a misfit beyond the accuracy, is left to the search as before: no
//! catalogue case's diagnosis changes by this step.

use crate::data::Dataset;
use crate::fit::Fitted;
use crate::model::Physics;
use crate::terms::Term;

use super::checks::within_a_tick;
use super::score::{score, Score};
use super::search::StepContext;

/// A delay within one tick taken into the nominal model.
#[derive(Debug, Clone)]
pub(super) struct Timing {
    /// The term (a delay of the catalogue).
    pub(super) term: Term,
    /// The model refitted with it.
    pub(super) fitted: Fitted,
    /// Its sentence: "<term>: a delay of … is within one sample period …".
    pub(super) words: String,
}

/// The delay within a tick to take into the refitted nominal model
/// `ctx.current` (scored `refit_score`), among the delays of `candidates`,
/// or `None` (the refit within the noise, or beyond the accuracy, or no
/// delay within a tick that every criterion accepts).
pub(super) fn implementation_timing(
    ctx: &StepContext,
    refit_score: &Score,
    candidates: &[Term],
) -> Option<Timing> {
    // Within the noise: nothing to take. Beyond the accuracy: the search
    // runs and takes a delay within a tick itself when it is the best term.
    if refit_score.noise_p >= ctx.level || refit_score.lack_of_fit_p < ctx.level {
        return None;
    }
    let d = ctx.d;
    let tried: Vec<Term> = candidates
        .iter()
        .copied()
        .filter(|t| t.is_delay())
        .filter(|t| t.shows_in().iter().any(|tf| d.supported.contains(tf)))
        .collect();
    if tried.is_empty() {
        return None;
    }
    let mut rows = ctx.evaluate(&tried);
    let pick = ctx.select(&mut rows)?;
    let (cand, fitted, _, _) = rows.swap_remove(pick);
    let words = within_a_tick(d, cand.term, &fitted.physics)?;
    Some(Timing {
        term: cand.term,
        words: format!("{}: {words}", cand.words),
        fitted,
    })
}

/// The score of a timing's model, as [`score`] of the refit.
pub(super) fn score_with(d: &Dataset, nominal: &Physics, t: &Timing) -> Score {
    score(d, nominal, &t.fitted.physics, &t.fitted.free)
}
