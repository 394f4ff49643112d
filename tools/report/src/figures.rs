//! `exo report`'s HTML: one self-contained file (SVG figures inline) with the
//! paper's figures made from the data: Bode plots of `S_{h-e/α}` with the
//! fitted M2 and M3 (Fig. 3 style), F-test bars on a log scale with the
//! critical values (Fig. 4), H against K on log-log axes with each
//! subject's power law (Fig. 5), and time responses of θ_e, τ_c, τ_s; plus
//! the tables of `exo fit`.

use std::fmt::Write as _;

use crate::error::{Error, Result};
use exo_impedance::{Complex64, DynamicStiffness};
use plotters::prelude::*;

use exo_analysis::study::{FitReport, ModelRow, SubjectReport};
use exo_recording::Recording;

/// A stretch of recorded signals for the time-response figure.
#[derive(Debug, Clone, Default)]
pub struct TimeTrace {
    /// What it shows, e.g. `subject B, experiment 1, period 4`.
    pub title: String,
    /// Time (s).
    pub t_s: Vec<f64>,
    /// θ_e (rad).
    pub theta_e_rad: Vec<f64>,
    /// τ_c (Nm).
    pub tau_c_nm: Vec<f64>,
    /// τ_s (Nm).
    pub tau_s_nm: Vec<f64>,
}

/// One analysis window of `r` (the middle window of its first experiment,
/// or the whole record), with a second before it: θ_e, τ_c, τ_s, at most
/// about 4000 points; `None` for a record without samples there. `subject`
/// goes into the title.
pub fn trace_of(r: &Recording, subject: &str) -> Option<TimeTrace> {
    // Closed windows only: a window the record ends in has no span to plot.
    let windows: Vec<(u32, u32, u64, u64)> = exo_analysis::analysis_windows(&r.protocol)
        .into_iter()
        .filter_map(|w| Some((w.state.experiment, w.state.period, w.start_ns, w.end_ns?)))
        .collect();
    // The middle window of the first experiment, or the whole record.
    let pick = windows
        .iter()
        .filter(|w| Some(w.0) == windows.first().map(|f| f.0))
        .nth(windows.len().min(10) / 2)
        .or(windows.first())
        .copied();
    let (title, lo, hi) = match pick {
        Some((e, p, s, t)) => (
            format!(
                "{}: subject {}, experiment {e}, period {p}",
                r.source, subject
            ),
            s.saturating_sub(1_000_000_000),
            t,
        ),
        None => (
            format!("{}: subject {}", r.source, subject),
            r.sensor.first().map_or(0, |s| s.stamp_ns),
            r.sensor.last().map_or(0, |s| s.stamp_ns + 1),
        ),
    };
    let sel: Vec<_> = r
        .sensor
        .iter()
        .filter(|s| s.stamp_ns >= lo && s.stamp_ns < hi)
        .collect();
    // At most ~4000 points per trace keep the SVG small.
    let step = (sel.len() / 4000).max(1);
    let t0 = sel.first().map_or(0, |s| s.stamp_ns);
    let mut tr = TimeTrace {
        title,
        ..Default::default()
    };
    for s in sel.iter().step_by(step) {
        tr.t_s.push((s.stamp_ns - t0) as f64 * 1e-9);
        tr.theta_e_rad.push(s.theta_e);
        tr.tau_c_nm.push(s.tau_c);
        tr.tau_s_nm.push(s.tau_s);
    }
    (!tr.t_s.is_empty()).then_some(tr)
}

pub(crate) const PALETTE: [RGBColor; 10] = [
    RGBColor(0, 104, 179),
    RGBColor(196, 78, 82),
    RGBColor(85, 168, 104),
    RGBColor(129, 114, 178),
    RGBColor(204, 185, 116),
    RGBColor(100, 181, 205),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(23, 190, 207),
];

pub(crate) fn plot_err<E: std::fmt::Debug>(e: E) -> Error {
    Error::Plot {
        message: format!("{e:?}"),
    }
}

pub(crate) fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        (0.0, 1.0)
    } else if (hi - lo).abs() < 1e-12 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo, hi)
    }
}

fn model_response(m: &ModelRow, extra_inertia: f64, w: f64) -> Complex64 {
    DynamicStiffness::from_array([m.m + extra_inertia, m.b, m.k, m.h]).response(w)
}

