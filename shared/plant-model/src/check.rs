//! What a plant model may hold: the documented range of every numeric key
//! ([`PLANT_RANGES`]) and the check of a model ([`PlantModel::validate`],
//! every key at fault named), with every numeric key read out
//! ([`PlantModel::numeric_keys`]).

use exo_config::{range_of, Range, Ranges};

use crate::{HysteresisMode, PlantModel, PlantModelError};

/// The largest Prony bank a plant model may ask for (elements): the bank is
/// fitted by non-negative least squares and integrated with the rest of the
/// state, so its size bounds both memory and time.
pub const MAX_PRONY_ELEMENTS: usize = 200;

/// The documented range of every numeric key of a plant model (the doc
/// comment of each key says the same); [`PlantModel::validate`] checks
/// them and, beyond them, band orders, the Prony bank's size (at most
/// [`MAX_PRONY_ELEMENTS`]) and the integration step against the fastest
/// mode. Array elements are written `[*]`.
pub const PLANT_RANGES: Ranges = &[
    ("human.inertia_kg_m2", Range::closed(0.001, 10.0)),
    ("human.stiffness_nm_per_rad", Range::above(0.0, 5000.0)),
    (
        "human.hysteretic_damping.loss_factor",
        Range::closed(0.0, 10.0),
    ),
    (
        "human.hysteretic_damping.band_rad_s[*]",
        Range::closed(0.001, 1e5),
    ),
    (
        "human.hysteretic_damping.elements_per_decade",
        Range::above(0.0, 50.0),
    ),
    (
        "human.hysteretic_damping.reference_rad_s",
        Range::above(0.0, 1e5),
    ),
    (
        "human.hysteretic_damping.matched_band_decades[*]",
        Range::closed(0.0, 3.0),
    ),
    (
        "human.viscous_damping.b_nm_s_per_rad",
        Range::closed(0.0, 1000.0),
    ),
    (
        "human.stretch_reflex.gain_nm_s_per_rad",
        Range::closed(0.0, 1000.0),
    ),
    ("human.stretch_reflex.delay_s", Range::closed(0.0, 1.0)),
    (
        "human.cubic_stiffness_nm_per_rad3",
        Range::closed(-1e5, 1e5),
    ),
    (
        "human.cubic_damping_nm_s3_per_rad3",
        Range::closed(0.0, 1e3),
    ),
    (
        "human.quadratic_stiffness_nm_per_rad2",
        Range::closed(-1e5, 1e5),
    ),
    ("human.stretch_reflex.cutoff_rad_s", Range::above(0.0, 1e4)),
    ("human.stiffness_drift_per_min", Range::closed(-0.5, 0.5)),
    (
        "human.rest_angle_rad",
        Range::closed(-std::f64::consts::TAU, std::f64::consts::TAU),
    ),
    (
        "human.active_angle_rad",
        Range::closed(-std::f64::consts::TAU, std::f64::consts::TAU),
    ),
    ("exo.arm_inertia_kg_m2", Range::above(0.0, 10.0)),
    ("exo.load_lever_arm_m", Range::closed(0.0, 2.0)),
    ("exo.load_kg", Range::closed(0.0, 50.0)),
    ("exo.backlash.lash_rad", Range::closed(0.0, 0.2)),
    ("exo.backlash.motor_inertia_kg_m2", Range::above(0.0, 10.0)),
    (
        "exo.backlash.mesh_stiffness_nm_per_rad",
        Range::above(0.0, 1e7),
    ),
    (
        "exo.backlash.mesh_damping_nm_s_per_rad",
        Range::closed(0.0, 1e4),
    ),
    ("gravity.arm_mass_kg", Range::closed(0.0, 50.0)),
    ("gravity.arm_com_m", Range::closed(0.0, 2.0)),
    ("gravity.g_m_s2", Range::closed(0.0, 20.0)),
    (
        "joint_friction.coulomb.torque_nm",
        Range::closed(0.0, 100.0),
    ),
    (
        "joint_friction.coulomb.smoothing_rad_s",
        Range::above(0.0, 100.0),
    ),
    (
        "joint_friction.viscous.b_nm_s_per_rad",
        Range::closed(0.0, 1000.0),
    ),
    (
        "cuff.compliance.stiffness_nm_per_rad",
        Range::above(0.0, 1e6),
    ),
    (
        "cuff.compliance.damping_nm_s_per_rad",
        Range::closed(0.0, 1e4),
    ),
    (
        "sea.dynamics.natural_frequency_hz",
        Range::above(0.0, 1000.0),
    ),
    ("sea.dynamics.damping_ratio", Range::above(0.0, 10.0)),
    ("sea.torque_limit_nm", Range::above(0.0, 1000.0)),
    ("sea.spring_stiffness_nm_per_rad", Range::above(0.0, 1e6)),
    ("actuator.delay_s", Range::closed(0.0, 1.0)),
    ("sensors.encoder.counts_per_rev", Range::closed(1.0, 1e12)),
    ("sensors.cuff_ft.lever_arm_m", Range::above(0.0, 2.0)),
    (
        "sensors.cuff_ft.force_resolution_n",
        Range::closed(0.0, 100.0),
    ),
    (
        "sensors.sea_deflection.counts_per_rev",
        Range::closed(1.0, 1e12),
    ),
    ("sensors.encoder.gain", Range::closed(0.1, 10.0)),
    ("sensors.encoder.offset", Range::closed(-10.0, 10.0)),
    ("sensors.encoder.noise_std", Range::closed(0.0, 10.0)),
    ("sensors.encoder.delay_s", Range::closed(0.0, 1.0)),
    ("sensors.cuff_ft.gain", Range::closed(0.1, 10.0)),
    ("sensors.cuff_ft.offset", Range::closed(-10.0, 10.0)),
    ("sensors.cuff_ft.noise_std", Range::closed(0.0, 10.0)),
    ("sensors.cuff_ft.delay_s", Range::closed(0.0, 1.0)),
    ("sensors.sea_deflection.gain", Range::closed(0.1, 10.0)),
    ("sensors.sea_deflection.offset", Range::closed(-10.0, 10.0)),
    ("sensors.sea_deflection.noise_std", Range::closed(0.0, 10.0)),
    ("sensors.sea_deflection.delay_s", Range::closed(0.0, 1.0)),
    ("integration.step_s", Range::above(0.0, 1e-3)),
    ("integration.seed", Range::closed(0.0, u64::MAX as f64)),
];

