//! `exo`: the command-line tool of the exo project.
//!
//! Subcommands:
//! - `exo design`: the paper's loop-shaping recipe for the fractional-order
//!   amplification controller (gains, filter, discrete coefficients, margins,
//!   predicted amplification, Bode plot).
//! - `exo run CONFIG`: start and supervise the processes of a run.
//! - `exo sim CONFIG`: the same run in one process (lockstep, no IPC).
//! - `exo tune SUBJECT`: the paper's tuning experiment, automated.
//! - `exo fit`, `exo report`, `exo import`: recordings to the paper's tables and figures.
//! - `exo reproduce`: the paper's modelling study, simulated and compared.
//! - `exo diagnose`, `exo diagnose-bench`: what a plant model leaves out.
//! - `exo op`: the operator console (reset, adopt f, start, stop).

mod args;
mod design_cmd;
mod diagnose_bench;
mod diagnose_cmd;
mod faults;
mod fit_cmd;
mod import_cmd;
mod op_cmd;
mod report_cmd;
mod reproduce_cmd;
mod run_cmd;
mod sim_cmd;
mod tune_cmd;

use clap::{Parser, Subcommand};

/// exo: identify a human joint's complex-stiffness impedance and run an
/// amplification controller tuned to it.
#[derive(Debug, Parser)]
#[command(name = "exo", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Design the fractional-order amplification controller (He et al. 2020,
    /// "Loop Shaping Methods"): kp, kf, f, lag filters, discrete coefficients,
    /// phase margins at both stiffness bounds, predicted amplification.
    Design(design_cmd::DesignArgs),
    /// Start and supervise the processes of a run configuration (plant
    /// simulator or hardware driver, controller, identifier, recorder).
    Run(run_cmd::RunArgs),
    /// The same run in one process: the nodes stepped in lockstep with no
    /// shared memory, recorded to the same contract, fitted and reported.
    Sim(sim_cmd::SimArgs),
    /// The paper's tuning experiment on a simulated subject: raise f until a
    /// spring-release test oscillates at low and high stiffness, take the
    /// lower, subtract 0.12; printed beside the model's prediction.
    Tune(tune_cmd::TuneArgs),
    /// Fit recordings as the paper does: FRF points, M1/M2/M3, F-tests,
    /// phase-shift and M2 tables, power laws and the recommended f.
    Fit(fit_cmd::FitArgs),
    /// A self-contained HTML report of recordings: the paper's figures
    /// (Bode plots with fits, F-test bars, power law, time responses) and tables.
    Report(report_cmd::ReportArgs),
    /// The paper's modelling study simulated: subjects A–J through the nine
    /// experiments in the real processes, recorded, fitted and compared with
    /// the simulated impedance.
    Reproduce(reproduce_cmd::ReproduceArgs),
    /// Where a plant model and recordings differ: locate the mismatch, name
    /// the physics the model left out, model it and show the fit improve.
    Diagnose(diagnose_cmd::DiagnoseArgs),
    /// The mismatch finder proven on concealed effects: each case simulated
    /// through the real processes, diagnosed, and a confusion table printed.
    DiagnoseBench(diagnose_bench::BenchArgs),
    /// Turn another rig's CSV (time, angle, torque, optional actuator torque)
    /// into a contract recording.
    Import(import_cmd::ImportArgs),
    /// The operator console: send a running system one command (reset a
    /// latched fault, adopt f, start or stop the protocol).
    Op(op_cmd::OpArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Design(args) => design_cmd::run(&args),
        Command::Run(args) => run_cmd::run(&args),
        Command::Sim(args) => sim_cmd::run(&args),
        Command::Tune(args) => tune_cmd::run(&args),
        Command::Fit(args) => fit_cmd::run(&args),
        Command::Report(args) => report_cmd::run(&args),
        Command::Import(args) => import_cmd::run(&args),
        Command::Reproduce(args) => reproduce_cmd::run(&args),
        Command::Diagnose(args) => diagnose_cmd::run(&args),
        Command::DiagnoseBench(args) => diagnose_bench::run(&args),
        Command::Op(args) => op_cmd::run(&args),
    };
    if let Err(err) = result {
        eprintln!("exo: error: {err:#}");
        let code = if err.downcast_ref::<faults::FinishedWithFaults>().is_some() {
            faults::FINISHED_WITH_FAULTS
        } else if let Some(op) = err.downcast_ref::<op_cmd::OpFailure>() {
            op.exit_code()
        } else {
            1
        };
        std::process::exit(code);
    }
}
