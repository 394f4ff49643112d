//! `exo fit`'s output: the paper's tables as text (Table II and III
//! layouts, F-tests of eq. ft, power law of eq. ch, eq. f's recommended
//! order) and as CSV files.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::{Error, Result};
use exo_analysis::study::FitReport;

/// `value ± half-width` to `digits` decimals, `—` for a term the model lacks.
fn with_ci(value: f64, ci: Option<f64>, digits: usize, present: bool) -> String {
    if !present {
        return "—".into();
    }
    match ci {
        Some(c) => format!("{value:.digits$} ± {c:.digits$}"),
        None => format!("{value:.digits$}"),
    }
}

/// The human-readable tables (intervals are 95 %).
pub fn tables(r: &FitReport) -> String {
    let mut s = String::new();
    for sub in &r.subjects {
        let _ = writeln!(s, "Subject {}", sub.subject);
        for e in &sub.experiments {
            let condition = e
                .condition
                .as_deref()
                .map_or(String::new(), |c| format!(" \"{c}\""));
            let _ = writeln!(
                s,
                "  experiment {}{condition} (α = {}, load {} kg, M_e = {:.4} kg·m²): {} FRF points; parameters from {}",
                e.experiment,
                e.alpha,
                e.load_kg,
                e.m_e_kg_m2,
                e.points.len(),
                match e.fit_source {
                    "actuator" => "(τ_s − τ_gravity)/θ_e − M_e s²",
                    _ => "S_h = τ_c/θ_e",
                }
            );
            let _ = writeln!(
                s,
                "    {:>9} {:>10} {:>10} {:>9} {:>9} {:>8}  {:>12} {:>8}",
                "ω rad/s", "Re S_h", "Im S_h", "∠S_h °", "γ²", "σ/|S_h|", "Re S_h-e/α*", "Im"
            );
            for p in &e.points {
                let _ = writeln!(
                    s,
                    "    {:>9.3} {:>10.3} {:>10.3} {:>9.2} {:>9.4} {:>8.4}  {:>12.3} {:>8.3}",
                    p.omega,
                    p.s_h[0],
                    p.s_h[1],
                    p.s_h_phase_deg,
                    p.coherence,
                    p.noise_rel,
                    p.s_h_e_alpha[0],
                    p.s_h_e_alpha[1]
                );
            }
            let _ = writeln!(
                s,
                "    (* S_h-e/α = S_h − (M_e/α) ω², re-created from S_h as the paper does)"
            );
            let _ = writeln!(
                s,
                "    {:>5} {:>17} {:>17} {:>19} {:>19} {:>7} {:>7}",
                "model", "K Nm/rad", "H Nm/rad", "B Nms/rad", "M_h kg·m²", "R²", "χ²/dof"
            );
            for (name, m) in &e.models {
                let _ = writeln!(
                    s,
                    "    {:>5} {:>17} {:>17} {:>19} {:>19} {:>7.4} {:>7}{}",
                    name,
                    with_ci(m.k, m.ci95.map(|c| c[0]), 2, true),
                    with_ci(m.h, m.ci95.map(|c| c[1]), 2, name != &"M1"),
                    with_ci(m.b, m.ci95.map(|c| c[2]), 4, name != &"M2"),
                    with_ci(m.m, m.ci95.map(|c| c[3]), 4, true),
                    m.r2,
                    m.chi2_per_dof.map_or("—".into(), |c| format!("{c:.2}")),
                    if m.held_at_zero.is_empty() {
                        String::new()
                    } else {
                        format!("  ({} held at 0)", m.held_at_zero.join(", "))
                    }
                );
            }
        }
        match (sub.beta0, sub.beta1, sub.r2) {
            (Some(b0), Some(b1), Some(r2)) => {
                let _ = writeln!(
                    s,
                    "  power law (M2): log10 H = {b0:.3} + {b1:.3} log10 K, R² = {r2:.3}"
                );
            }
            _ => {
                let _ = writeln!(s, "  power law: needs M2 fits of at least two experiments");
            }
        }
        match (sub.recommended_f, &sub.recommended_f_note) {
            (Some(f), _) => {
                let _ = writeln!(s, "  recommended fractional order (eq. f): f = {f:.3}");
            }
            (None, Some(n)) => {
                let _ = writeln!(s, "  recommended fractional order: none ({n})");
            }
            _ => {}
        }
    }
    let _ = writeln!(s, "\nF-tests (eq. ft)");
    let _ = writeln!(
        s,
        "  {:>10} {:>12} {:>12} {:>10} {:>12}",
        "group", "F M1−M3", "F M2−M3", "critical", "df"
    );
    for g in r.f_tests.all_groups() {
        let _ = writeln!(
            s,
            "  {:>10} {:>12.3} {:>12.3} {:>10.3} {:>12}",
            g.group,
            g.m1_m3.statistic,
            g.m2_m3.statistic,
            g.m1_m3.critical,
            format!("({}, {})", g.m1_m3.df[0], g.m1_m3.df[1])
        );
    }
    let _ = writeln!(
        s,
        "\nPhase of S_h (Table II layout; last three frequencies excluded)"
    );
    for p in &r.phase_table {
        let cells: Vec<String> = p
            .groups
            .iter()
            .map(|g| {
                format!(
                    "exp {}: {:.1}° ± {:.1}° (n = {})",
                    g.experiments, g.mean_deg, g.se_deg, g.n
                )
            })
            .collect();
        let cells = if cells.is_empty() {
            "no point: every experiment has three frequencies or fewer, and the highest three are left out".to_string()
        } else {
            cells.join("   ")
        };
        let _ = writeln!(s, "  {:>8}  {cells}", p.subject);
    }
    let _ = writeln!(s, "\nM2 parameters (Table III layout)");
    for sub in &r.subjects {
        let row: Vec<String> = sub
            .experiments
            .iter()
            .filter_map(|e| {
                e.models
                    .get("M2")
                    .map(|m| format!("{}: K {:.2} H {:.2} M_h {:.3}", e.experiment, m.k, m.h, m.m))
            })
            .collect();
        let _ = writeln!(s, "  {:>8}  {}", sub.subject, row.join(" | "));
    }
    if !r.warnings.is_empty() {
        let _ = writeln!(s, "\nNot used:");
        for w in &r.warnings {
            let _ = writeln!(s, "  - {w}");
        }
    }
    s
}

