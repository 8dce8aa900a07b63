//! The rotation of a deformed element: the rotation `R` closest to the deformation gradient
//! `F`, i.e. the maximiser of `tr(RᵀF)` over proper rotations (`det R = +1`).
//!
//! For `det F > 0` this is the orthogonal factor of the polar decomposition `F = R S`. For a
//! flat or inverted element (`det F ≤ 0`) the polar factor would be a reflection; the
//! maximiser over rotations is then `U diag(1, 1, −1) Vᵀ` (`F = U Σ Vᵀ`, the sign put on the
//! smallest singular value), the usual sign-corrected choice of invertible FEM (Irving,
//! Teran & Fedkiw 2004), which makes an inverted element push itself back out instead of
//! collapsing further or producing NaN.
//!
//! Fast path — Newton on the rotation group, warm-started from the element's previous
//! rotation (a unit quaternion kept per element): with `M = RᵀF`, the gradient of
//! `tr((R exp(ω̂))ᵀ F)` at `ω = 0` is `g = vee(M − Mᵀ)` and its Hessian `−H` with
//! `H = tr(S) I − S`, `S = sym(M)`; the step `ω = H⁻¹ g` converges quadratically (cubically for
//! a pure rotation). The step is applied as the quaternion `(1, ω/2)`, normalised (no
//! trigonometry; it turns by `2 atan(|ω|/2) = |ω| − |ω|³/12`, an error below Newton's own). At
//! the maximiser `H` has eigenvalues `σᵢ + σⱼ` (signed singular values),
//! so it is positive definite exactly when Newton is well posed. Between two time steps an
//! element turns by far less than a radian, so one or two Newton steps reach round-off.
//!
//! Robust path — when `H` is not positive definite (inverted or nearly flat elements, a cold
//! start more than 90° away, e.g. a body handed over already rotated) or Newton has not
//! converged after a few steps, the rotation is taken from a 3×3 SVD (nalgebra, iteration
//! count bounded) with the sign correction above. Non-finite `F` leaves the rotation as it was:
//! the caller's blow-up check catches the non-finite state.

use super::element::{mat_t_mul, Mat3};

/// Newton steps before falling back to the SVD.
pub(crate) const MAX_NEWTON: usize = 8;
/// A Newton step shorter than this (radians) ends the iteration: the remaining error is of the
/// order of its square (~1e-8 rad, well below what the CG tolerance of a step resolves), and
/// the next call, warm-started, polishes it further (a body at rest converges to round-off).
/// Between two time steps this takes two Newton steps per element, where 1e-6 took three (the
/// third only to confirm); on the 50k-tetrahedra bar the trajectory is the same to 1e-6 m.
pub(crate) const STEP_TOL: f64 = 1e-4;

/// Finds the rotation closest to `f` (see the module docs) and stores it in `q` (unit
/// quaternion `[w, x, y, z]`), which on entry is the starting guess; read it back with
/// [`quat_to_mat`] and [`quat_to_mat_minus_identity`].
pub(crate) fn closest_rotation(f: &Mat3, q: &mut [f64; 4]) {
    let scale = frobenius(f);
    if !scale.is_finite() {
        return;
    }
    for _ in 0..MAX_NEWTON {
        let r = quat_to_mat(q);
        let m = mat_t_mul(&r, f);
        let g = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]];
        let t = m[0][0] + m[1][1] + m[2][2];
        // H = tr(S) I − S, S = sym(M).
        let h00 = t - m[0][0];
        let h11 = t - m[1][1];
        let h22 = t - m[2][2];
        let h01 = -0.5 * (m[0][1] + m[1][0]);
        let h02 = -0.5 * (m[0][2] + m[2][0]);
        let h12 = -0.5 * (m[1][2] + m[2][1]);
        // Positive definite by leading minors, with a margin relative to |F|.
        let eps = 1e-3 * scale;
        let c00 = h11 * h22 - h12 * h12;
        let c01 = h02 * h12 - h01 * h22;
        let c02 = h01 * h12 - h02 * h11;
        let det = h00 * c00 + h01 * c01 + h02 * c02;
        if !(h00 > eps && h00 * h11 - h01 * h01 > eps * eps && det > eps * eps * eps) {
            break;
        }
        // A critical point with H positive definite is the maximiser (the others, e.g. a half
        // turn away, are saddles or minima and were sent to the SVD above).
        if g[0] * g[0] + g[1] * g[1] + g[2] * g[2] <= 1e-28 * scale * scale {
            return;
        }
        let c11 = h00 * h22 - h02 * h02;
        let c12 = h01 * h02 - h00 * h12;
        let c22 = h00 * h11 - h01 * h01;
        let inv = 1.0 / det;
        let mut w = [
            (c00 * g[0] + c01 * g[1] + c02 * g[2]) * inv,
            (c01 * g[0] + c11 * g[1] + c12 * g[2]) * inv,
            (c02 * g[0] + c12 * g[1] + c22 * g[2]) * inv,
        ];
        let len2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        if len2 > 1.0 {
            // Far from the optimum the quadratic model is poor: limit the step to a radian.
            let s = 1.0 / len2.sqrt();
            w = [w[0] * s, w[1] * s, w[2] * s];
        }
        // Rotate by ≈ w: the quaternion (1, w/2), normalised, turns by 2·atan(|w|/2), which
        // differs from |w| by |w|³/12 — below Newton's own error, and free of trigonometry.
        *q = quat_mul(q, &[1.0, 0.5 * w[0], 0.5 * w[1], 0.5 * w[2]]);
        if len2 < STEP_TOL * STEP_TOL {
            return;
        }
    }
    *q = svd_quaternion(f);
}

