//! Heap allocations made by the per-tick IPC calls, counted by a global
//! allocator after warm-up, on every thread of a process where this test
//! runs alone (the binary's other tests run in threads of their own).
//! iceoryx2 0.10's publisher allocates per sample (the team measured one
//! `Arc` per `send_copy`); receive, notify and the listener's timed wait do
//! not. This test pins what is true on this version, so a change in either
//! direction is noticed.

use std::time::Duration;

use exo_messages::SensorSample;
use exo_service_kit::channels::SENSOR;
use exo_service_kit::ipc::Ipc;

use exo_test_support::allocations_anywhere as count;

#[test]
fn allocations_per_tick_of_the_ipc_calls() {
    // Every thread is counted: no other test may run in the process.
    if !exo_test_support::in_a_process_of_its_own(concat!(
        module_path!(),
        "::allocations_per_tick_of_the_ipc_calls"
    )) {
        return;
    }
    let inst = format!("exotest-alloc-{}", std::process::id());
    let ipc = Ipc::open("alloc_test", &inst, None).unwrap();
    let outbox = ipc.outbox(SENSOR).unwrap();
    let inbox = ipc.inbox(SENSOR, 4).unwrap();
    // Warm-up.
    for i in 0..100 {
        outbox
            .send(SensorSample {
                seq: i,
                ..Default::default()
            })
            .unwrap();
        while inbox.try_recv().unwrap().is_some() {}
    }
    const N: usize = 1000;
    let (_, send_allocs) = count(|| {
        for i in 0..N {
            outbox
                .send(SensorSample {
                    seq: i as u64,
                    ..Default::default()
                })
                .unwrap();
            // Drain so the buffer never overflows.
            while inbox.try_recv().unwrap().is_some() {}
        }
    });
    let (_, recv_side) = count(|| {
        for _ in 0..N {
            let _ = inbox.try_recv().unwrap();
            inbox.wait(Duration::from_micros(1)).unwrap();
        }
    });
    eprintln!(
        "allocations per send+notify+receive: {:.2}",
        send_allocs as f64 / N as f64
    );
    eprintln!(
        "allocations per receive+timed wait: {:.2}",
        recv_side as f64 / N as f64
    );
    assert_eq!(recv_side, 0, "receiving and waiting must not allocate");
    assert!(
        send_allocs <= N,
        "more than one allocation per published sample: {send_allocs} for {N}"
    );
}