/// A free-text CSV cell, quoted.
fn csv_text(s: Option<&str>) -> String {
    s.map_or(String::new(), |s| format!("\"{}\"", s.replace('"', "\"\"")))
}

/// Writes the tables as CSV files into `dir` (created if missing):
/// `frf.csv`, `models.csv`, `ftests.csv`, `phase.csv`, `power_law.csv`.
pub fn write_csv(dir: &Path, r: &FitReport) -> Result<()> {
    exo_recording::files::create_output_dir(dir).map_err(Error::file("creating", dir))?;
    let mut frf = String::from("subject,experiment,condition,period,omega_rad_s,s_h_re,s_h_im,s_h_e_alpha_re,s_h_e_alpha_im,s_h_e_actuator_re,s_h_e_actuator_im,s_h_phase_deg,coherence,noise_rel\n");
    let mut models = String::from("subject,experiment,condition,model,K,H,B,M,K_ci95,H_ci95,B_ci95,M_ci95,r2,rss,chi2_per_dof\n");
    for s in &r.subjects {
        for e in &s.experiments {
            for p in &e.points {
                let _ = writeln!(
                    frf,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    s.subject,
                    e.experiment,
                    csv_text(e.condition.as_deref()),
                    p.period,
                    p.omega,
                    p.s_h[0],
                    p.s_h[1],
                    p.s_h_e_alpha[0],
                    p.s_h_e_alpha[1],
                    p.s_h_e_actuator[0],
                    p.s_h_e_actuator[1],
                    p.s_h_phase_deg,
                    p.coherence,
                    p.noise_rel
                );
            }
            for (name, m) in &e.models {
                let ci = m.ci95.map_or(
                    [String::new(), String::new(), String::new(), String::new()],
                    |c| c.map(|x| x.to_string()),
                );
                let _ = writeln!(
                    models,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    s.subject,
                    e.experiment,
                    csv_text(e.condition.as_deref()),
                    name,
                    m.k,
                    m.h,
                    m.b,
                    m.m,
                    ci[0],
                    ci[1],
                    ci[2],
                    ci[3],
                    m.r2,
                    m.rss,
                    m.chi2_per_dof.map_or(String::new(), |c| c.to_string())
                );
            }
        }
    }
    let mut ft = String::from("group,test,statistic,critical,df_num,df_den,p_value\n");
    for g in r.f_tests.all_groups() {
        for (name, t) in [("M1-M3", &g.m1_m3), ("M2-M3", &g.m2_m3)] {
            let _ = writeln!(
                ft,
                "{},{},{},{},{},{},{}",
                g.group, name, t.statistic, t.critical, t.df[0], t.df[1], t.p_value
            );
        }
    }
    let mut phase = String::from("subject,experiments,mean_deg,se_deg,n\n");
    for p in &r.phase_table {
        for g in &p.groups {
            let _ = writeln!(
                phase,
                "{},{},{},{},{}",
                p.subject, g.experiments, g.mean_deg, g.se_deg, g.n
            );
        }
    }
    let mut pl = String::from("subject,beta0,beta1,r2,recommended_f\n");
    for s in &r.subjects {
        let o = |v: Option<f64>| v.map_or(String::new(), |x| x.to_string());
        let _ = writeln!(
            pl,
            "{},{},{},{},{}",
            s.subject,
            o(s.beta0),
            o(s.beta1),
            o(s.r2),
            o(s.recommended_f)
        );
    }
    for (name, text) in [
        ("frf.csv", frf),
        ("models.csv", models),
        ("ftests.csv", ft),
        ("phase.csv", phase),
        ("power_law.csv", pl),
    ] {
        let p = dir.join(name);
        exo_recording::files::write_output_file(&p, text).map_err(Error::file("writing", &p))?;
    }
    Ok(())
}
