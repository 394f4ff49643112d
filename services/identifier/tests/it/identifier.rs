//! The identifier on synthetic streams from a known human, with protocol
//! states as the controller sends them (every period: 5 s bias ramp-in,
//! 5 s settling, 5 s analysis, 5 s ramp-out, rest): FRF points, M1–M3
//! refits, F-tests, the power law and eq. f's recommendation; faults,
//! missing commands, late protocol states and broadband windows.
//!
//! This file holds the synthetic stream and the fits (sine periods, three
//! experiments, a broadband window); what the identifier discards, warns
//! about or refuses (faults, missing commands, late protocol states, bad
//! settings) is `identifier_inputs.rs`'s, on the same stream.

use std::collections::VecDeque;

use exo_identifier::{
    Event, FitSource, Identifier, IdentifierSettings, KRangeSource, F_TEST_LEVEL,
};
use exo_impedance::{
    f_critical, fractional_order, Complex64, DynamicStiffness, PowerLaw, StiffnessRange,
};
use exo_messages::{
    ActuatorCommand, ControlMode, FrfPoint, ImpedanceEstimate, ProtocolPhase, ProtocolState,
    SensorSample,
};

/// `M_e` of the default settings with the 4.5 kg load: 0.1 + 4.5 · 0.45² kg·m².
pub(crate) const M_E: f64 = 0.1 + 4.5 * 0.45 * 0.45;
const LOAD_KG: f64 = 4.5;
const RATE: f64 = 1000.0;
/// Excitation amplitude of θ_e (rad).
const AMP_RAD: f64 = 0.02;
/// Gravity of arm and load about the joint, `τ_g = 20 sin θ` (Nm): its
/// slope at the posture, 20 cos 0.8 ≈ 13.9 Nm/rad, is what S_h-e/α would
/// gain if gravity stayed in τ_s.
pub(crate) const GRAVITY_NM: f64 = 20.0;
pub(crate) const POSTURE_RAD: f64 = 0.8;
/// The paper's frequencies, 2 · 10^(0.1 k) rad/s, k = 0…9.
pub(crate) fn paper_omega(period: u32) -> f64 {
    2.0 * 10f64.powf(0.1 * (period - 1) as f64)
}

/// The SEA's torque tracking in the synthetic plant, `τ_s/τ_d = 1/(1 + 0.01 jω)`.
fn sea(omega: f64) -> Complex64 {
    1.0 / Complex64::new(1.0, 0.01 * omega)
}

/// How a sink receives protocol states.
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Delivery {
    /// Every tick, before the tick's sample (as the brief's controller).
    EveryTick,
    /// Only when (experiment, period, phase) changes, `delay` ticks after
    /// the tick's sample.
    OnChange { delay: u64 },
}

pub(crate) struct Sink {
    id: Identifier,
    events: Vec<Event>,
    delivery: Delivery,
    queue: VecDeque<(u64, ProtocolState)>,
    last_key: Option<(u32, u32, Option<ProtocolPhase>)>,
    commands: bool,
}

impl Sink {
    pub(crate) fn frf(&self) -> Vec<FrfPoint> {
        self.events
            .iter()
            .filter_map(|e| match e {
                Event::Frf(p) => Some(*p),
                _ => None,
            })
            .collect()
    }
    pub(crate) fn estimates(&self) -> Vec<ImpedanceEstimate> {
        self.events
            .iter()
            .filter_map(|e| match e {
                Event::Estimate(e) => Some(*e),
                _ => None,
            })
            .collect()
    }
    pub(crate) fn warnings(&self) -> Vec<&str> {
        self.events
            .iter()
            .filter_map(|e| match e {
                Event::Warning(w) | Event::RefitNote(w) => Some(w.as_str()),
                _ => None,
            })
            .collect()
    }
    fn last_estimate(&self, model: u32) -> ImpedanceEstimate {
        *self
            .estimates()
            .iter()
            .rev()
            .find(|e| e.model == model)
            .unwrap()
    }
}

/// A synthetic run fed to several identifiers at once.
pub(crate) struct Stream {
    pub(crate) sinks: Vec<Sink>,
    tick: u64,
    noise: u64,
}

