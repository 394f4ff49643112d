//! What a run file may hold: the documented range of every numeric key
//! ([`RUN_RANGES`]) and the checks of [`RunConfig::from_file`] and
//! [`RunConfig::validate`] (every key at fault named), beside the settings
//! they check (`run.rs`).

use std::path::Path;

use super::{output_dir_problem, BusBackend, ProtocolMode, RunConfig, TimingMode};
use crate::{
    Check, ExperimentTable, Range, Ranges, Result, MAX_DURATION_S, MAX_EXPERIMENT, MAX_PERIOD,
};

/// The documented range of every numeric key of a run file (the doc
/// comment of each key says the same). Beyond these, [`RunConfig::from_file`]
/// checks what involves several keys or files: the deadlines are at least
/// one control period, the velocity cut-off and every excitation frequency
/// are below the Nyquist frequency of `run.rate_hz`, the protocol lasts at
/// most a day, the experiments and periods exist, and `run.output_dir` is
/// not a file.
pub const RUN_RANGES: Ranges = &[
    ("run.rate_hz", Range::closed(1.0, 100_000.0)),
    ("run.seed", Range::closed(0.0, u64::MAX as f64)),
    ("run.max_sim_time_s", Range::above(0.0, MAX_DURATION_S)),
    ("run.lockstep_spin_us", Range::closed(0.0, 100_000.0)),
    ("player.pace_hz", Range::closed(1.0, 1e6)),
    ("realtime.sched_fifo_priority", Range::closed(1.0, 99.0)),
    ("realtime.controller_cpu", Range::closed(0.0, 1023.0)),
    ("realtime.sensor_driver_cpu", Range::closed(0.0, 1023.0)),
    ("realtime.plant_sim_cpu", Range::closed(0.0, 1023.0)),
    (
        "protocol.experiments[*]",
        Range::closed(1.0, MAX_EXPERIMENT as f64),
    ),
    ("protocol.periods[*]", Range::closed(1.0, MAX_PERIOD as f64)),
    ("protocol.rest_s", Range::closed(0.0, 3600.0)),
    ("protocol.ramp_in_s", Range::closed(0.0, 3600.0)),
    ("protocol.settling_s", Range::closed(0.0, 3600.0)),
    ("protocol.analysis_s", Range::closed(0.01, 3600.0)),
    ("protocol.ramp_out_s", Range::closed(0.0, 3600.0)),
    (
        "protocol.multisine.band_rad_s[*]",
        Range::above(0.0, 10_000.0),
    ),
    ("protocol.multisine.lines", Range::closed(1.0, 1000.0)),
    ("protocol.multisine.period_s", Range::above(0.0, 3600.0)),
    (
        "protocol.multisine.settling_periods",
        Range::closed(1.0, 1000.0),
    ),
    ("protocol.multisine.periods", Range::closed(2.0, 1000.0)),
    ("protocol.multisine.peak_nm", Range::above(0.0, 1000.0)),
    ("protocol.stop_when.k_rel_ci", Range::above(0.0, 1.0)),
    ("protocol.stop_when.h_rel_ci", Range::above(0.0, 1.0)),
    ("protocol.stop_when.min_periods", Range::closed(2.0, 1000.0)),
    ("voluntary.amplitude_rad", Range::closed(0.0, 1.5)),
    ("voluntary.omega_rad_s", Range::above(0.0, 10_000.0)),
    ("voluntary.duration_s", Range::above(0.0, 3600.0)),
    ("voluntary.grip_kg", Range::closed(0.0, 100.0)),
    ("voluntary.bias_nm", Range::closed(-100.0, 100.0)),
    (
        "voluntary.experiment",
        Range::closed(1.0, MAX_EXPERIMENT as f64),
    ),
    (
        "release.experiment",
        Range::closed(1.0, MAX_EXPERIMENT as f64),
    ),
    ("release.spring_torque_nm", Range::closed(-100.0, 100.0)),
    ("release.hold_s", Range::above(0.0, 3600.0)),
    ("release.observe_s", Range::above(0.0, 3600.0)),
    ("controller.kp", Range::above(0.0, 20.0)),
    ("controller.f", Range::below(0.0, 1.0)),
    (
        "controller.k_range_nm_per_rad[*]",
        Range::above(0.0, 5000.0),
    ),
    ("controller.filters", Range::closed(1.0, 16.0)),
    ("controller.p1_rad_s", Range::above(0.0, 10_000.0)),
    ("controller.r_pp", Range::above(1.0, 100.0)),
    ("controller.f_bounds[*]", Range::closed(0.0, 0.999)),
    ("controller.limits.torque_nm", Range::above(0.0, 1000.0)),
    (
        "controller.limits.torque_rate_nm_per_s",
        Range::above(0.0, 1e6),
    ),
    (
        "controller.limits.theta_rad[*]",
        Range::closed(-std::f64::consts::TAU, std::f64::consts::TAU),
    ),
    ("controller.limits.tau_c_nm", Range::above(0.0, 1000.0)),
    ("safety.command_deadline_ms", Range::above(0.0, 1000.0)),
    ("safety.sample_deadline_ms", Range::above(0.0, 1000.0)),
    ("safety.lockstep_timeout_ms", Range::above(0.0, 60_000.0)),
    ("safety.drive_watchdog_ms", Range::above(0.0, 1000.0)),
    ("safety.bus_deadline_ms", Range::above(0.0, 1000.0)),
    ("rig.arm_inertia_kg_m2", Range::above(0.0, 10.0)),
    ("rig.arm_mass_kg", Range::closed(0.0, 50.0)),
    ("rig.arm_com_m", Range::closed(0.0, 2.0)),
    ("rig.load_lever_arm_m", Range::closed(0.0, 2.0)),
    ("rig.gravity_m_s2", Range::closed(0.0, 20.0)),
    ("rig.encoder_counts_per_rev", Range::closed(1.0, 1e12)),
    ("rig.cuff_lever_arm_m", Range::above(0.0, 2.0)),
    ("rig.sea_stiffness_nm_per_rad", Range::above(0.0, 1e6)),
    ("rig.sea_counts_per_rev", Range::closed(1.0, 1e12)),
    ("rig.velocity_cutoff_hz", Range::above(0.0, 50_000.0)),
    ("bus.ethercat.position", Range::closed(0.0, 255.0)),
    ("bus.ethercat.pdu_timeout_ms", Range::above(0.0, 1000.0)),
    ("bus.ethercat.quick_stop_ms", Range::closed(0.0, 1000.0)),
    ("bus.ethercat.wake_spin_us", Range::closed(0.0, 1000.0)),
    ("bus.ethercat.max_missed_cycles", Range::closed(1.0, 1000.0)),
    (
        "bus.ethercat.drive_watchdog_cycles",
        Range::closed(1.0, 1000.0),
    ),
    (
        "bus.ethercat.rx_pdo.entries[*].scale",
        Range::closed(-1e9, 1e9),
    ),
    (
        "bus.ethercat.tx_pdo.entries[*].scale",
        Range::closed(-1e9, 1e9),
    ),
];

