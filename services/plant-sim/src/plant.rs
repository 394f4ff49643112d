//! The simulated plant: state-space assembly from the plant model, exact
//! zero-order-hold stepping, and the raw sensor readings a rig would deliver.
//!
//! States (SI units): exoskeleton angle and velocity; forearm angle and
//! velocity when the cuff is compliant (otherwise forearm and exoskeleton
//! move together); SEA torque and its rate when the SEA has dynamics; one
//! internal state per Prony element. Inputs held over a step: the motor
//! torque command (after the actuator delay and saturation), the posture
//! the human holds `θ_eq` and its rate, and the nonlinear exoskeleton torques
//! (gravity `−g(m_a l_a + m_L l_L) sin θ_e`, Coulomb friction) evaluated at
//! the start of the step. With backlash in the joint (`[exo.backlash]`)
//! the SEA's torque drives a motor side (angle, velocity) stepped beside
//! the linear part, and the gear mesh's torque reaches the arm through the
//! nonlinear input.
//!
//! Sign convention (the paper's): `τ_c` is the torque the cuff applies to
//! the human; the human's impedance pulls the forearm back towards `θ_eq`.

use nalgebra::{DMatrix, DVector};

use crate::model::{HysteresisMode, PlantModel};
use crate::prony::PronyBank;
use crate::rng::Rng;
use numerics::{apply_cols, apply_cols_any, Delay, SineNear};

mod assembly;
mod numerics;

const U_TAU_D: usize = 0;
const U_THETA_EQ: usize = 1;
const U_OMEGA_EQ: usize = 2;
const U_TAU_NL: usize = 3;
/// Torque on the human joint from the stretch reflex (`[human.stretch_reflex]`).
const U_TAU_REFLEX: usize = 4;
const N_INPUTS: usize = 5;

/// What the human does (set by the caller each control period).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HumanDrive {
    /// Equilibrium posture `θ_eq` (rad) the impedance pulls towards.
    pub theta_eq_rad: f64,
    /// Its rate (rad/s).
    pub omega_eq_rad_s: f64,
}

/// Noise-free physical values (for tests and diagnostics).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlantTruth {
    /// Simulated time (s).
    pub t_s: f64,
    /// Exoskeleton angle θ_e (rad).
    pub theta_e_rad: f64,
    /// Exoskeleton velocity (rad/s).
    pub omega_e_rad_s: f64,
    /// Forearm angle (rad).
    pub theta_h_rad: f64,
    /// Interaction torque τ_c (Nm): cuff on human.
    pub tau_c_nm: f64,
    /// SEA spring torque τ_s (Nm).
    pub tau_s_nm: f64,
    /// Gravity torque on the exoskeleton (Nm), `+g(...) sin θ` (the controller's compensation target).
    pub tau_g_nm: f64,
}

/// Raw readings, as the bus delivers them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RawSensors {
    /// Joint encoder counts.
    pub encoder_counts: i64,
    /// Cuff wrench `[f_x, f_y, f_z, t_x, t_y, t_z]` (N, Nm).
    pub cuff_wrench: [f64; 6],
    /// SEA deflection counts.
    pub sea_deflection_counts: i64,
}

#[derive(Debug, Clone, Copy)]
struct Layout {
    th_e: usize,
    w_e: usize,
    th_h: usize,
    w_h: usize,
    sea: Option<usize>,
    z0: usize,
    n_z: usize,
    n: usize,
}

