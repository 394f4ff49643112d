//! Benchmarks of the science core (not timed tests). Each group measures a
//! baseline side by side in the same run.
//!
//! - `fit_90_experiments`: M1, M2 and M3 fitted to 90 experiments of 10 FRF
//!   points with F^sub, F^exp and F^all; baseline: the same 270 least-squares
//!   problems solved the textbook way, with nalgebra's dense SVD on the
//!   stacked 20 × p design matrix (no F-tests).
//! - `controller_step`: one step of the 5-section discrete lag cascade;
//!   baseline: one first-order section alone.
//!
//! Run: `cargo bench -p exo-impedance --bench science`.

use criterion::{criterion_group, criterion_main, Criterion};
use exo_impedance::*;
use nalgebra::{DMatrix, DVector};
use std::hint::black_box;

fn dataset() -> Vec<Vec<FrfPoint>> {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..90)
        .map(|e| {
            let truth = DynamicStiffness {
                m_kg_m2: 0.11 + 1.01 / [1.0, 2.0, 4.0][e % 3],
                b_nm_s_per_rad: 0.1,
                k_nm_per_rad: 10.0 + e as f64,
                h_nm_per_rad: 4.0 + 0.3 * e as f64,
            };
            (0..10)
                .map(|i| {
                    let w = 2.0 * 10f64.powf(0.1 * i as f64);
                    let s = truth.response(w);
                    FrfPoint {
                        omega_rad_s: w,
                        value: s + Complex64::new(uniform(), uniform()),
                        std_dev_nm_per_rad: 0.0,
                    }
                })
                .collect()
        })
        .collect()
}

fn fit_and_test(data: &[Vec<FrfPoint>]) -> f64 {
    let fits: Vec<ModelComparison> = data
        .iter()
        .map(|pts| fit_all(pts, FitTarget::Human).expect("fit"))
        .collect();
    let mut acc = 0.0;
    for subject in fits.chunks(9) {
        acc += paper_f_tests(subject, 0.05)
            .expect("F sub")
            .m1_vs_m3
            .statistic;
    }
    for e in 0..9 {
        let group: Vec<ModelComparison> = fits.iter().skip(e).step_by(9).copied().collect();
        acc += paper_f_tests(&group, 0.05)
            .expect("F exp")
            .m1_vs_m3
            .statistic;
    }
    acc + paper_f_tests(&fits, 0.05)
        .expect("F all")
        .m1_vs_m3
        .statistic
}

fn dense_svd_baseline(data: &[Vec<FrfPoint>]) -> f64 {
    let mut acc = 0.0;
    for pts in data {
        for model in ImpedanceModel::ALL {
            let terms = model.terms();
            let mut a = DMatrix::<f64>::zeros(2 * pts.len(), terms.len());
            let mut y = DVector::<f64>::zeros(2 * pts.len());
            for (k, p) in pts.iter().enumerate() {
                for (j, t) in terms.iter().enumerate() {
                    let (re, im) = t.regressor(p.omega_rad_s);
                    a[(2 * k, j)] = re;
                    a[(2 * k + 1, j)] = im;
                }
                y[2 * k] = p.value.re;
                y[2 * k + 1] = p.value.im;
            }
            let x = a.svd(true, true).solve(&y, 1e-12).expect("svd solve");
            acc += x[0];
        }
    }
    acc
}

fn fits(c: &mut Criterion) {
    let data = dataset();
    let mut g = c.benchmark_group("fit_90_experiments");
    g.bench_function("exo_fit_all_plus_f_tests", |b| {
        b.iter(|| fit_and_test(black_box(&data)))
    });
    g.bench_function("baseline_dense_svd_fits_only", |b| {
        b.iter(|| dense_svd_baseline(black_box(&data)))
    });
    g.finish();
}

fn controller_step(c: &mut Criterion) {
    let filter = LagFilter::new(5, 1.0, 10f64.sqrt(), 0.6, 3.9).expect("filter");
    let mut cascade = filter.discretize(1000.0).expect("discretize");
    let single = LagFilter::new(1, 1.0, 10f64.sqrt(), 0.6, 3.9).expect("filter");
    let mut one = single.discretize(1000.0).expect("discretize");
    let mut g = c.benchmark_group("controller_step");
    let mut x = 0.0f64;
    g.bench_function("lag_cascade_5_sections", |b| {
        b.iter(|| {
            x += 1e-3;
            cascade.step(black_box(x.sin()))
        })
    });
    g.bench_function("baseline_single_section", |b| {
        b.iter(|| {
            x += 1e-3;
            one.step(black_box(x.sin()))
        })
    });
    g.finish();
}

criterion_group!(benches, fits, controller_step);
criterion_main!(benches);
