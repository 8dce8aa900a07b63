//! Organ-to-organ collision (`lop_sim::collide`): detection and penalty response.
//!
//! Invariants guarded:
//! - two boxes overlapping by a known amount along x: exactly the vertices inside the other box
//!   are found, with depth = the overlap and normal ±x; separated or merely touching boxes give
//!   nothing (a skin turns touching into a shallow contact);
//! - the penalty loads balance: zero total force and zero total torque;
//! - on the faceted cylinder a vertex pushed in gets the radial normal;
//! - two mass-spring bodies pressed together by opposite loads settle in contact, carrying the
//!   whole load through the penalty springs, with depths set by load / (stiffness × vertices);
//! - detection is deterministic and independent of history (tree refits and rebuilds);
//! - detection and penalty loads allocate nothing, from the first call on.

use std::path::PathBuf;

use crate::common;

use common::shipped_mesh as shipped;
use lop_sim::collide::{CollisionBody, CollisionParams, Collisions, Penetration};
use lop_sim::mesh::TetMesh;
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, NodeMass};
use lop_test_support::alloc;
use lop_test_support::vec3::sub;

// Counts the allocations of the current thread while tracking is on (other tests' threads
// cannot disturb the count), as in `msd_alloc.rs`.
// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

/// A box `[lo, hi]` split into `n³` cells of six tetrahedra each (Kuhn subdivision along the
/// cell diagonal, conforming across cells). Node `(i, j, k)` has index `(k (n+1) + j)(n+1) + i`
/// and coordinates `lo + (hi − lo) · (i, j, k) / n`.
fn box_mesh(lo: [f64; 3], hi: [f64; 3], n: u32) -> TetMesh {
    let id = |i: u32, j: u32, k: u32| (k * (n + 1) + j) * (n + 1) + i;
    let mut nodes = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                let c = [i, j, k];
                nodes.push([0, 1, 2].map(|d| lo[d] + (hi[d] - lo[d]) * c[d] as f64 / n as f64));
            }
        }
    }
    let perms = [
        [1, 2, 4],
        [1, 4, 2],
        [2, 1, 4],
        [2, 4, 1],
        [4, 1, 2],
        [4, 2, 1],
    ];
    let mut tets = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let corner = |b: u32| id(i + (b & 1), j + (b >> 1 & 1), k + (b >> 2 & 1));
                for [a, b, _] in perms {
                    let mut t = [corner(0), corner(a), corner(a | b), corner(7)];
                    // Half of the six are left-handed: swap two corners to orient them.
                    let [p0, p1, p2, p3] = t.map(|v| nodes[v as usize]);
                    let (u, v, w) = (sub(p1, p0), sub(p2, p0), sub(p3, p0));
                    let det = u[0] * (v[1] * w[2] - v[2] * w[1])
                        - u[1] * (v[0] * w[2] - v[2] * w[0])
                        + u[2] * (v[0] * w[1] - v[1] * w[0]);
                    if det < 0.0 {
                        t.swap(2, 3);
                    }
                    tets.push(t);
                }
            }
        }
    }
    TetMesh::from_parts(nodes, tets, vec![], PathBuf::from("box")).expect("box mesh")
}

