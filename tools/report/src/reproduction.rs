//! `exo reproduce`'s output: the comparison of the recovered impedance with
//! the simulated subjects ([`exo_analysis::reproduce`]) as Markdown tables.

use std::fmt::Write as _;

use exo_analysis::reproduce::{ExperimentComparison, Reproduction};

/// The comparison as Markdown tables (readable in a terminal, pasted in the README).
pub fn tables(r: &Reproduction) -> String {
    let mut s = String::new();
    let c = r.criteria;
    let _ = writeln!(
        s,
        "M2 parameters recovered against the simulated inputs (worst of 9 experiments; limit {:.0} %)\n",
        100.0 * c.kh_rel
    );
    let _ = writeln!(
        s,
        "| subject | worst K_h error | worst H_h error | β0 fit / inputs / Table III | β1 fit / inputs / Table III | F_M1−M3 (critical) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for sub in &r.subjects {
        let worst = |f: fn(&ExperimentComparison) -> f64| {
            sub.experiments
                .iter()
                .map(f)
                .fold(0.0_f64, |a, e| if e.abs() > a.abs() { e } else { a })
        };
        let (fb0, fb1) = sub.law_fit.map_or(("–".into(), "–".into()), |l| {
            (format!("{:.3}", l.beta0), format!("{:.3}", l.beta1))
        });
        let (rb0, rb1) = sub
            .law_reported
            .as_ref()
            .map_or(("–".into(), "–".into()), |l| {
                (format!("{:.2}", l.beta0), format!("{:.2}", l.beta1))
            });
        let f = sub.f_m1_m3.map_or("–".into(), |f| {
            format!("{:.1} ({:.2})", f.statistic, f.critical)
        });
        let _ = writeln!(
            s,
            "| {} | {:+.2} % | {:+.2} % | {fb0} / {:.3} / {rb0} | {fb1} / {:.3} / {rb1} | {f} |",
            sub.subject,
            100.0 * worst(|e| e.k_rel_error),
            100.0 * worst(|e| e.h_rel_error),
            sub.law_input.beta0,
            sub.law_input.beta1,
        );
    }
    let _ = writeln!(
        s,
        "\nPhase of S_h (degrees), mean ± SE over each group's periods but the last three, against arg(K − M_h ω² + jH) of the inputs (limit {}°)\n",
        c.phase_deg
    );
    let labels: Vec<String> = {
        let mut l: Vec<String> = r
            .subjects
            .iter()
            .flat_map(|s| s.phase.iter().map(|p| p.experiments.clone()))
            .collect();
        l.sort();
        l.dedup();
        l
    };
    let _ = writeln!(
        s,
        "| subject | {} |",
        labels
            .iter()
            .map(|l| format!("exp {l}: fit / inputs"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|---|{}", "---|".repeat(labels.len()));
    for sub in &r.subjects {
        let cells: Vec<String> = labels
            .iter()
            .map(|l| {
                sub.phase
                    .iter()
                    .find(|p| &p.experiments == l)
                    .map_or("–".into(), |p| {
                        format!(
                            "{:.1} ± {:.1} / {:.1}",
                            p.fitted_deg, p.se_deg, p.implied_deg
                        )
                    })
            })
            .collect();
        let _ = writeln!(s, "| {} | {} |", sub.subject, cells.join(" | "));
    }
    if r.pass() {
        let _ = writeln!(s, "\nAll criteria met.");
    } else {
        let _ = writeln!(s, "\nCriteria missed:");
        for f in &r.failures {
            let _ = writeln!(s, "  {f}");
        }
    }
    s
}
