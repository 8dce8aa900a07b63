//! lop-ipc's wire-contract tests, one module per former test file, linked into one test binary
//! (`cargo test -p lop-ipc --test contract`): one build and link of the dependencies instead of
//! one per file.

mod c_header;
mod layout;
mod tool_board;
