//! `exo diagnose` on physics outside its catalogue (issue 15), in
//! recordings the independent Python rig wrote (`tools/python/independent_rig.py`,
//! no code shared with exo's simulator), diagnosed against the right linear
//! model (`configs/plants/default.toml`: the rig's arm, load, gravity and
//! 10 Hz SEA; a hysteretic human whose K_h, H_h, M_h the refit finds; with
//! the rig subject's posture strategy, `rig_model`).
//!
//! The truth of every case is the generator's: no catalogue term is in the
//! data. So no catalogue term may be named as the answer, a
//! gravity-compensation error least of all (the case). A generic
//! form of the library may be named as discovered physics only where the
//! generator put it (a stiffening spring, a drifting stiffness), with its
//! parameter near the generator's; elsewhere the verdict must say the misfit
//! is unexplained. With nothing concealed the verdict is "no missing
//! physics" and never also "structure remains".

use std::path::{Path, PathBuf};

use exo_tests::*;
use serde_json::Value;

/// A scratch directory of its own for each test (`case`), which run in
/// parallel in one process.
fn scratch(case: &str) -> ScratchDir {
    exo_tests::scratch_dir(&format!("diag-outside-{case}"))
}

/// Experiments 1, 4, 7 of Table I (α = 1; bias 0, 4, 8 Nm), ten periods
/// (the amplitude rises 10^0.2× at periods 8–10), seed 7.
fn rig(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let rec = dir.join(name);
    stdout_of(
        python_script("independent_rig.py")
            .arg(&rec)
            .args(["--seed", "7", "--experiments", "1,4,7"])
            .args(extra),
    );
    rec
}

/// The rig's nominal model (beside the recording `rec`): the default
/// plant as the rig describes itself (`exo_diagnose::bench::independent_rig`:
/// its subject holds the arm at its goal against the bias, its own `g`),
/// without gravity for a horizontal rig.
fn rig_model(rec: &Path, gravity: bool) -> PathBuf {
    let mut m =
        exo_plant_model::PlantModel::from_file(&configs_dir().join("plants/default.toml")).unwrap();
    exo_diagnose::bench::independent_rig(&mut m, !gravity);
    let name = if gravity {
        "rig-nominal.toml"
    } else {
        "rig-nominal-horizontal.toml"
    };
    let path = rec.parent().unwrap().join(name);
    std::fs::write(&path, m.to_toml_string()).unwrap();
    path
}

fn diagnose(rec: &Path) -> Value {
    diagnose_against(rec, &rig_model(rec, true))
}

fn diagnose_against(rec: &Path, model: &Path) -> Value {
    let out = exo(&[
        "diagnose",
        "--json",
        "--model",
        model.to_str().unwrap(),
        rec.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "exo diagnose: {}", stderr(&out));
    serde_json::from_str(&stdout(&out)).unwrap()
}

fn verdict(v: &Value) -> Vec<String> {
    v["verdict"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect()
}

/// The fitted value of a generic form's parameter in the final model.
fn final_value(v: &Value, key: &str) -> f64 {
    v["final_physics"][key].as_f64().unwrap()
}

/// The candidate `term` of the step that added it.
fn chosen<'a>(v: &'a Value, term: &str) -> &'a Value {
    v["steps"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|s| s["candidates"].as_array().unwrap())
        .find(|c| c["term"] == term && c["chosen"] == true)
        .unwrap_or_else(|| panic!("{term} not chosen"))
}

/// (term, partial) of every term found.
fn found(v: &Value) -> Vec<(String, bool)> {
    v["found"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["term"].as_str().unwrap().to_string(),
                f["partial"].as_bool().unwrap(),
            )
        })
        .collect()
}

/// The characterisation of what remains in one transfer function.
fn remains<'a>(v: &'a Value, tf: &str) -> &'a Value {
    v["remains"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["tf"] == tf)
        .unwrap_or_else(|| panic!("no {tf} in remains"))
}

