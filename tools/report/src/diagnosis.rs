//! `exo diagnose -o DIR`'s HTML: Bode overlays of data, nominal and updated
//! model per transfer function with their residuals, a time-domain overlay
//! of the window the nominal model missed most, and the tables; and
//! `exo diagnose-bench`'s table of its cases ([`bench_table`]).

use std::fmt::Write as _;

use std::path::Path;

use crate::error::{Error, Result};
use exo_diagnose::bench::Outcome;
use exo_diagnose::data::{Dataset, Tf};
use exo_diagnose::engine::Score;
use exo_diagnose::{Diagnosis, Physics, Term};
use exo_plant_model::PlantModel;
use num_complex::Complex64;
use plotters::prelude::*;

use crate::figures::{bounds, esc, plot_err, PALETTE};

struct Series {
    experiment: u32,
    points: Vec<(f64, Complex64, Complex64, Complex64)>,
}

fn series(d: &Dataset, tf: Tf, nominal: &Physics, fin: &Physics) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    for e in d.experiments() {
        let mut pts: Vec<(f64, Complex64, Complex64, Complex64)> = d
            .of(tf)
            .filter(|o| d.conditions[o.window].experiment == e)
            .map(|o| {
                let c = &d.conditions[o.window];
                (
                    o.omega_rad_s,
                    o.value,
                    nominal.predict(o, c),
                    fin.predict(o, c),
                )
            })
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        if !pts.is_empty() {
            out.push(Series {
                experiment: e,
                points: pts,
            });
        }
    }
    out
}

