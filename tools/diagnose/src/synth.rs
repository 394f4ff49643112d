//! An in-process stand-in for a recorded identification run: the plant
//! simulator (the same `exo_plant_sim::Plant` the `exo-plant-sim` process
//! runs) driven by single sines on top of the controller's gravity
//! compensation and a bias torque, at α = 1, sampled through its sensor
//! model into contract messages. It is for checking the forward model
//! against the simulator and for fast tests; the benchmark of concealed
//! effects (`exo diagnose-bench`) records the real processes instead.

use exo_messages::{ActuatorCommand, ControlMode, ProtocolState, SensorSample};
use exo_plant_sim::{HumanDrive, Plant, PlantModel};
use exo_recording::Recording;

/// One period of the synthetic protocol.
#[derive(Debug, Clone, Copy)]
pub struct SynthPeriod {
    /// Experiment number.
    pub experiment: u32,
    /// Period number.
    pub period: u32,
    /// Excitation frequency (rad/s).
    pub omega_rad_s: f64,
    /// Excitation amplitude (Nm).
    pub amplitude_nm: f64,
    /// Human stiffness and hysteretic damping (Nm/rad).
    pub k_h: f64,
    /// Hysteretic damping (Nm/rad).
    pub h_h: f64,
    /// Load (kg).
    pub load_kg: f64,
    /// Bias torque (Nm).
    pub bias_nm: f64,
}

/// Timing and the controller's view of gravity.
#[derive(Debug, Clone, Copy)]
pub struct SynthSettings {
    /// Control rate (Hz).
    pub rate_hz: f64,
    /// Settling before each analysis window (s).
    pub settle_s: f64,
    /// Analysis window (s).
    pub analysis_s: f64,
    /// The controller's gravity torque per unit `sin θ` of the arm alone (Nm)
    /// (`None`: the plant's own, i.e. exact compensation).
    pub ctrl_arm_mgl_nm: Option<f64>,
}

impl Default for SynthSettings {
    fn default() -> Self {
        Self {
            rate_hz: 1000.0,
            settle_s: 6.0,
            analysis_s: 6.0,
            ctrl_arm_mgl_nm: None,
        }
    }
}

/// Simulates `periods` through `model` and returns them as a recording
/// (`exo/sensor`, `exo/command`, `exo/protocol`).
pub fn synthesize(model: &PlantModel, periods: &[SynthPeriod], s: &SynthSettings) -> Recording {
    let mut plant = Plant::new(model);
    let g = &model.gravity;
    let arm_mgl = s.ctrl_arm_mgl_nm.unwrap_or(if g.enabled {
        g.g_m_s2 * g.arm_mass_kg * g.arm_com_m
    } else {
        0.0
    });
    let lever = model.exo.load_lever_arm_m;
    let gg = if g.enabled { g.g_m_s2 } else { 0.0 };
    let h = model.integration.step_s;
    let sub = ((1.0 / s.rate_hz) / h).round().max(1.0) as usize;
    let dt = sub as f64 * h;
    let tau = std::f64::consts::TAU;
    let enc = model.sensors.encoder.counts_per_rev;
    let sea_cpr = model.sensors.sea_deflection.counts_per_rev;
    let k_sea = model.sea.spring_stiffness_nm_per_rad;
    let lever_ft = model.sensors.cuff_ft.lever_arm_m;
    let mut rec = Recording {
        source: "synthetic".into(),
        ..Default::default()
    };
    plant.set_drive(HumanDrive {
        theta_eq_rad: model.human.active_angle_rad,
        omega_eq_rad_s: 0.0,
    });
    let mut seq = 0u64;
    let mut t = 0.0f64;
    let mut experiment = None;
    for p in periods {
        if experiment != Some(p.experiment) {
            // The origin of `human.stiffness_drift_per_min`.
            plant.start_experiment_clock();
            experiment = Some(p.experiment);
        }
        plant.set_human_impedance(p.k_h, p.h_h);
        plant.set_load_kg(p.load_kg);
        plant.set_excitation_omega(p.omega_rad_s);
        let mgl = arm_mgl + gg * p.load_kg * lever;
        let n_settle = (s.settle_s / dt).round() as usize;
        let n_total = n_settle + (s.analysis_s / dt).round() as usize;
        let t_start = t;
        let state = |phase: u32, stamp: f64| ProtocolState {
            experiment: p.experiment,
            period: p.period,
            phase,
            omega: p.omega_rad_s,
            amplitude: p.amplitude_nm,
            alpha: 1.0,
            load_kg: p.load_kg,
            bias_nm: p.bias_nm,
            stamp_ns: (stamp * 1e9).round() as u64,
            ..Default::default()
        };
        rec.protocol.push(state(2, t));
        for i in 0..n_total {
            if i == n_settle {
                rec.protocol.push(state(3, t));
            }
            let raw = plant.raw_sensors();
            let theta = raw.encoder_counts as f64 / enc * tau;
            let tau_c = raw.cuff_wrench[1] * lever_ft;
            let tau_s = raw.sea_deflection_counts as f64 / sea_cpr * tau * k_sea;
            let stamp_ns = (t * 1e9).round() as u64;
            rec.sensor.push(SensorSample {
                seq,
                stamp_ns,
                theta_e: theta,
                omega_e: 0.0,
                tau_c,
                tau_s,
                status: 0,
                ..Default::default()
            });
            // The sine fades in over the first second of settling.
            let ts = t - t_start;
            let fade = (ts / 1.0).min(1.0);
            let ramp = (ts / 2.0).min(1.0);
            let tau_g = mgl * theta.sin();
            let tau_x = fade * p.amplitude_nm * (p.omega_rad_s * ts).sin();
            let tau_b = ramp * p.bias_nm;
            let tau_d = tau_g + tau_b + tau_x;
            rec.command.push(ActuatorCommand {
                seq,
                stamp_ns,
                sensor_seq: seq,
                tau_d,
                tau_gravity: tau_g,
                tau_bias: tau_b,
                tau_excitation: tau_x,
                mode: ControlMode::Run.as_u32(),
                ..Default::default()
            });
            for _ in 0..sub {
                plant.step(tau_d);
            }
            seq += 1;
            t += dt;
        }
        rec.protocol.push(state(4, t));
    }
    rec
}
