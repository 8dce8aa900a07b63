//! Time stepping of the FEM body (implicit scheme of thesis eqs. 4.20–4.22).
//!
//! Invariants guarded:
//! - a damped body under gravity comes to rest at the static solution (`solve_static`), in
//!   both modes — the corotational one at a large, geometrically non-linear deflection;
//! - fixed nodes never move; stepping is deterministic bit for bit;
//! - an inverted element (a node flipped through its opposite face) gives no NaN in
//!   corotational mode and the element turns itself back out;
//! - a blow-up (non-finite load, runaway speed) resets the body and reports the cause;
//! - bad parameters and degenerate elements are errors that name the culprit;
//! - the `Model` enum dispatches to the FEM body.

use std::path::PathBuf;

use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{box_mesh, Fem, FemError, FemMode, FemParameters};
use lop_sim::mesh::TetMesh;
use lop_sim::model::{BlowUp, Model, ModelKind, ToolContact};

const G: [f64; 3] = [0.0, -9.81, 0.0];

/// A 10 × 2 × 2 cm cantilever clamped at x = 0.
fn beam() -> TetMesh {
    box_mesh([0.1, 0.02, 0.02], [10, 2, 2], |p| p[0] == 0.0)
}

fn params(young: f64, mode: FemMode) -> FemParameters {
    FemParameters {
        young,
        poisson: 0.3,
        density: 100.0,
        damping: 20.0,
        dt: 0.01,
        mode,
    }
}

fn max_diff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |k| (p[k] - q[k]).abs()))
        .fold(0.0, f64::max)
}

fn settles_at_static(young: f64, mode: FemMode) -> f64 {
    let mesh = beam();
    let mut stat = Fem::new(&mesh, params(young, mode)).unwrap();
    let eq = stat.solve_static(G, &[]).unwrap();
    println!(
        "{mode:?}: static solve {} iterations, residual {:.1e}",
        eq.iterations, eq.residual
    );
    let sag = max_diff(&eq.positions, &mesh.nodes);
    let mut fem = Fem::new(&mesh, params(young, mode)).unwrap();
    let mut steps = 0;
    while steps < 5000 {
        fem.step(G, &[], None).unwrap();
        steps += 1;
        if steps > 10 && fem.max_speed() < 1e-12 {
            break;
        }
        for &i in &mesh.fixed {
            assert_eq!(fem.positions()[i as usize], mesh.nodes[i as usize]);
        }
    }
    let err = max_diff(fem.positions(), &eq.positions);
    println!("{mode:?} E={young}: tip sag {sag:.3e} m, settled in {steps} steps, |x - x_static| {err:.2e} m");
    assert!(fem.max_speed() < 1e-12, "not settled: {}", fem.max_speed());
    assert!(
        err < 1e-9 * sag.max(1e-3),
        "{mode:?}: {err:e} from the static solution"
    );
    sag
}

#[test]
fn damped_linear_body_comes_to_rest_at_static_solution() {
    let sag = settles_at_static(5e5, FemMode::Linear);
    assert!(sag > 1e-4 && sag < 1e-2);
}

#[test]
fn damped_corotational_body_comes_to_rest_at_static_solution() {
    // Soft enough to sag by a third of its length: far from linear.
    let sag = settles_at_static(2e3, FemMode::Corotational);
    assert!(sag > 0.02, "{sag}");
}

#[test]
fn deterministic_bit_for_bit() {
    let mesh = beam();
    let tool = ToolSphere {
        center: [0.05, 0.0195, 0.01],
        radius: 0.003,
        stiffness: 300.0,
        law: ForceLaw::Linear,
    };
    let candidates: Vec<u32> = (0..mesh.surface.len() as u32).collect();
    let contact = ToolContact {
        tool,
        surface: &mesh.surface,
        candidates: &candidates,
        anchor: None,
        patch: None,
    };
    for mode in [FemMode::Linear, FemMode::Corotational] {
        let run = || {
            let mut fem = Fem::new(&mesh, params(5e4, mode)).unwrap();
            let mut reports = Vec::new();
            for s in 0..150 {
                let c = (s % 3 != 0).then_some(&contact);
                reports.push(fem.step(G, &[], c).unwrap());
            }
            (fem.positions().to_vec(), fem.velocities().to_vec(), reports)
        };
        let (a, b) = (run(), run());
        assert!(a.2.iter().any(|r| r.depth > 0.0), "the tool touches");
        assert_eq!(a, b, "{mode:?}");
    }
}

