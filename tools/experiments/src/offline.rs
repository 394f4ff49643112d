//! `exo fit`'s pipeline as a library: contract recordings (whoever wrote
//! them), another rig's CSVs ([`exo_analysis::import`]) and the trials of a
//! study file ([`exo_analysis::trials`]) read, their samples, commands and
//! protocol states run through this crate's [`Identifier`] in time order
//! (the same code that runs online), grouped by subject, and analysed by
//! [`exo_analysis::study`] into the paper's tables. `exo fit`, `exo report`,
//! `exo run`, `exo sim` and `exo reproduce` call [`fit`].
//!
//! Errors name the file, the metadata key or the option (`--level`, …) as
//! `exo fit` reports them.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use exo_analysis::study::{analyse, AnalysisSettings, ExperimentData, FitReport, SubjectData};
use exo_analysis::trials::{self, TrialSpec};
use exo_analysis::{effective_alpha, FitSource, Played};
use exo_impedance::{exo_inertia_kg_m2, DampingSign, Joint};
use exo_messages::{ActuatorCommand, FrfPoint, ProtocolState, SensorSample};
use exo_recording::{read_recording_topics, Recordable, Recording};

use exo_identifier::{Event, Identifier, IdentifierSettings};

use crate::error::{Error, Result};

/// What to fit and how: `exo fit`'s options (the command line's names in
/// brackets).
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Contract recordings or CSV files (CSVs are experiments 1, 2, … of one
    /// subject `imported`, in the order given).
    pub recordings: Vec<PathBuf>,
    /// A study file whose CSV trials are fitted too (`--study`).
    pub study: Option<PathBuf>,
    /// False-rejection probability of the F-tests, in (0, 1) (`--level`).
    pub level: f64,
    /// Guaranteed phase margin (degrees) for eq. f, in (0, 90)
    /// (`--phase-margin-deg`).
    pub phase_margin_deg: f64,
    /// Stiffness range (Nm/rad) for eq. f as `[MIN, MAX]`; `None`: each
    /// subject's fitted range (`--k-range`).
    pub k_range: Option<[f64; 2]>,
    /// Use the FRF points the online identifier recorded (`--recorded-frf`).
    pub recorded_frf: bool,
    /// Exoskeleton inertia without load (kg·m²) when a recording does not
    /// say (`--arm-inertia-kg-m2`).
    pub arm_inertia_kg_m2: f64,
    /// Load lever arm (m) when a recording does not say (`--load-lever-arm-m`).
    pub load_lever_arm_m: f64,
    /// Which measured FRF the parameters come from (`--fit-source`).
    pub fit_source: FitSource,
    /// Fit with B ≥ 0 and H ≥ 0 (`--nonneg-damping`).
    pub nonneg_damping: bool,
    /// Ordinary least squares instead of noise weighting (`--unweighted`).
    pub unweighted: bool,
    /// The joint; `None`: the recordings' `joint` metadata, else unspecified.
    pub joint: Option<Joint>,
}

impl FitOptions {
    /// `exo fit`'s defaults for `recordings`, as `exo run` and
    /// `exo reproduce` fit their own recordings.
    pub fn for_recordings(recordings: Vec<PathBuf>) -> Self {
        FitOptions {
            recordings,
            study: None,
            level: 0.05,
            phase_margin_deg: 10.8,
            k_range: None,
            recorded_frf: false,
            arm_inertia_kg_m2: 0.1,
            load_lever_arm_m: 0.45,
            fit_source: FitSource::CuffTorque,
            nonneg_damping: false,
            unweighted: false,
            joint: None,
        }
    }
}

/// What the fitter gets out of one recording.
pub struct Loaded {
    /// The recording.
    pub recording: Recording,
    /// Subject name.
    pub subject: String,
    /// FRF points by experiment.
    pub points: BTreeMap<u32, Vec<FrfPoint>>,
    /// α and load per experiment (from the protocol states).
    pub settings: BTreeMap<u32, (f64, f64)>,
    /// `M_e` without load and the load lever arm used.
    pub rig: (f64, f64),
    /// The recording asks for a fit of `S_h` (no actuator torque).
    pub human_only: bool,
    /// The lab's name for the condition (metadata `condition`).
    pub condition: Option<String>,
    /// The joint the recording says it is of (metadata `joint`).
    pub joint: Option<Joint>,
}

fn meta_f64(r: &Recording, key: &str, default: f64) -> Result<f64> {
    match r.meta(key) {
        None => Ok(default),
        Some(v) => {
            let x: f64 = v.trim().parse().map_err(|source| Error::MetadataNumber {
                recording: r.source.clone(),
                key: key.to_string(),
                value: v.to_string(),
                source,
            })?;
            if !x.is_finite() {
                return Err(Error::Metadata {
                    recording: r.source.clone(),
                    key: key.to_string(),
                    detail: format!("{v} is not finite"),
                });
            }
            Ok(x)
        }
    }
}

