//! What the simulated subject does with the arm: the posture it holds (rest,
//! or about 45° while a period runs, moved smoothly), and in the
//! amplification experiments a voluntary sinusoid on top. The impedance pulls
//! the forearm towards this equilibrium (equilibrium-point control).

use exo_messages::ProtocolPhase;

use crate::plant::HumanDrive;

/// The subject's posture and voluntary motion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PostureDrive {
    rest_rad: f64,
    active_rad: f64,
    voluntary: Option<(f64, f64)>,
    time_constant_s: f64,
    posture_rad: f64,
    motion_t_s: f64,
    goal_offset_rad: f64,
}

impl PostureDrive {
    /// A subject resting at `rest_rad`, raising the arm to `active_rad`
    /// during a period; with `voluntary = Some((amplitude_rad, omega_rad_s))`
    /// it also moves sinusoidally while the perturbation phases run.
    pub fn new(rest_rad: f64, active_rad: f64, voluntary: Option<(f64, f64)>) -> Self {
        PostureDrive {
            rest_rad,
            active_rad,
            voluntary,
            time_constant_s: 0.5,
            posture_rad: rest_rad,
            motion_t_s: 0.0,
            goal_offset_rad: 0.0,
        }
    }

    /// Moves the reference of the active phases by `offset_rad` from
    /// `active_rad` (a subject that holds its goal against a bias,
    /// [`crate::model::PostureReference::HoldsGoal`]); 0 by default.
    pub fn set_goal_offset(&mut self, offset_rad: f64) {
        if offset_rad.is_finite() {
            self.goal_offset_rad = offset_rad;
        }
    }

    /// Advances `dt_s` in protocol `phase` and returns the equilibrium the
    /// impedance pulls towards. The arm is raised from the bias's ramp-in to
    /// its ramp-out; the voluntary motion runs while the perturbation does
    /// (settling and analysis).
    pub fn update(&mut self, dt_s: f64, phase: ProtocolPhase) -> HumanDrive {
        use ProtocolPhase::*;
        let target = match phase {
            RampIn | Settling | Analysis | RampOut => self.active_rad + self.goal_offset_rad,
            Idle | Rest => self.rest_rad,
        };
        let a = (-dt_s / self.time_constant_s).exp();
        let previous = self.posture_rad;
        self.posture_rad = target + (self.posture_rad - target) * a;
        let posture_rate = (self.posture_rad - previous) / dt_s;
        let (mut theta, mut omega) = (self.posture_rad, posture_rate);
        if let Some((amp, w)) = self.voluntary {
            if matches!(phase, Settling | Analysis) {
                self.motion_t_s += dt_s;
                theta += amp * (w * self.motion_t_s).sin();
                omega += amp * w * (w * self.motion_t_s).cos();
            } else {
                self.motion_t_s = 0.0;
            }
        }
        HumanDrive {
            theta_eq_rad: theta,
            omega_eq_rad_s: omega,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raises_the_arm_during_a_period_and_lowers_it_at_rest() {
        let mut d = PostureDrive::new(0.3, 0.8, None);
        let mut last = HumanDrive::default();
        for _ in 0..5000 {
            last = d.update(1e-3, ProtocolPhase::RampIn);
        }
        assert!((last.theta_eq_rad - 0.8).abs() < 1e-3);
        for _ in 0..5000 {
            last = d.update(1e-3, ProtocolPhase::Rest);
        }
        assert!((last.theta_eq_rad - 0.3).abs() < 1e-3);
    }

    #[test]
    fn voluntary_motion_is_a_sinusoid_about_the_posture() {
        let mut d = PostureDrive::new(0.8, 0.8, Some((0.1, 10.0)));
        let mut drive = HumanDrive::default();
        for _ in 0..157 {
            drive = d.update(1e-3, ProtocolPhase::Analysis);
        }
        // A quarter period of 10 rad/s is 157 ms: at the crest.
        assert!((drive.theta_eq_rad - 0.9).abs() < 1e-3, "{drive:?}");
    }
}
