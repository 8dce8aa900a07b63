//! 3D Green coordinates (`lop_sim::gc`): reproduction, partition of unity, similarity
//! invariance, accuracy next to the cage, agreement with quadrature of the defining integrals,
//! the binding's fast path, cage validation and the box cages.
//!
//! Tolerances are relative to the cage size `L` (bounding-box diagonal, ~1–3 here) unless
//! said otherwise. The closed form is a few dozen floating-point operations per triangle on
//! numbers of size `L`, summed over 8–56 vertices and 12–108 triangles, so rounding alone puts
//! ~1e-16…1e-15·L on a result; each test says what it observes and why its bound is safe.

use std::f64::consts::PI;

use lop_sim::gc::{box_cage, subdivided_box_cage, Cage, CageError, GreenCoordinates};
use lop_test_support::rng::Rng;
use lop_test_support::vec3::{add, cross, dist, dot, norm, scale, sub};

/// Cage validation and the binding's refusals.
#[path = "../gc_validation/mod.rs"]
mod gc_validation;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// The error of building Green coordinates on an invalid cage.
fn err(cage: &Cage) -> CageError {
    GreenCoordinates::new(&cage.vertices, &cage.triangles).expect_err("invalid cage")
}

/// Bounding-box diagonal of a vertex set: the "cage size" L of the tolerances.
fn size(vertices: &[[f64; 3]]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in vertices {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    dist(hi, lo)
}

fn centroid(vertices: &[[f64; 3]]) -> [f64; 3] {
    let s = vertices.iter().fold([0.0; 3], |s, &v| add(s, v));
    scale(s, 1.0 / vertices.len() as f64)
}

fn gc_of(cage: &Cage) -> GreenCoordinates {
    GreenCoordinates::new(&cage.vertices, &cage.triangles).expect("valid cage")
}

/// An axis-aligned, non-cubic box cage: [-0.35, 0.75] × [-0.25, 1.05] × [-0.15, 0.45].
fn irregular_box() -> Cage {
    box_cage(&[[-0.3, -0.2, -0.1], [0.7, 1.0, 0.4]], 0.05)
}

/// A convex octahedron with six different vertex distances, shifted off the origin, so no face
/// is axis-aligned and no two faces are congruent.
fn octahedron() -> Cage {
    let c = [0.2, -0.1, 0.3];
    let r = [[0.9, 1.1], [1.3, 0.8], [1.0, 1.2]]; // [axis][+, −]
    let mut vertices = Vec::new();
    for (a, ra) in r.iter().enumerate() {
        for (s, &len) in ra.iter().enumerate() {
            let mut v = c;
            v[a] += if s == 0 { len } else { -len };
            vertices.push(v);
        }
    }
    let mut triangles = Vec::new();
    for sx in 0..2 {
        for sy in 0..2 {
            for sz in 0..2 {
                let (x, y, z) = (sx, 2 + sy, 4 + sz);
                // An odd number of negative half-axes reverses the orientation.
                if (sx + sy + sz) % 2 == 0 {
                    triangles.push([x, y, z]);
                } else {
                    triangles.push([x, z, y]);
                }
            }
        }
    }
    Cage {
        vertices,
        triangles,
    }
}

/// A subdivided box (n = 3) with every vertex moved by up to 0.03 per coordinate: irregular and
/// in general non-convex. Points in [0, 1] × [0, 0.8] × [0, 0.6] are ≥ 0.1 − 0.03·√3 > 0.04
/// inside it.
fn perturbed_box() -> Cage {
    let mut cage = subdivided_box_cage(&[[0.0, 0.0, 0.0], [1.0, 0.8, 0.6]], 0.1, 3);
    let mut rng = Rng::new(7);
    for v in &mut cage.vertices {
        for c in v.iter_mut() {
            *c += rng.range(-0.03, 0.03);
        }
    }
    cage
}

/// Random points strictly inside a convex cage: convex combinations of all its vertices with
/// weights in [0.05, 1].
fn convex_interior(cage: &Cage, count: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| {
            let w: Vec<f64> = cage.vertices.iter().map(|_| rng.range(0.05, 1.0)).collect();
            let total: f64 = w.iter().sum();
            cage.vertices
                .iter()
                .zip(&w)
                .fold([0.0; 3], |s, (&v, &wi)| add(s, scale(v, wi / total)))
        })
        .collect()
}

