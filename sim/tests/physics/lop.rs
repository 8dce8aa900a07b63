//! Levels of precision: the cage model's accuracy against its precise model, and the
//! controller's transitions under a scripted poke, without a pop.

use crate::common;

use common::{cylinder, cylinder_fem_params};
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::Fem;
use lop_sim::lop::{
    fitted_cells, CageDynamics, CageModel, CageShape, CageSprings, GcParameters, LopPolicy,
    PrecisionController, StartLevel, SwitchReason,
};
use lop_sim::mesh::TetMesh;
use lop_sim::model::{Model, ModelKind};
use lop_sim::world::World;

const GRAVITY: [f64; 3] = [0.0, -9.81, 0.0];

/// Table 6.1's FEM column on the shipped cylinder (radius 30 mm, height 120 mm, base fixed).
fn fem(mesh: &TetMesh) -> Fem {
    Fem::new(mesh, cylinder_fem_params()).unwrap()
}

fn gc_params(shape: CageShape, dynamics: CageDynamics) -> GcParameters {
    GcParameters {
        shape,
        padding: 0.003, // 5 % of the 60 mm diameter
        dynamics,
        dt: 0.02,
    }
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn max_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| distance(*p, *q))
        .fold(0.0, f64::max)
}

/// Steps a model under gravity until its fastest node is slower than 1e-6 m/s.
fn settle(model: &mut Model, max_steps: usize) {
    for _ in 0..max_steps {
        model.step(GRAVITY, &[], None).unwrap();
        if model.max_speed() < 1e-6 {
            return;
        }
    }
    panic!("did not settle in {max_steps} steps");
}

/// The cylinder under gravity: the static sag of the FEM, and the GC cage's with projected
/// dynamics. The projected cage's stiffness is matched to the same FEM's compliance, so its
/// equilibrium is close to the FEM's best approximation among the cage's shapes: the error
/// must shrink as the cage gets finer, the fitted cage (1 × 2 × 1 cells here) must meet the
/// issue's 2 % of the smallest dimension, and even the thesis' box must follow most of the sag
/// (3.5 mm, 5.9 % of the diameter), not merely stay put.
#[test]
fn projected_cage_follows_the_fem_sag() {
    let mesh = cylinder();
    let smallest = 0.06;
    let mut reference = fem(&mesh);
    reference.solve_static(GRAVITY, &[]).unwrap();
    let sag = max_distance(reference.positions(), &mesh.nodes);
    assert!(sag > 0.05 * smallest, "FEM sag {sag} m");

    let mut errors = Vec::new();
    for shape in [
        CageShape::Box,
        CageShape::Fitted,
        CageShape::SubdividedBox(2),
        CageShape::SubdividedBox(3),
    ] {
        let precise = Model::Fem(fem(&mesh));
        let gc =
            CageModel::from_precise(&mesh, gc_params(shape, CageDynamics::Projected), &precise)
                .unwrap();
        let mut model = Model::Gc(Box::new(gc));
        settle(&mut model, 5000);
        let err = max_distance(model.positions(), reference.positions());
        eprintln!(
            "{shape:?}: FEM sag {:.3} mm, GC error max {:.3} mm ({:.2} % of the diameter)",
            sag * 1e3,
            err * 1e3,
            100.0 * err / smallest,
        );
        // Fixed nodes never move.
        for &f in &mesh.fixed {
            assert_eq!(model.positions()[f as usize], mesh.nodes[f as usize]);
        }
        errors.push(err);
    }
    // Measured: box 0.60 mm, fitted 0.145, 2-subdivided 0.141, 3-subdivided 0.080 (the
    // Galerkin cage: 1.49, 0.44, 0.20, 0.10).
    assert!(
        errors[0] <= sag / 2.0,
        "box: {} m vs sag {sag} m",
        errors[0]
    );
    for (shape, err) in ["fitted", "subdivided 2", "subdivided 3"]
        .iter()
        .zip(&errors[1..])
    {
        assert!(*err <= 0.02 * smallest, "{shape}: max error {err} m");
    }
    assert!(
        errors.windows(2).all(|w| w[1] < w[0]),
        "finer cages must not be worse: {errors:?}"
    );
}

