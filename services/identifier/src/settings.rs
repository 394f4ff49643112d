//! The identifier's settings ([`IdentifierSettings`]), from a run file or
//! given, and their check.

use crate::FitSource;
use exo_impedance::DampingSign;

/// Where eq. f's stiffness range comes from.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum KRangeSource {
    /// [`IdentifierSettings::k_range_nm_per_rad`] (the controller's range).
    #[default]
    Settings,
    /// The smallest and largest M2 stiffness of the experiments so far.
    Experiments,
}

/// Settings of the identifier.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifierSettings {
    /// Control rate (Hz): one sample per tick. Sizes the rings; broadband
    /// windows use the rate of their own time stamps.
    pub rate_hz: f64,
    /// Longest analysis window kept (s); longer windows keep their last part.
    pub max_window_s: f64,
    /// Exoskeleton inertia without load (kg·m²).
    pub arm_inertia_kg_m2: f64,
    /// Lever arm of the load (m): `M_e = arm + load · lever²`.
    pub load_lever_arm_m: f64,
    /// Guaranteed phase margin for eq. f (degrees).
    pub phase_margin_deg: f64,
    /// Stiffness range (Nm/rad) for eq. f when [`KRangeSource::Settings`].
    pub k_range_nm_per_rad: [f64; 2],
    /// Where eq. f's stiffness range comes from.
    pub k_range_source: KRangeSource,
    /// Bounds the recommended f is clamped to (within `[0, 1)`).
    pub f_bounds: [f64; 2],
    /// Which measured FRF the parameters are estimated from.
    pub fit_source: FitSource,
    /// Sign constraint on the damping terms of the fits.
    pub damping: DampingSign,
    /// Welch segment length (samples, at least 16; any length) for broadband windows.
    pub welch_segment: usize,
    /// Points a broadband window is summarised into.
    pub broadband_points: usize,
    /// Smallest coherence of a broadband bin kept (0–1).
    pub min_coherence: f64,
    /// Smallest input power of a broadband bin kept, relative to the strongest bin.
    pub min_rel_power: f64,
    /// Band (rad/s) a broadband estimate is limited to.
    pub broadband_band_rad_s: [f64; 2],
    /// Fit a linear trend with the sinusoid in sine windows, and a cubic
    /// beside the lines in periodic (multisine) windows (slow drift).
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
            k_range_source: KRangeSource::Settings,
            f_bounds: [0.0, 0.9],
            fit_source: FitSource::CuffTorque,
            damping: DampingSign::Free,
            welch_segment: 4096,
            broadband_points: 20,
            min_coherence: 0.6,
            min_rel_power: 1e-3,
            broadband_band_rad_s: [1.0, 100.0],
            detrend: true,
        }
    }
}

impl IdentifierSettings {
    /// The identifier's settings for run `cfg`: its rate, the arm of its
    /// rig (M_e), the controller's design range and f bounds; the rest
    /// default.
    pub fn of_run(cfg: &exo_config::RunConfig) -> Self {
        IdentifierSettings {
            rate_hz: cfg.run.rate_hz,
            arm_inertia_kg_m2: cfg.rig.arm_inertia_kg_m2,
            load_lever_arm_m: cfg.rig.load_lever_arm_m,
            k_range_nm_per_rad: cfg.controller.k_range_nm_per_rad,
            f_bounds: cfg.controller.f_bounds,
            // A multisine's analysis window may be longer than the default
            // ring: keep it whole, with room for its closing samples.
            max_window_s: cfg
                .experiments
                .as_ref()
                .map_or(0.0, |t| t.timing.analysis_s + 5.0)
                .max(IdentifierSettings::default().max_window_s),
            ..IdentifierSettings::default()
        }
    }
}

/// A setting the identifier cannot work with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("identifier settings: {field} = {value}: {why}")]
pub struct SettingsError {
    /// The setting, e.g. `"rate_hz"`.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What it must be.
    pub why: &'static str,
}

impl IdentifierSettings {
    /// Checks every setting (finite, positive where needed, ordered ranges).
    pub fn validate(&self) -> Result<(), SettingsError> {
        let err = |field, value, why| Err(SettingsError { field, value, why });
        let positive = [
            ("rate_hz", self.rate_hz),
            ("max_window_s", self.max_window_s),
            ("arm_inertia_kg_m2", self.arm_inertia_kg_m2),
            ("phase_margin_deg", self.phase_margin_deg),
            ("k_range_nm_per_rad[0]", self.k_range_nm_per_rad[0]),
            ("broadband_band_rad_s[1]", self.broadband_band_rad_s[1]),
        ];
        for (field, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return err(field, v, "must be a finite number above zero");
            }
        }
        let non_negative = [
            ("load_lever_arm_m", self.load_lever_arm_m),
            ("min_rel_power", self.min_rel_power),
            ("broadband_band_rad_s[0]", self.broadband_band_rad_s[0]),
        ];
        for (field, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                return err(field, v, "must be a finite number, not negative");
            }
        }
        if self.rate_hz * self.max_window_s > 1e8 {
            return err(
                "max_window_s",
                self.max_window_s,
                "rate_hz · max_window_s must stay below 1e8 samples",
            );
        }
        if self.phase_margin_deg >= 90.0 {
            return err(
                "phase_margin_deg",
                self.phase_margin_deg,
                "must be below 90",
            );
        }
        let [k_lo, k_hi] = self.k_range_nm_per_rad;
        if !(k_hi.is_finite() && k_hi > k_lo) {
            return err(
                "k_range_nm_per_rad[1]",
                k_hi,
                "must be finite and above k_range_nm_per_rad[0]",
            );
        }
        let [f_lo, f_hi] = self.f_bounds;
        if !(f_lo.is_finite() && f_lo >= 0.0) {
            return err("f_bounds[0]", f_lo, "must lie in [0, 1)");
        }
        if !(f_hi.is_finite() && f_hi >= f_lo && f_hi < 1.0) {
            return err("f_bounds[1]", f_hi, "must lie in [f_bounds[0], 1)");
        }
        if !(self.min_coherence.is_finite() && (0.0..=1.0).contains(&self.min_coherence)) {
            return err("min_coherence", self.min_coherence, "must lie in [0, 1]");
        }
        if self.broadband_band_rad_s[1] <= self.broadband_band_rad_s[0] {
            return err(
                "broadband_band_rad_s[1]",
                self.broadband_band_rad_s[1],
                "must be above broadband_band_rad_s[0]",
            );
        }
        if self.welch_segment < 16 {
            return err(
                "welch_segment",
                self.welch_segment as f64,
                "must be at least 16",
            );
        }
        if self.broadband_points == 0 {
            return err("broadband_points", 0.0, "must be at least 1");
        }
        Ok(())
    }
}