/// No sentence says both that nothing is missing and that structure remains.
fn assert_exclusive(v: &Value) {
    for line in verdict(v) {
        assert!(
            !(line.contains("no missing physics") && line.contains("remains")),
            "contradictory verdict: {line}"
        );
    }
}

#[test]
fn physics_outside_the_catalogue_is_reported_unexplained_not_named() {
    let dir = scratch("forms");

    // Null: the linear human the model describes; nothing is missing.
    let v = diagnose(&rig(&dir, "linear.mcap", &[]));
    assert!(found(&v).is_empty(), "{:#?}", verdict(&v));
    assert!(
        verdict(&v)
            .iter()
            .any(|l| l.starts_with("no missing physics")),
        "{:#?}",
        verdict(&v)
    );
    assert_exclusive(&v);
    for r in v["remains"].as_array().unwrap() {
        assert!(r["findings"].as_array().unwrap().is_empty(), "{r:#}");
    }

    // A stiffening spring τ = K(θ − θ_p) + K₃(θ − θ_p)³ in the human joint,
    // K₃ = 120 Nm/rad³: discovered as the library's polynomial spring, with
    // K₃ near the generator's, and confirmed where it predicts more than
    // the fundamental (the 3rd harmonic of τ_c it predicts is in the data).
    let v = diagnose(&rig(&dir, "k3-120.mcap", &["--k3", "120"]));
    let text = verdict(&v).join("\n");
    assert_eq!(
        found(&v),
        vec![("cubic_stiffness".to_string(), false)],
        "K₃ = 120:\n{text}"
    );
    let k3 = final_value(&v, "k3");
    assert!((k3 - 120.0).abs() < 0.15 * 120.0, "K₃ = {k3}:\n{text}");
    assert!(
        text.contains("discovered outside the catalogue") && text.contains("stiffening spring"),
        "K₃ = 120:\n{text}"
    );
    let h = &chosen(&v, "cubic_stiffness")["harmonic_check"];
    assert!(
        h["confirmed"].as_f64().unwrap() > 0.5 && h["contradicts"] == false,
        "K₃ = 120 harmonic check: {h:#}"
    );
    // Its rival, a drifting stiffness, absorbs as much of the misfit at the
    // second step but the change within the windows it predicts is not
    // there.
    assert!(
        text.contains("not named: the human's stiffness drifting")
            && text.contains("the change within a window it predicts (")
            && text.contains(") is not in the data"),
        "K₃ = 120:\n{text}"
    );
    assert_exclusive(&v);

    // K₃ = 400: the polynomial spring fits (K₃ ≈ 380) but is rejected by the
    // amplitude check (documented limit); what is added are catalogue
    // terms, each only as a partial answer, never a gravity error.
    let v = diagnose(&rig(&dir, "k3-400.mcap", &["--k3", "400"]));
    let f = found(&v);
    let text = verdict(&v).join("\n");
    assert!(
        f.iter().all(|(t, _)| t != "gravity_error"),
        "K₃ = 400: a gravity error named:\n{text}"
    );
    assert!(
        f.iter().all(|(_, partial)| *partial),
        "K₃ = 400: a term named as the answer:\n{text}"
    );
    assert!(text.contains("unexplained"), "K₃ = 400:\n{text}");
    assert_exclusive(&v);
    // What remains is said to depend on the amplitude: S_h stiffens with
    // the angle amplitude (¾K₃A² makes the in-phase part grow).
    let a = &remains(&v, "S_h")["angle_amplitude"];
    assert!(
        a["significant"] == true && a["in_phase"]["value"].as_f64().unwrap() > 0.0,
        "K₃ = 400: {a:#}\n{text}"
    );
    assert!(
        text.contains("S_h: changes with the angle amplitude"),
        "K₃ = 400:\n{text}"
    );

    // The human's stiffness drifting within each experiment, K(1 + ρt).
    // At 2 % per minute the change within a window that is the drift's own
    // signature (the protocol's time is its frequency, so across windows
    // the two are one) is 2 σ: too small to check. The form is "untested",
    // nothing is named, and no lesser catalogue term takes its misfit (a
    // partial cuff compliance did before).
    let v = diagnose(&rig(&dir, "drift-0.02.mcap", &["--k-drift", "0.02"]));
    let text = verdict(&v).join("\n");
    assert!(found(&v).is_empty(), "ρ = 0.02:\n{text}");
    assert!(
        text.contains("not named: the human's stiffness drifting")
            && text.contains("too small to check in these recordings (untested)"),
        "ρ = 0.02:\n{text}"
    );
    assert_exclusive(&v);
    // At 5 % per minute it is checked and confirmed: discovered as the
    // library's drift with ρ near the generator's; nothing else.
    let rho = 0.05;
    let v = diagnose(&rig(&dir, "drift-0.05.mcap", &["--k-drift", "0.05"]));
    let text = verdict(&v).join("\n");
    assert_eq!(
        found(&v),
        vec![("stiffness_drift".to_string(), false)],
        "ρ = {rho}:\n{text}"
    );
    let fitted = final_value(&v, "k_drift_per_min");
    assert!(
        (fitted - rho).abs() < 0.15 * rho,
        "ρ = {rho}: fitted {fitted}\n{text}"
    );
    assert!(
        text.contains("the rest is within the measured noise"),
        "ρ = {rho}:\n{text}"
    );
    assert_exclusive(&v);

    // A spring in the exoskeleton joint centred at the posture (3 Nm/rad):
    // it stiffens S_h-e and leaves the static balance alone, so a term that
    // would move the balance is contradicted there.
    let v = diagnose(&rig(&dir, "exo-spring.mcap", &["--exo-spring", "3"]));
    let text = verdict(&v).join("\n");
    assert!(found(&v).is_empty(), "exo spring:\n{text}");
    // The library's polynomial spring absorbs part of it, but the 3rd
    // harmonic of τ_c it predicts is not in the data.
    assert!(
        text.contains("not named: an amplitude-dependent stiffness")
            && text.contains("the 3rd harmonic of τ_c it predicts (")
            && text.contains(") is not in the data"),
        "exo spring:\n{text}"
    );
    assert!(text.contains("unexplained"), "exo spring:\n{text}");
    // The cuff gain, which would explain part of S_h, is contradicted by
    // the static balance (since stop 36 the balance, judged by its own
    // noise, also keeps it from being significant at all).
    let cuff_gain_contradicted = v["steps"].as_array().unwrap().iter().any(|s| {
        s["candidates"].as_array().unwrap().iter().any(|c| {
            c["term"] == "cuff_sensor_gain"
                && c["tf_checks"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|t| t["tf"] == "static_balance" && t["contradicts"] == true)
        })
    });
    assert!(
        cuff_gain_contradicted,
        "the cuff gain not contradicted by the static balance:\n{text}"
    );
    assert_exclusive(&v);
    // A linear spring: no dependence on the angle amplitude is claimed.
    for tf in ["S_h", "S_h-e"] {
        let a = &remains(&v, tf)["angle_amplitude"];
        assert!(a["significant"] == false, "exo spring {tf}: {a:#}");
    }
}

