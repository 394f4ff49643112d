//! The diagnosis's nested F-test and Holm's correction recomputed by hand
//! from its public output (issue 23).
//!
//! A concealed hysteretic damping (`jH` per experiment: three parameters
//! added at once) behind a viscous nominal model, simulated in process. For
//! every step of the search this test recomputes, with the formulas written
//! here:
//! - the degrees of freedom `(Δp, n − p₁)`: Δp = the term's added parameters,
//!   n = the real residuals of the dataset, p₁ = the current model's free
//!   parameters plus Δp;
//! - the raw p-value `P(F_{Δp, n−p₁} > F)` (`f_survival`, itself pinned to
//!   scipy in `shared/impedance/tests/ftest_scipy.rs`);
//! - Holm's step-down adjustment over the m candidates of the step, sorted
//!   by raw p: `p̃_(i) = max_{j ≤ i} min(1, (m − j + 1) p_(j))`;
//! - the critical value at the candidate's Holm level `α/(m − i + 1)`;
//!
//! And for the term found, its F statistic from the two models' residual
//! sums, `F = ((RSS₀ − RSS₁)/Δp) / (RSS₁/(n − p₁))`, and its held-out
//! change. Then the location and what remains: each transfer function's R²
//! from its definition, the sign of the residual phase's correlation with
//! ω (the physics of hysteresis behind a viscous model), the 2.5ω floor at
//! the noise level of the harmonics, the bands' χ² pooling to the whole,
//! and the within-window rates of a non-drifting plant as noise.

use crate::common;
use common::default_plant;

use exo_diagnose::data::within_window_rates;
use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::fit::rss;
use exo_diagnose::remains::characterise;
use exo_diagnose::synth::{synthesize, SynthPeriod, SynthSettings};
use exo_diagnose::{diagnose, Settings, Term, Tf};
use exo_impedance::ftest::{f_critical, f_survival};

/// Three experiments of ten periods, as in `tests/it/engine.rs`.
fn protocol() -> Vec<SynthPeriod> {
    common::protocol(&[
        (1, 15.0, 5.0, 0.0, 0.0),
        (2, 30.0, 10.0, 4.5, 0.0),
        (3, 45.0, 14.0, 0.0, 3.0),
    ])
}

fn close(what: &str, got: f64, want: f64, tol: f64) {
    if got == want {
        return; // includes a p-value that underflows to 0 on both sides
    }
    let rel = ((got - want) / want).abs();
    assert!(
        rel <= tol,
        "{what}: {got:e} vs hand-computed {want:e} (relative {rel:.2e})"
    );
}

