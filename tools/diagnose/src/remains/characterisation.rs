//! [`characterise`]: what remains of a model's misfit per transfer function
//! (its dependence on the amplitude, the operating point, the frequency
//! band, the time within a window and within an experiment, and the
//! harmonics), and the frequency bands' residuals.

use std::collections::BTreeMap;

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::data::Dataset;
use crate::model::Physics;
use crate::signatures::HarmonicContent;

use super::regress::{last_coefficient, matrix, rows, t_p, trend, weighted_mean, wls, Row};
use super::time::{over_time, within_window};
use super::words::{angle_words, band_words, time_words, within_words, words_of};
use super::{
    AmplitudeDependence, AngleAmplitudeDependence, BandResidual, Estimate,
    OperatingPointDependence, Remains,
};

/// Characterises what remains of `phys`'s misfit per supported transfer
/// function; `level` is the family-wise level of the tests.
pub fn characterise(d: &Dataset, phys: &Physics, level: f64) -> Vec<Remains> {
    let ntests = (2 * d.supported.len()).max(1) as f64;
    let alpha = level / ntests;
    // The amplitude groups: windows above the lowest single-sine amplitude.
    let amps: Vec<f64> = d
        .conditions
        .iter()
        .map(|c| c.amplitude_nm)
        .filter(|a| *a > 0.0)
        .collect();
    let lo = amps.iter().copied().fold(f64::INFINITY, f64::min);
    let two_amplitudes = amps.iter().any(|a| *a > lo * 1.05);
    let high = |r: &Row| d.conditions[r.o.window].amplitude_nm > lo * 1.05;
    let content = crate::signatures::harmonics(d, level);
    let mut out = Vec::new();
    for &tf in &d.supported {
        let rs = rows(d, phys, tf);
        let parts = if tf.is_dynamic() { 2 } else { 1 };
        let chi: f64 = rs
            .iter()
            .map(|r| {
                (0..parts)
                    .map(|k| (r.rel[k] / r.sd[k]).powi(2))
                    .sum::<f64>()
            })
            .sum::<f64>()
            / (parts * rs.len()).max(1) as f64;
        // Something remains in this transfer function at all: its χ²
        // against the measured noise rejects (same level division). Only
        // then is a dependence of the residual reported as a finding.
        let ncomp = (parts * rs.len()) as f64;
        let misfit = ncomp > 0.0
            && statrs::distribution::ChiSquared::new(ncomp)
                .is_ok_and(|c| c.sf(chi * ncomp) < alpha);
        let mut by_exp: BTreeMap<u32, usize> = BTreeMap::new();
        for r in &rs {
            *by_exp
                .entry(d.conditions[r.o.window].experiment)
                .or_default() += 1;
        }
        let exps: Vec<u32> = by_exp.keys().copied().collect();
        let exp_of = |r: &Row| d.conditions[r.o.window].experiment;

        // Amplitude: per-experiment trends plus a shared step.
        let amplitude = if two_amplitudes {
            let mut cols = Vec::new();
            for &e in &exps {
                let sel = |r: &Row| exp_of(r) == e;
                if tf.is_dynamic() {
                    cols.extend(trend(&rs, &sel));
                } else {
                    cols.push(rs.iter().map(|r| f64::from(u8::from(sel(r)))).collect());
                }
            }
            cols.push(rs.iter().map(|r| f64::from(u8::from(high(r)))).collect());
            let x = matrix(&cols);
            let fit_part = |k: usize| last_coefficient(&rs, &x, k);
            let ip = fit_part(0);
            let q = if tf.is_dynamic() { fit_part(1) } else { None };
            ip.map(|in_phase| {
                let mean = |h: bool, f: &dyn Fn(&Row) -> f64| {
                    let v: Vec<f64> = rs.iter().filter(|r| high(r) == h).map(f).collect();
                    v.iter().sum::<f64>() / v.len().max(1) as f64
                };
                let amp = |r: &Row| d.conditions[r.o.window].amplitude_nm;
                let th = |r: &Row| d.conditions[r.o.window].theta_amp_rad;
                let significant = misfit
                    && (in_phase.p_value < alpha || q.is_some_and(|q: Estimate| q.p_value < alpha));
                AmplitudeDependence {
                    amplitudes_nm: [mean(false, &amp), mean(true, &amp)],
                    theta_amp_rad: [mean(false, &th), mean(true, &th)],
                    in_phase,
                    quadrature: q,
                    significant,
                }
            })
        } else {
            None
        };

        // Angle amplitude: per-experiment trends plus a shared slope in A².
        // Only when the angle amplitude varies within an experiment (single
        // sines at several frequencies): a broadband window has one
        // amplitude for all its bands, which the per-experiment trend
        // already holds.
        let varies = exps.iter().any(|&e| {
            let mut a: Vec<i64> = rs
                .iter()
                .filter(|r| exp_of(r) == e)
                .map(|r| (d.conditions[r.o.window].theta_amp_rad * 1e6).round() as i64)
                .collect();
            a.sort_unstable();
            a.dedup();
            a.len() >= 3
        });
        let angle_amplitude = if tf.is_dynamic() && varies {
            let th = |r: &Row| d.conditions[r.o.window].theta_amp_rad;
            let mut cols = Vec::new();
            for &e in &exps {
                cols.extend(trend(&rs, &|r: &Row| exp_of(r) == e));
            }
            cols.push(rs.iter().map(|r| (th(r) / 0.1).powi(2)).collect());
            let x = matrix(&cols);
            let fit_part = |k: usize| last_coefficient(&rs, &x, k);
            fit_part(0).map(|in_phase| {
                let q = fit_part(1);
                let lo = rs.iter().map(th).fold(f64::INFINITY, f64::min);
                let hi = rs.iter().map(th).fold(0.0, f64::max);
                AngleAmplitudeDependence {
                    theta_amp_rad: [lo, hi],
                    // The in-phase part only: a spring's describing function
                    // is real; a quadrature slope is where the arm's
                    // resonance (the angle amplitude's peak) confounds it
                    // most (measured: a linear exoskeleton spring gives a
                    // quadrature slope of −2.65 ± 0.13 % in S_h-e).
                    significant: misfit && in_phase.p_value < alpha,
                    in_phase,
                    quadrature: q,
                }
            })
        } else {
            None
        };

        // Operating point: one shared trend plus per-experiment offsets.
        let operating_point = if exps.len() >= 2 {
            let all = |_: &Row| true;
            let base_cols = if tf.is_dynamic() {
                trend(&rs, &all)
            } else {
                vec![vec![1.0; rs.len()]]
            };
            let mut cols = base_cols.clone();
            for &e in &exps[1..] {
                cols.push(
                    rs.iter()
                        .map(|r| f64::from(u8::from(exp_of(r) == e)))
                        .collect(),
                );
            }
            let (x0, x1) = (matrix(&base_cols), matrix(&cols));
            let q = exps.len() - 1;
            let test = |k: usize| -> Option<(Vec<f64>, Vec<f64>, f64, f64)> {
                let y: Vec<f64> = rs.iter().map(|r| r.rel[k]).collect();
                let sd: Vec<f64> = rs.iter().map(|r| r.sd[k]).collect();
                let (_, _, rss0, _) = wls(&x0, &y, &sd)?;
                let (b, se, rss1, dof) = wls(&x1, &y, &sd)?;
                // As the standard errors: the residual variance, at least the noise.
                let f = ((rss0 - rss1) / q as f64) / (rss1 / dof).max(1.0);
                let p = FisherSnedecor::new(q as f64, dof).map_or(f64::NAN, |d| d.sf(f.max(0.0)));
                let off = b.len() - q;
                Some((b[off..].to_vec(), se[off..].to_vec(), p, dof))
            };
            let ip = test(0);
            let qd = if tf.is_dynamic() { test(1) } else { None };
            ip.map(|(b, se, p, dof)| {
                let bias = |e: u32| {
                    d.conditions
                        .iter()
                        .find(|c| c.experiment == e)
                        .map_or(f64::NAN, |c| c.bias_nm)
                };
                let mut per = vec![(
                    exps[0],
                    bias(exps[0]),
                    Estimate {
                        value: 0.0,
                        std_error: 0.0,
                        p_value: 1.0,
                    },
                    qd.as_ref().map(|_| Estimate {
                        value: 0.0,
                        std_error: 0.0,
                        p_value: 1.0,
                    }),
                )];
                for (i, &e) in exps[1..].iter().enumerate() {
                    per.push((
                        e,
                        bias(e),
                        Estimate {
                            value: b[i],
                            std_error: se[i],
                            p_value: t_p(b[i], se[i], dof),
                        },
                        qd.as_ref().map(|(bq, sq, _, _)| Estimate {
                            value: bq[i],
                            std_error: sq[i],
                            p_value: t_p(bq[i], sq[i], dof),
                        }),
                    ));
                }
                let pq = qd.as_ref().map_or(f64::NAN, |x| x.2);
                OperatingPointDependence {
                    per_experiment: per,
                    p_value: [p, pq],
                    significant: misfit && (p < alpha || pq < alpha),
                }
            })
        } else {
            None
        };
        let bands = if tf.is_dynamic() {
            bands(&rs)
        } else {
            Vec::new()
        };
        let within_window = within_window(d, tf, alpha);
        let over_time = over_time(d, &rs, tf, &exps, alpha, misfit);
        let harmonics: Vec<HarmonicContent> =
            content.iter().filter(|h| h.tf == tf).cloned().collect();
        let mut lines = words_of(
            tf,
            chi,
            &amplitude,
            &operating_point,
            two_amplitudes,
            misfit,
        );
        if let Some(a) = &angle_amplitude {
            lines.insert(1, (angle_words(tf, a), a.significant));
        }
        if !bands.is_empty() {
            lines.push(band_words(tf, &bands, misfit));
        }
        if let Some(w) = &within_window {
            lines.push(within_words(tf, w));
        }
        if let Some(o) = &over_time {
            lines.push(time_words(tf, o));
        }
        // As every other dependence: a finding only where the transfer
        // function's own residual is beyond the noise (gravity's sin θ
        // makes even harmonics at large angle amplitudes that the
        // linearised model, within the noise at ω, need not describe).
        lines.extend(
            crate::signatures::words(tf, &harmonics.iter().collect::<Vec<_>>())
                .into_iter()
                .map(|(w, f)| (w, f && misfit)),
        );
        let words: Vec<String> = lines.iter().map(|l| l.0.clone()).collect();
        let findings: Vec<String> = lines.into_iter().filter(|l| l.1).map(|l| l.0).collect();
        out.push(Remains {
            tf,
            chi2_per_component: chi,
            amplitude,
            angle_amplitude,
            operating_point,
            bands,
            within_window,
            over_time,
            harmonics,
            words,
            findings,
        });
    }
    out
}