/// A cubic damper in the rig's human joint (`--b3`: `B₃ θ̇³` beside its
/// linear damping) at 0.5 and 2 Nm·s³/rad³. The library's cubic damper
/// may be named as discovered physics, with `B₃` near the generator's;
/// otherwise the verdict says the misfit is unexplained, and every term
/// added (catalogue or another form) is only a partial answer. Either way
/// the 3rd harmonic of τ_c the damper predicts, `¼ B₃ (jωΘ)³`, is in the
/// rig's data: the candidate's harmonic check confirms it.
#[test]
fn a_cubic_damper_in_the_rigs_human_is_discovered_or_left_unexplained() {
    let dir = scratch("b3");
    for (b3, arg) in [(0.5, "0.5"), (2.0, "2")] {
        let v = diagnose(&rig(&dir, &format!("b3-{arg}.mcap"), &["--b3", arg]));
        let text = verdict(&v).join("\n");
        let f = found(&v);
        for (term, partial) in &f {
            assert!(
                *partial || term == "cubic_damping",
                "B₃ = {b3}: {term} named as the answer:\n{text}"
            );
        }
        if f.iter().any(|(t, _)| t == "cubic_damping") {
            let fitted = final_value(&v, "b3");
            assert!(
                (fitted - b3).abs() < 0.2 * b3,
                "B₃ = {b3}: fitted {fitted}\n{text}"
            );
        } else {
            assert!(text.contains("unexplained"), "B₃ = {b3}:\n{text}");
        }
        let checks: Vec<&Value> = v["steps"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|s| s["candidates"].as_array().unwrap())
            .filter(|c| c["term"] == "cubic_damping")
            .map(|c| &c["harmonic_check"])
            .collect();
        assert!(
            !checks.is_empty(),
            "B₃ = {b3}: the damper never tried\n{text}"
        );
        for h in checks {
            assert!(
                h["confirmed"].as_f64().unwrap() > 0.5 && h["contradicts"] == false,
                "B₃ = {b3} harmonic check: {h:#}"
            );
        }
        assert_exclusive(&v);
    }
}

