//! Ending a multisine experiment's analysis once its K and H are known
//! (`protocol.stop_when`, issue 34 item 3): the identifier's M2 estimates
//! of the running experiment ([`Controller::on_estimate`]) say whether its
//! 95 % intervals are narrow enough; if so, the window ends at the whole
//! period of the multisine after the one the estimate's data end with (at
//! least `min_periods` into the window, before its last): the protocol's
//! clock skips the rest of the window ([`Controller::analysis_skip`]). The
//! period after, not the next boundary: where the estimate is computed in
//! the same step as the controller's (`exo sim`) it is in hand at the very
//! boundary its data end at, where it comes from the identifier process it
//! arrives some samples later; counted from the data, both end the window
//! at the same tick. The skip is whole periods of a periodic
//! excitation at a constant bias and a full envelope, so every commanded
//! signal is continuous across it; the ramp-out, rest and the following
//! experiments then run as they would have, earlier.

use exo_config::{RunConfig, StopWhen};
use exo_impedance::fit::ci95_half_width;
use exo_impedance::ImpedanceModel;
use exo_messages::{FitModel, ImpedanceEstimate};

use super::Controller;

/// `protocol.stop_when` in ticks of the run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct StopRule {
    /// The thresholds and the fewest periods.
    when: StopWhen,
    /// Ticks in one period of the multisine.
    period_ticks: u64,
    /// Ticks from a protocol period's start to its analysis window
    /// (ramp-in and settling).
    analysis_from_ticks: u64,
    /// Whole multisine periods the analysis window holds at most.
    periods: u64,
    /// Ticks in one protocol period (one experiment's step).
    step_ticks: u64,
    /// One multisine period less half a sample (ns): a boundary is due
    /// once its sample is this long after the known estimate's data end.
    after_data_ns: u64,
}

impl StopRule {
    /// The rule of run `cfg`, when it has one (`protocol.stop_when` in
    /// multisine mode); its timing in ticks at `run.rate_hz`.
    pub(super) fn of_run(cfg: &RunConfig) -> Option<Self> {
        let (when, m) = (cfg.protocol.stop_when?, cfg.protocol.multisine()?);
        let rate = cfg.run.rate_hz;
        let ticks = |s: f64| (s * rate).round() as u64;
        let t = cfg.experiment_table().timing;
        Some(StopRule {
            when,
            period_ticks: ticks(m.period_s),
            analysis_from_ticks: ticks(t.ramp_in_s + t.settling_s),
            periods: u64::from(m.periods),
            step_ticks: ticks(t.period_s()),
            after_data_ns: ((m.period_s - 0.5 / rate) * 1e9).round() as u64,
        })
    }
}

/// What an estimate did to `protocol.stop_when`'s verdict
/// ([`Controller::on_estimate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopNews {
    /// Its experiment's K and H are now known well enough (they were not,
    /// or another experiment's were).
    Known,
    /// They were, and this estimate's are not: the window goes on.
    NoLongerKnown,
    /// The verdict stands: `met` by this estimate or not, as before.
    Unchanged {
        /// Whether this estimate met the rule.
        met: bool,
    },
}

impl Controller {
    /// Takes the identifier's estimate: with `protocol.stop_when`, an M2
    /// estimate says whether its experiment's K and H are known well
    /// enough (95 % half-widths, Student's t at the fit's `2n − 3` degrees
    /// of freedom, within the rule's fractions); the latest estimate of an
    /// experiment decides. Returns what that changed, `None` when the
    /// estimate decides nothing (no rule, another model, no degree of
    /// freedom). Allocation-free.
    pub fn on_estimate(&mut self, e: &ImpedanceEstimate) -> Option<StopNews> {
        let rule = self.stop_rule?;
        if FitModel::from_u32(e.model) != Some(FitModel::M2) {
            return None;
        }
        let dof = (2 * e.n_points as usize).checked_sub(ImpedanceModel::M2.n_params())?;
        let k_ci = ci95_half_width(e.k_h_se, dof).ok()?;
        let h_ci = ci95_half_width(e.h_h_se, dof).ok()?;
        let met = rule.when.met(e.k_h, k_ci, e.h_h, h_ci);
        let was = self.known_experiment() == Some(e.experiment);
        if met {
            self.known = Some((e.experiment, e.stamp_ns));
        } else if was {
            self.known = None;
        }
        Some(match (was, met) {
            (false, true) => StopNews::Known,
            (true, false) => StopNews::NoLongerKnown,
            _ => StopNews::Unchanged { met },
        })
    }