pub(super) fn range_of_run(key: &str) -> Range {
    crate::range_of(RUN_RANGES, key).unwrap_or(Range::closed(f64::NAN, f64::NAN))
}

impl RunConfig {
    /// The checks against the experiment table (with the run's timing
    /// overrides applied): experiments and periods exist, every excitation
    /// is below the Nyquist frequency, the protocol lasts at most a day.
    pub(super) fn check_against_table(&self, c: &Check<'_>, table: &ExperimentTable) {
        let tfile = &self.protocol.experiments_file;
        for (i, n) in self.protocol.experiments.iter().enumerate() {
            if table.get(*n).is_none() {
                c.note(
                    &format!("protocol.experiments[{i}]"),
                    format!(
                        "experiment {n} is not in {}; it has {:?}",
                        tfile.display(),
                        table
                            .experiment
                            .iter()
                            .map(|e| e.number)
                            .collect::<Vec<_>>()
                    ),
                );
            }
        }
        if let Some(periods) = &self.protocol.periods {
            for (i, p) in periods.iter().enumerate() {
                if *p == 0 || *p > table.periods {
                    c.note(
                        &format!("protocol.periods[{i}]"),
                        format!(
                            "period {p} is outside 1..={} (periods of {})",
                            table.periods,
                            tfile.display()
                        ),
                    );
                }
            }
        }
        let rate = self.run.rate_hz;
        if !range_of_run("run.rate_hz").contains(rate) {
            return;
        }
        let nyquist = std::f64::consts::PI * rate;
        self.check_multisine_against_table(c, table);
        if self.protocol.mode.identifies() {
            let periods = self.periods_run(table);
            let mut seen = Vec::new();
            for n in &self.protocol.experiments {
                let (Some(idx), false) = (table.index_of(*n), seen.contains(n)) else {
                    continue;
                };
                seen.push(*n);
                let e = &table.experiment[idx];
                if self.protocol.mode == ProtocolMode::Multisine {
                    continue; // its band is checked with the design
                }
                let worst = periods
                    .iter()
                    .map(|p| (*p, table.omega_rad_s(e, *p)))
                    .find(|(_, w)| w.is_nan() || *w >= nyquist);
                if let Some((p, w)) = worst {
                    c.push(crate::invalid(
                        tfile,
                        format!("experiment[{idx}].start_omega_rad_s"),
                        format!(
                            "experiment {n} excites at {} rad/s in period {p} (start_omega_rad_s {} × frequency_step {}^{}), not below the Nyquist frequency π·run.rate_hz = {nyquist:.1} rad/s of {} (run.rate_hz = {rate})",
                            crate::number(w),
                            e.start_omega_rad_s,
                            table.frequency_step,
                            p.saturating_sub(1),
                            c.file().display()
                        ),
                    ));
                }
            }
            let steps = self.protocol.experiments.len() * periods.len();
            let total = steps as f64 * table.timing.period_s();
            let t = &table.timing;
            let each_valid = [
                ("protocol.ramp_in_s", t.ramp_in_s),
                ("protocol.settling_s", t.settling_s),
                ("protocol.analysis_s", t.analysis_s),
                ("protocol.ramp_out_s", t.ramp_out_s),
                ("protocol.rest_s", t.rest_s),
            ]
            .iter()
            .all(|(k, v)| range_of_run(k).contains(*v));
            if each_valid && total > MAX_DURATION_S {
                c.note(
                    "protocol",
                    format!(
                        "the protocol would last {total} s ({} experiments × {} periods × {} s per period, timing of {} with this file's overrides), more than a day ({MAX_DURATION_S} s)",
                        self.protocol.experiments.len(),
                        periods.len(),
                        table.timing.period_s(),
                        tfile.display()
                    ),
                );
            }
        }
        if let Some(v) = self
            .voluntary
            .filter(|_| self.protocol.mode == ProtocolMode::Voluntary)
        {
            if v.omega_rad_s.is_finite() && v.omega_rad_s >= nyquist {
                c.note(
                    "voluntary.omega_rad_s",
                    format!(
                        "{} rad/s is not below the Nyquist frequency π·run.rate_hz = {nyquist:.1} rad/s",
                        v.omega_rad_s
                    ),
                );
            }
        }
    }

