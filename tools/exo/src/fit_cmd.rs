//! `exo fit RECORDING.mcap …`: the paper's post-hoc analysis of contract
//! recordings, whoever wrote them. Each recording's samples, commands and
//! protocol states go through the identifier's own code (the same that runs
//! online), then [`exo_analysis::study`] makes the paper's tables.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use exo_analysis::{effective_alpha, FitSource, Played};
use exo_identifier::{Event, Identifier, IdentifierSettings};
use exo_impedance::{exo_inertia_kg_m2, DampingSign, Joint};
use exo_messages::{ActuatorCommand, FrfPoint, ProtocolState, SensorSample};
use exo_recording::{read_recording_topics, Recordable, Recording};

use exo_analysis::study::{analyse, AnalysisSettings, ExperimentData, FitReport, SubjectData};

/// Arguments of `exo fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Contract recordings (docs/recording-format.md), or another rig's CSV
    /// files (as `exo import` reads them): CSVs are taken as experiments 1,
    /// 2, 3… of one subject `imported`, in the order given, each labelled
    /// with its file name (use `--study` to say more).
    #[arg(required_unless_present = "study")]
    pub recordings: Vec<PathBuf>,
    /// A study file (see `exo import --study`): its CSV trials, each with
    /// its subject, experiment, condition, α and load, are fitted together.
    #[arg(long, value_name = "STUDY.toml")]
    pub study: Option<PathBuf>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Also write the tables as CSV files into this directory.
    #[arg(long, value_name = "DIR")]
    pub csv: Option<PathBuf>,
    /// False-rejection probability of the F-tests.
    #[arg(long, default_value_t = 0.05)]
    pub level: f64,
    /// Guaranteed phase margin (degrees) for the recommended f (eq. f).
    #[arg(long, default_value_t = 10.8)]
    pub phase_margin_deg: f64,
    /// Stiffness range (Nm/rad) for eq. f, as MIN,MAX (default: each subject's fitted range).
    #[arg(long, value_name = "MIN,MAX", value_delimiter = ',', num_args = 2)]
    pub k_range: Option<Vec<f64>>,
    /// Use the FRF points the online identifier recorded instead of recomputing them.
    #[arg(long)]
    pub recorded_frf: bool,
    /// Exoskeleton inertia without load (kg·m²) when a recording does not say.
    #[arg(long, default_value_t = 0.1)]
    pub arm_inertia_kg_m2: f64,
    /// Load lever arm (m) when a recording does not say.
    #[arg(long, default_value_t = 0.45)]
    pub load_lever_arm_m: f64,
    /// Which measured FRF the parameters are estimated from: `cuff`
    /// (S_h = τ_c/θ_e, the paper's way) or `actuator` ((τ_s − τ_gravity)/θ_e
    /// = S_h + M_e s², the whole M_e removed).
    #[arg(long, value_enum, default_value_t = FitSourceArg::Cuff)]
    pub fit_source: FitSourceArg,
    /// Fit with B ≥ 0 and H ≥ 0 (a passive joint) instead of unconstrained.
    #[arg(long)]
    pub nonneg_damping: bool,
    /// Ordinary least squares, as the paper fitted, instead of weighting
    /// each point by its measured noise.
    #[arg(long)]
    pub unweighted: bool,
    /// The joint (elbow, ankle, knee, wrist), for the plausible human
    /// inertia; default: the recording's `joint` metadata, else unspecified.
    #[arg(long, value_parser = parse_joint)]
    pub joint: Option<Joint>,
}

/// `--fit-source` on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum FitSourceArg {
    /// `S_h = τ_c/θ_e` from the cuff (the paper's estimate).
    Cuff,
    /// `(τ_s − τ_gravity)/θ_e` from the SEA torque, the whole `M_e` removed.
    Actuator,
}

impl From<FitSourceArg> for FitSource {
    fn from(a: FitSourceArg) -> Self {
        match a {
            FitSourceArg::Cuff => FitSource::CuffTorque,
            FitSourceArg::Actuator => FitSource::ActuatorTorque,
        }
    }
}

fn parse_joint(s: &str) -> Result<Joint, String> {
    Joint::parse(s)
        .ok_or_else(|| format!("`{s}`: expected elbow, ankle, knee, wrist or unspecified"))
}

impl FitArgs {
    /// The command-line defaults for `recordings`, as `exo run` and
    /// `exo reproduce` fit their own recordings.
    pub fn for_recordings(recordings: Vec<PathBuf>) -> Self {
        FitArgs {
            recordings,
            study: None,
            json: false,
            csv: None,
            level: 0.05,
            phase_margin_deg: 10.8,
            k_range: None,
            recorded_frf: false,
            arm_inertia_kg_m2: 0.1,
            load_lever_arm_m: 0.45,
            fit_source: FitSourceArg::Cuff,
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
            let x: f64 = v.trim().parse().with_context(|| {
                format!("{}: metadata exo.{key} = {v:?} is not a number", r.source)
            })?;
            if !x.is_finite() {
                bail!("{}: metadata exo.{key} = {v} is not finite", r.source);
            }
            Ok(x)
        }
    }
}

