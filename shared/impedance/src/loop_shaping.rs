//! Loop shaping of the amplification controller (section "Loop Shaping Methods").
//!
//! The loop is `L(s) = k_p · F(s) · P(s)` with the plant from desired actuator
//! torque to interaction torque
//!
//! ```text
//!         S_h(s)              M_h s² + K(1 + c j)
//! P(s) = ──────── G_SEA(s) = ──────────────────────── G_SEA(s),   M_{h-e} = M_h + M_e
//!        S_{h-e}(s)          M_{h-e} s² + K(1 + c j)
//! ```
//!
//! and a second-order SEA `G_SEA(s) = ω_n²/(s² + 2ζω_n s + ω_n²)`.

use num_complex::Complex64;
use serde::Serialize;

use crate::error::{finite, positive, Result, ScienceError};
use crate::lag_filter::LagFilter;
use crate::power_law::PowerLaw;

/// Proportional gain `k_p = (M_{h-e}/M_h)^(1/2)` (eq. kp), which puts the
/// crossover of `k_p P(s)` midway (on a log scale) between `ω_{h-e}` and `ω_h`.
pub fn proportional_gain(m_e_kg_m2: f64, m_h_kg_m2: f64) -> Result<f64> {
    positive("m_e_kg_m2", m_e_kg_m2)?;
    positive("m_h_kg_m2", m_h_kg_m2)?;
    Ok(((m_e_kg_m2 + m_h_kg_m2) / m_h_kg_m2).sqrt())
}

/// Crossover `ω_gc = √(K / (M_{h-e} M_h)^(1/2))` (rad/s) of `k_p P(s)` at
/// stiffness `K` (eq. kp).
pub fn crossover_frequency(k_nm_per_rad: f64, m_e_kg_m2: f64, m_h_kg_m2: f64) -> Result<f64> {
    positive("k_nm_per_rad", k_nm_per_rad)?;
    positive("m_e_kg_m2", m_e_kg_m2)?;
    positive("m_h_kg_m2", m_h_kg_m2)?;
    Ok((k_nm_per_rad / ((m_e_kg_m2 + m_h_kg_m2) * m_h_kg_m2).sqrt()).sqrt())
}

/// The range of human stiffness a controller must be stable for (Nm/rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StiffnessRange {
    /// Lower bound `K̲_h` (Nm/rad).
    pub k_min: f64,
    /// Upper bound `K̄_h` (Nm/rad).
    pub k_max: f64,
}

impl StiffnessRange {
    /// A range with `0 < k_min ≤ k_max`.
    pub fn new(k_min: f64, k_max: f64) -> Result<Self> {
        positive("k_min", k_min)?;
        positive("k_max", k_max)?;
        if k_min > k_max {
            return Err(ScienceError::ReversedRange { k_min, k_max });
        }
        Ok(StiffnessRange { k_min, k_max })
    }

    /// Nominal stiffness `K̂_h = (K̲_h K̄_h)^(1/2)` (eq. kf).
    pub fn nominal(&self) -> f64 {
        (self.k_min * self.k_max).sqrt()
    }
}

/// Nominal crossover `ω̂_gc` (rad/s) at the geometric-mean stiffness (eq. kf).
pub fn nominal_crossover(range: StiffnessRange, m_e_kg_m2: f64, m_h_kg_m2: f64) -> Result<f64> {
    crossover_frequency(range.nominal(), m_e_kg_m2, m_h_kg_m2)
}

/// Gain `k_f = ω̂_gc^f` (eq. kf) that gives `F(s) = k_f s^(−f)` unit magnitude at `ω̂_gc`.
pub fn fractional_gain(nominal_crossover_rad_s: f64, f: f64) -> Result<f64> {
    positive("nominal_crossover_rad_s", nominal_crossover_rad_s)?;
    finite("f", f)?;
    Ok(nominal_crossover_rad_s.powf(f))
}

