//! The identifier on synthetic streams from a known human: FRF points, M2
//! refits, F-tests, the power law and eq. f's recommendation; faults and
//! broadband windows.

use exo_identifier::{Event, Identifier, IdentifierSettings};
use exo_impedance::{fractional_order, Complex64, DynamicStiffness, PowerLaw, StiffnessRange};
use exo_messages::{status, ActuatorCommand, ProtocolState, SensorSample};

const M_E: f64 = 0.1 + 4.5 * 0.45 * 0.45;
const RATE: f64 = 1000.0;

struct Stream {
    id: Identifier,
    events: Vec<Event>,
    tick: u64,
    seq: u64,
    noise: u64,
}

impl Stream {
    fn new() -> Self {
        Stream {
            id: Identifier::new(IdentifierSettings::default()),
            events: Vec::new(),
            tick: 0,
            seq: 0,
            noise: 0x1234_5678_9abc_def1,
        }
    }

    fn gauss(&mut self) -> f64 {
        let mut u = || {
            self.noise ^= self.noise << 13;
            self.noise ^= self.noise >> 7;
            self.noise ^= self.noise << 17;
            ((self.noise >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (a, b) = (u(), u());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }

    fn protocol(&mut self, experiment: u32, period: u32, phase: u32, omega: f64, alpha: f64) {
        let p = ProtocolState {
            experiment,
            period,
            phase,
            omega,
            amplitude: 2.0,
            alpha,
            load_kg: 4.5,
            stamp_ns: self.tick * 1_000_000,
            ..Default::default()
        };
        self.id.on_protocol(&p, &mut self.events);
    }
}

/// Feeds one sine period (2 s settling, 5 s analysis, 1 s rest) of a human
/// `human` seen through `M_e/α`.
#[allow(clippy::too_many_arguments)]
fn period(
    st: &mut Stream,
    experiment: u32,
    n: u32,
    omega: f64,
    human: DynamicStiffness,
    alpha: f64,
    noise: f64,
    fault_at: Option<usize>,
) {
    let s_h = human.response(omega);
    let s_hea = s_h - M_E / alpha * omega * omega;
    let amp = 0.02;
    for (phase, dur) in [(2u32, 2.0), (3, 5.0), (5, 1.0)] {
        st.protocol(experiment, n, phase, omega, alpha);
        for k in 0..(dur * RATE) as usize {
            let t = st.tick as f64 / RATE;
            let x = Complex64::from_polar(amp, omega * t);
            let theta = 0.8 + x.im;
            let tau_g = 16.0 * (theta - 0.8) + 12.0;
            let tau_c = (s_h * x).im + noise * st.gauss();
            let tau_s = (s_hea * x).im + tau_g + 4.0 + noise * st.gauss();
            let stamp = st.tick * 1_000_000;
            let status = if phase == 3 && fault_at == Some(k) {
                status::FT_FAULT
            } else {
                0
            };
            st.id.on_command(&ActuatorCommand {
                seq: st.seq,
                stamp_ns: stamp,
                sensor_seq: st.seq,
                tau_d: tau_s,
                tau_gravity: tau_g,
                tau_bias: 4.0,
                ..Default::default()
            });
            st.id.on_sample(
                &SensorSample {
                    seq: st.seq,
                    stamp_ns: stamp,
                    theta_e: theta,
                    tau_c,
                    tau_s,
                    status,
                    ..Default::default()
                },
                &mut st.events,
            );
            st.tick += 1;
            st.seq += 1;
        }
    }
}

fn experiment(st: &mut Stream, number: u32, k: f64, h: f64, alpha: f64, noise: f64) {
    let human = DynamicStiffness::from_array([0.11, 0.0, k, h]);
    for p in 1..=10u32 {
        let omega = 2.0 * 10f64.powf(0.1 * (p - 1) as f64);
        period(st, number, p, omega, human, alpha, noise, None);
    }
}

#[test]
fn ten_periods_give_ten_points_and_m2_recovers_k_and_h() {
    let mut st = Stream::new();
    experiment(&mut st, 1, 30.0, 12.0, 1.0, 0.01);
    let frf: Vec<_> = st
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Frf(p) => Some(*p),
            _ => None,
        })
        .collect();
    assert_eq!(
        frf.len(),
        10,
        "{:?}",
        st.events
            .iter()
            .filter(|e| matches!(e, Event::Warning(_)))
            .collect::<Vec<_>>()
    );
    let human = DynamicStiffness::from_array([0.11, 0.0, 30.0, 12.0]);
    for p in &frf {
        let truth = human.response(p.omega);
        let got = Complex64::new(p.s_h_re, p.s_h_im);
        assert!(
            (got - truth).norm() < 0.01 * truth.norm(),
            "{} vs {truth}",
            got
        );
        assert!(p.coherence > 0.99);
        assert!(p.noise_rel > 0.0 && p.noise_rel < 0.01);
    }
    let last_m2 = st
        .events
        .iter()
        .rev()
        .find_map(|e| match e {
            Event::Estimate(e) if e.model == 2 => Some(*e),
            _ => None,
        })
        .unwrap();
    assert_eq!(last_m2.n_points, 10);
    assert!((last_m2.k_h / 30.0 - 1.0).abs() < 0.01, "K {}", last_m2.k_h);
    assert!((last_m2.h_h / 12.0 - 1.0).abs() < 0.02, "H {}", last_m2.h_h);
    assert!((last_m2.m_h - 0.11).abs() < 0.01, "M {}", last_m2.m_h);
    assert!(
        last_m2.f_m1_m3 > last_m2.f_critical,
        "F(M1−M3) {} vs critical {}",
        last_m2.f_m1_m3,
        last_m2.f_critical
    );
    assert_eq!(
        last_m2.recommended_f, 0.0,
        "one experiment: no power law yet"
    );
}

#[test]
fn three_experiments_give_the_power_law_and_eq_f() {
    let law = PowerLaw::new(-0.3, 1.1).unwrap();
    let mut st = Stream::new();
    for (n, k, alpha) in [(1, 20.0, 1.0), (4, 45.0, 2.0), (7, 80.0, 4.0)] {
        experiment(
            &mut st,
            n,
            k,
            law.hysteretic_damping(k).unwrap(),
            alpha,
            0.005,
        );
    }
    let last = st
        .events
        .iter()
        .rev()
        .find_map(|e| match e {
            Event::Estimate(e) if e.model == 2 => Some(*e),
            _ => None,
        })
        .unwrap();
    assert!((last.beta0 + 0.3).abs() < 0.02, "β0 {}", last.beta0);
    assert!((last.beta1 - 1.1).abs() < 0.02, "β1 {}", last.beta1);
    let fitted = PowerLaw::new(last.beta0, last.beta1).unwrap();
    let f = fractional_order(fitted, StiffnessRange::new(10.03, 108.33).unwrap(), 10.8).unwrap();
    assert!((last.recommended_f - f.clamp(0.0, 0.9)).abs() < 1e-12);
    assert!(last.recommended_f > 0.0);
}

#[test]
fn a_fault_discards_only_its_window() {
    let mut st = Stream::new();
    let human = DynamicStiffness::from_array([0.11, 0.0, 30.0, 12.0]);
    period(&mut st, 1, 1, 2.0, human, 1.0, 0.0, None);
    period(&mut st, 1, 2, 2.5, human, 1.0, 0.0, Some(1234));
    period(&mut st, 1, 3, 3.2, human, 1.0, 0.0, None);
    let frf: Vec<u32> = st
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Frf(p) => Some(p.period),
            _ => None,
        })
        .collect();
    assert_eq!(frf, vec![1, 3]);
    assert!(st.events.iter().any(
        |e| matches!(e, Event::Warning(w) if w.contains("period 2") && w.contains("discarded"))
    ));
}