/// What a period's analysis window gets wrong on purpose.
#[derive(Clone, Copy, Default)]
pub(crate) struct Faults {
    /// `(phase, tick within the phase, status bits)` of one sample.
    pub(crate) status: Option<(ProtocolPhase, usize, u32)>,
    /// Tick within the analysis phase whose τ_c is NaN.
    pub(crate) nan_at: Option<usize>,
    /// `(phase, tick within the phase, mode)` of one command.
    pub(crate) mode: Option<(ProtocolPhase, usize, ControlMode)>,
}

impl Stream {
    pub(crate) fn new() -> Self {
        Stream {
            sinks: Vec::new(),
            tick: 0,
            noise: 0x1234_5678_9abc_def1,
        }
    }

    pub(crate) fn with(
        mut self,
        s: IdentifierSettings,
        delivery: Delivery,
        commands: bool,
    ) -> Self {
        self.sinks.push(Sink {
            id: Identifier::try_new(s).unwrap(),
            events: Vec::new(),
            delivery,
            queue: VecDeque::new(),
            last_key: None,
            commands,
        });
        self
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

    /// One tick: protocol state `p`, then command and sample (per sink's delivery).
    fn tick(&mut self, p: ProtocolState, c: ActuatorCommand, s: SensorSample) {
        let tick = self.tick;
        for sink in &mut self.sinks {
            let key = (p.experiment, p.period, p.protocol_phase());
            match sink.delivery {
                Delivery::EveryTick => sink.id.on_protocol(&p, &mut sink.events),
                Delivery::OnChange { delay } => {
                    if sink.last_key != Some(key) {
                        sink.queue.push_back((tick + delay, p));
                    }
                }
            }
            sink.last_key = Some(key);
            if sink.commands {
                sink.id.on_command(&c);
            }
            sink.id.on_sample(&s, &mut sink.events);
            while sink.queue.front().is_some_and(|(at, _)| *at <= tick) {
                let (_, q) = sink.queue.pop_front().unwrap();
                sink.id.on_protocol(&q, &mut sink.events);
            }
        }
        self.tick += 1;
    }

    fn state(
        &self,
        experiment: u32,
        period: u32,
        phase: ProtocolPhase,
        omega: f64,
        alpha: f64,
    ) -> ProtocolState {
        ProtocolState {
            experiment,
            period,
            phase: phase.as_u32(),
            omega,
            amplitude: 2.0,
            alpha,
            load_kg: LOAD_KG,
            bias_nm: 4.0,
            stamp_ns: self.tick * 1_000_000,
            ..Default::default()
        }
    }

    /// One protocol period of a human `s_h(ω)` seen through `M_e/α`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn period(
        &mut self,
        experiment: u32,
        n: u32,
        omega: f64,
        s_h: Complex64,
        alpha: f64,
        noise_nm: f64,
        faults: Faults,
    ) {
        // The SEA moves the human and the whole exoskeleton,
        // M_e θ̈ = τ_s − τ_c − τ_g, whatever α: τ̃_s/θ_e = S_h + M_e s².
        let _ = alpha;
        let s_he = s_h - M_E * omega * omega;
        let schedule = [
            (ProtocolPhase::RampIn, 5.0),
            (ProtocolPhase::Settling, 5.0),
            (ProtocolPhase::Analysis, 5.0),
            (ProtocolPhase::RampOut, 5.0),
            (ProtocolPhase::Rest, 2.0),
        ];
        let mut excitation_start = 0;
        for (phase, dur_s) in schedule {
            if phase == ProtocolPhase::Settling {
                excitation_start = self.tick;
            }
            for k in 0..(dur_s * RATE) as usize {
                let p = self.state(experiment, n, phase, omega, alpha);
                // The bias ramps the posture by up to 0.05 rad (raised cosine).
                let ramp = match phase {
                    ProtocolPhase::RampIn => {
                        0.5 - 0.5 * (std::f64::consts::PI * k as f64 / (dur_s * RATE)).cos()
                    }
                    ProtocolPhase::RampOut => {
                        0.5 + 0.5 * (std::f64::consts::PI * k as f64 / (dur_s * RATE)).cos()
                    }
                    ProtocolPhase::Settling | ProtocolPhase::Analysis => 1.0,
                    _ => 0.0,
                };
                let excited = matches!(phase, ProtocolPhase::Settling | ProtocolPhase::Analysis);
                let t = (self.tick - excitation_start) as f64 / RATE;
                let x = if excited {
                    Complex64::from_polar(AMP_RAD, omega * t)
                } else {
                    Complex64::new(0.0, 0.0)
                };
                let theta = POSTURE_RAD + 0.05 * ramp + x.im;
                let tau_g = GRAVITY_NM * theta.sin();
                let bias = 4.0 * ramp;
                let tau_c = (s_h * x).im + noise_nm * self.gauss();
                let tau_s = (s_he * x).im + tau_g + bias + noise_nm * self.gauss();
                // The command the SEA tracked: τ_s = G(jω) τ_d at ω, with
                // gravity's slope about the posture in the tracked torque.
                let slope = GRAVITY_NM * (POSTURE_RAD + 0.05 * ramp).cos();
                let tau_d = (s_he * x).im
                    + tau_g
                    + bias
                    + ((1.0 / sea(omega) - 1.0) * (s_he + slope) * x).im;
                let mut st = 0;
                if let Some((fp, fk, bits)) = faults.status {
                    if fp == phase && fk == k {
                        st = bits;
                    }
                }
                let tau_c = if phase == ProtocolPhase::Analysis && faults.nan_at == Some(k) {
                    f64::NAN
                } else {
                    tau_c
                };
                let stamp = self.tick * 1_000_000;
                let mode = match faults.mode {
                    Some((fp, fk, m)) if fp == phase && fk == k => m.as_u32(),
                    // Left unset (Idle), as some writers leave it.
                    _ => 0,
                };
                let c = ActuatorCommand {
                    seq: self.tick,
                    stamp_ns: stamp,
                    sensor_seq: self.tick,
                    tau_d,
                    tau_gravity: tau_g,
                    tau_bias: bias,
                    mode,
                    ..Default::default()
                };
                let s = SensorSample {
                    seq: self.tick,
                    stamp_ns: stamp,
                    theta_e: theta,
                    tau_c,
                    tau_s,
                    status: st,
                    ..Default::default()
                };
                self.tick(p, c, s);
            }
        }
    }

