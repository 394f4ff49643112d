//! Heap allocations made by the per-tick iceoryx2 calls, counted by a global
//! allocator on the calling thread, in a steady-state loop after warm-up.
//!
//! The counts are asserted exactly, so a change of iceoryx2 in either
//! direction fails here and `ALLOCATIONS.md` / the `ipc` module docs must be
//! updated with it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Duration;

use exo_messages::ipc::{self, Inbox, Outbox, Svc, Wake};
use exo_messages::services::{self, EventQos, PubSubQos};
use exo_messages::SensorSample;
use iceoryx2::prelude::{CallbackProgression, WaitSetBuilder};

struct Counting;

thread_local! {
    // `const` initialiser and no destructor: reading it never allocates.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> usize {
    ALLOCATIONS.with(|c| c.get())
}

/// Runs `f` and returns its result and the allocations it made on this thread.
fn counted<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let before = allocations();
    let r = f();
    (r, allocations() - before)
}

const N: usize = 1000;
const WARM_UP: usize = 100;

fn sample(i: usize) -> SensorSample {
    SensorSample {
        seq: i as u64,
        theta_e: i as f64 * 1e-3,
        ..Default::default()
    }
}

#[test]
fn allocations_of_the_per_tick_ipc_calls() {
    let instance = format!("exotest-alloc-{}", std::process::id());
    let node = ipc::open_node("exotest_alloc", None).expect("node");
    let qos = PubSubQos {
        max_publishers: 2,
        ..services::STREAM_QOS
    };
    let pubsub =
        ipc::open_publish_subscribe_with::<SensorSample>(&node, &format!("{instance}/raw"), &qos)
            .expect("service");
    let publisher = pubsub.publisher_builder().create().expect("publisher");
    let subscriber = pubsub
        .subscriber_builder()
        .buffer_size(8)
        .create()
        .expect("subscriber");
    let event = ipc::open_event_with(
        &node,
        &format!("{instance}/raw/event"),
        &EventQos {
            max_notifiers: 2,
            max_listeners: 2,
            max_nodes: 4,
        },
    )
    .expect("event");
    let notifier = event.notifier_builder().create().expect("notifier");
    let listener = event.listener_builder().create().expect("listener");

    // Warm-up: connections, first loans, socket buffers.
    for i in 0..WARM_UP {
        publisher.send_copy(sample(i)).expect("send_copy");
        let s = publisher.loan_uninit().expect("loan");
        s.write_payload(sample(i)).send().expect("send");
        while subscriber.receive().expect("receive").is_some() {}
        notifier.notify().expect("notify");
        listener
            .timed_wait(|_| {}, Duration::from_millis(100))
            .expect("timed_wait");
    }

    let (mut loan_send, mut send_copy, mut receive, mut notify) = (0, 0, 0, 0);
    let (mut loan_only, mut write_send_only) = (0, 0);
    let (mut timed_wait_pending, mut try_wait) = (0, 0);
    let mut received = 0;
    for i in 0..N {
        let (r, a) = counted(|| {
            let s = publisher.loan_uninit()?;
            s.write_payload(sample(i)).send()
        });
        r.expect("loan_uninit + send");
        loan_send += a;

        let (r, a) = counted(|| publisher.send_copy(sample(i)));
        r.expect("send_copy");
        send_copy += a;

        // Where the allocation is: the loan, not the send.
        let (r, a) = counted(|| publisher.loan_uninit());
        let s = r.expect("loan_uninit");
        loan_only += a;
        let (r, a) = counted(|| s.write_payload(sample(i)).send());
        r.expect("send");
        write_send_only += a;

        for _ in 0..3 {
            let (r, a) = counted(|| subscriber.receive().map(|s| s.map(|s| *s.payload())));
            let s = r.expect("receive").expect("a sample is waiting");
            assert_eq!(s.seq, i as u64);
            received += 1;
            receive += a;
        }

        let (r, a) = counted(|| notifier.notify());
        r.expect("notify");
        notify += a;

        // The notification is pending, so this returns at once.
        let (r, a) = counted(|| listener.timed_wait(|_| {}, Duration::from_millis(100)));
        assert_eq!(r.expect("timed_wait"), 1, "one notification collected");
        timed_wait_pending += a;

        let (r, a) = counted(|| listener.try_wait(|_| {}));
        assert_eq!(r.expect("try_wait"), 0);
        try_wait += a;
    }
    assert_eq!(received, 3 * N);

    // A timed wait that times out (nothing pending): fewer rounds, each one
    // takes a scheduler tick or more.
    let mut timed_wait_timeout = 0;
    const TIMEOUTS: usize = 20;
    for _ in 0..TIMEOUTS {
        let (r, a) = counted(|| listener.timed_wait(|_| {}, Duration::from_micros(100)));
        assert_eq!(r.expect("timed_wait"), 0);
        timed_wait_timeout += a;
    }

    eprintln!("allocations over {N} calls after {WARM_UP} warm-up rounds:");
    eprintln!("  loan_uninit + write_payload + send: {loan_send}");
    eprintln!("  send_copy:                          {send_copy}");
    eprintln!("  loan_uninit alone:                  {loan_only}");
    eprintln!("  write_payload + send alone:         {write_send_only}");
    eprintln!("  receive:                            {receive} (over {received})");
    eprintln!("  notify:                             {notify}");
    eprintln!("  timed_wait (notification pending):  {timed_wait_pending}");
    eprintln!("  try_wait:                           {try_wait}");
    eprintln!("  timed_wait (timing out), {TIMEOUTS} calls:   {timed_wait_timeout}");

    // What we were told, checked: the publisher allocates once per sample
    // (iceoryx2 0.10's per-loan `Rc` state), everything else never.
    assert_eq!(
        loan_send, N,
        "loan_uninit + send: one allocation per sample"
    );
    assert_eq!(send_copy, N, "send_copy: one allocation per sample");
    assert_eq!(loan_only, N, "the allocation is made by the loan");
    assert_eq!(write_send_only, 0, "write_payload + send make none");
    assert_eq!(receive, 0, "receive must not allocate");
    assert_eq!(notify, 0, "notify must not allocate");
    assert_eq!(timed_wait_pending, 0, "timed_wait must not allocate");
    assert_eq!(
        timed_wait_timeout, 0,
        "a timed-out timed_wait must not allocate"
    );
    assert_eq!(try_wait, 0, "try_wait must not allocate");
}

