//! `exo diagnose` on physics outside its catalogue (issue 15), in
//! recordings the independent Python rig wrote (`tools/python/independent_rig.py`,
//! no code shared with exo's simulator), diagnosed against the right linear
//! model (`configs/plants/default.toml`: the rig's arm, load, gravity and
//! 10 Hz SEA; a hysteretic human whose K_h, H_h, M_h the refit finds).
//!
//! The truth of every case is the generator's: no catalogue term is in the
//! data. So nothing may be named as the answer, a gravity-compensation error
//! least of all (the case), and the verdict must say the misfit is
//! unexplained; with nothing concealed the verdict is "no missing physics"
//! and never also "structure remains".

use std::path::{Path, PathBuf};
use std::process::Command;

use exo_tests::*;
use serde_json::Value;

fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("exo-it-diag-outside-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Experiments 1, 4, 7 of Table I (α = 1; bias 0, 4, 8 Nm), ten periods
/// (the amplitude rises 10^0.2× at periods 8–10), seed 7.
fn rig(dir: &Path, name: &str, extra: &[&str]) -> PathBuf {
    let rec = dir.join(name);
    let out = Command::new(python())
        .arg(workspace_root().join("tools/python/independent_rig.py"))
        .arg(&rec)
        .args(["--seed", "7", "--experiments", "1,4,7"])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "independent_rig.py {extra:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    rec
}

fn diagnose(rec: &Path) -> Value {
    let model = configs_dir().join("plants/default.toml");
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
    let dir = scratch();

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

    // A stiffening spring τ = K(θ − θ_p) + K₃(θ − θ_p)³ in the human joint.
    for k3 in ["120", "400"] {
        let v = diagnose(&rig(&dir, &format!("k3-{k3}.mcap"), &["--k3", k3]));
        let f = found(&v);
        let text = verdict(&v).join("\n");
        assert!(
            f.iter().all(|(t, _)| t != "gravity_error"),
            "K₃ = {k3}: a gravity error named:\n{text}"
        );
        assert!(
            f.iter().all(|(_, partial)| *partial),
            "K₃ = {k3}: a term named as the answer:\n{text}"
        );
        assert!(text.contains("unexplained"), "K₃ = {k3}:\n{text}");
        assert_exclusive(&v);
        // What remains is said to depend on the amplitude: S_h stiffens
        // with the angle amplitude (¾K₃A² makes the in-phase part grow).
        let a = &remains(&v, "S_h")["angle_amplitude"];
        assert!(
            a["significant"] == true && a["in_phase"]["value"].as_f64().unwrap() > 0.0,
            "K₃ = {k3}: {a:#}\n{text}"
        );
        assert!(
            text.contains("S_h: changes with the angle amplitude"),
            "K₃ = {k3}:\n{text}"
        );
        if k3 == "120" {
            // Every significant candidate absorbs part of the spring at one
            // amplitude only: none is accepted at all.
            assert!(f.is_empty(), "K₃ = {k3}:\n{text}");
        }
    }

    // A spring in the exoskeleton joint centred at the posture (3 Nm/rad):
    // it stiffens S_h-e and leaves the static balance alone, so a term that
    // would move the balance is contradicted there.
    let v = diagnose(&rig(&dir, "exo-spring.mcap", &["--exo-spring", "3"]));
    let text = verdict(&v).join("\n");
    assert!(found(&v).is_empty(), "exo spring:\n{text}");
    assert!(text.contains("unexplained"), "exo spring:\n{text}");
    let balance_contradicts = v["steps"].as_array().unwrap().iter().any(|s| {
        s["candidates"].as_array().unwrap().iter().any(|c| {
            c["significant"].as_bool().unwrap()
                && c["tf_checks"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|t| t["tf"] == "static_balance" && t["contradicts"] == true)
        })
    });
    assert!(
        balance_contradicts,
        "no significant candidate contradicted by the static balance:\n{text}"
    );
    assert_exclusive(&v);
    // A linear spring: no dependence on the angle amplitude is claimed.
    for tf in ["S_h", "S_h-e"] {
        let a = &remains(&v, tf)["angle_amplitude"];
        assert!(a["significant"] == false, "exo spring {tf}: {a:#}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
