//! lop-scene's tests, one module per former test file, linked into one test binary
//! (`cargo test -p lop-scene --test scene`): one build and link of the dependencies instead of
//! one per file.

mod closed_loop_tools;
mod cut_topology;
mod fix_selectors;
mod live_rounds;
mod render_surface;
mod tool_laws;