/// Backlash in the rig's joint (`--lash`: lost motion in the gear mesh
/// between the SEA's output and the arm, written by the rig's own physics)
/// at 0.02 and 0.1 rad. The arm is held up against gravity, so the SEA's
/// torque never reverses and the mesh never opens: there is nothing to
/// find, and nothing may be named ("no missing physics").
#[test]
fn backlash_in_the_rigs_joint_under_gravity_names_nothing() {
    let dir = scratch("lash");
    for lash in ["0.02", "0.1"] {
        let v = diagnose(&rig(&dir, &format!("lash-{lash}.mcap"), &["--lash", lash]));
        let text = verdict(&v).join("\n");
        assert!(found(&v).is_empty(), "lash {lash}:\n{text}");
        assert!(
            verdict(&v)
                .iter()
                .any(|l| l.starts_with("no missing physics")),
            "lash {lash}:\n{text}"
        );
        assert_exclusive(&v);
    }
}

/// A stiffness that depends on posture in the rig's human joint (`--k2`:
/// `½ K₂ (θ − θ_plan)²` beside its linear spring, so `dK/dθ = K₂`) at two
/// sizes: the transfer functions do not see it to first order; the 2nd
/// harmonic of `τ_c` does. It is discovered there with K₂ near the
/// generator's, the same at both amplitudes; no catalogue term is the
/// answer. (The rig's softest human, experiment 1, loses its equilibrium
/// at K₂ = 20: the quadratic's mean torque outgrows its static spring.)
#[test]
fn a_posture_dependent_stiffness_is_discovered_in_the_2nd_harmonic() {
    let dir = scratch("k2");
    for (k2, arg) in [(8.0, "8"), (15.0, "15")] {
        let v = diagnose(&rig(&dir, &format!("k2-{arg}.mcap"), &["--k2", arg]));
        let text = verdict(&v).join("\n");
        assert_exclusive(&v);
        let forms: Vec<String> = found(&v)
            .into_iter()
            .filter(|(t, partial)| {
                assert!(
                    *partial || t == "posture_stiffness",
                    "K₂ = {k2}: {t} named as the answer:\n{text}"
                );
                t == "posture_stiffness"
            })
            .map(|(t, _)| t)
            .collect();
        assert_eq!(forms.len(), 1, "K₂ = {k2}:\n{text}");
        let fitted = final_value(&v, "k2");
        assert!(
            (fitted - k2).abs() < 0.1 * k2,
            "K₂ = {k2}: fitted {fitted}\n{text}"
        );
        let p = &v["posture"];
        assert_eq!(p["accepted"], true, "K₂ = {k2}: {p:#}");
        let [lo, hi] = [0, 1].map(|i| p["per_amplitude"][i][0].as_f64().unwrap());
        assert!(
            (lo - k2).abs() < 0.1 * k2 && (hi - k2).abs() < 0.5 * k2,
            "K₂ = {k2}: {lo} at the low amplitude, {hi} at the high one"
        );
    }
}