    /// `[protocol.multisine]`'s own values, and the keys multisine mode
    /// sets itself (the periods and the settling and analysis windows).
    fn check_multisine_values(&self, c: &Check<'_>) {
        let p = &self.protocol;
        if let (Some(_), false) = (&p.multisine, p.mode == ProtocolMode::Multisine) {
            c.note(
                "protocol.multisine",
                "is used only with protocol.mode = \"multisine\"",
            );
        }
        if let (Some(_), false) = (&p.stop_when, p.mode == ProtocolMode::Multisine) {
            c.note(
                "protocol.stop_when",
                "is used only with protocol.mode = \"multisine\" (it ends an analysis window at a whole period of the multisine)",
            );
        }
        if p.mode != ProtocolMode::Multisine {
            return;
        }
        let m = p.multisine.unwrap_or_default();
        if let Some(w) = p.stop_when {
            c.key("protocol.stop_when.k_rel_ci", w.k_rel_ci);
            c.key("protocol.stop_when.h_rel_ci", w.h_rel_ci);
            if c.key("protocol.stop_when.min_periods", f64::from(w.min_periods))
                && w.min_periods > m.periods
            {
                c.note(
                    "protocol.stop_when.min_periods",
                    format!(
                        "must be at most protocol.multisine.periods = {} (the most periods analysed), got {}",
                        m.periods, w.min_periods
                    ),
                );
            }
        }
        let [lo, hi] = m.band_rad_s;
        if c.key("protocol.multisine.band_rad_s[0]", lo)
            & c.key("protocol.multisine.band_rad_s[1]", hi)
            && lo >= hi
        {
            c.note(
                "protocol.multisine.band_rad_s[1]",
                format!("must be above protocol.multisine.band_rad_s[0] = {lo} (the band is [low, high]), got {hi}"),
            );
        }
        c.key("protocol.multisine.lines", f64::from(m.lines));
        c.key("protocol.multisine.period_s", m.period_s);
        c.key(
            "protocol.multisine.settling_periods",
            f64::from(m.settling_periods),
        );
        if m.periods < 2 {
            c.note(
                "protocol.multisine.periods",
                format!("{} whole period(s) give no noise estimate (it comes from the spread between periods): at least 2", m.periods),
            );
        } else {
            c.key("protocol.multisine.periods", f64::from(m.periods));
        }
        if let Some(peak) = m.peak_nm {
            c.key("protocol.multisine.peak_nm", peak);
        }
        for (key, set) in [
            ("protocol.periods", p.periods.is_some()),
            ("protocol.settling_s", p.settling_s.is_some()),
            ("protocol.analysis_s", p.analysis_s.is_some()),
        ] {
            if set {
                c.note(
                    key,
                    "is not used in multisine mode: each experiment is one protocol period whose settling and analysis windows are protocol.multisine.settling_periods and .periods whole periods of the multisine; leave the key out",
                );
            }
        }
    }

