//! The identifier in a multisine run (issue 34 item 2): one point per
//! excited line from the analysis window's whole periods, each with its
//! noise from the spread between periods, and the M2 fit of an M2 human.
//!
//! The stream is written here from the physics, not from the estimator:
//! `θ_e` is a sum of cosines at the run's lines (phases drawn in the test),
//! and `τ_c = Re Σ S_h(jω_l) X_l e^{jω_l t}` is the human's exact periodic
//! steady state (a complex stiffness answers each line with `S_h(jω_l)`),
//! plus white noise of a known σ, so the standard error each line must
//! report follows from σ, the period and the amplitude alone.

use exo_config::MultisineSettings;
use exo_identifier::{Event, Identifier, IdentifierSettings};
use exo_impedance::{Complex64, DynamicStiffness};
use exo_messages::{ActuatorCommand, ProtocolPhase, ProtocolState, SensorSample};

use crate::identifier::M_E;

const RATE: f64 = 1000.0;
const AMP_RAD: f64 = 0.01;

fn settings() -> MultisineSettings {
    MultisineSettings {
        band_rad_s: [2.0, 32.0],
        lines: 6,
        period_s: 2.0,
        settling_periods: 1,
        periods: 3,
        peak_nm: None,
    }
}

struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// Feeds `analysis_samples` of analysis (after one period of settling) of
/// the human through `id`, and returns its events and the lines (ω, phase).
fn run(
    id: Identifier,
    human: DynamicStiffness,
    noise_nm: f64,
    analysis_samples: usize,
    seed: u64,
) -> (Vec<Event>, Vec<(f64, f64)>) {
    run_with(
        id,
        human,
        noise_nm,
        analysis_samples,
        seed,
        Stream::default(),
    )
}

/// The SEA's torque tracking in the stream, `τ_s/τ_d = 1/(1 + 0.01 jω)`.
fn sea(omega: f64) -> Complex64 {
    1.0 / Complex64::new(1.0, 0.01 * omega)
}

/// How [`run_with`] delivers the stream.
struct Stream {
    /// Whether the controller's commands are sent.
    commands: bool,
    /// The protocol states' excitation amplitude (Nm).
    amplitude_nm: f64,
    /// Ticks each sample (and command) reaches the identifier after the
    /// protocol state of its tick (as a process reading its protocol
    /// inbox first, a batch at a time, may see them).
    sample_lag: usize,
    /// A tick whose sample carries the driver's fault status.
    fault_at: Option<usize>,
    /// The experiment, and the tick its stream starts at (stamps and seqs
    /// count from there).
    experiment: u32,
    start_tick: u64,
}

impl Default for Stream {
    fn default() -> Self {
        Stream {
            commands: true,
            amplitude_nm: 3.0,
            sample_lag: 0,
            fault_at: None,
            experiment: 1,
            start_tick: 0,
        }
    }
}

/// [`run`], delivered as `stream` says.
fn run_with(
    id: Identifier,
    human: DynamicStiffness,
    noise_nm: f64,
    analysis_samples: usize,
    seed: u64,
    stream: Stream,
) -> (Vec<Event>, Vec<(f64, f64)>) {
    let (events, lines, _) = run_kept(id, human, noise_nm, analysis_samples, seed, stream);
    (events, lines)
}