fn bodies<'a>(meshes: &'a [&'a TetMesh]) -> Vec<CollisionBody<'a>> {
    meshes
        .iter()
        .map(|m| CollisionBody {
            positions: &m.nodes,
            surface: &m.surface,
        })
        .collect()
}

fn collisions(meshes: &[&TetMesh]) -> Collisions {
    let surfaces: Vec<&[[u32; 3]]> = meshes.iter().map(|m| m.surface.as_slice()).collect();
    Collisions::new(&surfaces)
}

const OVERLAP: f64 = 0.04;

/// A = [0, 1]³ (4 cells a side); B = [1 − δ, 1.6 − δ] × [0.2, 0.8]² (3 cells a side), δ = 0.04
/// shifted along x by `shift`.
fn boxes(shift: f64) -> (TetMesh, TetMesh) {
    let a = box_mesh([0.0; 3], [1.0; 3], 4);
    let x0 = 1.0 - OVERLAP + shift;
    let b = box_mesh([x0, 0.2, 0.2], [x0 + 0.6, 0.8, 0.8], 3);
    (a, b)
}

/// Total force and total torque about `o` of per-body loads at per-body positions, with the
/// sums of magnitudes to scale them by.
fn resultants(loads: &[Vec<[f64; 3]>], pos: &[&[[f64; 3]]], o: [f64; 3]) -> [f64; 4] {
    let (mut f, mut t, mut fs, mut ts) = ([0.0; 3], [0.0; 3], 0.0, 0.0);
    for (l, x) in loads.iter().zip(pos) {
        for (fi, xi) in l.iter().zip(x.iter()) {
            let r = [xi[0] - o[0], xi[1] - o[1], xi[2] - o[2]];
            let ti = [
                r[1] * fi[2] - r[2] * fi[1],
                r[2] * fi[0] - r[0] * fi[2],
                r[0] * fi[1] - r[1] * fi[0],
            ];
            for k in 0..3 {
                f[k] += fi[k];
                t[k] += ti[k];
            }
            fs += fi.iter().map(|c| c * c).sum::<f64>().sqrt();
            ts += ti.iter().map(|c| c * c).sum::<f64>().sqrt();
        }
    }
    let len = |v: [f64; 3]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
    [len(f), fs, len(t), ts]
}

fn penalty(c: &Collisions, meshes: &[&TetMesh], k: f64) -> Vec<Vec<[f64; 3]>> {
    let mut loads: Vec<Vec<[f64; 3]>> = meshes
        .iter()
        .map(|m| vec![[0.0; 3]; m.nodes.len()])
        .collect();
    let mut slices: Vec<&mut [[f64; 3]]> = loads.iter_mut().map(|l| l.as_mut_slice()).collect();
    c.add_penalty_loads(&CollisionParams { stiffness: k }, &mut slices);
    loads
}

#[test]
fn overlapping_boxes_penetrate_by_the_overlap() {
    let (a, b) = boxes(0.0);
    let meshes = [&a, &b];
    let mut c = collisions(&meshes);
    let found = c.detect(&bodies(&meshes)).to_vec();

    // B's 16 vertices on its x = 0.96 face are inside A, 0.04 behind A's x = 1 face; A's 9
    // vertices on x = 1 with y, z in {0.25, 0.5, 0.75} are inside B, 0.04 behind its x = 0.96
    // face (0.05 from its y and z faces). Nothing else is inside anything.
    let expect_b: Vec<u32> = (0..16u32).map(|f| f * 4).collect(); // i = 0, every (j, k)
    let expect_a: Vec<u32> = [1, 2, 3]
        .iter()
        .flat_map(|&k| [1, 2, 3].map(|j| (k * 5 + j) * 5 + 4))
        .collect();
    let in_a: Vec<&Penetration> = found.iter().filter(|p| p.body == 0).collect();
    let in_b: Vec<&Penetration> = found.iter().filter(|p| p.body == 1).collect();
    assert_eq!(in_a.iter().map(|p| p.node).collect::<Vec<_>>(), expect_a);
    assert_eq!(in_b.iter().map(|p| p.node).collect::<Vec<_>>(), expect_b);
    assert_eq!(found.len(), 25);
    for p in &found {
        assert!(
            (p.depth - OVERLAP).abs() < 1e-12,
            "{p:?}: depth {} instead of {OVERLAP}",
            p.depth
        );
        // Out of A along +x (B's vertices), out of B along −x (A's vertices).
        let nx = if p.other == 0 { 1.0 } else { -1.0 };
        assert!(
            (p.normal[0] - nx).abs() < 1e-12
                && p.normal[1].abs() < 1e-12
                && p.normal[2].abs() < 1e-12,
            "{p:?}"
        );
        assert!((p.bary.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert_eq!(p.other, 1 - p.body);
    }
    let s = c.stats();
    assert_eq!((s.body_pairs, s.penetrations), (1, 25));
    assert!((s.max_depth - OVERLAP).abs() < 1e-12);
    // The box filter: only vertices inside the other's box were queried (A: its x = 1 face
    // inside B's yz range, 3×3 = 9, plus B: its 16 x-min face vertices).
    assert_eq!(s.vertex_queries, 25);
    // ~log T triangle tests per query, not T (A's surface has 192 triangles, B's 108).
    assert!(
        s.triangle_tests < 25 * 40,
        "{} triangle tests for 25 queries",
        s.triangle_tests
    );
}

#[test]
fn vertices_deeper_than_the_depth_limit_are_not_reported() {
    let (a, b) = boxes(0.0);
    let meshes = [&a, &b];
    let mut c = collisions(&meshes);
    c.set_depth_limit(0.039);
    assert!(c.detect(&bodies(&meshes)).is_empty());
    assert_eq!(c.stats().out_of_reach, 25);
    c.set_depth_limit(0.041);
    assert_eq!(c.detect(&bodies(&meshes)).len(), 25);
    assert_eq!(c.stats().out_of_reach, 0);
    // The skin extends the reach outwards only: 0.01 outside counts, 0.04 inside does not.
    c.set_depth_limit(0.039);
    c.set_skin(0.01);
    assert!(c.detect(&bodies(&meshes)).is_empty());
    let (a, b) = boxes(OVERLAP + 0.005);
    let meshes = [&a, &b];
    assert_eq!(c.detect(&bodies(&meshes)).len(), 25);
}

#[test]
fn separated_and_touching_boxes_do_not_collide() {
    // Separated by 0.06: the boxes do not even overlap.
    let (a, b) = boxes(OVERLAP + 0.06);
    let meshes = [&a, &b];
    let mut c = collisions(&meshes);
    assert!(c.detect(&bodies(&meshes)).is_empty());
    assert_eq!(c.stats().body_pairs, 0);
    assert_eq!(c.stats().vertex_queries, 0);

    // Touching: B's x-min face lies in A's x = 1 face. Its vertices are on A's surface, not in
    // it, and A's are on B's: queried, found at distance 0, not inside.
    let (a, b) = boxes(OVERLAP);
    let meshes = [&a, &b];
    let mut c = collisions(&meshes);
    assert!(c.detect(&bodies(&meshes)).is_empty());
    assert_eq!(c.stats().body_pairs, 1);
    assert_eq!(c.stats().vertex_queries, 25);
    assert_eq!(c.stats().max_depth, 0.0);

    // With a 0.01 skin the same 25 vertices touch, each 0.01 deep; 0.004 apart, 0.006 deep.
    c.set_skin(0.01);
    let found = c.detect(&bodies(&meshes));
    assert_eq!(found.len(), 25);
    assert!(found.iter().all(|p| (p.depth - 0.01).abs() < 1e-15));
    let (a, b) = boxes(OVERLAP + 0.004);
    let meshes = [&a, &b];
    let found = c.detect(&bodies(&meshes)).to_vec();
    assert_eq!(found.len(), 25);
    for p in &found {
        assert!((p.depth - 0.006).abs() < 1e-12, "{p:?}");
        let nx = if p.other == 0 { 1.0 } else { -1.0 };
        assert!((p.normal[0] - nx).abs() < 1e-12, "{p:?}");
    }
}

#[test]
fn penalty_loads_balance_force_and_torque() {
    let k = 300.0;
    // Aligned boxes: every vertex pushed along ±x by k δ.
    let (a, b) = boxes(0.0);
    let meshes = [&a, &b];
    let mut c = collisions(&meshes);
    c.detect(&bodies(&meshes));
    let loads = penalty(&c, &meshes, k);
    let on_b: f64 = loads[1].iter().map(|f| f[0]).sum();
    // B is pushed +x by its 16 vertices in A and by the reactions of A's 9 vertices in B.
    assert!((on_b - 25.0 * k * OVERLAP).abs() < 1e-9, "{on_b}");
    let [f, fs, t, ts] = resultants(&loads, &[&a.nodes, &b.nodes], [0.3, -0.2, 0.7]);
    assert!(
        f <= 1e-12 * fs && t <= 1e-12 * ts,
        "force {f} / {fs}, torque {t} / {ts}"
    );

    // A generic case: a box tilted about two axes plunged into the cylinder's side, closest
    // points on faces, edges and vertices of both meshes.
    let cyl = shipped("cylinder");
    let (s, co) = (0.4f64.sin(), 0.4f64.cos());
    let (s2, c2) = (0.7f64.sin(), 0.7f64.cos());
    let mut tilted = box_mesh([-0.01; 3], [0.01; 3], 3);
    for p in tilted.nodes.iter_mut() {
        let [x, y, z] = *p;
        let (x, y) = (co * x - s * y, s * x + co * y);
        let (y, z) = (c2 * y - s2 * z, s2 * y + c2 * z);
        *p = [x + 0.033, y + 0.05, z + 0.004];
    }
    let meshes = [&cyl, &tilted];
    let mut c = collisions(&meshes);
    let n = c.detect(&bodies(&meshes)).len();
    let by_body = [0, 1].map(|b| c.penetrations().iter().filter(|p| p.body == b).count());
    assert!(by_body[0] > 0 && by_body[1] > 0, "{by_body:?} of {n}");
    let loads = penalty(&c, &meshes, k);
    let [f, fs, t, ts] = resultants(&loads, &[&cyl.nodes, &tilted.nodes], [0.01, 0.02, -0.03]);
    assert!(fs > 0.0);
    assert!(
        f <= 1e-12 * fs && t <= 1e-12 * ts,
        "force {f} / {fs}, torque {t} / {ts}"
    );
}

/// A one-tetrahedron probe with its tip at `tip` and its base 10 mm further along `out`.
fn probe(tip: [f64; 3], out: [f64; 3]) -> TetMesh {
    // Two unit vectors across `out`.
    let helper = if out[1].abs() < 0.9 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let unit = |a: [f64; 3]| {
        let l = a.iter().map(|c| c * c).sum::<f64>().sqrt();
        a.map(|c| c / l)
    };
    let u = unit(cross(out, helper));
    let v = cross(out, u);
    let at =
        |o: f64, su: f64, sv: f64| [0, 1, 2].map(|k| tip[k] + o * out[k] + su * u[k] + sv * v[k]);
    let nodes = vec![
        tip,
        at(0.01, 0.004, 0.0),
        at(0.01, -0.002, 0.0035),
        at(0.01, -0.002, -0.0035),
    ];
    TetMesh::from_parts(nodes, vec![[0, 1, 2, 3]], vec![], PathBuf::from("probe")).expect("probe")
}

/// The one penetration of the probe (body 1) into the cylinder (body 0).
fn probe_hit(cyl: &TetMesh, probe: &TetMesh) -> Penetration {
    let meshes = [cyl, probe];
    let mut c = collisions(&meshes);
    let found: Vec<Penetration> = c
        .detect(&bodies(&meshes))
        .iter()
        .filter(|p| p.body == 1)
        .copied()
        .collect();
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].node, 0);
    found[0]
}

#[test]
fn a_vertex_pushed_into_the_cylinder_gets_the_radial_normal() {
    // The shipped cylinder: radius 30 mm, axis y, 0 ≤ y ≤ 120 mm, rings of 14 nodes every 12 mm,
    // alternate rings turned by half a facet (an antiprism), so each side triangle leans
    // atan(R (1 − cos(π/14)) / 12 mm) = 3.6° off the axis.
    let cyl = shipped("cylinder");
    let facet = std::f64::consts::TAU / 14.0;
    let sagitta = 0.03 * (1.0 - (facet / 2.0).cos());
    let lean = (sagitta / 0.012).atan();
    let deg = |a: f64| a.to_degrees();
    let angle = |n: [f64; 3], r: [f64; 3]| {
        let c: f64 = n.iter().zip(&r).map(|(a, b)| a * b).sum();
        c.clamp(-1.0, 1.0).acos()
    };

    // 1 mm under the centre of every side triangle: the closest point is the centre, the
    // normal radial but for the lean.
    let mut sides = 0;
    for t in &cyl.surface {
        let [a, b, c] = t.map(|v| cyl.nodes[v as usize]);
        let centre = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
        let radial = [centre[0], 0.0, centre[2]];
        let rl = radial.iter().map(|c| c * c).sum::<f64>().sqrt();
        let radial = radial.map(|c| c / rl);
        let (e1, e2) = (sub(b, a), sub(c, a));
        let n = [
            e1[1] * e2[2] - e1[2] * e2[1],
            e1[2] * e2[0] - e1[0] * e2[2],
            e1[0] * e2[1] - e1[1] * e2[0],
        ];
        let nl = n.iter().map(|c| c * c).sum::<f64>().sqrt();
        let n = n.map(|c| c / nl);
        if n[1].abs() > 0.5 {
            continue; // a cap triangle
        }
        let tip = [0, 1, 2].map(|k| centre[k] - 0.001 * n[k]);
        let p = probe_hit(&cyl, &probe(tip, n));
        assert!((p.depth - 0.001).abs() < 1e-12, "{p:?}");
        assert!(p.bary.iter().all(|w| (w - 1.0 / 3.0).abs() < 1e-9), "{p:?}");
        let off = angle(p.normal, radial);
        assert!((off - lean).abs() < 1e-6, "{p:?}: {}° off radial", deg(off));
        sides += 1;
    }
    assert_eq!(sides, 2 * 14 * 10);

    // 2 mm inside the circle at 679 spots around and along: the normal is the exact direction
    // to the closest point of the faceted surface, off the true radial by at most half a facet
    // combined with the lean (13.4°).
    let bound = ((facet / 2.0).cos() * lean.cos()).acos();
    let (mut worst, mut sum, mut n) = (0.0f64, 0.0, 0);
    for i in 0..97 {
        for j in 0..7 {
            let theta = i as f64 * 0.0731;
            let y = 0.03 + 0.0041 * j as f64 + 0.0003 * i as f64;
            let radial = [theta.cos(), 0.0, theta.sin()];
            let p = probe_hit(
                &cyl,
                &probe([0.028 * radial[0], y, 0.028 * radial[2]], radial),
            );
            // The facets are inside the circle by up to the sagitta (0.75 mm).
            assert!(
                p.depth > 0.002 - sagitta - 1e-9 && p.depth < 0.002 + 1e-9,
                "{p:?}"
            );
            let off = angle(p.normal, radial);
            worst = worst.max(off);
            sum += off;
            n += 1;
        }
    }
    let mean = sum / n as f64;
    assert!(
        worst <= bound + 1e-9,
        "worst {}° > {}°",
        deg(worst),
        deg(bound)
    );
    // Uniformly spread azimuths are off by facet / 4 = 6.4° on average (plus the lean).
    let mean_bound = ((facet / 4.0).cos() * lean.cos()).acos();
    assert!(
        mean <= mean_bound,
        "mean {}° > {}°",
        deg(mean),
        deg(mean_bound)
    );
    eprintln!(
        "cylinder normals: worst {:.2}°, mean {:.2}° off radial",
        deg(worst),
        deg(mean)
    );
}

#[test]
fn pressed_bodies_settle_in_contact_carrying_the_load() {
    // A 20 mm cube held at its far face (x = 0) and a 20 × 16 × 16 mm block 1 mm away, centred
    // on it, pushed together by 0.2 N each (spread over their free nodes) and kept apart only by
    // the penalty springs. (Two free bodies under opposite fixed-direction loads with
    // frictionless contact buckle: the pair turns and slides. Holding one is the stable setup.)
    let mut a = box_mesh([0.0; 3], [0.02; 3], 4);
    a.fixed = (0..25u32).map(|f| f * 5).collect(); // i = 0
    let b = box_mesh([0.021, 0.002, 0.002], [0.041, 0.018, 0.018], 3);
    let params = MsdParameters {
        stiffness: 500.0,
        mass: NodeMass::PerNode(0.01),
        damping: 0.5,
        dt: 0.002,
        integrator: Integrator::ImplicitEuler,
    };
    // The penalty loads are explicit (evaluated before each step): h² k / m = 4e-6 · 100 / 0.01
    // = 0.04 ≪ 1 keeps them stable.
    let k = 100.0;
    let load = 0.2;
    let mut models = [MassSpring::new(&a, params), MassSpring::new(&b, params)];
    let mut c = Collisions::new(&[&a.surface, &b.surface]);
    let free_a = a.nodes.len() - a.fixed.len();
    let mut ext = [
        vec![[load / free_a as f64, 0.0, 0.0]; a.nodes.len()],
        vec![[-load / b.nodes.len() as f64, 0.0, 0.0]; b.nodes.len()],
    ];
    for &f in &a.fixed {
        ext[0][f as usize] = [0.0; 3];
    }
    let mut loads = [vec![[0.0; 3]; a.nodes.len()], vec![[0.0; 3]; b.nodes.len()]];
    for _ in 0..500 {
        c.detect(&[
            CollisionBody {
                positions: models[0].positions(),
                surface: &a.surface,
            },
            CollisionBody {
                positions: models[1].positions(),
                surface: &b.surface,
            },
        ]);
        for (l, e) in loads.iter_mut().zip(&ext) {
            l.copy_from_slice(e);
        }
        let [la, lb] = &mut loads;
        c.add_penalty_loads(&CollisionParams { stiffness: k }, &mut [la, lb]);
        for (m, l) in models.iter_mut().zip(&loads) {
            m.step([0.0; 3], l, None).expect("stable");
        }
    }
    // Settled along the load. Across it, the frictionless contact leaves B free to slide, and
    // the Kuhn meshes' asymmetry tilts the bent contact faces by a hair: B creeps sideways at a
    // few µm/s against its damping (a tangential force ~1e-4 of the load).
    let vx = models
        .iter()
        .flat_map(|m| m.velocities().iter().map(|v| v[0].abs()))
        .fold(0.0, f64::max);
    assert!(vx < 1e-7, "not settled: {vx} m/s along x");
    let speed = models.iter().map(|m| m.max_speed()).fold(0.0, f64::max);
    assert!(speed < 1e-5, "sliding at {speed} m/s");
    let found = c.penetrations();
    let s = c.stats();
    // The facing faces: B's 16 x-min vertices are all over A's face; A's 9 vertices with y, z in
    // {5, 10, 15} mm are over B's. All of them are in contact, and nothing else.
    assert_eq!(found.len(), 25, "{found:?}");
    for p in found {
        let x = models[p.body].positions()[p.node as usize][0];
        assert!((x - 0.0205).abs() < 1e-3, "{p:?} at x = {x}");
        assert!(p.normal[0].abs() > 0.999, "{p:?}");
    }
    // In contact: the penalty springs carry the whole load across, k Σ depth · |n_x| = F at
    // rest (B's vertices in A pushed +x along A's normal; A's vertices in B pushing back +x on
    // B), and the normals are within a hair of ±x, so k Σ depth = F too.
    let along: f64 = found.iter().map(|p| k * p.depth * p.normal[0].abs()).sum();
    assert!(
        (along - load).abs() < 1e-6 * load,
        "penalty force {along} N for a {load} N load"
    );
    let total: f64 = found.iter().map(|p| k * p.depth).sum();
    assert!(
        (total - load).abs() < 1e-4 * load,
        "k Σ depth = {total} N for a {load} N load"
    );
    // Shared evenly the depth would be F / (k · 25) = 80 µm; the block bends, so the share is
    // uneven, but no vertex carries more than twice that.
    let even = load / (k * 25.0);
    assert!(
        s.max_depth <= 2.0 * even,
        "max depth {} m vs even share {even} m",
        s.max_depth
    );
    eprintln!(
        "pressed: max depth {:.1} µm, even share {:.1} µm, {} contacts, |v_x| {vx:.1e}, |v| {speed:.1e} m/s",
        s.max_depth * 1e6,
        even * 1e6,
        found.len()
    );
}

#[test]
fn detection_is_deterministic_and_history_free() {
    let cyl = shipped("cylinder");
    let mut probe = box_mesh([0.02, 0.04, -0.01], [0.05, 0.07, 0.02], 3);
    let meshes = [&cyl, &probe];
    let mut c = collisions(&meshes);
    let first = c.detect(&bodies(&meshes)).to_vec();
    let again = c.detect(&bodies(&meshes)).to_vec();
    assert!(!first.is_empty());
    assert_eq!(first, again);

    // Drag the probe far through and around the cylinder (refits, rebuilds), then back: the same
    // penetrations as a fresh detector's, bit for bit.
    // A crumpled step (nodes shuffled) loosens the refitted tree enough to rebuild it.
    let rest = probe.nodes.clone();
    let mut builds = 0;
    for step in 0..20 {
        let a = step as f64 * 0.3;
        for (p, r) in probe.nodes.iter_mut().zip(&rest) {
            *p = [
                r[0] - 0.004 * step as f64,
                r[1] + 0.01 * a.sin(),
                r[2] * (1.0 + 0.5 * a.cos()) + 0.3 * r[0] * r[1],
            ];
        }
        if step == 10 {
            let n = probe.nodes.len();
            for i in 0..n {
                probe.nodes.swap(i, (i * 37 + 11) % n);
            }
        }
        let meshes = [&cyl, &probe];
        c.detect(&bodies(&meshes));
        builds += c.stats().tree_builds;
    }
    assert!(builds >= 1, "never rebuilt");
    probe.nodes.clone_from(&rest);
    let meshes = [&cyl, &probe];
    let back = c.detect(&bodies(&meshes)).to_vec();
    let fresh = collisions(&meshes).detect(&bodies(&meshes)).to_vec();
    assert_eq!(back, first);
    assert_eq!(fresh, first);
}

#[test]
fn detection_and_loads_allocate_nothing() {
    // The organs in their scene places (≈1 mm apart) with a 2 mm skin, so there are contacts,
    // then the spleen shoved 5 mm into its neighbours and crumpled (a tree rebuild).
    let mut organs = ["liver", "spleen", "stomach", "pancreas"].map(shipped);
    let mut c = collisions(&organs.iter().collect::<Vec<_>>());
    c.set_skin(0.002);
    let mut loads: Vec<Vec<[f64; 3]>> = organs
        .iter()
        .map(|m| vec![[0.0; 3]; m.nodes.len()])
        .collect();
    let params = CollisionParams { stiffness: 10.0 };
    for round in 0..3 {
        let meshes: Vec<&TetMesh> = organs.iter().collect();
        let bodies = bodies(&meshes);
        let mut slices: Vec<&mut [[f64; 3]]> = loads.iter_mut().map(|l| l.as_mut_slice()).collect();
        let n = alloc::this_thread(|| {
            c.detect(&bodies);
            c.add_penalty_loads(&params, &mut slices);
        })
        .allocations;
        assert_eq!(n, 0, "round {round}: {n} allocations");
        assert!(c.stats().penetrations > 0, "round {round}: no contacts");
        if round == 0 {
            for p in organs[1].nodes.iter_mut() {
                p[0] -= 0.005;
            }
        } else {
            let n = organs[1].nodes.len();
            for i in 0..n {
                organs[1].nodes.swap(i, (i * 37 + 11) % n);
            }
        }
    }
    assert!(
        c.stats().tree_builds > 0,
        "the crumpled spleen's tree was not rebuilt"
    );
}
