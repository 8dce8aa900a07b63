//! The lane arithmetic of the batched element loops (`batch.rs`): four elements at a time, one
//! per lane, as plain arrays or AVX (chosen at run time), and the per-lane rotation math
//! (closest rotation by quaternion Newton steps with an SVD fallback, small matrix helpers).

use super::batch::{Lanes, LANES};
use super::rotation::{self, MAX_NEWTON, STEP_TOL};
use std::ops::{Add, Div, Mul, Neg, Sub};
/// Whether the AVX kernels can run here (cached by the standard library after the first call).
#[cfg(target_arch = "x86_64")]
#[inline]
pub(super) fn avx_available() -> bool {
    is_x86_feature_detected!("avx") && is_x86_feature_detected!("avx2")
}

/// `[[Lanes; 3]; 4]` (four vectors of three components, per lane) into registers.
#[inline(always)]
pub(super) fn load_vectors<S: Simd>(x: &[[Lanes; 3]; 4]) -> [[S; 3]; 4] {
    // Element by element from the reference: written as a loop into a zeroed array, the
    // product's kernel copied the 384 bytes to the stack through a `memcpy` call per batch
    // (6 % of the 20k-tetrahedra liver's contact step).
    std::array::from_fn(|k| std::array::from_fn(|c| S::load(&x[k][c])))
}

/// The SVD fallback of the rotation search, on the lanes flagged in `lanes` (bit `l`).
#[cold]
#[inline(never)]
pub(super) fn svd_fallback<S: Simd>(f: &[[S; 3]; 3], q: &mut [S; 4], lanes: u8) {
    let mut fa = [[[0.0; LANES]; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            fa[r][c] = f[r][c].to_array();
        }
    }
    let mut qa = [[0.0; LANES]; 4];
    for c in 0..4 {
        qa[c] = q[c].to_array();
    }
    for l in 0..LANES {
        if lanes & (1 << l) != 0 {
            let mut fl = [[0.0; 3]; 3];
            for r in 0..3 {
                for c in 0..3 {
                    fl[r][c] = fa[r][c][l];
                }
            }
            let ql = rotation::svd_quaternion(&fl);
            for c in 0..4 {
                qa[c][l] = ql[c];
            }
        }
    }
    for c in 0..4 {
        q[c] = S::load(&qa[c]);
    }
}

/// [`rotation::closest_rotation`] on every lane: updates `q` in place and returns the lanes
/// (bit `l` for lane `l`) that need the SVD fallback (Newton not applicable, or not converged
/// in `MAX_NEWTON` steps). A lane with non-finite `F` keeps its `q` and is not flagged (as in
/// the scalar search).
#[inline(always)]
pub(super) fn closest_rotation<S: Simd>(f: &[[S; 3]; 3], q: &mut [S; 4]) -> u8 {
    // Frobenius norm, summed row by row as the scalar `frobenius`.
    let mut sum = f[0][0] * f[0][0];
    for k in 1..9 {
        let x = f[k / 3][k % 3];
        sum = sum + x * x;
    }
    let scale = sum.sqrt();
    // Finite lanes: `scale < ∞` is false for ∞ and NaN.
    let mut active = scale.lt(S::splat(f64::INFINITY));
    let mut svd = 0u8;
    let eps = S::splat(1e-3) * scale;
    let eps2 = eps * eps;
    let eps3 = eps2 * eps;
    let tiny = S::splat(1e-28) * scale * scale;
    let tol2 = S::splat(STEP_TOL * STEP_TOL);
    for _ in 0..MAX_NEWTON {
        if active == 0 {
            break;
        }
        let r = quat_to_mat(q);
        let m = mat_t_mul(&r, f);
        let g = [m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]];
        let t = m[0][0] + m[1][1] + m[2][2];
        // H = tr(S) I − S, S = sym(M).
        let h00 = t - m[0][0];
        let h11 = t - m[1][1];
        let h22 = t - m[2][2];
        let half = S::splat(-0.5);
        let h01 = half * (m[0][1] + m[1][0]);
        let h02 = half * (m[0][2] + m[2][0]);
        let h12 = half * (m[1][2] + m[2][1]);
        let c00 = h11 * h22 - h12 * h12;
        let c01 = h02 * h12 - h01 * h22;
        let c02 = h01 * h12 - h02 * h11;
        let det = h00 * c00 + h01 * c01 + h02 * c02;
        let pd = h00.gt(eps) & (h00 * h11 - h01 * h01).gt(eps2) & det.gt(eps3);
        let g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        let c11 = h00 * h22 - h02 * h02;
        let c12 = h01 * h02 - h00 * h12;
        let c22 = h00 * h11 - h01 * h01;
        let inv = S::splat(1.0) / det;
        let mut w = [
            (c00 * g[0] + c01 * g[1] + c02 * g[2]) * inv,
            (c01 * g[0] + c11 * g[1] + c12 * g[2]) * inv,
            (c02 * g[0] + c12 * g[1] + c22 * g[2]) * inv,
        ];
        let len2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
        let long = len2.gt(S::splat(1.0));
        if long != 0 {
            let s = S::splat(1.0) / len2.sqrt();
            for x in &mut w {
                *x = S::select(long, *x * s, *x);
            }
        }
        let hf = S::splat(0.5);
        let next = quat_mul(q, &[S::splat(1.0), hf * w[0], hf * w[1], hf * w[2]]);
        svd |= active & !pd;
        let update = active & pd & g2.gt(tiny);
        active = update & !len2.lt(tol2);
        for c in 0..4 {
            q[c] = S::select(update, next[c], q[c]);
        }
    }
    svd | active
}

