//! `exo`: the command-line tool of the exo project.
//!
//! Subcommands:
//! - `exo design`: the paper's loop-shaping recipe for the fractional-order
//!   amplification controller (gains, filter, discrete coefficients, margins,
//!   predicted amplification, Bode plot).
//! - `exo run CONFIG`: start and supervise the processes of a run.
//! - `exo tune SUBJECT`: the paper's tuning experiment, automated.

mod args;
mod design_cmd;
mod plot;
mod run_cmd;
mod stability;
mod supervisor;
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
    /// The paper's tuning experiment on a simulated subject: raise f until a
    /// spring-release test oscillates at low and high stiffness, take the
    /// lower, subtract 0.12; printed beside the model's prediction.
    Tune(tune_cmd::TuneArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Design(args) => design_cmd::run(&args),
        Command::Run(args) => run_cmd::run(&args),
        Command::Tune(args) => tune_cmd::run(&args),
    };
    if let Err(err) = result {
        eprintln!("exo: error: {err:#}");
        std::process::exit(1);
    }
}