/// Runs a recording's streams through the identifier, in time order;
/// broadband windows line by line at `periodic_lines` (period samples,
/// bins) when the recording names a periodic multisine.
pub fn identify(
    r: &Recording,
    periodic_lines: Option<(usize, Vec<usize>)>,
    s: IdentifierSettings,
) -> (BTreeMap<u32, Vec<FrfPoint>>, Vec<String>) {
    let mut warnings = Vec::new();
    let mut id = Identifier::new(s);
    if let Some((period_samples, bins)) = periodic_lines {
        // A window longer than the ring keeps its last part, which still
        // holds whole periods (any period's worth of samples is one).
        match Identifier::new(s).with_periodic_lines(period_samples, bins) {
            Ok(periodic) => id = periodic,
            Err(e) => warnings.push(format!(
                "{}: {e}; broadband windows by Welch's method",
                r.source
            )),
        }
    }
    let mut events = Vec::new();
    let mut merge = exo_analysis::Merge::new(&r.protocol, &r.command);
    for smp in &r.sensor {
        let _ = merge.up_to(smp.stamp_ns, |x| -> Result<(), std::convert::Infallible> {
            match x {
                Played::Protocol(p) => id.on_protocol(p, &mut events),
                Played::Command(c) => id.on_command(c),
            }
            Ok(())
        });
        id.on_sample(smp, &mut events);
    }
    for p in merge.remaining_protocol() {
        id.on_protocol(p, &mut events);
    }
    id.flush(&mut events);
    for e in events {
        // The online refits' notes (models not fitted yet, no power law yet)
        // say nothing here: the analysis fits every experiment itself.
        if let Event::Warning(w) = e {
            warnings.push(format!("{}: {w}", r.source));
        }
    }
    (id.points().clone(), warnings)
}

/// Reads and identifies one recording.
pub fn load(path: &Path, a: &FitOptions) -> Result<Loaded> {
    // Fitting and reporting use these four; decoding the bus topics and the
    // estimates too would double the memory and time spent per file.
    let recording = read_recording_topics(
        path,
        &[
            SensorSample::TOPIC,
            ActuatorCommand::TOPIC,
            ProtocolState::TOPIC,
            FrfPoint::TOPIC,
        ],
    )?;
    identify_recording(recording, path, a)
}

/// Whether `path` names a CSV file (by its extension).
pub fn is_csv(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
}

/// Every input of `exo fit`: recordings as they are, CSVs imported in
/// memory (numbered as experiments 1, 2, … in the order given), and the
/// trials of `--study`. Progress (which file, a segment read with its run)
/// goes to `note`, one line each (`exo fit` prints it on stderr).
pub fn load_inputs(a: &FitOptions, note: &mut dyn FnMut(String)) -> Result<Vec<Loaded>> {
    // A later segment of a recording also given is read with it.
    let given: Vec<PathBuf> = a
        .recordings
        .iter()
        .filter(|p| {
            let first = exo_recording::segments::first_segment_of(p);
            let with_its_first = first.is_some_and(|f| a.recordings.contains(&f));
            if with_its_first {
                note(format!(
                    "exo fit: {} is read as a segment of its run",
                    p.display()
                ));
            }
            !with_its_first
        })
        .cloned()
        .collect();
    let csvs: Vec<PathBuf> = given.iter().filter(|p| is_csv(p)).cloned().collect();
    let mut trials = trials::default_trials(&csvs).into_iter();
    let mut inputs: Vec<(PathBuf, Option<TrialSpec>)> = given
        .iter()
        .map(|p| (p.clone(), if is_csv(p) { trials.next() } else { None }))
        .collect();
    if let Some(study) = &a.study {
        inputs.extend(
            trials::load_study(study)?
                .into_iter()
                .map(|(p, t)| (p, Some(t))),
        );
    }
    let total = inputs.len();
    // Each input is read and identified on its own: one per core, the
    // notes and the results in the inputs' order.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<std::sync::Mutex<Option<Result<Loaded>>>> =
        inputs.iter().map(|_| std::sync::Mutex::new(None)).collect();
    let workers = std::thread::available_parallelism()
        .map_or(1, std::num::NonZeroUsize::get)
        .clamp(1, total.max(1));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some((p, trial)) = inputs.get(i) else {
                    break;
                };
                let r = match trial {
                    Some(t) => exo_analysis::import::recording_from_csv(p, t)
                        .map_err(Error::from)
                        .and_then(|rec| identify_recording(rec, p, a)),
                    None => load(p, a),
                };
                *results[i]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(r);
            });
        }
    });
    let mut loaded = Vec::with_capacity(total);
    for (i, ((p, _), r)) in inputs.iter().zip(results).enumerate() {
        if total > 1 {
            note(format!("exo fit: [{}/{}] {}", i + 1, total, p.display()));
        }
        let r = r
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .unwrap_or_else(|| Err(Error::NotRead { path: p.clone() }));
        loaded.push(r?);
    }
    Ok(loaded)
}

