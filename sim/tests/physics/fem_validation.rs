//! Validation of the tetrahedral FEM against closed-form solutions.
//!
//! - Cantilever under its own weight vs Euler–Bernoulli (`δ = qL⁴/(8EI)`): linear
//!   tetrahedra lock in bending, so the coarse mesh is far too stiff; the error falls like h²
//!   and is within 5 % on the fine mesh. The corotational static solve agrees with the linear
//!   one at this small deflection.
//! - Patch test: a linear displacement prescribed on the boundary of an irregular mesh is
//!   reproduced in the interior to round-off, with the uniform strain in every element (linear
//!   mode; and the corotational mode reproduces a large homogeneous stretch-and-rotation).
//! - A rigidly rotated body: corotational elements feel no force, linear ones a large one.

use std::path::PathBuf;

use lop_sim::fem::{box_mesh, Fem, FemError, FemMode, FemParameters};
use lop_sim::mesh::TetMesh;

type Mat3 = [[f64; 3]; 3];

fn params(young: f64, poisson: f64, density: f64, mode: FemMode) -> FemParameters {
    FemParameters {
        young,
        poisson,
        density,
        damping: 0.0,
        dt: 0.01,
        mode,
    }
}

fn mat_vec(a: &Mat3, x: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| a[r][0] * x[0] + a[r][1] * x[1] + a[r][2] * x[2])
}

/// Rotation by `angle` about the unit `axis` (Rodrigues).
fn rotation(axis: [f64; 3], angle: f64) -> Mat3 {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let [x, y, z] = axis.map(|a| a / n);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

/// Deformation gradient of tetrahedron `t` from rest `X` to `x`, computed independently of the
/// library: `F = Ds Dm⁻¹`.
#[allow(clippy::needless_range_loop)]
fn deformation_gradient(rest: &[[f64; 3]], x: &[[f64; 3]], t: [u32; 4]) -> Mat3 {
    let cols = |p: &[[f64; 3]]| -> Mat3 {
        let o = p[t[0] as usize];
        let mut m = [[0.0; 3]; 3];
        for k in 0..3 {
            let q = p[t[k + 1] as usize];
            for r in 0..3 {
                m[r][k] = q[r] - o[r];
            }
        }
        m
    };
    let (dm, ds) = (cols(rest), cols(x));
    let det = dm[0][0] * (dm[1][1] * dm[2][2] - dm[1][2] * dm[2][1])
        - dm[0][1] * (dm[1][0] * dm[2][2] - dm[1][2] * dm[2][0])
        + dm[0][2] * (dm[1][0] * dm[2][1] - dm[1][1] * dm[2][0]);
    let mut inv = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            let (r1, r2) = ((c + 1) % 3, (c + 2) % 3);
            let (c1, c2) = ((r + 1) % 3, (r + 2) % 3);
            inv[r][c] = (dm[r1][c1] * dm[r2][c2] - dm[r1][c2] * dm[r2][c1]) / det;
        }
    }
    let mut f = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            f[r][c] = (0..3).map(|k| ds[r][k] * inv[k][c]).sum();
        }
    }
    f
}

// ---------------------------------------------------------------------------------------------
// Cantilever

/// Tip deflection (mean over the tip face) of a cantilever `L × h × h` clamped at x = 0 under
/// gravity along −y, and the Euler–Bernoulli value `qL⁴/(8EI)`.
fn cantilever(cells: [usize; 3], mode: FemMode) -> (f64, f64) {
    let (l, h) = (0.5, 0.05); // L/h = 10
    let (e, rho, g) = (1e8, 100.0, 9.81);
    let mesh = box_mesh([l, h, h], cells, |p| p[0] == 0.0);
    let mut fem = Fem::new(&mesh, params(e, 0.0, rho, mode)).unwrap();
    let report = fem.solve_static([0.0, -g, 0.0], &[]).unwrap();
    assert!(report.residual < 1e-9, "residual {:e}", report.residual);
    assert_eq!(fem.positions(), report.positions.as_slice());
    assert!(fem.max_speed() == 0.0);
    let tip: Vec<usize> = (0..mesh.nodes.len())
        .filter(|&i| mesh.nodes[i][0] == l)
        .collect();
    let sag = tip
        .iter()
        .map(|&i| mesh.nodes[i][1] - report.positions[i][1])
        .sum::<f64>()
        / tip.len() as f64;
    let q = rho * g * h * h;
    let inertia = h.powi(4) / 12.0;
    (sag, q * l.powi(4) / (8.0 * e * inertia))
}

