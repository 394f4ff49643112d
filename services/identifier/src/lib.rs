//! # exo-identifier (logic)
//!
//! The online complex-stiffness estimator, as a state machine fed the
//! run's streams in any interleaving (the process feeds it from iceoryx2,
//! `exo fit` from a recording):
//!
//! - Every sample and command goes into preallocated rings (no allocation
//!   per sample).
//! - The protocol's analysis phase (`ProtocolState.phase = 3`) marks a window
//!   by time stamps: from the first tick in the phase to the first tick after
//!   it. Once a sample at or past the window's end has arrived, the window is
//!   analysed:
//!   - a sine period (`omega > 0`): single-frequency correlation over whole
//!     cycles ([`exo_impedance::frf`]) gives one [`FrfPoint`]: `S_h =
//!     τ_c/θ_e`, `S_{h-e/α} = τ_s/θ_e`, `τ_s/τ_d`, coherence and relative
//!     noise;
//!   - broadband (`omega = 0`): Welch H1 with coherence over the excited
//!     band, several points.
//!
//!   A fault bit or the safe state in any sample of the window discards the
//!   window with a warning.
//! - After each point the experiment's points are refitted with M1, M2 and
//!   M3 (`S_{h-e/α}` with the known `M_e/α` removed, as the paper fits) and
//!   one [`ImpedanceEstimate`] per model is produced, with `F_{M1−M3}`,
//!   `F_{M2−M3}` and the critical value; across experiments, M2's (K, H)
//!   give the subject's power law and eq. f's recommended fractional order,
//!   clamped to the configured bounds.
//!
//! Heavy work happens only at window ends, never per sample.

use std::collections::BTreeMap;

use exo_impedance::frf::{average_bins, band_groups, sine_amplitude, sine_ratio, welch_h1};
use exo_impedance::{
    fit_all, fit_power_law, fractional_order, paper_f_tests, Complex64, FitTarget,
    FrfPoint as FitPoint, ImpedanceModel, ModelComparison, StiffnessRange,
};
use exo_messages::{
    status, ActuatorCommand, FrfPoint, ImpedanceEstimate, ProtocolState, SensorSample,
};

/// Settings of the identifier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifierSettings {
    /// Control rate (Hz): one sample per tick.
    pub rate_hz: f64,
    /// Longest analysis window kept (s); longer windows keep their last part.
    pub max_window_s: f64,
    /// Exoskeleton inertia without load (kg·m²).
    pub arm_inertia_kg_m2: f64,
    /// Lever arm of the load (m): `M_e = arm + load · lever²`.
    pub load_lever_arm_m: f64,
    /// Guaranteed phase margin for eq. f (degrees).
    pub phase_margin_deg: f64,
    /// Stiffness range (Nm/rad) for eq. f.
    pub k_range_nm_per_rad: [f64; 2],
    /// Bounds the recommended f is clamped to.
    pub f_bounds: [f64; 2],
    /// Welch segment length (samples, a power of two) for broadband windows.
    pub welch_segment: usize,
    /// Points a broadband window is summarised into.
    pub broadband_points: usize,
    /// Smallest coherence of a broadband bin kept.
    pub min_coherence: f64,
    /// Band (rad/s) a broadband estimate is limited to.
    pub broadband_band_rad_s: [f64; 2],
    /// Remove a linear trend in sine windows.
    pub detrend: bool,
}

impl Default for IdentifierSettings {
    fn default() -> Self {
        IdentifierSettings {
            rate_hz: 1000.0,
            max_window_s: 60.0,
            arm_inertia_kg_m2: 0.1,
            load_lever_arm_m: 0.45,
            phase_margin_deg: 10.8,
            k_range_nm_per_rad: [10.03, 108.33],
            f_bounds: [0.0, 0.9],
            welch_segment: 4096,
            broadband_points: 20,
            min_coherence: 0.6,
            broadband_band_rad_s: [1.0, 100.0],
            detrend: true,
        }
    }
}

/// What the identifier produced.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// A new FRF point.
    Frf(FrfPoint),
    /// A refit after a point (one per model).
    Estimate(ImpedanceEstimate),
    /// Something could not be used, and why.
    Warning(String),
}

/// A fixed-capacity ring of samples.
#[derive(Debug, Clone)]
struct Ring<const N: usize> {
    stamp: Vec<u64>,
    values: Vec<[f64; N]>,
    flags: Vec<u32>,
    head: usize,
    len: usize,
}

