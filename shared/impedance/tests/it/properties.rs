//! Property tests on random parameters.

use exo_impedance::*;
use proptest::prelude::*;
use proptest::test_runner::{FileFailurePersistence, RngSeed};

fn frequencies(w0: f64, n: usize) -> Vec<f64> {
    (0..n).map(|i| w0 * 10f64.powf(0.1 * i as f64)).collect()
}

proptest! {
    // A fixed seed (issue 23): every run draws the same 128 cases, so a CI
    // failure reproduces locally (`PROPTEST_RNG_SEED` still overrides it),
    // and the cases that failed before, kept in
    // `properties.proptest-regressions`, are re-run first.
    #![proptest_config(ProptestConfig {
        cases: 128,
        rng_seed: RngSeed::Fixed(0x0023_5EED),
        failure_persistence: Some(Box::new(FileFailurePersistence::SourceParallel("proptest-regressions"))),
        ..ProptestConfig::default()
    })]

    /// Noise-free points from M3 with random parameters: every model's fit
    /// is reproduced by M3 exactly, and M3 recovers its parameters.
    #[test]
    fn fit_round_trips(
        m in 0.02f64..2.0, b in 0.0f64..3.0, k in 5.0f64..150.0, h in 0.0f64..60.0,
        w0 in 0.5f64..5.0, n in 3usize..15,
    ) {
        let truth = DynamicStiffness { m_kg_m2: m, b_nm_s_per_rad: b, k_nm_per_rad: k, h_nm_per_rad: h };
        let pts: Vec<FrfPoint> = frequencies(w0, n)
            .into_iter()
            .map(|w| FrfPoint { omega_rad_s: w, value: truth.response(w), std_dev_nm_per_rad: 0.0 })
            .collect();
        let fit = fit_model(ImpedanceModel::M3, &pts, FitTarget::Human).unwrap();
        let scale = truth.to_array().iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for t in Term::ALL {
            prop_assert!((fit.params.get(t) - truth.get(t)).abs() <= 1e-8 * scale,
                "{t:?}: {} vs {}", fit.params.get(t), truth.get(t));
        }
    }

    /// F ≥ 0 and every RSS non-negative, on arbitrary noisy data; the nested
    /// models never fit better than M3.
    #[test]
    fn f_statistics_are_non_negative(
        k in 5.0f64..150.0, h in 0.0f64..60.0, b in 0.0f64..3.0,
        noise in prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 10),
    ) {
        let truth = DynamicStiffness { m_kg_m2: 0.5, b_nm_s_per_rad: b, k_nm_per_rad: k, h_nm_per_rad: h };
        let pts: Vec<FrfPoint> = frequencies(2.0, 10)
            .into_iter()
            .zip(&noise)
            .map(|(w, (a, c))| FrfPoint { omega_rad_s: w, value: truth.response(w) + Complex64::new(*a, *c), std_dev_nm_per_rad: 0.0 })
            .collect();
        let cmp = fit_all(&pts, FitTarget::Human).unwrap();
        prop_assert!(cmp.m3.rss <= cmp.m1.rss * (1.0 + 1e-9) + 1e-12);
        prop_assert!(cmp.m3.rss <= cmp.m2.rss * (1.0 + 1e-9) + 1e-12);
        let t = paper_f_tests(&[cmp], 0.05).unwrap();
        prop_assert!(t.m1_vs_m3.statistic >= 0.0 && t.m2_vs_m3.statistic >= 0.0);
        prop_assert!(t.m1_vs_m3.p_value >= 0.0 && t.m1_vs_m3.p_value <= 1.0);
    }

    /// With a fast SEA and the crossover at the centre of a long lag-filter
    /// band, the phase margin is the paper's: the plant's phase lead at the
    /// crossover minus 90·f, never below atan(c) − 90·f (the bound
    /// f < atan(c)/90), and within a few degrees of it when M_e ≫ M_h.
    #[test]
    fn phase_margin_follows_the_hysteretic_bound(
        c in 0.1f64..1.0, k in 10.0f64..100.0, ratio in 20.0f64..400.0, frac in 0.05f64..0.9,
    ) {
        let m_h = 0.11;
        let m_e = m_h * ratio;
        let f = frac * c.atan().to_degrees() / 90.0;
        let kp = proportional_gain(m_e, m_h).unwrap();
        let w_gc = crossover_frequency(k, m_e, m_h).unwrap();
        let r_pp = 10f64.sqrt();
        let n = 12;
        // Centre of the band (geometric mean of p1 and z_n) at ω_gc.
        let p1 = w_gc / (r_pp.powi(n as i32 - 1) * r_pp.powf(f)).sqrt();
        let filter = LagFilter::new(n, p1, r_pp, f, fractional_gain(w_gc, f).unwrap()).unwrap();
        let sea = SeaModel::new(1.0e4, 0.7).unwrap();
        let plant = AmplificationPlant::new(m_e, m_h, k, c, sea).unwrap();
        let l = AmplificationLoop { kp, filter, plant };
        let a = l.analyze(1e-3 * p1, 1e3 * sea.omega_n_rad_s()).unwrap();
        let first = a.crossovers.first().copied().expect("a crossover");
        let w_he = (k / (m_e + m_h)).sqrt();
        let w_h = (k / m_h).sqrt();
        prop_assert!(first.omega_rad_s > w_he && first.omega_rad_s < w_h, "{first:?} not in ({w_he}, {w_h})");
        let ideal = 180.0 + plant.phase_deg(first.omega_rad_s) - 90.0 * f;
        prop_assert!((first.phase_margin_deg - ideal).abs() < 0.5, "PM {} vs ideal {ideal}", first.phase_margin_deg);
        let bound = c.atan().to_degrees() - 90.0 * f;
        prop_assert!(first.phase_margin_deg > bound - 0.5, "PM {} below bound {bound}", first.phase_margin_deg);
    }
}

/// "Close to": the margin's excess over atan(c) − 90·f comes from the
/// plant's extra phase lead between ω_{h-e} and ω_h, which vanishes as
/// M_e/M_h grows (the crossover moves away from both resonances).
#[test]
fn phase_margin_approaches_the_bound_as_the_exo_outweighs_the_human() {
    let (m_h, k, c, f) = (0.11, 30.0, 0.4, 0.15);
    let excess = |ratio: f64| {
        let m_e = m_h * ratio;
        let kp = proportional_gain(m_e, m_h).unwrap();
        let w_gc = crossover_frequency(k, m_e, m_h).unwrap();
        let r_pp = 10f64.sqrt();
        let p1 = w_gc / (r_pp.powi(11) * r_pp.powf(f)).sqrt();
        let filter = LagFilter::new(12, p1, r_pp, f, fractional_gain(w_gc, f).unwrap()).unwrap();
        let plant =
            AmplificationPlant::new(m_e, m_h, k, c, SeaModel::new(1.0e4, 0.7).unwrap()).unwrap();
        let a = AmplificationLoop { kp, filter, plant }
            .analyze(1e-3 * p1, 1e6)
            .unwrap();
        a.crossovers[0].phase_margin_deg - (c.atan().to_degrees() - 90.0 * f)
    };
    let (e10, e100, e10000) = (excess(10.0), excess(100.0), excess(10_000.0));
    assert!(
        e10 > e100 && e100 > e10000 && e10000 >= -0.5,
        "{e10} {e100} {e10000}"
    );
    assert!(e10000 < 1.0, "excess at M_e/M_h = 1e4 is {e10000}°");
}