    /// In multisine mode, against the experiment table at a valid
    /// `run.rate_hz`: the design exists (a whole number of samples per
    /// period, the band below Nyquist and holding enough resolved
    /// frequencies for its lines), and each experiment's bias plus its
    /// peak excitation is within `controller.limits.torque_nm`.
    fn check_multisine_against_table(&self, c: &Check<'_>, table: &ExperimentTable) {
        let Some(m) = self.protocol.multisine() else {
            return;
        };
        let valid = [
            ("protocol.multisine.band_rad_s[*]", m.band_rad_s[0]),
            ("protocol.multisine.band_rad_s[*]", m.band_rad_s[1]),
            ("protocol.multisine.lines", f64::from(m.lines)),
            ("protocol.multisine.period_s", m.period_s),
        ]
        .iter()
        .all(|(k, v)| range_of_run(k).contains(*v))
            && m.band_rad_s[0] < m.band_rad_s[1];
        if valid {
            if let Err(e) = m.bins(self.run.rate_hz) {
                c.note(e.key, e.why);
            }
        }
        let limit = self.controller.limits.torque_nm;
        let peak_ok = m
            .peak_nm
            .is_none_or(|v| range_of_run("protocol.multisine.peak_nm").contains(v));
        if !(peak_ok && range_of_run("controller.limits.torque_nm").contains(limit)) {
            return;
        }
        for n in &self.protocol.experiments {
            let Some(e) = table.get(*n) else { continue };
            let peak = m.peak_nm_of(table, e);
            if e.bias_nm.abs() + peak > limit {
                c.note(
                    if m.peak_nm.is_some() {
                        "protocol.multisine.peak_nm"
                    } else {
                        "controller.limits.torque_nm"
                    },
                    format!(
                        "experiment {n}'s bias {} Nm and the multisine's peak {peak} Nm reach {} Nm, beyond controller.limits.torque_nm = {limit} Nm",
                        e.bias_nm,
                        e.bias_nm.abs() + peak
                    ),
                );
            }
        }
    }

    /// `[bus]`: the EtherCAT backend needs its table and the wall clock.
    pub(super) fn check_bus(&self, c: &Check<'_>, rate_ok: bool) {
        match (self.bus.backend, &self.bus.ethercat) {
            (BusBackend::Ethercat, None) => c.note(
                "bus.ethercat",
                "bus.backend = \"ethercat\" needs a [bus.ethercat] table (interface, identity, PDO mapping)",
            ),
            (BusBackend::Ethercat, Some(e)) => {
                if self.run.timing != TimingMode::Realtime {
                    c.note(
                        "run.timing",
                        "bus.backend = \"ethercat\" drives hardware on the wall clock: run.timing must be \"realtime\"",
                    );
                }
                if rate_ok {
                    e.check(c, self.run.rate_hz);
                    // The controller must not latch on a stall the bus
                    // rides through (docs/hardware.md, "Late and lost
                    // cycles"): its sample deadline spans the missed
                    // cycles the driver tolerates.
                    let missed = e.max_missed_cycles(self.run.rate_hz);
                    let ride_ms = f64::from(missed) * 1000.0 / self.run.rate_hz;
                    let deadline_ms = self.safety.sample_deadline_ms;
                    if deadline_ms.is_finite() && deadline_ms < ride_ms {
                        c.note(
                            "safety.sample_deadline_ms",
                            format!(
                                "{deadline_ms} ms is shorter than the {ride_ms} ms of missed cycles the EtherCAT bus rides through (bus.ethercat.max_missed_cycles = {missed} at {} Hz): the controller would latch its safe state on a stall the driver holds through",
                                self.run.rate_hz
                            ),
                        );
                    }
                }
            }
            (BusBackend::Simulator, _) => {}
        }
    }

