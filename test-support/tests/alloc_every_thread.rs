//! The counting allocator in `every_thread` mode counts every thread's allocations in the
//! process-wide totals.

use lop_test_support::alloc::{self, Counting};

#[global_allocator]
static A: Counting = Counting::every_thread();

#[test]
fn counts_every_thread() {
    alloc::reset();
    std::thread::spawn(|| drop(std::hint::black_box(vec![0u8; 16])))
        .join()
        .unwrap();
    assert!(alloc::allocations() >= 1);
    let before = alloc::allocations();
    let c = alloc::this_thread(|| drop(std::hint::black_box(vec![0u8; 8])));
    assert_eq!(c.allocations, 1);
    assert!(alloc::allocations() > before);
}