    /// Ten periods at the paper's frequencies of an M2 human.
    fn experiment(&mut self, number: u32, k: f64, h: f64, alpha: f64, noise_nm: f64) {
        let human = DynamicStiffness::from_array([0.11, 0.0, k, h]);
        for p in 1..=10u32 {
            let omega = paper_omega(p);
            self.period(
                number,
                p,
                omega,
                human.response(omega),
                alpha,
                noise_nm,
                Faults::default(),
            );
        }
    }
}

pub(crate) fn brief_human() -> DynamicStiffness {
    DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0])
}

#[test]
fn ten_periods_give_ten_points_and_the_m2_fit_recovers_k_and_h() {
    let noise = 0.02;
    let alpha = 2.0;
    let human = brief_human();
    let mut st = Stream::new()
        .with(IdentifierSettings::default(), Delivery::EveryTick, true)
        .with(
            IdentifierSettings {
                fit_source: FitSource::ActuatorTorque,
                ..IdentifierSettings::default()
            },
            Delivery::EveryTick,
            true,
        );
    st.experiment(1, 40.0, 10.0, alpha, noise);
    let coupled = &st.sinks[0];
    let frf = coupled.frf();
    assert_eq!(frf.len(), 10, "{:?}", coupled.warnings());
    // What the identifier keeps is what it reported, under its experiment;
    // and it runs on the settings it was given.
    assert_eq!(coupled.id.points().len(), 1);
    assert_eq!(coupled.id.points()[&1], frf);
    assert_eq!(coupled.id.settings().fit_source, FitSource::CuffTorque);
    assert_eq!(
        st.sinks[1].id.settings().fit_source,
        FitSource::ActuatorTorque
    );
    for (i, p) in frf.iter().enumerate() {
        assert_eq!((p.experiment, p.period, p.seq), (1, i as u32 + 1, i as u64));
        assert!((p.omega - paper_omega(p.period)).abs() < 1e-12);
        assert_eq!(p.validate(), Ok(()));
        let truth = human.response(p.omega);
        let got = Complex64::new(p.s_h_re, p.s_h_im);
        // The reported standard error, checked against the truth; 0.02 Nm
        // of noise on ≥ 3000 samples of a ≥ 0.7 Nm response is < 0.5 %.
        assert!(p.noise_rel > 0.0 && p.noise_rel < 5e-3, "{}", p.noise_rel);
        assert!(
            (got - truth).norm() < 4.0 * p.noise_rel * truth.norm(),
            "ω {}: {got} vs {truth}, noise_rel {}",
            p.omega,
            p.noise_rel
        );
        assert!(p.coherence > 0.99, "{}", p.coherence);
        // The actuator side has the same noise on τ_s, so the same
        // absolute error scale; gravity (13.9 Nm/rad if left in) must be gone,
        // and the whole M_e is in it.
        let he = Complex64::new(p.s_he_re, p.s_he_im);
        let truth_he = truth - M_E * p.omega * p.omega;
        assert!(
            (he - truth_he).norm() < 4.0 * p.noise_rel * truth.norm(),
            "ω {}: S_h-e {he} vs {truth_he}",
            p.omega
        );
        assert!(
            p.s_he_noise_rel > 0.0
                && p.s_he_noise_rel * he.norm() < 4.0 * p.noise_rel * truth.norm()
        );
        // S_h-e/α is re-created from S_h with M_e/α, not measured.
        let hea = Complex64::new(p.s_hea_re, p.s_hea_im);
        let want = got - Complex64::new(M_E / alpha * p.omega * p.omega, 0.0);
        assert!((hea - want).norm() < 1e-9 * want.norm(), "{hea} vs {want}");
        // τ_s/τ_d: noise only on τ_s, |τ_d| ≥ 0.4 Nm at these frequencies:
        // standard error below σ·√(4·2.6/3000)/0.4 ≈ 3e-3.
        let g = Complex64::new(p.sea_re, p.sea_im);
        assert!(
            (g - sea(p.omega)).norm() < 0.015,
            "ω {}: τ_s/τ_d {g}",
            p.omega
        );
    }
    // Refits: after one point nothing, after two M1 and M2, from three all.
    let est = coupled.estimates();
    let models_after = |n: u32| -> Vec<u32> {
        est.iter()
            .filter(|e| e.n_points == n)
            .map(|e| e.model)
            .collect()
    };
    assert!(models_after(1).is_empty());
    assert_eq!(models_after(2), vec![1, 2]);
    assert_eq!(models_after(3), vec![1, 2, 3]);
    assert_eq!(models_after(10), vec![1, 2, 3]);
    let w = coupled.warnings();
    assert!(
        w.iter()
            .any(|w| w.contains("after 1 FRF point") && w.contains("M1") && w.contains("M3")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("after 2 FRF point")
                && w.contains("M3 (4 parameters) needs 3 points"))
    );
    assert_eq!(w.len(), 2, "{w:?}");
    assert!(est.iter().all(|e| e.validate().is_ok()));
    assert!(est.windows(2).all(|w| w[1].seq == w[0].seq + 1));
    for sink in &st.sinks {
        let m2 = sink.last_estimate(2);
        assert_eq!((m2.n_points, m2.period), (10, 10));
        // Within four of its own standard errors, which are small.
        assert!(
            (m2.k_h - 40.0).abs() < 4.0 * m2.k_h_se && m2.k_h_se < 0.2,
            "K {} ± {}",
            m2.k_h,
            m2.k_h_se
        );
        assert!(
            (m2.h_h - 10.0).abs() < 4.0 * m2.h_h_se && m2.h_h_se < 0.2,
            "H {} ± {}",
            m2.h_h,
            m2.h_h_se
        );
        assert!(
            (m2.m_h - 0.11).abs() < 4.0 * m2.m_h_se,
            "M {} ± {}",
            m2.m_h,
            m2.m_h_se
        );
        assert!((m2.c_h - 0.25).abs() < 0.01);
        // C = H/K and its standard error by first-order propagation,
        // written out: σ_C² = (σ_H/K)² + (H σ_K/K²)².
        assert_eq!(m2.c_h, m2.h_h / m2.k_h);
        let c_se = ((m2.h_h_se / m2.k_h).powi(2)
            + (m2.h_h * m2.k_h_se / (m2.k_h * m2.k_h)).powi(2))
        .sqrt();
        assert!(
            (m2.c_h_se - c_se).abs() <= 1e-12 * c_se,
            "σ_C {} vs {c_se}",
            m2.c_h_se
        );
        // Hysteretic data: M1 (viscous only) is rejected against M3, M2 is not.
        let crit = f_critical(1.0, 16.0, F_TEST_LEVEL).unwrap();
        assert!((m2.f_critical - crit).abs() < 1e-9);
        assert!(
            m2.f_m1_m3 > m2.f_critical,
            "F(M1−M3) {} vs {}",
            m2.f_m1_m3,
            m2.f_critical
        );
        assert!(
            m2.f_m2_m3 < m2.f_critical,
            "F(M2−M3) {} vs {}",
            m2.f_m2_m3,
            m2.f_critical
        );
        assert_eq!(m2.recommended_f, 0.0, "one experiment: no power law yet");
        assert!(sink.id.power_law().is_none() && sink.id.recommended_f().is_none());
    }
    // S_h fitted directly agrees with the paper's S_h-e/α fit.
    let (a, b) = (st.sinks[0].last_estimate(2), st.sinks[1].last_estimate(2));
    assert!((a.k_h - b.k_h).abs() < 4.0 * (a.k_h_se + b.k_h_se));
    assert!((a.h_h - b.h_h).abs() < 4.0 * (a.h_h_se + b.h_h_se));
}

