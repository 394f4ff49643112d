//! The control tick makes no heap allocation (counted by a global allocator).

use exo_config::RunConfig;
use exo_controller::{Controller, TickInput};
use exo_messages::{OperatorCommand, OperatorCommandKind};

#[test]
fn controller_tick_operator_commands_and_adopting_f_do_not_allocate() {
    let mut cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
    cfg.controller.f = Some(0.44);
    let mut c = Controller::from_config(&cfg).unwrap();
    let count = exo_test_support::ThreadCount::start();
    let mut acc = 0.0;
    // Operator commands on the way: a stop (ramp-out, then held), a start
    // at experiment 7, a repeat, an unknown kind, a refused start, a reset,
    // adopting f.
    let operator = |seq: u64| {
        let (kind, value) = match seq {
            8_000 => (OperatorCommandKind::StopProtocol.as_u32(), 0.0),
            20_000 => (OperatorCommandKind::StartProtocol.as_u32(), 7.0),
            20_001 => (OperatorCommandKind::StartProtocol.as_u32(), 7.0),
            30_000 => (99, 0.0),
            30_001 => (OperatorCommandKind::StartProtocol.as_u32(), 5.0),
            40_000 => (OperatorCommandKind::ResetFault.as_u32(), 0.0),
            50_000 => (OperatorCommandKind::AdoptFractionalOrder.as_u32(), 0.95),
            _ => return None,
        };
        Some(OperatorCommand {
            seq: if seq == 20_001 { 20_000 } else { seq },
            kind,
            value,
            ..Default::default()
        })
    };
    for seq in 0..100_000u64 {
        if let Some(cmd) = operator(seq) {
            std::hint::black_box(c.on_operator(&cmd));
        }
        let t = seq as f64 * 1e-3;
        let tick = c.tick(&TickInput {
            seq,
            theta_e_rad: 0.7 + 0.05 * t.sin(),
            omega_e_rad_s: 0.05 * t.cos(),
            tau_c_nm: (3.0 * t).sin(),
            tau_s_nm: 0.0,
            status: 0,
            stamp_ns: 0,
        });
        acc += tick.tau_d_nm;
    }
    assert!(c.adopt_fractional_order(0.3));
    let allocations = count.stop();
    assert!(acc.is_finite());
    assert_eq!(
        allocations, 0,
        "{allocations} allocations in 100 000 ticks and 7 operator commands"
    );
}
