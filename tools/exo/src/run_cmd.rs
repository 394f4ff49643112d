//! `exo run CONFIG`: validates a run configuration and every file it names,
//! then starts and supervises its processes; `exo run --check CONFIG`
//! validates only, starting nothing.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use exo_config::{ProtocolMode, RunConfig, TimingMode};

use std::time::Instant;

use exo_identifier::offline::{fit, FitOptions};
use exo_messages::ProtocolState;
use exo_service_kit::channels::Channel;
use exo_service_kit::collect::Collector;
use exo_service_kit::KeptOff;

use crate::supervisor::{
    config_args, sibling_program, supervise, Logs, Ready, ReadyProbe, Role, ServiceSpec,
};

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

/// The processes a configuration asks for, in start order; the recorder
/// writes `recording` when given.
pub fn services_of(
    cfg: &RunConfig,
    config: &std::path::Path,
    recording: Option<&std::path::Path>,
) -> Result<Vec<ServiceSpec>> {
    let s = cfg.services;
    let mut out = Vec::new();
    let table: [(bool, &'static str, &'static str, Role); 6] = [
        (s.recorder, "recorder", "exo-recorder", Role::Restartable),
        (
            s.identifier,
            "identifier",
            "exo-identifier",
            Role::Restartable,
        ),
        (
            s.plant_sim,
            "plant-sim",
            "exo-plant-sim",
            // With run.max_sim_time_s the simulator's normal exit is the end.
            if cfg.run.max_sim_time_s.is_some() {
                Role::EndsRun
            } else {
                Role::Critical
            },
        ),
        (
            s.sensor_driver,
            "sensor-driver",
            "exo-sensor-driver",
            // Without a controller the driver ends the run.
            if s.controller {
                Role::Critical
            } else {
                Role::EndsRun
            },
        ),
        (s.controller, "controller", "exo-controller", Role::EndsRun),
        // A recording played back: the run ends with it.
        (s.player, "player", "exo-player", Role::EndsRun),
    ];
    for (enabled, name, bin, role) in table {
        if enabled {
            let mut args = config_args(config);
            if let (Some(r), "recorder") = (recording, name) {
                args.push("--output".into());
                args.push(r.display().to_string());
            }
            let probe = match name {
                "recorder" => Some(ReadyProbe::SubscribesBusMotor),
                "identifier" => Some(ReadyProbe::PublishesEstimate),
                _ => None,
            };
            out.push(ServiceSpec {
                name,
                program: sibling_program(bin)?,
                args,
                role,
                ready: probe.map(|probe| Ready {
                    instance: cfg.run.instance.clone(),
                    probe,
                }),
            });
        }
    }
    Ok(out)
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
            protocol: Collector::start(&node, instance, Channel::Protocol)
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
        let segments = exo_recording::segments::segments(r);
        for s in &segments {
            eprintln!("exo: recording {}", s.display());
        }
        if segments.len() > 1 {
            faults.extend(recording_gaps(r)?);
        }
    }
    faults.extend(watch.faults()?);
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
/// `report: PATH`; only for the identification protocol, which alone
/// excites the subject for a fit (a replay republishes whatever the
/// recording's protocol was), and not with `no_report`.
pub fn fit_and_report(cfg: &RunConfig, recording: &Path, no_report: bool) -> Result<()> {
    if no_report || cfg.protocol.mode != ProtocolMode::Identification {
        return Ok(());
    }
    let fit_args = FitOptions::for_recordings(vec![recording.to_path_buf()]);
    let (_, report) = fit(&fit_args, &mut crate::fit_cmd::note)?;
    print!("{}", exo_report::fit::tables(&report));
    let stem = recording
        .file_stem()
        .map_or("run".into(), |s| s.to_string_lossy().into_owned());
    let dir = recording
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .join(format!("{stem}-report"));
    let page = crate::report_cmd::write_report(&fit_args, &dir)?;
    println!("recording: {}", recording.display());
    println!("report:    {}", page.display());
    Ok(())
}

/// A run file that passed [`check_run`].
pub struct Checked {
    /// The run configuration, with its experiment table and subject.
    pub cfg: RunConfig,
    /// What was checked, one line each, for `exo run --check`.
    pub checked: Vec<String>,
    /// What is valid but deserves a warning (e.g. a controller stable at
    /// the subject's stiffness but not over the whole design range).
    pub warnings: Vec<String>,
}

/// [`check_run`], with every error in one `anyhow` error (one per line).
pub fn check_or_fail(config: &Path) -> Result<Checked> {
    check_run(config).map_err(|errors| {
        anyhow::anyhow!(
            "{} is refused ({} error{}); nothing was started:\n  {}",
            config.display(),
            errors.len(),
            if errors.len() == 1 { "" } else { "s" },
            errors.join("\n  ")
        )
    })
}

