//! The plant's state space assembled from the plant model and the current
//! settings (human impedance, load, excitation), and its zero-order-hold
//! discretisation: [`Plant::rebuild`], run on parameter changes only.

use nalgebra::{DMatrix, DVector};

use super::{Layout, Plant, N_INPUTS, U_OMEGA_EQ, U_TAU_D, U_TAU_NL, U_TAU_REFLEX, U_THETA_EQ};
use crate::expm::zoh;
use crate::model::HysteresisMode;
use crate::prony::PronyBank;

impl Plant {
    /// Rebuilds the state space and its discretisation (on parameter changes only).
    pub(super) fn rebuild(&mut self) {
        self.settle_tau_c();
        let m = &self.model;
        let hd = m.human.hysteretic_damping;
        let spring = PronyBank {
            k_inf_nm_per_rad: self.k_h,
            k_nm_per_rad: vec![],
            tau_s: vec![],
        };
        let mut equivalent_viscous = hd.enabled && hd.mode == HysteresisMode::EquivalentViscous;
        let bank = if !(hd.enabled && self.h_h > 0.0) {
            spring
        } else {
            match hd.mode {
                HysteresisMode::EquivalentViscous => spring,
                HysteresisMode::Prony => PronyBank::fit(
                    self.k_h,
                    self.h_h / self.k_h,
                    hd.band_rad_s,
                    hd.elements_per_decade,
                    hd.reference_rad_s,
                )
                .unwrap_or(spring),
                // Exact at the excitation; should the band not allow it
                // (`K_∞ < 0`, a loss factor far above the paper's), the
                // equivalent viscous damping is exact there too.
                HysteresisMode::PronyMatched => PronyBank::fit_matched(
                    self.k_h,
                    self.h_h,
                    self.excitation_omega,
                    hd.matched_band_decades,
                    hd.elements_per_decade,
                )
                .unwrap_or_else(|_| {
                    equivalent_viscous = true;
                    spring
                }),
            }
        };
        // The old bank's elastic torque and relaxation rate at the current
        // deviation, which the new bank takes over (no torque step on a
        // change of bank).
        let old_layout = self.layout;
        let remap = (self.x.len() == old_layout.n && bank != self.bank)
            .then(|| {
                let xi = self.x[old_layout.th_h] - self.drive.theta_eq_rad;
                let strains: Vec<f64> = (0..old_layout.n_z)
                    .map(|i| xi - self.x[old_layout.z0 + i])
                    .collect();
                let torque = self.bank.elastic_torque(xi, &strains);
                let rate = self.bank.relaxation_rate(&strains);
                bank.strains_carrying(xi, torque, rate)
                    .map(|s| s.iter().map(|s| xi - s).collect::<Vec<f64>>())
            })
            .flatten();
        self.bank = bank;
        let mut b_h = if m.human.viscous_damping.enabled {
            m.human.viscous_damping.b_nm_s_per_rad
        } else {
            0.0
        };
        if equivalent_viscous {
            b_h += self.h_h / self.excitation_omega;
        }
        self.b_human = b_h;
        let compliant = m.cuff.compliance.enabled;
        let sea = m.sea.dynamics.enabled;
        let n_z = self.bank.k_nm_per_rad.len();
        let mut n = 2;
        let (th_h, w_h) = if compliant {
            n += 2;
            (2, 3)
        } else {
            (0, 1)
        };
        let sea_idx = if sea {
            n += 2;
            Some(n - 2)
        } else {
            None
        };
        let z0 = n;
        n += n_z;
        let l = Layout {
            th_e: 0,
            w_e: 1,
            th_h,
            w_h,
            sea: sea_idx,
            z0,
            n_z,
            n,
        };

        let m_h = m.human.inertia_kg_m2;
        // With backlash the SEA drives the motor side, which the mesh
        // couples to the arm through `U_TAU_NL` ([`Plant::mesh_torque`]).
        let m_e = m.arm_side_inertia_kg_m2(self.load_kg);
        let backlash = m.exo.backlash.enabled();
        let b_f = if m.joint_friction.viscous.enabled {
            m.joint_friction.viscous.b_nm_s_per_rad
        } else {
            0.0
        };
        let k_total = self.bank.k_inf_nm_per_rad + self.bank.k_nm_per_rad.iter().sum::<f64>();
        let mut a = DMatrix::<f64>::zeros(n, n);
        let mut b = DMatrix::<f64>::zeros(n, N_INPUTS);
        // Impedance torque on the human, as a row over states and inputs, with
        // the deviation ξ = θ_h − θ_eq from the held posture and z_i the
        // dashpot extension of Maxwell element i:
        // τ_imp = −K_∞ ξ − Σ k_i (ξ − z_i) − B (ω_h − ω_eq).
        let mut imp_x = DVector::<f64>::zeros(n);
        let mut imp_u = DVector::<f64>::zeros(N_INPUTS);
        imp_x[th_h] -= k_total;
        imp_x[w_h] -= b_h;
        imp_u[U_THETA_EQ] += k_total;
        imp_u[U_OMEGA_EQ] += b_h;
        for (i, k) in self.bank.k_nm_per_rad.iter().enumerate() {
            imp_x[z0 + i] += k;
        }
        // Maxwell elements: ż_i = (ξ − z_i)/τ_i (dashpot k_i τ_i in series with spring k_i).
        for (i, tau) in self.bank.tau_s.iter().enumerate() {
            a[(z0 + i, th_h)] = 1.0 / tau;
            a[(z0 + i, z0 + i)] = -1.0 / tau;
            b[(z0 + i, U_THETA_EQ)] = -1.0 / tau;
        }
        // Actuator torque on the exoskeleton.
        let mut act_x = DVector::<f64>::zeros(n);
        let mut act_u = DVector::<f64>::zeros(N_INPUTS);
        match sea_idx {
            Some(s) => {
                let wn = 2.0 * std::f64::consts::PI * m.sea.dynamics.natural_frequency_hz;
                let z = m.sea.dynamics.damping_ratio;
                a[(s, s + 1)] = 1.0;
                a[(s + 1, s)] = -wn * wn;
                a[(s + 1, s + 1)] = -2.0 * z * wn;
                b[(s + 1, U_TAU_D)] = wn * wn;
                if !backlash {
                    act_x[s] = 1.0;
                }
            }
            None if !backlash => act_u[U_TAU_D] = 1.0,
            None => {}
        }
        a[(0, 1)] = 1.0;
        if compliant {
            let (kc, bc) = (
                m.cuff.compliance.stiffness_nm_per_rad,
                m.cuff.compliance.damping_nm_s_per_rad,
            );
            // Cuff torque on the human: kc (θ_e − θ_h) + bc (ω_e − ω_h).
            let mut cuff = DVector::<f64>::zeros(n);
            cuff[0] = kc;
            cuff[th_h] -= kc;
            cuff[1] = bc;
            cuff[w_h] -= bc;
            a[(th_h, w_h)] = 1.0;
            for j in 0..n {
                a[(w_h, j)] += (imp_x[j] + cuff[j]) / m_h;
                a[(1, j)] += (act_x[j] - cuff[j]) / m_e;
            }
            a[(1, 1)] -= b_f / m_e;
            for j in 0..N_INPUTS {
                b[(w_h, j)] += imp_u[j] / m_h;
                b[(1, j)] += act_u[j] / m_e;
            }
            b[(1, U_TAU_NL)] += 1.0 / m_e;
            b[(w_h, U_TAU_REFLEX)] += 1.0 / m_h;
        } else {
            let m_tot = m_e + m_h;
            for j in 0..n {
                a[(1, j)] += (imp_x[j] + act_x[j]) / m_tot;
            }
            a[(1, 1)] -= b_f / m_tot;
            for j in 0..N_INPUTS {
                b[(1, j)] += (imp_u[j] + act_u[j]) / m_tot;
            }
            b[(1, U_TAU_NL)] += 1.0 / m_tot;
            b[(1, U_TAU_REFLEX)] += 1.0 / m_tot;
        }
        // The rigid cuff's torque: what accelerates the forearm
        // (M_h ω̇_e, from the rows of A and B) less the forearm's impedance
        // torque (imp_x·x + K_tot θ_eq + B_h ω_eq) and the reflex.
        self.tau_c_row = if compliant {
            Vec::new()
        } else {
            (0..n)
                .map(|j| m_h * a[(1, j)] - imp_x[j])
                .chain(
                    (0..N_INPUTS).map(|j| m_h * b[(1, j)] - f64::from(u8::from(j == U_TAU_REFLEX))),
                )
                .collect()
        };
        self.k_total = k_total;
        let (phi, gamma) = zoh(&a, &b, m.integration.step_s);
        // Carry the state over a rebuild (new Prony states start at θ_h).
        let mut x = DVector::<f64>::zeros(n);
        if self.x.len() == self.layout.n {
            let old = self.layout;
            x[0] = self.x[old.th_e];
            x[1] = self.x[old.w_e];
            x[th_h] = self.x[old.th_h];
            x[w_h] = self.x[old.w_h];
            if let (Some(s), Some(os)) = (sea_idx, old.sea) {
                x[s] = self.x[os];
                x[s + 1] = self.x[os + 1];
            }
            match remap {
                // A new bank, holding the old one's elastic torque.
                Some(z) => {
                    for (i, z) in z.iter().enumerate() {
                        x[z0 + i] = *z;
                    }
                }
                None => {
                    for i in 0..n_z.min(old.n_z) {
                        x[z0 + i] = self.x[old.z0 + i];
                    }
                }
            }
        }
        self.layout = l;
        self.a = a;
        self.b = b;
        self.phi_gamma_cols = phi.iter().chain(gamma.iter()).copied().collect();
        self.x = x;
        self.x_next = DVector::zeros(n);
    }
}
