//! The reduction itself ([`reduce`]): each recording's analysis windows,
//! found in its protocol topic, their samples, conditions and
//! observations.

use std::collections::BTreeMap;

use exo_recording::Recording;

use super::broadband::broadband;
use super::condition::Condition;
use super::dataset::{Dataset, WindowSignals};
use super::sine::single_sine;
use super::transient::pool_transients;
use super::{Reduction, Tf};

/// An analysis window found in the protocol topic.
struct Span {
    experiment: u32,
    period: u32,
    start_ns: u64,
    end_ns: u64,
    omega: f64,
    load_kg: f64,
    bias_nm: f64,
    alpha: f64,
    amplitude: f64,
}

fn spans(r: &Recording) -> Vec<Span> {
    let stream_end = r.sensor.last().map(|s| s.stamp_ns + 1);
    exo_analysis::analysis_windows(&r.protocol)
        .into_iter()
        .filter_map(|w| {
            let p = w.state;
            Some(Span {
                experiment: p.experiment,
                period: p.period,
                start_ns: w.start_ns,
                end_ns: w.end_ns.or(stream_end)?,
                omega: p.omega,
                load_kg: p.load_kg,
                bias_nm: p.bias_nm,
                alpha: p.alpha,
                amplitude: p.amplitude,
            })
        })
        .collect()
}