/// Bode plot of one subject's `S_{h-e/α}` points with the fitted M2 (solid) and M3 (dashed).
pub fn bode_svg(s: &SubjectReport) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 640)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (top, bottom) = root.split_vertically(320);
        let pts = s.experiments.iter().flat_map(|e| e.points.iter());
        let (w_lo, w_hi) = bounds(pts.clone().map(|p| p.omega));
        let (w_lo, w_hi) = (w_lo / 1.2, w_hi * 1.2);
        let mags = pts.clone().map(|p| {
            Complex64::new(p.s_h_e_alpha[0], p.s_h_e_alpha[1])
                .norm()
                .max(1e-6)
        });
        let (m_lo, m_hi) = bounds(mags.map(|m| m.log10()));
        let (p_lo, p_hi) = bounds(pts.map(|p| {
            Complex64::new(p.s_h_e_alpha[0], p.s_h_e_alpha[1])
                .arg()
                .to_degrees()
        }));
        let mut mag = ChartBuilder::on(&top)
            .caption(
                format!(
                    "Subject {}: S_h-e/α re-created from S_h = τc/θe, and M2 (solid), M3 (dashed)",
                    s.subject
                ),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (w_lo..w_hi).log_scale(),
                (10f64.powf(m_lo - 0.2)..10f64.powf(m_hi + 0.2)).log_scale(),
            )
            .map_err(plot_err)?;
        mag.configure_mesh()
            .y_desc("|S| (Nm/rad)")
            .x_desc("ω (rad/s)")
            .draw()
            .map_err(plot_err)?;
        let mut phase = ChartBuilder::on(&bottom)
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(60)
            .build_cartesian_2d((w_lo..w_hi).log_scale(), (p_lo - 15.0)..(p_hi + 15.0))
            .map_err(plot_err)?;
        phase
            .configure_mesh()
            .y_desc("∠S (deg)")
            .x_desc("ω (rad/s)")
            .draw()
            .map_err(plot_err)?;
        for (i, e) in s.experiments.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let data: Vec<(f64, Complex64)> = e
                .points
                .iter()
                .map(|p| (p.omega, Complex64::new(p.s_h_e_alpha[0], p.s_h_e_alpha[1])))
                .collect();
            mag.draw_series(
                data.iter()
                    .map(|(w, z)| Circle::new((*w, z.norm().max(1e-6)), 3, color.filled())),
            )
            .map_err(plot_err)?
            .label(format!("exp {} (α = {})", e.experiment, e.alpha))
            .legend(move |(x, y)| Circle::new((x + 8, y), 3, color.filled()));
            phase
                .draw_series(
                    data.iter()
                        .map(|(w, z)| Circle::new((*w, z.arg().to_degrees()), 3, color.filled())),
                )
                .map_err(plot_err)?;
            let extra = e.m_e_kg_m2 / e.alpha;
            let grid: Vec<f64> = (0..=120)
                .map(|k| w_lo * (w_hi / w_lo).powf(k as f64 / 120.0))
                .collect();
            for (name, dashed) in [("M2", false), ("M3", true)] {
                let Some(m) = e.models.get(name) else {
                    continue;
                };
                let curve: Vec<(f64, Complex64)> = grid
                    .iter()
                    .map(|&w| (w, model_response(m, extra, w)))
                    .collect();
                let style = if dashed {
                    color.mix(0.6).stroke_width(1)
                } else {
                    color.stroke_width(2)
                };
                mag.draw_series(LineSeries::new(
                    curve.iter().map(|(w, z)| (*w, z.norm().max(1e-6))),
                    style,
                ))
                .map_err(plot_err)?;
                phase
                    .draw_series(LineSeries::new(
                        curve.iter().map(|(w, z)| (*w, z.arg().to_degrees())),
                        style,
                    ))
                    .map_err(plot_err)?;
            }
        }
        mag.configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// F-test bars on a log scale (Fig. 4): `F_{M1−M3}` and `F_{M2−M3}` per
