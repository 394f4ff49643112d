//! `exo design`'s output: the Bode plot of the loop `L(jω) = kp·F(jω)·P(jω)`
//! at both stiffness bounds, with crossovers and phase margins marked
//! (`--plot`), the `--json` document and the human-readable summary.

use std::path::Path;

use std::fmt::Write as _;

use crate::error::{Error, Result};
use exo_impedance::design::FractionalOrderSource;
use serde::Serialize;

use crate::figures::plot_err;
use exo_impedance::design::{Design, DesignInputs};
use exo_impedance::{AmplificationLoop, AmplificationPlant};
use plotters::prelude::*;

/// Draws the Bode plot to an SVG file.
pub fn bode_svg(inputs: &DesignInputs, d: &Design, path: &Path) -> Result<()> {
    let cases = d.margins.as_ref().ok_or(Error::NoLossFactor)?;
    let loops: Vec<(f64, AmplificationLoop)> = cases
        .iter()
        .map(|c| {
            let plant = AmplificationPlant::new(
                inputs.m_e_kg_m2,
                inputs.m_h_kg_m2,
                c.k_nm_per_rad,
                c.loss_factor,
                inputs.sea,
            )?;
            Ok((
                c.k_nm_per_rad,
                AmplificationLoop {
                    kp: d.kp,
                    filter: d.filter,
                    plant,
                },
            ))
        })
        .collect::<Result<_, exo_impedance::ScienceError>>()?;
    let (w_lo, w_hi) = (0.1 * d.filter.p1_rad_s(), 3.0 * inputs.sea.omega_n_rad_s());
    let omegas: Vec<f64> = (0..=800)
        .map(|i| w_lo * (w_hi / w_lo).powf(i as f64 / 800.0))
        .collect();
    // (K, [(ω, |L| dB, ∠L deg)]) per stiffness bound.
    type Curve = (f64, Vec<(f64, f64, f64)>);
    let curves: Vec<Curve> = loops
        .iter()
        .map(|(k, l)| {
            (
                *k,
                omegas
                    .iter()
                    .map(|&w| (w, 20.0 * l.response(w).norm().log10(), l.phase_deg(w)))
                    .collect(),
            )
        })
        .collect();
    let (mut db_lo, mut db_hi, mut ph_lo, mut ph_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (_, c) in &curves {
        for &(_, db, ph) in c {
            db_lo = db_lo.min(db);
            db_hi = db_hi.max(db);
            ph_lo = ph_lo.min(ph);
            ph_hi = ph_hi.max(ph);
        }
    }
    let ph_lo = ph_lo.min(-190.0);
    let ph_hi = ph_hi.max(10.0);

    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(Error::file("creating", dir))?;
    }
    let root = SVGBackend::new(path, (900, 760)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_err)?;
    let (top, bottom) = root.split_vertically(380);
    let colors = [RGBColor(0, 104, 179), RGBColor(148, 44, 44)];

    let mut mag = ChartBuilder::on(&top)
        .caption(
            format!(
                "Loop L = kp·F·P   (kp = {:.3}, f = {:.3}, {} lag filters)",
                d.kp,
                d.f,
                d.filter.n_filters()
            ),
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d((w_lo..w_hi).log_scale(), (db_lo - 5.0)..(db_hi + 5.0))
        .map_err(plot_err)?;
    mag.configure_mesh()
        .y_desc("|L| (dB)")
        .x_desc("ω (rad/s)")
        .draw()
        .map_err(plot_err)?;
    mag.draw_series(LineSeries::new([(w_lo, 0.0), (w_hi, 0.0)], BLACK.mix(0.5)))
        .map_err(plot_err)?;
    for ((k, c), color) in curves.iter().zip(colors) {
        mag.draw_series(LineSeries::new(
            c.iter().map(|&(w, db, _)| (w, db)),
            color.stroke_width(2),
        ))
        .map_err(plot_err)?
        .label(format!("K = {k} Nm/rad"))
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    mag.configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(plot_err)?;

    let mut phase = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(60)
        .build_cartesian_2d((w_lo..w_hi).log_scale(), (ph_lo - 10.0)..(ph_hi + 10.0))
        .map_err(plot_err)?;
    phase
        .configure_mesh()
        .y_desc("∠L (deg)")
        .x_desc("ω (rad/s)")
        .draw()
        .map_err(plot_err)?;
    phase
        .draw_series(LineSeries::new(
            [(w_lo, -180.0), (w_hi, -180.0)],
            BLACK.mix(0.5),
        ))
        .map_err(plot_err)?;
    for ((_, c), color) in curves.iter().zip(colors) {
        phase
            .draw_series(LineSeries::new(
                c.iter().map(|&(w, _, ph)| (w, ph)),
                color.stroke_width(2),
            ))
            .map_err(plot_err)?;
    }
    for (case, color) in cases.iter().zip(colors) {
        for x in &case.analysis.crossovers {
            let w = x.omega_rad_s;
            mag.draw_series(std::iter::once(Circle::new((w, 0.0), 5, color.filled())))
                .map_err(plot_err)?;
            phase
                .draw_series([PathElement::new(
                    vec![(w, -180.0), (w, x.phase_deg)],
                    color.stroke_width(3),
                )])
                .map_err(plot_err)?;
            phase
                .draw_series(std::iter::once(Text::new(
                    format!("PM {:.1}° @ {:.2} rad/s", x.phase_margin_deg, w),
                    (w * 1.1, x.phase_deg + 8.0),
                    ("sans-serif", 14).into_font().color(&color),
                )))
                .map_err(plot_err)?;
        }
    }
    root.present().map_err(plot_err)?;
    Ok(())
}

/// The `--json` document of a design, pretty-printed.
pub fn json(inputs: &DesignInputs, d: &Design) -> serde_json::Result<String> {
    serde_json::to_string_pretty(&JsonDesign::new(inputs, d))
}

/// The `--json` document ([`json`]). Stable keys: `kp`, `omega_gc`, `kf`, `f`,
/// `phase_margin_deg` {`k_min`, `k_max`}, `predicted` [{`omega`,
/// `magnitude`, `phase_deg`}]; the rest is detail.
#[derive(Serialize)]
struct JsonDesign<'a> {
    kp: f64,
    kp_source: &'static str,
    omega_gc: f64,
    k_nominal: f64,
    kf: f64,
    f: f64,
    f_source: FractionalOrderSource,
    phase_margin_deg: Bounds<Option<f64>>,
    crossovers: Bounds<Vec<exo_impedance::Crossover>>,
    loss_factor: Bounds<Option<f64>>,
    predicted: &'a [exo_impedance::design::Prediction],
    filter: JsonFilter,
    discrete: JsonDiscrete<'a>,
    inputs: &'a DesignInputs,
}

#[derive(Serialize)]
struct Bounds<T> {
    k_min: T,
    k_max: T,
}

#[derive(Serialize)]
struct JsonFilter {
    n: usize,
    p1_rad_s: f64,
    r_pp: f64,
    r_zp: f64,
    gain: f64,
    poles_rad_s: Vec<f64>,
    zeros_rad_s: Vec<f64>,
}

#[derive(Serialize)]
struct JsonDiscrete<'a> {
    rate_hz: f64,
    method: &'static str,
    gain: f64,
    sections: &'a [exo_impedance::FirstOrderSection],
}

