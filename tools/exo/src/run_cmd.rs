//! `exo run CONFIG`: validates a run configuration and every file it names,
//! then starts and supervises its processes; `exo run --check CONFIG`
//! validates only, starting nothing.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use exo_config::{RunConfig, TimingMode};

use std::time::Instant;

use exo_experiments::offline::{fit, FitOptions};
use exo_messages::ProtocolState;
use exo_service_kit::channels::PROTOCOL;
use exo_service_kit::collect::Collector;
use exo_service_kit::KeptOff;

use exo_supervisor::{check_or_fail, services_of, supervise, Logs};

/// Arguments of `exo run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The run configuration (e.g. configs/default.toml).
    pub config: PathBuf,
    /// Do not fit the recording and write the report after the run.
    #[arg(long)]
    pub no_report: bool,
    /// Only check: validate the run file and every file it names (plant
    /// model, subject, experiment table, the iceoryx2 configuration), the
    /// checks across them (Nyquist, integration step, the controller's
    /// stability, the output directory), start nothing and write nothing;
    /// print `ok` and what was checked, or every error found (file: key:
    /// what is wrong) and exit non-zero. `exo run` makes the same check
    /// before it starts any process.
    #[arg(long)]
    pub check: bool,
}

/// Prints a line whenever the run enters a new experiment period: which
/// one, simulated time (from the samples' stamps) and wall time.
pub struct Progress {
    protocol: Collector<ProtocolState>,
    seen: usize,
    last: (u32, u32),
    first_stamp_ns: Option<u64>,
    wall: Instant,
}

impl Progress {
    /// Watches the protocol channel of `instance`; a line per period.
    pub fn start(instance: &str) -> Result<Self> {
        let node = format!("exo_progress_{}", std::process::id());
        Ok(Progress {
            protocol: Collector::start(&node, instance, PROTOCOL)
                .context("watching the protocol channel for progress")?,
            seen: 0,
            last: (0, 0),
            first_stamp_ns: None,
            wall: Instant::now(),
        })
    }

    /// Prints what is new since the last call.
    pub fn poll(&mut self) {
        let states = self.protocol.snapshot();
        for p in &states[self.seen.min(states.len())..] {
            let first = *self.first_stamp_ns.get_or_insert(p.stamp_ns);
            if (p.experiment, p.period) != self.last && p.experiment > 0 {
                let sim_s = p.stamp_ns.saturating_sub(first) as f64 * 1e-9;
                let wall_s = self.wall.elapsed().as_secs_f64();
                eprintln!(
                    "exo: experiment {} period {} (ω = {:.2} rad/s, {:.2} Nm, α = {}): sim {:.1} s, wall {:.1} s ({:.1}× real time)",
                    p.experiment,
                    p.period,
                    p.omega,
                    p.amplitude,
                    p.alpha,
                    sim_s,
                    wall_s,
                    sim_s / wall_s.max(1e-9)
                );
            }
            self.last = (p.experiment, p.period);
        }
        self.seen = states.len();
    }
}

/// Where a run's recording goes: `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`.
pub fn recording_path(cfg: &RunConfig) -> PathBuf {
    let unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    cfg.run.output_dir.join(format!(
        "{}-{}-{unix_s}.mcap",
        cfg.run.instance,
        cfg.subject().name
    ))
}