/// Reduces recordings to observations. Never fails on user data: what
/// cannot be used is named in [`Dataset::notes`].
pub fn reduce(recordings: &[Recording], s: &Reduction) -> Dataset {
    let mut d = Dataset::default();
    // Recordings of different subjects keep their experiments apart: the
    // i-th subject's experiment n becomes 100·i + n (i from 1).
    let mut subjects: Vec<String> = Vec::new();
    for r in recordings {
        let s = r.meta("subject").unwrap_or(&r.source).to_string();
        if !subjects.contains(&s) {
            subjects.push(s);
        }
    }
    if subjects.len() > 1 {
        d.notes.push(format!(
            "{} subjects: experiment n of subject i is numbered 100·i + n ({})",
            subjects.len(),
            subjects
                .iter()
                .enumerate()
                .map(|(i, s)| format!("{}: {s}", i + 1))
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    for r in recordings {
        let subject = r.meta("subject").unwrap_or(&r.source);
        let key_offset = if subjects.len() > 1 {
            100 * (1 + subjects.iter().position(|s| s == subject).unwrap_or(0) as u32)
        } else {
            0
        };
        d.sources.push(r.source.clone());
        for w in &r.warnings {
            d.notes.push(w.clone());
        }
        if r.protocol.is_empty() {
            d.notes.push(format!(
                "{}: topic exo/protocol is missing or empty: no analysis windows",
                r.source
            ));
        }
        if r.sensor.is_empty() {
            d.notes.push(format!(
                "{}: topic exo/sensor is missing or empty",
                r.source
            ));
            continue;
        }
        let human_only = r.meta("fit_target") == Some("human");
        // Commands by the sample they answer.
        let mut answer: BTreeMap<u64, (f64, f64)> = BTreeMap::new();
        for c in &r.command {
            answer.insert(c.sensor_seq, (c.tau_d, c.tau_gravity));
        }
        if r.command.is_empty() && !human_only {
            d.notes.push(format!(
                "{}: topic exo/command is missing: only S_h (τ_c/θ_e) is compared",
                r.source
            ));
        }
        let spans = spans(r);
        if spans.is_empty() && !r.protocol.is_empty() {
            d.notes.push(format!(
                "{}: the protocol has no analysis phase (phase 3): no windows",
                r.source
            ));
        }
        for sp in &spans {
            let what = format!(
                "{}: experiment {} period {}",
                r.source, sp.experiment, sp.period
            );
            let lo = r.sensor.partition_point(|x| x.stamp_ns < sp.start_ns);
            let hi = r.sensor.partition_point(|x| x.stamp_ns < sp.end_ns);
            let samples = &r.sensor[lo..hi];
            if samples.len() < 16 {
                d.notes
                    .push(format!("{what}: {} samples, window skipped", samples.len()));
                continue;
            }
            let t0 = samples[0].stamp_ns;
            let mut sig = WindowSignals {
                omega_rad_s: sp.omega,
                ..Default::default()
            };
            let mut tau_d = Vec::with_capacity(samples.len());
            let mut tau_s_raw = Vec::with_capacity(samples.len());
            let mut tau_g = Vec::with_capacity(samples.len());
            let mut answered = 0usize;
            let mut bad = 0usize;
            for x in samples {
                if !(x.theta_e.is_finite() && x.tau_c.is_finite() && x.tau_s.is_finite()) {
                    bad += 1;
                    continue;
                }
                let (td, tg) = match answer.get(&x.seq) {
                    Some(&(td, tg)) if td.is_finite() && tg.is_finite() => {
                        answered += 1;
                        (td, tg)
                    }
                    _ => (f64::NAN, 0.0),
                };
                sig.t_s.push((x.stamp_ns - t0) as f64 * 1e-9);
                sig.theta_rad.push(x.theta_e);
                sig.tau_c_nm.push(x.tau_c);
                sig.tau_s_net_nm.push(x.tau_s - tg);
                tau_s_raw.push(x.tau_s);
                tau_d.push(td);
                sig.tau_s_nm.push(x.tau_s);
                sig.tau_d_nm.push(td);
                tau_g.push(tg);
            }
            if bad > 0 {
                d.notes.push(format!(
                    "{what}: {bad} samples with non-finite values left out"
                ));
            }
            let n = sig.t_s.len();
            if n < 16 {
                continue;
            }
            let span_s = sig.t_s[n - 1];
            let dt = if span_s > 0.0 {
                span_s / (n - 1) as f64
            } else {
                1e-3
            };
            let has_command = answered * 10 >= n * 9 && !human_only;
            // The window's whole cycles (all of a broadband window): the
            // means the plant is linearised about. A partial cycle's mean is
            // biased by the sine it holds (at 2 rad/s a 5 s window is one
            // cycle and 0.6 of another: with experiment 1's 0.1 rad that
            // is about 1°, which moves gravity's slope `m g l cos θ₀`).
            let whole = if sp.omega > 0.0 {
                exo_impedance::frf::whole_cycles(&sig.t_s, sp.omega).unwrap_or(n)
            } else {
                n
            }
            .max(1);
            let theta0 = sig.theta_rad[..whole].iter().sum::<f64>() / whole as f64;
            let cond_index = d.conditions.len();
            let mut cond = Condition {
                experiment: sp.experiment + key_offset,
                period: sp.period,
                load_kg: sp.load_kg,
                bias_nm: sp.bias_nm,
                alpha: sp.alpha,
                amplitude_nm: sp.amplitude,
                theta0_rad: theta0,
                theta_amp_rad: 0.0,
                sin_theta_mean: theta0.sin(),
                tau_s_mean_nm: f64::NAN,
                tau_c_mean_nm: sig.tau_c_nm[..whole].iter().sum::<f64>() / whole as f64,
                command: None,
                gravity: None,
                sample_period_s: dt,
                start_s: t0.saturating_sub(r.sensor[0].stamp_ns) as f64 * 1e-9,
                elapsed_s: 0.0,
            };
            let before = d.observations.len();
            if sp.omega > 0.0 {
                single_sine(
                    &what,
                    &sig,
                    &tau_d,
                    &tau_s_raw,
                    &tau_g,
                    has_command,
                    cond_index,
                    s,
                    &mut cond,
                    &mut d,
                );
            } else {
                broadband(
                    &what,
                    &sig,
                    &tau_d,
                    &tau_s_raw,
                    &tau_g,
                    has_command,
                    cond_index,
                    s,
                    &mut cond,
                    &mut d,
                );
            }
            if d.observations.len() > before {
                d.conditions.push(cond);
                d.signals.push(sig);
            }
        }
    }
    // Each window's time within its experiment (from the experiment's
    // first window; a recording's experiments keep their own clocks).
    let mut first: BTreeMap<u32, f64> = BTreeMap::new();
    for c in &d.conditions {
        let f = first.entry(c.experiment).or_insert(c.start_s);
        *f = f.min(c.start_s);
    }
    for c in &mut d.conditions {
        c.elapsed_s = c.start_s - first[&c.experiment];
    }
    pool_transients(&mut d);
    let mut sup: Vec<Tf> = d.observations.iter().map(|o| o.tf).collect();
    sup.sort_unstable();
    sup.dedup();
    d.supported = sup;
    d
}
