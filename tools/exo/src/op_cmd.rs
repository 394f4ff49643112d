//! `exo op`: the operator console. Sends one [`OperatorCommand`] to a
//! running system on its `<instance>/operator` channel: reset a latched
//! fault, adopt a fractional order f, start or stop the protocol.
//!
//! It opens an iceoryx2 node like the other tools, subscribes to the
//! controller's answers (`<instance>/operator/reply`), waits (bounded)
//! until a controller listens, sends the command once with a `seq` unique
//! per send (the wall clock in ns) and waits (bounded by `--wait-s`) for
//! the answer to that `seq`: it prints what the controller did and exits 0,
//! or what it refused and why and exits 1; no controller or no answer
//! exits 2, naming the instance.

use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use exo_config::RunConfig;
use exo_messages::{OperatorCommand, OperatorCommandKind, OperatorVerdict};
use exo_service_kit::channels::{OPERATOR, OPERATOR_REPLY};
use exo_service_kit::ipc::Ipc;

/// The least time given to an answer after sending, whatever `--wait-s`:
/// the controller takes operator commands once per control tick.
const LINGER: Duration = Duration::from_millis(300);

/// Arguments of `exo op`.
#[derive(Debug, Args)]
pub struct OpArgs {
    /// The run file of the running system (its `run.instance` names the channels).
    #[arg(
        long,
        value_name = "RUN.toml",
        global = true,
        conflicts_with = "instance"
    )]
    config: Option<PathBuf>,
    /// The running system's instance (`run.instance`; default "exo").
    #[arg(long, value_name = "NAME", global = true)]
    instance: Option<String>,
    /// The iceoryx2 configuration (default: $EXO_ICEORYX2_CONFIG, else configs/iceoryx2.toml).
    #[arg(long, value_name = "FILE", global = true)]
    iceoryx2_config: Option<PathBuf>,
    /// How long to wait for a controller to listen (s).
    #[arg(long, value_name = "SECONDS", default_value_t = 2.0, global = true)]
    wait_s: f64,
    #[command(subcommand)]
    action: OpAction,
}

/// What to ask for.
#[derive(Debug, Clone, Copy, Subcommand)]
enum OpAction {
    /// Clear the controller's latched fault and the sensor driver's latched safe state.
    Reset,
    /// Adopt the fractional order F (in [0, 1); the controller clamps it to
    /// the run's controller.f_bounds), e.g. the identifier's recommended f.
    AdoptF {
        /// The fractional order f.
        #[arg(value_name = "F", allow_negative_numbers = true)]
        f: f64,
    },
    /// (Re)start the protocol at experiment N's first period (1–9; one of
    /// the run's protocol.experiments), ramping a running period out first;
    /// without N (or 0), continue a stopped protocol.
    Start {
        /// The experiment to start at; 0 or none: continue after a stop.
        #[arg(value_name = "N", allow_negative_numbers = true)]
        experiment: Option<u32>,
    },
    /// Stop the protocol: bias and excitation ramp out, then gravity
    /// compensation is held (no fault) until a start or the end of the run.
    Stop,
}

impl OpAction {
    /// The command's kind and value, or an error naming the bad argument.
    fn kind_and_value(self) -> Result<(OperatorCommandKind, f64)> {
        Ok(match self {
            OpAction::Reset => (OperatorCommandKind::ResetFault, 0.0),
            OpAction::AdoptF { f } => {
                if !(f.is_finite() && (0.0..1.0).contains(&f)) {
                    bail!("adopt-f: F must be a fractional order in [0, 1), not {f}");
                }
                (OperatorCommandKind::AdoptFractionalOrder, f)
            }
            OpAction::Start { experiment } => {
                let n = experiment.unwrap_or(0);
                if n > exo_messages::protocol::MAX_EXPERIMENT {
                    bail!(
                        "start: N must be an experiment 1–{} (or 0 / none to continue after a stop), not {n}",
                        exo_messages::protocol::MAX_EXPERIMENT
                    );
                }
                (OperatorCommandKind::StartProtocol, f64::from(n))
            }
            OpAction::Stop => (OperatorCommandKind::StopProtocol, 0.0),
        })
    }
}

