//! The counter counts what is allocated, on the armed thread only or on
//! every thread, and nothing when nothing is allocated.

use exo_test_support::{allocations_anywhere, allocations_on_this_thread, CountingAllocator};

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
