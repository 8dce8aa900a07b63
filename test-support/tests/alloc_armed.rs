//! The counting allocator in `armed_threads` mode counts armed threads only, per thread and in
//! the process-wide totals; it also finds a closure's largest single allocation.

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

    // The largest single allocation of a closure (one test: the totals below must not see
    // another test's armed thread).
    let (n, largest) = alloc::largest_on_this_thread(|| {
        drop(std::hint::black_box(vec![0u8; 1000]));
        drop(std::hint::black_box(vec![0u8; 300]));
        7
    });
    assert_eq!((n, largest), (7, 1000));
    // Nested: the inner call sees only its own; the outer one still sees the larger.
    let ((_, inner), outer) = alloc::largest_on_this_thread(|| {
        drop(std::hint::black_box(vec![0u8; 500]));
        alloc::largest_on_this_thread(|| drop(std::hint::black_box(vec![0u8; 100])))
    });
    assert_eq!((inner, outer), (100, 500));

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
