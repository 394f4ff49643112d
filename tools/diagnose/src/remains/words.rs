//! What remains in words: each dependence's sentence, and the findings of
//! a transfer function (the significant ones, or that one amplitude cannot
//! tell).

use crate::data::Tf;

use super::{
    AmplitudeDependence, AngleAmplitudeDependence, BandResidual, Estimate,
    OperatingPointDependence, TimeDependence, WithinWindow,
};

pub(super) fn band_words(tf: Tf, b: &[BandResidual], misfit: bool) -> (String, bool) {
    let each: Vec<String> = b
        .iter()
        .map(|x| {
            let mut s = format!(
                "{} {:.1}× the noise ({} points; in phase {}",
                x.band,
                x.chi2_per_component,
                x.points,
                est(&x.in_phase, " %")
            );
            if let Some(q) = &x.quadrature {
                s += &format!(", quadrature {}", est(q, " %"));
            }
            s + ")"
        })
        .collect();
    let worst = b
        .iter()
        .max_by(|a, c| {
            (a.chi2_per_component * a.points as f64)
                .total_cmp(&(c.chi2_per_component * c.points as f64))
        })
        .map_or("", |x| x.band);
    let s = if misfit {
        format!(
            "{}: by frequency band, most of the misfit is in the {worst} band — {}",
            tf.name(),
            each.join("; ")
        )
    } else {
        format!("{}: by frequency band — {}", tf.name(), each.join("; "))
    };
    (s, misfit)
}

pub(super) fn within_words(tf: Tf, w: &WithinWindow) -> (String, bool) {
    let s = if w.significant {
        format!(
            "{}: changes within a window — in phase {} per second, quadrature {} per second (second half of each of {} windows against its first; fatigue, warm-up or a drifting sensor; the arm's decaying ringing is not at ω and does not enter)",
            tf.name(),
            est(&w.in_phase, " %"),
            est(&w.quadrature, " %"),
            w.windows
        )
    } else {
        format!(
            "{}: no change within a window detected (in phase {} per second, quadrature {} per second; {} windows split in halves)",
            tf.name(),
            est(&w.in_phase, " %"),
            est(&w.quadrature, " %"),
            w.windows
        )
    };
    (s, w.significant)
}

pub(super) fn time_words(tf: Tf, t: &TimeDependence) -> (String, bool) {
    let unit = if tf.is_dynamic() { " %" } else { " Nm" };
    if t.confounded_with_frequency {
        return (
            format!(
                "{}: a drift over the experiment cannot be told from a dependence on frequency by the residual alone: the periods sweep ω upwards, so a window's start time is a function of its frequency ({:.1} % of the time's spread is independent of it); a frequency repeated late in the experiment would tell, and the drift form of the library tests it through the model",
                tf.name(),
                100.0 * t.independent_share
            ),
            false,
        );
    }
    let mut s = match &t.in_phase {
        Some(e) if t.significant => format!(
            "{}: drifts over the experiment — {} per minute",
            tf.name(),
            est(e, unit)
        ),
        Some(e) => format!(
            "{}: no drift over the experiment detected ({} per minute",
            tf.name(),
            est(e, unit)
        ),
        None => format!("{}: drift over the experiment not estimable", tf.name()),
    };
    if let Some(q) = &t.quadrature {
        s += &format!(", quadrature {} per minute", est(q, unit));
    }
    if t.in_phase.is_some() && !t.significant {
        s += ")";
    }
    (s, t.significant)
}

fn est(e: &Estimate, unit: &str) -> String {
    let d = if e.std_error.is_finite() && e.std_error > 0.0 {
        (1 - e.std_error.log10().floor() as i64).clamp(0, 6) as usize
    } else {
        2
    };
    format!(
        "{:+.d$} ± {:.d$}{unit} (p = {:.1e})",
        e.value, e.std_error, e.p_value
    )
}