/// Fractional order `f` that guarantees phase margin `φ` over the stiffness
/// range (eq. f): `f = (atan(c_min) − φ)/90°`, where the smallest loss factor
/// `c_min` is at `K̄` when `β1 < 1` and at `K̲` when `β1 ≥ 1`.
///
/// Errors when the result is not in `(0, 1)`, e.g. when `φ` is larger than
/// the subject's smallest hysteretic phase `atan(c_min)`.
pub fn fractional_order(
    law: PowerLaw,
    range: StiffnessRange,
    phase_margin_deg: f64,
) -> Result<f64> {
    finite("phase_margin_deg", phase_margin_deg)?;
    if !(phase_margin_deg > 0.0 && phase_margin_deg < 90.0) {
        return Err(ScienceError::OutOfRange {
            name: "phase_margin_deg",
            value: phase_margin_deg,
            allowed: "(0, 90)",
        });
    }
    let k_worst = if law.beta1 < 1.0 {
        range.k_max
    } else {
        range.k_min
    };
    let phase_deg = law.low_frequency_phase_deg(k_worst)?;
    let f = (phase_deg - phase_margin_deg) / 90.0;
    if !(f > 0.0 && f < 1.0) {
        return Err(ScienceError::Infeasible(format!(
            "eq. f gives f = {f:.3}, outside (0, 1): the subject's smallest hysteretic phase is atan(c) = {phase_deg:.2}° at K = {k_worst} Nm/rad, so a guaranteed phase margin of {phase_margin_deg}° leaves no room for a fractional order"
        )));
    }
    Ok(f)
}

/// Second-order SEA torque dynamics `G_SEA(s) = ω_n²/(s² + 2ζω_n s + ω_n²)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SeaModel {
    /// Natural frequency `ω_n/2π` (Hz); the paper's SEA has a 10 Hz bandwidth.
    pub natural_frequency_hz: f64,
    /// Damping ratio ζ.
    pub damping_ratio: f64,
}

impl Default for SeaModel {
    fn default() -> Self {
        SeaModel {
            natural_frequency_hz: 10.0,
            damping_ratio: 0.7,
        }
    }
}

impl SeaModel {
    /// An SEA model with positive natural frequency and damping ratio.
    pub fn new(natural_frequency_hz: f64, damping_ratio: f64) -> Result<Self> {
        positive("sea natural_frequency_hz", natural_frequency_hz)?;
        positive("sea damping_ratio", damping_ratio)?;
        Ok(SeaModel {
            natural_frequency_hz,
            damping_ratio,
        })
    }

    /// `ω_n` (rad/s).
    pub fn omega_n_rad_s(&self) -> f64 {
        2.0 * std::f64::consts::PI * self.natural_frequency_hz
    }

    /// `G_SEA(jω)`.
    pub fn response(&self, omega_rad_s: f64) -> Complex64 {
        let wn = self.omega_n_rad_s();
        let s = Complex64::new(0.0, omega_rad_s);
        wn * wn / (s * s + 2.0 * self.damping_ratio * wn * s + wn * wn)
    }

    /// Continuous phase of `G_SEA(jω)` (degrees), in `(−180, 0]` for `ω ≥ 0`.
    pub fn phase_deg(&self, omega_rad_s: f64) -> f64 {
        let wn = self.omega_n_rad_s();
        -(2.0 * self.damping_ratio * wn * omega_rad_s)
            .atan2(wn * wn - omega_rad_s * omega_rad_s)
            .to_degrees()
    }
}

/// The plant `P(s) = S_h(s)/S_{h-e}(s) · G_SEA(s)` from `τ_d` to `τ_c`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AmplificationPlant {
    /// Exoskeleton inertia `M_e` (kg·m²).
    pub m_e_kg_m2: f64,
    /// Human inertia `M_h` (kg·m²).
    pub m_h_kg_m2: f64,
    /// Human stiffness `K_h` (Nm/rad).
    pub k_nm_per_rad: f64,
    /// Loss factor `c_h = H_h/K_h`.
    pub loss_factor: f64,
    /// SEA torque dynamics.
    pub sea: SeaModel,
}

impl AmplificationPlant {
    /// A plant with positive inertias and stiffness and a finite, non-negative loss factor.
    pub fn new(
        m_e_kg_m2: f64,
        m_h_kg_m2: f64,
        k_nm_per_rad: f64,
        loss_factor: f64,
        sea: SeaModel,
    ) -> Result<Self> {
        positive("m_e_kg_m2", m_e_kg_m2)?;
        positive("m_h_kg_m2", m_h_kg_m2)?;
        positive("k_nm_per_rad", k_nm_per_rad)?;
        finite("loss_factor", loss_factor)?;
        if loss_factor < 0.0 {
            return Err(ScienceError::OutOfRange {
                name: "loss_factor",
                value: loss_factor,
                allowed: "[0, ∞)",
            });
        }
        SeaModel::new(sea.natural_frequency_hz, sea.damping_ratio)?;
        Ok(AmplificationPlant {
            m_e_kg_m2,
            m_h_kg_m2,
            k_nm_per_rad,
            loss_factor,
            sea,
        })
    }

    fn complex_stiffness(&self) -> Complex64 {
        Complex64::new(self.k_nm_per_rad, self.k_nm_per_rad * self.loss_factor)
    }