/// Why `exo op` did not succeed, with its exit code: a refusal (1) or no
/// answer (2). Bad arguments and other errors exit 1 as every command's do.
#[derive(Debug, thiserror::Error)]
pub enum OpFailure {
    /// The controller refused the command (its reason in the text).
    #[error("{0}")]
    Refused(String),
    /// No controller listens, none answered within `--wait-s`, or its answer
    /// did not decode.
    #[error("{0}")]
    NoAnswer(String),
}

impl OpFailure {
    /// The process's exit code: 1 for a refusal, 2 for no answer.
    pub fn exit_code(&self) -> i32 {
        match self {
            OpFailure::Refused(_) => 1,
            OpFailure::NoAnswer(_) => 2,
        }
    }
}

/// Runs `exo op`: exits 0 only on an accepted command, 1 on a refusal, 2
/// when no controller answers within `--wait-s`.
pub fn run(args: &OpArgs) -> Result<()> {
    let (kind, value) = args.action.kind_and_value()?;
    if !(args.wait_s.is_finite() && args.wait_s >= 0.0) {
        bail!(
            "--wait-s must be a finite number of seconds ≥ 0, not {}",
            args.wait_s
        );
    }
    let instance = match (&args.config, &args.instance) {
        (Some(path), _) => RunConfig::from_file(path)?.run.instance,
        (None, Some(name)) => name.clone(),
        (None, None) => "exo".to_string(),
    };
    let node = format!("exo_op_{}", std::process::id());
    let ipc = Ipc::open(&node, &instance, args.iceoryx2_config.as_deref())
        .context("opening the operator console's iceoryx2 node")?;
    let replies = ipc.inbox(OPERATOR_REPLY, 16)?;
    let outbox = ipc.outbox(OPERATOR)?;
    let patience = Duration::from_secs_f64(args.wait_s);
    let start = Instant::now();
    if !controller_listens(&ipc, patience)? {
        return Err(OpFailure::NoAnswer(format!(
            "no controller is listening on `{}` (waited {} s): is the run with instance `{instance}` going (exo run RUN.toml)?",
            outbox.name(),
            args.wait_s
        ))
        .into());
    }
    let seq = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let cmd = OperatorCommand::new(seq, exo_service_kit::monotonic_ns(), kind, value);
    cmd.validate()
        .with_context(|| format!("operator command {kind}"))?;
    outbox.send(cmd)?;
    // The answer, bounded by what is left of the patience (at least the
    // controller's tick to take it: LINGER).
    let deadline = start + patience.max(LINGER);
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        let Some(reply) = replies.recv_timeout(left.min(Duration::from_millis(50)))? else {
            if left.is_zero() {
                return Err(OpFailure::NoAnswer(format!(
                    "sent {kind} value {value} as seq {seq} on {}, but no answer came on `{instance}/operator/reply` within {} s",
                    outbox.name(),
                    args.wait_s
                ))
                .into());
            }
            continue;
        };
        if reply.seq != seq {
            continue; // another console's
        }
        if let Err(e) = reply.validate() {
            return Err(OpFailure::NoAnswer(format!(
                "the controller's answer to seq {seq} does not decode ({e}); not taken for an acceptance"
            ))
            .into());
        }
        let text = reply.text().unwrap_or_default();
        return match reply.verdict() {
            Some(OperatorVerdict::Accepted) => {
                println!("exo op: {kind} value {value} (seq {seq}): {text}");
                Ok(())
            }
            Some(OperatorVerdict::Refused) => Err(OpFailure::Refused(format!(
                "the controller refused {kind} (seq {seq}): {text}"
            ))
            .into()),
            // A fresh seq per send: a repeat means another console sent
            // the same one.
            Some(OperatorVerdict::Repeated) | None => Err(OpFailure::NoAnswer(format!(
                "the controller took seq {seq} for a repeat ({text}); nothing done"
            ))
            .into()),
        };
    }
}

/// Waits until a controller listens on the operator channel: a subscriber
/// there and a publisher on the reply channel, which only a controller has
/// (a player replaying a run publishes the protocol, never replies).
/// Bounded by `patience`; whether one does.
fn controller_listens(ipc: &Ipc, patience: Duration) -> Result<bool> {
    let start = Instant::now();
    loop {
        let listening = ipc.port_counts(OPERATOR)?.subscribers > 0
            && ipc.port_counts(OPERATOR_REPLY)?.publishers > 0;
        if listening {
            return Ok(true);
        }
        if start.elapsed() >= patience {
            return Ok(false);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}