#[test]
fn inverted_element_recovers_without_nan() {
    let mesh = box_mesh([0.04, 0.04, 0.04], [2, 2, 2], |p| p[1] == 0.0);
    // The centre node, and a tetrahedron that uses it: reflect the node through the plane
    // of its opposite face.
    let centre = mesh
        .nodes
        .iter()
        .position(|p| *p == [0.02, 0.02, 0.02])
        .unwrap() as u32;
    let t = *mesh.tets.iter().find(|t| t.contains(&centre)).unwrap();
    let others: Vec<[f64; 3]> = t
        .iter()
        .filter(|&&k| k != centre)
        .map(|&k| mesh.nodes[k as usize])
        .collect();
    let (a, b, c) = (others[0], others[1], others[2]);
    let sub = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let (u, v) = (sub(b, a), sub(c, a));
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    let p = mesh.nodes[centre as usize];
    let dist = (sub(p, a)[0] * n[0] + sub(p, a)[1] * n[1] + sub(p, a)[2] * n[2]) / nn;
    let mut x = mesh.nodes.clone();
    x[centre as usize] = [0, 1, 2].map(|k| p[k] - 2.0 * dist * n[k]);

    let signed_volume = |x: &[[f64; 3]]| {
        let [p0, p1, p2, p3] = t.map(|k| x[k as usize]);
        let (e1, e2, e3) = (sub(p1, p0), sub(p2, p0), sub(p3, p0));
        e1[0] * (e2[1] * e3[2] - e2[2] * e3[1]) - e1[1] * (e2[0] * e3[2] - e2[2] * e3[0])
            + e1[2] * (e2[0] * e3[1] - e2[1] * e3[0])
    };
    assert!(signed_volume(&x) < 0.0, "the element starts inverted");

    let mut fem = Fem::new(&mesh, params(1e4, FemMode::Corotational)).unwrap();
    fem.set_state(&x, &vec![[0.0; 3]; x.len()]);
    for _ in 0..300 {
        fem.step([0.0; 3], &[], None).expect("no blow-up");
        assert!(fem.positions().iter().flatten().all(|c| c.is_finite()));
    }
    assert!(signed_volume(fem.positions()) > 0.0, "turned back out");
    assert!(
        max_diff(fem.positions(), &mesh.nodes) < 1e-6,
        "back at rest"
    );
}

#[test]
fn blow_up_resets_and_reports() {
    let mesh = beam();
    for mode in [FemMode::Linear, FemMode::Corotational] {
        let mut fem = Fem::new(&mesh, params(2e4, mode)).unwrap();
        for _ in 0..5 {
            fem.step(G, &[], None).unwrap();
        }
        let mut bad = vec![[0.0; 3]; mesh.nodes.len()];
        bad[20] = [f64::NAN, 0.0, 0.0];
        assert_eq!(fem.step(G, &bad, None), Err(BlowUp::NonFinite), "{mode:?}");
        assert_eq!(fem.positions(), mesh.nodes.as_slice());
        assert_eq!(fem.max_speed(), 0.0);
        // A kick far beyond anything a hand does: 1 kN on a 40 mg node.
        bad[20] = [1e3, 0.0, 0.0];
        assert_eq!(fem.step(G, &bad, None), Err(BlowUp::Runaway), "{mode:?}");
        assert_eq!(fem.positions(), mesh.nodes.as_slice());
        // And it carries on normally afterwards.
        fem.step(G, &[], None).unwrap();
    }
}

#[test]
fn bad_parameters_are_named() {
    let mesh = beam();
    let ok = params(1e4, FemMode::Corotational);
    let cases: [(FemParameters, &str); 6] = [
        (FemParameters { young: 0.0, ..ok }, "young"),
        (FemParameters { poisson: 0.5, ..ok }, "poisson"),
        (
            FemParameters {
                poisson: f64::NAN,
                ..ok
            },
            "poisson",
        ),
        (
            FemParameters {
                density: -1.0,
                ..ok
            },
            "density",
        ),
        (
            FemParameters {
                damping: f64::INFINITY,
                ..ok
            },
            "damping",
        ),
        (FemParameters { dt: 0.0, ..ok }, "dt"),
    ];
    for (p, name) in cases {
        match Fem::new(&mesh, p) {
            Err(e @ FemError::InvalidParameter { name: n, .. }) => {
                assert_eq!(n, name);
                assert!(e.to_string().contains(name), "{e}");
            }
            other => panic!("{name}: {:?}", other.map(|_| ())),
        }
    }
}