#[inline(always)]
pub(super) fn quat_mul<S: Simd>(a: &[S; 4], b: &[S; 4]) -> [S; 4] {
    let q = [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ];
    let s = S::splat(1.0) / (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    [q[0] * s, q[1] * s, q[2] * s, q[3] * s]
}

/// `R` of a unit quaternion, as `(R − I) + I`: bit-for-bit the scalar `1 − 2(y² + z²)` etc.
/// (adding 1 to `−2(y² + z²)` rounds exactly as subtracting `2(y² + z²)` from 1).
#[inline(always)]
pub(super) fn quat_to_mat<S: Simd>(q: &[S; 4]) -> [[S; 3]; 3] {
    plus_identity(quat_to_mat_minus_identity(q))
}

#[inline(always)]
pub(super) fn plus_identity<S: Simd>(mut m: [[S; 3]; 3]) -> [[S; 3]; 3] {
    for (k, row) in m.iter_mut().enumerate() {
        row[k] = row[k] + S::splat(1.0);
    }
    m
}

#[inline(always)]
pub(super) fn quat_to_mat_minus_identity<S: Simd>(q: &[S; 4]) -> [[S; 3]; 3] {
    let [w, x, y, z] = *q;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let (xy, xz, yz) = (x * y, x * z, y * z);
    let (wx, wy, wz) = (w * x, w * y, w * z);
    let (m2, two) = (S::splat(-2.0), S::splat(2.0));
    [
        [m2 * (yy + zz), two * (xy - wz), two * (xz + wy)],
        [two * (xy + wz), m2 * (xx + zz), two * (yz - wx)],
        [two * (xz - wy), two * (yz + wx), m2 * (xx + yy)],
    ]
}

/// `l tr(h) I + m (h + hᵀ)`: the stress of the strain `sym(h)` (with the Lamé parameters), or
/// the stiffness product's `Vλ tr(G) I + Vμ (G + Gᵀ)`.
#[inline(always)]
pub(super) fn isotropic<S: Simd>(h: &[[S; 3]; 3], l: S, m: S) -> [[S; 3]; 3] {
    let tr = l * (h[0][0] + h[1][1] + h[2][2]);
    let mut s = [[S::splat(0.0); 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            s[a][b] = m * (h[a][b] + h[b][a]);
        }
        s[a][a] = s[a][a] + tr;
    }
    s
}

/// `aᵀ b`.
#[inline(always)]
pub(super) fn mat_t_mul<S: Simd>(a: &[[S; 3]; 3], b: &[[S; 3]; 3]) -> [[S; 3]; 3] {
    let mut m = [[S::splat(0.0); 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] = a[0][r] * b[0][c] + a[1][r] * b[1][c] + a[2][r] * b[2][c];
        }
    }
    m
}

#[inline(always)]
pub(super) fn mat_vec<S: Simd>(m: &[[S; 3]; 3], v: &[S; 3]) -> [S; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

/// One value per lane, with lane-wise arithmetic; comparisons return a bit mask (bit `l` for
/// lane `l`, set where the IEEE comparison holds: never for NaN).
pub(super) trait Simd:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    fn splat(x: f64) -> Self;
    fn new(x: Lanes) -> Self;
    fn load(x: &Lanes) -> Self;
    fn to_array(self) -> Lanes;
    fn sqrt(self) -> Self;
    fn gt(self, o: Self) -> u8;
    fn lt(self, o: Self) -> u8;
    /// `a` on the lanes set in `m`, `b` elsewhere.
    fn select(m: u8, a: Self, b: Self) -> Self;
}

/// Plain arrays: what the compiler makes of them (the fallback without AVX).
#[derive(Debug, Clone, Copy)]
pub(super) struct Portable(pub(super) Lanes);