/// [`run_with`], returning the identifier too.
fn run_kept(
    mut id: Identifier,
    human: DynamicStiffness,
    noise_nm: f64,
    analysis_samples: usize,
    seed: u64,
    stream: Stream,
) -> (Vec<Event>, Vec<(f64, f64)>, Identifier) {
    let mut late = std::collections::VecDeque::new();
    let m = settings();
    let (n_period, bins) = m.bins(RATE).unwrap();
    let mut rng = Rng(seed);
    // (ω, phase) of each line, phases drawn here.
    let lines: Vec<(f64, f64)> = bins
        .iter()
        .map(|b| {
            (
                std::f64::consts::TAU * *b as f64 * RATE / n_period as f64,
                std::f64::consts::TAU * rng.uniform(),
            )
        })
        .collect();
    let mut events = Vec::new();
    let total = n_period + analysis_samples + 1;
    for k in 0..total {
        let phase = if k < n_period {
            ProtocolPhase::Settling
        } else if k < n_period + analysis_samples {
            ProtocolPhase::Analysis
        } else {
            ProtocolPhase::RampOut
        };
        let t = k as f64 / RATE;
        let (mut x, mut tc, mut ts, mut td) = (0.0, 0.0, 0.0, 0.0);
        for (w, ph) in &lines {
            let e = Complex64::from_polar(AMP_RAD, w * t + ph);
            let s_h = human.response(*w);
            x += e.re;
            tc += (s_h * e).re;
            ts += ((s_h - M_E * w * w) * e).re;
            td += ((s_h - M_E * w * w) / sea(*w) * e).re;
        }
        let stamp = (stream.start_tick + k as u64) * 1_000_000;
        let seq = stream.start_tick + k as u64;
        let p = ProtocolState {
            experiment: stream.experiment,
            period: 1,
            phase: phase.as_u32(),
            omega: 0.0,
            amplitude: stream.amplitude_nm,
            alpha: 1.0,
            load_kg: 4.5,
            stamp_ns: stamp,
            ..Default::default()
        };
        id.on_protocol(&p, &mut events);
        let command = ActuatorCommand {
            seq,
            stamp_ns: stamp,
            sensor_seq: seq,
            tau_d: td,
            ..Default::default()
        };
        let sample = SensorSample {
            seq,
            stamp_ns: stamp,
            theta_e: 0.8 + x,
            tau_c: tc + noise_nm * rng.gauss(),
            tau_s: ts + noise_nm * rng.gauss(),
            status: if stream.fault_at == Some(k) {
                exo_messages::status::ENCODER_FAULT
            } else {
                0
            },
            ..Default::default()
        };
        late.push_back((command, sample));
        while late.len() > stream.sample_lag {
            let (c, s) = late.pop_front().unwrap();
            if stream.commands {
                id.on_command(&c);
            }
            id.on_sample(&s, &mut events);
        }
    }
    for (c, s) in late {
        if stream.commands {
            id.on_command(&c);
        }
        id.on_sample(&s, &mut events);
    }
    id.flush(&mut events);
    (events, lines, id)
}

/// An identifier estimating line by line at the design's bins.
fn with_multisine() -> Identifier {
    let (n, bins) = settings().bins(RATE).unwrap();
    Identifier::try_new(IdentifierSettings::default())
        .unwrap()
        .with_periodic_lines(n, bins)
        .unwrap()
}

fn points(events: &[Event]) -> Vec<exo_messages::FrfPoint> {
    events
        .iter()
        .filter_map(|e| match e {
            Event::Frf(p) => Some(*p),
            _ => None,
        })
        .collect()
}

#[test]
fn each_excited_line_gives_a_point_with_the_humans_response_and_a_calibrated_error() {
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let sigma = 0.05;
    let (events, lines) = run(with_multisine(), human, sigma, 3 * 2000, 7);
    let pts = points(&events);
    assert_eq!(pts.len(), lines.len(), "{events:?}");
    // The standard error of a line's Ȳ/X̄: the noise's DFT coefficient
    // (1/N normalisation) has variance σ²/N a period, σ²/(N P) averaged
    // over P periods, against |X| = A/2 of a cosine of amplitude A.
    let want_se = (sigma * sigma / (2000.0 * 3.0)).sqrt() / (AMP_RAD / 2.0);
    let mut worst = 0.0f64;
    for (p, (w, _)) in pts.iter().zip(&lines) {
        assert!((p.omega - w).abs() < 1e-9, "{} vs {w}", p.omega);
        assert!(p.validate().is_ok(), "{p:?}");
        let truth = human.response(*w);
        let got = Complex64::new(p.s_h_re, p.s_h_im);
        let se = p.noise_rel * got.norm();
        // Three periods: the reported σ has 2·2 = 4 degrees of freedom, so
        // it scatters; within a factor of 3 of the truth either way.
        assert!(
            se > want_se / 3.0 && se < want_se * 3.0,
            "ω {w}: reported {se}, expected {want_se}"
        );
        worst = worst.max((got - truth).norm() / want_se);
        assert_eq!((p.experiment, p.period), (1, 1));
        let hea = Complex64::new(p.s_he_re, p.s_he_im);
        let truth_he = truth - M_E * w * w;
        assert!(
            (hea - truth_he).norm() < 5.0 * want_se,
            "ω {w}: {hea} vs {truth_he}"
        );
        // τ_s carries noise of the same σ: the same standard error.
        let se_he = p.s_he_noise_rel * hea.norm();
        assert!(
            se_he > want_se / 3.0 && se_he < want_se * 3.0,
            "ω {w}: S_h-e reported {se_he}, expected {want_se}"
        );
        // τ_d is noise-free, τ_s noisy: τ_s/τ_d is the SEA's tracking
        // within τ_s's noise over |τ_d| at the line.
        let g = sea(*w);
        let td_line = (truth_he / g).norm() * AMP_RAD / 2.0;
        let want_sea_se = (sigma * sigma / (2000.0 * 3.0)).sqrt() / td_line;
        let got_sea = Complex64::new(p.sea_re, p.sea_im);
        assert!(
            (got_sea - g).norm() < 5.0 * want_sea_se,
            "ω {w}: {got_sea} vs {g}"
        );
        // The coherence the noise implies over the three periods.
        let want_coh = 1.0 / (1.0 + 3.0 * p.noise_rel * p.noise_rel);
        assert!(
            (p.coherence - want_coh).abs() < 1e-12 && p.coherence > 0.99,
            "{p:?}"
        );
    }
    // Every line within 5 true standard errors (Rayleigh: P(|z| > 5σ) ≈ 4e-6).
    assert!(worst < 5.0, "worst error {worst} standard errors");
    // The M2 fit of the six lines recovers K and H.
    let m2 = events
        .iter()
        .rev()
        .find_map(|e| match e {
            Event::Estimate(e) if e.model == 2 => Some(*e),
            _ => None,
        })
        .expect("an M2 estimate");
    assert!((m2.k_h - 40.0).abs() < 0.4, "K {}", m2.k_h);
    assert!((m2.h_h - 10.0).abs() < 0.4, "H {}", m2.h_h);
}

