//! How much faster than real time the run's nodes step in one process
//! (issue 20), per job, beside the baseline measured in the same run: the
//! same configuration through the five processes in lockstep (`exo run`).
//!
//! ```text
//! cargo build --release --workspace --bins
//! cargo bench -p exo-sim --bench sim_speed [-- REPEATS]
//! ```
//!
//! Jobs: a tuning trial of `exo tune` (spring release, no identifier, no
//! recording), the default run with the identifier and a sink that only
//! counts, the default run recorded to MCAP (what `exo sim` does), one
//! subject of `exo reproduce` (nine experiments) with its prony_matched
//! plant and with the default plant, one case of `exo diagnose-bench`, and
//! the reproduction recorded. Each is repeated (default 5); the ratio
//! simulated time / CPU time of the simulating thread (one core; robust to
//! other load on a shared machine) is reported as percentiles of a
//! histogram, beside the median ratio to wall time.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use exo_config::{ProtocolMode, ReleaseSettings, RunConfig};
use exo_plant_sim::PlantModel;
use exo_sim::{FileSink, Sim};
use hdrhistogram::Histogram;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Writes `cfg` to `dir/name.toml` and loads it back, as the tools do.
fn materialise(cfg: &RunConfig, dir: &Path, name: &str) -> (RunConfig, PathBuf) {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, toml::to_string(cfg).unwrap()).unwrap();
    (RunConfig::from_file(&path).unwrap(), path)
}

fn absolute(cfg: &mut RunConfig, dir: &Path) {
    cfg.subject_file = std::path::absolute(&cfg.subject_file).unwrap();
    cfg.plant_model = std::path::absolute(&cfg.plant_model).unwrap();
    cfg.protocol.experiments_file = std::path::absolute(&cfg.protocol.experiments_file).unwrap();
    cfg.run.output_dir = dir.to_path_buf();
}

enum Sink {
    Count,
    File,
}

/// CPU time of the calling thread (s): what one core spent on the run,
/// whatever else the machine was doing.
fn thread_cpu_s() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: a valid timespec for the call to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// One in-process run: (simulated s, wall s, CPU s of this thread).
fn once(
    cfg: &RunConfig,
    file: &Path,
    model: &PlantModel,
    sink: &Sink,
    out: &Path,
) -> (f64, f64, f64) {
    let started = Instant::now();
    let cpu0 = thread_cpu_s();
    let mut sim = Sim::new(cfg, model).unwrap();
    match sink {
        Sink::Count => {
            let mut n = 0u64;
            sim.run(|_| -> Result<(), ()> {
                n += 1;
                Ok(())
            })
            .unwrap();
            std::hint::black_box(n);
        }
        Sink::File => {
            let mut f = FileSink::create(out, cfg, file).unwrap();
            sim.run(|r| f.write(r)).unwrap();
            f.finish().unwrap();
        }
    }
    let wall = started.elapsed().as_secs_f64();
    let cpu = thread_cpu_s() - cpu0;
    let sim_s = sim.plant().tick() as f64 * sim.plant().period_ns() as f64 * 1e-9;
    (sim_s, wall, cpu)
}

/// Runs one job `repeats` times and prints its row; returns the simulated s.
fn report(name: &str, cfg: &RunConfig, file: &Path, sink: Sink, repeats: usize, dir: &Path) -> f64 {
    let model = PlantModel::from_file(&cfg.plant_model).unwrap();
    let mut h = Histogram::<u64>::new(3).unwrap();
    let mut h_wall = Histogram::<u64>::new(3).unwrap();
    let mut sim_s = 0.0;
    for i in 0..repeats {
        let (s, wall, cpu) = once(
            cfg,
            file,
            &model,
            &sink,
            &dir.join(format!("{name}-{i}.mcap")),
        );
        sim_s = s;
        h.record((s / cpu.max(1e-9)).round() as u64).unwrap();
        h_wall.record((s / wall).round() as u64).unwrap();
    }
    println!(
        "| {name} | {sim_s:.1} | {repeats} | {}× | {}× | {}× | {}× |",
        h.value_at_quantile(0.0),
        h.value_at_quantile(0.5),
        h.max(),
        h_wall.value_at_quantile(0.5)
    );
    sim_s
}