/// Identifies a recording already read (or imported).
pub fn identify_recording(recording: Recording, path: &Path, a: &FitOptions) -> Result<Loaded> {
    let r = &recording;
    let subject = r.meta("subject").map(str::to_string).unwrap_or_else(|| {
        path.file_stem()
            .map_or("unknown".into(), |s| s.to_string_lossy().into_owned())
    });
    let arm = meta_f64(r, "arm_inertia_kg_m2", a.arm_inertia_kg_m2)?;
    let lever = meta_f64(r, "load_lever_arm_m", a.load_lever_arm_m)?;
    let rate = meta_f64(r, "rate_hz", 0.0)?;
    let rate = if rate > 0.0 {
        rate
    } else {
        // Estimate from the sample stamps.
        let n = r.sensor.len();
        if n > 1 {
            let span = r.sensor[n - 1]
                .stamp_ns
                .saturating_sub(r.sensor[0].stamp_ns) as f64
                * 1e-9;
            if span > 0.0 {
                (n - 1) as f64 / span
            } else {
                1000.0
            }
        } else {
            1000.0
        }
    };
    let mut extra = Vec::new();
    if r.protocol.is_empty() {
        extra.push(format!(
            "{}: topic exo/protocol is missing or empty: no analysis windows can be found",
            r.source
        ));
    }
    if r.sensor.is_empty() {
        extra.push(format!(
            "{}: topic exo/sensor is missing or empty",
            r.source
        ));
    }
    let human_only = r.meta("fit_target") == Some("human");
    let source = a.fit_source;
    if human_only && source == FitSource::ActuatorTorque {
        extra.push(format!(
            "{}: no actuator torque in this record (fit_target = human): fitted from the cuff's S_h, not --fit-source actuator",
            r.source
        ));
    } else if r.command.is_empty() && !r.sensor.is_empty() && source == FitSource::ActuatorTorque {
        extra.push(format!(
            "{}: topic exo/command is missing: the actuator side keeps τ_s's gravity part",
            r.source
        ));
    }
    let joint = match r.meta("joint") {
        None => None,
        Some(j) => Some(Joint::parse(j).ok_or_else(|| Error::Metadata {
            recording: r.source.clone(),
            key: "joint".into(),
            detail: format!("{j:?}: expected elbow, ankle, knee, wrist or unspecified"),
        })?),
    };
    let (points, mut warnings) = if a.recorded_frf || r.sensor.is_empty() {
        if !r.frf.is_empty() && !a.recorded_frf {
            extra.push(format!(
                "{}: no samples; using the {} FRF points the online identifier recorded",
                r.source,
                r.frf.len()
            ));
        }
        let mut m: BTreeMap<u32, Vec<FrfPoint>> = BTreeMap::new();
        for p in &r.frf {
            m.entry(p.experiment).or_default().push(*p);
        }
        (m, Vec::new())
    } else {
        // A multisine run is estimated line by line, as online, at the
        // lines its `exo` metadata names.
        let lines = match exo_recording::excitation::MultisineLines::read_from(|k| r.meta(k)) {
            Ok(l) => l,
            Err(e) => {
                extra.push(format!(
                    "{}: {e}; broadband windows by Welch's method",
                    r.source
                ));
                None
            }
        };
        identify(
            r,
            lines.map(|l| (l.period_samples, l.bins)),
            IdentifierSettings {
                rate_hz: rate,
                arm_inertia_kg_m2: arm,
                load_lever_arm_m: lever,
                max_window_s: 120.0,
                fit_source: source,
                ..IdentifierSettings::default()
            },
        )
    };
    warnings.extend(extra);
    let mut settings = BTreeMap::new();
    for p in &r.protocol {
        if p.experiment > 0 {
            settings.entry(p.experiment).or_insert((p.alpha, p.load_kg));
        }
    }
    // α and load not known: say once per recording which values were assumed.
    let told = |key: &str| r.meta(key) == Some("true");
    let alpha_unknown: Vec<u32> = settings
        .iter()
        .filter(|(n, (alpha, _))| {
            points.contains_key(*n) && (told("alpha_assumed") || effective_alpha(*alpha) != *alpha)
        })
        .map(|(n, _)| *n)
        .collect();
    if !alpha_unknown.is_empty() {
        warnings.push(format!(
            "{}: α of experiment(s) {alpha_unknown:?} not known; assumed 1 (no amplification): only the re-created S_h-e/α depends on it, not the fitted parameters",
            r.source
        ));
    }
    if told("load_assumed") && !points.is_empty() {
        let load = settings.values().next().map_or(0.0, |s| s.1);
        warnings.push(format!(
            "{}: the exoskeleton's load was not known; assumed {load} kg (M_e = {} kg·m²){}",
            r.source,
            exo_inertia_kg_m2(arm, load, lever),
            if source == FitSource::ActuatorTorque {
                ": the actuator-side fit removes this M_e, so M_h carries any error in it"
            } else {
                ": only the re-created S_h-e/α depends on it, not the fitted parameters"
            }
        ));
    }
    let condition = r.meta("condition").map(str::to_string);
    let mut loaded = Loaded {
        recording,
        subject,
        points,
        settings,
        rig: (arm, lever),
        human_only,
        condition,
        joint,
    };
    loaded.recording.warnings.extend(warnings);
    Ok(loaded)
}

