//! The real ankle record (`../shared/data/ankle-stiffness-reklab`, the
//! Kearney lab's, not ours): the numbers README.md states for it are
//! asserted here, and the fit is cross-checked with an independent numpy
//! fitter (`tools/python/fit_broadband.py`, which reads the CSV itself: no
//! exo importer, FFT, band averaging or least squares in common) (issue 23).
//!
//! README's values are checked to the precision it prints them with (the
//! printed value is the true one rounded), which is tighter than their
//! stated 95 % intervals; the README's ± are those intervals (Student's t
//! at 34 dof times the standard error), checked to their printed precision
//! too.

use std::path::Path;

use exo_tests::{
    ankle_csv, exo, import_ankle, python_script, stderr, stdout, stdout_of, ScratchDir,
};
use serde_json::Value;

fn scratch(tag: &str) -> ScratchDir {
    exo_tests::scratch_dir(&format!("ankle-{tag}"))
}

/// `exo fit --json --joint ankle` of the record, with `extra` flags.
fn exo_fit(rec: &Path, extra: &[&str]) -> Value {
    let mut args = vec!["fit", "--json", "--joint", "ankle"];
    args.extend_from_slice(extra);
    args.push(rec.to_str().unwrap());
    let out = exo(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    serde_json::from_str(&stdout(&out)).unwrap()
}

/// The independent numpy fit of the CSV.
fn numpy_fit(extra: &[&str]) -> Value {
    let out = stdout_of(
        python_script("fit_broadband.py")
            .arg(ankle_csv())
            .arg("--flip-torque")
            .args(extra),
    );
    serde_json::from_slice(&out).unwrap()
}

/// `value` rounds to README's `printed` (the same number of decimals).
fn assert_printed(value: f64, printed: &str, what: &str) {
    let decimals = printed.split('.').nth(1).map_or(0, str::len);
    let p: f64 = printed.parse().unwrap();
    let half = 0.5 * 10f64.powi(-(decimals as i32));
    assert!(
        (value - p).abs() <= half * (1.0 + 1e-9),
        "{what}: {value} is not README's {printed}"
    );
}

fn f64_at(v: &Value, path: &[&str]) -> f64 {
    let mut x = v;
    for k in path {
        x = &x[*k];
    }
    x.as_f64()
        .unwrap_or_else(|| panic!("{path:?} is not a number: {x}"))
}

/// Index of K, H, B, M in exo's `ci95` and `std_errors`.
const K: usize = 0;
const H: usize = 1;
const B: usize = 2;
const M: usize = 3;

fn ci(v: &Value, model: &str, i: usize) -> f64 {
    v["subjects"][0]["experiments"][0]["models"][model]["ci95"][i]
        .as_f64()
        .unwrap()
}

fn param(v: &Value, model: &str, name: &str) -> f64 {
    f64_at(
        &v["subjects"][0]["experiments"][0]["models"][model],
        &[name],
    )
}

#[test]
fn the_readmes_fit_of_the_real_ankle_record_holds() {
    let dir = scratch("readme");
    let rec = import_ankle(&dir);
    // README, "Real data", weighted by each band's noise (the default).
    let v = exo_fit(&rec, &[]);
    let e = &v["subjects"][0]["experiments"][0];
    assert_eq!(
        e["points"].as_array().unwrap().len(),
        19,
        "19 broadband points"
    );
    let f = &v["f_tests"]["all"];
    assert_printed(f64_at(f, &["m2_m3", "statistic"]), "105.4", "F_M2−M3");
    assert_printed(
        f64_at(f, &["m2_m3", "critical"]),
        "4.13",
        "its critical value",
    );
    assert!(f["m2_m3"]["significant"].as_bool().unwrap());
    assert_printed(f64_at(f, &["m1_m3", "statistic"]), "0.02", "F_M1−M3");
    assert!(!f["m1_m3"]["significant"].as_bool().unwrap());
    assert_printed(param(&v, "M3", "H"), "-0.9", "M3's H");
    assert_printed(ci(&v, "M3", H), "13.1", "M3's H interval");
    // H is consistent with zero: its interval covers it.
    assert!(param(&v, "M3", "H").abs() < ci(&v, "M3", H));
    assert_printed(param(&v, "M3", "K"), "100.7", "K");
    assert_printed(ci(&v, "M3", K), "9.9", "K's interval");
    assert_printed(param(&v, "M3", "B"), "1.18", "B");
    assert_printed(ci(&v, "M3", B), "0.23", "B's interval");
    assert_printed(param(&v, "M3", "M"), "0.0124", "M_h");
    assert_printed(ci(&v, "M3", M), "0.0023", "M_h's interval");
    for m in ["M1", "M2", "M3"] {
        assert!(param(&v, m, "r2") <= 0.79, "{m}: R² ≤ 0.79");
    }
    assert_printed(param(&v, "M3", "r2"), "0.79", "M3's R²");
    let chi2_dof = param(&v, "M3", "chi2_per_dof");
    assert_printed(chi2_dof, "27", "M3's χ²/dof");
    assert_printed(chi2_dof.sqrt(), "5.2", "M3's residual over the noise");
    // Unweighted (--unweighted, the paper's OLS).
    let v = exo_fit(&rec, &["--unweighted"]);
    let f = &v["f_tests"]["all"];
    assert_printed(f64_at(f, &["m2_m3", "statistic"]), "72.7", "OLS F_M2−M3");
    assert_printed(f64_at(f, &["m1_m3", "statistic"]), "2.2", "OLS F_M1−M3");
    assert_printed(param(&v, "M3", "H"), "-9.4", "OLS M3's H");
    assert_printed(ci(&v, "M3", H), "12.8", "OLS M3's H interval");
}

/// `|a − b| ≤ 1e-6 of max(|b|, floor)`: the issue asks 1 %; the two agree
/// to about 1e-14 (measured), so a millionth leaves room for another
/// platform's rounding and catches far smaller errors than 1 % would.
fn assert_agrees(a: f64, b: f64, floor: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-6 * b.abs().max(floor),
        "{what}: exo {a}, numpy {b}"
    );
}

