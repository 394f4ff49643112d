//! Weighted least squares, its intervals and the sign constraint, each
//! checked against a truth computed independently of `fit_model`: closed
//! forms written out here, and Monte-Carlo coverage over seeded noise.

use exo_impedance::{
    fit_model, fit_model_with, students_t_quantile, Complex64, DampingSign, DynamicStiffness,
    FitTarget, FrfPoint, ImpedanceModel,
};

const M_E: f64 = 1.01125;

/// The paper's ten frequencies from 2 rad/s.
fn omegas() -> Vec<f64> {
    (0..10).map(|i| 2.0 * 10f64.powf(0.1 * i as f64)).collect()
}

use crate::rng::SplitMix64 as Rng;

/// Points of `truth` with circular complex noise of `σ_k = sigma[k]`
/// (`E|δ|² = σ²`, so σ/√2 in each part), carrying their σ.
fn noisy(truth: DynamicStiffness, sigma: &[f64], rng: &mut Rng) -> Vec<FrfPoint> {
    omegas()
        .iter()
        .zip(sigma)
        .map(|(&w, &s)| {
            let d = Complex64::new(rng.gaussian(), rng.gaussian()) * (s / 2f64.sqrt());
            let v = truth.response(w) + d;
            FrfPoint::new(w, v.re, v.im).with_std_dev(s)
        })
        .collect()
}

fn human() -> DynamicStiffness {
    DynamicStiffness {
        m_kg_m2: 0.13,
        b_nm_s_per_rad: 0.0,
        k_nm_per_rad: 25.0,
        h_nm_per_rad: 8.0,
    }
}

/// In M2 the imaginary part holds H alone, so the weighted estimate of H is
/// the weighted mean of Im S_k with weights 1/σ_k², and its standard error
/// `√(s²/Σ(2/σ_k²))` with `s² = χ²/(2n − 3)`: written out here by hand.
#[test]
fn m2_hysteresis_is_the_noise_weighted_mean_of_the_imaginary_parts() {
    let sigma: Vec<f64> = (0..10).map(|k| 0.2 * (1.0 + k as f64)).collect();
    let pts = noisy(human(), &sigma, &mut Rng(7));
    let fit = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap();
    assert!(fit.weighted);
    let (mut num, mut den) = (0.0, 0.0);
    for p in &pts {
        let w = 1.0 / (p.std_dev_nm_per_rad * p.std_dev_nm_per_rad);
        num += w * p.value.im;
        den += w;
    }
    let h_closed = num / den;
    assert!(
        (fit.params.h_nm_per_rad - h_closed).abs() < 1e-10,
        "{} vs {h_closed}",
        fit.params.h_nm_per_rad
    );
    // χ² and the residual scale, by hand from the fitted parameters.
    let chi2: f64 = pts
        .iter()
        .map(|p| {
            let r = p.value - fit.params.response(p.omega_rad_s);
            2.0 * r.norm_sqr() / (p.std_dev_nm_per_rad * p.std_dev_nm_per_rad)
        })
        .sum();
    assert!(
        (fit.chi2 / chi2 - 1.0).abs() < 1e-10,
        "{} vs {chi2}",
        fit.chi2
    );
    assert_eq!(fit.dof, 17);
    let s2 = chi2 / 17.0;
    let se_h = (s2 / (2.0 * den)).sqrt();
    let got = fit.std_errors.unwrap().h_nm_per_rad;
    assert!((got / se_h - 1.0).abs() < 1e-9, "{got} vs {se_h}");
    // Student's t at 17 degrees of freedom, 97.5 %: 2.109816 (tables).
    let t = students_t_quantile(17, 0.975).unwrap();
    assert!((t - 2.109816).abs() < 1e-5, "{t}");
    let ci = fit.ci95.unwrap().h_nm_per_rad;
    assert!((ci / (t * se_h) - 1.0).abs() < 1e-9);
    let rc = fit.reduced_chi2.unwrap();
    assert!((rc - s2).abs() < 1e-12);
}

