//! # exo-sim
//!
//! The run's nodes composed in one process: the plant simulator, the sensor
//! driver, the controller and the identifier, each the same plain type its
//! process steps ([`PlantNode`], [`DriverNode`], [`ControllerNode`],
//! [`Identifier`]), handed their inputs in the order the processes receive
//! them in lockstep, with no shared memory and no waiting. Every message a
//! process would publish goes to a sink ([`Record`], the recorder's own
//! record type), e.g. a contract MCAP ([`FileSink`]), so `exo sim` writes
//! what `exo run` records, bit for bit (`tests/tests/it/determinism.rs`).
//!
//! One tick, as the processes do it in lockstep:
//!
//! 1. the plant's frame (`exo/bus/sensor`); the driver calibrates it into
//!    a sample (`exo/sensor`), which the identifier takes;
//! 2. once the controller has finished the protocol, the run ends here
//!    (the process has exited: this last sample goes unanswered);
//! 3. the controller answers: the protocol state when it changed
//!    (`exo/protocol`), then the command (`exo/command`);
//! 4. the driver writes the motor torque (`exo/bus/motor`): the
//!    controller's, or its latched safe state's;
//! 5. the plant advances one period with it, then takes the protocol
//!    state (the plant process reads it before its next frame), as does
//!    the driver;
//! 6. the identifier takes the protocol state and the command; its FRF
//!    points and estimates (`exo/identifier/*`) go to the sink and the
//!    estimates to the controller before the next sample.
//!
//! The run ends when the controller has finished or the plant reaches
//! `run.max_sim_time_s`, whichever is first ([`Ended`]).

use std::path::Path;

use exo_config::RunConfig;
use exo_controller::node::ControllerNode;
use exo_controller::ControllerError;
use exo_identifier::{Event, Identifier};
use exo_messages::BusMotorCommand;
use exo_plant_sim::{PlantModel, PlantNode, StepMismatch};
use exo_recorder::{start_recording, Drops, FileWriter};
use exo_recording::RecordingError;
use exo_sensor_driver::node::raw_frame;
use exo_sensor_driver::DriverNode;

pub use exo_recorder::Record;

/// Why a simulation could not be set up or written.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The plant model does not fit the run.
    #[error(transparent)]
    Plant(#[from] StepMismatch),
    /// The controller cannot be built from the run.
    #[error(transparent)]
    Controller(#[from] ControllerError),
    /// The recording could not be written.
    #[error(transparent)]
    Recording(#[from] RecordingError),
    /// The identifier cannot be built from the run (its multisine's lines).
    #[error("identifier: protocol.multisine: {0}")]
    Identifier(String),
}

/// How a simulation ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ended {
    /// The controller finished the protocol.
    ControllerFinished,
    /// The plant reached the run's bound (`run.max_sim_time_s`) first.
    Bound,
}

/// The run's nodes, stepped together.
pub struct Sim {
    plant: PlantNode,
    driver: DriverNode,
    controller: ControllerNode,
    identifier: Option<Identifier>,
    events: Vec<Event>,
    motor_seq: u64,
}

impl Sim {
    /// The nodes of run `cfg` (loaded with `RunConfig::from_file`) with
    /// plant model `model`; the identifier only when `services.identifier`
    /// is on.
    pub fn new(cfg: &RunConfig, model: &PlantModel) -> Result<Self, SimError> {
        Ok(Sim {
            plant: PlantNode::new(cfg, model, None)?,
            driver: DriverNode::new(cfg),
            controller: ControllerNode::new(cfg)?,
            identifier: match cfg.services.identifier {
                true => Some(Identifier::of_run(cfg).map_err(SimError::Identifier)?),
                false => None,
            },
            events: Vec::with_capacity(64),
            motor_seq: 0,
        })
    }

    /// The plant node (its ground truth, its tick).
    pub fn plant(&self) -> &PlantNode {
        &self.plant
    }

    /// Runs to the end, handing every published message to `sink` in
    /// publication order; stops at the sink's first error.
    pub fn run<E>(&mut self, mut sink: impl FnMut(Record) -> Result<(), E>) -> Result<Ended, E> {
        loop {
            if self.plant.finished() {
                return Ok(Ended::Bound);
            }
            let frame = self.plant.frame(self.plant.lockstep_stamp_ns());
            sink(Record::BusSensor(frame))?;
            let sample = self.driver.on_frame(&raw_frame(&frame), 0);
            sink(Record::Sensor(sample))?;
            if let Some(id) = self.identifier.as_mut() {
                id.on_sample(&sample, &mut self.events);
            }
            if self.controller.finished() {
                self.drain_events(&mut sink)?;
                return Ok(Ended::ControllerFinished);
            }
            let answer = self.controller.on_sample(&sample);
            if let Some(p) = answer.protocol {
                sink(Record::Protocol(p))?;
            }
            sink(Record::Command(answer.command))?;
            let out = match self.driver.latched_output() {
                Some(o) => o,
                None => self
                    .driver
                    .answer(&answer.command)
                    .unwrap_or_else(|| self.driver.on_deadline()),
            };
            self.driver.report_latch(&out);
            let motor = BusMotorCommand {
                seq: self.motor_seq,
                stamp_ns: frame.stamp_ns,
                frame_seq: frame.seq,
                tau_motor_nm: out.tau_motor_nm,
                enable: u32::from(self.driver.motor_enable()),
                ..Default::default()
            };
            self.motor_seq += 1;
            sink(Record::BusMotor(motor))?;
            self.plant.on_motor(&motor);
            self.plant.advance();
            if let Some(p) = answer.protocol {
                self.plant.on_protocol(&p);
                self.driver.on_protocol(&p);
            }
            if let Some(id) = self.identifier.as_mut() {
                if let Some(p) = answer.protocol {
                    id.on_protocol(&p, &mut self.events);
                }
                id.on_command(&answer.command);
            }
            self.drain_events(&mut sink)?;
        }
    }

    /// Hands the identifier's new outputs to the sink (its estimates also
    /// to the controller) and logs them as the identifier process does.
    fn drain_events<E>(&mut self, sink: &mut impl FnMut(Record) -> Result<(), E>) -> Result<(), E> {
        for e in self.events.drain(..) {
            e.log();
            match e {
                Event::Frf(p) => sink(Record::Frf(p))?,
                Event::Estimate(est) => {
                    self.controller.on_estimate(&est);
                    sink(Record::Estimate(est))?;
                }
                Event::Warning(_) | Event::RefitNote(_) => {}
            }
        }
        Ok(())
    }
}

/// A sink writing the run's contract MCAP, as the recorder process does:
/// the same metadata and attachments, every message, and the `exo.drops`
/// record (gaps in what was written: none, in one process).
pub struct FileSink {
    writer: FileWriter,
    drops: Drops,
}

impl FileSink {
    /// Starts the recording of run `cfg` (read from `config_file`) at `path`.
    pub fn create(path: &Path, cfg: &RunConfig, config_file: &Path) -> Result<Self, SimError> {
        Ok(FileSink {
            writer: start_recording(path, cfg, config_file)?,
            drops: Drops::default(),
        })
    }

    /// Writes one record.
    pub fn write(&mut self, r: Record) -> Result<(), RecordingError> {
        self.drops.see(&r);
        r.write_to(&mut self.writer)
    }

    /// Writes the drop counts and the summary, and closes the file;
    /// returns the messages written.
    pub fn finish(mut self) -> Result<u64, RecordingError> {
        self.writer
            .write_metadata("exo.drops", &self.drops.metadata(0))?;
        let written = self.writer.messages_written();
        self.writer.finish()?;
        Ok(written)
    }
}
