//! Automatic stability verdict on a spring-release response (the paper's
//! post-tuning test, section "Tuning Results"): after the springs are
//! detached, does the joint angle's oscillation die out, or is it sustained
//! or growing?
//!
//! Method. The window after the release (minus a short `skip_s`, the step
//! itself) is split into `segments` equal parts. The angle's deviation from
//! the equilibrium, estimated as the mean of the window's last 40 %, gives
//! one RMS per part. A loop with phase margin φ near crossover ω_c rings
//! down roughly as `exp(−ζ ω_c t)` with `ζ ≈ φ/100` (φ in degrees), so over a
//! few seconds a stable loop's RMS falls by a large factor while a marginal or
//! unstable one keeps (or grows) it. The verdict is *oscillates* when the
//! last part's RMS is at least `sustain_ratio` of the first part's (default
//! 0.5: over a 4 s window that is ζ below about 0.02 at 10 rad/s, i.e. a
//! margin of about 2°), or when the safe state latched during the run (the
//! safety stepped in, which only an unstable loop does in this test). A
//! release too small to stand out of the noise (`min_rms_rad`) is an error,
//! not a verdict.

use std::fmt;

use crate::error::{Error, Result};

/// Settings of the detector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detector {
    /// Time (s) after the release left out (the step itself).
    pub skip_s: f64,
    /// Number of equal parts the rest of the window is split into.
    pub segments: usize,
    /// Last-to-first RMS ratio at or above which the response counts as sustained.
    pub sustain_ratio: f64,
    /// Smallest first-part RMS (rad) that counts as a response.
    pub min_rms_rad: f64,
}

impl Default for Detector {
    fn default() -> Self {
        Detector {
            skip_s: 0.2,
            segments: 6,
            sustain_ratio: 0.5,
            min_rms_rad: 2e-4,
        }
    }
}

/// What the detector concluded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The oscillation dies out: stable.
    Decays,
    /// Sustained or growing oscillation, or the safety stepped in: unstable.
    Oscillates,
}

/// The detector's evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityReport {
    /// The verdict.
    pub verdict: Verdict,
    /// RMS of the angle deviation in the first part (rad).
    pub rms_first_rad: f64,
    /// RMS of the angle deviation in the last part (rad).
    pub rms_last_rad: f64,
    /// `rms_last_rad / rms_first_rad`.
    pub decay_ratio: f64,
    /// Exponential growth rate of the RMS envelope (1/s; negative = decaying),
    /// least squares over the parts.
    pub growth_rate_per_s: f64,
    /// Dominant oscillation frequency (rad/s) from the zero crossings of the
    /// parts above the noise floor; 0 if there are fewer than two.
    pub frequency_rad_s: f64,
    /// Whether the safe state latched during the run.
    pub safe_state: bool,
}

impl fmt::Display for StabilityReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} (RMS {:.2e} → {:.2e} rad, ratio {:.3}, envelope rate {:+.2}/s, {:.1} rad/s{})",
            match self.verdict {
                Verdict::Decays => "decays",
                Verdict::Oscillates => "oscillates",
            },
            self.rms_first_rad,
            self.rms_last_rad,
            self.decay_ratio,
            self.growth_rate_per_s,
            self.frequency_rad_s,
            if self.safe_state {
                ", safe state latched"
            } else {
                ""
            }
        )
    }
}