#[test]
fn cantilever_converges_to_euler_bernoulli() {
    // Two cells across the width suffice (ν = 0: no bending about y); thickness and length
    // are refined together. Shear deformation adds ~0.8 % at L/h = 10 (Timoshenko).
    let (coarse, eb) = cantilever([40, 4, 2], FemMode::Linear);
    let (fine, _) = cantilever([100, 10, 2], FemMode::Linear);
    let (err_coarse, err_fine) = ((coarse - eb).abs() / eb, (fine - eb).abs() / eb);
    println!("Euler-Bernoulli {eb:.4e} m; coarse {coarse:.4e} ({err_coarse:.3}), fine {fine:.4e} ({err_fine:.3})");
    assert!(
        coarse < fine && fine < eb * 1.01,
        "locking makes tets stiff"
    );
    assert!(err_fine < 0.05, "fine mesh error {err_fine}");
    // h shrinks 2.5×: second order would divide the error by 6.25; ask for at least 4.
    assert!(err_fine < err_coarse / 4.0, "{err_coarse} -> {err_fine}");
}

#[test]
fn corotational_static_matches_linear_at_small_deflection() {
    let (lin, _) = cantilever([40, 4, 2], FemMode::Linear);
    let (corot, _) = cantilever([40, 4, 2], FemMode::Corotational);
    // δ/L ≈ 6e-4: geometric non-linearity is of that relative order at most.
    assert!((corot - lin).abs() < 1e-3 * lin, "{corot} vs {lin}");
}

#[test]
fn static_solve_needs_supports() {
    let mesh = box_mesh([0.1, 0.02, 0.02], [4, 1, 1], |_| false);
    let mut fem = Fem::new(&mesh, params(1e4, 0.3, 100.0, FemMode::Linear)).unwrap();
    assert_eq!(
        fem.solve_static([0.0, -9.81, 0.0], &[]),
        Err(FemError::Unsupported)
    );
    // One fixed node leaves rotations about it free.
    let mesh = box_mesh([0.1, 0.02, 0.02], [4, 1, 1], |p| p == [0.0; 3]);
    let mut fem = Fem::new(&mesh, params(1e4, 0.3, 100.0, FemMode::Linear)).unwrap();
    let r = fem.solve_static([0.0, -9.81, 0.0], &[]);
    assert!(
        matches!(r, Err(FemError::Singular)) || r.as_ref().is_ok_and(|s| s.residual > 1e-6),
        "{:?}",
        r.map(|s| s.residual)
    );
}

// ---------------------------------------------------------------------------------------------
// Patch test

/// A 4×4×4-cell cube with its interior nodes jittered (an irregular mesh), every boundary
/// node fixed.
fn irregular_cube() -> TetMesh {
    let n = 4;
    let mesh = box_mesh([1.0; 3], [n; 3], |p| {
        p.iter().any(|&c| c == 0.0 || c == 1.0)
    });
    let h = 1.0 / n as f64;
    let mut nodes = mesh.nodes.clone();
    for (i, p) in nodes.iter_mut().enumerate() {
        if mesh.fixed.binary_search(&(i as u32)).is_err() {
            // Deterministic pseudo-random jitter up to ±0.2 h per axis.
            for (k, c) in p.iter_mut().enumerate() {
                let s = ((i * 7 + k * 13) as f64 * 1.618_033_988_7).fract() - 0.5;
                *c += 0.4 * h * s;
            }
        }
    }
    TetMesh::from_parts(
        nodes,
        mesh.tets.clone(),
        mesh.fixed.clone(),
        PathBuf::from("cube"),
    )
    .expect("jittered cube is valid")
}

