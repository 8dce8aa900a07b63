//! Smoke test of `lop-bench timings --quick`: both timings run and print every row. No bound on
//! any number (they are timings of a debug build on a shared machine).

use crate::common;

use std::time::Duration;

#[test]
fn timings_quick_prints_every_row() {
    let stdout = common::run_bench(
        &["timings".as_ref(), "--quick".as_ref()],
        Duration::from_secs(300),
    );
    let collision_rows = stdout.lines().filter(|l| l.contains("depth limit")).count();
    assert_eq!(collision_rows, 3, "{stdout}");
    let cage_rows = stdout
        .lines()
        .filter(|l| l.contains("555 points") && l.contains("deform_into"))
        .count();
    assert_eq!(cage_rows, 3, "{stdout}");
    // The organs touch with ~1 mm gaps: the 2 mm skin finds contacts.
    for l in stdout.lines().filter(|l| l.contains("skin 2 mm")) {
        assert!(
            !l.contains("penetrations: 0,"),
            "no contact with the skin: {l}"
        );
    }
}