impl<const N: usize> Ring<N> {
    fn new(capacity: usize) -> Self {
        Ring {
            stamp: vec![0; capacity],
            values: vec![[0.0; N]; capacity],
            flags: vec![0; capacity],
            head: 0,
            len: 0,
        }
    }

    fn push(&mut self, stamp: u64, v: [f64; N], flags: u32) {
        let cap = self.stamp.len();
        let i = (self.head + self.len) % cap;
        self.stamp[i] = stamp;
        self.values[i] = v;
        self.flags[i] = flags;
        if self.len < cap {
            self.len += 1;
        } else {
            self.head = (self.head + 1) % cap;
        }
    }

    /// Entries with `start <= stamp < end`, oldest first (allocates: window ends only).
    fn window(&self, start: u64, end: u64) -> Vec<(u64, [f64; N], u32)> {
        let cap = self.stamp.len();
        (0..self.len)
            .map(|k| (self.head + k) % cap)
            .filter(|&i| self.stamp[i] >= start && self.stamp[i] < end)
            .map(|i| (self.stamp[i], self.values[i], self.flags[i]))
            .collect()
    }

    fn latest(&self) -> Option<u64> {
        (self.len > 0).then(|| self.stamp[(self.head + self.len - 1) % self.stamp.len()])
    }
}

/// An analysis window being delimited.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Window {
    state: ProtocolState,
    start_ns: u64,
    end_ns: Option<u64>,
}

/// The identifier.
#[derive(Debug, Clone)]
pub struct Identifier {
    s: IdentifierSettings,
    sensor: Ring<3>,
    command: Ring<2>,
    window: Option<Window>,
    last_phase: u32,
    frf_seq: u64,
    estimate_seq: u64,
    /// Points per experiment.
    points: BTreeMap<u32, Vec<FrfPoint>>,
    /// Latest M2 (K, H) per experiment.
    m2: BTreeMap<u32, (f64, f64)>,
    /// α and load per experiment.
    settings_of: BTreeMap<u32, (f64, f64)>,
}

impl Identifier {
    /// An identifier with rings of `max_window_s` (allocated now, once).
    pub fn new(s: IdentifierSettings) -> Self {
        let cap = ((s.rate_hz * s.max_window_s).ceil() as usize).max(16);
        Identifier {
            s,
            sensor: Ring::new(cap),
            command: Ring::new(cap),
            window: None,
            last_phase: 0,
            frf_seq: 0,
            estimate_seq: 0,
            points: BTreeMap::new(),
            m2: BTreeMap::new(),
            settings_of: BTreeMap::new(),
        }
    }

    /// The points so far, by experiment.
    pub fn points(&self) -> &BTreeMap<u32, Vec<FrfPoint>> {
        &self.points
    }

    /// A calibrated sample. Allocation-free.
    pub fn on_sample(&mut self, s: &SensorSample, out: &mut Vec<Event>) {
        self.sensor
            .push(s.stamp_ns, [s.theta_e, s.tau_c, s.tau_s], s.status);
        self.try_finish(out);
    }

    /// A controller command (for `τ_s/τ_d`). Allocation-free.
    pub fn on_command(&mut self, c: &ActuatorCommand) {
        self.command.push(c.stamp_ns, [c.tau_d, c.tau_gravity], 0);
    }

    /// A protocol state.
    pub fn on_protocol(&mut self, p: &ProtocolState, out: &mut Vec<Event>) {
        const ANALYSIS: u32 = 3;
        if p.phase == ANALYSIS && self.last_phase != ANALYSIS {
            if self.window.is_some_and(|w| w.end_ns.is_some()) {
                // A previous window still waits for its last samples: analyse what is there.
                self.finish(out);
            }
            self.window = Some(Window {
                state: *p,
                start_ns: p.stamp_ns,
                end_ns: None,
            });
        } else if p.phase != ANALYSIS && self.last_phase == ANALYSIS {
            if let Some(w) = self.window.as_mut() {
                w.end_ns = Some(p.stamp_ns);
            }
        }
        self.last_phase = p.phase;
        self.try_finish(out);
    }