/// group, with each group's critical value drawn as a black tick.
pub fn ftest_svg(r: &FitReport) -> Result<String> {
    let groups: Vec<&exo_analysis::study::FPair> = r.f_tests.all_groups().collect();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 360)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let values = groups
            .iter()
            .flat_map(|g| [g.m1_m3.statistic, g.m2_m3.statistic, g.m1_m3.critical])
            .map(|v| v.max(1e-3));
        let (lo, hi) = bounds(values.map(|v| v.log10()));
        let n = groups.len().max(1);
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "F-statistics: M1−M3 (blue, significance of jH) and M2−M3 (red, of Bs); black: critical value",
                ("sans-serif", 15),
            )
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                0f64..n as f64,
                (10f64.powf(lo - 0.3)..10f64.powf(hi + 0.3)).log_scale(),
            )
            .map_err(plot_err)?;
        let labels: Vec<String> = groups.iter().map(|g| g.group.clone()).collect();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n)
            .x_label_formatter(&|x| {
                let i = x.floor() as usize;
                labels.get(i).cloned().unwrap_or_default()
            })
            .y_desc("F")
            .draw()
            .map_err(plot_err)?;
        let floor = 10f64.powf(lo - 0.3);
        for (i, g) in groups.iter().enumerate() {
            let x = i as f64;
            for (dx, v, c) in [
                (0.1, g.m1_m3.statistic, PALETTE[0]),
                (0.5, g.m2_m3.statistic, PALETTE[1]),
            ] {
                chart
                    .draw_series(std::iter::once(Rectangle::new(
                        [(x + dx, floor), (x + dx + 0.38, v.max(floor))],
                        c.filled(),
                    )))
                    .map_err(plot_err)?;
            }
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(x + 0.05, g.m1_m3.critical), (x + 0.95, g.m1_m3.critical)],
                    BLACK.stroke_width(2),
                )))
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// H against K of M2 on log-log axes with each subject's power law (Fig. 5).
pub fn power_law_svg(r: &FitReport) -> Result<String> {
    let pairs: Vec<(usize, f64, f64)> = r
        .subjects
        .iter()
        .enumerate()
        .flat_map(|(i, s)| {
            s.experiments.iter().filter_map(move |e| {
                e.models
                    .get("M2")
                    .filter(|m| m.k > 0.0 && m.h > 0.0)
                    .map(|m| (i, m.k, m.h))
            })
        })
        .collect();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (700, 520)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (k_lo, k_hi) = bounds(pairs.iter().map(|p| p.1.log10()));
        let (h_lo, h_hi) = bounds(pairs.iter().map(|p| p.2.log10()));
        let (k_lo, k_hi) = (10f64.powf(k_lo - 0.1), 10f64.powf(k_hi + 0.1));
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "M2: H against K with log10 H = β0 + β1 log10 K",
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(
                (k_lo..k_hi).log_scale(),
                (10f64.powf(h_lo - 0.15)..10f64.powf(h_hi + 0.15)).log_scale(),
            )
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc("K (Nm/rad)")
            .y_desc("H (Nm/rad)")
            .draw()
            .map_err(plot_err)?;
        for (i, s) in r.subjects.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            chart
                .draw_series(
                    pairs
                        .iter()
                        .filter(|p| p.0 == i)
                        .map(|p| Circle::new((p.1, p.2), 4, color.filled())),
                )
                .map_err(plot_err)?
                .label(match (s.beta0, s.beta1) {
                    (Some(b0), Some(b1)) => format!("{}: β0 = {b0:.2}, β1 = {b1:.2}", s.subject),
                    _ => s.subject.clone(),
                })
                .legend(move |(x, y)| Circle::new((x + 8, y), 4, color.filled()));
            if let (Some(b0), Some(b1)) = (s.beta0, s.beta1) {
                chart
                    .draw_series(LineSeries::new(
                        [k_lo, k_hi].map(|k| (k, 10f64.powf(b0 + b1 * k.log10()))),
                        color.stroke_width(2),
                    ))
                    .map_err(plot_err)?;
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

/// θ_e (top) and τ_c, τ_s (bottom) against time.
pub fn time_svg(trace: &TimeTrace) -> Result<String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 480)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (top, bottom) = root.split_vertically(220);
        let (t_lo, t_hi) = bounds(trace.t_s.iter().copied());
        let (a_lo, a_hi) = bounds(trace.theta_e_rad.iter().copied());
        let (q_lo, q_hi) = bounds(trace.tau_c_nm.iter().chain(&trace.tau_s_nm).copied());
        let mut a = ChartBuilder::on(&top)
            .caption(&trace.title, ("sans-serif", 15))
            .margin(8)
            .x_label_area_size(24)
            .y_label_area_size(60)
            .build_cartesian_2d(t_lo..t_hi, a_lo..a_hi)
            .map_err(plot_err)?;
        a.configure_mesh()
            .y_desc("θe (rad)")
            .draw()
            .map_err(plot_err)?;
        a.draw_series(LineSeries::new(
            trace
                .t_s
                .iter()
                .copied()
                .zip(trace.theta_e_rad.iter().copied()),
            PALETTE[1].stroke_width(1),
        ))
        .map_err(plot_err)?;
        let mut q = ChartBuilder::on(&bottom)
            .margin(8)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(t_lo..t_hi, q_lo..q_hi)
            .map_err(plot_err)?;
        q.configure_mesh()
            .x_desc("t (s)")
            .y_desc("torque (Nm)")
            .draw()
            .map_err(plot_err)?;
        for (series, color, name) in [
            (&trace.tau_c_nm, PALETTE[0], "τc"),
            (&trace.tau_s_nm, PALETTE[2], "τs"),
        ] {
            q.draw_series(LineSeries::new(
                trace.t_s.iter().copied().zip(series.iter().copied()),
                color.stroke_width(1),
            ))
            .map_err(plot_err)?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        }
        q.configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

pub(crate) fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The whole report as one HTML document.
pub fn html(
    title: &str,
    sources: &[String],
    r: &FitReport,
    traces: &[TimeTrace],
) -> Result<String> {
    let mut h = String::new();
    let w = &mut h;
    let _ = write!(
        w,
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>{}</title><style>\
         body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         th{{background:#eee}}.warn{{color:#a33}}</style></head><body><h1>{}</h1>",
        esc(title),
        esc(title)
    );
    let _ = write!(
        w,
        "<p>Recordings: {}</p>",
        sources
            .iter()
            .map(|s| esc(s))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if !r.warnings.is_empty() {
        let _ = write!(w, "<h2>What could not be used</h2><ul>");
        for x in &r.warnings {
            let _ = write!(w, "<li class=\"warn\">{}</li>", esc(x));
        }
        let _ = write!(w, "</ul>");
    }
    let _ = write!(w, "<h2>M2 parameters (Table III layout; ± 95 % intervals)</h2><table><tr><th>subject</th><th>exp</th><th>condition</th><th>K (Nm/rad)</th><th>H (Nm/rad)</th><th>M_h (kg·m²)</th><th>R²</th><th>χ²/dof</th></tr>");
    for s in &r.subjects {
        for e in &s.experiments {
            if let Some(m) = e.models.get("M2") {
                let pm = |v: f64, i: usize, d: usize| match m.ci95 {
                    Some(c) => format!("{v:.d$} ± {:.d$}", c[i]),
                    None => format!("{v:.d$}"),
                };
                let _ = write!(
                    w,
                    "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{:.3}</td><td>{}</td></tr>",
                    esc(&s.subject),
                    e.experiment,
                    esc(e.condition.as_deref().unwrap_or("")),
                    pm(m.k, 0, 2),
                    pm(m.h, 1, 2),
                    pm(m.m, 3, 4),
                    m.r2,
                    m.chi2_per_dof.map_or("—".into(), |c| format!("{c:.2}"))
                );
            }
        }
        if let (Some(b0), Some(b1), Some(r2)) = (s.beta0, s.beta1, s.r2) {
            let _ = write!(
                w,
                "<tr><td>{}</td><td>power law</td><td colspan=\"6\">β0 = {b0:.3}, β1 = {b1:.3}, R² = {r2:.3}; recommended f = {}</td></tr>",
                esc(&s.subject),
                s.recommended_f.map_or_else(
                    || s.recommended_f_note.clone().unwrap_or_default(),
                    |f| format!("{f:.3}")
                )
            );
        }
    }
    let _ = write!(w, "</table><h2>Phase of S_h (Table II layout)</h2><table><tr><th>subject</th><th>experiments</th><th>mean (deg)</th><th>s.e. (deg)</th><th>n</th></tr>");
    for p in &r.phase_table {
        for g in &p.groups {
            let _ = write!(
                w,
                "<tr><td>{}</td><td>{}</td><td>{:.1}</td><td>{:.1}</td><td>{}</td></tr>",
                esc(&p.subject),
                g.experiments,
                g.mean_deg,
                g.se_deg,
                g.n
            );
        }
    }
    let _ = write!(w, "</table><h2>F-tests (eq. ft)</h2>");
    if r.f_tests.per_subject.is_empty() && r.f_tests.all.is_none() {
        let _ = write!(w, "<p>No F-test could be computed.</p>");
    } else {
        let _ = write!(w, "{}", ftest_svg(r)?);
        let _ = write!(w, "<table><tr><th>group</th><th>F M1−M3</th><th>F M2−M3</th><th>critical</th><th>df</th></tr>");
        for g in r.f_tests.all_groups() {
            let _ = write!(
                w,
                "<tr><td>{}</td><td>{:.2}</td><td>{:.2}</td><td>{:.2}</td><td>({}, {})</td></tr>",
                esc(&g.group),
                g.m1_m3.statistic,
                g.m2_m3.statistic,
                g.m1_m3.critical,
                g.m1_m3.df[0],
                g.m1_m3.df[1]
            );
        }
        let _ = write!(w, "</table>");
    }
    let _ = write!(w, "<h2>Bode plots of S_h-e/α with the fitted models</h2>");
    for s in &r.subjects {
        if s.experiments.iter().any(|e| !e.points.is_empty()) {
            let _ = write!(w, "{}", bode_svg(s)?);
        }
    }
    if r.subjects.iter().any(|s| s.beta0.is_some()) {
        let _ = write!(w, "<h2>Power law</h2>{}", power_law_svg(r)?);
    }
    if !traces.is_empty() {
        let _ = write!(w, "<h2>Time responses</h2>");
        for t in traces {
            let _ = write!(w, "{}", time_svg(t)?);
        }
    }
    let _ = write!(w, "</body></html>");
    Ok(h)
}