/// Backlash in a horizontal rig (`--horizontal --lash`: no gravity on the
/// arm, none compensated, so the SEA's torque reverses with the sine where
/// no bias holds the mesh closed), diagnosed against the default plant with
/// gravity off: the library's backlash form is discovered with the lost
/// motion near the generator's at both sizes (its describing function,
/// `tools/diagnose/src/model.rs`, shares nothing with the rig's mesh), no
/// catalogue term is the answer, and the linear horizontal rig gets no
/// missing physics.
#[test]
fn backlash_in_a_horizontal_rig_is_discovered() {
    let dir = scratch("lash-horizontal");
    let linear = rig(&dir, "h-linear.mcap", &["--horizontal"]);
    let model = rig_model(&linear, false);

    let v = diagnose_against(&linear, &model);
    assert!(found(&v).is_empty(), "{:#?}", verdict(&v));
    assert_exclusive(&v);

    for (lash, arg) in [(0.05, "0.05"), (0.1, "0.1")] {
        let v = diagnose_against(
            &rig(
                &dir,
                &format!("h-{arg}.mcap"),
                &["--horizontal", "--lash", arg],
            ),
            &model,
        );
        let text = verdict(&v).join("\n");
        assert_exclusive(&v);
        let terms = found(&v);
        for (t, partial) in &terms {
            assert!(
                *partial || t == "backlash",
                "lash {lash}: {t} named as the answer:\n{text}"
            );
        }
        assert!(
            terms.iter().any(|(t, partial)| t == "backlash" && !partial),
            "lash {lash}: backlash not discovered:\n{text}"
        );
        let fitted = 2.0 * final_value(&v, "lash_half_rad");
        assert!(
            (fitted - lash).abs() < 0.1 * lash,
            "lash {lash}: fitted {fitted}\n{text}"
        );
    }
}

/// Backlash's own signature beyond the transfer functions (issue 30,
/// item 1), on data we did not write: the 2nd and 3rd harmonics of the
/// SEA's torque that a lost motion `2δ` leaves beyond the arm's linear
/// impedance (`exo_diagnose::model::Mesh::lost_motion_harmonic`).
///
/// - On the horizontal rig with 0.05 rad of lost motion, the harmonics the
///   form predicts at the fitted δ are in the data at their predicted size
///   (the fraction β of the prediction the data follow is within
///   [0.6, 1.2]: the rig's mesh has a compliance and damping of its own,
///   which round the impacts the form treats as instant).
/// - On the same rig without lost motion, the harmonics the form would
///   predict at δ = 0.025 rad are many noise σ and the data show none of
///   them (β ≈ 0): a backlash fitted to a smooth residual of the transfer
///   functions is refused by its own signature.
#[test]
fn backlashs_harmonics_are_in_the_rigs_data_only_where_it_has_lost_motion() {
    use exo_diagnose::signatures::backlash_harmonic_check;
    let dir = scratch("lash-signature");
    let default = std::fs::read_to_string(configs_dir().join("plants/default.toml")).unwrap();
    let horizontal = default.replacen("[gravity]\nenabled = true", "[gravity]\nenabled = false", 1);
    let model = exo_plant_model::PlantModel::from_toml_str(&horizontal, "horizontal.toml").unwrap();
    let dataset = |rec: &Path| {
        let r = exo_recording::read_recording(rec).unwrap();
        exo_diagnose::reduce(&[r], &exo_diagnose::Reduction::default())
    };
    let settings = exo_diagnose::Settings::default();

    let d = dataset(&rig(
        &dir,
        "h-lash.mcap",
        &["--horizontal", "--lash", "0.05"],
    ));
    let found = exo_diagnose::diagnose(&d, &model, &settings).unwrap();
    let after = found.final_physics.clone();
    assert!(
        (2.0 * after.lash_half_rad - 0.05).abs() < 0.005,
        "{:#?}",
        found.verdict
    );
    let mut before = after.clone();
    before.lash_half_rad = 0.0;
    let (moved, beta, se, _) = backlash_harmonic_check(&d, &before, &after).unwrap();
    assert!(
        moved > 100.0,
        "predicted signature of {:.1} σ",
        moved.sqrt()
    );
    assert!((0.6..=1.2).contains(&beta), "β = {beta} ± {se}");

    let d = dataset(&rig(&dir, "h-null.mcap", &["--horizontal"]));
    let null = exo_diagnose::diagnose(&d, &model, &settings).unwrap();
    assert!(null.found.is_empty(), "{:#?}", null.verdict);
    let before = null.final_physics.clone();
    let mut after = before.clone();
    after.lash_half_rad = 0.025;
    let (moved, beta, se, _) = backlash_harmonic_check(&d, &before, &after).unwrap();
    assert!(
        moved > 100.0,
        "predicted signature of {:.1} σ",
        moved.sqrt()
    );
    assert!(beta.abs() < 0.1 && se < 0.1, "β = {beta} ± {se}");
}