/// Without a σ on every point the fit is the paper's ordinary least squares.
#[test]
fn without_noise_on_every_point_the_fit_is_unweighted() {
    let sigma: Vec<f64> = (0..10).map(|k| 0.2 * (1.0 + k as f64)).collect();
    let mut pts = noisy(human(), &sigma, &mut Rng(3));
    pts[4].std_dev_nm_per_rad = 0.0;
    let fit = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap();
    assert!(!fit.weighted);
    assert_eq!(fit.chi2, fit.rss);
    assert!(fit.reduced_chi2.is_none() && fit.misfit_p_value.is_none());
    let mean_im = pts.iter().map(|p| p.value.im).sum::<f64>() / pts.len() as f64;
    assert!((fit.params.h_nm_per_rad - mean_im).abs() < 1e-10);
}

/// Monte-Carlo coverage: points whose noise differs tenfold across the band
/// (as near a natural frequency); over 400 seeds the 95 % intervals of K, H
/// and M must hold the truth in 90–99 % of fits. The weighted fit must also
/// be more precise than the unweighted one on the same data.
#[test]
fn ninety_five_percent_intervals_cover_the_truth() {
    let truth = human();
    let sigma: Vec<f64> = (0..10).map(|k| 0.1 * 10f64.powf(k as f64 / 9.0)).collect();
    let runs = 400;
    let mut hits = [0usize; 3];
    let (mut sq_w, mut sq_u) = (0.0, 0.0);
    let mut rng = Rng(2024);
    for _ in 0..runs {
        let pts = noisy(truth, &sigma, &mut rng);
        let fit = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap();
        let ci = fit.ci95.unwrap();
        let p = fit.params;
        hits[0] += usize::from((p.k_nm_per_rad - truth.k_nm_per_rad).abs() <= ci.k_nm_per_rad);
        hits[1] += usize::from((p.h_nm_per_rad - truth.h_nm_per_rad).abs() <= ci.h_nm_per_rad);
        hits[2] += usize::from((p.m_kg_m2 - truth.m_kg_m2).abs() <= ci.m_kg_m2);
        sq_w += (p.k_nm_per_rad - truth.k_nm_per_rad).powi(2);
        let unweighted: Vec<FrfPoint> = pts
            .iter()
            .map(|q| FrfPoint::new(q.omega_rad_s, q.value.re, q.value.im))
            .collect();
        let u = fit_model(ImpedanceModel::M2, &unweighted, FitTarget::Human).unwrap();
        sq_u += (u.params.k_nm_per_rad - truth.k_nm_per_rad).powi(2);
    }
    for (name, h) in ["K", "H", "M"].iter().zip(hits) {
        let cover = h as f64 / runs as f64;
        assert!(
            (0.90..=0.99).contains(&cover),
            "{name}: 95 % interval covered the truth in {:.1} % of {runs} fits",
            100.0 * cover
        );
    }
    assert!(
        sq_w < 0.8 * sq_u,
        "weighted MSE {sq_w} vs unweighted {sq_u}"
    );
}

/// `(τ_s − τ_g)/θ_e` holds the whole exoskeleton inertia whatever α is: the
/// actuator-side target removes `M_e` and returns the human's `M_h`.
#[test]
fn actuator_side_points_give_the_human_inertia() {
    let truth = human();
    let pts: Vec<FrfPoint> = omegas()
        .iter()
        .map(|&w| {
            let v = truth.response(w) - Complex64::new(M_E * w * w, 0.0);
            FrfPoint::new(w, v.re, v.im)
        })
        .collect();
    let fit = fit_model(
        ImpedanceModel::M2,
        &pts,
        FitTarget::ActuatorSide { m_e_kg_m2: M_E },
    )
    .unwrap();
    assert!((fit.params.m_kg_m2 - 0.13).abs() < 1e-9, "{:?}", fit.params);
    // Read as S_h-e/α with α = 4, the same points put 3/4 of M_e into M_h.
    let wrong = fit_model(
        ImpedanceModel::M2,
        &pts,
        FitTarget::Coupled {
            m_e_kg_m2: M_E,
            alpha: 4.0,
        },
    )
    .unwrap();
    assert!((wrong.params.m_kg_m2 - (0.13 + 0.75 * M_E)).abs() < 1e-9);
}

