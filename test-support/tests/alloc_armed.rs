//! The counting allocator in `armed_threads` mode counts armed threads only, per thread and in
//! the process-wide totals.

use lop_test_support::alloc::{self, Counting};

#[global_allocator]
static A: Counting = Counting::armed_threads();

#[test]
fn counts_armed_threads_only() {
    let c = alloc::this_thread(|| drop(std::hint::black_box(vec![0u8; 64])));
    assert_eq!(c.allocations, 1);
    assert_eq!(c.bytes, 64);
    let c = alloc::this_thread(|| {});
    assert_eq!(c, alloc::Counts::default());

    // Another thread, armed and measured from here through the totals.
    alloc::reset();
    std::thread::spawn(|| {
        alloc::arm();
        drop(std::hint::black_box(vec![0u8; 16]));
        alloc::disarm();
        drop(std::hint::black_box(vec![0u8; 16])); // not counted
    })
    .join()
    .unwrap();
    assert_eq!(alloc::allocations(), 1);
    assert_eq!(alloc::bytes(), 16);

    // Unarmed work anywhere is not counted.
    alloc::reset();
    drop(std::hint::black_box(vec![0u8; 16]));
    assert_eq!(alloc::allocations(), 0);

    // `counted` restores the previous state.
    alloc::counted(|| alloc::counted(|| ()));
    drop(std::hint::black_box(vec![0u8; 16]));
    assert_eq!(alloc::allocations(), 0);
}