pub(super) fn angle_words(tf: Tf, a: &AngleAmplitudeDependence) -> String {
    let mut s = if a.significant {
        format!(
            "{}: changes with the angle amplitude — in-phase residual {} per (0.1 rad)² of amplitude squared",
            tf.name(),
            est(&a.in_phase, " %")
        )
    } else {
        format!(
            "{}: no in-phase dependence on the angle amplitude reported (in-phase {} per (0.1 rad)²",
            tf.name(),
            est(&a.in_phase, " %")
        )
    };
    if let Some(q) = &a.quadrature {
        s += &format!(", quadrature {}", est(q, " %"));
    }
    if a.significant {
        s += &format!(
            ", beyond a smooth trend in frequency per experiment (amplitudes {:.3}–{:.3} rad; a positive in-phase slope is what a stiffening spring's describing function ¾K₃A² gives, a negative one a softening spring; the angle amplitude also varies with frequency, largest near the arm's natural frequency, which the trend separates only in part)",
            a.theta_amp_rad[0], a.theta_amp_rad[1]
        );
    } else {
        s += ")";
    }
    s
}

pub(super) fn words_of(
    tf: Tf,
    chi: f64,
    amp: &Option<AmplitudeDependence>,
    op: &Option<OperatingPointDependence>,
    two_amplitudes: bool,
    misfit: bool,
) -> Vec<(String, bool)> {
    let unit = if tf.is_dynamic() { " %" } else { " Nm" };
    let mut w = vec![(
        format!(
            "{}: residual {:.1}× the noise variance ({})",
            tf.name(),
            chi,
            if misfit {
                "beyond the noise"
            } else {
                "within the noise: no dependence is reported"
            }
        ),
        false,
    )];
    match amp {
        Some(a) if a.significant => {
            let mut s = format!(
                "{}: depends on amplitude — where the excitation rises from {:.1} to {:.1} Nm (angle amplitude {:.3} → {:.3} rad) the in-phase residual steps by {}",
                tf.name(),
                a.amplitudes_nm[0],
                a.amplitudes_nm[1],
                a.theta_amp_rad[0],
                a.theta_amp_rad[1],
                est(&a.in_phase, unit)
            );
            if let Some(q) = &a.quadrature {
                s += &format!(", the quadrature residual by {}", est(q, unit));
            }
            s += ", beyond a smooth trend in frequency (the higher amplitude is also the highest frequencies)";
            w.push((s, true));
        }
        Some(a) => w.push((format!(
            "{}: no dependence on amplitude detected (in-phase step at {:.1} Nm {}; its standard error includes the structure the frequency trend does not describe)",
            tf.name(),
            a.amplitudes_nm[1],
            est(&a.in_phase, unit)
        ), false)),
        None if !two_amplitudes => w.push((format!(
            "{}: the recordings have one excitation amplitude, so they cannot tell whether what remains depends on it; two amplitudes at each frequency would",
            tf.name()
        ), misfit)),
        None => {}
    }
    match op {
        Some(o) if o.significant => {
            let each: Vec<String> = o
                .per_experiment
                .iter()
                .skip(1)
                .map(|(e, b, ip, q)| {
                    let mut s = if tf.is_dynamic() {
                        format!("exp {e} (bias {b:.1} Nm) in phase {}", est(ip, unit))
                    } else {
                        format!("exp {e} (bias {b:.1} Nm) {}", est(ip, unit))
                    };
                    if let Some(q) = q {
                        s += &format!(", quadrature {}", est(q, unit));
                    }
                    s
                })
                .collect();
            let p = if tf.is_dynamic() {
                format!(
                    "F-test p = {:.1e} in phase, {:.1e} in quadrature",
                    o.p_value[0], o.p_value[1]
                )
            } else {
                format!("F-test p = {:.1e}", o.p_value[0])
            };
            w.push((
                format!(
                    "{}: differs between operating points ({p}), relative to exp {}: {}",
                    tf.name(),
                    o.per_experiment[0].0,
                    each.join("; ")
                ),
                true,
            ));
        }
        Some(o) => w.push((
            format!(
                "{}: no difference between operating points detected (p = {:.2})",
                tf.name(),
                o.p_value[0].min(if o.p_value[1].is_nan() {
                    1.0
                } else {
                    o.p_value[1]
                })
            ),
            false,
        )),
        None => {}
    }
    w
}
