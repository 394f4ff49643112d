//! `exo sim CONFIG`: the run in one process. The nodes the processes step
//! (`exo-sim`) are stepped here in lockstep with no shared memory; the
//! recording is the one `exo run` writes through the five processes (the
//! same contract, message for message), then fitted and reported as
//! `exo run` does.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use exo_config::TimingMode;
use exo_plant_model::PlantModel;
use exo_sim::{Ended, FileSink, Record, Sim};

use crate::faults::{describe, is_fault_command, is_fault_sample};
use exo_supervisor::check_or_fail;

use crate::run_cmd::{fit_and_report, recording_path, Finished};

/// `exo sim` arguments.
#[derive(Debug, Args)]
pub struct SimArgs {
    /// The run configuration (e.g. configs/default.toml); its timing is
    /// taken as lockstep whatever it says.
    pub config: PathBuf,
    /// Do not fit the recording and write the report after the run.
    #[arg(long)]
    pub no_report: bool,
    /// Write the recording here instead of
    /// `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`.
    #[arg(long, value_name = "FILE")]
    pub output: Option<PathBuf>,
}

/// Runs `exo sim`.
pub fn run(args: &SimArgs) -> Result<()> {
    exo_service_kit::init_logging("sim");
    let checked = check_or_fail(&args.config)?;
    for w in &checked.warnings {
        eprintln!("exo: warning: {w}");
    }
    let cfg = checked.cfg;
    if cfg.run.timing != TimingMode::Lockstep {
        eprintln!(
            "exo: note: {} asks for real-time timing; `exo sim` steps the nodes in lockstep",
            args.config.display()
        );
    }
    let model = PlantModel::from_file(&cfg.plant_model)?;
    let recording = args.output.clone().unwrap_or_else(|| recording_path(&cfg));
    eprintln!(
        "exo: simulating {} in one process ({} Hz, subject {})",
        args.config.display(),
        cfg.run.rate_hz,
        cfg.subject().name
    );
    let started = Instant::now();
    let mut sim = Sim::new(&cfg, &model)?;
    let mut file = FileSink::create(&recording, &cfg, &args.config)?;
    let (mut fault_commands, mut fault_samples) = (Vec::new(), Vec::new());
    let ended = sim.run(|r| {
        match r {
            Record::Command(c) if is_fault_command(&c) => fault_commands.push(c),
            Record::Sensor(s) if is_fault_sample(&s) => fault_samples.push(s),
            _ => {}
        }
        file.write(r)
    });
    // The recording is renamed into place only when complete: on a failure
    // an earlier file of that name stays as it was, and the half-written
    // partial file goes.
    let written = ended
        .with_context(|| format!("simulating {}", args.config.display()))
        .and_then(|ended| {
            let messages = file
                .finish()
                .with_context(|| format!("finishing {}", recording.display()))?;
            Ok((ended, messages))
        });
    let (ended, messages) = written.inspect_err(|_| {
        exo_recording::segments::discard_partial(&recording);
    })?;
    let wall_s = started.elapsed().as_secs_f64();
    let sim_s = sim.plant().tick() as f64 * sim.plant().period_ns() as f64 * 1e-9;
    eprintln!(
        "exo: {} after {sim_s:.1} s simulated in {wall_s:.2} s ({:.0}× real time), {messages} messages",
        match ended {
            Ended::ControllerFinished => "protocol done",
            Ended::Bound => "run.max_sim_time_s reached",
        },
        sim_s / wall_s.max(1e-9),
    );
    eprintln!("exo: recording {}", recording.display());
    let faults = describe(&fault_commands, &fault_samples);
    for f in &faults {
        eprintln!("exo: fault: {f}");
    }
    fit_and_report(&cfg, &recording, args.no_report)?;
    Finished {
        recording: Some(recording),
        faults,
    }
    .check()
}
