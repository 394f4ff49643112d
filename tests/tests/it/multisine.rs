//! A multisine run end to end (issue 34 items 1, 2 and 6): `exo run
//! configs/multisine.toml`, the real processes in lockstep. The controller
//! plays the designed multisine (the wire's broadband ω = 0, its peak the
//! sine-step protocol's), the identifier estimates the human line by line
//! from whole periods, and each line agrees with the plant's human as the
//! plant model defines it: the causal Prony bank of `plants/multisine.toml`
//! (`exo_plant_sim::prony::PronyBank`, the simulator's own element), less
//! `M_h ω²`, within the line's reported noise.

use exo_config::{MultisineSettings, RunConfig};
use exo_messages::{FrfPoint, ProtocolPhase};
use exo_service_kit::channels::{COMMAND, IDENTIFIER_ESTIMATE, IDENTIFIER_FRF, PROTOCOL};
use exo_tests::*;
use num_complex::Complex64;

#[test]
fn a_multisine_run_identifies_every_line_of_the_simulated_human() {
    let sc = Scenario::of("multisine.toml", "msrun", &[]);
    let protocol = sc.collect(PROTOCOL);
    let commands = sc.collect(COMMAND);
    let frf = sc.collect(IDENTIFIER_FRF);
    let estimates = sc.collect(IDENTIFIER_ESTIMATE);
    let out = exo(&["run", sc.config.to_str().unwrap()]);
    assert!(out.status.success(), "exo run failed:\n{}", stderr(&out));
    let (protocol, commands, frf, estimates) = (
        protocol.finish(),
        commands.finish(),
        frf.finish(),
        estimates.finish(),
    );
    let cfg = RunConfig::from_file(&sc.config).unwrap();
    let table = cfg.experiment_table();
    let m: MultisineSettings = cfg.protocol.multisine().unwrap();
    // The wire: broadband (ω = 0) with each experiment's peak, one period
    // per experiment.
    for n in [1, 7] {
        let peak = m.peak_nm_of(table, table.get(n).unwrap());
        assert!((peak - 2.0 * 10f64.powf(0.2)).abs() < 1e-12);
        let analysis: Vec<_> = protocol
            .iter()
            .filter(|p| p.experiment == n && p.protocol_phase() == Some(ProtocolPhase::Analysis))
            .collect();
        assert!(!analysis.is_empty(), "no analysis state of experiment {n}");
        assert!(analysis
            .iter()
            .all(|p| p.omega == 0.0 && p.amplitude == peak && p.period == 1));
        // Estimated live as the periods accrue: an M2 estimate of the
        // experiment once two of its three periods are in (stamped just
        // after their last sample), before its window closes, and the
        // window's own at its end. (After the third, the window's close may
        // come first: the same periods, then estimated once.)
        let opens = analysis.iter().map(|p| p.stamp_ns).min().unwrap();
        let two_periods_ns = (2.0 * m.period_s * 1e9) as u64;
        let closes = protocol
            .iter()
            .filter(|p| p.experiment == n && p.protocol_phase() == Some(ProtocolPhase::RampOut))
            .map(|p| p.stamp_ns)
            .min()
            .expect("the window closes");
        let m2: Vec<_> = estimates
            .iter()
            .filter(|e| e.experiment == n && e.model == 2)
            .collect();
        let first = m2.first().expect("an M2 estimate");
        assert!(first.stamp_ns < closes, "experiment {n}: {m2:?}");
        let tick_ns = (1e9 / cfg.run.rate_hz) as u64;
        assert_eq!(
            first.stamp_ns,
            opens + two_periods_ns - tick_ns + 1,
            "experiment {n}: {m2:?}"
        );
        assert!(
            m2.iter().any(|e| e.stamp_ns >= closes),
            "experiment {n}: {m2:?}"
        );
    }
    // The excitation reaches its peak and never passes it.
    let peak = 2.0 * 10f64.powf(0.2);
    let largest = commands
        .iter()
        .map(|c| c.tau_excitation.abs())
        .fold(0.0, f64::max);
    assert!(largest <= peak + 1e-9 && largest > 0.99 * peak, "{largest}");

    let (_, bins) = m.bins(cfg.run.rate_hz).unwrap();
    // `exo fit` on the recording (item 6) reads the lines from its
    // metadata and estimates each experiment line by line, as online.
    let recording = std::fs::read_dir(sc.dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "mcap"))
        .expect("the run's recording");
    // The run fits its recording and writes the report beside it, as the
    // sine steps' runs do.
    let said = stdout(&out);
    let page = said
        .lines()
        .find_map(|l| l.strip_prefix("report:"))
        .map(|p| std::path::PathBuf::from(p.trim()))
        .unwrap_or_else(|| panic!("exo run named no report:\n{said}"));
    assert!(page.is_file(), "{}", page.display());
    assert!(said.contains("M2 parameters"), "{said}");
    let fit = exo(&["fit", recording.to_str().unwrap(), "--json"]);
    assert!(fit.status.success(), "exo fit:\n{}", stderr(&fit));
    let json: serde_json::Value = serde_json::from_str(&stdout(&fit)).unwrap();
    for e in json["subjects"][0]["experiments"].as_array().unwrap() {
        let omegas: Vec<f64> = e["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["omega"].as_f64().unwrap())
            .collect();
        assert_eq!(omegas.len(), bins.len(), "{e}");
        for (w, b) in omegas.iter().zip(&bins) {
            assert!((w - std::f64::consts::TAU * *b as f64 / m.period_s).abs() < 1e-9);
        }
    }
    let plant = exo_plant_model::PlantModel::from_file(&cfg.plant_model).unwrap();
    let hd = plant.human.hysteretic_damping;
    for n in [1u32, 7] {
        let pts: Vec<&FrfPoint> = frf.iter().filter(|p| p.experiment == n).collect();
        assert_eq!(
            pts.len(),
            bins.len(),
            "experiment {n}: {} points",
            pts.len()
        );
        let e = cfg.subject().get(n).unwrap();
        let (k, h) = (e.stiffness_nm_per_rad, e.hysteretic_damping_nm_per_rad);
        let bank = exo_plant_sim::prony::PronyBank::fit(
            k,
            h / k,
            hd.band_rad_s,
            hd.elements_per_decade,
            hd.reference_rad_s,
        )
        .unwrap();
        let m_h = cfg.subject().inertia_kg_m2;
        for (p, b) in pts.iter().zip(&bins) {
            let w = std::f64::consts::TAU * *b as f64 / m.period_s;
            assert!((p.omega - w).abs() < 1e-9, "{} vs {w}", p.omega);
            let truth = bank.response(w) - m_h * w * w;
            let got = Complex64::new(p.s_h_re, p.s_h_im);
            // Four reported standard errors, and 3 % for what the run's
            // own transient (the arm's mode rung by the fade-in) leaves.
            let allowed = 4.0 * p.noise_rel * got.norm() + 0.03 * truth.norm();
            assert!(
                (got - truth).norm() < allowed,
                "experiment {n}, ω {w:.3}: {got:.3} vs {truth:.3} (allowed {allowed:.3})"
            );
        }
    }
}