impl PlantModel {
    /// Checks every value, naming every key at fault (one error, or
    /// [`PlantModelError::Several`]): each against its range in
    /// [`PLANT_RANGES`], then band orders, the Prony bank's size and the
    /// integration step against the fastest mode.
    pub fn validate(&self, file: &str) -> Result<(), PlantModelError> {
        let mut errors: Vec<PlantModelError> = Vec::new();
        let mut bad = |key: &str, message: String| {
            errors.push(PlantModelError::Invalid {
                file: file.to_string(),
                key: key.to_string(),
                message,
            })
        };
        let mut all_ok = true;
        for (key, value) in self.numeric_keys() {
            let range = range_of(PLANT_RANGES, &key).unwrap_or(Range::closed(f64::NAN, f64::NAN));
            if !range.contains(value) {
                all_ok = false;
                bad(
                    &key,
                    if value.is_finite() {
                        format!("must lie in {range}, got {}", exo_config::number(value))
                    } else {
                        format!("must be a finite number in {range}, got {value}")
                    },
                );
            }
        }
        let h = &self.human.hysteretic_damping;
        if h.band_rad_s[0] >= h.band_rad_s[1] {
            bad(
                "human.hysteretic_damping.band_rad_s[1]",
                format!(
                    "must be above human.hysteretic_damping.band_rad_s[0] = {} (the band is [low, high]), got {}",
                    h.band_rad_s[0], h.band_rad_s[1]
                ),
            );
        }
        let [below, above] = h.matched_band_decades;
        if below + above <= 0.0 {
            for i in 0..2 {
                bad(
                    &format!("human.hysteretic_damping.matched_band_decades[{i}]"),
                    "the band [below, above] must be wider than zero decades".into(),
                );
            }
        }
        if all_ok {
            // The bank as `prony::PronyBank::fit` builds it: half a decade
            // beyond the band each side.
            let decades = match h.mode {
                HysteresisMode::Prony => Some((h.band_rad_s[1] / h.band_rad_s[0]).log10()),
                HysteresisMode::PronyMatched => Some(below + above),
                HysteresisMode::EquivalentViscous => None,
            };
            if let Some(d) = decades {
                let n = ((d + 1.0) * h.elements_per_decade).ceil() + 1.0;
                if n > MAX_PRONY_ELEMENTS as f64 {
                    bad(
                        "human.hysteretic_damping.elements_per_decade",
                        format!(
                            "{} per decade over {:.2} decades makes a Prony bank of {n} elements; at most {MAX_PRONY_ELEMENTS}",
                            h.elements_per_decade,
                            d + 1.0
                        ),
                    );
                }
            }
            let step = self.integration.step_s;
            let w_max = [
                2.0 * std::f64::consts::PI * self.sea.dynamics.natural_frequency_hz,
                (self.cuff.compliance.stiffness_nm_per_rad / self.human.inertia_kg_m2).sqrt(),
            ]
            .into_iter()
            .fold(0.0, f64::max);
            let bl = self.exo.backlash;
            if bl.enabled() {
                if bl.motor_inertia_kg_m2 >= self.exo.arm_inertia_kg_m2 {
                    bad(
                        "exo.backlash.motor_inertia_kg_m2",
                        format!(
                            "must be below exo.arm_inertia_kg_m2 = {} (it is a part of it), got {}",
                            self.exo.arm_inertia_kg_m2, bl.motor_inertia_kg_m2
                        ),
                    );
                }
                let w_mesh = (bl.mesh_stiffness_nm_per_rad / bl.motor_inertia_kg_m2).sqrt();
                if w_mesh * step > 0.5 {
                    bad(
                        "exo.backlash.mesh_stiffness_nm_per_rad",
                        format!(
                            "the mesh's mode √(k_g/J_m) = {w_mesh:.0} rad/s is too fast for integration.step_s = {step} s: at most {:.3e} Nm/rad",
                            (0.5 / step).powi(2) * bl.motor_inertia_kg_m2
                        ),
                    );
                }
            }
            if w_max * step > 0.5 {
                bad(
                    "integration.step_s",
                    format!("{step} s is too coarse for the fastest mode ({w_max:.0} rad/s): use at most {:.2e}", 0.5 / w_max),
                );
            }
        }
        match errors.len() {
            0 => Ok(()),
            1 => Err(errors.remove(0)),
            _ => Err(PlantModelError::Several(errors)),
        }
    }