#[test]
fn three_experiments_give_the_power_law_and_eq_f() {
    let law = PowerLaw::new(-0.3, 1.1).unwrap();
    let bounded = IdentifierSettings {
        k_range_source: KRangeSource::Experiments,
        f_bounds: [0.0, 0.2],
        ..IdentifierSettings::default()
    };
    let mut st = Stream::new()
        .with(IdentifierSettings::default(), Delivery::EveryTick, true)
        .with(bounded, Delivery::EveryTick, true);
    for (n, k, alpha) in [(1, 20.0, 1.0), (4, 45.0, 2.0), (7, 80.0, 4.0)] {
        st.experiment(n, k, law.hysteretic_damping(k).unwrap(), alpha, 0.005);
    }
    let sink = &st.sinks[0];
    let last = sink.last_estimate(2);
    assert_eq!(last.experiment, 7);
    assert!((last.beta0 + 0.3).abs() < 0.01, "β0 {}", last.beta0);
    assert!((last.beta1 - 1.1).abs() < 0.01, "β1 {}", last.beta1);
    assert!(last.power_law_r2 > 0.999);
    let pl = sink.id.power_law().unwrap();
    assert_eq!(
        (pl.law.beta0, pl.law.beta1, pl.n),
        (last.beta0, last.beta1, 3)
    );
    // Eq. f with the controller's range and the default phase margin,
    // exactly what exo_impedance's loop shaping computes.
    let fitted = PowerLaw::new(last.beta0, last.beta1).unwrap();
    let f = fractional_order(fitted, StiffnessRange::new(10.03, 108.33).unwrap(), 10.8).unwrap();
    assert_eq!(last.recommended_f, f.clamp(0.0, 0.9));
    assert!(last.recommended_f > 0.0 && last.recommended_f <= 0.9);
    assert_eq!(sink.id.recommended_f(), Some(last.recommended_f));
    // Every model's estimate carries the same power law and f.
    for m in [1, 3] {
        let e = sink.last_estimate(m);
        assert_eq!((e.beta0, e.recommended_f), (last.beta0, last.recommended_f));
    }
    // The power law appears with the second experiment's first M2 fit.
    let est = sink.estimates();
    let first_with_law = est.iter().find(|e| e.beta1 != 0.0).unwrap();
    assert_eq!((first_with_law.experiment, first_with_law.n_points), (4, 2));
    // The range from the experiments' K and bounds [0, 0.2]: clamped.
    let b = st.sinks[1].last_estimate(2);
    let ks: Vec<f64> = st.sinks[1]
        .id
        .m2_by_experiment()
        .values()
        .map(|kh| kh.0)
        .collect();
    let (k_lo, k_hi) = (
        ks.iter().copied().fold(f64::INFINITY, f64::min),
        ks.iter().copied().fold(0.0, f64::max),
    );
    assert!((k_lo - 20.0).abs() < 0.2 && (k_hi - 80.0).abs() < 0.8);
    let law_b = PowerLaw::new(b.beta0, b.beta1).unwrap();
    let f_b = fractional_order(law_b, StiffnessRange::new(k_lo, k_hi).unwrap(), 10.8).unwrap();
    assert!(f_b > 0.2, "unclamped f {f_b} should exceed the bound");
    assert_eq!(b.recommended_f, 0.2);
}