/// Validates the run file `config` and every file it names before any
/// process starts, writing nothing: the run file, its experiment table and
/// subject (`exo_config`), the plant model, the iceoryx2 configuration the
/// services will load, and across them: the plant's integration step
/// divides the control period, the output directory can be created and
/// written, and the controller's model loop is not clearly unstable at the
/// stiffness the subject holds in any experiment of the run nor at either
/// bound of `controller.k_range_nm_per_rad` (refused below
/// [`REFUSE_BELOW_MARGIN_DEG`], warned below 0°). Returns every error
/// found, each naming its file and key.
pub fn check_run(config: &Path) -> std::result::Result<Checked, Vec<String>> {
    let mut errors: Vec<String> = Vec::new();
    let mut checked: Vec<String> = Vec::new();
    let mut warnings: Vec<String> = Vec::new();
    let cfg = match RunConfig::from_file(config) {
        Ok(c) => Some(c),
        Err(e) => {
            errors.extend(e.each().iter().map(|e| e.to_string()));
            None
        }
    };
    // The plant model is checked even when the run file has errors, as long
    // as the run file parses (so its path is known).
    let plant_path = match &cfg {
        Some(c) => Some(c.plant_model.clone()),
        None => exo_config::read_toml::<RunConfig>(config).ok().map(|raw| {
            config
                .parent()
                .unwrap_or(Path::new("."))
                .join(raw.plant_model)
        }),
    };
    let plant = plant_path
        .as_ref()
        .and_then(|p| match exo_plant_sim::PlantModel::from_file(p) {
            Ok(m) => Some(m),
            Err(exo_plant_sim::PlantModelError::Several(v)) => {
                errors.extend(v.iter().map(|e| e.to_string()));
                None
            }
            Err(e) => {
                errors.push(e.to_string());
                None
            }
        });
    let ipc_config = exo_service_kit::ipc::config_path(None);
    match exo_service_kit::ipc::load_config(&ipc_config) {
        Ok(_) => checked.push(format!(
            "iceoryx2     {}",
            ipc_config
                .canonicalize()
                .unwrap_or_else(|_| ipc_config.clone())
                .display()
        )),
        Err(e) => errors.push(e.to_string()),
    }
    if let (Some(cfg), Some(plant)) = (&cfg, &plant) {
        check_across(config, cfg, plant, &mut errors, &mut checked, &mut warnings);
    }
    match (cfg, plant) {
        (Some(cfg), Some(_)) if errors.is_empty() => {
            let table = cfg.experiment_table();
            let periods = cfg.periods_run(table);
            let mut lines = vec![
                format!(
                    "run file     {} ({:?} at {} Hz, instance {}, {:?} protocol)",
                    config.display(),
                    cfg.run.timing,
                    cfg.run.rate_hz,
                    cfg.run.instance,
                    cfg.protocol.mode
                ),
                format!(
                    "experiments  {} (experiments {:?}, periods {:?}, {} s per period)",
                    cfg.protocol.experiments_file.display(),
                    cfg.protocol.experiments,
                    periods,
                    table.timing.period_s()
                ),
                format!(
                    "subject      {} ({})",
                    cfg.subject_file.display(),
                    cfg.subject().name
                ),
                format!("plant        {}", cfg.plant_model.display()),
            ];
            lines.append(&mut checked);
            Ok(Checked {
                cfg,
                checked: lines,
                warnings,
            })
        }
        _ => Err(errors),
    }
}