    /// Every numeric key of the model with its value, in file order.
    pub fn numeric_keys(&self) -> Vec<(String, f64)> {
        let h = &self.human;
        let d = &h.hysteretic_damping;
        let r = &h.stretch_reflex;
        let mut out: Vec<(String, f64)> = vec![
            ("human.inertia_kg_m2".into(), h.inertia_kg_m2),
            ("human.stiffness_nm_per_rad".into(), h.stiffness_nm_per_rad),
            ("human.hysteretic_damping.loss_factor".into(), d.loss_factor),
            (
                "human.hysteretic_damping.band_rad_s[0]".into(),
                d.band_rad_s[0],
            ),
            (
                "human.hysteretic_damping.band_rad_s[1]".into(),
                d.band_rad_s[1],
            ),
            (
                "human.hysteretic_damping.elements_per_decade".into(),
                d.elements_per_decade,
            ),
            (
                "human.hysteretic_damping.reference_rad_s".into(),
                d.reference_rad_s,
            ),
            (
                "human.hysteretic_damping.matched_band_decades[0]".into(),
                d.matched_band_decades[0],
            ),
            (
                "human.hysteretic_damping.matched_band_decades[1]".into(),
                d.matched_band_decades[1],
            ),
            (
                "human.viscous_damping.b_nm_s_per_rad".into(),
                h.viscous_damping.b_nm_s_per_rad,
            ),
            (
                "human.stretch_reflex.gain_nm_s_per_rad".into(),
                r.gain_nm_s_per_rad,
            ),
            ("human.stretch_reflex.delay_s".into(), r.delay_s),
            ("human.stretch_reflex.cutoff_rad_s".into(), r.cutoff_rad_s),
            (
                "human.cubic_stiffness_nm_per_rad3".into(),
                h.cubic_stiffness_nm_per_rad3,
            ),
            (
                "human.cubic_damping_nm_s3_per_rad3".into(),
                h.cubic_damping_nm_s3_per_rad3,
            ),
            (
                "human.quadratic_stiffness_nm_per_rad2".into(),
                h.quadratic_stiffness_nm_per_rad2,
            ),
            (
                "human.stiffness_drift_per_min".into(),
                h.stiffness_drift_per_min,
            ),
            ("human.rest_angle_rad".into(), h.rest_angle_rad),
            ("human.active_angle_rad".into(), h.active_angle_rad),
            ("exo.arm_inertia_kg_m2".into(), self.exo.arm_inertia_kg_m2),
            ("exo.load_lever_arm_m".into(), self.exo.load_lever_arm_m),
            ("exo.load_kg".into(), self.exo.load_kg),
            ("exo.backlash.lash_rad".into(), self.exo.backlash.lash_rad),
            (
                "exo.backlash.motor_inertia_kg_m2".into(),
                self.exo.backlash.motor_inertia_kg_m2,
            ),
            (
                "exo.backlash.mesh_stiffness_nm_per_rad".into(),
                self.exo.backlash.mesh_stiffness_nm_per_rad,
            ),
            (
                "exo.backlash.mesh_damping_nm_s_per_rad".into(),
                self.exo.backlash.mesh_damping_nm_s_per_rad,
            ),
            ("gravity.arm_mass_kg".into(), self.gravity.arm_mass_kg),
            ("gravity.arm_com_m".into(), self.gravity.arm_com_m),
            ("gravity.g_m_s2".into(), self.gravity.g_m_s2),
            (
                "joint_friction.coulomb.torque_nm".into(),
                self.joint_friction.coulomb.torque_nm,
            ),
            (
                "joint_friction.coulomb.smoothing_rad_s".into(),
                self.joint_friction.coulomb.smoothing_rad_s,
            ),
            (
                "joint_friction.viscous.b_nm_s_per_rad".into(),
                self.joint_friction.viscous.b_nm_s_per_rad,
            ),
            (
                "cuff.compliance.stiffness_nm_per_rad".into(),
                self.cuff.compliance.stiffness_nm_per_rad,
            ),
            (
                "cuff.compliance.damping_nm_s_per_rad".into(),
                self.cuff.compliance.damping_nm_s_per_rad,
            ),
            (
                "sea.dynamics.natural_frequency_hz".into(),
                self.sea.dynamics.natural_frequency_hz,
            ),
            (
                "sea.dynamics.damping_ratio".into(),
                self.sea.dynamics.damping_ratio,
            ),
            ("sea.torque_limit_nm".into(), self.sea.torque_limit_nm),
            (
                "sea.spring_stiffness_nm_per_rad".into(),
                self.sea.spring_stiffness_nm_per_rad,
            ),
            ("actuator.delay_s".into(), self.actuator.delay_s),
            (
                "sensors.encoder.counts_per_rev".into(),
                self.sensors.encoder.counts_per_rev,
            ),
            (
                "sensors.cuff_ft.lever_arm_m".into(),
                self.sensors.cuff_ft.lever_arm_m,
            ),
            (
                "sensors.cuff_ft.force_resolution_n".into(),
                self.sensors.cuff_ft.force_resolution_n,
            ),
            (
                "sensors.sea_deflection.counts_per_rev".into(),
                self.sensors.sea_deflection.counts_per_rev,
            ),
        ];
        for (name, t) in [
            ("sensors.encoder", self.sensors.encoder.terms),
            ("sensors.cuff_ft", self.sensors.cuff_ft.terms),
            ("sensors.sea_deflection", self.sensors.sea_deflection.terms),
        ] {
            out.push((format!("{name}.gain"), t.gain));
            out.push((format!("{name}.offset"), t.offset));
            out.push((format!("{name}.noise_std"), t.noise_std));
            out.push((format!("{name}.delay_s"), t.delay_s));
        }
        out.push(("integration.step_s".into(), self.integration.step_s));
        out.push(("integration.seed".into(), self.integration.seed as f64));
        out
    }
}