/// The thesis' mass-spring cage moves under gravity and settles; it is tuned by hand, so only
/// its sanity is checked here (its error is `lop-bench lop`'s business).
#[test]
fn mass_spring_cage_settles_under_gravity() {
    let mesh = cylinder();
    let precise = Model::Fem(fem(&mesh));
    let dynamics = CageDynamics::MassSpring(CageSprings::THESIS);
    let gc = CageModel::from_precise(&mesh, gc_params(CageShape::Box, dynamics), &precise).unwrap();
    let mut model = Model::Gc(Box::new(gc));
    settle(&mut model, 20_000);
    let moved = max_distance(model.positions(), &mesh.nodes);
    assert!(moved > 1e-5 && moved < 0.01, "moved {moved} m");
    let top = mesh
        .nodes
        .iter()
        .enumerate()
        .max_by(|a, b| a.1[1].total_cmp(&b.1[1]))
        .unwrap()
        .0;
    assert!(
        model.positions()[top][1] < mesh.nodes[top][1],
        "the top sank"
    );
}

/// A nodal load on a cage body reaches the cage (`Gᵀ f`): a lateral push on the top of the
/// cylinder bends it towards +x about as far as the FEM's static answer.
#[test]
fn loads_reach_the_cage() {
    let mesh = cylinder();
    let top: Vec<usize> = (0..mesh.nodes.len())
        .filter(|&k| mesh.nodes[k][1] > 0.119)
        .collect();
    assert!(top.len() >= 5);
    let mut loads = vec![[0.0; 3]; mesh.nodes.len()];
    for &k in &top {
        loads[k] = [0.01 / top.len() as f64, 0.0, 0.0];
    }
    let mut reference = fem(&mesh);
    reference.solve_static([0.0; 3], &loads).unwrap();
    let precise = Model::Fem(fem(&mesh));
    let gc = CageModel::from_precise(
        &mesh,
        gc_params(CageShape::Box, CageDynamics::Projected),
        &precise,
    )
    .unwrap();
    let mut model = Model::Gc(Box::new(gc));
    for _ in 0..3000 {
        model.step([0.0; 3], &loads, None).unwrap();
    }
    let dx = |x: &[[f64; 3]]| top.iter().map(|&k| x[k][0] - mesh.nodes[k][0]).sum::<f64>();
    let (fem_dx, gc_dx) = (dx(reference.positions()), dx(model.positions()));
    eprintln!(
        "top deflection: FEM {:.3} mm, GC {:.3} mm",
        fem_dx / top.len() as f64 * 1e3,
        gc_dx / top.len() as f64 * 1e3
    );
    assert!(fem_dx > 0.0);
    // A reduced model is stiffer than the full one (fewer ways to deform): between half and all
    // of the FEM's deflection.
    assert!(
        gc_dx > 0.5 * fem_dx && gc_dx <= 1.02 * fem_dx,
        "{gc_dx} vs {fem_dx}"
    );
}

/// A tool that approaches the cylinder's side, presses 4 mm in, holds, and leaves.
fn tool_at(t: f64) -> ToolSphere {
    // Surface at x = 0.03 (radius), y = 0.08; the tool starts 10 mm away.
    let depth = if t < 0.5 {
        -0.010 + 0.028 * t // reaches +4 mm at t = 0.5
    } else if t < 1.0 {
        0.004
    } else if t < 1.5 {
        0.004 - 0.028 * (t - 1.0)
    } else {
        -0.010
    };
    ToolSphere {
        center: [0.03 + 0.003 - depth, 0.08, 0.0],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    }
}