#[test]
fn degenerate_element_is_named() {
    // TetMesh's fields are public, so a caller can bypass its validation.
    let mesh = TetMesh {
        nodes: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 0.0],
        ],
        tets: vec![[0, 1, 2, 3], [0, 1, 4, 2]],
        surface: vec![],
        fixed: vec![0],
        source: PathBuf::from("flat"),
    };
    let err = Fem::new(&mesh, params(1e4, FemMode::Linear)).unwrap_err();
    assert!(
        matches!(
            err,
            FemError::DegenerateElement {
                element: 1,
                nodes: [0, 1, 4, 2],
                ..
            }
        ),
        "{err:?}"
    );
    assert!(err.to_string().contains("tetrahedron 1"), "{err}");
}

#[test]
fn model_dispatches_to_fem() {
    let mesh = beam();
    let fem = Fem::new(&mesh, params(2e4, FemMode::Corotational)).unwrap();
    let mut model = Model::Fem(fem.clone());
    assert_eq!(model.kind(), ModelKind::Fem);
    assert_eq!(model.substeps(), 1);
    assert_eq!(model.dt(), 0.01);
    model.step(G, &[], None).unwrap();
    let mut direct = fem;
    direct.step(G, &[], None).unwrap();
    assert_eq!(model.positions(), direct.positions());
    assert!(model.kinetic_energy() > 0.0);
    model.reset();
    assert_eq!(model.positions(), mesh.nodes.as_slice());
}

#[test]
fn state_transfer_continues_the_motion() {
    // Levels-of-precision switching hands (x, v) to a fresh body: it continues the same
    // trajectory (to the solver tolerance; the fresh body's rotations start cold).
    let mesh = beam();
    let mut a = Fem::new(&mesh, params(2e3, FemMode::Corotational)).unwrap();
    for _ in 0..30 {
        a.step(G, &[], None).unwrap();
    }
    let mut b = Fem::new(&mesh, params(2e3, FemMode::Corotational)).unwrap();
    b.set_state(a.positions(), a.velocities());
    for _ in 0..30 {
        a.step(G, &[], None).unwrap();
        b.step(G, &[], None).unwrap();
    }
    let d = max_diff(a.positions(), b.positions());
    assert!(d < 1e-9, "{d:e}");
}

#[test]
fn fully_fixed_body_is_inert() {
    let mesh = box_mesh([0.02; 3], [1, 1, 1], |_| true);
    for mode in [FemMode::Linear, FemMode::Corotational] {
        let mut fem = Fem::new(&mesh, params(1e4, mode)).unwrap();
        assert_eq!(fem.dofs(), 0);
        fem.step(G, &[], None).unwrap();
        assert_eq!(fem.positions(), mesh.nodes.as_slice());
        let report = fem.solve_static(G, &[]).unwrap();
        assert_eq!(report.positions, mesh.nodes);
    }
}

/// Linear mode solves for the new displacement directly (no elastic forces evaluated); the
/// corotational mode solves for the increment with the element forces. In the small-strain
/// limit both schemes are the same implicit scheme, so their trajectories must agree: under a
/// thousandth of gravity (0.4 µm of motion, strains of 1e-5), every step's positions match to a part
/// in 10⁵ of the motion (the corotational warp's own error at this strain is far below that).
#[test]
fn linear_total_form_matches_the_increment_form_at_small_strain() {
    let mesh = beam();
    let g = G.map(|c| c * 1e-3);
    let mut lin = Fem::new(&mesh, params(5e5, FemMode::Linear)).unwrap();
    let mut cor = Fem::new(&mesh, params(5e5, FemMode::Corotational)).unwrap();
    let mut worst: f64 = 0.0;
    let mut motion: f64 = 0.0;
    for _ in 0..60 {
        lin.step(g, &[], None).unwrap();
        cor.step(g, &[], None).unwrap();
        worst = worst.max(max_diff(lin.positions(), cor.positions()));
        motion = motion.max(max_diff(lin.positions(), &mesh.nodes));
    }
    println!("motion {motion:.3e} m, largest difference {worst:.3e} m");
    assert!(motion > 1e-8, "the load must move the beam");
    assert!(
        worst < 1e-5 * motion,
        "{worst:e} apart for {motion:e} of motion"
    );
}
