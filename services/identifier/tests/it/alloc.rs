//! Per-sample calls do not allocate: a counting global allocator watches
//! `on_protocol`, `on_command` and `on_sample` through a whole protocol
//! period, and only the call that closes the analysis window may allocate.

use exo_identifier::{Event, Identifier, IdentifierSettings};
use exo_messages::{ActuatorCommand, ProtocolPhase, ProtocolState, SensorSample};

use exo_test_support::allocations_on_this_thread as counted;

#[test]
fn per_sample_calls_do_not_allocate_until_a_window_closes() {
    let mut id = Identifier::new(IdentifierSettings::default());
    // Room for the window's events, so pushing them is not what we count.
    let mut events: Vec<Event> = Vec::with_capacity(64);
    let omega = 5.0;
    let (mut tick, mut quiet, mut closing) = (0u64, 0usize, Vec::new());
    for (phase, dur_s) in [
        (ProtocolPhase::RampIn, 1.0),
        (ProtocolPhase::Settling, 1.0),
        (ProtocolPhase::Analysis, 5.0),
        (ProtocolPhase::RampOut, 1.0),
        (ProtocolPhase::Rest, 1.0),
    ] {
        for _ in 0..(dur_s * 1000.0) as usize {
            let stamp = tick * 1_000_000;
            let t = tick as f64 * 1e-3;
            let x = 0.02 * (omega * t).sin();
            let p = ProtocolState {
                experiment: 1,
                period: 1,
                phase: phase.as_u32(),
                omega,
                amplitude: 2.0,
                alpha: 1.0,
                stamp_ns: stamp,
                ..Default::default()
            };
            let c = ActuatorCommand {
                stamp_ns: stamp,
                tau_d: 30.0 * x,
                tau_gravity: 1.0,
                ..Default::default()
            };
            let s = SensorSample {
                seq: tick,
                stamp_ns: stamp,
                theta_e: 0.8 + x,
                tau_c: 40.0 * x,
                tau_s: 30.0 * x + 1.0,
                ..Default::default()
            };
            let events_before = events.len();
            let ((), n) = counted(|| {
                id.on_protocol(&p, &mut events);
                id.on_command(&c);
                id.on_sample(&s, &mut events);
            });
            if events.len() == events_before {
                quiet += n;
            } else {
                closing.push(n);
            }
            tick += 1;
        }
    }
    assert_eq!(quiet, 0, "allocations in ticks that produced nothing");
    // Exactly one tick closed the window (an FRF point and a warning that
    // one point is too few for a fit), and it did allocate.
    assert_eq!(closing.len(), 1);
    assert!(closing[0] > 0);
    assert_eq!(id.points()[&1].len(), 1);
}