/// A joint whose data say H < 0: the free fit reports it, the non-negative
/// fit holds H at zero and is then exactly M1 (the best passive model), with
/// the degrees of freedom of its free parameters.
#[test]
fn non_negative_damping_holds_a_negative_term_at_zero() {
    let active = DynamicStiffness {
        m_kg_m2: 0.02,
        b_nm_s_per_rad: 1.5,
        k_nm_per_rad: 200.0,
        h_nm_per_rad: -12.0,
    };
    let sigma = vec![0.5; 10];
    let pts = noisy(active, &sigma, &mut Rng(11));
    let free = fit_model(ImpedanceModel::M3, &pts, FitTarget::Human).unwrap();
    assert!(free.params.h_nm_per_rad < -8.0, "{:?}", free.params);
    let nn = fit_model_with(
        ImpedanceModel::M3,
        &pts,
        FitTarget::Human,
        DampingSign::NonNegative,
    )
    .unwrap();
    assert_eq!(nn.params.h_nm_per_rad, 0.0);
    assert!(nn.held_at_zero[3] && !nn.held_at_zero[1]);
    assert!(nn.params.b_nm_s_per_rad >= 0.0);
    assert_eq!(nn.dof, 20 - 3);
    let m1 = fit_model(ImpedanceModel::M1, &pts, FitTarget::Human).unwrap();
    for (a, b) in nn.params.to_array().iter().zip(m1.params.to_array()) {
        assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{a} vs {b}");
    }
    // A passive joint's fit is left as it is.
    let pts = noisy(human(), &sigma, &mut Rng(12));
    let free = fit_model(ImpedanceModel::M3, &pts, FitTarget::Human).unwrap();
    let nn = fit_model_with(
        ImpedanceModel::M3,
        &pts,
        FitTarget::Human,
        DampingSign::NonNegative,
    )
    .unwrap();
    if free.params.b_nm_s_per_rad >= 0.0 {
        assert_eq!(nn, free);
    }
}

#[test]
fn a_negative_or_non_finite_noise_is_named() {
    let mut pts = noisy(human(), &[0.3; 10], &mut Rng(1));
    pts[2].std_dev_nm_per_rad = -1.0;
    let e = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap_err();
    assert!(e.to_string().contains("std_dev_nm_per_rad[2]"), "{e}");
    pts[2].std_dev_nm_per_rad = f64::NAN;
    assert!(fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).is_err());
}

/// A σ far below the others is raised to a tenth of the median σ (here of
/// an even count: the mean of the middle two), so one lucky point cannot
/// carry the fit: H of M2 is then the weighted mean with that floor.
#[test]
fn a_tiny_noise_is_floored_at_a_tenth_of_the_median() {
    let sigma = [1e-6, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.4, 1.6, 1.8];
    let pts = noisy(human(), &sigma, &mut Rng(5));
    let fit = fit_model(ImpedanceModel::M2, &pts, FitTarget::Human).unwrap();
    // Median of the ten: (0.8 + 1.0) / 2 = 0.9; floor 0.09.
    let effective: Vec<f64> = sigma.iter().map(|s| s.max(0.09)).collect();
    let (mut num, mut den) = (0.0, 0.0);
    for (p, s) in pts.iter().zip(&effective) {
        num += p.value.im / (s * s);
        den += 1.0 / (s * s);
    }
    assert!(
        (fit.params.h_nm_per_rad - num / den).abs() < 1e-9,
        "{} vs {}",
        fit.params.h_nm_per_rad,
        num / den
    );
    // Odd count: the middle value (0.8 of the first nine; floor 0.08).
    let pts9 = &pts[..9];
    let fit = fit_model(ImpedanceModel::M2, pts9, FitTarget::Human).unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    for (p, s) in pts9.iter().zip(sigma) {
        let s = s.max(0.08);
        num += p.value.im / (s * s);
        den += 1.0 / (s * s);
    }
    assert!((fit.params.h_nm_per_rad - num / den).abs() < 1e-9);
}