impl Detector {
    /// Classifies the response `theta_e_rad` sampled at `t_s` (s, increasing)
    /// after a release at `release_t_s`. `safe_state` says whether the safe
    /// state latched at any time during the run.
    pub fn classify(
        &self,
        t_s: &[f64],
        theta_e_rad: &[f64],
        release_t_s: f64,
        safe_state: bool,
    ) -> Result<StabilityReport> {
        let refuse = |detail: String| Error::Stability { detail };
        if t_s.len() != theta_e_rad.len() {
            return Err(refuse(format!(
                "{} time stamps but {} angles",
                t_s.len(),
                theta_e_rad.len()
            )));
        }
        if self.segments < 2 {
            return Err(refuse("at least 2 segments are needed".to_string()));
        }
        let window: Vec<(f64, f64)> = t_s
            .iter()
            .zip(theta_e_rad)
            .filter(|(t, _)| **t >= release_t_s + self.skip_s)
            .map(|(t, th)| (*t, *th))
            .collect();
        if let Some((t, th)) = window
            .iter()
            .find(|(t, th)| !t.is_finite() || !th.is_finite())
        {
            return Err(refuse(format!("non-finite sample (t = {t}, θ = {th})")));
        }
        let per = window.len() / self.segments;
        if per < 10 {
            return Err(refuse(format!(
                "only {} samples after the release (+{} s); observe longer",
                window.len(),
                self.skip_s
            )));
        }
        let tail = &window[window.len() * 3 / 5..];
        let equilibrium = tail.iter().map(|(_, th)| th).sum::<f64>() / tail.len() as f64;
        let rms: Vec<(f64, f64)> = window
            .chunks_exact(per)
            .take(self.segments)
            .map(|c| {
                let t_mid = 0.5 * (c[0].0 + c[c.len() - 1].0);
                let ms = c
                    .iter()
                    .map(|(_, th)| (th - equilibrium).powi(2))
                    .sum::<f64>()
                    / c.len() as f64;
                (t_mid, ms.sqrt())
            })
            .collect();
        let (rms_first, rms_last) = (rms[0].1, rms[rms.len() - 1].1);
        if rms_first < self.min_rms_rad && !safe_state {
            return Err(refuse(format!(
                "the release moved the arm by only {rms_first:.2e} rad RMS (below {:.1e}); use a stronger spring",
                self.min_rms_rad
            )));
        }
        // Least-squares slope of ln(RMS) over time, over the parts that stand
        // out of the noise floor (at least a twentieth of the first part's
        // RMS; the first two parts always).
        let pts: Vec<(f64, f64)> = rms
            .iter()
            .enumerate()
            .take_while(|(i, (_, r))| *i < 2 || *r >= 0.05 * rms_first)
            .map(|(_, (t, r))| (*t, r.max(1e-12).ln()))
            .collect();
        let n = pts.len() as f64;
        let (mt, ml) = (
            pts.iter().map(|p| p.0).sum::<f64>() / n,
            pts.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let sxx: f64 = pts.iter().map(|p| (p.0 - mt).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - ml)).sum();
        let growth = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        // Zero crossings of the deviation over the parts used for the rate
        // (where the oscillation, not the noise, crosses zero).
        let used = (pts.len() * per).min(window.len());
        let mut crossings = Vec::new();
        for w in window[..used].windows(2) {
            let (a, b) = (w[0].1 - equilibrium, w[1].1 - equilibrium);
            if (a < 0.0) != (b < 0.0) {
                let frac = a / (a - b);
                crossings.push(w[0].0 + frac * (w[1].0 - w[0].0));
            }
        }
        let frequency = if crossings.len() >= 2 {
            let span = crossings[crossings.len() - 1] - crossings[0];
            std::f64::consts::PI * (crossings.len() - 1) as f64 / span
        } else {
            0.0
        };
        let ratio = rms_last / rms_first.max(1e-300);
        let verdict = if safe_state || ratio >= self.sustain_ratio {
            Verdict::Oscillates
        } else {
            Verdict::Decays
        };
        Ok(StabilityReport {
            verdict,
            rms_first_rad: rms_first,
            rms_last_rad: rms_last,
            decay_ratio: ratio,
            growth_rate_per_s: growth,
            frequency_rad_s: frequency,
            safe_state,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A damped (σ < 0) or growing (σ > 0) sinusoid about 0.8 rad with
    /// deterministic pseudo-noise, released at 1 s, sampled at 1 kHz for 5 s.
    fn response(sigma: f64, omega: f64, noise_rad: f64) -> (Vec<f64>, Vec<f64>) {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let (mut t, mut th) = (Vec::new(), Vec::new());
        for k in 0..5000 {
            let tk = k as f64 * 1e-3;
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let x = if tk < 1.0 {
                0.85
            } else {
                0.8 + 0.05 * (sigma * (tk - 1.0)).exp() * (omega * (tk - 1.0)).cos()
            };
            t.push(tk);
            th.push(x + noise_rad * u);
        }
        (t, th)
    }

    #[test]
    fn a_well_damped_ring_down_decays() {
        let (t, th) = response(-3.0, 12.0, 1e-4);
        let r = Detector::default().classify(&t, &th, 1.0, false).unwrap();
        assert_eq!(r.verdict, Verdict::Decays, "{r}");
        assert!((r.growth_rate_per_s + 3.0).abs() < 0.6, "{r}");
    }

    #[test]
    fn a_sustained_or_growing_oscillation_is_caught_with_its_frequency() {
        for sigma in [0.0, 0.3] {
            let (t, th) = response(sigma, 12.0, 1e-4);
            let r = Detector::default().classify(&t, &th, 1.0, false).unwrap();
            assert_eq!(r.verdict, Verdict::Oscillates, "σ = {sigma}: {r}");
            assert!((r.frequency_rad_s - 12.0).abs() < 0.3, "{r}");
        }
    }

    #[test]
    fn a_lightly_damped_but_decaying_response_counts_as_decaying_only_below_the_threshold() {
        // ζ ω = 0.1/s over ~4 s: ratio ≈ 0.7, sustained by this definition.
        let (t, th) = response(-0.1, 12.0, 1e-4);
        let r = Detector::default().classify(&t, &th, 1.0, false).unwrap();
        assert_eq!(r.verdict, Verdict::Oscillates, "{r}");
        // ζ ω = 0.5/s: ratio ≈ 0.17.
        let (t, th) = response(-0.5, 12.0, 1e-4);
        let r = Detector::default().classify(&t, &th, 1.0, false).unwrap();
        assert_eq!(r.verdict, Verdict::Decays, "{r}");
    }

    #[test]
    fn a_latched_safe_state_means_unstable() {
        let (t, th) = response(-3.0, 12.0, 1e-4);
        let r = Detector::default().classify(&t, &th, 1.0, true).unwrap();
        assert_eq!(r.verdict, Verdict::Oscillates);
    }

    #[test]
    fn bad_input_is_an_error_not_a_verdict() {
        let d = Detector::default();
        let (t, mut th) = response(-3.0, 12.0, 1e-4);
        assert!(d.classify(&t, &th[..10], 1.0, false).is_err());
        assert!(d.classify(&t, &th, 4.99, false).is_err(), "too short");
        th[3000] = f64::NAN;
        assert!(d.classify(&t, &th, 1.0, false).is_err());
        let flat = vec![0.8; t.len()];
        let e = d.classify(&t, &flat, 1.0, false).unwrap_err();
        assert!(e.to_string().contains("stronger spring"), "{e}");
    }
}