/// The plant.
#[derive(Debug, Clone)]
pub struct Plant {
    model: PlantModel,
    k_h: f64,
    h_h: f64,
    load_kg: f64,
    excitation_omega: f64,
    layout: Layout,
    bank: PronyBank,
    b_human: f64,
    /// `[Φ Γ]` of one step, column by column (`n × (n + N_INPUTS)`,
    /// column-major): `x⁺ = Σ_j [Φ Γ]_j [x; u]_j`, each column a vector
    /// operation over the states.
    phi_gamma_cols: Vec<f64>,
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    /// The rigid cuff's torque as a row over `[x u]` (`n + N_INPUTS`):
    /// `τ_c = row · [x u] − K_tot θ_eq − B_h ω_eq`, the forearm's
    /// `M_h ω̇_e` less its impedance torque and the reflex
    /// (see [`Plant::tau_c_nm`]); empty with a compliant cuff.
    tau_c_row: Vec<f64>,
    /// `K_∞ + Σ k_i` of the bank (Nm/rad), the impedance's static stiffness.
    k_total: f64,
    gravity_sine: SineNear,
    x: DVector<f64>,
    x_next: DVector<f64>,
    u: DVector<f64>,
    t_s: f64,
    drive: HumanDrive,
    actuator_delay: Delay,
    /// The stretch reflex: the joint velocity delayed, and its two low-pass states.
    reflex_delay: Delay,
    reflex_lp: [f64; 2],
    /// Per-step gain of each low-pass section, `1 − e^{−ω_c h}`.
    reflex_alpha: f64,
    theta_delay: Delay,
    tau_c_delay: Delay,
    /// With no cuff-sensor delay, the last step's τ_c is computed only when
    /// it is read ([`Plant::settle_tau_c`]): one sample in ten is.
    tau_c_pending: bool,
    tau_s_delay: Delay,
    tau_d_held: f64,
    external_torque_nm: f64,
    /// The motor side of a joint with backlash (`[exo.backlash]`): its
    /// angle (rad) and velocity (rad/s); unused without backlash.
    motor: [f64; 2],
    /// Simulated time (s) at which the running experiment started (the
    /// origin of `human.stiffness_drift_per_min`).
    drift_origin_s: f64,
    rng: Rng,
}

fn steps_of(delay_s: f64, h: f64) -> usize {
    (delay_s / h).round() as usize
}