/// Runs a recording's streams through the identifier, in time order.
pub fn identify(
    r: &Recording,
    s: IdentifierSettings,
) -> (BTreeMap<u32, Vec<FrfPoint>>, Vec<String>) {
    let mut id = Identifier::new(s);
    let mut events = Vec::new();
    let mut warnings = Vec::new();
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
pub fn load(path: &Path, a: &FitArgs) -> Result<Loaded> {
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
/// trials of `--study`.
pub fn load_inputs(a: &FitArgs) -> Result<Vec<Loaded>> {
    // A later segment of a recording also given is read with it.
    let given: Vec<PathBuf> = a
        .recordings
        .iter()
        .filter(|p| {
            let first = exo_recording::segments::first_segment_of(p);
            let with_its_first = first.is_some_and(|f| a.recordings.contains(&f));
            if with_its_first {
                eprintln!("exo fit: {} is read as a segment of its run", p.display());
            }
            !with_its_first
        })
        .cloned()
        .collect();
    let csvs: Vec<PathBuf> = given.iter().filter(|p| is_csv(p)).cloned().collect();
    let mut trials = exo_analysis::trials::default_trials(&csvs).into_iter();
    let mut inputs: Vec<(PathBuf, Option<exo_analysis::trials::TrialSpec>)> = given
        .iter()
        .map(|p| (p.clone(), if is_csv(p) { trials.next() } else { None }))
        .collect();
    if let Some(study) = &a.study {
        inputs.extend(
            exo_analysis::trials::load_study(study)?
                .into_iter()
                .map(|(p, t)| (p, Some(t))),
        );
    }
    let total = inputs.len();
    let mut loaded = Vec::with_capacity(total);
    for (i, (p, trial)) in inputs.iter().enumerate() {
        if total > 1 {
            eprintln!("exo fit: [{}/{}] {}", i + 1, total, p.display());
        }
        loaded.push(match trial {
            Some(t) => identify_recording(exo_analysis::import::recording_from_csv(p, t)?, p, a)?,
            None => load(p, a)?,
        });
    }
    Ok(loaded)
}

/// Identifies a recording already read (or imported).
pub fn identify_recording(recording: Recording, path: &Path, a: &FitArgs) -> Result<Loaded> {
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
    let source = FitSource::from(a.fit_source);
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
        Some(j) => Some(Joint::parse(j).with_context(|| {
            format!(
                "{}: metadata exo.joint = {j:?}: expected elbow, ankle, knee, wrist or unspecified",
                r.source
            )
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
        identify(
            r,
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
pub fn fit(a: &FitArgs) -> Result<(Vec<Loaded>, FitReport)> {
    if !(a.level > 0.0 && a.level < 1.0) {
        bail!("--level = {}: must lie in (0, 1)", a.level);
    }
    if !(a.phase_margin_deg > 0.0 && a.phase_margin_deg < 90.0) {
        bail!(
            "--phase-margin-deg = {}: must lie in (0, 90)",
            a.phase_margin_deg
        );
    }
    if let Some(k) = &a.k_range {
        if !(k[0] > 0.0 && k[1] > k[0] && k[1].is_finite()) {
            bail!("--k-range = {},{}: needs 0 < MIN < MAX", k[0], k[1]);
        }
    }
    let loaded = load_inputs(a)?;
    let data = subject_data(&loaded);
    let mut warnings: Vec<String> = loaded
        .iter()
        .flat_map(|l| l.recording.warnings.iter().cloned())
        .collect();
    if data.iter().all(|s| s.experiments.is_empty()) {
        bail!(
            "no FRF point in {}:\n  {}",
            a.recordings
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", "),
            warnings.join("\n  ")
        );
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
        (None, _) => bail!(
            "the recordings are of different joints ({joints:?}); fit them apart or give --joint"
        ),
    };
    let settings = AnalysisSettings {
        level: a.level,
        phase_margin_deg: a.phase_margin_deg,
        k_range_nm_per_rad: a.k_range.as_ref().map(|k| [k[0], k[1]]),
        fit_source: a.fit_source.into(),
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

/// `value ± half-width` to `digits` decimals, `—` for a term the model lacks.
fn with_ci(value: f64, ci: Option<f64>, digits: usize, present: bool) -> String {
    if !present {
        return "—".into();
    }
    match ci {
        Some(c) => format!("{value:.digits$} ± {c:.digits$}"),
        None => format!("{value:.digits$}"),
    }
}

/// The human-readable tables (intervals are 95 %).
pub fn tables(r: &FitReport) -> String {
    let mut s = String::new();
    for sub in &r.subjects {
        let _ = writeln!(s, "Subject {}", sub.subject);
        for e in &sub.experiments {
            let condition = e
                .condition
                .as_deref()
                .map_or(String::new(), |c| format!(" \"{c}\""));
            let _ = writeln!(
                s,
                "  experiment {}{condition} (α = {}, load {} kg, M_e = {:.4} kg·m²): {} FRF points; parameters from {}",
                e.experiment,
                e.alpha,
                e.load_kg,
                e.m_e_kg_m2,
                e.points.len(),
                match e.fit_source {
                    "actuator" => "(τ_s − τ_gravity)/θ_e − M_e s²",
                    _ => "S_h = τ_c/θ_e",
                }
            );
            let _ = writeln!(
                s,
                "    {:>9} {:>10} {:>10} {:>9} {:>9} {:>8}  {:>12} {:>8}",
                "ω rad/s", "Re S_h", "Im S_h", "∠S_h °", "γ²", "σ/|S_h|", "Re S_h-e/α*", "Im"
            );
            for p in &e.points {
                let _ = writeln!(
                    s,
                    "    {:>9.3} {:>10.3} {:>10.3} {:>9.2} {:>9.4} {:>8.4}  {:>12.3} {:>8.3}",
                    p.omega,
                    p.s_h[0],
                    p.s_h[1],
                    p.s_h_phase_deg,
                    p.coherence,
                    p.noise_rel,
                    p.s_h_e_alpha[0],
                    p.s_h_e_alpha[1]
                );
            }
            let _ = writeln!(
                s,
                "    (* S_h-e/α = S_h − (M_e/α) ω², re-created from S_h as the paper does)"
            );
            let _ = writeln!(
                s,
                "    {:>5} {:>17} {:>17} {:>19} {:>19} {:>7} {:>7}",
                "model", "K Nm/rad", "H Nm/rad", "B Nms/rad", "M_h kg·m²", "R²", "χ²/dof"
            );
            for (name, m) in &e.models {
                let _ = writeln!(
                    s,
                    "    {:>5} {:>17} {:>17} {:>19} {:>19} {:>7.4} {:>7}{}",
                    name,
                    with_ci(m.k, m.ci95.map(|c| c[0]), 2, true),
                    with_ci(m.h, m.ci95.map(|c| c[1]), 2, name != &"M1"),
                    with_ci(m.b, m.ci95.map(|c| c[2]), 4, name != &"M2"),
                    with_ci(m.m, m.ci95.map(|c| c[3]), 4, true),
                    m.r2,
                    m.chi2_per_dof.map_or("—".into(), |c| format!("{c:.2}")),
                    if m.held_at_zero.is_empty() {
                        String::new()
                    } else {
                        format!("  ({} held at 0)", m.held_at_zero.join(", "))
                    }
                );
            }
        }
        match (sub.beta0, sub.beta1, sub.r2) {
            (Some(b0), Some(b1), Some(r2)) => {
                let _ = writeln!(
                    s,
                    "  power law (M2): log10 H = {b0:.3} + {b1:.3} log10 K, R² = {r2:.3}"
                );
            }
            _ => {
                let _ = writeln!(s, "  power law: needs M2 fits of at least two experiments");
            }
        }
        match (sub.recommended_f, &sub.recommended_f_note) {
            (Some(f), _) => {
                let _ = writeln!(s, "  recommended fractional order (eq. f): f = {f:.3}");
            }
            (None, Some(n)) => {
                let _ = writeln!(s, "  recommended fractional order: none ({n})");
            }
            _ => {}
        }
    }
    let _ = writeln!(s, "\nF-tests (eq. ft)");
    let _ = writeln!(
        s,
        "  {:>10} {:>12} {:>12} {:>10} {:>12}",
        "group", "F M1−M3", "F M2−M3", "critical", "df"
    );
    for g in r.f_tests.all_groups() {
        let _ = writeln!(
            s,
            "  {:>10} {:>12.3} {:>12.3} {:>10.3} {:>12}",
            g.group,
            g.m1_m3.statistic,
            g.m2_m3.statistic,
            g.m1_m3.critical,
            format!("({}, {})", g.m1_m3.df[0], g.m1_m3.df[1])
        );
    }
    let _ = writeln!(
        s,
        "\nPhase of S_h (Table II layout; last three frequencies excluded)"
    );
    for p in &r.phase_table {
        let cells: Vec<String> = p
            .groups
            .iter()
            .map(|g| {
                format!(
                    "exp {}: {:.1}° ± {:.1}° (n = {})",
                    g.experiments, g.mean_deg, g.se_deg, g.n
                )
            })
            .collect();
        let cells = if cells.is_empty() {
            "no point: every experiment has three frequencies or fewer, and the highest three are left out".to_string()
        } else {
            cells.join("   ")
        };
        let _ = writeln!(s, "  {:>8}  {cells}", p.subject);
    }
    let _ = writeln!(s, "\nM2 parameters (Table III layout)");
    for sub in &r.subjects {
        let row: Vec<String> = sub
            .experiments
            .iter()
            .filter_map(|e| {
                e.models
                    .get("M2")
                    .map(|m| format!("{}: K {:.2} H {:.2} M_h {:.3}", e.experiment, m.k, m.h, m.m))
            })
            .collect();
        let _ = writeln!(s, "  {:>8}  {}", sub.subject, row.join(" | "));
    }
    if !r.warnings.is_empty() {
        let _ = writeln!(s, "\nNot used:");
        for w in &r.warnings {
            let _ = writeln!(s, "  - {w}");
        }
    }
    s
}

/// A free-text CSV cell, quoted.
fn csv_text(s: Option<&str>) -> String {
    s.map_or(String::new(), |s| format!("\"{}\"", s.replace('"', "\"\"")))
}

fn write_csv(dir: &Path, r: &FitReport) -> Result<()> {
    exo_recording::files::create_output_dir(dir)
        .with_context(|| format!("creating {}", dir.display()))?;
    let mut frf = String::from("subject,experiment,condition,period,omega_rad_s,s_h_re,s_h_im,s_h_e_alpha_re,s_h_e_alpha_im,s_h_e_actuator_re,s_h_e_actuator_im,s_h_phase_deg,coherence,noise_rel\n");
    let mut models = String::from("subject,experiment,condition,model,K,H,B,M,K_ci95,H_ci95,B_ci95,M_ci95,r2,rss,chi2_per_dof\n");
    for s in &r.subjects {
        for e in &s.experiments {
            for p in &e.points {
                let _ = writeln!(
                    frf,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    s.subject,
                    e.experiment,
                    csv_text(e.condition.as_deref()),
                    p.period,
                    p.omega,
                    p.s_h[0],
                    p.s_h[1],
                    p.s_h_e_alpha[0],
                    p.s_h_e_alpha[1],
                    p.s_h_e_actuator[0],
                    p.s_h_e_actuator[1],
                    p.s_h_phase_deg,
                    p.coherence,
                    p.noise_rel
                );
            }
            for (name, m) in &e.models {
                let ci = m.ci95.map_or(
                    [String::new(), String::new(), String::new(), String::new()],
                    |c| c.map(|x| x.to_string()),
                );
                let _ = writeln!(
                    models,
                    "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                    s.subject,
                    e.experiment,
                    csv_text(e.condition.as_deref()),
                    name,
                    m.k,
                    m.h,
                    m.b,
                    m.m,
                    ci[0],
                    ci[1],
                    ci[2],
                    ci[3],
                    m.r2,
                    m.rss,
                    m.chi2_per_dof.map_or(String::new(), |c| c.to_string())
                );
            }
        }
    }
    let mut ft = String::from("group,test,statistic,critical,df_num,df_den,p_value\n");
    for g in r.f_tests.all_groups() {
        for (name, t) in [("M1-M3", &g.m1_m3), ("M2-M3", &g.m2_m3)] {
            let _ = writeln!(
                ft,
                "{},{},{},{},{},{},{}",
                g.group, name, t.statistic, t.critical, t.df[0], t.df[1], t.p_value
            );
        }
    }
    let mut phase = String::from("subject,experiments,mean_deg,se_deg,n\n");
    for p in &r.phase_table {
        for g in &p.groups {
            let _ = writeln!(
                phase,
                "{},{},{},{},{}",
                p.subject, g.experiments, g.mean_deg, g.se_deg, g.n
            );
        }
    }
    let mut pl = String::from("subject,beta0,beta1,r2,recommended_f\n");
    for s in &r.subjects {
        let o = |v: Option<f64>| v.map_or(String::new(), |x| x.to_string());
        let _ = writeln!(
            pl,
            "{},{},{},{},{}",
            s.subject,
            o(s.beta0),
            o(s.beta1),
            o(s.r2),
            o(s.recommended_f)
        );
    }
    for (name, text) in [
        ("frf.csv", frf),
        ("models.csv", models),
        ("ftests.csv", ft),
        ("phase.csv", phase),
        ("power_law.csv", pl),
    ] {
        let p = dir.join(name);
        exo_recording::files::write_output_file(&p, text)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

/// Runs `exo fit`.
pub fn run(a: &FitArgs) -> Result<()> {
    let (_, report) = fit(a)?;
    if let Some(dir) = &a.csv {
        write_csv(dir, &report)?;
    }
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", tables(&report));
    }
    Ok(())
}