/// The catalogue's cases on data we did not write (issue 30, item 4): the
/// rig's viscous human (`--damping viscous`, an equivalent-viscous damping
/// exact at each period's frequency) with a 5 ms cuff-sensor delay, a 4 ms
/// SEA-sensor delay, a 5 ms encoder delay and a 600 Nm/rad cuff compliance
/// (`--cuff-compliance`, the forearm a body of its own behind a spring and
/// a 2 Nm·s/rad damper), each diagnosed against the default plant. Each
/// is named with the generator's value, and nothing beside it: any other
/// term would be a false alarm (the generator found backlash beside
/// every one of them). Each value within 5 % of the generator's (measured
/// 2026-11-28: 4.95 ± 0.14 ms, 3.944 ± 0.080 ms, 5.051 ± 0.065 ms,
/// 613 ± 15 Nm/rad).
#[test]
fn the_rigs_sensor_delays_and_cuff_compliance_are_named_alone() {
    let dir = scratch("catalogue-on-rig");
    let cases: [(&str, &[&str], &str, f64); 4] = [
        (
            "cuff-delay",
            &["--cuff-delay", "0.005"],
            "cuff_sensor_delay",
            0.005,
        ),
        (
            "sea-delay",
            &["--sea-delay", "0.004"],
            "sea_sensor_delay",
            0.004,
        ),
        (
            "encoder-delay",
            &["--encoder-delay", "0.005"],
            "encoder_delay",
            0.005,
        ),
        (
            "cuff-600",
            &["--cuff-compliance", "600"],
            "cuff_compliance",
            600.0,
        ),
    ];
    for (name, args, term, truth) in cases {
        let mut all = vec!["--damping", "viscous"];
        all.extend_from_slice(args);
        let v = diagnose(&rig(&dir, &format!("{name}.mcap"), &all));
        let text = verdict(&v).join("\n");
        assert_eq!(
            found(&v),
            vec![(term.to_string(), false)],
            "{name}: named\n{text}"
        );
        let fitted = match term {
            "encoder_delay" => v["final_physics"]["delay_s"][0].as_f64().unwrap(),
            "cuff_sensor_delay" => v["final_physics"]["delay_s"][1].as_f64().unwrap(),
            "sea_sensor_delay" => v["final_physics"]["delay_s"][2].as_f64().unwrap(),
            _ => 1.0 / final_value(&v, "cuff_compliance"),
        };
        assert!(
            (fitted - truth).abs() < 0.05 * truth,
            "{name}: fitted {fitted} against the generator's {truth}\n{text}"
        );
        assert_exclusive(&v);
    }
}