/// Validates a run file, then starts and supervises its processes with
/// progress lines; returns the recording's path when the recorder ran and
/// the faults the run met.
pub fn run_config(config: &std::path::Path, logs: Logs) -> Result<Finished> {
    // Validate everything before any process starts.
    let checked = check_or_fail(config)?;
    for w in &checked.warnings {
        eprintln!("exo: warning: {w}");
    }
    let cfg = checked.cfg;
    exo_recording::files::create_output_dir(&cfg.run.output_dir).map_err(|e| {
        anyhow::anyhow!(
            "{}: run.output_dir: cannot create {}: {e}",
            config.display(),
            cfg.run.output_dir.display()
        )
    })?;
    let recording = cfg.services.recorder.then(|| recording_path(&cfg));
    let services = services_of(&cfg, config, recording.as_deref())?;
    eprintln!(
        "exo: starting {} for {} ({:?} timing at {} Hz)",
        services
            .iter()
            .map(|s| s.name)
            .collect::<Vec<_>>()
            .join(", "),
        config.display(),
        cfg.run.timing,
        cfg.run.rate_hz
    );
    keep_off_the_control_path(&cfg);
    let mut progress = Progress::start(&cfg.run.instance)?;
    let watch = crate::faults::FaultWatch::start(&cfg.run.instance)?;
    let outcome = supervise(services, logs, || progress.poll())
        .with_context(|| format!("run of {}", config.display()));
    progress.poll();
    let mut faults = outcome?;
    if let Some(r) = &recording {
        // A recorder that died (and was not restarted) left its last
        // segment under its partial name.
        for done in exo_recording::segments::finish_orphans(r)
            .with_context(|| format!("finishing the segments of {}", r.display()))?
        {
            faults.push(format!(
                "the recorder did not finish {}: kept with what its complete chunks hold (the end of the run may be missing){}",
                done.0.display(),
                exo_recording::segments::given_up_note(&done.1)
            ));
        }
        let segments = exo_recording::segments::segments(r);
        for s in &segments {
            eprintln!("exo: recording {}", s.display());
        }
        if segments.len() > 1 {
            faults.extend(recording_gaps(r)?);
        }
        faults.extend(recorder_misses(&segments));
    }
    let (seen, missed) = watch.faults()?;
    faults.extend(seen);
    if let Some(m) = missed {
        eprintln!("exo: note: {m}");
    }
    for f in &faults {
        eprintln!("exo: fault: {f}");
    }
    Ok(Finished { recording, faults })
}

/// The samples a recording in several segments misses (its recorder was
/// restarted), one line each.
fn recording_gaps(first: &Path) -> Result<Vec<String>> {
    use exo_recording::Recordable;
    let r = exo_recording::read_recording_topics(first, &[exo_messages::SensorSample::TOPIC])
        .with_context(|| format!("reading {} and its segments", first.display()))?;
    Ok(r.warnings
        .into_iter()
        .filter(|w| w.contains("are in no segment"))
        .collect())
}

/// The samples the recorder missed within each segment (sequence gaps:
/// its subscriber buffers overflowed while it was stalled or slow), one
/// line per segment and topic, from each segment's `exo.drops` record. A
/// segment without the record (its recorder died) is named already, as
/// the restart or the unfinished file.
fn recorder_misses(segments: &[PathBuf]) -> Vec<String> {
    let mut out = Vec::new();
    for s in segments {
        let missed = exo_recording::drops::read_drops(s).and_then(|d| match d {
            Some(d) => exo_recording::drops::missed(s, &d),
            None => Ok(Vec::new()),
        });
        match missed {
            Ok(missed) => out.extend(missed.iter().map(|m| describe_missed(s, m))),
            Err(e) => out.push(format!(
                "cannot read what the recorder missed in {}: {e}",
                s.display()
            )),
        }
    }
    out
}

/// One topic's misses as a fault line: the count, the first missing seq,
/// the file.
pub fn describe_missed(file: &Path, m: &exo_recording::drops::Missed) -> String {
    format!(
        "the recorder missed {} samples of {} (sequence gaps){} in {}",
        m.count,
        m.topic,
        m.first_seq
            .map_or(String::new(), |s| format!(", the first seq {s},")),
        file.display()
    )
}

/// A run the processes finished.
pub struct Finished {
    /// The recording, when the recorder ran.
    pub recording: Option<PathBuf>,
    /// The faults seen on the way ([`crate::faults::FaultWatch`]).
    pub faults: Vec<String>,
}

impl Finished {
    /// `Ok` for a run without faults, else the error naming them (exit
    /// code [`crate::faults::FINISHED_WITH_FAULTS`]).
    pub fn check(self) -> Result<()> {
        if self.faults.is_empty() {
            Ok(())
        } else {
            Err(crate::faults::FinishedWithFaults(self.faults).into())
        }
    }
}

