//! `exo report RECORDING.mcap … -o DIR`: the fit of [`crate::fit_cmd`] as a
//! self-contained HTML report with the paper's figures made from the data.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;

use exo_identifier::offline::{fit, FitOptions, Loaded};

use crate::fit_cmd::{note, FitArgs};
use exo_report::figures::{html, TimeTrace};

/// Arguments of `exo report`.
#[derive(Debug, Args)]
pub struct ReportArgs {
    /// What to fit (the same options as `exo fit`).
    #[command(flatten)]
    pub fit: FitArgs,
    /// Directory the report (report.html) is written to.
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
}

/// One analysis window of each recording, with a second before it: θ_e, τ_c, τ_s.
fn traces(loaded: &[Loaded]) -> Vec<TimeTrace> {
    let mut out = Vec::new();
    for l in loaded {
        let r = &l.recording;
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
                    r.source, l.subject
                ),
                s.saturating_sub(1_000_000_000),
                t,
            ),
            None => (
                format!("{}: subject {}", r.source, l.subject),
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
        if !tr.t_s.is_empty() {
            out.push(tr);
        }
    }
    out
}

/// Fits `fit` and writes `<out>/report.html`; returns its path.
pub fn write_report(fit_args: &FitOptions, out: &Path) -> Result<PathBuf> {
    let (loaded, report) = fit(fit_args, &mut note)?;
    eprintln!("exo report: drawing the figures");
    let sources: Vec<String> = fit_args
        .recordings
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let page = html(
        "exo report: complex-stiffness identification",
        &sources,
        &report,
        &traces(&loaded),
    )?;
    exo_recording::files::create_output_dir(out)
        .with_context(|| format!("creating {}", out.display()))?;
    let path = out.join("report.html");
    exo_recording::files::write_output_file(&path, page)
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}

/// Runs `exo report`.
pub fn run(a: &ReportArgs) -> Result<()> {
    let path = write_report(&a.fit.options(), &a.out)?;
    println!("{}", path.display());
    Ok(())
}
