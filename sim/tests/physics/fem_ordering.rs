//! The fill-reducing ordering of the FEM system (`sim/src/fem/ordering.rs`).
//!
//! Invariants guarded:
//! - the ordering only renumbers the unknowns: a body solved with geometric nested dissection
//!   moves exactly as one solved with AMD (linear mode, direct solves: to round-off; static
//!   equilibria: to 1e-10);
//! - `Fem::new` keeps the ordering with the smaller factor: AMD on a small mesh, nested
//!   dissection on a larger box, and never a factor larger than either.

use lop_sim::fem::{box_mesh, Fem, FemMode, FemParameters, NodeOrdering};
use lop_sim::mesh::TetMesh;

const G: [f64; 3] = [0.0, -9.81, 0.0];

fn params(mode: FemMode) -> FemParameters {
    FemParameters {
        young: 3000.0,
        poisson: 0.45,
        density: 1000.0,
        damping: 1.0,
        dt: 0.01,
        mode,
    }
}

/// A 0.1 m-wide bar clamped at x = 0, with `cells` cubes (several levels of dissection above
/// the leaves).
fn bar(cells: [usize; 3]) -> TetMesh {
    let a = 0.1 / cells[1] as f64;
    let size = [a * cells[0] as f64, 0.1, 0.1];
    box_mesh(size, cells, |p| p[0] <= 1e-9 * size[0])
}

fn max_diff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).abs()))
        .fold(0.0, f64::max)
}

fn max_displacement(x: &[[f64; 3]], rest: &[[f64; 3]]) -> f64 {
    max_diff(x, rest)
}

#[test]
fn nested_dissection_moves_the_body_as_amd_does() {
    let mesh = bar([14, 6, 6]);
    let mut amd = Fem::with_ordering(&mesh, params(FemMode::Linear), NodeOrdering::Amd).unwrap();
    let mut nd = Fem::with_ordering(
        &mesh,
        params(FemMode::Linear),
        NodeOrdering::NestedDissection,
    )
    .unwrap();
    assert_eq!(amd.ordering(), NodeOrdering::Amd);
    assert_eq!(nd.ordering(), NodeOrdering::NestedDissection);
    for _ in 0..20 {
        amd.step(G, &[], None).unwrap();
        nd.step(G, &[], None).unwrap();
    }
    let moved = max_displacement(amd.positions(), &mesh.nodes);
    assert!(moved > 1e-3, "the bar sags: {moved}");
    let diff = max_diff(amd.positions(), nd.positions());
    assert!(diff <= 1e-10 * moved, "{diff:e} of {moved:e}");
    let vdiff = max_diff(amd.velocities(), nd.velocities());
    let speed = amd.max_speed();
    assert!(vdiff <= 1e-10 * speed, "{vdiff:e} of {speed:e}");
}

#[test]
fn nested_dissection_static_solution_matches_amd() {
    let mesh = bar([14, 6, 6]);
    let stiff = FemParameters {
        young: 3e5,
        ..params(FemMode::Linear)
    };
    let a = Fem::with_ordering(&mesh, stiff, NodeOrdering::Amd)
        .unwrap()
        .solve_static(G, &[])
        .unwrap();
    let n = Fem::with_ordering(&mesh, stiff, NodeOrdering::NestedDissection)
        .unwrap()
        .solve_static(G, &[])
        .unwrap();
    let moved = max_displacement(&a.positions, &mesh.nodes);
    let diff = max_diff(&a.positions, &n.positions);
    assert!(diff <= 1e-10 * moved, "{diff:e} of {moved:e}");
}

#[test]
fn corotational_steps_agree_within_the_cg_tolerance() {
    // Different orderings round the single-precision preconditioner differently, so CG stops
    // at different iterates within its tolerance (relative residual 1e-5).
    let mesh = bar([14, 6, 6]);
    let p = params(FemMode::Corotational);
    let mut amd = Fem::with_ordering(&mesh, p, NodeOrdering::Amd).unwrap();
    let mut nd = Fem::with_ordering(&mesh, p, NodeOrdering::NestedDissection).unwrap();
    for _ in 0..20 {
        amd.step(G, &[], None).unwrap();
        nd.step(G, &[], None).unwrap();
    }
    let moved = max_displacement(amd.positions(), &mesh.nodes);
    let diff = max_diff(amd.positions(), nd.positions());
    assert!(diff <= 1e-5 * moved, "{diff:e} of {moved:e}");
}

#[test]
fn the_smaller_factor_is_chosen() {
    for (cells, expected) in [
        ([10, 4, 4], NodeOrdering::Amd),
        ([21, 9, 9], NodeOrdering::NestedDissection),
    ] {
        let mesh = bar(cells);
        let p = params(FemMode::Corotational);
        let chosen = Fem::new(&mesh, p).unwrap();
        let nnz = |o| Fem::with_ordering(&mesh, p, o).unwrap().solver_info().1;
        let (amd, nd) = (nnz(NodeOrdering::Amd), nnz(NodeOrdering::NestedDissection));
        assert_eq!(chosen.ordering(), expected, "{cells:?}: AMD {amd}, ND {nd}");
        assert_eq!(chosen.solver_info().1, amd.min(nd), "{cells:?}");
    }
}