    /// `P(jω)` for `ω > 0`.
    pub fn response(&self, omega_rad_s: f64) -> Complex64 {
        let w2 = omega_rad_s * omega_rad_s;
        let kc = self.complex_stiffness();
        let s_h = kc - self.m_h_kg_m2 * w2;
        let s_he = kc - (self.m_h_kg_m2 + self.m_e_kg_m2) * w2;
        s_h / s_he * self.sea.response(omega_rad_s)
    }

    /// Continuous phase of `P(jω)` (degrees) for `ω ≥ 0`, summed factor by factor.
    pub fn phase_deg(&self, omega_rad_s: f64) -> f64 {
        let w2 = omega_rad_s * omega_rad_s;
        let k = self.k_nm_per_rad;
        let h = k * self.loss_factor;
        let s_h = h.atan2(k - self.m_h_kg_m2 * w2);
        let s_he = h.atan2(k - (self.m_h_kg_m2 + self.m_e_kg_m2) * w2);
        (s_h - s_he).to_degrees() + self.sea.phase_deg(omega_rad_s)
    }
}

/// The loop `L(s) = k_p F(s) P(s)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AmplificationLoop {
    /// Proportional gain `k_p`.
    pub kp: f64,
    /// The lag-filter approximation of `F(s)`.
    pub filter: LagFilter,
    /// The plant.
    pub plant: AmplificationPlant,
}

/// One gain crossover of the loop.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Crossover {
    /// Frequency where `|L(jω)| = 1` (rad/s).
    pub omega_rad_s: f64,
    /// Phase of `L` there (degrees, continuous from `ω → 0`).
    pub phase_deg: f64,
    /// Phase margin `180° + ∠L` (degrees); negative means unstable.
    pub phase_margin_deg: f64,
    /// Whether `|L|` falls (`true`) or rises through 1 here.
    pub falling: bool,
}

/// Every crossover of the loop in a frequency band, and the smallest margin.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LoopAnalysis {
    /// All crossovers, lowest frequency first (the paper warns there may be several).
    pub crossovers: Vec<Crossover>,
    /// The smallest phase margin over the crossovers (degrees); `None` if there is none.
    pub min_phase_margin_deg: Option<f64>,
}

impl AmplificationLoop {
    /// `L(jω)`.
    pub fn response(&self, omega_rad_s: f64) -> Complex64 {
        self.kp * self.filter.response(omega_rad_s) * self.plant.response(omega_rad_s)
    }

    /// Continuous phase of `L(jω)` (degrees) for `ω ≥ 0`.
    pub fn phase_deg(&self, omega_rad_s: f64) -> f64 {
        self.filter.phase_deg(omega_rad_s) + self.plant.phase_deg(omega_rad_s)
    }

    /// `log10 |L(jω)|`.
    fn log_gain(&self, omega_rad_s: f64) -> f64 {
        self.response(omega_rad_s).norm().log10()
    }

    /// Finds every gain crossover between `omega_lo` and `omega_hi` (rad/s):
    /// a scan at 200 points per decade for sign changes of `log|L|`, each
    /// refined by bisection in `log ω` to 1e-12 relative.
    pub fn analyze(&self, omega_lo_rad_s: f64, omega_hi_rad_s: f64) -> Result<LoopAnalysis> {
        positive("omega_lo_rad_s", omega_lo_rad_s)?;
        positive("omega_hi_rad_s", omega_hi_rad_s)?;
        if omega_hi_rad_s <= omega_lo_rad_s {
            return Err(ScienceError::Infeasible(format!(
                "crossover search band is empty: {omega_lo_rad_s} to {omega_hi_rad_s} rad/s"
            )));
        }
        let (a, b) = (omega_lo_rad_s.log10(), omega_hi_rad_s.log10());
        let steps = ((b - a) * 200.0).ceil().max(1.0) as usize;
        let mut crossovers = Vec::new();
        let mut x_prev = a;
        let mut g_prev = self.log_gain(10f64.powf(a));
        for i in 1..=steps {
            let x = a + (b - a) * i as f64 / steps as f64;
            let g = self.log_gain(10f64.powf(x));
            if !g.is_finite() || !g_prev.is_finite() {
                return Err(ScienceError::Infeasible(format!(
                    "loop gain is not finite near {:.3} rad/s",
                    10f64.powf(x)
                )));
            }
            if (g_prev >= 0.0) != (g >= 0.0) {
                let (mut lo, mut hi) = (x_prev, x);
                let rising = g > g_prev;
                for _ in 0..100 {
                    let mid = 0.5 * (lo + hi);
                    if (self.log_gain(10f64.powf(mid)) >= 0.0) == rising {
                        hi = mid;
                    } else {
                        lo = mid;
                    }
                    if hi - lo < 1e-13 {
                        break;
                    }
                }
                let w = 10f64.powf(0.5 * (lo + hi));
                let phase = self.phase_deg(w);
                crossovers.push(Crossover {
                    omega_rad_s: w,
                    phase_deg: phase,
                    phase_margin_deg: 180.0 + phase,
                    falling: !rising,
                });
            }
            x_prev = x;
            g_prev = g;
        }
        let min_phase_margin_deg = crossovers
            .iter()
            .map(|c| c.phase_margin_deg)
            .min_by(|x, y| x.total_cmp(y));
        Ok(LoopAnalysis {
            crossovers,
            min_phase_margin_deg,
        })
    }
}