/// The controller under a scripted poke: GC at rest → FEM on contact → GC once settled, and
/// neither switch makes a visible jump (≤ 1 % of the smallest dimension between consecutive
/// frames, against the body's own motion in the frames around it).
#[test]
fn poke_switches_to_fem_and_back_without_a_pop() {
    let mesh = cylinder();
    let smallest = 0.06;
    let precise = Model::Fem(fem(&mesh));
    let gc = CageModel::from_precise(
        &mesh,
        gc_params(CageShape::Box, CageDynamics::Projected),
        &precise,
    )
    .unwrap();
    let policy = LopPolicy {
        start: StartLevel::Gc,
        ..LopPolicy::default()
    };
    let (active, lop) = PrecisionController::new(precise, gc, policy);
    assert_eq!(active.kind(), ModelKind::Gc);
    let mut world = World::new([0.0; 3]);
    let i = world.add_lop_body("cyl", mesh.clone(), active, lop);

    let mut kinds = Vec::new();
    let mut prev = world.bodies[i].model.positions().to_vec();
    let mut jumps_at_switch = Vec::new();
    let mut residuals = Vec::new();
    let mut max_frame_move: f64 = 0.0;
    let mut switches_seen = 0;
    let mut t = 0.0;
    while t < 4.0 {
        let tool = tool_at(t);
        world.step_body(i, Some(&tool)).unwrap();
        let b = &mut world.bodies[i];
        t = b.time;
        let x = b.model.positions();
        let moved = max_distance(x, &prev);
        max_frame_move = max_frame_move.max(moved);
        let lop = b.lop.as_mut().unwrap();
        if let Some(sw) = lop.take_switch() {
            switches_seen += 1;
            jumps_at_switch.push(moved);
            residuals.push(sw.residual);
            eprintln!(
                "t = {:.2}: {:?} -> {:?} ({:?}), jump {:.2e} m, residual {:.2e} m, frame move {:.2e} m",
                sw.time, sw.from, sw.to, sw.reason, sw.jump, sw.residual, moved
            );
            kinds.push((sw.from, sw.to, sw.reason));
        }
        prev.copy_from_slice(x);
    }
    assert_eq!(
        kinds,
        vec![
            (ModelKind::Gc, ModelKind::Fem, SwitchReason::Contact),
            (ModelKind::Fem, ModelKind::Gc, SwitchReason::Settled),
        ]
    );
    assert_eq!(switches_seen, 2);
    assert_eq!(world.bodies[i].lop.as_ref().unwrap().switches(), 2);
    assert_eq!(world.bodies[i].model.kind(), ModelKind::Gc);
    // The switches themselves: the frame in which a switch happens moves no node by more than
    // 1 % of the smallest dimension (the tool is pressing or just released there, so some
    // motion is the body's own).
    for j in &jumps_at_switch {
        assert!(*j <= 0.01 * smallest, "jump {j} m at a switch");
    }
    eprintln!("largest frame-to-frame move over the run: {max_frame_move:.2e} m");
    // After the blend the body is back at rest near its rest shape.
    let rest_err = max_distance(world.bodies[i].model.positions(), &mesh.nodes);
    assert!(rest_err < 0.002 * smallest, "rest error {rest_err} m");
}

/// Without a blend the hand-over to the cage snaps by the fit residual; with a blend the
/// displayed shape starts exactly where the precise model left it and the residual fades
/// linearly: the blended and the unblended cage differ by `r · (1 − t/blend)`, so no step adds
/// more than `r · dt / blend` on top of the cage's own motion.
#[test]
fn hand_over_starts_from_the_precise_shape_and_fades_the_residual() {
    let mesh = cylinder();
    // A deformed state the box cage cannot represent exactly: a dent under a held tool.
    let tool = tool_at(0.75);
    let mut world = World::new([0.0; 3]);
    let i = world.add_model("cyl", mesh.clone(), Model::Fem(fem(&mesh)));
    for _ in 0..50 {
        world.step_body(i, Some(&tool)).unwrap();
    }
    let x = world.bodies[i].model.positions().to_vec();
    let v = vec![[0.0; 3]; x.len()];
    let gc = CageModel::from_precise(
        &mesh,
        gc_params(CageShape::Box, CageDynamics::Projected),
        &Model::Fem(fem(&mesh)),
    )
    .unwrap();
    let (mut blended, mut snapped) = (gc.clone(), gc);
    let residual = blended.take_over(&x, &v, 0.2);
    assert_eq!(snapped.take_over(&x, &v, 0.0), residual);
    assert!(
        residual > 1e-5,
        "the dent is not representable: residual {residual}"
    );
    assert!(max_distance(blended.positions(), &x) < 1e-15);
    let snap = max_distance(snapped.positions(), &x);
    assert!(
        (snap - residual).abs() < 1e-9,
        "snap {snap} vs residual {residual}"
    );

    let offset = |a: &CageModel, b: &CageModel| -> Vec<[f64; 3]> {
        a.positions()
            .iter()
            .zip(b.positions())
            .map(|(p, q)| [p[0] - q[0], p[1] - q[1], p[2] - q[2]])
            .collect()
    };
    let mut prev = offset(&blended, &snapped);
    for step in 1..=15 {
        blended.step([0.0; 3], &[], None).unwrap();
        snapped.step([0.0; 3], &[], None).unwrap();
        let now = offset(&blended, &snapped);
        let change = max_distance(&now, &prev);
        // 0.2 s at dt 0.02: ten steps of a tenth each (1e-9: single-precision displacements).
        let expected = if step <= 10 { residual / 10.0 } else { 0.0 };
        assert!(
            (change - expected).abs() <= 1e-3 * residual + 1e-9,
            "step {step}: offset changed by {change}, expected {expected}"
        );
        prev = now;
    }
    assert_eq!(blended.blending(), 0.0);
    assert!(max_distance(&prev, &vec![[0.0; 3]; prev.len()]) < 1e-9);
}