impl Plant {
    /// A plant at rest at the human's rest posture.
    pub fn new(model: &PlantModel) -> Self {
        let h = model.integration.step_s;
        let mut p = Plant {
            model: *model,
            k_h: model.human.stiffness_nm_per_rad,
            h_h: model.human.stiffness_nm_per_rad * model.human.hysteretic_damping.loss_factor,
            load_kg: model.exo.load_kg,
            excitation_omega: model.human.hysteretic_damping.reference_rad_s,
            layout: Layout {
                th_e: 0,
                w_e: 1,
                th_h: 0,
                w_h: 1,
                sea: None,
                z0: 2,
                n_z: 0,
                n: 2,
            },
            bank: PronyBank {
                k_inf_nm_per_rad: 0.0,
                k_nm_per_rad: vec![],
                tau_s: vec![],
            },
            b_human: 0.0,
            phi_gamma_cols: Vec::new(),
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 0),
            tau_c_row: Vec::new(),
            k_total: 0.0,
            gravity_sine: SineNear::new(model.human.rest_angle_rad),
            x: DVector::zeros(0),
            x_next: DVector::zeros(0),
            u: DVector::zeros(N_INPUTS),
            t_s: 0.0,
            drive: HumanDrive {
                theta_eq_rad: model.human.rest_angle_rad,
                omega_eq_rad_s: 0.0,
            },
            actuator_delay: Delay::new(steps_of(model.actuator.delay_s, h), 0.0),
            reflex_delay: Delay::new(steps_of(model.human.stretch_reflex.delay_s, h), 0.0),
            reflex_lp: [0.0; 2],
            reflex_alpha: 1.0
                - (-model.human.stretch_reflex.cutoff_rad_s * model.integration.step_s).exp(),
            theta_delay: Delay::new(
                steps_of(model.sensors.encoder.terms.delay_s, h),
                model.human.rest_angle_rad,
            ),
            tau_c_delay: Delay::new(steps_of(model.sensors.cuff_ft.terms.delay_s, h), 0.0),
            tau_c_pending: false,
            tau_s_delay: Delay::new(steps_of(model.sensors.sea_deflection.terms.delay_s, h), 0.0),
            tau_d_held: 0.0,
            external_torque_nm: 0.0,
            motor: [model.human.rest_angle_rad, 0.0],
            drift_origin_s: 0.0,
            rng: Rng::new(model.integration.seed),
        };
        p.rebuild();
        let rest = model.human.rest_angle_rad;
        p.x[p.layout.th_e] = rest;
        p.x[p.layout.th_h] = rest;
        p
    }

    /// Marks the start of an experiment: the human's stiffness drift
    /// (`human.stiffness_drift_per_min`) counts from now.
    pub fn start_experiment_clock(&mut self) {
        self.drift_origin_s = self.t_s;
    }

    /// Time (s) since the current experiment started
    /// ([`start_experiment_clock`](Self::start_experiment_clock)): what
    /// the human's stiffness drift has run for.
    pub fn experiment_elapsed_s(&self) -> f64 {
        self.t_s - self.drift_origin_s
    }

    /// The model.
    pub fn model(&self) -> &PlantModel {
        &self.model
    }

    /// The human's stiffness `K` and hysteretic damping `H` (Nm/rad) now.
    pub fn human_impedance(&self) -> (f64, f64) {
        (self.k_h, self.h_h)
    }

    /// The load on the exoskeleton arm (kg) now.
    pub fn load_kg(&self) -> f64 {
        self.load_kg
    }

    /// The running excitation frequency (rad/s) the hysteresis follows.
    pub fn excitation_omega_rad_s(&self) -> f64 {
        self.excitation_omega
    }

    /// The external torque (Nm) on the exoskeleton joint now.
    pub fn external_torque_nm(&self) -> f64 {
        self.external_torque_nm
    }

    /// Sets the human's stiffness `K` and hysteretic damping `H` (Nm/rad).
    pub fn set_human_impedance(&mut self, k_nm_per_rad: f64, h_nm_per_rad: f64) {
        if (k_nm_per_rad, h_nm_per_rad) != (self.k_h, self.h_h)
            && k_nm_per_rad > 0.0
            && h_nm_per_rad >= 0.0
        {
            self.k_h = k_nm_per_rad;
            self.h_h = h_nm_per_rad;
            self.rebuild();
        }
    }

    /// Sets the load on the exoskeleton arm (kg).
    pub fn set_load_kg(&mut self, load_kg: f64) {
        if load_kg != self.load_kg && load_kg.is_finite() && load_kg >= 0.0 {
            self.load_kg = load_kg;
            self.rebuild();
        }
    }

    /// Sets the running excitation frequency (rad/s) used by the
    /// equivalent-viscous hysteresis mode (`B_eq = H/ω`) and by the
    /// prony-matched mode (its corrections make `K + jH` exact there).
    pub fn set_excitation_omega(&mut self, omega_rad_s: f64) {
        let uses_it = self.model.human.hysteretic_damping.enabled
            && matches!(
                self.model.human.hysteretic_damping.mode,
                HysteresisMode::EquivalentViscous | HysteresisMode::PronyMatched
            );
        if uses_it
            && omega_rad_s > 0.0
            && omega_rad_s.is_finite()
            && omega_rad_s != self.excitation_omega
        {
            self.excitation_omega = omega_rad_s;
            self.rebuild();
        }
    }

    /// Sets an external torque (Nm) on the exoskeleton joint, e.g. the test
    /// springs of the paper's post-tuning test (positive = raising the arm).
    /// It is not seen by the cuff sensor; non-finite values are ignored.
    pub fn set_external_torque_nm(&mut self, tau_nm: f64) {
        if tau_nm.is_finite() {
            self.external_torque_nm = tau_nm;
        }
    }

    /// Sets what the human does.
    pub fn set_drive(&mut self, drive: HumanDrive) {
        if drive.theta_eq_rad.is_finite() && drive.omega_eq_rad_s.is_finite() {
            self.settle_tau_c();
            self.drive = drive;
        }
    }

    /// Pushes the last step's τ_c into its (zero-length) delay line if it
    /// has not been yet: before it is read, and before anything it depends
    /// on (the state space, the drive) changes.
    fn settle_tau_c(&mut self) {
        if self.tau_c_pending {
            self.tau_c_pending = false;
            let tau_c = self.tau_c_nm();
            self.tau_c_delay.push(tau_c);
        }
    }

    fn nonlinear_torque(&mut self) -> f64 {
        let (th, w) = (self.x[self.layout.th_e], self.x[self.layout.w_e]);
        let mut tau = self.external_torque_nm - self.gravity_torque_tracked(th);
        if self.model.exo.backlash.enabled() {
            tau += self.mesh_torque();
        }
        let c = self.model.joint_friction.coulomb;
        if c.enabled {
            tau -= c.torque_nm * (w / c.smoothing_rad_s).tanh();
        }
        tau
    }

    /// `g (m_a l_a + m_L l_L)` (Nm) with the current load, 0 when gravity
    /// is off ([`PlantModel::gravity_moment_nm`]).
    fn gravity_moment_nm(&self) -> f64 {
        self.model.gravity_moment_nm(self.load_kg)
    }

    /// The gravity torque at `theta` (Nm): `g (m_a l_a + m_L l_L) sin θ`,
    /// with the current load.
    pub fn gravity_torque(&self, theta: f64) -> f64 {
        let moment = self.gravity_moment_nm();
        if moment == 0.0 {
            return 0.0;
        }
        moment * theta.sin()
    }

    /// [`Plant::gravity_torque`] on the integration path, its sine carried
    /// from step to step ([`SineNear`]) instead of a `sin` per step.
    fn gravity_torque_tracked(&mut self, theta: f64) -> f64 {
        let moment = self.gravity_moment_nm();
        if moment == 0.0 {
            return 0.0;
        }
        moment * self.gravity_sine.sin(theta)
    }

    /// Advances one integration step with motor command `tau_d_nm`. Allocation-free.
    pub fn step(&mut self, tau_d_nm: f64) {
        let limit = self.model.sea.torque_limit_nm;
        let cmd = if tau_d_nm.is_finite() {
            tau_d_nm.clamp(-limit, limit)
        } else {
            0.0
        };
        self.tau_d_held = self.actuator_delay.push(cmd);
        self.u[U_TAU_D] = self.tau_d_held;
        self.u[U_THETA_EQ] = self.drive.theta_eq_rad;
        self.u[U_OMEGA_EQ] = self.drive.omega_eq_rad_s;
        self.u[U_TAU_NL] = self.nonlinear_torque();
        self.u[U_TAU_REFLEX] = self.reflex_torque()
            + self.cubic_spring_torque()
            + self.quadratic_spring_torque()
            + self.cubic_damper_torque()
            + self.drift_spring_torque();
        let (x, u) = (self.x.as_slice(), self.u.as_slice());
        let (cols, next) = (&self.phi_gamma_cols, self.x_next.as_mut_slice());
        // Up to 16 states (rigid cuff with the SEA: 4; compliant: 6; a
        // Prony bank adds one per element) with the size known to the
        // compiler, so the product is unrolled; larger ones in a loop.
        match x.len() {
            2 => apply_cols::<2>(cols, x, u, next),
            3 => apply_cols::<3>(cols, x, u, next),
            4 => apply_cols::<4>(cols, x, u, next),
            5 => apply_cols::<5>(cols, x, u, next),
            6 => apply_cols::<6>(cols, x, u, next),
            7 => apply_cols::<7>(cols, x, u, next),
            8 => apply_cols::<8>(cols, x, u, next),
            9 => apply_cols::<9>(cols, x, u, next),
            10 => apply_cols::<10>(cols, x, u, next),
            11 => apply_cols::<11>(cols, x, u, next),
            12 => apply_cols::<12>(cols, x, u, next),
            13 => apply_cols::<13>(cols, x, u, next),
            14 => apply_cols::<14>(cols, x, u, next),
            15 => apply_cols::<15>(cols, x, u, next),
            16 => apply_cols::<16>(cols, x, u, next),
            _ => apply_cols_any(cols, x, u, next),
        }
        std::mem::swap(&mut self.x, &mut self.x_next);
        self.t_s += self.model.integration.step_s;
        self.drive.theta_eq_rad += self.drive.omega_eq_rad_s * self.model.integration.step_s;
        self.advance_reflex();
        self.theta_delay.push(self.x[self.layout.th_e]);
        if self.tau_c_delay.buf.len() == 1 {
            self.tau_c_pending = true;
        } else {
            self.tau_c_delay.push(self.tau_c_nm());
        }
        self.tau_s_delay.push(self.tau_s_nm());
    }

    /// Advances `duration_s` (rounded to whole steps) with the command held.
    pub fn advance(&mut self, duration_s: f64, tau_d_nm: f64) {
        let n = (duration_s / self.model.integration.step_s).round() as usize;
        for _ in 0..n {
            self.step(tau_d_nm);
        }
    }

    /// The stretch reflex's torque on the human joint (Nm):
    /// `−G · LP(θ̇_h(t − δ))`, 0 when the term is off.
    fn reflex_torque(&self) -> f64 {
        let r = self.model.human.stretch_reflex;
        if r.enabled {
            -r.gain_nm_s_per_rad * self.reflex_lp[1]
        } else {
            0.0
        }
    }

    /// The cubic part of the human's spring on the human joint (Nm):
    /// `−K₃ (θ_h − θ_eq)³`, held over the step like the reflex; 0 when
    /// `human.cubic_stiffness_nm_per_rad3` is 0.
    fn cubic_spring_torque(&self) -> f64 {
        let k3 = self.model.human.cubic_stiffness_nm_per_rad3;
        if k3 == 0.0 {
            return 0.0;
        }
        let d = self.x[self.layout.th_h] - self.drive.theta_eq_rad;
        -k3 * d * d * d
    }

    /// The quadratic part of the human's spring on the human joint (Nm):
    /// `−½ K₂ (θ_h − θ_eq)²` (a stiffness `K + K₂ (θ_h − θ_eq)` that depends
    /// on posture), held over the step like the reflex; 0 when
    /// `human.quadratic_stiffness_nm_per_rad2` is 0.
    fn quadratic_spring_torque(&self) -> f64 {
        let k2 = self.model.human.quadratic_stiffness_nm_per_rad2;
        if k2 == 0.0 {
            return 0.0;
        }
        let d = self.x[self.layout.th_h] - self.drive.theta_eq_rad;
        -0.5 * k2 * d * d
    }

    /// The human's cubic damper on the human joint (Nm):
    /// `−B₃ (ω_h − ω_eq)³` (about the drive's own motion, as the linear
    /// damper), held over the step like the reflex; 0 when
    /// `human.cubic_damping_nm_s3_per_rad3` is 0.
    fn cubic_damper_torque(&self) -> f64 {
        let b3 = self.model.human.cubic_damping_nm_s3_per_rad3;
        if b3 == 0.0 {
            return 0.0;
        }
        let w = self.x[self.layout.w_h] - self.drive.omega_eq_rad_s;
        -b3 * w * w * w
    }

    /// The drifting part of the human's spring on the human joint (Nm):
    /// `−K ρ (t − t₀)/60 (θ_h − θ_eq)`, `t₀` the experiment's start
    /// ([`Plant::start_experiment_clock`]), held over the step like the
    /// reflex; 0 when `human.stiffness_drift_per_min` is 0.
    fn drift_spring_torque(&self) -> f64 {
        let rho = self.model.human.stiffness_drift_per_min;
        if rho == 0.0 {
            return 0.0;
        }
        let d = self.x[self.layout.th_h] - self.drive.theta_eq_rad;
        -self.k_h * rho * (self.t_s - self.drift_origin_s) / 60.0 * d
    }

    /// The backlash mesh's torque on the arm (Nm) at the step's start, and
    /// the motor side advanced over the step under the SEA's torque less
    /// the mesh's (semi-implicit Euler: the mesh's mode is at most
    /// 0.5 rad per step, `PlantModel::validate`).
    fn mesh_torque(&mut self) -> f64 {
        let bl = self.model.exo.backlash;
        let (th, w) = (self.x[self.layout.th_e], self.x[self.layout.w_e]);
        let [th_m, w_m] = self.motor;
        let tau_mesh = bl.mesh_torque_nm(th_m - th, w_m - w);
        let h = self.model.integration.step_s;
        let w_m = w_m + h * (self.tau_s_nm() - tau_mesh) / bl.motor_inertia_kg_m2;
        self.motor = [th_m + h * w_m, w_m];
        tau_mesh
    }

    /// Feeds the stretch velocity through the reflex's delay and its two
    /// first-order low-pass sections (exact for a held input).
    fn advance_reflex(&mut self) {
        let r = self.model.human.stretch_reflex;
        if !r.enabled {
            return;
        }
        let stretch_rate = self.x[self.layout.w_h] - self.drive.omega_eq_rad_s;
        let v = self.reflex_delay.push(stretch_rate);
        let a = self.reflex_alpha;
        self.reflex_lp[0] += a * (v - self.reflex_lp[0]);
        self.reflex_lp[1] += a * (self.reflex_lp[0] - self.reflex_lp[1]);
    }

    /// The forearm's impedance torque (Nm) at the current state and drive.
    #[cfg(test)]
    fn impedance_torque(&self) -> f64 {
        let l = self.layout;
        let x = &self.x;
        let th_h = x[l.th_h];
        let mut tau = -self.bank.k_inf_nm_per_rad * (th_h - self.drive.theta_eq_rad)
            - self.b_human * (x[l.w_h] - self.drive.omega_eq_rad_s);
        for (i, k) in self.bank.k_nm_per_rad.iter().enumerate() {
            tau -= k * (th_h - self.drive.theta_eq_rad - x[l.z0 + i]);
        }
        tau
    }

    /// The noise-free physical state.
    pub fn truth(&self) -> PlantTruth {
        let l = self.layout;
        let x = &self.x;
        PlantTruth {
            t_s: self.t_s,
            theta_e_rad: x[l.th_e],
            omega_e_rad_s: x[l.w_e],
            theta_h_rad: x[l.th_h],
            tau_c_nm: self.tau_c_nm(),
            tau_s_nm: self.tau_s_nm(),
            tau_g_nm: self.gravity_torque(x[l.th_e]),
        }
    }

    /// The SEA spring torque τ_s (Nm), noise-free; the held command when
    /// the SEA term is off.
    fn tau_s_nm(&self) -> f64 {
        match self.layout.sea {
            Some(s) => self.x[s],
            None => self.tau_d_held,
        }
    }

    /// The torque τ_c (Nm) the cuff applies to the forearm, noise-free.
    fn tau_c_nm(&self) -> f64 {
        let l = self.layout;
        let x = &self.x;
        if self.model.cuff.compliance.enabled {
            let c = self.model.cuff.compliance;
            c.stiffness_nm_per_rad * (x[l.th_e] - x[l.th_h])
                + c.damping_nm_s_per_rad * (x[l.w_e] - x[l.w_h])
        } else {
            // Rigid: the cuff supplies what accelerates the forearm against
            // its impedance and the reflex (`tau_c_row`).
            let (row_x, row_u) = self.tau_c_row.split_at(l.n);
            let mut acc = 0.0;
            for (r, xj) in row_x.iter().zip(x.iter()) {
                acc += r * xj;
            }
            for (r, uj) in row_u.iter().zip(self.u.iter()) {
                acc += r * uj;
            }
            acc - self.k_total * self.drive.theta_eq_rad - self.b_human * self.drive.omega_eq_rad_s
        }
    }

    /// The raw sensor readings now (delayed, with gain, offset, noise and quantisation).
    pub fn raw_sensors(&mut self) -> RawSensors {
        self.settle_tau_c();
        let s = self.model.sensors;
        let tau = std::f64::consts::TAU;
        let e = s.encoder.terms;
        let theta =
            e.gain * self.theta_delay.oldest() + e.offset + e.noise_std * self.rng.gaussian();
        let encoder_counts = (theta / tau * s.encoder.counts_per_rev).round() as i64;
        let f = s.cuff_ft.terms;
        let tau_c =
            f.gain * self.tau_c_delay.oldest() + f.offset + f.noise_std * self.rng.gaussian();
        let mut f_y = tau_c / s.cuff_ft.lever_arm_m;
        if s.cuff_ft.force_resolution_n > 0.0 {
            f_y = (f_y / s.cuff_ft.force_resolution_n).round() * s.cuff_ft.force_resolution_n;
        }
        let d = s.sea_deflection.terms;
        let tau_s =
            d.gain * self.tau_s_delay.oldest() + d.offset + d.noise_std * self.rng.gaussian();
        let deflection = tau_s / self.model.sea.spring_stiffness_nm_per_rad;
        RawSensors {
            encoder_counts,
            cuff_wrench: [0.0, f_y, 0.0, 0.0, 0.0, 0.0],
            sea_deflection_counts: (deflection / tau * s.sea_deflection.counts_per_rev).round()
                as i64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn default_model() -> PlantModel {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../configs/plants/default.toml");
        PlantModel::from_file(&path).unwrap()
    }

    #[test]
    fn the_rigid_cuff_torque_row_is_the_forearms_balance() {
        // τ_c = M_h ω̇_e − τ_imp − τ_reflex, written out from A, B and the
        // impedance, against the precomputed row, with every term of the
        // row on: viscous damping, the reflex, gravity, a moving drive.
        let mut m = default_model();
        m.human.viscous_damping.enabled = true;
        m.human.viscous_damping.b_nm_s_per_rad = 0.8;
        m.human.stretch_reflex.enabled = true;
        m.human.stretch_reflex.gain_nm_s_per_rad = 2.0;
        m.human.stretch_reflex.delay_s = 0.001;
        assert!(!m.cuff.compliance.enabled);
        let mut p = Plant::new(&m);
        p.set_human_impedance(40.0, 12.0);
        p.set_excitation_omega(6.0);
        p.set_drive(HumanDrive {
            theta_eq_rad: 0.5,
            omega_eq_rad_s: 0.3,
        });
        let mut checked = 0;
        for i in 0..3000 {
            p.step(4.0 * (i as f64 * 0.004).sin());
            let l = p.layout;
            let mut acc = 0.0;
            for j in 0..l.n {
                acc += p.a[(l.w_e, j)] * p.x[j];
            }
            for j in 0..N_INPUTS {
                acc += p.b[(l.w_e, j)] * p.u[j];
            }
            let reference = m.human.inertia_kg_m2 * acc - p.impedance_torque() - p.u[U_TAU_REFLEX];
            let got = p.tau_c_nm();
            assert!(
                (got - reference).abs() <= 1e-9 * (1.0 + reference.abs()),
                "step {i}: {got} vs {reference}"
            );
            checked += usize::from(reference.abs() > 0.1);
        }
        assert!(checked > 1000, "the torque was too small to check");
    }

    #[test]
    fn an_undelayed_cuff_reading_is_the_torque_at_the_end_of_the_last_step() {
        // τ_c of a step is computed when read; a change of drive or of the
        // human's impedance between the step and the reading must not
        // change what is read.
        let mut m = default_model();
        m.sensors.cuff_ft.terms.delay_s = 0.0;
        m.sensors.cuff_ft.terms.noise_std = 0.0;
        m.sensors.cuff_ft.terms.gain = 1.0;
        m.sensors.cuff_ft.terms.offset = 0.0;
        m.sensors.cuff_ft.force_resolution_n = 0.0;
        let lever = m.sensors.cuff_ft.lever_arm_m;
        let mut p = Plant::new(&m);
        for i in 0..500 {
            p.step(3.0 * (i as f64 * 0.01).sin());
            let expected = p.truth().tau_c_nm;
            if i % 3 == 0 {
                p.set_drive(HumanDrive {
                    theta_eq_rad: 0.2 + 1e-3 * i as f64,
                    omega_eq_rad_s: 0.5,
                });
            }
            if i % 7 == 0 {
                p.set_human_impedance(30.0 + i as f64, 10.0);
            }
            if i % 2 == 0 {
                let read = p.raw_sensors().cuff_wrench[1] * lever;
                assert!(
                    (read - expected).abs() <= 1e-12 * (1.0 + expected.abs()),
                    "step {i}: read {read}, torque at the step's end {expected}"
                );
            }
        }
    }
}