impl Simd for Portable {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Portable([x; LANES])
    }
    #[inline(always)]
    fn new(x: Lanes) -> Self {
        Portable(x)
    }
    #[inline(always)]
    fn load(x: &Lanes) -> Self {
        Portable(*x)
    }
    #[inline(always)]
    fn to_array(self) -> Lanes {
        self.0
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = x.sqrt();
        }
        Portable(r)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> u8 {
        let mut m = 0;
        for l in 0..LANES {
            m |= ((self.0[l] > o.0[l]) as u8) << l;
        }
        m
    }
    #[inline(always)]
    fn lt(self, o: Self) -> u8 {
        o.gt(self)
    }
    #[inline(always)]
    fn select(m: u8, a: Self, b: Self) -> Self {
        let mut r = b.0;
        for l in 0..LANES {
            if m & (1 << l) != 0 {
                r[l] = a.0[l];
            }
        }
        Portable(r)
    }
}

macro_rules! lanewise {
    ($trait:ident, $f:ident, $op:tt) => {
        impl $trait for Portable {
            type Output = Portable;
            #[inline(always)]
            fn $f(self, o: Portable) -> Portable {
                let mut r = [0.0; LANES];
                for l in 0..LANES {
                    r[l] = self.0[l] $op o.0[l];
                }
                Portable(r)
            }
        }
    };
}
lanewise!(Add, add, +);
lanewise!(Sub, sub, -);
lanewise!(Mul, mul, *);
lanewise!(Div, div, /);

impl Neg for Portable {
    type Output = Portable;
    #[inline(always)]
    fn neg(self) -> Portable {
        let mut r = self.0;
        for x in &mut r {
            *x = -*x;
        }
        Portable(r)
    }
}

/// AVX registers. Only built inside the `#[target_feature(enable = "avx")]` kernels, which
/// run only where the CPU has AVX; every method is inlined into them.
#[cfg(target_arch = "x86_64")]
pub(super) mod avx {
    use super::{Lanes, Simd, LANES};
    use std::arch::x86_64::*;
    use std::ops::{Add, Div, Mul, Neg, Sub};

    const _: () = assert!(LANES == 4, "one __m256d holds four lanes");

    #[derive(Clone, Copy)]
    pub(in crate::fem) struct Avx(__m256d);

    // SAFETY (every `unsafe` block below): an `Avx` exists only inside the AVX kernels, which
    // are called only after checking that the CPU has AVX; the loads and stores are of whole
    // `[f64; 4]` arrays.
    impl Simd for Avx {
        #[inline(always)]
        fn splat(x: f64) -> Self {
            Avx(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn new(x: Lanes) -> Self {
            Avx(unsafe { _mm256_set_pd(x[3], x[2], x[1], x[0]) })
        }
        #[inline(always)]
        fn load(x: &Lanes) -> Self {
            Avx(unsafe { _mm256_loadu_pd(x.as_ptr()) })
        }
        #[inline(always)]
        fn to_array(self) -> Lanes {
            let mut r = [0.0; 4];
            unsafe { _mm256_storeu_pd(r.as_mut_ptr(), self.0) };
            r
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            Avx(unsafe { _mm256_sqrt_pd(self.0) })
        }
        #[inline(always)]
        fn gt(self, o: Self) -> u8 {
            unsafe { _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(self.0, o.0)) as u8 }
        }
        #[inline(always)]
        fn lt(self, o: Self) -> u8 {
            unsafe { _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_LT_OQ>(self.0, o.0)) as u8 }
        }
        #[inline(always)]
        fn select(m: u8, a: Self, b: Self) -> Self {
            let bit = |l: u8| if m & (1 << l) != 0 { -1i64 } else { 0 };
            unsafe {
                let mask = _mm256_castsi256_pd(_mm256_set_epi64x(bit(3), bit(2), bit(1), bit(0)));
                Avx(_mm256_blendv_pd(b.0, a.0, mask))
            }
        }
    }

    macro_rules! avx_op {
        ($trait:ident, $f:ident, $intr:ident) => {
            impl $trait for Avx {
                type Output = Avx;
                #[inline(always)]
                fn $f(self, o: Avx) -> Avx {
                    Avx(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    avx_op!(Add, add, _mm256_add_pd);
    avx_op!(Sub, sub, _mm256_sub_pd);
    avx_op!(Mul, mul, _mm256_mul_pd);
    avx_op!(Div, div, _mm256_div_pd);

    impl Neg for Avx {
        type Output = Avx;
        #[inline(always)]
        fn neg(self) -> Avx {
            Avx(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }
}
