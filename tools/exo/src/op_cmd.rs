//! `exo op`: the operator console. Sends one [`OperatorCommand`] to a
//! running system on its `<instance>/operator` channel: reset a latched
//! fault, adopt a fractional order f, start or stop the protocol.
//!
//! It opens an iceoryx2 node like the other tools, waits (bounded) until a
//! controller listens, sends the command once with a `seq` unique per send
//! (the wall clock in ns) and keeps its publisher a moment so the command
//! reaches the receivers, which act on each `seq` once and log what they did.
//! The controller's log says whether it was acted on or refused (and why).

use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use exo_config::RunConfig;
use exo_messages::{OperatorCommand, OperatorCommandKind};
use exo_service_kit::channels::{OPERATOR, PROTOCOL};
use exo_service_kit::ipc::Ipc;

/// How long the publisher stays after sending: the receivers take operator
/// commands once per control tick, and a subscriber connecting meanwhile
/// still gets the command from the publisher's history.
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

/// Runs `exo op`.
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
    let outbox = ipc.outbox(OPERATOR)?;
    if !controller_listens(&ipc, Duration::from_secs_f64(args.wait_s))? {
        bail!(
            "no controller is listening on `{}` (waited {} s): is the run with instance `{instance}` going (exo run RUN.toml)?",
            outbox.name(),
            args.wait_s
        );
    }
    let seq = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let cmd = OperatorCommand::new(seq, exo_service_kit::monotonic_ns(), kind, value);
    cmd.validate()
        .with_context(|| format!("operator command {kind}"))?;
    outbox.send(cmd)?;
    println!(
        "exo op: sent {kind} value {value} as seq {seq} on {}; the controller's log says what it did",
        outbox.name()
    );
    std::thread::sleep(LINGER);
    Ok(())
}

/// Waits until a controller listens on the operator channel: a subscriber
/// there and a publisher on the protocol channel, which only the controller
/// has (it opens its operator subscriber first). Bounded by `patience`;
/// whether one does.
fn controller_listens(ipc: &Ipc, patience: Duration) -> Result<bool> {
    let start = Instant::now();
    loop {
        let listening =
            ipc.port_counts(OPERATOR)?.subscribers > 0 && ipc.port_counts(PROTOCOL)?.publishers > 0;
        if listening {
            return Ok(true);
        }
        if start.elapsed() >= patience {
            return Ok(false);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}