fn main() {
    let repeats: usize = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .map_or(5, |a| a.parse().expect("REPEATS is a whole number"));
    let dir = std::env::temp_dir().join(format!("exo-sim-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let configs = root().join("configs");
    let default = RunConfig::from_file(&configs.join("default.toml")).unwrap();
    let reproduce = RunConfig::from_file(&configs.join("reproduce.toml")).unwrap();

    println!("| job (in one process) | simulated s | runs | per CPU s: min | median | max | per wall s: median |");
    println!("|---|---|---|---|---|---|---|");
    // exo tune's trial: the default plant, spring release at experiment 7.
    let mut tune = default.clone();
    absolute(&mut tune, &dir);
    tune.services.identifier = false;
    tune.services.recorder = false;
    tune.protocol.mode = ProtocolMode::Release;
    tune.protocol.experiments = vec![7];
    tune.protocol.periods = None;
    tune.release = Some(ReleaseSettings {
        experiment: 7,
        spring_torque_nm: 3.0,
        hold_s: 2.0,
        observe_s: 4.0,
    });
    tune.controller.f = Some(0.5);
    let (tune, tune_file) = materialise(&tune, &dir, "tune");
    report(
        "exo tune trial",
        &tune,
        &tune_file,
        Sink::Count,
        repeats,
        &dir,
    );

    let mut run = default.clone();
    absolute(&mut run, &dir);
    let (run, run_file) = materialise(&run, &dir, "default");
    let run_sim_s = report(
        "default run, identifier, no file",
        &run,
        &run_file,
        Sink::Count,
        repeats,
        &dir,
    );
    report(
        "default run recorded (exo sim)",
        &run,
        &run_file,
        Sink::File,
        repeats,
        &dir,
    );

    let mut repro = reproduce.clone();
    absolute(&mut repro, &dir);
    repro.subject_file = configs.join("subjects/A.toml");
    let (repro, repro_file) = materialise(&repro, &dir, "reproduce-A");
    report(
        "exo reproduce, one subject, no file",
        &repro,
        &repro_file,
        Sink::Count,
        repeats,
        &dir,
    );
    // The same subject and protocol with the default plant (equivalent
    // viscous hysteresis instead of reproduce's prony_matched bank): the
    // issue's "default plant".
    let mut repro_default = repro.clone();
    repro_default.plant_model = configs.join("plants/default.toml");
    let (repro_default, repro_default_file) =
        materialise(&repro_default, &dir, "reproduce-A-default-plant");
    report(
        "exo reproduce, one subject, default plant, no file",
        &repro_default,
        &repro_default_file,
        Sink::Count,
        repeats,
        &dir,
    );
    // exo diagnose-bench's re-simulation of one case (its configuration,
    // the default plant as the case's truth).
    let mut bench = RunConfig::from_file(&configs.join("diagnose-bench.toml")).unwrap();
    absolute(&mut bench, &dir);
    let (bench, bench_file) = materialise(&bench, &dir, "diagnose-bench");
    report(
        "exo diagnose-bench, one case, no file",
        &bench,
        &bench_file,
        Sink::Count,
        repeats,
        &dir,
    );
    report(
        "exo reproduce, one subject, recorded",
        &repro,
        &repro_file,
        Sink::File,
        repeats,
        &dir,
    );

    // Baseline: the default run through the five processes in lockstep.
    // The build's own target directory (`CARGO_TARGET_DIR`, else the
    // workspace's `target/`).
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| root().join("target"), PathBuf::from);
    let exo = target.join("release/exo");
    if exo.exists() {
        let started = Instant::now();
        let out = Command::new(&exo)
            .args(["run", run_file.to_str().unwrap(), "--no-report"])
            .env("RUST_LOG", "warn")
            .output()
            .unwrap();
        let wall = started.elapsed().as_secs_f64();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let sim_s = run_sim_s;
        println!(
            "\nbaseline: the default run through the five processes (exo run, lockstep): {sim_s:.1} s simulated in {wall:.1} s wall ({:.0}× real time)",
            sim_s / wall
        );
    } else {
        println!(
            "\nbaseline skipped: build {} first (cargo build --release)",
            exo.display()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