/// Points whose imaginary parts are `b ω + h`, exactly, for the sign tests.
fn imaginary_line(b: f64, h: f64) -> Vec<FrfPoint> {
    let truth = DynamicStiffness {
        m_kg_m2: 0.1,
        b_nm_s_per_rad: b,
        k_nm_per_rad: 30.0,
        h_nm_per_rad: h,
    };
    omegas()
        .iter()
        .enumerate()
        .map(|(k, &w)| {
            // A small deterministic wobble so no face fits exactly.
            let v =
                truth.response(w) + Complex64::new(0.0, 0.05 * if k % 2 == 0 { 1.0 } else { -1.0 });
            FrfPoint::new(w, v.re, v.im).with_std_dev(0.1)
        })
        .collect()
}

/// The constrained optimum checked face by face: B and H both negative
/// need both held at zero; B > 0 with H < 0 holds H (the best of two
/// feasible faces, not the first found); B < 0 with H > 0 holds B.
#[test]
fn non_negative_damping_finds_the_best_feasible_face() {
    let fit_nn = |pts: &[FrfPoint]| {
        fit_model_with(
            ImpedanceModel::M3,
            pts,
            FitTarget::Human,
            DampingSign::NonNegative,
        )
        .unwrap()
    };
    let nested = |model, pts: &[FrfPoint]| fit_model(model, pts, FitTarget::Human).unwrap();
    // Both negative: only stiffness and inertia remain (χ² of that face by hand).
    let pts = imaginary_line(-0.3, -2.0);
    let free = nested(ImpedanceModel::M3, &pts);
    assert!(free.params.b_nm_s_per_rad < 0.0 && free.params.h_nm_per_rad < 0.0);
    let nn = fit_nn(&pts);
    assert_eq!(nn.held_at_zero, [false, true, false, true]);
    assert_eq!(
        (nn.params.b_nm_s_per_rad, nn.params.h_nm_per_rad),
        (0.0, 0.0)
    );
    let chi2_im: f64 = pts
        .iter()
        .map(|p| 2.0 * p.value.im * p.value.im / 0.01)
        .sum();
    let m1 = nested(ImpedanceModel::M1, &pts);
    // Real parts as M1's (same real-part terms), imaginary parts unexplained.
    let chi2_re = m1.chi2
        - pts
            .iter()
            .map(|p| {
                let r = p.value.im - m1.params.b_nm_s_per_rad * p.omega_rad_s;
                2.0 * r * r / 0.01
            })
            .sum::<f64>();
    assert!(
        (nn.chi2 / (chi2_re + chi2_im) - 1.0).abs() < 1e-9,
        "{} vs {}",
        nn.chi2,
        chi2_re + chi2_im
    );
    assert_eq!(nn.dof, 20 - 2);
    // B > 0, H < 0: the best face holds H (= M1), though holding B also
    // leaves a feasible (worse) fit and is tried first.
    let pts = imaginary_line(0.5, -1.0);
    let nn = fit_nn(&pts);
    assert_eq!(nn.held_at_zero, [false, false, false, true]);
    let m1 = nested(ImpedanceModel::M1, &pts);
    assert!((nn.params.b_nm_s_per_rad - m1.params.b_nm_s_per_rad).abs() < 1e-9);
    // B < 0, H > 0: holds B (= M2).
    let pts = imaginary_line(-0.2, 5.0);
    let nn = fit_nn(&pts);
    assert_eq!(nn.held_at_zero, [false, true, false, false]);
    let m2 = nested(ImpedanceModel::M2, &pts);
    assert!((nn.params.h_nm_per_rad - m2.params.h_nm_per_rad).abs() < 1e-9);
    assert_eq!(nn.params.b_nm_s_per_rad, 0.0);
}