/// One point per line, each `S_h` the human's own to 1e-9 (noise-free).
fn assert_every_line_exact(events: &[Event], lines: &[(f64, f64)], human: DynamicStiffness) {
    let pts = points(events);
    assert_eq!(pts.len(), lines.len());
    for (p, (w, _)) in pts.iter().zip(lines) {
        let got = Complex64::new(p.s_h_re, p.s_h_im);
        let truth = human.response(*w);
        assert!(
            (got - truth).norm() < 1e-9 * truth.norm(),
            "{got} vs {truth}"
        );
    }
}

#[test]
fn without_noise_the_lines_are_exact() {
    let human = DynamicStiffness::from_array([0.11, 0.3, 25.0, 6.0]);
    let (events, lines) = run(with_multisine(), human, 0.0, 3 * 2000, 11);
    assert_every_line_exact(&events, &lines, human);
}

#[test]
fn a_window_of_fewer_than_two_whole_periods_gives_no_point_and_says_why() {
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let (events, _) = run(with_multisine(), human, 0.05, 3999, 3);
    assert!(points(&events).is_empty());
    assert!(
        events.iter().any(|e| matches!(e, Event::Warning(w)
            if w.contains("fewer than two whole multisine periods"))),
        "{events:?}"
    );
}

#[test]
fn a_partial_period_at_the_windows_end_is_left_out() {
    // 2.5 periods of analysis: the two whole ones are used; the lines
    // stay exact without noise (a partial period would leak).
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let (events, lines) = run(with_multisine(), human, 0.0, 5000, 5);
    assert_every_line_exact(&events, &lines, human);
}

#[test]
fn lines_that_no_period_can_carry_are_refused() {
    let id = || Identifier::new(IdentifierSettings::default());
    for (n, bins) in [
        (3usize, vec![1usize]),
        (2000, vec![]),
        (2000, vec![0, 5]),
        (2000, vec![5, 1000]),
        (2000, vec![5, 7, 5]),
    ] {
        let err = id().with_periodic_lines(n, bins.clone()).err();
        assert_eq!(
            err.map(|e| e.field),
            Some("periodic_lines"),
            "{n} samples, bins {bins:?}"
        );
    }
    assert!(id().with_periodic_lines(2000, vec![1, 999]).is_ok());
    assert!(id().with_periodic_lines(4, vec![1]).is_ok());
}

#[test]
fn without_the_commands_there_is_no_sea_tracking_but_every_line() {
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let stream = Stream {
        commands: false,
        ..Stream::default()
    };
    let (events, lines) = run_with(with_multisine(), human, 0.0, 3 * 2000, 9, stream);
    let pts = points(&events);
    assert_eq!(pts.len(), lines.len());
    for p in &pts {
        assert_eq!((p.sea_re, p.sea_im), (0.0, 0.0), "{p:?}");
        let truth = human.response(p.omega);
        assert!((Complex64::new(p.s_h_re, p.s_h_im) - truth).norm() < 1e-9 * truth.norm());
    }
}

