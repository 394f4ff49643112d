//! The in-process composition on its own: the order of the messages of a
//! tick, who answers what, and how a run ends. (That the messages equal
//! the processes' is `tests/tests/it/determinism.rs`.)

use exo_config::RunConfig;
use exo_plant_sim::PlantModel;
use exo_sim::{Ended, Record, Sim};

fn short_run() -> RunConfig {
    let mut cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
    cfg.protocol.experiments = vec![1];
    cfg.protocol.periods = Some(vec![1]);
    cfg
}

fn run(cfg: &RunConfig) -> (Ended, Vec<Record>) {
    let model = PlantModel::from_file(&cfg.plant_model).unwrap();
    let mut sim = Sim::new(cfg, &model).unwrap();
    let mut out = Vec::new();
    let ended = sim
        .run(|r| -> Result<(), ()> {
            out.push(r);
            Ok(())
        })
        .unwrap();
    (ended, out)
}

#[test]
fn each_tick_is_frame_sample_protocol_command_motor_and_the_last_sample_goes_unanswered() {
    let cfg = short_run();
    let (ended, records) = run(&cfg);
    assert_eq!(ended, Ended::ControllerFinished);
    let period_ns = (1e9 / cfg.run.rate_hz) as u64;
    let mut tick = 0u64;
    let mut i = 0;
    let mut frfs = 0;
    let mut states = 0;
    let next_control = |i: &mut usize| {
        while let Some(Record::Frf(_) | Record::Estimate(_)) = records.get(*i) {
            *i += 1;
        }
    };
    loop {
        next_control(&mut i);
        let Some(Record::BusSensor(f)) = records.get(i) else {
            panic!("tick {tick}: {:?}", records.get(i));
        };
        assert_eq!((f.seq, f.stamp_ns, f.status), (tick, tick * period_ns, 0));
        let Some(Record::Sensor(s)) = records.get(i + 1) else {
            panic!("tick {tick}: {:?}", records.get(i + 1));
        };
        assert_eq!((s.seq, s.stamp_ns, s.status), (tick, f.stamp_ns, 0));
        i += 2;
        if i == records.len() {
            break; // the controller had finished: this sample is unanswered
        }
        if let Some(Record::Protocol(p)) = records.get(i) {
            assert_eq!(p.stamp_ns, s.stamp_ns);
            states += 1;
            i += 1;
        }
        let Some(Record::Command(c)) = records.get(i) else {
            panic!("tick {tick}: {:?}", records.get(i));
        };
        assert_eq!((c.seq, c.sensor_seq, c.stamp_ns), (tick, tick, s.stamp_ns));
        let Some(Record::BusMotor(m)) = records.get(i + 1) else {
            panic!("tick {tick}: {:?}", records.get(i + 1));
        };
        assert_eq!(
            (m.seq, m.frame_seq, m.stamp_ns, m.enable),
            (tick, tick, f.stamp_ns, 1)
        );
        assert_eq!(
            m.tau_motor_nm, c.tau_d,
            "the driver applies the controller's torque"
        );
        i += 2;
        frfs += records[i..]
            .iter()
            .take_while(|r| matches!(r, Record::Frf(_) | Record::Estimate(_)))
            .filter(|r| matches!(r, Record::Frf(_)))
            .count();
        tick += 1;
    }
    assert!(states >= 5, "{states} protocol states");
    assert_eq!(frfs, 1, "one FRF point for the one period analysed");
    let duration_ticks = (21.0 * cfg.run.rate_hz) as u64;
    assert!(tick > duration_ticks, "{tick} ticks");
}

#[test]
fn the_plant_bound_ends_a_run_and_no_identifier_means_no_frf() {
    let mut cfg = short_run();
    cfg.run.max_sim_time_s = Some(1.0);
    cfg.services.identifier = false;
    let (ended, records) = run(&cfg);
    assert_eq!(ended, Ended::Bound);
    let frames: Vec<u64> = records
        .iter()
        .filter_map(|r| match r {
            Record::BusSensor(f) => Some(f.seq),
            _ => None,
        })
        .collect();
    assert_eq!(frames.len(), 1000);
    assert_eq!(frames.last(), Some(&999));
    assert!(!records
        .iter()
        .any(|r| matches!(r, Record::Frf(_) | Record::Estimate(_))));
}

#[test]
fn a_sink_error_stops_the_run_at_once() {
    let cfg = short_run();
    let model = PlantModel::from_file(&cfg.plant_model).unwrap();
    let mut sim = Sim::new(&cfg, &model).unwrap();
    let mut n = 0;
    let r = sim.run(|_| {
        n += 1;
        if n == 10 {
            Err("full")
        } else {
            Ok(())
        }
    });
    assert_eq!(r, Err("full"));
    assert_eq!(n, 10);
    assert!(sim.plant().tick() <= 3);
}