#[cfg(test)]
mod tests {
    //! Every numeric key of the shipped plant model set in turn to NaN,
    //! ±inf, 0, a negative value and 1e300: refused naming the key, or
    //! accepted within its documented range; never a panic.

    use super::*;
    use std::panic::{catch_unwind, AssertUnwindSafe};
    use toml::{Table, Value};

    fn plants_dir() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/plants")
    }

    fn leaf_mut<'a>(doc: &'a mut Table, path: &str) -> &'a mut Value {
        exo_config::toml_paths::leaf_mut(doc, path).unwrap_or_else(|| panic!("no key {path}"))
    }

    #[test]
    fn the_shipped_plants_are_valid() {
        for entry in std::fs::read_dir(plants_dir()).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "toml") {
                PlantModel::from_file(&path).unwrap_or_else(|e| panic!("{e}"));
            }
        }
    }

    #[test]
    fn every_numeric_key_is_refused_by_name_or_accepted_within_its_range() {
        let text = std::fs::read_to_string(plants_dir().join("default.toml")).unwrap();
        let doc: Table = toml::from_str(&text).unwrap();
        let keys: Vec<String> = exo_config::toml_paths::numeric_leaves(&Value::Table(doc.clone()))
            .into_iter()
            .map(|(k, _)| k)
            .collect();
        assert!(keys.len() > 40, "only {} numeric keys", keys.len());
        let mut failures = Vec::new();
        for key in &keys {
            let original = leaf_mut(&mut doc.clone(), key).clone();
            let (is_int, magnitude) = match original {
                Value::Integer(i) => (true, (i as f64).abs()),
                Value::Float(f) => (false, f.abs()),
                _ => unreachable!(),
            };
            let negative = if magnitude > 0.0 { -magnitude } else { -1.0 };
            let mut bad = vec![
                Value::Float(f64::NAN),
                Value::Float(f64::INFINITY),
                Value::Float(f64::NEG_INFINITY),
                Value::Float(1e300),
            ];
            if is_int {
                bad.extend([Value::Integer(0), Value::Integer(negative as i64)]);
            } else {
                bad.extend([Value::Float(0.0), Value::Float(negative)]);
            }
            for b in bad {
                let mut changed = doc.clone();
                *leaf_mut(&mut changed, key) = b.clone();
                let text = toml::to_string(&changed).unwrap();
                let outcome = catch_unwind(AssertUnwindSafe(|| {
                    PlantModel::from_toml_str(&text, "plant.toml")
                }));
                match outcome {
                    Err(_) => failures.push(format!("{key} = {b}: panicked")),
                    Ok(Err(e)) => {
                        let e = e.to_string();
                        if !(e.contains("plant.toml") && e.contains(key.as_str())) {
                            failures.push(format!("{key} = {b}: refused without naming it: {e}"));
                        }
                    }
                    Ok(Ok(_)) => {
                        let v = match b {
                            Value::Integer(i) => i as f64,
                            Value::Float(f) => f,
                            _ => unreachable!(),
                        };
                        match range_of(PLANT_RANGES, key) {
                            Some(r) if r.contains(v) => {}
                            r => failures.push(format!(
                                "{key} = {b}: accepted outside its documented range {r:?}"
                            )),
                        }
                    }
                }
            }
        }
        assert!(failures.is_empty(), "{}", failures.join("\n"));
    }

    #[test]
    fn a_huge_prony_bank_is_refused_naming_the_key() {
        let text = std::fs::read_to_string(plants_dir().join("default.toml"))
            .unwrap()
            .replace("mode = \"equivalent_viscous\"", "mode = \"prony\"");
        for (per_decade, ok) in [("3.0", true), ("50.0", false), ("1e9", false)] {
            let t = text.replace(
                "elements_per_decade = 3.0",
                &format!("elements_per_decade = {per_decade}"),
            );
            let r = PlantModel::from_toml_str(&t, "plant.toml");
            assert_eq!(r.is_ok(), ok, "{per_decade}: {r:?}");
            if let Err(e) = r {
                assert!(
                    e.to_string()
                        .contains("human.hysteretic_damping.elements_per_decade"),
                    "{e}"
                );
            }
        }
    }
}
