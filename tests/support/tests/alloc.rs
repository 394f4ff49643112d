//! The counter counts what is allocated, on the armed thread only or on
//! every thread, and nothing when nothing is allocated; threads measuring
//! at the same time each count their own; a test can be run alone.

use std::sync::Barrier;

use exo_test_support::{
    allocations_anywhere, allocations_on_this_thread, in_a_process_of_its_own, CountingAllocator,
    ThreadCount,
};

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn allocations_are_counted_where_asked_and_only_there() {
    let (v, n) = allocations_on_this_thread(|| vec![1u8; 100]);
    assert_eq!((v.len(), n), (100, 1));
    let ((), n) = allocations_on_this_thread(|| {
        let mut x = 0u64;
        for k in 0..1000u64 {
            x = x.wrapping_add(std::hint::black_box(k));
        }
        std::hint::black_box(x);
    });
    assert_eq!(n, 0);
    // Another thread's allocation: not counted on this thread, counted
    // anywhere (the spawn itself allocates too).
    let ((), here) = allocations_on_this_thread(|| {
        std::thread::spawn(|| drop(std::hint::black_box(vec![0u8; 10])))
            .join()
            .unwrap();
    });
    let ((), anywhere) = allocations_anywhere(|| {
        std::thread::spawn(|| drop(std::hint::black_box(vec![0u8; 10])))
            .join()
            .unwrap();
    });
    assert!(anywhere > here, "{anywhere} anywhere, {here} here");
}

/// Eight threads armed at once, each allocating its own number of boxes
/// between two barriers: each counts exactly its own (a shared counter
/// would give each the sum).
#[test]
fn threads_measuring_at_once_each_count_their_own() {
    let barrier = Barrier::new(8);
    let counts: Vec<(usize, usize)> = std::thread::scope(|s| {
        let handles: Vec<_> = (1..=8)
            .map(|k| {
                let barrier = &barrier;
                s.spawn(move || {
                    let count = ThreadCount::start();
                    barrier.wait();
                    for i in 0..100 * k {
                        drop(std::hint::black_box(Box::new(i)));
                    }
                    barrier.wait();
                    (100 * k, count.stop())
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (want, got) in counts {
        // Barrier::wait may allocate at most once on first use (its
        // thread's parker); never another thread's boxes.
        eprintln!("DBG {got} {want}");
        assert!(
            got >= want && got <= want + 2,
            "{got} counted, {want} allocated"
        );
    }
}

/// Run alone, a test sees only its own allocations even on every thread:
/// here exactly the one it makes (the parent process, where the other
/// tests of this binary run, returns at once).
#[test]
fn a_test_run_in_a_process_of_its_own_counts_every_thread_alone() {
    if !in_a_process_of_its_own(concat!(
        module_path!(),
        "::a_test_run_in_a_process_of_its_own_counts_every_thread_alone"
    )) {
        return;
    }
    let (v, n) = allocations_anywhere(|| std::hint::black_box(vec![7u8; 10]));
    assert_eq!((v.len(), n), (10, 1));
}