/// Groups loaded recordings by subject for the analysis.
pub fn subject_data(loaded: &[Loaded]) -> Vec<SubjectData> {
    let mut by: BTreeMap<String, SubjectData> = BTreeMap::new();
    for l in loaded {
        let sd = by.entry(l.subject.clone()).or_insert_with(|| SubjectData {
            subject: l.subject.clone(),
            experiments: BTreeMap::new(),
        });
        for (n, pts) in &l.points {
            let (alpha, load) = l.settings.get(n).copied().unwrap_or((1.0, 0.0));
            let e = sd.experiments.entry(*n).or_insert_with(|| ExperimentData {
                experiment: *n,
                alpha: effective_alpha(alpha),
                load_kg: load,
                m_e_kg_m2: exo_inertia_kg_m2(l.rig.0, load, l.rig.1),
                points: Vec::new(),
                human_only: l.human_only,
                condition: l.condition.clone(),
            });
            e.points.extend(pts.iter().copied());
        }
    }
    by.into_values().collect()
}

/// Loads every recording and analyses them together.
/// Progress goes to `note` (see [`load_inputs`]).
pub fn fit(a: &FitOptions, note: &mut dyn FnMut(String)) -> Result<(Vec<Loaded>, FitReport)> {
    if !(a.level > 0.0 && a.level < 1.0) {
        return Err(Error::Option {
            option: "--level",
            detail: format!("{}: must lie in (0, 1)", a.level),
        });
    }
    if !(a.phase_margin_deg > 0.0 && a.phase_margin_deg < 90.0) {
        return Err(Error::Option {
            option: "--phase-margin-deg",
            detail: format!("{}: must lie in (0, 90)", a.phase_margin_deg),
        });
    }
    if let Some(k) = &a.k_range {
        if !(k[0] > 0.0 && k[1] > k[0] && k[1].is_finite()) {
            return Err(Error::Option {
                option: "--k-range",
                detail: format!("{},{}: needs 0 < MIN < MAX", k[0], k[1]),
            });
        }
    }
    let loaded = load_inputs(a, note)?;
    let data = subject_data(&loaded);
    let mut warnings: Vec<String> = loaded
        .iter()
        .flat_map(|l| l.recording.warnings.iter().cloned())
        .collect();
    if data.iter().all(|s| s.experiments.is_empty()) {
        return Err(Error::NoFrfPoint {
            recordings: a.recordings.clone(),
            warnings,
        });
    }
    // The joint: the command line's, else the recordings' (all alike), else unspecified.
    let joints: std::collections::BTreeSet<&'static str> = loaded
        .iter()
        .filter_map(|l| l.joint.map(Joint::name))
        .collect();
    let joint = match (a.joint, joints.len()) {
        (Some(j), _) => j,
        (None, 1) => loaded.iter().find_map(|l| l.joint).unwrap_or_default(),
        (None, 0) => Joint::Unspecified,
        (None, _) => return Err(Error::MixedJoints { joints }),
    };
    let settings = AnalysisSettings {
        level: a.level,
        phase_margin_deg: a.phase_margin_deg,
        k_range_nm_per_rad: a.k_range,
        fit_source: a.fit_source,
        damping: if a.nonneg_damping {
            DampingSign::NonNegative
        } else {
            DampingSign::Free
        },
        joint,
        weighted: !a.unweighted,
        ..AnalysisSettings::default()
    };
    let mut report = analyse(&data, &settings)?;
    warnings.append(&mut report.warnings);
    report.warnings = warnings;
    Ok((loaded, report))
}