/// Prescribes `x = F X + t` on the fixed nodes (interior left at rest), solves, and returns
/// the worst interior position error relative to the displacement scale, and the worst
/// element deviation of `F`.
fn patch(mode: FemMode, f: Mat3, t: [f64; 3]) -> (f64, f64) {
    let mesh = irregular_cube();
    let target: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .map(|&p| {
            let q = mat_vec(&f, p);
            [q[0] + t[0], q[1] + t[1], q[2] + t[2]]
        })
        .collect();
    let mut start = mesh.nodes.clone();
    for &i in &mesh.fixed {
        start[i as usize] = target[i as usize];
    }
    let mut fem = Fem::new(&mesh, params(5000.0, 0.3, 1000.0, mode)).unwrap();
    fem.set_state(&start, &vec![[0.0; 3]; start.len()]);
    let report = fem.solve_static([0.0; 3], &[]).unwrap();
    let x = &report.positions;
    let scale = (0..mesh.nodes.len())
        .flat_map(|i| (0..3).map(move |k| (i, k)))
        .map(|(i, k)| (target[i][k] - mesh.nodes[i][k]).abs())
        .fold(0.0, f64::max);
    let mut pos_err: f64 = 0.0;
    for i in 0..mesh.nodes.len() {
        for k in 0..3 {
            pos_err = pos_err.max((x[i][k] - target[i][k]).abs() / scale);
        }
    }
    let mut f_err: f64 = 0.0;
    for &tet in &mesh.tets {
        let fe = deformation_gradient(&mesh.nodes, x, tet);
        for r in 0..3 {
            for c in 0..3 {
                f_err = f_err.max((fe[r][c] - f[r][c]).abs());
            }
        }
    }
    (pos_err, f_err)
}

#[test]
fn patch_test_linear() {
    let a = [
        [1.0 + 2e-3, 5e-4, -1e-3],
        [-7e-4, 1.0 - 1.5e-3, 3e-4],
        [1.2e-3, 4e-4, 1.0 + 8e-4],
    ];
    let (pos_err, f_err) = patch(FemMode::Linear, a, [1e-3, -2e-3, 5e-4]);
    assert!(pos_err < 1e-10, "interior error {pos_err:e}");
    // The strain of every element is the uniform strain: F − I is reproduced to round-off
    // relative to its size (~1e-3).
    assert!(f_err < 1e-12, "element F error {f_err:e}");
}

#[test]
fn patch_test_corotational_large_homogeneous_deformation() {
    // 30° turn after a 20 % stretch and a shear: homogeneous, hence an exact equilibrium of
    // the corotational equations too, far outside small-strain territory.
    let r = rotation([1.0, -0.5, 0.3], 30f64.to_radians());
    let u = [[1.2, 0.1, 0.0], [0.0, 0.9, 0.05], [0.0, 0.0, 1.1]];
    let mut f = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            f[i][j] = (0..3).map(|k| r[i][k] * u[k][j]).sum();
        }
    }
    let (pos_err, f_err) = patch(FemMode::Corotational, f, [0.1, -0.2, 0.05]);
    // To the static solver's tolerance (relative residual 1e-10).
    assert!(pos_err < 1e-9, "interior error {pos_err:e}");
    assert!(f_err < 1e-9, "element F error {f_err:e}");
}

// ---------------------------------------------------------------------------------------------
// Rigid rotation

#[test]
fn corotational_elements_ignore_rigid_rotation() {
    let mesh = box_mesh([0.1, 0.05, 0.02], [4, 2, 2], |_| false);
    let young = 1e4;
    let volume = mesh.info().volume / mesh.tets.len() as f64;
    let force_scale = young * volume.powf(2.0 / 3.0);
    let r = rotation([1.0, 1.0, 1.0], 90f64.to_radians());
    let rotated: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .map(|&p| {
            let q = mat_vec(&r, p);
            [q[0] + 0.3, q[1] - 0.1, q[2] + 0.2]
        })
        .collect();
    let still = vec![[0.0; 3]; rotated.len()];
    let worst = |mode| {
        let mut fem = Fem::new(&mesh, params(young, 0.3, 1000.0, mode)).unwrap();
        fem.set_state(&rotated, &still);
        fem.elastic_forces()
            .iter()
            .map(|f| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
            .fold(0.0, f64::max)
            / force_scale
    };
    let corot = worst(FemMode::Corotational);
    let linear = worst(FemMode::Linear);
    println!("|f| / (E V^(2/3)): corotational {corot:e}, linear {linear:e}");
    assert!(corot < 1e-9, "corotational {corot:e}");
    assert!(linear > 0.1, "linear {linear:e}");

    // And a step from that rotated state at rest stays at rest (no gravity, no load).
    let mut fem = Fem::new(&mesh, params(young, 0.3, 1000.0, FemMode::Corotational)).unwrap();
    fem.set_state(&rotated, &still);
    fem.step([0.0; 3], &[], None).unwrap();
    assert!(fem.max_speed() < 1e-9, "{}", fem.max_speed());
}