    /// Analyses a delimited window once its last sample has arrived.
    fn try_finish(&mut self, out: &mut Vec<Event>) {
        let ready = matches!(
            (self.window, self.sensor.latest()),
            (Some(Window { end_ns: Some(end), .. }), Some(latest)) if latest + 1 >= end
        );
        if ready {
            self.finish(out);
        }
    }

    /// Analyses the current window if it has an end (call at the end of a recording).
    pub fn flush(&mut self, out: &mut Vec<Event>) {
        if self.window.is_some_and(|w| w.end_ns.is_some()) {
            self.finish(out);
        }
    }

    fn m_e(&self, load_kg: f64) -> f64 {
        self.s.arm_inertia_kg_m2 + load_kg * self.s.load_lever_arm_m.powi(2)
    }

    fn finish(&mut self, out: &mut Vec<Event>) {
        let Some(w) = self.window.take() else { return };
        let Some(end) = w.end_ns else { return };
        let p = w.state;
        let what = format!(
            "experiment {} period {} (ω = {:.3} rad/s)",
            p.experiment, p.period, p.omega
        );
        if p.amplitude <= 0.0 {
            out.push(Event::Warning(format!(
                "{what}: no excitation (amplitude 0: voluntary motion or a release test); no FRF point"
            )));
            return;
        }
        let samples = self.sensor.window(w.start_ns, end);
        if samples.len() < 16 {
            out.push(Event::Warning(format!(
                "{what}: only {} samples in the analysis window; no FRF point",
                samples.len()
            )));
            return;
        }
        let bad = status::FAULT_MASK | status::SAFE_STATE;
        if let Some((stamp, _, f)) = samples.iter().find(|(_, _, f)| f & bad != 0) {
            out.push(Event::Warning(format!(
                "{what}: sample at {stamp} ns has status {f:#x} (fault or safe state); window discarded"
            )));
            return;
        }
        let t0 = samples[0].0;
        let t: Vec<f64> = samples.iter().map(|x| (x.0 - t0) as f64 * 1e-9).collect();
        let col = |i: usize| -> Vec<f64> { samples.iter().map(|x| x.1[i]).collect() };
        let (th, tc, mut ts) = (col(0), col(1), col(2));
        let commands = self.command.window(w.start_ns, end);
        // τ̃_s = τ_s − τ_gravity (the paper removes gravity from τ_s): the
        // command answering each sample carries the controller's gravity
        // compensation. The bias is constant over the window (the mean goes).
        let ts_raw = ts.clone();
        let mut k = 0;
        let mut matched = 0;
        for (i, (stamp, _, _)) in samples.iter().enumerate() {
            while k < commands.len() && commands[k].0 < *stamp {
                k += 1;
            }
            if k < commands.len() && commands[k].0 == *stamp {
                ts[i] -= commands[k].1[1];
                matched += 1;
            }
        }
        if matched > 0 && matched < samples.len() * 9 / 10 {
            out.push(Event::Warning(format!(
                "{what}: only {matched} of {} samples have their command; S_h-e/α uses τ_s with gravity where it is missing",
                samples.len()
            )));
        }
        let new_points: Vec<FrfPoint> = if p.omega > 0.0 {
            match self.sine_point(&t, &th, &tc, &ts, &ts_raw, &commands, t0, &p) {
                Ok(pt) => vec![pt],
                Err(e) => {
                    out.push(Event::Warning(format!("{what}: {e}")));
                    return;
                }
            }
        } else {
            match self.broadband_points(&th, &tc, &ts, &ts_raw, &commands, samples.len(), &p) {
                Ok(v) if !v.is_empty() => v,
                Ok(_) => {
                    out.push(Event::Warning(format!(
                        "{what}: broadband window has no coherent excited band"
                    )));
                    return;
                }
                Err(e) => {
                    out.push(Event::Warning(format!("{what}: {e}")));
                    return;
                }
            }
        };
        self.settings_of.insert(p.experiment, (p.alpha, p.load_kg));
        for mut pt in new_points {
            pt.seq = self.frf_seq;
            self.frf_seq += 1;
            pt.stamp_ns = end;
            out.push(Event::Frf(pt));
            self.points.entry(p.experiment).or_default().push(pt);
        }
        self.refit(p.experiment, p.period, end, out);
    }