const DISCRETISATION: &str =
    "bilinear (Tustin) per first-order section, pre-warped at sqrt(p_i z_i)";

impl<'a> JsonDesign<'a> {
    fn new(inputs: &'a DesignInputs, d: &'a Design) -> Self {
        let pick = |i: usize| d.margins.as_ref().map(|m| &m[i]);
        JsonDesign {
            kp: d.kp,
            kp_source: if d.kp_explicit { "explicit" } else { "eq_kp" },
            omega_gc: d.omega_gc,
            k_nominal: d.k_nominal,
            kf: d.kf,
            f: d.f,
            f_source: d.f_source,
            phase_margin_deg: Bounds {
                k_min: pick(0).and_then(|c| c.analysis.min_phase_margin_deg),
                k_max: pick(1).and_then(|c| c.analysis.min_phase_margin_deg),
            },
            crossovers: Bounds {
                k_min: pick(0)
                    .map(|c| c.analysis.crossovers.clone())
                    .unwrap_or_default(),
                k_max: pick(1)
                    .map(|c| c.analysis.crossovers.clone())
                    .unwrap_or_default(),
            },
            loss_factor: Bounds {
                k_min: pick(0).map(|c| c.loss_factor),
                k_max: pick(1).map(|c| c.loss_factor),
            },
            predicted: &d.predicted,
            filter: JsonFilter {
                n: d.filter.n_filters(),
                p1_rad_s: d.filter.p1_rad_s(),
                r_pp: d.filter.r_pp(),
                r_zp: d.filter.r_zp(),
                gain: d.filter.gain(),
                poles_rad_s: d.filter.poles_rad_s(),
                zeros_rad_s: d.filter.zeros_rad_s(),
            },
            discrete: JsonDiscrete {
                rate_hz: d.rate_hz,
                method: DISCRETISATION,
                gain: d.discrete.gain(),
                sections: d.discrete.sections(),
            },
            inputs,
        }
    }
}

