//! The check of a run before any process starts (`exo run`, `exo run
//! --check`, `exo sim`): every file a run file names, and the checks across
//! them, each error naming its file and key.

use std::path::{Path, PathBuf};

use exo_analysis::preflight::controller_margins;
use exo_config::RunConfig;

use crate::error::{Error, Result};

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

/// [`check_run`], with every error in one [`Error::Refused`] (one per line).
pub fn check_or_fail(config: &Path) -> Result<Checked> {
    check_run(config).map_err(|errors| Error::Refused {
        config: config.to_path_buf(),
        errors,
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
/// [`exo_analysis::preflight::REFUSE_BELOW_MARGIN_DEG`], warned below 0°; see
/// [`exo_analysis::preflight`]). Returns every error
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
        .and_then(|p| match exo_plant_model::PlantModel::from_file(p) {
            Ok(m) => Some(m),
            Err(exo_plant_model::PlantModelError::Several(v)) => {
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
    plant: &exo_plant_model::PlantModel,
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
    match controller_margins(
        config,
        cfg,
        plant.sea.dynamics.natural_frequency_hz,
        plant.sea.dynamics.damping_ratio,
    ) {
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
