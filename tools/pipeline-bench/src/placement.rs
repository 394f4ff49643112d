//! The paced baselines run under the pipeline's CPU placement and
//! scheduling: the run file's `[realtime]` (CPU per process, `SCHED_FIFO`,
//! locked memory) is applied to the stand-in in each process's place and
//! to the bench's own probing thread, so that a pinned pipeline is never
//! compared with an unpinned ping-pong (on this VM, where the hand-over
//! crosses CPUs moves the round trip's median by a factor of three).

use std::ffi::OsString;

use anyhow::{anyhow, Result};
use exo_config::RunConfig;
use exo_service_kit::{request_realtime, RealtimeProcess, RealtimeRequest};

/// What each process of the loop asks for in real time.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Placement {
    /// The plant simulator (in the bare loops: the bench, which plays it).
    pub plant: RealtimeRequest,
    /// The sensor driver (in the ping-pong: the bench, which plays it).
    pub driver: RealtimeRequest,
    /// The controller.
    pub controller: RealtimeRequest,
}

impl Placement {
    /// The placement the services of `cfg` take in real time (none unless
    /// `cfg` has a `[realtime]` section).
    pub fn of(cfg: &RunConfig) -> Self {
        let rt = cfg.realtime.as_ref();
        Placement {
            plant: RealtimeRequest::of(rt, RealtimeProcess::PlantSim),
            driver: RealtimeRequest::of(rt, RealtimeProcess::SensorDriver),
            controller: RealtimeRequest::of(rt, RealtimeProcess::Controller),
        }
    }

    /// One line for the table's header.
    pub fn describe(&self) -> String {
        let one = |r: &RealtimeRequest| {
            let mut parts = vec![match r.cpu {
                Some(c) => format!("CPU {c}"),
                None => "any CPU".to_string(),
            }];
            if let Some(p) = r.sched_fifo_priority {
                parts.push(format!("SCHED_FIFO {p}"));
            }
            if r.lock_memory {
                parts.push("mlockall".to_string());
            }
            parts.join(", ")
        };
        format!(
            "plant {}; driver {}; controller {}",
            one(&self.plant),
            one(&self.driver),
            one(&self.controller)
        )
    }
}

/// The hidden command-line flags that pass `req` to a stand-in.
pub fn role_flags(req: &RealtimeRequest) -> Vec<OsString> {
    let mut v = Vec::new();
    if let Some(c) = req.cpu {
        v.push("--cpu".into());
        v.push(c.to_string().into());
    }
    if let Some(p) = req.sched_fifo_priority {
        v.push("--fifo-priority".into());
        v.push(p.to_string().into());
    }
    if req.lock_memory {
        v.push("--lock-memory".into());
    }
    v
}

/// Places the calling thread as `req` asks (affinity and scheduling are
/// per thread on Linux); refusals are printed, as the services log theirs.
/// Children started afterwards inherit the placement, so start them first.
pub fn place_this_thread(who: &str, req: RealtimeRequest) {
    if req != RealtimeRequest::default() {
        for r in request_realtime(who, req).refusals {
            eprintln!("exo-pipeline-bench: {who}: {r}");
        }
    }
}

/// Runs `f` on a thread of its own, so that what it does to its thread's
/// placement ([`place_this_thread`]) ends with it.
pub fn on_own_thread<T: Send>(who: &str, f: impl FnOnce() -> Result<T> + Send) -> Result<T> {
    std::thread::scope(|s| {
        s.spawn(f)
            .join()
            .map_err(|_| anyhow!("{who}: the probing thread panicked"))?
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use exo_service_kit::allowed_cpus;

    #[test]
    fn the_flags_carry_every_setting_and_nothing_when_nothing_is_asked() {
        assert!(role_flags(&RealtimeRequest::default()).is_empty());
        let f = role_flags(&RealtimeRequest {
            sched_fifo_priority: Some(80),
            lock_memory: true,
            cpu: Some(1),
        });
        let f: Vec<String> = f.iter().map(|s| s.to_string_lossy().into_owned()).collect();
        assert_eq!(f, ["--cpu", "1", "--fifo-priority", "80", "--lock-memory"]);
    }

    #[test]
    fn a_run_file_without_realtime_places_nothing() {
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
        assert_eq!(Placement::of(&cfg), Placement::default());
        assert!(Placement::of(&cfg).describe().contains("plant any CPU"));
    }

    #[test]
    fn the_shipped_realtime_run_file_puts_the_control_path_on_one_cpu() {
        let cfg = RunConfig::from_file(&exo_config::configs_dir().join("realtime.toml")).unwrap();
        assert_eq!(cfg.run.timing, exo_config::TimingMode::Realtime);
        let p = Placement::of(&cfg);
        assert_eq!(p.driver.cpu, Some(1));
        assert_eq!(p.controller.cpu, p.driver.cpu);
        assert_eq!(p.plant.cpu, p.driver.cpu);
        assert_eq!(
            p.describe(),
            "plant CPU 1, SCHED_FIFO 80, mlockall; driver CPU 1, SCHED_FIFO 80, mlockall; \
             controller CPU 1, SCHED_FIFO 80, mlockall"
        );
    }

    #[test]
    fn a_placement_ends_with_its_thread() {
        let before = allowed_cpus().unwrap();
        let v = on_own_thread("test", || {
            place_this_thread(
                "test",
                RealtimeRequest {
                    cpu: Some(0),
                    ..Default::default()
                },
            );
            Ok(allowed_cpus().unwrap())
        })
        .unwrap();
        assert_eq!(v, vec![0]);
        assert_eq!(allowed_cpus().unwrap(), before);
    }
}