#[test]
fn a_broadband_window_gives_several_points() {
    // Random perturbation, like the ankle recording: θ is white noise
    // low-passed twice at 60 rad/s; the human is an M1 (a causal system a
    // time series can carry exactly): τ_c = K θ + B θ̇ + M θ̈, derivatives by
    // central differences (exact to (ωh)²/6 < 0.1 % up to 60 rad/s).
    let (k, b, m) = (30.0, 0.4, 0.11);
    let human = DynamicStiffness::from_array([m, b, k, 0.0]);
    let mut st = Stream::new();
    let n = 60_000;
    let a = (-60.0 / RATE).exp();
    let (mut f1, mut f2) = (0.0, 0.0);
    let mut theta = Vec::with_capacity(n + 2);
    for _ in 0..n + 2 {
        f1 = a * f1 + (1.0 - a) * st.gauss();
        f2 = a * f2 + (1.0 - a) * f1;
        theta.push(0.05 * f2);
    }
    st.protocol(2, 1, 2, 0.0, 1.0);
    st.protocol(2, 1, 3, 0.0, 1.0);
    for j in 1..=n {
        let (x0, x1, x2) = (theta[j - 1], theta[j], theta[j + 1]);
        let v = (x2 - x0) * RATE / 2.0;
        let acc = (x2 - 2.0 * x1 + x0) * RATE * RATE;
        let tau_c = k * x1 + b * v + m * acc;
        let tau_s = tau_c + M_E * acc;
        let stamp = st.tick * 1_000_000;
        st.id.on_command(&ActuatorCommand {
            stamp_ns: stamp,
            tau_d: tau_s,
            ..Default::default()
        });
        st.id.on_sample(
            &SensorSample {
                seq: st.seq,
                stamp_ns: stamp,
                theta_e: 0.8 + x1,
                tau_c,
                tau_s,
                ..Default::default()
            },
            &mut st.events,
        );
        st.tick += 1;
        st.seq += 1;
    }
    st.protocol(2, 1, 5, 0.0, 1.0);
    st.id.on_sample(
        &SensorSample {
            stamp_ns: st.tick * 1_000_000,
            ..Default::default()
        },
        &mut st.events,
    );
    let pts: Vec<_> = st
        .events
        .iter()
        .filter_map(|e| match e {
            Event::Frf(p) => Some(*p),
            _ => None,
        })
        .collect();
    assert!(pts.len() >= 10, "{} points; {:?}", pts.len(), st.events);
    for p in &pts {
        let truth = human.response(p.omega);
        let got = Complex64::new(p.s_h_re, p.s_h_im);
        // Noise-free signals, but finite random segments leak between bins
        // (coherence a little below 1): the error must lie within three of
        // the reported standard errors (plus 1 %).
        assert!(
            (got - truth).norm() < (3.0 * p.noise_rel + 0.01) * truth.norm(),
            "ω {}: {got} vs {truth}, noise_rel {}",
            p.omega,
            p.noise_rel
        );
        assert!(p.coherence > 0.8, "{}", p.coherence);
        let hea = Complex64::new(p.s_hea_re, p.s_hea_im);
        let truth_hea = truth - M_E * p.omega * p.omega;
        // Leakage between neighbouring bins matters where S_h-e/α changes
        // fast from one bin to the next (near the coupled resonance, ~5 rad/s,
        // it changes by 70 % per bin): allowed 5 % plus a tenth of the change
        // per bin, |dS/dω|·Δω = 2(M + M_e)ω·Δω; checked where |S_h-e/α| ≥ |S_h|.
        let per_bin = 2.0 * (m + M_E) * p.omega * std::f64::consts::TAU / 4.096;
        if truth_hea.norm() >= truth.norm() {
            assert!(
                (hea - truth_hea).norm() < 0.05 * truth_hea.norm() + 0.1 * per_bin,
                "ω {}: S_hea {hea} vs {truth_hea}",
                p.omega
            );
        }
    }
}
