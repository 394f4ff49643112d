//! The checks a candidate is judged by beyond its F-test: what it does to
//! each supported transfer function ([`TfCheck`]), its own signature within
//! the windows or in the harmonics ([`WindowCheck`]), its parameters fitted
//! at each excitation amplitude ([`AmplitudeCheck`]), and a delay within one
//! sample period.

use num_complex::Complex64;
use serde::Serialize;

use crate::data::{Dataset, Observation, Tf};
use crate::fit::{fit, sigma_floor, Fitted};
use crate::model::{Param, Physics};
use crate::stats::normal_quantile;
use crate::terms::Term;

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
/// half of each window to its second, [`crate::data::within_window_rates`])
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
    pub(super) fn new(
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
    pub(super) fn words(&self) -> String {
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
pub(super) fn window_check(
    d: &Dataset,
    before: &Physics,
    after: &Physics,
    z: f64,
) -> Option<WindowCheck> {
    let (mut ym, mut mm, mut rows) = (0.0, 0.0, Vec::new());
    for tf in [Tf::Sh, Tf::She] {
        if !d.supported.contains(&tf) {
            continue;
        }
        for r in crate::data::within_window_rates(d, tf) {
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

/// What `after` does to each supported transfer function compared with
/// `before` ([`TfCheck`]), `z` the one-sided critical value.
pub(super) fn tf_checks(d: &Dataset, before: &Physics, after: &Physics, z: f64) -> Vec<TfCheck> {
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

/// The harmonic check of the change from `before` to `after`: the 3rd
/// harmonic of `τ_c` for the polynomial spring and the cubic damper, the
/// 2nd and 3rd of the SEA's torque for backlash and, beyond the SEA's
/// response to the command's own, for the torque limit; `None` when
/// `after` predicts no harmonic.
pub(super) fn harmonic_check(
    d: &Dataset,
    before: &Physics,
    after: &Physics,
    z: f64,
) -> Option<WindowCheck> {
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

/// The longest sample period of the recordings (s).
pub(super) fn longest_sample_period_s(d: &Dataset) -> f64 {
    d.conditions
        .iter()
        .map(|c| c.sample_period_s)
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max)
}

/// The one-sided critical value of the checks made per transfer function
/// (a candidate's change on each, its window and harmonic signatures):
/// the normal quantile at `level`, Bonferroni over the `supported`
/// transfer functions (at least one).
pub(super) fn per_tf_critical_z(level: f64, supported: usize) -> f64 {
    crate::stats::normal_quantile(1.0 - level / supported.max(1) as f64)
}

/// Why a fitted delay is not named: shorter than one sample period, it
/// cannot be told from how an implementation times a value within its tick
/// (a set-point held over the tick lags by half of it, one ramped over the
/// next tick by a whole one, a filter discretised by the bilinear transform
/// by none; measured: a Tustin-discretised SEA on the independent rig at
/// 500 Hz fits as a 0.85 ± 0.10 ms delay of the motor command).
/// docs/diagnose.md, "The judgement by the measured noise".
pub(super) fn within_a_tick(d: &Dataset, term: Term, phys: &Physics) -> Option<String> {
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
pub(super) struct AmpGroups {
    /// Per window: 0 low, 1 high, `None` broadband.
    pub(super) group: Vec<Option<u8>>,
    amplitudes: [f64; 2],
    periods: [String; 2],
}

pub(super) fn amplitude_groups(d: &Dataset) -> Option<AmpGroups> {
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
pub(super) fn plain_pm(v: f64, se: f64) -> String {
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
pub(super) fn amplitude_check(
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