#[test]
fn allocations_of_a_waitset_wake_up() {
    let instance = format!("exotest-alloc-ws-{}", std::process::id());
    let node = ipc::open_node("exotest_alloc_ws", None).expect("node");
    let event = ipc::open_event_with(
        &node,
        &format!("{instance}/event"),
        &EventQos {
            max_notifiers: 2,
            max_listeners: 2,
            max_nodes: 4,
        },
    )
    .expect("event");
    let notifier = event.notifier_builder().create().expect("notifier");
    let listener = event.listener_builder().create().expect("listener");
    let waitset = WaitSetBuilder::new().create::<Svc>().expect("waitset");
    let _guard = waitset.attach_notification(&listener).expect("attach");

    let round = |count: &mut usize| {
        notifier.notify().expect("notify");
        let mut woke = 0;
        let (r, a) = counted(|| {
            waitset.wait_and_process_once(|_| {
                woke += 1;
                CallbackProgression::Continue
            })
        });
        r.expect("wait_and_process_once");
        assert_eq!(woke, 1);
        listener.try_wait(|_| {}).expect("drain");
        *count += a;
    };
    let mut ignored = 0;
    for _ in 0..WARM_UP {
        round(&mut ignored);
    }
    let mut waitset_allocs = 0;
    for _ in 0..N {
        round(&mut waitset_allocs);
    }
    eprintln!("WaitSet::wait_and_process_once: {waitset_allocs} allocations over {N} wake-ups");
    assert_eq!(
        waitset_allocs,
        2 * N,
        "WaitSet::wait_and_process_once: two allocations per wake-up"
    );
}

#[test]
fn allocations_of_the_outbox_and_inbox() {
    let instance = format!("exotest-alloc-box-{}", std::process::id());
    let node = ipc::open_node("exotest_alloc_box", None).expect("node");
    let outbox = Outbox::<SensorSample>::open(&node, services::SENSOR, &instance).expect("outbox");
    let inbox = Inbox::<SensorSample>::open(&node, services::SENSOR, &instance, 4, Wake::Listen)
        .expect("inbox");
    for i in 0..WARM_UP {
        outbox.send(sample(i)).expect("send");
        assert!(inbox.wait(Duration::from_millis(100)).expect("wait"));
        while inbox.try_recv().expect("recv").is_some() {}
    }
    let (mut send, mut wait, mut recv) = (0, 0, 0);
    for i in 0..N {
        let (r, a) = counted(|| outbox.send(sample(i)));
        assert_eq!(r.expect("send"), 1);
        send += a;
        let (r, a) = counted(|| inbox.wait(Duration::from_millis(100)));
        assert!(r.expect("wait"));
        wait += a;
        let (r, a) = counted(|| inbox.try_recv());
        assert_eq!(r.expect("recv").map(|s| s.seq), Some(i as u64));
        recv += a;
    }
    let (r, a) = counted(|| inbox.wait(Duration::from_micros(200)));
    assert!(!r.expect("wait"));
    wait += a;
    eprintln!("Outbox::send {send}, Inbox::wait {wait}, Inbox::try_recv {recv} over {N}");
    assert_eq!(
        send, N,
        "Outbox::send: the publisher's one allocation per sample"
    );
    assert_eq!(wait, 0, "Inbox::wait must not allocate");
    assert_eq!(recv, 0, "Inbox::try_recv must not allocate");
}