    /// The experiment whose K and H the latest estimate found known well
    /// enough (`protocol.stop_when`), if any.
    pub fn known_experiment(&self) -> Option<u32> {
        self.known.map(|(e, _)| e)
    }

    /// The ticks of analysis to skip now, `rel` ticks of protocol time
    /// after a start at step `from_step`, at a sample stamped `stamp_ns`:
    /// the rest of the analysis window when the running experiment is
    /// known, this tick begins its `k`-th whole multisine period,
    /// `min_periods ≤ k < periods`, and a whole period has passed since the
    /// known estimate's data end.
    pub(super) fn analysis_skip(&self, from_step: usize, rel: u64, stamp_ns: u64) -> Option<u64> {
        let rule = self.stop_rule?;
        let (known, data_end_ns) = self.known?;
        if stamp_ns < data_end_ns.saturating_add(rule.after_data_ns) {
            return None;
        }
        let step = from_step.checked_add(usize::try_from(rel / rule.step_ticks).ok()?)?;
        let (experiment, _) = self.protocol.step(step)?;
        if experiment != known {
            return None;
        }
        let into_analysis = (rel % rule.step_ticks).checked_sub(rule.analysis_from_ticks)?;
        if !into_analysis.is_multiple_of(rule.period_ticks) {
            return None;
        }
        let k = into_analysis / rule.period_ticks;
        (k >= u64::from(rule.when.min_periods) && k < rule.periods)
            .then(|| (rule.periods - k) * rule.period_ticks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TickInput;
    use exo_messages::{OperatorCommand, OperatorCommandKind as K, ProtocolPhase};

    const RATE: f64 = 200.0;
    /// Ticks in one period of the multisine (0.5 s at 200 Hz).
    const N: u64 = 100;
    /// Whole periods the analysis window holds at most.
    const PERIODS: u64 = 5;
    /// Nanoseconds a tick at 200 Hz; tick `k` is stamped `k · TICK_NS`.
    const TICK_NS: u64 = 5_000_000;

    /// The shipped multisine run at 200 Hz with 0.5 s periods, five
    /// analysed, one of settling, and `stop_when` with `min_periods` (none
    /// without), written to a run file of its own (the timing follows from
    /// the file).
    fn run_file(min_periods: Option<u32>) -> RunConfig {
        let dir = exo_config::configs_dir();
        let text = std::fs::read_to_string(dir.join("multisine.toml")).unwrap();
        let mut out = String::new();
        let mut in_multisine = false;
        for line in text.lines() {
            let key = line.split('=').next().unwrap_or("").trim();
            if line.starts_with('[') {
                in_multisine = line.trim() == "[protocol.multisine]";
            }
            let line = match key {
                "plant_model" | "subject_file" | "experiments_file" => {
                    let rel = line.split('"').nth(1).unwrap();
                    format!("{key} = \"{}\"", dir.join(rel).display())
                }
                "rate_hz" => format!("rate_hz = {RATE}"),
                "band_rad_s" if in_multisine => "band_rad_s = [13.0, 60.0]".into(),
                "lines" if in_multisine => "lines = 3".into(),
                "period_s" if in_multisine => format!("period_s = {}", N as f64 / RATE),
                "periods" if in_multisine => format!("periods = {PERIODS}"),
                _ => line.to_string(),
            };
            out.push_str(&line);
            out.push('\n');
        }
        if let Some(min) = min_periods {
            out.push_str(&format!(
                "\n[protocol.stop_when]\nk_rel_ci = 0.05\nh_rel_ci = 0.10\nmin_periods = {min}\n"
            ));
        }
        let file = std::env::temp_dir().join(format!(
            "exo-stop-when-{}-{min_periods:?}.toml",
            std::process::id()
        ));
        std::fs::write(&file, out).unwrap();
        let cfg = RunConfig::from_file(&file).unwrap();
        let _ = std::fs::remove_file(&file);
        cfg
    }

    fn run(min_periods: u32) -> RunConfig {
        run_file(Some(min_periods))
    }

    /// An M2 estimate of `experiment` from 3 lines (dof 3: t = 3.182) with
    /// K 40 ± `k_se`, H 10 ± `h_se`, whose data end at `end_ns`.
    fn m2_at(experiment: u32, k_se: f64, h_se: f64, end_ns: u64) -> ImpedanceEstimate {
        ImpedanceEstimate {
            stamp_ns: end_ns,
            experiment,
            period: 1,
            n_points: 3,
            model: FitModel::M2.as_u32(),
            k_h: 40.0,
            k_h_se: k_se,
            h_h: 10.0,
            h_h_se: h_se,
            ..Default::default()
        }
    }

    /// [`m2_at`] with the data ending with tick `last` (stamped just after
    /// it, as the identifier does).
    fn m2_to(experiment: u32, k_se: f64, h_se: f64, last: u64) -> ImpedanceEstimate {
        m2_at(experiment, k_se, h_se, last * TICK_NS + 1)
    }

    type Seen = (u64, u32, ProtocolPhase, f64, f64);

    /// Ticks the controller from `from` to `to` (exclusive) at rest, with
    /// `deliver` called before each tick; each tick's experiment, phase,
    /// excitation and bias.
    fn ticks(
        c: &mut Controller,
        from: u64,
        to: u64,
        mut deliver: impl FnMut(&mut Controller, u64),
    ) -> Vec<Seen> {
        (from..to)
            .map(|seq| {
                deliver(c, seq);
                let t = c.tick(&TickInput {
                    seq,
                    stamp_ns: seq * TICK_NS,
                    theta_e_rad: 0.8,
                    ..Default::default()
                });
                let p = t.protocol;
                (
                    seq,
                    p.experiment,
                    p.phase,
                    p.tau_excitation_nm,
                    p.tau_bias_nm,
                )
            })
            .collect()
    }

    /// The first tick of experiment `n` in `phase`.
    fn first(t: &[Seen], n: u32, phase: ProtocolPhase) -> u64 {
        t.iter()
            .find(|x| x.1 == n && x.2 == phase)
            .map(|x| x.0)
            .unwrap()
    }

    /// Ticks of the protocol's step and of its analysis start, by hand
    /// from the run file's timing.
    fn timing(cfg: &RunConfig) -> (u64, u64) {
        let t = cfg.experiment_table().timing;
        (
            (t.period_s() * RATE).round() as u64,
            ((t.ramp_in_s + t.settling_s) * RATE).round() as u64,
        )
    }

    /// The largest step of a signal from one tick to the next over `ticks`.
    fn largest_step(t: &[Seen], ticks: std::ops::Range<u64>, f: impl Fn(&Seen) -> f64) -> f64 {
        ticks
            .map(|k| (f(&t[k as usize + 1]) - f(&t[k as usize])).abs())
            .fold(0.0, f64::max)
    }

    #[test]
    fn without_an_estimate_every_analysis_runs_its_whole_periods() {
        let cfg = run(2);
        let (step, analysis) = timing(&cfg);
        let mut c = Controller::from_config(&cfg).unwrap();
        let t = ticks(&mut c, 0, 2 * step, |_, _| {});
        assert_eq!(first(&t, 1, ProtocolPhase::Analysis), analysis);
        assert_eq!(first(&t, 1, ProtocolPhase::RampOut), analysis + PERIODS * N);
        assert_eq!(first(&t, 7, ProtocolPhase::RampIn), step);
    }

    /// K ± 3.182 · 0.5 = 1.6 (4 % of 40), H ± 3.182 · 0.25 = 0.8 (8 % of
    /// 10): known, from the window's first two periods. In hand at the
    /// very boundary its data end at (as in `exo sim`) or half a period
    /// later (as from the identifier process), the window ends one period
    /// later, after three whole periods, and everything after comes two
    /// periods earlier; the excitation is continuous across the skip
    /// (whole periods of a periodic signal), and the next experiment is not
    /// cut short.
    #[test]
    fn a_known_experiment_ends_its_analysis_a_period_after_its_data() {
        let cfg = run(2);
        let (step, analysis) = timing(&cfg);
        let data_end = analysis + 2 * N - 1;
        for arrives in [data_end, data_end + N / 2] {
            let mut c = Controller::from_config(&cfg).unwrap();
            let t = ticks(&mut c, 0, 2 * step, |c, seq| {
                if seq == arrives {
                    assert_eq!(
                        c.on_estimate(&m2_to(1, 0.5, 0.25, data_end)),
                        Some(StopNews::Known)
                    );
                }
            });
            assert_eq!(c.known_experiment(), Some(1));
            let out = first(&t, 1, ProtocolPhase::RampOut);
            assert_eq!(out, analysis + 3 * N, "arriving at {arrives}");
            assert_eq!(first(&t, 7, ProtocolPhase::RampIn), step - 2 * N);
            assert_eq!(
                first(&t, 7, ProtocolPhase::RampOut) - first(&t, 7, ProtocolPhase::Analysis),
                PERIODS * N
            );
            // The excitation at the skip: the step from the last analysed
            // tick to the first of the ramp-out is like any other tick's.
            let jump = (t[out as usize].3 - t[out as usize - 1].3).abs();
            let typical = largest_step(&t, analysis..out - 1, |x| x.3);
            assert!(jump <= typical, "{jump} against {typical}");
        }
    }

    /// A data end stamped on a sample's own time, or half a sample after
    /// it, still counts from that sample (the tolerance for a stamp's
    /// jitter): the window ends a whole period after it.
    #[test]
    fn a_data_end_within_half_a_sample_counts_from_that_sample() {
        let cfg = run(2);
        let (_, analysis) = timing(&cfg);
        for end_ns in [
            (analysis + 2 * N) * TICK_NS,
            (analysis + 2 * N) * TICK_NS + TICK_NS / 2,
        ] {
            let mut c = Controller::from_config(&cfg).unwrap();
            let t = ticks(&mut c, 0, analysis + (PERIODS + 1) * N, |c, seq| {
                if seq == analysis + 2 * N {
                    c.on_estimate(&m2_at(1, 0.5, 0.25, end_ns));
                }
            });
            assert_eq!(
                first(&t, 1, ProtocolPhase::RampOut),
                analysis + 3 * N,
                "data end {end_ns} ns"
            );
        }
        // Data ending half-way through the third period (an estimate need
        // not end on a boundary): the first boundary a whole period after
        // it is the fifth period's start.
        let mut c = Controller::from_config(&cfg).unwrap();
        let t = ticks(&mut c, 0, analysis + (PERIODS + 1) * N, |c, seq| {
            if seq == analysis + 2 * N + N / 2 + 1 {
                c.on_estimate(&m2_to(1, 0.5, 0.25, analysis + 2 * N + N / 2));
            }
        });
        assert_eq!(first(&t, 1, ProtocolPhase::RampOut), analysis + 4 * N);
    }

    #[test]
    fn no_window_ends_before_min_periods_nor_for_a_wide_or_another_estimate() {
        // Known during the first period: the window still holds `min_periods`.
        for min in [2, 3] {
            let cfg = run(min);
            let (_, analysis) = timing(&cfg);
            let mut c = Controller::from_config(&cfg).unwrap();
            let t = ticks(&mut c, 0, analysis + (PERIODS + 1) * N, |c, seq| {
                if seq == analysis + 10 {
                    c.on_estimate(&m2_to(1, 0.5, 0.25, analysis + 9));
                }
            });
            assert_eq!(
                first(&t, 1, ProtocolPhase::RampOut),
                analysis + u64::from(min) * N,
                "min_periods {min}"
            );
        }
        let cfg = run(2);
        let (_, analysis) = timing(&cfg);
        let at = analysis + 10;
        for (e, news) in [
            // K ± 3.182 · 0.7 = 2.2: 5.6 % of 40, beyond 5 %.
            (
                m2_to(1, 0.7, 0.25, at),
                Some(StopNews::Unchanged { met: false }),
            ),
            // H ± 3.182 · 0.35 = 1.1: 11 % of 10, beyond 10 %.
            (
                m2_to(1, 0.5, 0.35, at),
                Some(StopNews::Unchanged { met: false }),
            ),
            // Known, but of another experiment.
            (m2_to(7, 0.5, 0.25, at), Some(StopNews::Known)),
            // Not M2.
            (
                ImpedanceEstimate {
                    model: FitModel::M3.as_u32(),
                    ..m2_to(1, 0.5, 0.25, at)
                },
                None,
            ),
            // One line: M2's three parameters leave no degree of freedom.
            (
                ImpedanceEstimate {
                    n_points: 1,
                    ..m2_to(1, 0.5, 0.25, at)
                },
                None,
            ),
        ] {
            let mut c = Controller::from_config(&cfg).unwrap();
            let t = ticks(&mut c, 0, analysis + (PERIODS + 1) * N, |c, seq| {
                if seq == at + 1 {
                    assert_eq!(c.on_estimate(&e), news, "{e:?}");
                }
            });
            assert_eq!(
                first(&t, 1, ProtocolPhase::RampOut),
                analysis + PERIODS * N,
                "{e:?}"
            );
        }
        // Known, known again, then not: the latest estimate decides, and
        // says what changed.
        let mut c = Controller::from_config(&cfg).unwrap();
        let t = ticks(&mut c, 0, analysis + (PERIODS + 1) * N, |c, seq| {
            if seq == analysis + 10 {
                assert_eq!(
                    c.on_estimate(&m2_to(1, 0.5, 0.25, seq - 1)),
                    Some(StopNews::Known)
                );
            }
            if seq == analysis + 20 {
                assert_eq!(
                    c.on_estimate(&m2_to(1, 0.5, 0.25, seq - 1)),
                    Some(StopNews::Unchanged { met: true })
                );
            }
            if seq == analysis + 30 {
                assert_eq!(
                    c.on_estimate(&m2_to(1, 2.0, 0.25, seq - 1)),
                    Some(StopNews::NoLongerKnown)
                );
            }
        });
        assert_eq!(c.known_experiment(), None);
        assert_eq!(first(&t, 1, ProtocolPhase::RampOut), analysis + PERIODS * N);
    }

    #[test]
    fn a_run_without_stop_when_ignores_the_estimates() {
        let cfg = run_file(None);
        let (_, analysis) = timing(&cfg);
        let mut c = Controller::from_config(&cfg).unwrap();
        let t = ticks(&mut c, 0, analysis + (PERIODS + 1) * N, |c, seq| {
            if seq == analysis + 10 {
                assert_eq!(c.on_estimate(&m2_to(1, 0.5, 0.25, analysis + 9)), None);
            }
        });
        assert_eq!(first(&t, 1, ProtocolPhase::RampOut), analysis + PERIODS * N);
    }

    /// An operator's stop and start of the known experiment measures it
    /// afresh: the earlier window's estimate does not end the new window,
    /// which runs its whole periods without a new one.
    #[test]
    fn a_window_started_again_is_not_ended_by_an_earlier_estimate() {
        let cfg = run(2);
        let (_, analysis) = timing(&cfg);
        let mut c = Controller::from_config(&cfg).unwrap();
        let stop = analysis + 50;
        let t = ticks(&mut c, 0, 3 * analysis + 2000, |c, seq| {
            if seq == analysis + 10 {
                c.on_estimate(&m2_to(1, 0.5, 0.25, analysis + 9));
            }
            if seq == stop {
                c.on_operator(&OperatorCommand::new(1, 0, K::StopProtocol, 0.0));
            }
            if seq == stop + 2000 {
                c.on_operator(&OperatorCommand::new(2, 0, K::StartProtocol, 1.0));
            }
        });
        assert_eq!(c.known_experiment(), None);
        let opens: Vec<u64> = t
            .windows(2)
            .filter(|w| {
                w[1].1 == 1
                    && w[1].2 == ProtocolPhase::Analysis
                    && w[0].2 != ProtocolPhase::Analysis
            })
            .map(|w| w[1].0)
            .collect();
        assert_eq!(opens.len(), 2, "{opens:?}");
        let closes = t
            .iter()
            .find(|x| x.0 > opens[1] && x.1 == 1 && x.2 == ProtocolPhase::RampOut)
            .map(|x| x.0)
            .unwrap();
        assert_eq!(closes - opens[1], PERIODS * N);
    }

    /// After a window ended early, an operator's stop ramps out from where
    /// the protocol is (the skipped periods counted): stopped in the next
    /// experiment's ramp-in, its bias fades from the value it had, with no
    /// step larger than the ramp's own.
    #[test]
    fn an_operator_stop_after_an_early_end_ramps_out_from_where_it_is() {
        let cfg = run(2);
        let (step, analysis) = timing(&cfg);
        let mut c = Controller::from_config(&cfg).unwrap();
        let data_end = analysis + 2 * N - 1;
        let ramp_in_7 = step - 2 * N;
        let stop = ramp_in_7 + 2 * N + 37;
        let t = ticks(&mut c, 0, stop + 2 * N, |c, seq| {
            if seq == data_end + 1 {
                c.on_estimate(&m2_to(1, 0.5, 0.25, data_end));
            }
            if seq == stop {
                let out = c.on_operator(&OperatorCommand::new(1, 0, K::StopProtocol, 0.0));
                assert!(
                    matches!(out, crate::OperatorOutcome::Stopping { experiment: 7, .. }),
                    "{out:?}"
                );
            }
        });
        assert_eq!(first(&t, 7, ProtocolPhase::RampIn), ramp_in_7);
        let bias = |k: u64| t[k as usize].4;
        assert!(bias(stop - 1) > 0.0, "experiment 7's bias ramps in");
        let ramp = largest_step(&t, ramp_in_7..stop - 1, |x| x.4);
        let at_stop = (bias(stop) - bias(stop - 1)).abs();
        assert!(
            at_stop <= 1.01 * ramp,
            "{at_stop} against the ramp's {ramp}"
        );
    }
}