/// A SEA discretised by the bilinear transform (`--sea-model tustin`, the
/// filter's output ramped over the next tick) times the torque differently
/// within a tick from the model's held command: at 500 Hz it fits as a
/// delay of the motor command of under a millisecond (0.85 ± 0.10 ms on a
/// null of seed 13012). It is another implementation of the nominal
/// physics: nothing is named, and the delay is reported as the rig's
/// timing, never as missing physics (`within_tick`; issue 30: named on
/// five of six such nulls when the transient-free values were judged
/// without the forward model's floor). Its misfit was within the forward
/// model's accuracy, so the search never ran and the refitted nominal
/// model stayed at χ²/dof 1.3–1.8 (`τ_s/τ_d` 2.4 per residual) on the
/// bench's nulls: the delay is now taken into the refit itself
/// (`engine/timing.rs`), which then stands within the sampling band of a
/// χ² of about 200 residuals, 1 ± 0.2 (issue 30 item 3).
#[test]
fn a_tustin_sea_names_nothing_and_a_delay_within_a_tick_is_timing() {
    let dir = scratch("tustin-timing");
    let v = diagnose(&rig(
        &dir,
        "tustin.mcap",
        &["--damping", "viscous", "--sea-model", "tustin"],
    ));
    let text = verdict(&v).join("\n");
    assert!(found(&v).is_empty(), "named\n{text}");
    assert!(text.contains("no missing physics"), "{text}");
    let within = v["within_tick"].as_array().unwrap();
    assert_eq!(within.len(), 1, "{text}");
    let w = within[0].as_str().unwrap();
    assert!(
        w.starts_with("a delay of the motor command: a delay of "),
        "{w}"
    );
    assert!(w.contains("within one sample period (2.0 ms)"), "{w}");
    let refit = v["refit"]["chi2_per_dof"].as_f64().unwrap();
    assert!((0.8..=1.2).contains(&refit), "refit χ²/dof {refit}\n{text}");
    // The refitted nominal model holds it: the motor command's delay
    // (`Physics::delay_s`: encoder, cuff, SEA sensor, actuator).
    let act = v["refit_physics"]["delay_s"][3].as_f64().unwrap();
    assert!(act > 0.0 && act < 2e-3, "refit actuator delay {act} s");
    assert_exclusive(&v);
}