/// `protocol.stop_when` end to end (issue 34 item 3): the shipped multisine
/// run with up to five analysed periods and `stop_when = { k_rel_ci = 0.05,
/// h_rel_ci = 0.10 }`, through the real processes (lockstep) and through
/// `exo sim` (the nodes in one process). Each experiment's analysis window
/// is a whole number of multisine periods, at least two, and ends before
/// its fifth when the identifier's estimate, published before the end,
/// had K and H within the fractions; both paths end every window at the
/// same point (the plant paces itself to the identifier); and the
/// recording is fitted line by line as any other.
#[test]
fn stop_when_ends_an_analysis_once_k_and_h_are_known() {
    let edits: &[(&str, &str)] = &[
        ("periods = 3 ", "periods = 5 "),
        (
            "[controller]\n",
            "[protocol.stop_when]\nk_rel_ci = 0.05\nh_rel_ci = 0.10\n\n[controller]\n",
        ),
    ];
    let sc = Scenario::of("multisine.toml", "msstop", edits);
    let out = exo(&["run", sc.config.to_str().unwrap()]);
    assert!(out.status.success(), "exo run failed:\n{}", stderr(&out));
    let cfg = RunConfig::from_file(&sc.config).unwrap();
    let period_ns = (cfg.protocol.multisine().unwrap().period_s * 1e9) as u64;
    let recordings: Vec<_> = std::fs::read_dir(sc.dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    assert_eq!(recordings.len(), 1, "{recordings:?}");
    let sim_rec = sc.dir.path().join("sim.mcap");
    let sim = exo(&[
        "sim",
        sc.config.to_str().unwrap(),
        "--no-report",
        "--output",
        sim_rec.to_str().unwrap(),
    ]);
    assert!(sim.status.success(), "exo sim failed:\n{}", stderr(&sim));
    let mut lengths = Vec::new();
    for rec in [&recordings[0], &sim_rec] {
        let r = exo_recording::read_recording(rec).unwrap();
        let mut per_experiment = Vec::new();
        for n in [1, 7] {
            let opens = r
                .protocol
                .iter()
                .filter(|p| {
                    p.experiment == n && p.protocol_phase() == Some(ProtocolPhase::Analysis)
                })
                .map(|p| p.stamp_ns)
                .min()
                .unwrap();
            let closes = r
                .protocol
                .iter()
                .filter(|p| p.experiment == n && p.protocol_phase() == Some(ProtocolPhase::RampOut))
                .map(|p| p.stamp_ns)
                .min()
                .unwrap();
            let len = closes - opens;
            assert_eq!(len % period_ns, 0, "{}: experiment {n}", rec.display());
            let periods = len / period_ns;
            assert!(
                (2..=5).contains(&periods),
                "experiment {n}: {periods} periods"
            );
            if periods < 5 {
                // Ended early: an M2 estimate within the rule came first
                // (twelve lines, three parameters: t at 21 degrees of
                // freedom, 2.0796 from the tables).
                const T21: f64 = 2.0796;
                let w = cfg.protocol.stop_when.unwrap();
                assert!(
                    r.estimate.iter().any(|e| e.experiment == n
                        && e.model == 2
                        && e.stamp_ns < closes
                        && w.met(e.k_h, T21 * e.k_h_se, e.h_h, T21 * e.h_h_se)),
                    "experiment {n} ended after {periods} periods with no estimate within the rule"
                );
            }
            per_experiment.push(periods);
        }
        lengths.push(per_experiment);
    }
    eprintln!("analysed periods (exo run, exo sim): {lengths:?}");
    assert_eq!(lengths[0], lengths[1], "exo run and exo sim differ");
    assert!(
        lengths[0].iter().any(|&p| p < 5),
        "no experiment ended early: {lengths:?}"
    );
    // The run's own fit of the recording: one point a line.
    let fit = exo(&["fit", recordings[0].to_str().unwrap(), "--json"]);
    assert!(fit.status.success(), "exo fit:\n{}", stderr(&fit));
    let json: serde_json::Value = serde_json::from_str(&stdout(&fit)).unwrap();
    for e in json["subjects"][0]["experiments"].as_array().unwrap() {
        assert_eq!(e["points"].as_array().unwrap().len(), 12, "{e}");
    }
}