/// The lag-filter layout of a fractional-order controller: everything of
/// eq. Fs but the order `f` (and `k_f`, which eq. kf derives from `f`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FractionalLayout {
    /// Proportional gain `k_p` (eq. kp).
    pub kp: f64,
    /// Nominal crossover `ω̂_gc` (rad/s) that sets `k_f = ω̂_gc^f` (eq. kf).
    pub omega_gc_hat_rad_s: f64,
    /// Number of lag filters `n`.
    pub filters: usize,
    /// First pole `p_1` (rad/s).
    pub p1_rad_s: f64,
    /// Pole-to-pole ratio `r_pp`.
    pub r_pp: f64,
}

impl FractionalLayout {
    /// The loop `k_p F(s) P(s)` at order `f` around `plant`.
    pub fn loop_at(&self, f: f64, plant: AmplificationPlant) -> Result<AmplificationLoop> {
        let k_f = fractional_gain(self.omega_gc_hat_rad_s, f)?;
        let filter = LagFilter::new(self.filters, self.p1_rad_s, self.r_pp, f, k_f)?;
        Ok(AmplificationLoop {
            kp: self.kp,
            filter,
            plant,
        })
    }

    /// The smallest phase margin (degrees) over `plants` at order `f`, every
    /// crossover counted (searched from `10⁻³ min(p_1, 1)` to `10³` times the
    /// SEA's or the filter band's top frequency); `+∞` if no crossover.
    pub fn min_phase_margin_deg(&self, f: f64, plants: &[AmplificationPlant]) -> Result<f64> {
        let mut worst = f64::INFINITY;
        for plant in plants {
            let l = self.loop_at(f, *plant)?;
            let lo = 1e-3 * self.p1_rad_s.min(1.0);
            let hi = 1e3 * plant.sea.omega_n_rad_s().max(l.filter.band_rad_s().1);
            if let Some(m) = l.analyze(lo, hi)?.min_phase_margin_deg {
                worst = worst.min(m);
            }
        }
        Ok(worst)
    }
}

/// The model's stability bound on the fractional order: the largest `f` in
/// `[0, 0.99]` for which the loop keeps a non-negative phase margin at every
/// plant of `plants` (e.g. the subject's low and high stiffness), with the
/// SEA. This is what the paper's tuning experiment finds on the rig ("raise f
/// until the exoskeleton oscillates", section "Loop Shaping Experiments")
/// before subtracting 0.12; eq. f is its SEA-free, power-law form.
///
/// Scans `f` in steps of 0.01 for the first loss of margin, then bisects to
/// `1e-4`. Errors when the loop has no margin even at `f = 0`; returns 0.99
/// when it never loses it.
pub fn marginal_fractional_order(
    layout: &FractionalLayout,
    plants: &[AmplificationPlant],
) -> Result<f64> {
    if plants.is_empty() {
        return Err(ScienceError::Infeasible(
            "marginal fractional order: no plant given".into(),
        ));
    }
    if layout.min_phase_margin_deg(0.0, plants)? < 0.0 {
        return Err(ScienceError::Infeasible(
            "the loop has a negative phase margin already at f = 0 (constant amplification k_p + 1)"
                .into(),
        ));
    }
    let mut stable = 0.0;
    for i in 1..=99 {
        let f = i as f64 * 0.01;
        if layout.min_phase_margin_deg(f, plants)? < 0.0 {
            let mut unstable = f;
            while unstable - stable > 1e-4 {
                let mid = 0.5 * (stable + unstable);
                if layout.min_phase_margin_deg(mid, plants)? < 0.0 {
                    unstable = mid;
                } else {
                    stable = mid;
                }
            }
            return Ok(stable);
        }
        stable = f;
    }
    Ok(stable)
}

