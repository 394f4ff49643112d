//! The driver's per-frame work (round-trip statistics included) makes no
//! heap allocation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use exo_config::{RunConfig, SafeState};
use exo_sensor_driver::{Driver, RawFrame, RoundTrip};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    // Only the test's own thread is counted: the test harness's threads
    // allocate at times of their own (a CI run once counted 4 of theirs).
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.try_with(|a| a.get()).unwrap_or(false) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn frame_and_command_handling_do_not_allocate() {
    let cfg = RunConfig::from_file(&exo_config::configs_dir().join("default.toml")).unwrap();
    let mut d = Driver::new(&cfg.rig, 1000.0, SafeState::GravityOnly, 40.0, 4.5);
    let mut round_trip = RoundTrip::new(0.01);
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    ARMED.with(|a| a.set(true));
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
    ARMED.with(|a| a.set(false));
    assert_eq!(ALLOCATIONS.load(Ordering::Relaxed) - before, 0);
    assert_eq!(round_trip.report().unwrap().latency.count, 99_990);
}
