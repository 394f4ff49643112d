//! The driver's per-frame work (round-trip statistics included) makes no
//! heap allocation.

use exo_config::{RunConfig, SafeState};
use exo_sensor_driver::{Driver, RawFrame, RoundTrip};

#[test]
fn frame_and_command_handling_do_not_allocate() {
    let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
    let mut d = Driver::new(&cfg.rig, 1000.0, SafeState::GravityOnly, 40.0, 4.5);
    let mut round_trip = RoundTrip::new(0.01);
    let count = exo_test_support::ThreadCount::start();
    for seq in 0..100_000u64 {
        let f = RawFrame {
            seq,
            encoder_counts: (seq % 5000) as i64,
            cuff_wrench: [0.0, 1.0, 0.0, 0.0, 0.0, 0.1],
            ..Default::default()
        };
        let s = d.on_frame(&f);
        let out = if seq % 1000 == 999 {
            d.on_deadline()
        } else {
            d.on_command(seq, s.tau_c)
        };
        assert!(out.is_some());
        // Round trips from 1 µs to ~1 s, over the histogram's buckets.
        let sent_ns = seq * 1_000_000;
        round_trip.record(sent_ns, sent_ns + 1_000 * (1 + seq * seq % 1_000_000));
        d.reset();
    }
    assert_eq!(count.stop(), 0);
    assert_eq!(round_trip.report().unwrap().latency.count, 99_990);
}