#[test]
fn without_the_lines_a_multisine_window_is_estimated_by_welch() {
    // The same stream through an identifier not told the lines: Welch's
    // points (band summaries), not one per line.
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let (events, lines) = run(
        Identifier::new(IdentifierSettings::default()),
        human,
        0.0,
        3 * 2000,
        7,
    );
    let pts = points(&events);
    assert!(!pts.is_empty());
    let on_lines = pts
        .iter()
        .filter(|p| lines.iter().any(|(w, _)| (p.omega - w).abs() < 1e-9))
        .count();
    assert!(on_lines < lines.len(), "{pts:?}");
}

/// A line the angle does not carry (here a bin the identifier is told of
/// but the stream never excites) is left out by name, and the window's
/// other lines stand, exact: one weak line must not cost the experiment
/// its other points (the rig's random subject 33, experiment 9, had lost
/// all twelve for one, stop 48).
#[test]
fn a_line_with_nothing_in_the_angle_is_left_out_alone() {
    let human = DynamicStiffness::from_array([0.11, 0.3, 25.0, 6.0]);
    let (n, bins) = settings().bins(RATE).unwrap();
    let extra = (1..n / 2).find(|b| !bins.contains(b)).unwrap();
    let mut told = bins.clone();
    told.push(extra);
    told.sort_unstable();
    let id = Identifier::try_new(IdentifierSettings::default())
        .unwrap()
        .with_periodic_lines(n, told)
        .unwrap();
    let (events, lines) = run(id, human, 0.0, 3 * 2000, 11);
    assert_every_line_exact(&events, &lines, human);
    let warned: Vec<&String> = events
        .iter()
        .filter_map(|e| match e {
            Event::Warning(w) if w.contains("left out") => Some(w),
            _ => None,
        })
        .collect();
    assert_eq!(warned.len(), 1, "{warned:?}");
    assert!(
        warned[0].contains(&format!("line at bin {extra} left out"))
            && warned[0].contains("nothing at bin"),
        "{warned:?}"
    );
}

/// The fits as periods accrue (issue 34 item 2): with four analysed
/// periods, M2 estimates are published as the second, third and fourth
/// whole period of the window is complete (stamped just after its last
/// sample), each from the lines of the periods so far, before the window
/// closes; no FRF point is published until it closes, and then one a line
/// with the window's own estimate (the same four periods). Each K and H
/// lies within four of its own standard errors (plus 1 %) of the human's,
/// and the standard errors shrink as periods accrue (noise alone: as
/// 1/√P, by about √2 from two periods to four).
#[test]
fn estimates_are_published_as_the_periods_accrue() {
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let n = 2000u64;
    let ms = 1_000_000u64;
    let (events, lines) = run(with_multisine(), human, 0.05, 4 * n as usize, 21);
    let window_start_ns = n * ms; // after one period of settling
    let window_end_ns = window_start_ns + 4 * n * ms;
    let m2: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            Event::Estimate(e) if e.model == 2 => Some(*e),
            _ => None,
        })
        .collect();
    let interim: Vec<_> = m2.iter().filter(|e| e.stamp_ns < window_end_ns).collect();
    // Whole periods of samples behind each: the last sample's stamp + 1 ns.
    let periods: Vec<u64> = interim
        .iter()
        .map(|e| (e.stamp_ns - 1 - window_start_ns) / ms + 1)
        .collect();
    assert_eq!(
        periods,
        [2 * n, 3 * n, 4 * n],
        "interim M2 after {periods:?} samples"
    );
    // The first FRF point comes after every interim estimate.
    let first_frf = events
        .iter()
        .position(|e| matches!(e, Event::Frf(_)))
        .unwrap();
    let last_interim = events
        .iter()
        .rposition(|e| matches!(e, Event::Estimate(x) if x.stamp_ns < window_end_ns))
        .unwrap();
    assert!(last_interim < first_frf);
    assert_eq!(points(&events).len(), lines.len());
    let last = *m2.last().unwrap();
    assert_eq!(last.stamp_ns, window_end_ns);
    assert_eq!((last.k_h, last.h_h), (interim[2].k_h, interim[2].h_h));
    for e in &interim {
        assert_eq!(e.n_points as usize, lines.len());
        assert!(
            (e.k_h - 40.0).abs() < 4.0 * e.k_h_se + 0.4,
            "K {} ± {}",
            e.k_h,
            e.k_h_se
        );
        assert!(
            (e.h_h - 10.0).abs() < 4.0 * e.h_h_se + 0.1,
            "H {} ± {}",
            e.h_h,
            e.h_h_se
        );
    }
    // Over seeds: the mean standard error of K and of H from four periods
    // against two (√(2/4) = 0.71 for noise alone).
    let (mut k2, mut k4, mut h2, mut h4) = (0.0, 0.0, 0.0, 0.0);
    for seed in 100..120 {
        let (events, _) = run(with_multisine(), human, 0.05, 4 * n as usize, seed);
        let e: Vec<_> = events
            .iter()
            .filter_map(|e| match e {
                Event::Estimate(e) if e.model == 2 => Some(*e),
                _ => None,
            })
            .collect();
        (k2, h2) = (k2 + e[0].k_h_se, h2 + e[0].h_h_se);
        (k4, h4) = (k4 + e[2].k_h_se, h4 + e[2].h_h_se);
    }
    eprintln!(
        "se ratio four / two periods: K {:.3}, H {:.3}",
        k4 / k2,
        h4 / h2
    );
    assert!(
        k4 / k2 < 0.9 && h4 / h2 < 0.9,
        "K {k2} → {k4}, H {h2} → {h4}"
    );
}