/// The checks that need the run file and the plant model together.
fn check_across(
    config: &Path,
    cfg: &RunConfig,
    plant: &exo_plant_sim::PlantModel,
    errors: &mut Vec<String>,
    checked: &mut Vec<String>,
    warnings: &mut Vec<String>,
) {
    let run_file = config.display();
    // The simulator advances a whole number of integration steps per tick.
    let period_s = 1.0 / cfg.run.rate_hz;
    let steps = period_s / plant.integration.step_s;
    if (steps - steps.round()).abs() > 1e-9 {
        errors.push(format!(
            "{}: integration.step_s: {} s does not divide the control period {period_s} s (run.rate_hz = {} of {run_file})",
            cfg.plant_model.display(),
            plant.integration.step_s,
            cfg.run.rate_hz
        ));
    }
    // The output directory: created by `exo run`, so its nearest existing
    // ancestor must be a directory we may write into.
    let out = &cfg.run.output_dir;
    let mut existing = Some(out.as_path());
    while let Some(p) = existing {
        if p.as_os_str().is_empty() || p.is_dir() {
            break;
        }
        existing = p.parent();
    }
    let existing = match existing {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if writable(&existing) {
        checked.push(format!(
            "output dir   {}{}",
            out.display(),
            if out.is_dir() {
                ""
            } else {
                " (will be created)"
            }
        ));
    } else {
        errors.push(format!(
            "{run_file}: run.output_dir: {} cannot be written: {} is not writable",
            out.display(),
            existing.display()
        ));
    }
    match controller_margins(config, cfg, plant) {
        Ok(m) => {
            checked.push(format!("controller   {}", m.summary));
            errors.extend(m.errors);
            warnings.extend(m.warnings);
        }
        Err(e) => errors.push(format!("{run_file}: {e}")),
    }
}

fn writable(dir: &Path) -> bool {
    use std::os::unix::ffi::OsStrExt;
    let Ok(c) = std::ffi::CString::new(dir.as_os_str().as_bytes()) else {
        return false;
    };
    // SAFETY: `c` is a valid NUL-terminated path; access(2) only reads it.
    unsafe { libc::access(c.as_ptr(), libc::W_OK | libc::X_OK) == 0 }
}

/// The controller's loop margins at the run's operating points.
struct Margins {
    summary: String,
    errors: Vec<String>,
    warnings: Vec<String>,
}

/// Below this phase margin (degrees) of the model loop `exo run` refuses a
/// controller; between it and 0° it warns. The model (complex stiffness
/// with a constant loss factor, the SEA, rigid cuff) is conservative: the
/// paper's own tuned design for subject B (k_p = 3.2, f = 0.60, Table IV),
/// stable on the rig and in the simulator (`tests/tests/amplification.rs`),
/// has −10.8° at the lower stiffness bound and −5.1° at the stiffness B
/// holds in experiment 4; a design clearly past the edge (f = 0.9 for B:
/// −30° and −33°) is far below.
pub const REFUSE_BELOW_MARGIN_DEG: f64 = -15.0;

/// The loop `(α(s) − 1) P(s)` of the amplification controller (the plant's
/// SEA, the rig's inertias with each experiment's load, the subject's
/// inertia) at the stiffness and loss factor the subject holds in every
/// experiment of the run, and — for a fractional-order controller — at
/// both bounds of `controller.k_range_nm_per_rad` (loss factor there from
/// the power law of the subject's experiments). A phase margin below
/// [`REFUSE_BELOW_MARGIN_DEG`] is an error naming the key that sets the
/// gain (`controller.f` with `controller.kp`, or an experiment's constant
/// α) and the margin; a negative one above it, a warning.
fn controller_margins(
    config: &Path,
    cfg: &RunConfig,
    plant: &exo_plant_sim::PlantModel,
) -> Result<Margins, String> {
    use exo_impedance::loop_shaping::FractionalLayout;
    use exo_impedance::{
        fit_power_law, nominal_crossover, proportional_gain, AmplificationPlant, SeaModel,
        StiffnessRange,
    };
    let science = |key: &str, e: exo_impedance::ScienceError| format!("{key}: {e}");
    let table = cfg.experiment_table();
    let subject = cfg.subject();
    let sea = SeaModel::new(
        plant.sea.dynamics.natural_frequency_hz,
        plant.sea.dynamics.damping_ratio,
    )
    .map_err(|e| science("sea.dynamics", e))?;
    let held: Vec<u32> = match cfg.protocol.mode {
        ProtocolMode::Identification => cfg.protocol.experiments.clone(),
        ProtocolMode::Voluntary => cfg.voluntary.map(|v| v.experiment).into_iter().collect(),
        ProtocolMode::Release => cfg.release.map(|r| r.experiment).into_iter().collect(),
    };
    let c = &cfg.controller;
    let [k_lo, k_hi] = c.k_range_nm_per_rad;
    let range =
        StiffnessRange::new(k_lo, k_hi).map_err(|e| science("controller.k_range_nm_per_rad", e))?;
    // The subject's loss factor at any stiffness, for the design range.
    let ks: Vec<f64> = subject
        .experiment
        .iter()
        .map(|x| x.stiffness_nm_per_rad)
        .collect();
    let hs: Vec<f64> = subject
        .experiment
        .iter()
        .map(|x| x.hysteretic_damping_nm_per_rad)
        .collect();
    let law = fit_power_law(&ks, &hs).ok().map(|fit| fit.law);
    // (margin, where, which key sets the gain)
    let mut found: Vec<(f64, String, String)> = Vec::new();
    let mut seen = Vec::new();
    for n in held {
        if seen.contains(&n) {
            continue;
        }
        seen.push(n);
        let (Some(spec), Some(e)) = (table.get(n), subject.get(n)) else {
            continue;
        };
        let m_e = cfg.exo_inertia_kg_m2(spec.load_kg);
        let m_h = subject.inertia_kg_m2;
        let at = AmplificationPlant::new(
            m_e,
            m_h,
            e.stiffness_nm_per_rad,
            e.hysteretic_damping_nm_per_rad / e.stiffness_nm_per_rad,
            sea,
        )
        .map_err(|e| science("subject_file", e))?;
        let holds = format!(
            "the stiffness subject {} holds in experiment {n} (K = {} Nm/rad, H = {} Nm/rad)",
            subject.name, e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad
        );
        match c.f {
            Some(f) => {
                let kp = match c.kp {
                    Some(kp) => kp,
                    None => proportional_gain(m_e, m_h).map_err(|e| science("controller.kp", e))?,
                };
                let layout = FractionalLayout {
                    kp,
                    omega_gc_hat_rad_s: nominal_crossover(range, m_e, m_h)
                        .map_err(|e| science("controller.k_range_nm_per_rad", e))?,
                    filters: c.filters,
                    p1_rad_s: c.p1_rad_s,
                    r_pp: c.r_pp,
                };
                // The controller discretises this filter at start: refuse
                // here what it would refuse there.
                layout
                    .loop_at(f, at)
                    .and_then(|l| l.filter.discretize(cfg.run.rate_hz))
                    .map_err(|e| science("controller.p1_rad_s", e))?;
                let key = if c.kp.is_some() {
                    format!(
                        "{}: controller.f: f = {f} with controller.kp = {kp}",
                        config.display()
                    )
                } else {
                    format!(
                        "{}: controller.f: f = {f} with k_p = {kp:.3} (eq. kp)",
                        config.display()
                    )
                };
                let m = layout
                    .min_phase_margin_deg(f, &[at])
                    .map_err(|e| science("controller.f", e))?;
                found.push((m, holds, key.clone()));
                for k in [k_lo, k_hi] {
                    let loss = match law {
                        Some(l) => l.loss_factor(k).ok(),
                        None => Some(e.hysteretic_damping_nm_per_rad / e.stiffness_nm_per_rad),
                    };
                    let Some(loss) = loss.filter(|l| l.is_finite() && *l >= 0.0) else {
                        continue;
                    };
                    let Ok(bound) = AmplificationPlant::new(m_e, m_h, k, loss, sea) else {
                        continue;
                    };
                    let mb = layout
                        .min_phase_margin_deg(f, &[bound])
                        .map_err(|e| science("controller.f", e))?;
                    found.push((
                        mb,
                        format!(
                            "K = {k} Nm/rad, a bound of controller.k_range_nm_per_rad (loss factor {loss:.3} from subject {}'s power law, load {} kg)",
                            subject.name, spec.load_kg
                        ),
                        key.clone(),
                    ));
                }
            }
            None if cfg.protocol.mode == ProtocolMode::Identification && spec.alpha > 1.0 => {
                // Constant α: the loop is (α − 1) P(s), the filter flat (f = 0).
                let layout = FractionalLayout {
                    kp: spec.alpha - 1.0,
                    omega_gc_hat_rad_s: 1.0,
                    filters: 1,
                    p1_rad_s: 1.0,
                    r_pp: 10.0,
                };
                let m = layout
                    .min_phase_margin_deg(0.0, &[at])
                    .map_err(|e| science("experiment alpha", e))?;
                let idx = table.index_of(n).unwrap_or(0);
                found.push((
                    m,
                    holds,
                    format!(
                        "{}: experiment[{idx}].alpha: constant α = {}",
                        cfg.protocol.experiments_file.display(),
                        spec.alpha
                    ),
                ));
            }
            None => {}
        }
    }
    let mut errors = Vec::new();
    let mut warnings = Vec::new();
    for (m, at, key) in &found {
        if *m < REFUSE_BELOW_MARGIN_DEG {
            errors.push(format!(
                "{key} leaves the amplification loop a phase margin of {m:.1}° at {at}, below {REFUSE_BELOW_MARGIN_DEG}°: it would oscillate; lower the gain"
            ));
        } else if *m < 0.0 {
            warnings.push(format!(
                "{key} leaves the model loop a phase margin of {m:.1}° at {at} (refused below {REFUSE_BELOW_MARGIN_DEG}°; the model is conservative, but watch for oscillation)"
            ));
        }
    }
    let worst = found.iter().map(|(m, ..)| *m).fold(f64::INFINITY, f64::min);
    let summary = match (c.f, found.is_empty()) {
        (Some(f), false) => format!(
            "α(s) = k_p F(s) + 1, f = {f}: smallest phase margin {worst:.1}° (at the subject's stiffness and the bounds of controller.k_range_nm_per_rad)"
        ),
        (None, false) => format!(
            "constant α per experiment: smallest phase margin {worst:.1}° at the subject's stiffness"
        ),
        (Some(f), true) => format!("α(s) = k_p F(s) + 1, f = {f}"),
        (None, true) => "constant α per experiment, no amplification loop (α ≤ 1)".into(),
    };
    Ok(Margins {
        summary,
        errors,
        warnings,
    })
}
