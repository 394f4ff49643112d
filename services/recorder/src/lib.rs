//! # exo-recorder (logic)
//!
//! The recorder writes every channel of a run into one contract MCAP
//! (`docs/recording-format.md`) through `exo-recording`. It only
//! subscribes: iceoryx2 subscribers with safe overflow never block a
//! publisher, so a slow, killed or hung recorder cannot delay control; what
//! it misses it counts from gaps in each topic's `seq` ([`DropCounter`]) and
//! reports in its log and in the file's `exo.drops` metadata.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use exo_config::RunConfig;

/// Counts samples missed on one topic from gaps in a sequence number that
/// rises by one per sample.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DropCounter {
    last: Option<u64>,
    /// Samples seen.
    pub received: u64,
    /// Samples missed (sum of the gaps).
    pub dropped: u64,
    /// Samples that went backwards or repeated (a restarted publisher, a re-send).
    pub out_of_order: u64,
}

impl DropCounter {
    /// Accounts for one sample with sequence number `seq`.
    pub fn see(&mut self, seq: u64) {
        self.received += 1;
        match self.last {
            Some(last) if seq > last => self.dropped += seq - last - 1,
            Some(_) => self.out_of_order += 1,
            None => {}
        }
        if self.last.is_none_or(|l| seq > l) {
            self.last = Some(seq);
        }
    }
}

/// The default recording path: `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`.
pub fn default_output(cfg: &RunConfig, unix_s: u64) -> PathBuf {
    cfg.run.output_dir.join(format!(
        "{}-{}-{unix_s}.mcap",
        cfg.run.instance,
        cfg.subject().name
    ))
}

/// The `exo` metadata record of a run (see the recording format).
pub fn run_metadata(cfg: &RunConfig, config_file: &Path) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        m.insert(k.to_string(), v);
    };
    put("subject", cfg.subject().name.clone());
    put("software_version", exo_recording::SOFTWARE.to_string());
    put("config_file", config_file.display().to_string());
    put("arm_inertia_kg_m2", cfg.rig.arm_inertia_kg_m2.to_string());
    put("load_lever_arm_m", cfg.rig.load_lever_arm_m.to_string());
    put("m_h_kg_m2", cfg.subject().inertia_kg_m2.to_string());
    put("rate_hz", cfg.run.rate_hz.to_string());
    put("timing", format!("{:?}", cfg.run.timing).to_lowercase());
    put("instance", cfg.run.instance.clone());
    put("seed", cfg.run.seed.to_string());
    put(
        "protocol_mode",
        format!("{:?}", cfg.protocol.mode).to_lowercase(),
    );
    m
}

/// The `exo.drops` metadata record: per topic, samples missed.
pub fn drops_metadata<'a>(
    counters: impl IntoIterator<Item = (&'a str, &'a DropCounter)>,
) -> BTreeMap<String, String> {
    counters
        .into_iter()
        .map(|(topic, c)| (topic.to_string(), c.dropped.to_string()))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_are_counted_and_repeats_are_not_drops() {
        let mut c = DropCounter::default();
        for s in [0, 1, 2, 5, 6, 6, 3, 7, 10] {
            c.see(s);
        }
        assert_eq!(c.received, 9);
        assert_eq!(c.dropped, 2 + 2);
        assert_eq!(c.out_of_order, 2);
    }

    #[test]
    fn the_run_metadata_names_the_subject_and_the_rig() {
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        let m = run_metadata(&cfg, Path::new("configs/default.toml"));
        assert_eq!(m["subject"], "B");
        assert_eq!(m["arm_inertia_kg_m2"], "0.1");
        assert_eq!(m["load_lever_arm_m"], "0.45");
        assert!(default_output(&cfg, 7)
            .to_string_lossy()
            .ends_with("exo-B-7.mcap"));
    }
}