/// Random points in [0, 1] × [0, 0.8] × [0, 0.6] (inside `perturbed_box`).
fn perturbed_interior(count: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = Rng::new(seed);
    (0..count)
        .map(|_| [rng.unit(), 0.8 * rng.unit(), 0.6 * rng.unit()])
        .collect()
}

/// `Σ φ_i v_i + Σ ψ_j n(t_j)` from the rest cage.
fn reproduce(gc: &GreenCoordinates, point: [f64; 3]) -> [f64; 3] {
    let (phi, psi) = gc.coordinates(point);
    let mut out = [0.0; 3];
    for (p, v) in phi.iter().zip(gc.vertices()) {
        out = add(out, scale(*v, *p));
    }
    for (j, p) in psi.iter().enumerate() {
        out = add(out, scale(gc.normal(j), *p));
    }
    out
}

/// The test cages with interior points: (name, cage, points, convex?).
fn cases() -> Vec<(&'static str, Cage, Vec<[f64; 3]>, bool)> {
    let bx = irregular_box();
    let sub2 = subdivided_box_cage(&[[-0.3, -0.2, -0.1], [0.7, 1.0, 0.4]], 0.05, 2);
    let oct = octahedron();
    let pts_box = convex_interior(&bx, 40, 1);
    let pts_sub2 = convex_interior(&sub2, 40, 2);
    let pts_oct = convex_interior(&oct, 40, 3);
    vec![
        ("box", bx, pts_box, true),
        ("subdivided box n=2", sub2, pts_sub2, true),
        ("octahedron", oct, pts_oct, true),
        (
            "perturbed box n=3",
            perturbed_box(),
            perturbed_interior(40, 4),
            false,
        ),
    ]
}

/// Rotation by `angle` about `axis` (Rodrigues).
fn rotation(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let k = scale(axis, 1.0 / norm(axis));
    let (s, c) = angle.sin_cos();
    let mut r = [[0.0; 3]; 3];
    for (i, row) in r.iter_mut().enumerate() {
        for (j, e) in row.iter_mut().enumerate() {
            let id = if i == j { 1.0 } else { 0.0 };
            let kx = match (i, j) {
                (0, 1) => -k[2],
                (0, 2) => k[1],
                (1, 0) => k[2],
                (1, 2) => -k[0],
                (2, 0) => -k[1],
                (2, 1) => k[0],
                _ => 0.0,
            };
            *e = c * id + s * kx + (1.0 - c) * k[i] * k[j];
        }
    }
    r
}