/// In real time with the driver or the controller pinned (`[realtime]`),
/// confines the launcher, and so every process it starts, to the other
/// CPUs: the identifier, the recorder and the launcher's own log forwarding
/// then never share a CPU with the control path, which pins itself back
/// onto its CPUs. On a kernel that is not preemptible, a process in a long
/// system call holds its CPU whatever the control path's priority
/// (BENCHMARKS.md, "Recorder under load"). Must run before the launcher
/// starts any thread.
fn keep_off_the_control_path(cfg: &RunConfig) {
    let Some(rt) = cfg
        .realtime
        .filter(|_| cfg.run.timing == TimingMode::Realtime)
    else {
        return;
    };
    let mut control: Vec<usize> = [rt.sensor_driver_cpu, rt.controller_cpu]
        .into_iter()
        .flatten()
        .collect();
    control.dedup();
    if control.is_empty() {
        return;
    }
    match exo_service_kit::keep_off_cpus(&control) {
        Ok(KeptOff::Confined(rest)) => eprintln!(
            "exo: control path on CPU {control:?}; launcher, identifier and recorder on CPU {rest:?}"
        ),
        Ok(KeptOff::AlreadyOff) => eprintln!(
            "exo: control path on CPU {control:?}; the launcher was already confined to other CPUs"
        ),
        Ok(KeptOff::NoneLeft) => eprintln!(
            "exo: warning: no CPU left besides the control path's {control:?}; \
             the identifier and the recorder share them"
        ),
        Err(e) => eprintln!(
            "exo: warning: could not keep the launcher off the control path's CPUs {control:?}: {e}"
        ),
    }
}

/// Runs `exo run`: the processes, then (when the run was recorded) the fit
/// and the report of the recording; with `--check`, only the check.
pub fn run(args: &RunArgs) -> Result<()> {
    if args.check {
        let checked = check_or_fail(&args.config)?;
        println!("ok");
        for line in &checked.checked {
            println!("  {line}");
        }
        for w in &checked.warnings {
            eprintln!("exo: warning: {w}");
        }
        return Ok(());
    }
    let finished = run_config(&args.config, Logs::Forward)?;
    if let Some(recording) = &finished.recording {
        let cfg = RunConfig::from_file(&args.config)?;
        fit_and_report(&cfg, recording, args.no_report)?;
    }
    finished.check()
}

/// After a run: fits the recording and writes its report beside it
/// (`<recording>-report/`), printing the tables and `recording: PATH`,
/// `report: PATH`; only for the modes that excite the subject for a fit
/// (the sine steps and the multisine: `ProtocolMode::identifies`; a replay
/// republishes whatever the recording's protocol was), and not with
/// `no_report`.
pub fn fit_and_report(cfg: &RunConfig, recording: &Path, no_report: bool) -> Result<()> {
    if no_report || !cfg.protocol.mode.identifies() {
        return Ok(());
    }
    let fit_args = FitOptions::for_recordings(vec![recording.to_path_buf()]);
    let (loaded, report) = fit(&fit_args, &mut crate::fit_cmd::note)?;
    print!("{}", exo_report::fit::tables(&report));
    let stem = recording
        .file_stem()
        .map_or("run".into(), |s| s.to_string_lossy().into_owned());
    let dir = recording
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .join(format!("{stem}-report"));
    let page = crate::report_cmd::write_fitted_report(&fit_args, &loaded, &report, &dir)?;
    println!("recording: {}", recording.display());
    println!("report:    {}", page.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_topic_the_recorder_missed_is_named_with_its_count_and_first_seq() {
        let m = exo_recording::drops::Missed {
            topic: "exo/sensor".into(),
            count: 1800,
            first_seq: Some(2301),
        };
        assert_eq!(
            describe_missed(Path::new("out/run.mcap"), &m),
            "the recorder missed 1800 samples of exo/sensor (sequence gaps), the first seq 2301, in out/run.mcap"
        );
        let older = exo_recording::drops::Missed {
            first_seq: None,
            ..m
        };
        assert_eq!(
            describe_missed(Path::new("r.mcap"), &older),
            "the recorder missed 1800 samples of exo/sensor (sequence gaps) in r.mcap"
        );
    }
}