/// After a hand-over under gravity the cage keeps the precise model's settled shape: no drift
/// to the cage's own equilibrium (the static correction).
#[test]
fn hand_over_under_gravity_does_not_drift() {
    let mesh = cylinder();
    let mut reference = fem(&mesh);
    reference.solve_static(GRAVITY, &[]).unwrap();
    let x = reference.positions().to_vec();
    let v = vec![[0.0; 3]; x.len()];
    let mut gc = CageModel::from_precise(
        &mesh,
        gc_params(CageShape::Box, CageDynamics::Projected),
        &Model::Fem(fem(&mesh)),
    )
    .unwrap();
    let residual = gc.take_over(&x, &v, 0.2);
    let mut fitted = gc.clone();
    for _ in 0..200 {
        gc.step(GRAVITY, &[], None).unwrap();
    }
    // After the blend, the cage shows its fit of the FEM sag, still: it moved from the FEM
    // shape by at most the residual, and the fit itself did not move.
    fitted.take_over(&x, &v, 0.0);
    let drift = max_distance(gc.positions(), fitted.positions());
    eprintln!("residual {residual:.2e} m, drift after 4 s {drift:.2e} m");
    assert!(drift < 1e-6, "drift {drift} m");
    assert!(gc.max_speed() < 1e-6);
}

/// The projected cage's stiffness is matched to the body's compliance: under a side load (no
/// gravity, so the FEM is linear), its static shape must be as close to the FEM's as the cage
/// can get at all — the FEM shape fitted to the cage (mass-weighted least squares, what
/// `take_over` does) — and far closer than the plain Galerkin cage, which locks (it is the best
/// fit in the energy norm, so it bends too little).
#[test]
fn projected_cage_has_the_fem_compliance_under_a_side_load() {
    let mesh = cylinder();
    let smallest = 0.06;
    let loads = side_loads(&mesh);
    let mut reference = fem(&mesh);
    reference.solve_static([0.0; 3], &loads).unwrap();
    let moved = max_distance(reference.positions(), &mesh.nodes);
    assert!(moved > 0.02 * smallest, "FEM moved {moved} m");

    for shape in [CageShape::Box, CageShape::Fitted] {
        let precise = Model::Fem(fem(&mesh));
        let mut errors = Vec::new();
        for dynamics in [CageDynamics::Projected, CageDynamics::Galerkin] {
            let gc = CageModel::from_precise(&mesh, gc_params(shape, dynamics), &precise).unwrap();
            let mut model = Model::Gc(Box::new(gc));
            let mut settled = false;
            for _ in 0..5000 {
                model.step([0.0; 3], &loads, None).unwrap();
                if model.max_speed() < 1e-7 {
                    settled = true;
                    break;
                }
            }
            assert!(settled, "{shape:?} {dynamics:?} did not settle");
            errors.push(max_distance(model.positions(), reference.positions()));
        }
        let mut fit =
            CageModel::from_precise(&mesh, gc_params(shape, CageDynamics::Projected), &precise)
                .unwrap();
        let zero = vec![[0.0; 3]; mesh.nodes.len()];
        let best = fit.take_over(reference.positions(), &zero, 0.0);
        eprintln!(
            "{shape:?}: FEM moved {:.3} mm; error projected {:.3} mm, Galerkin {:.3} mm, best \
             fit {:.3} mm",
            moved * 1e3,
            errors[0] * 1e3,
            errors[1] * 1e3,
            best * 1e3
        );
        // Measured: box 0.190 mm (best fit 0.194, Galerkin 1.002), fitted 0.087 (0.088,
        // 0.572), of 2.36 mm of motion.
        assert!(
            errors[0] <= 1.2 * best + 1e-3 * moved,
            "{shape:?}: projected {} m vs best fit {best} m",
            errors[0]
        );
        assert!(
            errors[0] < 0.5 * errors[1],
            "{shape:?}: projected {} m vs Galerkin {} m",
            errors[0],
            errors[1]
        );
    }
}

