//! lop-sim's mesh and surface reader tests, one module per former test file, linked into one
//! test binary (`cargo test -p lop-sim --test mesh`): one build and link of the dependencies
//! instead of one per file.
//!
//! The counting allocator counts only armed threads; the bounded-memory tests read the largest
//! allocation of their own thread (`alloc::largest_on_this_thread`), so the other modules'
//! tests running in parallel cannot disturb them. Every scratch directory is named by its test
//! (`mesh_text::scratch`), and the names are distinct across the modules.

use lop_test_support::alloc::Counting;

#[global_allocator]
static A: Counting = Counting::armed_threads();

#[path = "../mesh_text/mod.rs"]
mod mesh_text;
#[path = "../vtk_build/mod.rs"]
mod vtk_build;

mod mesh_corpus;
mod mesh_detect;
mod mesh_errors;
mod mesh_errors_gmsh_vtk;
mod mesh_fuzz;
mod mesh_gmsh_v1;
mod mesh_gmsh_writes;
mod mesh_io;
mod mesh_meshio;
mod mesh_surface;
mod mesh_vtk;
mod mesh_vtk_bounded;
mod mesh_vtk_writers;
mod surface_check;
