//! The tool blackboard `PREFIX/tool/latest` holds an entry per tool, keys `0..MAX_TOOLS`
//! (`tool_latest_key`): one writer may hold every entry at once, and a reader sees each tool's
//! newest state under its own key, the others untouched.

use lop_ipc::services::{self, tool_latest_key};
use lop_ipc::*;

#[test]
fn the_tool_blackboard_has_an_entry_per_tool() {
    let prefix = format!(
        "lop-ipc-board-{}-{}",
        std::process::id(),
        clock::monotonic_ns()
    );
    let names = ServiceNames::new(&prefix).unwrap();
    let node = services::node("lop-ipc-board-test").unwrap();
    let board = services::tool_board_owner(&node, &names).unwrap();
    let writer = board.writer_builder().create().unwrap();
    let entries: Vec<_> = (0..MAX_TOOLS)
        .map(|t| writer.entry::<ToolState>(&tool_latest_key(t)).unwrap())
        .collect();
    assert!(writer
        .entry::<ToolState>(&tool_latest_key(MAX_TOOLS))
        .is_err());

    let reader_board = services::tool_board_reader(&node, &names).unwrap();
    let reader = reader_board.reader_builder().create().unwrap();
    let read = |t: usize| {
        *reader
            .entry::<ToolState>(&tool_latest_key(t))
            .unwrap()
            .get()
    };
    // Before any write, each entry names its tool.
    for t in 0..MAX_TOOLS {
        assert_eq!(read(t).tool, t as u32);
        assert_eq!(read(t).stamp_ns, 0);
    }
    let state = ToolState {
        contract_version: CONTRACT_VERSION,
        tool: 2,
        stamp_ns: 7,
        ..Default::default()
    };
    entries[2].update_with_copy(state);
    assert_eq!(read(2), state);
    assert_eq!(read(0).stamp_ns, 0);
    assert_eq!(read(3).stamp_ns, 0);
}
