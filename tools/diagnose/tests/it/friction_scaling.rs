//! Friction must scale with 1/amplitude (issue 15, item 1): hysteretic
//! damping of the human (a loss independent of amplitude) behind a viscous
//! model, with hysteretic damping left out of the candidates, must not be
//! named as Coulomb friction, whose describing function falls as 1/A.

use crate::common;
use common::default_plant;

use exo_diagnose::data::{reduce, Reduction};
use exo_diagnose::synth::{synthesize, SynthPeriod, SynthSettings};
use exo_diagnose::{diagnose, Settings, Term};

/// Two experiments of ten periods from 2 rad/s, the amplitude 10^0.2×
/// higher at periods 8–10 (the protocol's).
fn protocol() -> Vec<SynthPeriod> {
    common::protocol(&[(1, 20.0, 8.0, 4.5, 0.0), (2, 40.0, 16.0, 4.5, 4.0)])
}

#[test]
fn an_amplitude_independent_loss_is_not_named_coulomb_friction() {
    let truth = default_plant();
    let mut nominal = truth;
    nominal.human.hysteretic_damping.enabled = false;
    nominal.human.viscous_damping.enabled = true;
    nominal.human.viscous_damping.b_nm_s_per_rad = 1.0;
    let rec = synthesize(&truth, &protocol(), &SynthSettings::default());
    let d = reduce(&[rec], &Reduction::default());
    let s = Settings {
        candidates: Term::ALL
            .into_iter()
            .filter(|t| *t != Term::HystereticDamping)
            .collect(),
        ..Settings::default()
    };
    let r = diagnose(&d, &nominal, &s).expect("diagnosis");
    for st in &r.steps {
        for c in &st.candidates {
            eprintln!(
                "step {} {:?} F {:.1} p {:.1e} share {:.2} {:?} {}",
                st.step,
                c.term,
                c.f,
                c.p_holm,
                c.explained_share,
                c.rejected_because,
                c.amplitude_check.as_ref().map_or("", |a| a.words.as_str())
            );
        }
    }
    for v in &r.verdict {
        eprintln!("=> {v}");
    }
    assert!(
        r.found.iter().all(|f| f.term != Term::CoulombFriction),
        "{:#?}",
        r.verdict
    );
}