/// The human-readable report (`plot`: the Bode plot's file, if drawn).
pub fn human(inputs: &DesignInputs, d: &Design, plot: Option<&std::path::Path>) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "exo design: fractional-order amplification controller (He et al., IEEE TNSRE 2020)"
    );
    let _ = writeln!(o);
    let _ = writeln!(o, "Inputs");
    let _ = writeln!(
        o,
        "  M_e = {:.3} kg·m², M_h = {:.3} kg·m², K from {} to {} Nm/rad (nominal K̂ = {:.2})",
        inputs.m_e_kg_m2, inputs.m_h_kg_m2, inputs.range.k_min, inputs.range.k_max, d.k_nominal
    );
    match (inputs.power_law, inputs.loss_factor) {
        (Some(l), _) => {
            let _ = writeln!(o, "  power law H = 10^{:.3} · K^{:.3}", l.beta0, l.beta1);
        }
        (None, Some(c)) => {
            let _ = writeln!(o, "  constant loss factor c = {c}");
        }
        _ => {}
    }
    let _ = writeln!(
        o,
        "  SEA {} Hz, ζ = {}; controller at {} Hz",
        inputs.sea.natural_frequency_hz, inputs.sea.damping_ratio, d.rate_hz
    );
    let _ = writeln!(o);
    let _ = writeln!(o, "Gains");
    let kp_src = if d.kp_explicit {
        "given"
    } else {
        "eq. kp: (M_he/M_h)^1/2"
    };
    let _ = writeln!(o, "  kp     = {:.4}   ({kp_src})", d.kp);
    let _ = writeln!(o, "  ω̂_gc   = {:.4} rad/s   (eq. kf, at K̂)", d.omega_gc);
    let f_src = match d.f_source {
        FractionalOrderSource::Explicit => "given".to_string(),
        FractionalOrderSource::EqF => format!(
            "eq. f, guaranteed phase margin {}°",
            inputs.phase_margin_deg.unwrap_or_default()
        ),
    };
    let _ = writeln!(o, "  f      = {:.4}   ({f_src})", d.f);
    let _ = writeln!(o, "  kf     = {:.4}   (eq. kf: ω̂_gc^f)", d.kf);
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "Lag filters (eq. Fs): n = {}, p1 = {} rad/s, r_pp = {:.4}, r_zp = r_pp^f = {:.4}, gain kf/p1^f = {:.4}",
        d.filter.n_filters(),
        d.filter.p1_rad_s(),
        d.filter.r_pp(),
        d.filter.r_zp(),
        d.filter.gain()
    );
    let _ = writeln!(
        o,
        "  {:>3}  {:>14}  {:>14}",
        "#", "pole (rad/s)", "zero (rad/s)"
    );
    for (i, (p, z)) in d
        .filter
        .poles_rad_s()
        .iter()
        .zip(d.filter.zeros_rad_s())
        .enumerate()
    {
        let _ = writeln!(o, "  {:>3}  {:>14.4}  {:>14.4}", i + 1, p, z);
    }
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "Discrete cascade at {} Hz, {}:\n  y = {:.6} · Π (b0 + b1 q⁻¹)/(1 + a1 q⁻¹)",
        d.rate_hz,
        DISCRETISATION,
        d.discrete.gain()
    );
    let _ = writeln!(o, "  {:>3}  {:>18}  {:>18}  {:>18}", "#", "b0", "b1", "a1");
    for (i, s) in d.discrete.sections().iter().enumerate() {
        let _ = writeln!(
            o,
            "  {:>3}  {:>18.12}  {:>18.12}  {:>18.12}",
            i + 1,
            s.b0,
            s.b1,
            s.a1
        );
    }
    let _ = writeln!(o);
    match &d.margins {
        Some(cases) => {
            let _ = writeln!(o, "Loop L = kp·F·P at the stiffness bounds");
            let _ = writeln!(
                o,
                "  {:>10}  {:>6}  {:>11}  {:>14}  {:>12}",
                "K (Nm/rad)", "c", "atan(c)/90", "crossover rad/s", "phase margin"
            );
            for c in cases {
                let pm = c
                    .analysis
                    .min_phase_margin_deg
                    .map_or("none".into(), |p| format!("{p:.2}°"));
                let xs: Vec<String> = c
                    .analysis
                    .crossovers
                    .iter()
                    .map(|x| format!("{:.3} ({:.1}°)", x.omega_rad_s, x.phase_margin_deg))
                    .collect();
                let _ = writeln!(
                    o,
                    "  {:>10.2}  {:>6.3}  {:>11.3}  {:>14}  {:>12}",
                    c.k_nm_per_rad,
                    c.loss_factor,
                    c.f_bound,
                    if xs.is_empty() {
                        "none".into()
                    } else {
                        xs.join(", ")
                    },
                    pm
                );
                if c.analysis.crossovers.len() > 1 {
                    let _ = writeln!(
                        o,
                        "  warning: {} crossovers at K = {}: the paper warns that multiple crossovers make the design unreliable",
                        c.analysis.crossovers.len(),
                        c.k_nm_per_rad
                    );
                }
                if d.f >= c.f_bound {
                    let _ = writeln!(
                        o,
                        "  warning: f = {:.3} is not below atan(c)/90 = {:.3} at K = {}: no guaranteed positive margin",
                        d.f, c.f_bound, c.k_nm_per_rad
                    );
                }
            }
        }
        None => {
            let _ = writeln!(
                o,
                "Phase margins: not computed (give --beta0/--beta1 or --loss-factor for the human's loss factor)"
            );
        }
    }
    let _ = writeln!(o);
    let _ = writeln!(
        o,
        "Predicted amplification τ̃s/τ̃c = α − 1 = kp·F(jω) (Table IV's quantity)"
    );
    let _ = writeln!(
        o,
        "  {:>10}  {:>10}  {:>10}  {:>16}  {:>16}",
        "ω (rad/s)", "|τs/τc|", "phase", "|.| through SEA", "phase thr. SEA"
    );
    for p in &d.predicted {
        let _ = writeln!(
            o,
            "  {:>10.3}  {:>10.3}  {:>9.1}°  {:>16.3}  {:>15.1}°",
            p.omega, p.magnitude, p.phase_deg, p.magnitude_with_sea, p.phase_deg_with_sea
        );
    }
    if let Some(p) = plot {
        let _ = writeln!(o);
        let _ = writeln!(o, "Bode plot of L(jω) written to {}", p.display());
    }
    o
}