#[test]
fn a_broadband_window_gives_several_points() {
    // Random perturbation, like the ankle recording: θ is white noise
    // low-passed twice at 60 rad/s; the human is an M1 (a causal system a
    // time series can carry exactly): τ_c = K θ + B θ̇ + M θ̈, derivatives by
    // central differences (exact to (ωh)²/6 < 0.1 % up to 60 rad/s).
    let (k, b, m) = (30.0, 0.4, 0.11);
    let human = DynamicStiffness::from_array([m, b, k, 0.0]);
    let mut st = Stream::new().with(IdentifierSettings::default(), Delivery::EveryTick, true);
    let n = 60_000;
    let a = (-60.0 / RATE).exp();
    let (mut f1, mut f2) = (0.0, 0.0);
    let mut theta = Vec::with_capacity(n + 2);
    for _ in 0..n + 2 {
        f1 = a * f1 + (1.0 - a) * st.gauss();
        f2 = a * f2 + (1.0 - a) * f1;
        theta.push(0.05 * f2);
    }
    let settle = st.state(2, 1, ProtocolPhase::Settling, 0.0, 1.0);
    st.tick(
        settle,
        ActuatorCommand::default(),
        SensorSample {
            stamp_ns: 0,
            ..Default::default()
        },
    );
    for j in 1..=n {
        let (x0, x1, x2) = (theta[j - 1], theta[j], theta[j + 1]);
        let v = (x2 - x0) * RATE / 2.0;
        let acc = (x2 - 2.0 * x1 + x0) * RATE * RATE;
        let tau_c = k * x1 + b * v + m * acc;
        let tau_s = tau_c + M_E * acc;
        let stamp = st.tick * 1_000_000;
        let p = st.state(2, 1, ProtocolPhase::Analysis, 0.0, 1.0);
        st.tick(
            p,
            ActuatorCommand {
                stamp_ns: stamp,
                tau_d: tau_s,
                ..Default::default()
            },
            SensorSample {
                seq: st.tick,
                stamp_ns: stamp,
                theta_e: 0.8 + x1,
                tau_c,
                tau_s,
                ..Default::default()
            },
        );
    }
    let p = st.state(2, 1, ProtocolPhase::RampOut, 0.0, 1.0);
    let stamp = st.tick * 1_000_000;
    st.tick(
        p,
        ActuatorCommand {
            stamp_ns: stamp,
            ..Default::default()
        },
        SensorSample {
            stamp_ns: stamp,
            ..Default::default()
        },
    );
    let sink = &st.sinks[0];
    let pts = sink.frf();
    assert!(
        pts.len() >= 10 && pts.len() <= 20,
        "{} points; {:?}",
        pts.len(),
        sink.warnings()
    );
    assert!(pts.windows(2).all(|w| w[1].omega > w[0].omega));
    assert!(pts
        .iter()
        .all(|p| p.period == 1 && p.experiment == 2 && p.validate().is_ok()));
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
        let hea = Complex64::new(p.s_he_re, p.s_he_im);
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
        // τ_s − τ_c = M_e θ̈ exactly here: the actuator side differs from
        // S_h by the real −M_e ω² alone, so their imaginary parts agree (to
        // the leakage allowed above), and it carries its own noise.
        let got_h = Complex64::new(p.s_h_re, p.s_h_im);
        assert!(
            (hea.im - got_h.im).abs() < 0.05 * got_h.norm() + 0.1 * per_bin,
            "ω {}: Im S_h-e {} vs Im S_h {}",
            p.omega,
            hea.im,
            got_h.im
        );
        assert!(
            p.s_he_noise_rel > 0.0 && p.s_he_noise_rel.is_finite(),
            "{}",
            p.s_he_noise_rel
        );
        // τ_d = τ_s exactly here.
        assert!((Complex64::new(p.sea_re, p.sea_im) - 1.0).norm() < 1e-9);
    }
    // Broadband points are refitted like sine points.
    let m1 = sink.last_estimate(1);
    assert_eq!(m1.n_points as usize, pts.len());
    assert!((m1.k_h / k - 1.0).abs() < 0.05, "K {}", m1.k_h);
}
