//! `exo report RECORDING.mcap … -o DIR`: the fit of [`crate::fit_cmd`] as a
//! self-contained HTML report with the paper's figures made from the data.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;

use exo_analysis::study::FitReport;
use exo_experiments::offline::{fit, FitOptions, Loaded};

use crate::fit_cmd::{note, FitArgs};
use exo_report::figures::{html, trace_of, TimeTrace};

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
    loaded
        .iter()
        .filter_map(|l| trace_of(&l.recording, &l.subject))
        .collect()
}

/// Fits `fit` and writes `<out>/report.html`; returns its path.
pub fn write_report(fit_args: &FitOptions, out: &Path) -> Result<PathBuf> {
    let (loaded, report) = fit(fit_args, &mut note)?;
    write_fitted_report(fit_args, &loaded, &report, out)
}

/// [`write_report`] of recordings already fitted.
pub fn write_fitted_report(
    fit_args: &FitOptions,
    loaded: &[Loaded],
    report: &FitReport,
    out: &Path,
) -> Result<PathBuf> {
    eprintln!("exo report: drawing the figures");
    let sources: Vec<String> = fit_args
        .recordings
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let page = html(
        "exo report: complex-stiffness identification",
        &sources,
        report,
        &traces(loaded),
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