fn apply(m: [[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

// ---------------------------------------------------------------------------------------------
// Reproduction, partition of unity, positivity
// ---------------------------------------------------------------------------------------------

/// The undeformed cage reproduces interior points, through `coordinates` and through `deform`.
/// Observed errors are ~1e-16·L; 1e-12·L is the bound asked for.
#[test]
fn identity_reproduces_interior_points() {
    for (name, cage, points, _) in cases() {
        let gc = gc_of(&cage);
        let l = size(&cage.vertices);
        for &p in &points {
            let e1 = dist(reproduce(&gc, p), p) / l;
            let e2 = dist(gc.deform(p, &cage.vertices), p) / l;
            assert!(e1 <= 1e-12 && e2 <= 1e-12, "{name}: {p:?}: {e1:e} {e2:e}");
        }
    }
}

/// Σφ = 1 inside (to rounding, ≤ 1e-13 for sums of ≤ 54 terms of size ≤ 1); ψ > 0 always;
/// φ > 0 in a convex cage.
#[test]
fn partition_of_unity_and_positivity() {
    for (name, cage, points, convex) in cases() {
        let gc = gc_of(&cage);
        for &p in &points {
            let (phi, psi) = gc.coordinates(p);
            let sum: f64 = phi.iter().sum();
            assert!((sum - 1.0).abs() <= 1e-13, "{name}: {p:?}: Σφ = {sum}");
            assert!(psi.iter().all(|&v| v > 0.0), "{name}: {p:?}: ψ = {psi:?}");
            if convex {
                assert!(phi.iter().all(|&v| v > 0.0), "{name}: {p:?}: φ = {phi:?}");
            }
        }
    }
}

/// The centre of a box projects onto the diagonal (an edge line) of every face, where the
/// paper's pseudocode divides by zero. Here it is an ordinary point: finite, Σφ = 1, identity.
#[test]
fn centre_of_a_box_is_an_ordinary_point() {
    for cage in [
        irregular_box(),
        box_cage(&[[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]], 0.5),
    ] {
        let gc = gc_of(&cage);
        let c = centroid(&cage.vertices);
        let (phi, psi) = gc.coordinates(c);
        assert!(phi.iter().chain(&psi).all(|v| v.is_finite()));
        let sum: f64 = phi.iter().sum();
        assert!((sum - 1.0).abs() <= 1e-14, "Σφ = {sum}");
        let e = dist(reproduce(&gc, c), c) / size(&cage.vertices);
        assert!(e <= 1e-14, "{e:e}");
    }
}

// ---------------------------------------------------------------------------------------------
// Similarity transforms and the scale factors s_j
// ---------------------------------------------------------------------------------------------

/// Rotation + uniform scale + translation of the cage moves interior points by the same map.
/// Observed ~1e-16 relative; bound 1e-10 as asked.
#[test]
fn similarity_transforms_are_reproduced() {
    let r = rotation([1.0, 2.0, -0.5], 0.7);
    let k = 1.7;
    let t = [0.3, -1.2, 2.5];
    let map = |v: [f64; 3]| add(scale(apply(r, v), k), t);
    for (name, cage, points, _) in cases() {
        let gc = gc_of(&cage);
        let moved: Vec<[f64; 3]> = cage.vertices.iter().map(|&v| map(v)).collect();
        let l = size(&moved);
        for &p in &points {
            let e = dist(gc.deform(p, &moved), map(p)) / l;
            assert!(e <= 1e-10, "{name}: {p:?}: {e:e}");
        }
    }
}

/// s_j = 1 for a rigid motion and k for a uniform scale by k; s_j n(t'_j) points along the
/// moved normal. Each is a handful of operations on O(1) numbers (observed ≤ 1.2e-15): 1e-14.
#[test]
fn scale_factors_of_rigid_motion_and_uniform_scale() {
    let r = rotation([0.3, -1.0, 0.8], 2.1);
    let t = [5.0, -2.0, 0.5];
    for (name, cage, _, _) in cases() {
        let gc = gc_of(&cage);
        let mut sn = vec![[0.0; 3]; gc.triangle_count()];
        for k in [1.0, 0.4, 2.5] {
            let moved: Vec<[f64; 3]> = cage
                .vertices
                .iter()
                .map(|&v| add(scale(apply(r, v), k), t))
                .collect();
            gc.scaled_normals(&moved, &mut sn);
            for (j, s) in sn.iter().enumerate() {
                let expected = scale(apply(r, gc.normal(j)), k);
                assert!(
                    dist(*s, expected) <= 1e-14 * k.max(1.0),
                    "{name}: k = {k}, triangle {j}: {s:?} vs {expected:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Accuracy next to the cage
// ---------------------------------------------------------------------------------------------

/// Points 1e-3 … 1e-9·L inside the cage from a face interior, every edge (including the
/// diagonals inside the flat faces of the boxes) and every vertex — and, on the boxes, from the
/// centre of a face, which lies on a triangle's edge line — give finite coordinates with Σφ = 1
/// and identity to 1e-13 (asked: ~1e-9; observed worst 7e-16 and 3e-16·L). That needs the
/// cancellation-free `R − L` (the plain subtraction gives NaN within ~1e-8 of an edge) and the
/// double-double solid angle next to an edge (plain `f64` gives errors ~1e-8 at 1e-9·L).
#[test]
fn accurate_close_to_faces_edges_and_vertices() {
    let cages = [
        ("box", irregular_box()),
        (
            "subdivided box n=2",
            subdivided_box_cage(&[[-0.3, -0.2, -0.1], [0.7, 1.0, 0.4]], 0.05, 2),
        ),
        ("octahedron", octahedron()),
    ];
    let mut worst = (0.0f64, 0.0f64);
    for (name, cage) in cages {
        let gc = gc_of(&cage);
        let l = size(&cage.vertices);
        let c = centroid(&cage.vertices);
        // (what, anchor on the cage, unit direction into the cage)
        let mut anchors: Vec<(String, [f64; 3], [f64; 3])> = Vec::new();
        let inward = |a: [f64; 3]| {
            let d = sub(c, a);
            scale(d, 1.0 / norm(d))
        };
        for (j, t) in cage.triangles.iter().enumerate() {
            let [a, b, d] = t.map(|i| cage.vertices[i]);
            // Face: a generic interior point (barycentric 0.2, 0.3, 0.5), moved along −n.
            let f = add(add(scale(a, 0.2), scale(b, 0.3)), scale(d, 0.5));
            anchors.push((
                format!("face of triangle {j}"),
                f,
                scale(gc.normal(j), -1.0),
            ));
            // Edge a–b: 0.37 of the way along, moved towards the centroid.
            for (k, (x, y)) in [(a, b), (b, d), (d, a)].into_iter().enumerate() {
                let e = add(scale(x, 0.63), scale(y, 0.37));
                anchors.push((format!("edge {}–{}", t[k], t[(k + 1) % 3]), e, inward(e)));
            }
            anchors.push((format!("vertex {}", t[0]), a, inward(a)));
        }
        if name.contains("box") {
            // Centre of the +x face: on the diagonal shared by its two triangles.
            let hi = cage
                .vertices
                .iter()
                .fold(f64::NEG_INFINITY, |m, v| m.max(v[0]));
            let face: Vec<[f64; 3]> = cage
                .vertices
                .iter()
                .copied()
                .filter(|v| v[0] == hi)
                .collect();
            let fc = centroid(&face);
            anchors.push(("centre of the +x face".into(), fc, [-1.0, 0.0, 0.0]));
        }
        for (what, anchor, dir) in &anchors {
            for exp in 3..=9 {
                let delta = 10f64.powi(-exp) * l;
                let p = add(*anchor, scale(*dir, delta));
                let (phi, psi) = gc.coordinates(p);
                assert!(
                    phi.iter().chain(&psi).all(|v| v.is_finite()),
                    "{name}, {what}, δ = 1e-{exp}·L: non-finite coordinates"
                );
                let sum: f64 = phi.iter().sum();
                let e = dist(reproduce(&gc, p), p) / l;
                worst = (worst.0.max((sum - 1.0).abs()), worst.1.max(e));
                assert!(
                    (sum - 1.0).abs() <= 1e-13 && e <= 1e-13,
                    "{name}, {what}, δ = 1e-{exp}·L: Σφ − 1 = {:e}, identity error {e:e}·L",
                    sum - 1.0
                );
            }
        }
    }
    println!(
        "worst |Σφ − 1| = {:e}, worst identity error = {:e}·L",
        worst.0, worst.1
    );
}

// ---------------------------------------------------------------------------------------------
// Against quadrature of the defining integrals
// ---------------------------------------------------------------------------------------------

/// Gauss–Legendre nodes and weights on [0, 1] (Newton iteration on the Legendre polynomial P_n).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            let w = 2.0 / ((1.0 - x * x) * dp * dp);
            (0.5 * (1.0 + x), 0.5 * w)
        })
        .collect()
}

/// φ and ψ of `eta` by direct quadrature of the definition (reference §1): each cage triangle
/// split into m² sub-triangles, each integrated with an n × n Gauss–Legendre rule on the
/// collapsed square (Duffy map).
fn quadrature(cage: &Cage, eta: [f64; 3], m: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let gl = gauss_legendre(n);
    let mut phi = vec![0.0; cage.vertices.len()];
    let mut psi = vec![0.0; cage.triangles.len()];
    for (j, t) in cage.triangles.iter().enumerate() {
        let x = t.map(|i| cage.vertices[i]);
        let c = cross(sub(x[1], x[0]), sub(x[2], x[0]));
        let nrm = scale(c, 1.0 / norm(c));
        let area = 0.5 * norm(c);
        let sub_area = area / (m * m) as f64;
        // Sub-triangles in barycentric (λ1, λ2) lattice coordinates.
        let mut subs: Vec<[[f64; 2]; 3]> = Vec::new();
        let h = 1.0 / m as f64;
        for i in 0..m {
            for k in 0..m - i {
                let (a, b) = (i as f64 * h, k as f64 * h);
                subs.push([[a, b], [a + h, b], [a, b + h]]);
                if i + k + 1 < m {
                    subs.push([[a + h, b], [a + h, b + h], [a, b + h]]);
                }
            }
        }
        for s in subs {
            for &(u, wu) in &gl {
                for &(v, wv) in &gl {
                    // Duffy: (u, v) ↦ corner0 + u (corner1 − corner0) + (1−u) v (corner2 − corner0).
                    let w = wu * wv * (1.0 - u) * 2.0 * sub_area;
                    let l1 =
                        s[0][0] + u * (s[1][0] - s[0][0]) + (1.0 - u) * v * (s[2][0] - s[0][0]);
                    let l2 =
                        s[0][1] + u * (s[1][1] - s[0][1]) + (1.0 - u) * v * (s[2][1] - s[0][1]);
                    let lam = [1.0 - l1 - l2, l1, l2];
                    let xi = add(
                        add(scale(x[0], lam[0]), scale(x[1], lam[1])),
                        scale(x[2], lam[2]),
                    );
                    let d = sub(xi, eta);
                    let r = norm(d);
                    psi[j] += w / (4.0 * PI * r);
                    let kern = w * dot(d, nrm) / (4.0 * PI * r * r * r);
                    for k in 0..3 {
                        phi[t[k]] += lam[k] * kern;
                    }
                }
            }
        }
    }
    (phi, psi)
}

/// The closed form agrees with quadrature of the defining integrals to ≤ 1e-8 (observed
/// ~1e-14: with sub-triangles ≤ 0.3 across and points ≥ 0.3 from the cage, the 12-point rule's
/// error is far below that).
#[test]
fn matches_quadrature_of_the_defining_integrals() {
    let cases = [
        (
            irregular_box(),
            vec![[0.2, 0.4, 0.15], [0.0, 0.1, 0.1], [0.4, 0.7, 0.2]],
        ),
        (
            octahedron(),
            vec![[0.2, -0.1, 0.3], [0.35, 0.0, 0.2], [0.0, -0.3, 0.45]],
        ),
    ];
    let mut worst = 0.0f64;
    for (cage, points) in cases {
        let gc = gc_of(&cage);
        for p in points {
            let (phi, psi) = gc.coordinates(p);
            let (qphi, qpsi) = quadrature(&cage, p, 8, 12);
            for (i, (a, b)) in phi.iter().zip(&qphi).enumerate() {
                worst = worst.max((a - b).abs());
                assert!(
                    (a - b).abs() <= 1e-8,
                    "{p:?}: φ_{i} = {a} vs quadrature {b}"
                );
            }
            for (j, (a, b)) in psi.iter().zip(&qpsi).enumerate() {
                worst = worst.max((a - b).abs());
                assert!(
                    (a - b).abs() <= 1e-8,
                    "{p:?}: ψ_{j} = {a} vs quadrature {b}"
                );
            }
        }
    }
    println!("worst difference to quadrature: {worst:e}");
}

// ---------------------------------------------------------------------------------------------
// The binding
// ---------------------------------------------------------------------------------------------

/// `bind` + `deform_into` equals `deform` point by point for a deformed cage that is not a
/// similarity (a stretch with shear plus random vertex displacements), ≤ 1e-12·L: both sum the
/// same O(1)·O(L) products in a different order. The point count (203) is not a multiple of
/// the panel width, so the padded last panel is exercised; `phi`/`psi` read back exactly what
/// `coordinates` gives.
#[test]
fn binding_matches_deform_for_a_general_deformation() {
    for (name, cage, _, _) in cases() {
        let gc = gc_of(&cage);
        let points = if name.starts_with("perturbed") {
            perturbed_interior(203, 11)
        } else {
            convex_interior(&cage, 203, 12)
        };
        let binding = gc.bind(&points).expect("inside");
        assert_eq!(binding.point_count(), 203);
        assert_eq!(binding.vertex_count(), gc.vertex_count());
        assert_eq!(binding.triangle_count(), gc.triangle_count());
        for p in [0, 7, 8, 202] {
            let (phi, psi) = gc.coordinates(points[p]);
            for (i, v) in phi.iter().enumerate() {
                assert_eq!(binding.phi(p, i), *v);
            }
            for (j, v) in psi.iter().enumerate() {
                assert_eq!(binding.psi(p, j), *v);
            }
        }

        let a = [[1.3, 0.2, 0.0], [0.0, 0.8, 0.1], [0.1, 0.0, 1.1]];
        let mut rng = Rng::new(99);
        let moved: Vec<[f64; 3]> = cage
            .vertices
            .iter()
            .map(|&v| {
                let d = [
                    rng.range(-0.05, 0.05),
                    rng.range(-0.05, 0.05),
                    rng.range(-0.05, 0.05),
                ];
                add(add(apply(a, v), d), [0.4, 0.0, -0.2])
            })
            .collect();
        let l = size(&moved);
        let mut sn = vec![[0.0; 3]; gc.triangle_count()];
        gc.scaled_normals(&moved, &mut sn);
        let mut out = vec![[f64::NAN; 3]; points.len()];
        binding.deform_into(&moved, &sn, &mut out);
        for (p, (&q, o)) in points.iter().zip(&out).enumerate() {
            let e = dist(gc.deform(q, &moved), *o) / l;
            assert!(e <= 1e-12, "{name}: point {p}: {e:e}");
        }
    }
}

/// The binding of the rest cage reproduces the bound points (identity through the fast path).
#[test]
fn binding_of_the_rest_cage_is_the_identity() {
    let cage = irregular_box();
    let gc = gc_of(&cage);
    let points = convex_interior(&cage, 555, 5);
    let binding = gc.bind(&points).unwrap();
    let mut sn = vec![[0.0; 3]; gc.triangle_count()];
    gc.scaled_normals(&cage.vertices, &mut sn);
    let mut out = vec![[0.0; 3]; points.len()];
    binding.deform_into(&cage.vertices, &sn, &mut out);
    let l = size(&cage.vertices);
    for (p, o) in points.iter().zip(&out) {
        assert!(dist(*p, *o) / l <= 1e-12);
    }
}

/// Binding no points is fine and deforms nothing.
#[test]
fn empty_binding() {
    let gc = gc_of(&irregular_box());
    let b = gc.bind(&[]).unwrap();
    assert_eq!(b.point_count(), 0);
    let mut sn = vec![[0.0; 3]; gc.triangle_count()];
    gc.scaled_normals(gc.vertices(), &mut sn);
    b.deform_into(gc.vertices(), &sn, &mut []);
}

// ---------------------------------------------------------------------------------------------
// Box cages
// ---------------------------------------------------------------------------------------------

#[test]
fn box_cages_count_validate_and_enclose_with_padding() {
    let mut rng = Rng::new(3);
    let points: Vec<[f64; 3]> = (0..100)
        .map(|_| {
            [
                rng.range(-0.1, 0.2),
                rng.range(0.5, 0.6),
                rng.range(-3.0, -2.0),
            ]
        })
        .collect();
    let pad = 0.01;
    assert_eq!(box_cage(&points, pad), subdivided_box_cage(&points, pad, 1));
    for (n, nv, nt) in [(1, 8, 12), (2, 26, 48), (3, 56, 108), (5, 152, 300)] {
        let cage = subdivided_box_cage(&points, pad, n);
        assert_eq!(
            (cage.vertices.len(), cage.triangles.len()),
            (nv, nt),
            "n = {n}"
        );
        let gc = gc_of(&cage);
        // No duplicate vertices.
        for (i, a) in cage.vertices.iter().enumerate() {
            for b in &cage.vertices[..i] {
                assert!(a != b, "n = {n}: duplicate vertex {a:?}");
            }
        }
        // Every point is at least `pad` from every face (up to rounding of min − pad).
        let lo = [0, 1, 2].map(|a| cage.vertices.iter().fold(f64::INFINITY, |m, v| m.min(v[a])));
        let hi = [0, 1, 2].map(|a| {
            cage.vertices
                .iter()
                .fold(f64::NEG_INFINITY, |m, v| m.max(v[a]))
        });
        for p in &points {
            for a in 0..3 {
                assert!(p[a] - lo[a] >= pad * (1.0 - 1e-12) && hi[a] - p[a] >= pad * (1.0 - 1e-12));
            }
        }
        // The points bind (are strictly inside).
        gc.bind(&points).unwrap();
    }
    // n = 0 is an empty cage, which `new` rejects.
    assert!(matches!(
        err(&subdivided_box_cage(&points, pad, 0)),
        CageError::TooFewVertices { count: 0 }
    ));
}