    /// Validates the values of the run file itself, naming every key at fault.
    pub fn validate(&self, file: &Path) -> Result<()> {
        let c = Check::with_ranges(file, RUN_RANGES);
        self.check_values(&c);
        c.finish()
    }

    /// Records every value of the run file itself that is out of range.
    pub(super) fn check_values(&self, c: &Check<'_>) {
        let rate_ok = c.key("run.rate_hz", self.run.rate_hz);
        c.key("run.seed", self.run.seed as f64);
        c.key("run.lockstep_spin_us", self.run.lockstep_spin_us);
        if let Some(t) = self.run.max_sim_time_s {
            c.key("run.max_sim_time_s", t);
        }
        let instance = &self.run.instance;
        if instance.is_empty()
            || instance.len() > 64
            || !instance
                .chars()
                .all(|ch| ch.is_ascii_alphanumeric() || ch == '_' || ch == '-')
        {
            c.note(
                "run.instance",
                format!("must be 1 to 64 letters, digits, '-' or '_', got {instance:?}"),
            );
        }
        if let Some(why) = output_dir_problem(&self.run.output_dir) {
            c.note("run.output_dir", why);
        }
        if let Some(p) = self.player.as_ref().and_then(|p| p.pace_hz) {
            c.key("player.pace_hz", p);
        }
        if let Some(a) = self.live.as_ref().and_then(|l| l.address.as_ref()) {
            if a.parse::<std::net::IpAddr>().is_err() {
                c.note(
                    "live.address",
                    format!("must be an IP address such as 127.0.0.1 or ::1, got {a:?}"),
                );
            }
        }
        if let Some(l) = self.tunnel.as_ref().and_then(|t| t.listen.as_ref()) {
            if l.is_empty() {
                c.note(
                    "tunnel.listen",
                    "name at least one endpoint, e.g. \"tcp/127.0.0.1:7447\"",
                );
            }
            for (i, e) in l.iter().enumerate() {
                if !e.contains('/') {
                    c.note(
                        &format!("tunnel.listen[{i}]"),
                        format!(
                            "must be a Zenoh endpoint such as \"tcp/127.0.0.1:7447\", got {e:?}"
                        ),
                    );
                }
            }
        }
        if let Some(rt) = &self.realtime {
            if let Some(p) = rt.sched_fifo_priority {
                c.key("realtime.sched_fifo_priority", f64::from(p));
            }
            for (key, cpu) in [
                ("realtime.controller_cpu", rt.controller_cpu),
                ("realtime.sensor_driver_cpu", rt.sensor_driver_cpu),
                ("realtime.plant_sim_cpu", rt.plant_sim_cpu),
            ] {
                if let Some(cpu) = cpu {
                    c.key(key, cpu as f64);
                }
            }
        }
        if self.protocol.experiments.is_empty() {
            c.note("protocol.experiments", "name at least one experiment");
        }
        for (i, n) in self.protocol.experiments.iter().enumerate() {
            c.key(&format!("protocol.experiments[{i}]"), f64::from(*n));
        }
        if let Some(periods) = &self.protocol.periods {
            if periods.is_empty() {
                c.note(
                    "protocol.periods",
                    "name at least one period, or leave the key out for all of them",
                );
            }
            for (i, p) in periods.iter().enumerate() {
                c.key(&format!("protocol.periods[{i}]"), f64::from(*p));
            }
        }
        for (key, v) in self.protocol.timing_overrides() {
            if let Some(v) = v {
                c.key(key, v);
            }
        }
        self.check_multisine_values(c);
        match (self.protocol.mode, &self.voluntary, &self.release) {
            (ProtocolMode::Voluntary, None, _) => c.note(
                "voluntary",
                "protocol.mode = \"voluntary\" needs a [voluntary] table",
            ),
            (ProtocolMode::Release, _, None) => c.note(
                "release",
                "protocol.mode = \"release\" needs a [release] table",
            ),
            _ => {}
        }
        if let Some(v) = &self.voluntary {
            c.key("voluntary.amplitude_rad", v.amplitude_rad);
            c.key("voluntary.omega_rad_s", v.omega_rad_s);
            c.key("voluntary.duration_s", v.duration_s);
            c.key("voluntary.grip_kg", v.grip_kg);
            c.key("voluntary.bias_nm", v.bias_nm);
            c.key("voluntary.experiment", f64::from(v.experiment));
        }
        if let Some(r) = &self.release {
            c.key("release.experiment", f64::from(r.experiment));
            c.key("release.spring_torque_nm", r.spring_torque_nm);
            c.key("release.hold_s", r.hold_s);
            c.key("release.observe_s", r.observe_s);
        }
        let k = &self.controller;
        if let Some(kp) = k.kp {
            c.key("controller.kp", kp);
        }
        if let Some(f) = k.f {
            c.key("controller.f", f);
        }
        let [k_lo, k_hi] = k.k_range_nm_per_rad;
        if c.key("controller.k_range_nm_per_rad[0]", k_lo)
            & c.key("controller.k_range_nm_per_rad[1]", k_hi)
            && k_lo > k_hi
        {
            c.note(
                "controller.k_range_nm_per_rad[1]",
                format!("must be at least controller.k_range_nm_per_rad[0] = {k_lo} (the range is [min, max]), got {k_hi}"),
            );
        }
        c.key("controller.filters", k.filters as f64);
        c.key("controller.p1_rad_s", k.p1_rad_s);
        c.key("controller.r_pp", k.r_pp);
        let [f_lo, f_hi] = k.f_bounds;
        if c.key("controller.f_bounds[0]", f_lo) & c.key("controller.f_bounds[1]", f_hi)
            && f_lo > f_hi
        {
            c.note(
                "controller.f_bounds[1]",
                format!("must be at least controller.f_bounds[0] = {f_lo} (the bounds are [min, max]), got {f_hi}"),
            );
        }
        let l = &k.limits;
        c.key("controller.limits.torque_nm", l.torque_nm);
        c.key(
            "controller.limits.torque_rate_nm_per_s",
            l.torque_rate_nm_per_s,
        );
        let [t_lo, t_hi] = l.theta_rad;
        if c.key("controller.limits.theta_rad[0]", t_lo)
            & c.key("controller.limits.theta_rad[1]", t_hi)
            && t_lo >= t_hi
        {
            c.note(
                "controller.limits.theta_rad[1]",
                format!("must be greater than controller.limits.theta_rad[0] = {t_lo} (the range is [min, max]), got {t_hi}"),
            );
        }
        c.key("controller.limits.tau_c_nm", l.tau_c_nm);
        let period_ms = 1000.0 / self.run.rate_hz;
        for (key, v) in [
            (
                "safety.command_deadline_ms",
                self.safety.command_deadline_ms,
            ),
            ("safety.sample_deadline_ms", self.safety.sample_deadline_ms),
            ("safety.drive_watchdog_ms", self.safety.drive_watchdog_ms),
            ("safety.bus_deadline_ms", self.safety.bus_deadline_ms),
        ] {
            if c.key(key, v) && rate_ok && v < period_ms {
                c.note(
                    key,
                    format!(
                        "{v} ms is shorter than one control period ({period_ms} ms at {} Hz)",
                        self.run.rate_hz
                    ),
                );
            }
        }
        c.key(
            "safety.lockstep_timeout_ms",
            self.safety.lockstep_timeout_ms,
        );
        self.check_bus(c, rate_ok);
        let r = &self.rig;
        c.key("rig.arm_inertia_kg_m2", r.arm_inertia_kg_m2);
        c.key("rig.arm_mass_kg", r.arm_mass_kg);
        c.key("rig.arm_com_m", r.arm_com_m);
        c.key("rig.load_lever_arm_m", r.load_lever_arm_m);
        c.key("rig.gravity_m_s2", r.gravity_m_s2);
        c.key("rig.encoder_counts_per_rev", r.encoder_counts_per_rev);
        c.key("rig.cuff_lever_arm_m", r.cuff_lever_arm_m);
        c.key("rig.sea_stiffness_nm_per_rad", r.sea_stiffness_nm_per_rad);
        c.key("rig.sea_counts_per_rev", r.sea_counts_per_rev);
        if c.key("rig.velocity_cutoff_hz", r.velocity_cutoff_hz)
            && rate_ok
            && r.velocity_cutoff_hz >= self.run.rate_hz / 2.0
        {
            c.note(
                "rig.velocity_cutoff_hz",
                format!(
                    "must be below half the control rate ({} Hz), got {}",
                    self.run.rate_hz / 2.0,
                    r.velocity_cutoff_hz
                ),
            );
        }
    }
}