/// Bode overlay of one transfer function: data (dots), nominal model
/// (dashed), updated model (solid); residual |data − model|/|model| below.
fn bode_svg(d: &Dataset, tf: Tf, r: &Diagnosis) -> Result<String> {
    let ss = series(d, tf, &r.nominal_physics, &r.final_physics);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 760)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (top, rest) = root.split_vertically(300);
        let (mid, bottom) = rest.split_vertically(240);
        let all = ss.iter().flat_map(|s| s.points.iter());
        let (w_lo, w_hi) = bounds(all.clone().map(|p| p.0));
        let (w_lo, w_hi) = (w_lo / 1.15, w_hi * 1.15);
        let (m_lo, m_hi) = bounds(
            all.clone()
                .flat_map(|p| [p.1, p.2, p.3])
                .map(|z| z.norm().max(1e-6).log10()),
        );
        let (p_lo, p_hi) = bounds(
            all.clone()
                .flat_map(|p| [p.1, p.2, p.3])
                .map(|z| z.arg().to_degrees()),
        );
        let (r_lo, r_hi) = bounds(
            all.flat_map(|p| {
                [
                    (p.1 - p.2).norm() / p.2.norm(),
                    (p.1 - p.3).norm() / p.3.norm(),
                ]
            })
            .map(|x| (100.0 * x).max(1e-3).log10()),
        );
        let mut mag = ChartBuilder::on(&top)
            .caption(
                format!(
                    "{} = {}: data (dots), nominal (dashed), with terms found (solid)",
                    tf.name(),
                    tf.signals()
                ),
                ("sans-serif", 16),
            )
            .margin(8)
            .x_label_area_size(24)
            .y_label_area_size(64)
            .build_cartesian_2d(
                (w_lo..w_hi).log_scale(),
                (10f64.powf(m_lo - 0.1)..10f64.powf(m_hi + 0.1)).log_scale(),
            )
            .map_err(plot_err)?;
        mag.configure_mesh()
            .y_desc("|S|")
            .draw()
            .map_err(plot_err)?;
        let mut phase = ChartBuilder::on(&mid)
            .margin(8)
            .x_label_area_size(24)
            .y_label_area_size(64)
            .build_cartesian_2d((w_lo..w_hi).log_scale(), (p_lo - 5.0)..(p_hi + 5.0))
            .map_err(plot_err)?;
        phase
            .configure_mesh()
            .y_desc("∠S (deg)")
            .draw()
            .map_err(plot_err)?;
        let mut res = ChartBuilder::on(&bottom)
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(64)
            .build_cartesian_2d(
                (w_lo..w_hi).log_scale(),
                (10f64.powf(r_lo - 0.1)..10f64.powf(r_hi + 0.1)).log_scale(),
            )
            .map_err(plot_err)?;
        res.configure_mesh()
            .y_desc("|data − model|/|model| (%)")
            .x_desc("ω (rad/s)")
            .draw()
            .map_err(plot_err)?;
        for (i, s) in ss.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            mag.draw_series(
                s.points
                    .iter()
                    .map(|p| Circle::new((p.0, p.1.norm().max(1e-6)), 3, color.filled())),
            )
            .map_err(plot_err)?
            .label(format!("exp {}", s.experiment))
            .legend(move |(x, y)| Circle::new((x + 8, y), 3, color.filled()));
            phase
                .draw_series(
                    s.points
                        .iter()
                        .map(|p| Circle::new((p.0, p.1.arg().to_degrees()), 3, color.filled())),
                )
                .map_err(plot_err)?;
            for (k, dashed) in [(2usize, true), (3usize, false)] {
                let pick =
                    |p: &(f64, Complex64, Complex64, Complex64)| if k == 2 { p.2 } else { p.3 };
                let style = if dashed {
                    color.mix(0.5).stroke_width(1)
                } else {
                    color.stroke_width(2)
                };
                mag.draw_series(LineSeries::new(
                    s.points.iter().map(|p| (p.0, pick(p).norm().max(1e-6))),
                    style,
                ))
                .map_err(plot_err)?;
                phase
                    .draw_series(LineSeries::new(
                        s.points.iter().map(|p| (p.0, pick(p).arg().to_degrees())),
                        style,
                    ))
                    .map_err(plot_err)?;
                res.draw_series(LineSeries::new(
                    s.points.iter().map(|p| {
                        let m = pick(p);
                        (p.0, (100.0 * (p.1 - m).norm() / m.norm()).max(1e-3))
                    }),
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

/// The window (and transfer function) where the nominal model's whitened
/// residual is largest.
fn worst_window(d: &Dataset, r: &Diagnosis) -> Option<(usize, Tf)> {
    d.observations
        .iter()
        .filter(|o| matches!(o.tf, Tf::Sh | Tf::She) && d.signals[o.window].omega_rad_s > 0.0)
        .map(|o| {
            let c = &d.conditions[o.window];
            let e = (r.nominal_physics.predict(o, c) - o.value).norm()
                / o.sigma[0].hypot(o.sigma[1]).max(1e-9);
            (o.window, o.tf, e)
        })
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(w, tf, _)| (w, tf))
}

/// Time overlay of one window: the measured torque and the torque each model
/// predicts from the measured angle (its mean plus the transfer function
/// times the angle's fundamental).
fn time_svg(d: &Dataset, r: &Diagnosis, window: usize, tf: Tf) -> Result<String> {
    let s = &d.signals[window];
    let c = &d.conditions[window];
    let y = if tf == Tf::Sh {
        &s.tau_c_nm
    } else {
        &s.tau_s_net_nm
    };
    let w = s.omega_rad_s;
    let th = exo_impedance::frf::sine_amplitude(&s.t_s, &s.theta_rad, w, true)?;
    let gravity = d
        .observations
        .iter()
        .find(|o| o.window == window && o.tf == Tf::She)
        .map_or(Complex64::new(0.0, 0.0), |o| o.gravity_comp);
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let predict = |p: &Physics| -> Vec<f64> {
        let a = p.predict_tf(tf, w, c, gravity) * th.amplitude;
        s.t_s
            .iter()
            .map(|t| mean + (a * Complex64::from_polar(1.0, w * t)).re)
            .collect()
    };
    let nom = predict(&r.nominal_physics);
    let fin = predict(&r.final_physics);
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (900, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let (t_lo, t_hi) = bounds(s.t_s.iter().copied());
        let (y_lo, y_hi) = bounds(y.iter().chain(&nom).chain(&fin).copied());
        let mut ch = ChartBuilder::on(&root)
            .caption(
                format!(
                    "experiment {} period {} (ω = {:.2} rad/s): {} measured (black), nominal (dashed red), with terms found (blue)",
                    c.experiment,
                    c.period,
                    w,
                    if tf == Tf::Sh { "τ_c" } else { "τ_s − τ_gravity" }
                ),
                ("sans-serif", 14),
            )
            .margin(8)
            .x_label_area_size(28)
            .y_label_area_size(60)
            .build_cartesian_2d(t_lo..t_hi, y_lo..y_hi)
            .map_err(plot_err)?;
        ch.configure_mesh()
            .x_desc("t (s, from the window start)")
            .y_desc("Nm")
            .draw()
            .map_err(plot_err)?;
        let step = (s.t_s.len() / 1500).max(1);
        let pts = |v: &[f64]| -> Vec<(f64, f64)> {
            s.t_s
                .iter()
                .zip(v)
                .step_by(step)
                .map(|(t, y)| (*t, *y))
                .collect()
        };
        ch.draw_series(LineSeries::new(pts(y), BLACK.stroke_width(1)))
            .map_err(plot_err)?;
        ch.draw_series(LineSeries::new(pts(&nom), RED.mix(0.7).stroke_width(1)))
            .map_err(plot_err)?;
        ch.draw_series(LineSeries::new(pts(&fin), BLUE.stroke_width(2)))
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    Ok(svg)
}

fn score_table(w: &mut String, r: &Diagnosis) {
    let _ = write!(
        w,
        "<table><tr><th>model</th><th>transfer function</th><th>points</th><th>RSS (χ²)</th><th>R²</th><th>held-out RSS</th></tr>"
    );
    let rows: [(&str, &Score); 3] = [
        ("nominal as given", &r.nominal),
        ("nominal refitted", &r.refit),
        ("with terms found", &r.final_score),
    ];
    for (label, s) in rows {
        for t in &s.per_tf {
            let _ = write!(
                w,
                "<tr><td>{label}</td><td>{}</td><td>{}</td><td>{:.1}</td><td>{:.4}</td><td>{:.1}</td></tr>",
                esc(t.tf.name()),
                t.points,
                t.rss,
                t.r2,
                t.heldout_rss
            );
        }
    }
    let _ = write!(w, "</table>");
}

/// The whole report.
pub fn html(d: &Dataset, r: &Diagnosis) -> Result<String> {
    let mut h = String::new();
    let w = &mut h;
    let _ = write!(
        w,
        "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>exo diagnose</title><style>\
         body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
         th{{background:#eee}}.verdict{{font-weight:bold}}.warn{{color:#a33}}</style></head><body>\
         <h1>exo diagnose</h1><p>Recordings: {}</p><h2>Verdict</h2><ul>",
        esc(&r.sources.join(", "))
    );
    for v in &r.verdict {
        let _ = write!(w, "<li class=\"verdict\">{}</li>", esc(v));
    }
    let _ = write!(w, "</ul><h2>Where the model and the data differ</h2><ul>");
    for l in &r.location.summary {
        let _ = write!(w, "<li>{}</li>", esc(l));
    }
    let _ = write!(w, "</ul><h2>Fit before and after</h2>");
    score_table(w, r);
    let _ = write!(w, "<h2>Candidate physics</h2>");
    for st in &r.steps {
        let _ = write!(
            w,
            "<h3>Step {}</h3><table><tr><th>candidate</th><th>+p</th><th>F</th><th>F crit</th><th>p (Holm)</th><th>ΔAIC</th><th>held-out</th><th>fitted</th><th>share of misfit</th><th>not added because</th></tr>",
            st.step
        );
        for c in &st.candidates {
            let _ = write!(
                w,
                "<tr{}><td>{}</td><td>{}</td><td>{:.2}</td><td>{:.2}</td><td>{:.2e}</td><td>{:.1}</td><td>{:+.1} %</td><td>{}</td><td>{:.0} %</td><td>{}</td></tr>",
                if c.chosen { " style=\"font-weight:bold\"" } else { "" },
                esc(c.words),
                c.added_parameters,
                c.f,
                c.f_critical,
                c.p_holm,
                c.delta_aic,
                100.0 * c.heldout_change,
                esc(&c.description),
                100.0 * c.explained_share,
                esc(&c.rejected_because.join("; "))
            );
        }
        let _ = write!(w, "</table>");
    }
    let _ = write!(w, "<h2>What remains, per transfer function</h2><ul>");
    for rm in &r.remains {
        for l in &rm.words {
            let _ = write!(w, "<li>{}</li>", esc(l));
        }
    }
    let _ = write!(w, "</ul><h2>Bode overlays</h2>");
    for &tf in &r.supported {
        let _ = write!(w, "{}", bode_svg(d, tf, r)?);
    }
    if let Some((win, tf)) = worst_window(d, r) {
        let _ = write!(
            w,
            "<h2>Time domain: the window the nominal model missed most</h2>{}",
            time_svg(d, r, win, tf)?
        );
    }
    let _ = write!(w, "<h2>Refitted parameters of the nominal model</h2><table><tr><th>parameter</th><th>nominal</th><th>fitted</th><th>s.e.</th><th>change</th></tr>");
    for c in &r.parameter_changes {
        let _ = write!(
            w,
            "<tr><td>{}</td><td>{:.4}</td><td>{:.4}</td><td>{}</td><td>{:+.1} %</td></tr>",
            esc(&c.label),
            c.nominal,
            c.fitted,
            std_error_cell(c.fitted, c.std_error),
            c.change_pct
        );
    }
    let _ = write!(w, "</table>");
    if !r.notes.is_empty() {
        let _ = write!(w, "<h2>What could not be used</h2><ul>");
        for n in &r.notes {
            let _ = write!(w, "<li class=\"warn\">{}</li>", esc(n));
        }
        let _ = write!(w, "</ul>");
    }
    let _ = write!(w, "</body></html>");
    Ok(h)
}

fn names(t: &[Term]) -> String {
    if t.is_empty() {
        "—".into()
    } else {
        t.iter()
            .map(|t| format!("{t:?}"))
            .collect::<Vec<_>>()
            .join(" + ")
    }
}

/// The named terms, a partial one ("partly explained by") marked.
fn named_with_partial(x: &Outcome) -> String {
    if x.named.is_empty() {
        return "—".into();
    }
    x.named
        .iter()
        .map(|t| {
            if x.partial.contains(t) {
                format!("{t:?} (partial)")
            } else {
                format!("{t:?}")
            }
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

/// `exo diagnose-bench`'s table: each case's true and named effects, the
/// fit before and after, and the confusion ([`confusion`]).
pub fn bench_table(o: &[Outcome]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\n{:<13} {:<34} {:<34} {:>9} {:>12} {:>10} {:>9}  ok",
        "case", "true effect", "named", "R² refit", "RSS refit", "RSS final", "held-out"
    );
    for x in o {
        let _ = writeln!(
            s,
            "{:<13} {:<34} {:<34} {:>9.4} {:>12.1} {:>10.1} {:>8.0}%  {}",
            x.case,
            names(&x.expected),
            named_with_partial(x),
            x.r2_refit,
            x.rss[0],
            x.rss[1],
            100.0 * x.heldout_change,
            if x.correct { "yes" } else { "NO" }
        );
    }
    let concealed = o.iter().filter(|x| !x.expected.is_empty()).count();
    let named_ok = o
        .iter()
        .filter(|x| !x.expected.is_empty() && x.correct)
        .count();
    let nulls = o.iter().filter(|x| x.expected.is_empty()).count();
    let clean = o
        .iter()
        .filter(|x| x.expected.is_empty() && x.named.is_empty())
        .count();
    let _ = writeln!(
        s,
        "\nconcealed effects named exactly: {named_ok} of {concealed}; null cases with nothing named: {clean} of {nulls}"
    );
    s.push_str(&confusion(o));
    for x in o {
        let _ = writeln!(s, "\n{} — {}", x.case, x.what);
        for v in &x.verdict {
            let _ = writeln!(s, "  {v}");
        }
    }
    s
}

/// The confusion matrix: rows are the true effects (and `none` for the null
/// cases), columns the terms named (and `none`). A true effect counts on
/// the diagonal when it was named, under `none` when it was missed; a term
/// named that the case does not have counts in the row of the case's
/// effect (or `none`), so every off-diagonal number is an error.
pub fn confusion(o: &[Outcome]) -> String {
    let label = |t: Option<Term>| t.map_or("none".to_string(), |t| format!("{t:?}"));
    let mut rows: Vec<Option<Term>> = Vec::new();
    let mut cols: Vec<Option<Term>> = Vec::new();
    let mut cells: std::collections::BTreeMap<(String, String), usize> = Default::default();
    let mut add = |r: Option<Term>,
                   c: Option<Term>,
                   rows: &mut Vec<Option<Term>>,
                   cols: &mut Vec<Option<Term>>| {
        if !rows.contains(&r) {
            rows.push(r);
        }
        if !cols.contains(&c) {
            cols.push(c);
        }
        *cells.entry((label(r), label(c))).or_default() += 1;
    };
    for x in o {
        if x.expected.is_empty() {
            if x.named.is_empty() {
                add(None, None, &mut rows, &mut cols);
            }
            for n in &x.named {
                add(None, Some(*n), &mut rows, &mut cols);
            }
            continue;
        }
        for t in &x.expected {
            let hit = x.named.contains(t);
            add(
                Some(*t),
                if hit { Some(*t) } else { None },
                &mut rows,
                &mut cols,
            );
        }
        for n in x.named.iter().filter(|n| !x.expected.contains(n)) {
            add(Some(x.expected[0]), Some(*n), &mut rows, &mut cols);
        }
    }
    let mut s = String::from(
        "\nconfusion (rows: true effect, columns: named; a case with two effects counts in both rows)\n",
    );
    let _ = write!(s, "{:<20}", "true \\ named");
    for c in &cols {
        let _ = write!(s, " {:>18}", label(*c));
    }
    s.push('\n');
    for r in &rows {
        let _ = write!(s, "{:<20}", label(*r));
        for c in &cols {
            let n = cells.get(&(label(*r), label(*c))).copied().unwrap_or(0);
            let _ = write!(
                s,
                " {:>18}",
                if n == 0 {
                    ".".to_string()
                } else {
                    n.to_string()
                }
            );
        }
        s.push('\n');
    }
    s
}

fn score_rows(w: &mut String, label: &str, s: &Score) {
    for t in &s.per_tf {
        let _ = writeln!(
            w,
            "  {label:<22} {:<15} {:>6} {:>14.1} {:>9.4} {:>14.1}",
            t.tf.name(),
            t.points,
            t.rss,
            t.r2,
            t.heldout_rss
        );
    }
}

/// The human-readable report of `exo diagnose`.
/// The standard-error cell of a refitted parameter: "not determined" when
/// it is not finite, zero or larger than the value.
fn std_error_cell(v: f64, se: f64) -> String {
    if exo_diagnose::terms::determined(v, se) {
        format!("{se:.4}")
    } else {
        "not determined".into()
    }
}

pub fn text(r: &Diagnosis) -> String {
    let mut w = String::new();
    let _ = writeln!(w, "exo diagnose: {}", r.sources.join(", "));
    let _ = writeln!(
        w,
        "transfer functions compared: {}",
        r.supported
            .iter()
            .map(|t| format!("{} = {}", t.name(), t.signals()))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if !r.notes.is_empty() {
        let _ = writeln!(w, "\nnot used ({}):", r.notes.len());
        for n in r.notes.iter().take(12) {
            let _ = writeln!(w, "  - {n}");
        }
        if r.notes.len() > 12 {
            let _ = writeln!(w, "  … and {} more (see --json)", r.notes.len() - 12);
        }
    }
    let _ = writeln!(w, "\n1. Where the model and the data differ");
    for l in &r.location.summary {
        let _ = writeln!(w, "  - {l}");
    }
    for s in &r.location.scaling {
        let _ = writeln!(
            w,
            "  - {} residual after the refit: correlation of its quadrature part with 1/amplitude {:+.2}, of its in-phase part with K_h {:+.2}, of its phase with ω {:+.2} ({} points)",
            s.tf.name(),
            s.with_inverse_amplitude,
            s.with_stiffness,
            s.phase_with_omega,
            s.windows
        );
    }
    // Harmonics against each window's own noise, the ringing kept out of
    // it (`exo_diagnose::signatures`): the lines of section 5.
    let harm: Vec<String> = r
        .remains
        .iter()
        .flat_map(|rm| rm.words.iter())
        .filter(|l| l.contains("harmonic of the excitation"))
        .cloned()
        .collect();
    for l in &harm {
        let _ = writeln!(w, "  - time domain: {l}");
    }
    let _ = writeln!(w, "\n2. Parameters of the nominal model, refitted");
    let _ = writeln!(
        w,
        "  {:<36} {:>12} {:>12} {:>10} {:>9}",
        "parameter", "nominal", "fitted", "s.e.", "change"
    );
    for c in &r.parameter_changes {
        let _ = writeln!(
            w,
            "  {:<36} {:>12.4} {:>12.4} {:>10} {:>8.1}%",
            c.label,
            c.nominal,
            c.fitted,
            std_error_cell(c.fitted, c.std_error),
            c.change_pct
        );
    }
    let _ = writeln!(w, "\n3. Candidate physics, one term at a time");
    if r.steps.is_empty() {
        let _ = writeln!(
            w,
            "  not searched: after the refit {}",
            r.refit.within_words(r.level, "the model")
        );
    }
    for st in &r.steps {
        let _ = writeln!(
            w,
            "  step {}: {:<44} {:>4} {:>10} {:>8} {:>10} {:>8} {:>9}",
            st.step, "candidate", "+p", "F", "F_crit", "p (Holm)", "ΔAIC", "held-out"
        );
        for c in &st.candidates {
            let _ = writeln!(
                w,
                "  {} {:<50} {:>4} {:>10.2} {:>8.2} {:>10.2e} {:>8.1} {:>8.1}%  {}",
                if c.chosen { "→" } else { " " },
                c.words,
                c.added_parameters,
                c.f,
                c.f_critical,
                c.p_holm,
                c.delta_aic,
                100.0 * c.heldout_change,
                if c.identified {
                    c.description.clone()
                } else {
                    format!(
                        "{} (not distinguishable from the term's absence)",
                        c.description
                    )
                }
            );
            // Why a significant candidate was not added: each criterion
            // that rejected it, with its reason.
            if !c.chosen && c.significant {
                for why in &c.rejected_because {
                    let _ = writeln!(w, "      rejected: {why}");
                }
            }
            if let Some(a) = &c.amplitude_check {
                let _ = writeln!(w, "      amplitude check: {}", a.words);
            }
        }
    }
    let _ = writeln!(w, "\n4. Fit before and after");
    let _ = writeln!(
        w,
        "  {:<22} {:<15} {:>6} {:>14} {:>9} {:>14}",
        "model", "transfer fn", "points", "RSS (χ²)", "R²", "held-out RSS"
    );
    score_rows(&mut w, "nominal as given", &r.nominal);
    score_rows(&mut w, "nominal refitted", &r.refit);
    score_rows(&mut w, "with terms found", &r.final_score);
    let _ = writeln!(w, "\n5. What remains, per transfer function (final model)");
    for rm in &r.remains {
        for l in &rm.words {
            let _ = writeln!(w, "  - {l}");
        }
    }
    let _ = writeln!(w, "\nVerdict");
    for v in &r.verdict {
        let _ = writeln!(w, "  {v}");
    }
    w
}

/// Writes the report, the updated model, the fitted subject and the JSON
/// into `dir` (created if missing): `report.html`, `updated-plant.toml`,
/// `updated-subject.toml`, `diagnosis.json`.
pub fn write_outputs(dir: &Path, nominal: &PlantModel, d: &Dataset, r: &Diagnosis) -> Result<()> {
    exo_recording::files::create_output_dir(dir).map_err(Error::file("creating", dir))?;
    let updated = r.updated_plant(nominal);
    let mut plant = format!(
        "# Updated by exo diagnose from {}.\n# Terms added: {}.\n\n",
        r.sources.join(", "),
        if r.found.is_empty() {
            "none".to_string()
        } else {
            r.found
                .iter()
                .map(|f| format!("{} ({}: {})", f.words, f.toml_key, f.description))
                .collect::<Vec<_>>()
                .join("; ")
        }
    );
    plant.push_str(&updated.to_toml_string());
    let p = dir.join("updated-plant.toml");
    exo_recording::files::write_output_file(&p, plant).map_err(Error::file("writing", &p))?;
    let p = dir.join("updated-subject.toml");
    exo_recording::files::write_output_file(&p, r.final_physics.subject_toml("diagnosed"))
        .map_err(Error::file("writing", &p))?;
    let p = dir.join("diagnosis.json");
    exo_recording::files::write_output_file(&p, serde_json::to_string_pretty(r)?)
        .map_err(Error::file("writing", &p))?;
    let p = dir.join("report.html");
    exo_recording::files::write_output_file(&p, html(d, r)?).map_err(Error::file("writing", &p))?;
    Ok(())
}