/// When the window's close is known before its last samples arrive (the
/// ramp-out's state read ahead of them), the periods completed after it
/// are the window's own analysis's, fitted once: interim fits only while
/// the window is open (after two and three of four periods), then the
/// window's own. And a window without excitation (amplitude 0) is not
/// fitted along the way, as it is not at its end.
#[test]
fn interim_fits_only_while_the_window_is_open_and_excited() {
    let human = DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]);
    let n = 2000u64;
    let ms = 1_000_000u64;
    let window_end_ns = n * ms + 4 * n * ms;
    let stream = Stream {
        sample_lag: 50,
        ..Stream::default()
    };
    let (events, _) = run_with(with_multisine(), human, 0.05, 4 * n as usize, 21, stream);
    let m2: Vec<u64> = events
        .iter()
        .filter_map(|e| match e {
            Event::Estimate(e) if e.model == 2 => Some(e.stamp_ns),
            _ => None,
        })
        .collect();
    // Just after the last sample of the second and third periods (the
    // window's samples counted from its own first, whenever they come),
    // then the window's own at its close.
    let window_start_ns = n * ms;
    assert_eq!(
        m2,
        [
            window_start_ns + 2 * n * ms - ms + 1,
            window_start_ns + 3 * n * ms - ms + 1,
            window_end_ns
        ]
    );
    let quiet = Stream {
        amplitude_nm: 0.0,
        ..Stream::default()
    };
    let (events, _) = run_with(with_multisine(), human, 0.05, 4 * n as usize, 21, quiet);
    assert!(
        !events
            .iter()
            .any(|e| matches!(e, Event::Estimate(_) | Event::Frf(_))),
        "{events:?}"
    );
}

/// A window discarded at its end (a sample with the driver's fault status
/// in its last period) leaves nothing of its interim fits: no points, no
/// M2 of its experiment, and no power law from it — here experiment 1 is
/// measured whole (K 40) and experiment 4's window (K 25), fitted along
/// the way, is discarded: one experiment is left, too few for a power law
/// (its interim M2 beside experiment 1's made one).
#[test]
fn a_discarded_window_leaves_nothing_of_its_interim_fits() {
    let n = 2000usize;
    let (_, _, id) = run_kept(
        with_multisine(),
        DynamicStiffness::from_array([0.11, 0.0, 40.0, 10.0]),
        0.05,
        4 * n,
        21,
        Stream::default(),
    );
    assert!(id.m2_by_experiment().contains_key(&1));
    let stream = Stream {
        experiment: 4,
        start_tick: 20 * n as u64,
        fault_at: Some(n + 3 * n + 500),
        ..Stream::default()
    };
    let (events, _, id) = run_kept(
        id,
        DynamicStiffness::from_array([0.11, 0.0, 25.0, 7.0]),
        0.05,
        4 * n,
        22,
        stream,
    );
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::Estimate(x) if x.model == 2 && x.experiment == 4 && x.beta1 != 0.0)),
        "interim estimates of experiment 4, with a power law, before the fault"
    );
    assert!(
        events
            .iter()
            .any(|e| matches!(e, Event::Warning(w) if w.contains("window discarded"))),
        "{events:?}"
    );
    assert!(points(&events).is_empty());
    assert!(id.points().get(&4).is_none(), "{:?}", id.points());
    assert_eq!(
        id.m2_by_experiment().keys().copied().collect::<Vec<_>>(),
        [1]
    );
    assert!(id.power_law().is_none(), "{:?}", id.power_law());
    assert!(id.recommended_f().is_none());
}
