//! `exo-recorder`: subscribes to every channel of the run and writes one
//! contract MCAP (`--output FILE`, default
//! `<run.output_dir>/<instance>-<subject>-<unix seconds>.mcap`) with the run's
//! metadata and its configuration files attached. On SIGTERM/SIGINT it drains
//! what is still buffered, writes the drop counts and the summary, and exits.
//! Killed with SIGKILL, it leaves a file whose complete chunks are readable.

use std::io::BufWriter;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};
use exo_config::RunConfig;
use exo_messages::{
    ActuatorCommand, BusMotorCommand, BusSensorFrame, FrfPoint, ImpedanceEstimate, OperatorCommand,
    ProtocolState, SensorSample,
};
use exo_recorder::{default_output, drops_metadata, run_metadata, DropCounter};
use exo_recording::{Recordable, RecordingWriter};
use exo_service_kit::channels::Channel;
use exo_service_kit::ipc::{Inbox, Ipc, MAX_BUFFER};
use exo_service_kit::{init_logging, ServiceArgs, StopFlag};
use tracing::{error, info, warn};

type Writer = RecordingWriter<BufWriter<std::fs::File>>;

fn main() {
    init_logging("recorder");
    if let Err(e) = run(ServiceArgs::from_command_line()) {
        error!("{e:#}");
        std::process::exit(1);
    }
}

/// One subscribed topic.
struct Tap<T: Recordable + iceoryx2::prelude::ZeroCopySend + Send> {
    inbox: Inbox<T>,
    drops: DropCounter,
    seq: fn(&T) -> u64,
}

impl<T: Recordable + iceoryx2::prelude::ZeroCopySend + Send> Tap<T> {
    fn open(ipc: &Ipc, ch: Channel, seq: fn(&T) -> u64) -> Result<Self> {
        Ok(Tap {
            inbox: ipc.inbox::<T>(ch, MAX_BUFFER)?,
            drops: DropCounter::default(),
            seq,
        })
    }

    /// Writes everything waiting; returns how many.
    fn drain(&mut self, w: &mut Writer) -> Result<usize> {
        let mut n = 0;
        while let Some(m) = self.inbox.try_recv()? {
            self.drops.see((self.seq)(&m));
            w.write(&m)?;
            n += 1;
        }
        Ok(n)
    }
}

struct Taps {
    sensor: Tap<SensorSample>,
    command: Tap<ActuatorCommand>,
    protocol: Tap<ProtocolState>,
    frf: Tap<FrfPoint>,
    estimate: Tap<ImpedanceEstimate>,
    operator: Tap<OperatorCommand>,
    bus_sensor: Tap<BusSensorFrame>,
    bus_motor: Tap<BusMotorCommand>,
}

impl Taps {
    fn drain(&mut self, w: &mut Writer) -> Result<usize> {
        Ok(self.sensor.drain(w)?
            + self.command.drain(w)?
            + self.protocol.drain(w)?
            + self.frf.drain(w)?
            + self.estimate.drain(w)?
            + self.operator.drain(w)?
            + self.bus_sensor.drain(w)?
            + self.bus_motor.drain(w)?)
    }

    /// `(topic, counter)` of the topics whose `seq` rises by one per sample.
    fn counted(&self) -> Vec<(&'static str, &DropCounter)> {
        vec![
            (SensorSample::TOPIC, &self.sensor.drops),
            (ActuatorCommand::TOPIC, &self.command.drops),
            (FrfPoint::TOPIC, &self.frf.drops),
            (ImpedanceEstimate::TOPIC, &self.estimate.drops),
            (BusSensorFrame::TOPIC, &self.bus_sensor.drops),
            (BusMotorCommand::TOPIC, &self.bus_motor.drops),
        ]
    }
}

fn attach_file(w: &mut Writer, name: &str, path: &std::path::Path) {
    match std::fs::read(path) {
        Ok(bytes) => {
            if let Err(e) = w.attach(name, "application/toml", &bytes, 0) {
                warn!("recorder: attaching {}: {e}", path.display());
            }
        }
        Err(e) => warn!("recorder: cannot attach {}: {e}", path.display()),
    }
}

fn run(args: ServiceArgs) -> Result<()> {
    let cfg = RunConfig::from_file(&args.config)?;
    let stop = StopFlag::install()?;
    let unix_s = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let path = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(&cfg, unix_s));
    let ipc = Ipc::open(
        "recorder",
        &cfg.run.instance,
        args.iceoryx2_config.as_deref(),
    )?;
    let mut taps = Taps {
        sensor: Tap::open(&ipc, Channel::Sensor, |m: &SensorSample| m.seq)?,
        command: Tap::open(&ipc, Channel::Command, |m: &ActuatorCommand| m.seq)?,
        protocol: Tap::open(&ipc, Channel::Protocol, |_: &ProtocolState| 0)?,
        frf: Tap::open(&ipc, Channel::IdentifierFrf, |m: &FrfPoint| m.seq)?,
        estimate: Tap::open(
            &ipc,
            Channel::IdentifierEstimate,
            |m: &ImpedanceEstimate| m.seq,
        )?,
        operator: Tap::open(&ipc, Channel::Operator, |m: &OperatorCommand| m.seq)?,
        bus_sensor: Tap::open(&ipc, Channel::BusSensor, |m: &BusSensorFrame| m.seq)?,
        bus_motor: Tap::open(&ipc, Channel::BusMotor, |m: &BusMotorCommand| m.seq)?,
    };
    let mut w = RecordingWriter::create(&path)?;
    w.register_contract()?;
    w.write_metadata("exo", &run_metadata(&cfg, &args.config))?;
    attach_file(&mut w, "config.toml", &args.config);
    attach_file(&mut w, "plant.toml", &cfg.plant_model);
    attach_file(&mut w, "subject.toml", &cfg.subject_file);
    w.flush()?;
    info!("recorder: writing {}", path.display());
    let started = Instant::now();
    let mut last_flush = Instant::now();
    let mut total = 0usize;
    while !stop.requested() {
        let n = taps.drain(&mut w)?;
        total += n;
        if n == 0 {
            taps.sensor.inbox.wait(Duration::from_millis(20))?;
        }
        // Close a chunk at least once a second even when little is written,
        // so a SIGKILL loses at most the last second.
        if last_flush.elapsed() > Duration::from_secs(1) {
            w.flush()?;
            last_flush = Instant::now();
        }
    }
    total += taps.drain(&mut w)?;
    let drops = drops_metadata(taps.counted());
    let dropped: u64 = taps.counted().iter().map(|(_, c)| c.dropped).sum();
    w.write_metadata("exo.drops", &drops)?;
    w.finish()
        .with_context(|| format!("finishing {}", path.display()))?;
    if dropped > 0 {
        warn!("recorder: {dropped} samples missed (sequence gaps): {drops:?}");
    }
    info!(
        "recorder: {total} messages in {:.1} s, {dropped} missed, file {}",
        started.elapsed().as_secs_f64(),
        path.display()
    );
    Ok(())
}