/// The fitted cage's cells: roughly cubic, but a long flat body (the shipped pancreas' extents,
/// 140 × 43 × 27.5 mm, which would get 5 × 2 × 1 cells and 36 vertices) keeps its segments
/// along its length and stays within `MAX_FITTED_VERTICES` (20: 4 × 1 × 1).
#[test]
fn fitted_cage_stays_small_on_a_long_flat_body() {
    let corners = |e: [f64; 3]| [[0.0; 3], e];
    assert_eq!(fitted_cells(&corners([0.14, 0.0434, 0.0275])), [4, 1, 1]);
    assert_eq!(fitted_cells(&corners([0.06, 0.12, 0.06])), [1, 2, 1]);
    assert_eq!(fitted_cells(&corners([0.1998, 0.1487, 0.0966])), [2, 2, 1]);
    assert_eq!(fitted_cells(&corners([0.4, 0.1, 0.1])), [4, 1, 1]);
}

/// Under gravity the Table 6.1 cylinder (E = 600 Pa, 120 mm tall) is far softer sideways than
/// at rest: the corotational FEM's weight, carried by a turning column, adds to the side load.
/// A projected cage built about the rest shape cannot follow that; one linearised about the
/// FEM's gravity equilibrium (`from_precise_under`) must, to within the best fit of its shape.
#[test]
fn prestressed_cage_follows_the_sagging_cylinder_sideways() {
    let mesh = cylinder();
    let loads = side_loads(&mesh);
    let mut sag = fem(&mesh);
    sag.solve_static(GRAVITY, &[]).unwrap();
    let mut reference = fem(&mesh);
    reference.solve_static(GRAVITY, &loads).unwrap();
    // The side load's own share of the motion.
    let sideways = max_distance(reference.positions(), sag.positions());

    let precise = Model::Fem(fem(&mesh));
    let params = gc_params(CageShape::Fitted, CageDynamics::Projected);
    let mut errors = Vec::new();
    for under in [true, false] {
        let gc = if under {
            CageModel::from_precise_under(&mesh, params, &precise, GRAVITY).unwrap()
        } else {
            CageModel::from_precise(&mesh, params, &precise).unwrap()
        };
        let mut model = Model::Gc(Box::new(gc));
        let mut settled = false;
        for _ in 0..5000 {
            model.step(GRAVITY, &loads, None).unwrap();
            if model.max_speed() < 1e-7 {
                settled = true;
                break;
            }
        }
        assert!(settled, "under gravity: {under}: did not settle");
        errors.push(max_distance(model.positions(), reference.positions()));
    }
    let mut fit = CageModel::from_precise(&mesh, params, &precise).unwrap();
    let zero = vec![[0.0; 3]; mesh.nodes.len()];
    let best = fit.take_over(reference.positions(), &zero, 0.0);
    eprintln!(
        "side load moves the sagging FEM {:.3} mm; cage error about the equilibrium {:.3} mm, \
         about rest {:.3} mm, best fit {:.3} mm",
        sideways * 1e3,
        errors[0] * 1e3,
        errors[1] * 1e3,
        best * 1e3
    );
    // Measured: the side load moves the sagging FEM 4.17 mm more; the cage about the
    // equilibrium is 0.166 mm off (best fit 0.172 mm), about rest 1.85 mm.
    assert!(
        errors[0] <= 1.5 * best + 0.02 * sideways,
        "about the equilibrium: {} m vs best fit {best} m",
        errors[0]
    );
    assert!(
        errors[0] < 0.25 * errors[1],
        "about the equilibrium {} m vs about rest {} m",
        errors[0],
        errors[1]
    );
}

/// 2 mN along +x shared by the free surface nodes of the cylinder's upper −x quarter.
fn side_loads(mesh: &TetMesh) -> Vec<[f64; 3]> {
    let fixed: Vec<bool> = (0..mesh.nodes.len())
        .map(|k| mesh.fixed.contains(&(k as u32)))
        .collect();
    let mut side: Vec<usize> = mesh
        .surface
        .iter()
        .flatten()
        .map(|&k| k as usize)
        .filter(|&k| !fixed[k] && mesh.nodes[k][0] < 0.0 && mesh.nodes[k][1] > 0.06)
        .collect();
    side.sort_unstable();
    side.dedup();
    let mut loads = vec![[0.0; 3]; mesh.nodes.len()];
    for &k in &side {
        loads[k] = [0.002 / side.len() as f64, 0.0, 0.0];
    }
    loads
}