/// The robust path alone: the rotation closest to `f` from its SVD, as a unit quaternion.
pub(crate) fn svd_quaternion(f: &Mat3) -> [f64; 4] {
    mat_to_quat(&svd_rotation(f))
}

/// `U diag(1, 1, det(UVᵀ)) Vᵀ` with the sign on the smallest singular value.
fn svd_rotation(f: &Mat3) -> Mat3 {
    let m = nalgebra::Matrix3::new(
        f[0][0], f[0][1], f[0][2], f[1][0], f[1][1], f[1][2], f[2][0], f[2][1], f[2][2],
    );
    let Some(svd) = m.try_svd(true, true, f64::EPSILON, 200) else {
        return IDENTITY;
    };
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return IDENTITY;
    };
    let s = svd.singular_values;
    if u.determinant() * v_t.determinant() < 0.0 {
        let k = (0..3).min_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap_or(2);
        u.column_mut(k).neg_mut();
    }
    let r = u * v_t;
    [
        [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
        [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
        [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
    ]
}

pub(crate) const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
pub(crate) const QUAT_IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

fn frobenius(f: &Mat3) -> f64 {
    f.iter().flatten().map(|x| x * x).sum::<f64>().sqrt()
}

#[inline]
fn quat_mul(a: &[f64; 4], b: &[f64; 4]) -> [f64; 4] {
    let q = [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ];
    let s = 1.0 / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    [q[0] * s, q[1] * s, q[2] * s, q[3] * s]
}

/// `R − I` of a unit quaternion, without the cancellation of forming `R` first.
#[inline]
pub(crate) fn quat_to_mat_minus_identity(q: &[f64; 4]) -> Mat3 {
    let [w, x, y, z] = *q;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, xz, yz) = (x * y, x * z, y * z);
    let (wx, wy, wz) = (w * x, w * y, w * z);
    [
        [-2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
        [2.0 * (xy + wz), -2.0 * (xx + zz), 2.0 * (yz - wx)],
        [2.0 * (xz - wy), 2.0 * (yz + wx), -2.0 * (xx + yy)],
    ]
}

#[inline]
pub(crate) fn quat_to_mat(q: &[f64; 4]) -> Mat3 {
    let [w, x, y, z] = *q;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, xz, yz) = (x * y, x * z, y * z);
    let (wx, wy, wz) = (w * x, w * y, w * z);
    [
        [1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
        [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
        [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)],
    ]
}

/// Quaternion of a rotation matrix (Shepperd's method: branch on the largest diagonal term).
fn mat_to_quat(r: &Mat3) -> [f64; 4] {
    let t = r[0][0] + r[1][1] + r[2][2];
    let q = if t > r[0][0].max(r[1][1]).max(r[2][2]) {
        let s = (1.0 + t).sqrt() * 2.0;
        [
            0.25 * s,
            (r[2][1] - r[1][2]) / s,
            (r[0][2] - r[2][0]) / s,
            (r[1][0] - r[0][1]) / s,
        ]
    } else if r[0][0] >= r[1][1] && r[0][0] >= r[2][2] {
        let s = (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt() * 2.0;
        [
            (r[2][1] - r[1][2]) / s,
            0.25 * s,
            (r[0][1] + r[1][0]) / s,
            (r[0][2] + r[2][0]) / s,
        ]
    } else if r[1][1] >= r[2][2] {
        let s = (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt() * 2.0;
        [
            (r[0][2] - r[2][0]) / s,
            (r[0][1] + r[1][0]) / s,
            0.25 * s,
            (r[1][2] + r[2][1]) / s,
        ]
    } else {
        let s = (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt() * 2.0;
        [
            (r[1][0] - r[0][1]) / s,
            (r[0][2] + r[2][0]) / s,
            (r[1][2] + r[2][1]) / s,
            0.25 * s,
        ]
    };
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n.is_finite() && n > 0.0 {
        [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
    } else {
        QUAT_IDENTITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotate(f: &Mat3, q: &mut [f64; 4]) -> Mat3 {
        closest_rotation(f, q);
        quat_to_mat(q)
    }
    fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
        let mut m = [[0.0; 3]; 3];
        for r in 0..3 {
            for c in 0..3 {
                m[r][c] = (0..3).map(|k| a[r][k] * b[k][c]).sum();
            }
        }
        m
    }
    fn det(m: &Mat3) -> f64 {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
    fn max_diff(a: &Mat3, b: &Mat3) -> f64 {
        (0..9)
            .map(|k| (a[k / 3][k % 3] - b[k / 3][k % 3]).abs())
            .fold(0.0, f64::max)
    }
    /// Unit quaternion of the rotation vector `w` (axis · angle).
    fn quat_exp(w: [f64; 3]) -> [f64; 4] {
        let angle = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
        let half = 0.5 * angle;
        // sin(θ/2)/θ, with its series below 1e-4 rad (error < 1e-17).
        let s = if angle < 1e-4 {
            0.5 - angle * angle / 48.0
        } else {
            half.sin() / angle
        };
        [half.cos(), w[0] * s, w[1] * s, w[2] * s]
    }

    fn rot(axis: [f64; 3], angle: f64) -> Mat3 {
        let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
        quat_to_mat(&quat_exp([
            axis[0] / n * angle,
            axis[1] / n * angle,
            axis[2] / n * angle,
        ]))
    }
    fn is_rotation(r: &Mat3) -> bool {
        let rtr = mat_t_mul(r, r);
        max_diff(&rtr, &IDENTITY) < 1e-12 && (det(r) - 1.0).abs() < 1e-12
    }

    #[test]
    fn recovers_rotation_of_stretched_frames() {
        let r0 = rot([1.0, 2.0, -0.5], 1.2);
        let stretch = [[1.3, 0.1, 0.0], [0.1, 0.8, -0.05], [0.0, -0.05, 1.1]];
        let f = mul(&r0, &stretch);
        // Cold start (identity): more than a radian away, so Newton is damped or falls back.
        let mut q = QUAT_IDENTITY;
        let r = rotate(&f, &mut q);
        assert!(max_diff(&r, &r0) < 1e-12, "{r:?}");
        // Warm start a little off: pure Newton.
        let mut q = mat_to_quat(&rot([1.0, 2.0, -0.4], 1.15));
        let r = rotate(&f, &mut q);
        assert!(max_diff(&r, &r0) < 1e-12);
        assert!(max_diff(&quat_to_mat(&q), &r0) < 1e-12);
    }

    #[test]
    fn half_turn_from_a_cold_start() {
        // Exactly 180° from the start: the gradient vanishes, Newton is not applicable.
        let r0 = rot([0.0, 0.0, 1.0], std::f64::consts::PI);
        let mut q = QUAT_IDENTITY;
        let r = rotate(&r0, &mut q);
        assert!(max_diff(&r, &r0) < 1e-12, "{r:?}");
    }

    #[test]
    fn inverted_and_flat_elements_give_proper_rotations() {
        // A reflection through the xy plane (inverted element): the closest rotation is I.
        let f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -0.2]];
        let mut q = QUAT_IDENTITY;
        let r = rotate(&f, &mut q);
        assert!(is_rotation(&r) && max_diff(&r, &IDENTITY) < 1e-12, "{r:?}");
        // Flattened to a plane, and collapsed to a line, and to a point.
        for f in [
            [[1.0, 0.2, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]],
            [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
            [[0.0; 3]; 3],
        ] {
            let mut q = QUAT_IDENTITY;
            let r = rotate(&f, &mut q);
            assert!(is_rotation(&r), "{f:?} -> {r:?}");
        }
        // Strongly inverted and rotated.
        let r0 = rot([0.3, -1.0, 0.2], 0.7);
        let f = mul(&r0, &[[0.9, 0.0, 0.0], [0.0, 1.1, 0.0], [0.0, 0.0, -1.5]]);
        let mut q = QUAT_IDENTITY;
        let r = rotate(&f, &mut q);
        assert!(is_rotation(&r));
        // The maximiser of tr(RᵀF): compare against a brute-force check of nearby rotations.
        let tr = |r: &Mat3| (0..3).map(|k| mat_t_mul(r, &f)[k][k]).sum::<f64>();
        for axis in [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
        ] {
            for a in [-0.01, 0.01, 1.0, 3.0] {
                assert!(tr(&mul(&r, &rot(axis, a))) <= tr(&r) + 1e-12);
            }
        }
    }

    #[test]
    fn non_finite_input_keeps_the_guess() {
        let mut q = QUAT_IDENTITY;
        closest_rotation(&[[f64::NAN; 3]; 3], &mut q);
        assert_eq!(q, QUAT_IDENTITY);
    }
}