    #[allow(clippy::too_many_arguments)]
    fn sine_point(
        &self,
        t: &[f64],
        th: &[f64],
        tc: &[f64],
        ts: &[f64],
        ts_raw: &[f64],
        commands: &[(u64, [f64; 2], u32)],
        t0: u64,
        p: &ProtocolState,
    ) -> Result<FrfPoint, exo_impedance::ScienceError> {
        let w = p.omega;
        let d = self.s.detrend;
        let a_th = sine_amplitude(t, th, w, d)?;
        let a_tc = sine_amplitude(t, tc, w, d)?;
        let a_ts = sine_amplitude(t, ts, w, d)?;
        let s_h = sine_ratio(&a_th, &a_tc)?;
        let s_hea = sine_ratio(&a_th, &a_ts)?;
        let sea = if commands.len() >= 16 {
            let tt: Vec<f64> = commands
                .iter()
                .map(|c| (c.0 as f64 - t0 as f64) * 1e-9)
                .collect();
            let td: Vec<f64> = commands.iter().map(|c| c.1[0]).collect();
            sine_amplitude(t, ts_raw, w, d)
                .and_then(|a_raw| {
                    sine_amplitude(&tt, &td, w, d).and_then(|a_td| sine_ratio(&a_td, &a_raw))
                })
                .map(|r| r.ratio)
                .unwrap_or(Complex64::new(0.0, 0.0))
        } else {
            Complex64::new(0.0, 0.0)
        };
        Ok(FrfPoint {
            experiment: p.experiment,
            period: p.period,
            omega: w,
            s_h_re: s_h.ratio.re,
            s_h_im: s_h.ratio.im,
            s_hea_re: s_hea.ratio.re,
            s_hea_im: s_hea.ratio.im,
            sea_re: sea.re,
            sea_im: sea.im,
            coherence: s_h.coherence,
            noise_rel: s_h.noise_rel,
            ..Default::default()
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn broadband_points(
        &self,
        th: &[f64],
        tc: &[f64],
        ts: &[f64],
        ts_raw: &[f64],
        commands: &[(u64, [f64; 2], u32)],
        n: usize,
        p: &ProtocolState,
    ) -> Result<Vec<FrfPoint>, exo_impedance::ScienceError> {
        let seg = self.s.welch_segment.min(n.next_power_of_two() / 2).max(16);
        let rate = self.s.rate_hz;
        let [lo, hi] = self.s.broadband_band_rad_s;
        let h_c = welch_h1(th, tc, rate, seg)?;
        let h_s = welch_h1(th, ts, rate, seg)?;
        let sea = if commands.len() >= seg {
            let td: Vec<f64> = commands.iter().map(|c| c.1[0]).collect();
            let m = td.len().min(ts_raw.len());
            Some(welch_h1(&td[..m], &ts_raw[..m], rate, seg)?)
        } else {
            None
        };
        let groups = band_groups(
            &h_c,
            self.s.min_coherence,
            1e-3,
            lo,
            hi,
            self.s.broadband_points,
        );
        // τ_s/θ_e and τ_s/τ_d averaged over the same bins as τ_c/θ_e.
        let picked: Vec<(exo_impedance::frf::H1Bin, Complex64, Complex64)> = groups
            .iter()
            .filter_map(|g| {
                let c = average_bins(&h_c, g)?;
                let s_hea = average_bins(&h_s, g).map_or(Complex64::new(0.0, 0.0), |b| b.h);
                let sea = sea
                    .as_deref()
                    .and_then(|s| average_bins(s, g))
                    .map_or(Complex64::new(0.0, 0.0), |b| b.h);
                Some((c, s_hea, sea))
            })
            .collect();
        Ok(picked
            .iter()
            .map(|(b, s_hea, sea)| {
                // Normalised random error of H1 (Bendat & Piersol): √((1 − γ²)/(2 γ² n_d)).
                let g2 = b.coherence.max(1e-6);
                let noise = ((1.0 - g2) / (2.0 * g2 * b.segments.max(1) as f64)).sqrt();
                FrfPoint {
                    experiment: p.experiment,
                    period: p.period,
                    omega: b.omega_rad_s,
                    s_h_re: b.h.re,
                    s_h_im: b.h.im,
                    s_hea_re: s_hea.re,
                    s_hea_im: s_hea.im,
                    sea_re: sea.re,
                    sea_im: sea.im,
                    coherence: b.coherence,
                    noise_rel: noise,
                    ..Default::default()
                }
            })
            .collect())
    }

    fn refit(&mut self, experiment: u32, period: u32, stamp_ns: u64, out: &mut Vec<Event>) {
        let Some(points) = self.points.get(&experiment) else {
            return;
        };
        let (alpha, load) = self
            .settings_of
            .get(&experiment)
            .copied()
            .unwrap_or((1.0, 0.0));
        let pts: Vec<FitPoint> = points
            .iter()
            .map(|p| FitPoint::new(p.omega, p.s_hea_re, p.s_hea_im))
            .collect();
        let target = FitTarget::Coupled {
            m_e_kg_m2: self.m_e(load),
            alpha: if alpha > 0.0 { alpha } else { 1.0 },
        };
        if pts.len() < 3 {
            return; // M3 has four parameters: two complex points are too few for a comparison.
        }
        let comparison: ModelComparison = match fit_all(&pts, target) {
            Ok(c) => c,
            Err(e) => {
                out.push(Event::Warning(format!(
                    "experiment {experiment}: no model fit with {} points: {e}",
                    pts.len()
                )));
                return;
            }
        };
        let (f13, f23, fcrit) = match paper_f_tests(&[comparison], 0.05) {
            Ok(t) => (
                t.m1_vs_m3.statistic,
                t.m2_vs_m3.statistic,
                t.m1_vs_m3.critical,
            ),
            Err(_) => (0.0, 0.0, 0.0),
        };
        let m2 = comparison.m2.params;
        if m2.k_nm_per_rad > 0.0 && m2.h_nm_per_rad > 0.0 {
            self.m2
                .insert(experiment, (m2.k_nm_per_rad, m2.h_nm_per_rad));
        }
        let (mut beta0, mut beta1, mut pl_r2, mut f_rec) = (0.0, 0.0, 0.0, 0.0);
        if self.m2.len() >= 2 {
            let (ks, hs): (Vec<f64>, Vec<f64>) = self.m2.values().copied().unzip();
            if let Ok(pl) = fit_power_law(&ks, &hs) {
                beta0 = pl.law.beta0;
                beta1 = pl.law.beta1;
                pl_r2 = pl.r2;
                let [k_lo, k_hi] = self.s.k_range_nm_per_rad;
                if let Ok(f) = StiffnessRange::new(k_lo, k_hi)
                    .and_then(|r| fractional_order(pl.law, r, self.s.phase_margin_deg))
                {
                    f_rec = f.clamp(self.s.f_bounds[0], self.s.f_bounds[1]);
                }
            }
        }
        for model in ImpedanceModel::ALL {
            let fit = comparison.get(model);
            let par = fit.params;
            let se = fit.std_errors.unwrap_or_default();
            let (k, h) = (par.k_nm_per_rad, par.h_nm_per_rad);
            let c = if k != 0.0 { h / k } else { 0.0 };
            // se of H/K by first-order propagation (K and H taken as independent).
            let c_se = if k != 0.0 {
                ((se.h_nm_per_rad / k).powi(2) + (h * se.k_nm_per_rad / (k * k)).powi(2)).sqrt()
            } else {
                0.0
            };
            let e = ImpedanceEstimate {
                seq: self.estimate_seq,
                stamp_ns,
                experiment,
                period,
                n_points: pts.len() as u32,
                model: match model {
                    ImpedanceModel::M1 => 1,
                    ImpedanceModel::M2 => 2,
                    ImpedanceModel::M3 => 3,
                },
                k_h: k,
                k_h_se: se.k_nm_per_rad.abs(),
                h_h: h,
                h_h_se: se.h_nm_per_rad.abs(),
                b_h: par.b_nm_s_per_rad,
                b_h_se: se.b_nm_s_per_rad.abs(),
                m_h: par.m_kg_m2,
                m_h_se: se.m_kg_m2.abs(),
                c_h: c,
                c_h_se: c_se,
                r2: fit.r2.min(1.0),
                f_m1_m3: f13,
                f_m2_m3: f23,
                f_critical: fcrit,
                beta0,
                beta1,
                power_law_r2: pl_r2,
                recommended_f: f_rec,
            };
            self.estimate_seq += 1;
            if e.first_non_finite().is_none() {
                out.push(Event::Estimate(e));
            } else {
                out.push(Event::Warning(format!(
                    "experiment {experiment}: {} estimate not finite; not published",
                    model.name()
                )));
            }
        }
    }
}