/// Predicted amplification `τ̃_s/τ̃_c = α(jω) − 1 = k_p F(jω)` with an ideal
/// actuator: the quantity of the paper's Table IV (section "Loop Shaping
/// Results", `α(s) = τ̃_s(s)/τ̃_c(s) + 1`).
pub fn predicted_amplification(kp: f64, filter: &LagFilter, omega_rad_s: f64) -> Complex64 {
    kp * filter.response(omega_rad_s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reversed_range_is_named() {
        let err = StiffnessRange::new(100.0, 10.0).unwrap_err();
        assert!(matches!(err, ScienceError::ReversedRange { .. }));
        assert!(err.to_string().contains("reversed"));
    }

    #[test]
    fn eq_f_picks_the_least_damped_end_of_the_range() {
        let range = StiffnessRange::new(10.0, 100.0).unwrap();
        let soft = PowerLaw::new(-0.2, 0.8).unwrap(); // c falls with K: worst at k_max
        let f = fractional_order(soft, range, 5.0).unwrap();
        let c = soft.loss_factor(100.0).unwrap();
        assert!((f - (c.atan().to_degrees() - 5.0) / 90.0).abs() < 1e-12);
        let stiff = PowerLaw::new(-0.5, 1.2).unwrap(); // c rises with K: worst at k_min
        let f = fractional_order(stiff, range, 5.0).unwrap();
        let c = stiff.loss_factor(10.0).unwrap();
        assert!((f - (c.atan().to_degrees() - 5.0) / 90.0).abs() < 1e-12);
    }

    #[test]
    fn too_large_a_phase_margin_is_infeasible() {
        let range = StiffnessRange::new(10.0, 100.0).unwrap();
        let law = PowerLaw::new(-0.23, 0.9).unwrap();
        assert!(matches!(
            fractional_order(law, range, 45.0),
            Err(ScienceError::Infeasible(_))
        ));
    }

    #[test]
    fn plant_phase_matches_complex_argument() {
        let p = AmplificationPlant::new(1.01, 0.11, 30.0, 0.4, SeaModel::default()).unwrap();
        for w in [0.5, 3.0, 9.0, 40.0] {
            let arg = p.response(w).arg().to_degrees();
            let diff = (p.phase_deg(w) - arg).rem_euclid(360.0);
            assert!(
                diff < 1e-9 || (360.0 - diff) < 1e-9,
                "w={w}: {} vs {arg}",
                p.phase_deg(w)
            );
        }
    }

    fn paper_layout() -> FractionalLayout {
        let m_e = 0.1 + 4.5 * 0.45 * 0.45;
        FractionalLayout {
            kp: proportional_gain(m_e, 0.11).unwrap(),
            omega_gc_hat_rad_s: nominal_crossover(
                StiffnessRange::new(10.03, 108.33).unwrap(),
                m_e,
                0.11,
            )
            .unwrap(),
            filters: 5,
            p1_rad_s: 1.0,
            r_pp: 10f64.sqrt(),
        }
    }

    #[test]
    fn the_marginal_order_is_where_the_phase_margin_reaches_zero() {
        let lay = paper_layout();
        let m_e = 0.1 + 4.5 * 0.45 * 0.45;
        let plants = [
            AmplificationPlant::new(m_e, 0.11, 20.0, 0.6, SeaModel::default()).unwrap(),
            AmplificationPlant::new(m_e, 0.11, 70.0, 0.45, SeaModel::default()).unwrap(),
        ];
        let f = marginal_fractional_order(&lay, &plants).unwrap();
        assert!(f > 0.0 && f < 0.99, "{f}");
        assert!(lay.min_phase_margin_deg(f, &plants).unwrap() >= 0.0);
        assert!(lay.min_phase_margin_deg(f + 2e-4, &plants).unwrap() < 0.0);
        assert!(lay.min_phase_margin_deg(f - 0.05, &plants).unwrap() > 0.0);
        // The bound over both plants is the lower of the two single bounds.
        let each = plants.map(|p| marginal_fractional_order(&lay, &[p]).unwrap());
        assert!((f - each[0].min(each[1])).abs() < 2e-4, "{f} vs {each:?}");
        // More hysteretic damping (more low-frequency phase lead from the
        // human) leaves room for a larger order.
        let damped = AmplificationPlant {
            loss_factor: 0.9,
            ..plants[1]
        };
        assert!(marginal_fractional_order(&lay, &[damped]).unwrap() > each[1]);
    }

    #[test]
    fn the_marginal_order_needs_a_plant() {
        assert!(marginal_fractional_order(&paper_layout(), &[]).is_err());
    }
}