#[test]
fn an_independent_numpy_fit_of_the_ankle_csv_agrees() {
    let dir = scratch("numpy");
    let rec = import_ankle(&dir);
    for extra in [&[][..], &["--unweighted"][..]] {
        let v = exo_fit(&rec, extra);
        let n = numpy_fit(extra);
        let e = &v["subjects"][0]["experiments"][0];
        let (pe, pn) = (
            e["points"].as_array().unwrap(),
            n["points"].as_array().unwrap(),
        );
        assert_eq!(pe.len(), pn.len(), "{extra:?}: points");
        for (a, b) in pe.iter().zip(pn) {
            let w = f64_at(b, &["omega"]);
            assert_agrees(f64_at(a, &["omega"]), w, 0.0, "ω");
            let mag = f64_at(b, &["re"]).hypot(f64_at(b, &["im"]));
            assert_agrees(
                a["s_h"][0].as_f64().unwrap(),
                f64_at(b, &["re"]),
                mag,
                "Re S_h",
            );
            assert_agrees(
                a["s_h"][1].as_f64().unwrap(),
                f64_at(b, &["im"]),
                mag,
                "Im S_h",
            );
            assert_agrees(
                f64_at(a, &["coherence"]),
                f64_at(b, &["coherence"]),
                0.0,
                "coherence",
            );
            assert_agrees(
                f64_at(a, &["noise_rel"]) * mag,
                f64_at(b, &["sigma"]),
                0.0,
                "σ",
            );
        }
        for (model, terms) in [("M1", "MBK"), ("M2", "MKH"), ("M3", "MBKH")] {
            let nm = &n["models"][model];
            for t in terms.chars().map(|c| c.to_string()) {
                let se = f64_at(nm, &["se", &t]);
                // A value near zero (M3's H) is compared on the scale of its error.
                assert_agrees(
                    param(&v, model, &t),
                    f64_at(nm, &["params", &t]),
                    se,
                    &format!("{extra:?} {model} {t}"),
                );
                let i = ["K", "H", "B", "M"].iter().position(|x| *x == t).unwrap();
                let se_exo = e["models"][model]["std_errors"][i].as_f64().unwrap();
                assert_agrees(se_exo, se, 0.0, &format!("{extra:?} {model} SE of {t}"));
            }
            assert_agrees(
                param(&v, model, "r2"),
                f64_at(nm, &["r2"]),
                0.0,
                &format!("{extra:?} {model} R²"),
            );
            assert_agrees(
                param(&v, model, "rss"),
                f64_at(nm, &["rss"]),
                0.0,
                &format!("{extra:?} {model} RSS"),
            );
        }
        let f = &v["f_tests"]["all"];
        for (g, k) in [("m1_m3", "M1_M3"), ("m2_m3", "M2_M3")] {
            // F_M1−M3 is 0.02 weighted: compared on the scale of one.
            assert_agrees(
                f64_at(f, &[g, "statistic"]),
                f64_at(&n["f"], &[k]),
                1.0,
                &format!("{extra:?} {g}"),
            );
        }
    }
}