/// The residual per frequency band, in order of frequency.
fn bands(rs: &[Row]) -> Vec<BandResidual> {
    let mut by: Vec<(&'static str, f64, Vec<&Row>)> = Vec::new();
    for r in rs {
        let b = crate::band::band_of(r.o.omega_rad_s);
        match by.iter_mut().find(|x| x.0 == b) {
            Some(x) => {
                x.1 = x.1.min(r.o.omega_rad_s);
                x.2.push(r);
            }
            None => by.push((b, r.o.omega_rad_s, vec![r])),
        }
    }
    by.sort_by(|a, b| a.1.total_cmp(&b.1));
    by.into_iter()
        .map(|(band, _, v)| {
            let part = |k: usize| {
                let y: Vec<f64> = v.iter().map(|r| r.rel[k]).collect();
                let sd: Vec<f64> = v.iter().map(|r| r.sd[k]).collect();
                weighted_mean(&y, &sd)
            };
            let chi = v
                .iter()
                .map(|r| (0..2).map(|k| (r.rel[k] / r.sd[k]).powi(2)).sum::<f64>())
                .sum::<f64>()
                / (2 * v.len()).max(1) as f64;
            BandResidual {
                band,
                points: v.len(),
                chi2_per_component: chi,
                in_phase: part(0),
                quadrature: Some(part(1)),
            }
        })
        .collect()
}