/// A posture-dependent stiffness too small to matter is not named (issue
/// 30): on a null of the independent rig found by the false-alarm bench
/// (`exo diagnose-bench --nulls 216 --seed-offset 1000`, null 83: seed
/// 1083, a 14-bit encoder), the posture form fitted K₂ = −0.33 ± 0.10
/// Nm/rad², significant in the 2nd harmonic, and was named. Its 2nd
/// harmonic is 0.05 % of τ_c's fundamental, within the forward model's
/// 0.5 % accuracy: now refused for that, and nothing is named.
#[test]
fn a_posture_form_within_the_models_accuracy_is_not_named() {
    let dir = scratch("posture-immaterial");
    let rec = dir.join("null-1083.mcap");
    stdout_of(python_script("independent_rig.py").arg(&rec).args([
        "--seed",
        "1083",
        "--experiments",
        "1,4,7",
        "--encoder-bits",
        "14",
    ]));
    let v = diagnose(&rec);
    assert!(found(&v).is_empty(), "{:#?}", verdict(&v));
    let why: Vec<String> = v["posture"]["rejected_because"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect();
    assert!(
        why.iter()
            .any(|w| w.contains("is within the forward model's accuracy")),
        "{why:#?}"
    );
}

/// The drive's torque limit (issue 30, item 6) on the independent rig,
/// whose drive clips the command it records unclipped (`--saturation`), at
/// two sizes: 27 Nm clips only the peaks of experiment 7 (bias 8 Nm on
/// 17 Nm of gravity compensation, commands up to 28.5 Nm), 26 Nm most of
/// its cycles. Each is named alone, at the rig's limit, confirmed by the
/// 2nd and 3rd harmonics the clipped peaks leave in the SEA's torque at the
/// size the fit predicts, and written into the updated plant (the same rig
/// without a limit names nothing:
/// `physics_outside_the_catalogue_is_reported_unexplained_not_named`).
#[test]
fn the_rigs_torque_limit_is_named_at_two_sizes_by_its_clipped_peaks() {
    let dir = scratch("saturation");
    for limit in [27.0_f64, 26.0] {
        let rec = rig(
            &dir,
            &format!("sat-{limit}.mcap"),
            &["--saturation", &limit.to_string()],
        );
        let out_dir = dir.join(format!("sat-{limit}"));
        let out = exo(&[
            "diagnose",
            "--json",
            "--model",
            rig_model(&rec, true).to_str().unwrap(),
            rec.to_str().unwrap(),
            "-o",
            out_dir.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "exo diagnose: {}", stderr(&out));
        let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
        assert_eq!(
            found(&v),
            vec![("actuator_saturation".to_string(), false)],
            "{limit} Nm: {:#?}",
            verdict(&v)
        );
        assert_exclusive(&v);
        let inv = final_value(&v, "saturation_per_nm");
        let fitted = 1.0 / inv;
        assert!(
            (fitted - limit).abs() < 0.01 * limit,
            "{limit} Nm: fitted {fitted}"
        );
        let c = chosen(&v, "actuator_saturation");
        let h = &c["harmonic_check"];
        assert_eq!(h["confirms"], true, "{limit} Nm: {h:#}");
        let beta = h["confirmed"].as_f64().unwrap();
        assert!((0.8..=1.25).contains(&beta), "{limit} Nm: β = {beta}");
        let plant = std::fs::read_to_string(out_dir.join("updated-plant.toml")).unwrap();
        let written: f64 = plant
            .lines()
            .find_map(|l| l.strip_prefix("torque_limit_nm = "))
            .and_then(|x| x.trim().parse().ok())
            .unwrap_or_else(|| panic!("no torque_limit_nm in {plant}"));
        assert!(
            (written - fitted).abs() < 1e-9 * fitted,
            "{written} against {fitted}"
        );
    }
}

/// A posture shift between experiments (issue 30, item 5) on the
/// independent rig: the subject's reference moved by +0.03, +0.075 and
/// −0.045 rad in experiments 1, 4 and 7 (re-seated). It is no dynamic term:
/// nothing is named, and the verdict locates it where it is beyond the
/// noise of the rig's own period-to-period posture (a 45° ± 2° goal each
/// period: a standard error of about 0.01 rad per experiment), by about
/// its size (the arm follows the reference a little less than fully); the
/// same rig without a shift locates nothing.
#[test]
fn a_posture_shift_between_experiments_is_located_not_named() {
    let dir = scratch("posture-shift");
    let posture = |v: &Value| -> Vec<(u64, f64, f64, bool)> {
        v["equilibrium"]["experiments"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| {
                (
                    e["experiment"].as_u64().unwrap(),
                    e["difference_rad"].as_f64().unwrap(),
                    e["std_error_rad"].as_f64().unwrap(),
                    e["differs"].as_bool().unwrap(),
                )
            })
            .collect()
    };
    let v = diagnose(&rig(&dir, "null.mcap", &[]));
    assert_eq!(v["equilibrium"]["quantity"], "the arm's mean angle");
    for (e, diff, se, differs) in posture(&v) {
        assert!(!differs, "exp {e}: {diff} ± {se}");
    }
    assert!(!verdict(&v).iter().any(|l| l.contains("posture")));

    let v = diagnose(&rig(
        &dir,
        "shift.mcap",
        &["--posture-shift", "1:0.03,4:0.075,7:-0.045"],
    ));
    assert!(found(&v).is_empty(), "{:#?}", verdict(&v));
    assert_exclusive(&v);
    for (e, diff, se, differs) in posture(&v) {
        let truth = match e {
            1 => 0.03,
            4 => 0.075,
            _ => -0.045,
        };
        assert!(
            (diff - truth).abs() < 3.0 * se + 0.01,
            "exp {e}: {diff} ± {se} against {truth}"
        );
        // The two shifts beyond four standard errors are located.
        if e != 1 {
            assert!(differs, "exp {e}: {diff} ± {se}");
        }
    }
    let line = verdict(&v)
        .into_iter()
        .find(|l| l.starts_with("posture, not dynamics"))
        .expect("a posture sentence");
    assert!(
        line.contains("in experiment 4") && line.contains("in experiment 7"),
        "{line}"
    );
}