#[test]
fn f_test_degrees_of_freedom_and_holm_match_the_hand_computation() {
    let truth = default_plant();
    let mut nominal = truth;
    nominal.human.hysteretic_damping.enabled = false;
    nominal.human.viscous_damping.enabled = true;
    nominal.human.viscous_damping.b_nm_s_per_rad = 1.0;
    let rec = synthesize(&truth, &protocol(), &SynthSettings::default());
    let d = reduce(&[rec], &Reduction::default());
    let s = Settings::default();
    let r = diagnose(&d, &nominal, &s).expect("diagnosis");

    let experiments = d.impedance_experiments();
    let (_, n) = rss(&d, &r.refit_physics, &|_, _| true);
    let n = n as f64;
    let mut p_current = r.refit.parameters as f64;
    let mut nontrivial_holm = false;
    assert!(!r.steps.is_empty());
    // A step number has the catalogue's candidates and then the library's
    // forms, both fitted against the same current model: the chosen term's
    // parameters count from the next step number on.
    let (mut pending, mut last_step) = (0.0, 0);
    for step in &r.steps {
        if step.step != last_step {
            p_current += pending;
            pending = 0.0;
            last_step = step.step;
        }
        let c = &step.candidates;
        let m = c.len();
        // Sorted by raw p (ties by fit), as Holm's procedure needs.
        assert!(c.windows(2).all(|w| w[0].p_value <= w[1].p_value));
        let mut running: f64 = 0.0;
        for (i, cand) in c.iter().enumerate() {
            eprintln!(
                "step {} {:?}: Δp {} F {:.3} p {:.3e} Holm {:.3e} crit {:.3}",
                step.step,
                cand.term,
                cand.added_parameters,
                cand.f,
                cand.p_value,
                cand.p_holm,
                cand.f_critical
            );
            let dp = cand.term.params(&experiments).len();
            assert_eq!(cand.added_parameters, dp, "{:?}", cand.term);
            let dof = n - (p_current + dp as f64);
            if cand.f.is_finite() && cand.f > 0.0 {
                close(
                    &format!("step {} {:?} p", step.step, cand.term),
                    cand.p_value,
                    f_survival(cand.f, dp as f64, dof).unwrap(),
                    1e-12,
                );
            } else {
                assert_eq!(cand.p_value, 1.0);
            }
            let holm = ((m - i) as f64 * cand.p_value).min(1.0);
            running = running.max(holm);
            close(
                &format!("step {} {:?} Holm", step.step, cand.term),
                cand.p_holm,
                running,
                1e-12,
            );
            if m - i > 1 && holm < 1.0 && cand.p_value > 0.0 {
                nontrivial_holm = true;
            }
            close(
                &format!("step {} {:?} critical", step.step, cand.term),
                cand.f_critical,
                f_critical(dp as f64, dof, s.level / (m - i) as f64).unwrap(),
                1e-12,
            );
        }
        if let Some(ch) = c.iter().find(|c| c.chosen) {
            pending += ch.added_parameters as f64;
        }
    }
    assert!(
        nontrivial_holm,
        "no candidate where Holm's factor changes the p-value"
    );

    // The term found and its F from the two models' residual sums.
    assert_eq!(
        r.found.len(),
        1,
        "found {:?}",
        r.found.iter().map(|f| f.term).collect::<Vec<_>>()
    );
    assert_eq!(r.found[0].term, Term::HystereticDamping);
    let dp = experiments.len() as f64;
    assert!(dp > 1.0, "the check of F's division by Δp needs Δp > 1");
    let (rss0, _) = rss(&d, &r.refit_physics, &|_, _| true);
    let (rss1, _) = rss(&d, &r.final_physics, &|_, _| true);
    let p1 = r.refit.parameters as f64 + dp;
    assert_eq!(r.final_score.parameters as f64, p1);
    let f = ((rss0 - rss1) / dp) / (rss1 / (n - p1));
    close("F of the term found", r.found[0].f, f, 1e-9);
    // Its held-out change: the relative change of the two-fold held-out
    // RSS, refitted model to final model (one term found).
    close(
        "held-out change of the term found",
        r.found[0].heldout_change,
        r.final_score.heldout_rss / r.refit.heldout_rss - 1.0,
        1e-9,
    );
    assert!(r.found[0].heldout_change < 0.0);

    // Where the refitted (viscous) model misses: its damping B·ω grows with
    // ω while the truth's H does not, so the residual's phase, arg(S/Ŝ),
    // falls with ω in S_h and S_h-e (correlations −0.46 and −0.52 measured).
    // Every correlation lies in [−1, 1] (Cauchy–Schwarz).
    for sc in &r.location.scaling {
        eprintln!("{sc:?}");
        for c in [
            sc.with_inverse_amplitude,
            sc.with_stiffness,
            sc.phase_with_omega,
        ] {
            assert!(c.is_nan() || c.abs() <= 1.0, "{sc:?}");
        }
        if matches!(sc.tf, Tf::Sh | Tf::She) {
            assert!(
                sc.phase_with_omega < -0.3,
                "{:?}: the residual's phase does not fall with ω ({})",
                sc.tf,
                sc.phase_with_omega
            );
        }
    }
    // The plant is linear (hysteresis as an equivalent viscous damping), so
    // the content at 2ω, 3ω and at the floor's 2.5ω is all sensor noise, of
    // one size: the floor within a factor 3 of the larger harmonic.
    for t in &r.location.time {
        eprintln!("{t:?}");
        let top = t.harmonics[0].max(t.harmonics[1]);
        assert!(
            t.floor > 0.0 && t.floor < 3.0 * top,
            "experiment {} {}: floor {} against harmonics {:?}",
            t.experiment,
            t.channel,
            t.floor,
            t.harmonics
        );
    }
    // What remains of the final model: each band's χ² per component is the
    // mean of z² over the band's components, so the bands' means weighted
    // by their points give the transfer function's (measured: 0.075 for
    // S_h from bands of 12, 9 and 9 points).
    for rem in characterise(&d, &r.final_physics, s.level) {
        if !rem.tf.is_dynamic() || rem.bands.is_empty() {
            continue;
        }
        let points: usize = rem.bands.iter().map(|b| b.points).sum();
        let pooled = rem
            .bands
            .iter()
            .map(|b| b.chi2_per_component * b.points as f64)
            .sum::<f64>()
            / points as f64;
        close(
            &format!("{:?}: the bands' χ² pooled", rem.tf),
            pooled,
            rem.chi2_per_component,
            1e-9,
        );
    }
    // The plant does not drift: the change of S_h between the halves of a
    // window is noise, rate/σ standard normal (mean z² 1.29 over 36
    // components measured; its standard deviation is √(2/36) = 0.24).
    let rates = within_window_rates(&d, Tf::Sh);
    assert!(rates.len() >= 10, "{} windows with a rate", rates.len());
    let z2 = rates
        .iter()
        .map(|x| (x.rate[0] / x.sd).powi(2) + (x.rate[1] / x.sd).powi(2))
        .sum::<f64>()
        / (2 * rates.len()) as f64;
    assert!(
        (0.3..3.0).contains(&z2),
        "S_h's within-window rates: mean z² {z2} is not noise"
    );

    // R² of each transfer function, nominal, refitted and final, from its
    // definition 1 − Σ|Ŝ − S|² / Σ|S − S̄|² over that function's points.
    for (what, score, phys) in [
        ("nominal", &r.nominal, &r.nominal_physics),
        ("refit", &r.refit, &r.refit_physics),
        ("final", &r.final_score, &r.final_physics),
    ] {
        assert!(!score.per_tf.is_empty());
        for t in &score.per_tf {
            let obs: Vec<_> = d.observations.iter().filter(|o| o.tf == t.tf).collect();
            assert_eq!(t.points, obs.len(), "{what} {:?} points", t.tf);
            let mean =
                obs.iter().map(|o| o.value).sum::<num_complex::Complex64>() / obs.len() as f64;
            let ss_res: f64 = obs
                .iter()
                .map(|o| (phys.predict(o, &d.conditions[o.window]) - o.value).norm_sqr())
                .sum();
            let ss_tot: f64 = obs.iter().map(|o| (o.value - mean).norm_sqr()).sum();
            eprintln!("{what} {:?}: R² {:.4}", t.tf, t.r2);
            close(
                &format!("{what} {:?} R²", t.tf),
                t.r2,
                1.0 - ss_res / ss_tot,
                1e-9,
            );
            assert!(t.r2 <= 1.0, "{what} {:?}: R² {} above 1", t.tf, t.r2);
        }
    }
}
