//! Supernodal Cholesky factors repacked for our own triangular solves: in half precision
//! (IEEE binary16) for the corotational preconditioner of the large meshes, and in double
//! precision for the direct solves of the small ones.
//!
//! Half precision. A preconditioner solve is memory-bound: it streams the factor twice
//! (forward and backward) and does two flops per value read. faer's single-precision factor of
//! the 50k-tetrahedra box is 64 MB, of which 11 MB are the unused upper triangles of the
//! supernodes' dense diagonal blocks. The half copy keeps only the lower triangles, in 16-bit
//! floats: 27 MB, under half the traffic.
//!
//! Range and accuracy: binary16 has 11 significant bits and normal numbers down to 2⁻¹⁴. The
//! factor is stored symmetrically scaled, `L̂ = D L` with `D = diag(A)^(−½)`: `L̂ L̂ᵀ = D A D`
//! has a unit diagonal, so every row of `L̂` has unit norm and every entry lies in `[−1, 1]`,
//! whatever the units of the matrix. Rounding `L̂` to binary16 perturbs it by at most
//! `2⁻¹¹` relative (entries below 2⁻¹⁴ keep an absolute accuracy of 2⁻²⁵): on the 50k box the
//! CG iteration counts of the smooth steps are those of the single-precision factor (CG runs
//! in double precision in its flexible form, which absorbs a preconditioner's rounding). The
//! diagonal of `L̂` is kept apart, inverted, in `f32`; the solves compute in `f32`.
//!
//! Double precision. On the organ meshes the factor (1.3 MB on the liver) sits in a core's L2
//! cache, and faer's general supernodal solve spends most of its time on per-supernode
//! overhead (block views, dispatch to its dense kernels sized for large blocks): the linear
//! liver's solve pair took 100 µs for 157k values. The same packed layout, sweeps and kernel
//! shapes in `f64` (scaled the same way, which costs nothing in accuracy: faer's result to
//! 1e-13, tested) take 74 µs; what is left is mostly the chain of short column operations in
//! the diagonal blocks, each waiting for the last. On large factors, where the solve streams
//! from memory, dropping the unused upper triangles helps too (100k-tetrahedra box: 47 →
//! 36 ms per solve pair).
//!
//! Layout, per supernode of `w` columns starting at column `s` with `m` rows below its
//! diagonal block: the strictly lower triangle of the diagonal block, column by column
//! (column `j` holds rows `j+1..w`), then the `m × w` panel below it, column-major. The
//! forward solve is column-oriented (axpys into the top of the vector and into a gathered
//! buffer of the panel's rows, four panel columns at a time); the backward solve is
//! dot products on the same columns.
//!
//! The kernels use AVX2 and FMA (and F16C for binary16) when the CPU has them (checked at run
//! time), and portable scalar code otherwise.

use std::fmt::Debug;
use std::iter::Sum;
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;

/// The arithmetic of the solves: `f32` or `f64`.
pub(crate) trait Real:
    Copy
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + Sum
{
    const ZERO: Self;
    const ONE: Self;
    fn from_f64(x: f64) -> Self;
    fn to_f64(self) -> f64;
    fn finite(self) -> bool;
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    #[inline(always)]
    fn from_f64(x: f64) -> f32 {
        x as f32
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
    #[inline(always)]
    fn from_f64(x: f64) -> f64 {
        x
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
}

/// A stored factor value: binary16 bits (`u16`, solved in `f32`) or `f64`.
pub(crate) trait Value: Copy + Default + Debug + 'static {
    /// The type the solves compute in, and faer's factor values are in.
    type Acc: Real;
    /// The value as `Acc`.
    fn widen(self) -> Self::Acc;
    /// `dst[i] = src[i] · scale[i]`, rounded to `Self`.
    fn pack(dst: &mut [Self], src: &[Self::Acc], scale: &[Self::Acc], simd: bool);
    /// Whether the SIMD kernels for this type can run here.
    fn simd_available() -> bool;
    /// The sweeps with the SIMD kernels.
    ///
    /// # Safety
    /// Only where [`Value::simd_available`] holds.
    unsafe fn sweeps_simd(f: &mut PackedFactor<Self>);
}

impl Value for u16 {
    type Acc = f32;
    #[inline(always)]
    fn widen(self) -> f32 {
        f16_to_f32(self)
    }
    fn pack(dst: &mut [u16], src: &[f32], scale: &[f32], simd: bool) {
        convert_scaled(dst, src, scale, simd);
    }
    fn simd_available() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            is_x86_feature_detected!("avx2")
                && is_x86_feature_detected!("fma")
                && is_x86_feature_detected!("f16c")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }
    unsafe fn sweeps_simd(f: &mut PackedFactor<u16>) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller checked the features.
        unsafe {
            avx2::sweeps_half(f)
        };
        #[cfg(not(target_arch = "x86_64"))]
        f.sweeps::<Scalar>();
    }
}

impl Value for f64 {
    type Acc = f64;
    #[inline(always)]
    fn widen(self) -> f64 {
        self
    }
    fn pack(dst: &mut [f64], src: &[f64], scale: &[f64], _simd: bool) {
        for ((d, s), c) in dst.iter_mut().zip(src).zip(scale) {
            *d = s * c;
        }
    }
    fn simd_available() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }
    unsafe fn sweeps_simd(f: &mut PackedFactor<f64>) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the caller checked the features.
        unsafe {
            avx2::sweeps_double(f)
        };
        #[cfg(not(target_arch = "x86_64"))]
        f.sweeps::<Scalar>();
    }
}

/// The half-precision preconditioner factor.
pub(crate) type HalfFactor = PackedFactor<u16>;

/// One supernode of a packed factor.
#[derive(Debug, Clone, Copy)]
struct Supernode {
    /// First column.
    start: u32,
    /// Columns.
    width: u32,
    /// Start of its below-diagonal rows in `rows`; `m` of them.
    rows: u32,
    m: u32,
    /// Start of its values in `vals`: the strict lower triangle, then the panel.
    vals: usize,
}

/// A supernodal Cholesky factor, scaled and packed (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct PackedFactor<V: Value> {
    nodes: Vec<Supernode>,
    /// Below-diagonal row indices of every supernode, concatenated.
    rows: Vec<u32>,
    /// The scaled factor's off-diagonal entries.
    vals: Vec<V>,
    /// Per column: `1 / L̂_jj`.
    inv_diag: Vec<V::Acc>,
    /// Per row: `dᵢ = A_ii^(−½)`.
    scale: Vec<V::Acc>,
    /// Scratch: the vector being solved for (`n`), and a supernode's gathered rows or scale
    /// factors (the largest `w + m`).
    x: Vec<V::Acc>,
    tmp: Vec<V::Acc>,
    simd: bool,
}

impl<V: Value> PackedFactor<V> {
    /// Allocates the factor for this supernodal structure (values unset).
    pub fn new(sn: &SymbolicSupernodalCholesky<u32>) -> PackedFactor<V> {
        let n = sn.nrows();
        let mut nodes = Vec::with_capacity(sn.n_supernodes());
        let mut vals = 0usize;
        let mut widest = 0usize;
        for k in 0..sn.n_supernodes() {
            let start = sn.supernode_begin()[k];
            let width = sn.supernode_end()[k] - start;
            let (r0, r1) = (sn.col_ptr_for_row_idx()[k], sn.col_ptr_for_row_idx()[k + 1]);
            let (w, m) = (width as usize, (r1 - r0) as usize);
            nodes.push(Supernode {
                start,
                width,
                rows: r0,
                m: r1 - r0,
                vals,
            });
            vals += w * (w - 1) / 2 + w * m;
            widest = widest.max(w + m);
        }
        PackedFactor {
            nodes,
            rows: sn.row_idx().to_vec(),
            // Eight more: the SIMD kernels read a column's last values up to eight at a time.
            vals: vec![V::default(); vals + 8],
            inv_diag: vec![V::Acc::ZERO; n],
            scale: vec![V::Acc::ZERO; n],
            x: vec![V::Acc::ZERO; n],
            tmp: vec![V::Acc::ZERO; widest],
            simd: V::simd_available(),
        }
    }

    /// Uses the portable kernels even where the SIMD ones could run (tests).
    #[cfg(test)]
    pub fn force_portable(&mut self, portable: bool) {
        self.simd = !portable && V::simd_available();
    }

    /// Fills the factor from faer's supernodal values `l` of `A = L Lᵀ` (its layout: per
    /// supernode, the `(w + m) × w` block column-major) and `A`'s diagonal. Returns false if a
    /// scaled entry is not finite or the diagonal not positive (then the factor must not be
    /// used).
    pub fn fill(
        &mut self,
        sn: &SymbolicSupernodalCholesky<u32>,
        l: &[V::Acc],
        diag: impl Fn(usize) -> f64,
    ) -> bool {
        for (i, d) in self.scale.iter_mut().enumerate() {
            let a = diag(i);
            if !(a > 0.0 && a.is_finite()) {
                return false;
            }
            *d = V::Acc::from_f64(1.0 / a.sqrt());
        }
        let mut ok = true;
        for (k, node) in self.nodes.iter().enumerate() {
            let (s, w, m) = (node.start as usize, node.width as usize, node.m as usize);
            let src = &l[sn.col_ptr_for_val()[k] as usize..sn.col_ptr_for_val()[k + 1] as usize];
            let rows = &self.rows[node.rows as usize..][..m];
            // Row scale factors of the block: the diagonal block's rows, then the panel's.
            let tmp = &mut self.tmp[..w + m];
            tmp[..w].copy_from_slice(&self.scale[s..s + w]);
            for (t, &r) in tmp[w..].iter_mut().zip(rows) {
                *t = self.scale[r as usize];
            }
            let (tri, panel) =
                self.vals[node.vals..][..w * (w - 1) / 2 + w * m].split_at_mut(w * (w - 1) / 2);
            let mut at = 0;
            for j in 0..w {
                let col = &src[j * (w + m)..(j + 1) * (w + m)];
                let d = col[j] * tmp[j];
                ok &= d > V::Acc::ZERO && d.finite();
                self.inv_diag[s + j] = V::Acc::ONE / d;
                let below = w - 1 - j;
                V::pack(
                    &mut tri[at..at + below],
                    &col[j + 1..w],
                    &tmp[j + 1..w],
                    self.simd,
                );
                at += below;
                V::pack(
                    &mut panel[j * m..(j + 1) * m],
                    &col[w..],
                    &tmp[w..],
                    self.simd,
                );
            }
        }
        ok
    }

    /// Solves `A x = rhs` in place (`A ≈ L Lᵀ`).
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) {
        for ((x, r), d) in self.x.iter_mut().zip(rhs.iter()).zip(&self.scale) {
            *x = V::Acc::from_f64(*r) * *d;
        }
        if self.simd {
            // SAFETY: `simd` is set only when the CPU has the kernels' features.
            unsafe { V::sweeps_simd(self) };
        } else {
            self.sweeps::<Scalar>();
        }
        for ((r, x), d) in rhs.iter_mut().zip(&self.x).zip(&self.scale) {
            *r = (*x * *d).to_f64();
        }
    }

    /// Forward (`L̂ y = x`) and backward (`L̂ᵀ x = y`) substitution on `x`.
    #[inline(always)]
    fn sweeps<K: Kernels<V>>(&mut self) {
        let x = &mut self.x[..];
        let vals = &self.vals[..];
        // The `len` values from `at`, and the padding up to a multiple of eight (the kernels'
        // contract; `vals` has eight spare values at its end).
        let col = |at: usize, len: usize| &vals[at..at + len.next_multiple_of(8)];
        for node in &self.nodes {
            let (s, w, m) = (node.start as usize, node.width as usize, node.m as usize);
            let panel = node.vals + w * (w - 1) / 2;
            let rows = &self.rows[node.rows as usize..][..m];
            let top = &mut x[s..s + w];
            let mut at = node.vals;
            for j in 0..w {
                let xj = top[j] * self.inv_diag[s + j];
                top[j] = xj;
                let below = w - 1 - j;
                K::axpy(&mut top[j + 1..], -xj, col(at, below));
                at += below;
            }
            let acc = &mut self.tmp[..m];
            acc.fill(V::Acc::ZERO);
            let mut j = 0;
            while j + 4 <= w {
                let c = |k: usize| col(panel + (j + k) * m, m);
                let a = [top[j], top[j + 1], top[j + 2], top[j + 3]];
                K::axpy4(acc, a, [c(0), c(1), c(2), c(3)]);
                j += 4;
            }
            while j < w {
                K::axpy(acc, top[j], col(panel + j * m, m));
                j += 1;
            }
            for (a, &r) in acc.iter().zip(rows) {
                x[r as usize] -= *a;
            }
        }
        for node in self.nodes.iter().rev() {
            let (s, w, m) = (node.start as usize, node.width as usize, node.m as usize);
            let panel = node.vals + w * (w - 1) / 2;
            let rows = &self.rows[node.rows as usize..][..m];
            let got = &mut self.tmp[..m];
            for (g, &r) in got.iter_mut().zip(rows) {
                *g = x[r as usize];
            }
            let top = &mut x[s..s + w];
            let mut j = 0;
            while j + 4 <= w {
                let c = |k: usize| col(panel + (j + k) * m, m);
                let d = K::dot4([c(0), c(1), c(2), c(3)], got);
                for k in 0..4 {
                    top[j + k] -= d[k];
                }
                j += 4;
            }
            while j < w {
                top[j] -= K::dot(col(panel + j * m, m), got);
                j += 1;
            }
            let mut at = panel;
            for j in (0..w).rev() {
                let below = w - 1 - j;
                at -= below;
                let d = K::dot(col(at, below), &top[j + 1..]);
                top[j] = (top[j] - d) * self.inv_diag[s + j];
            }
        }
    }
}

/// `dst[i] = f16(src[i] · scale[i])`.
fn convert_scaled(dst: &mut [u16], src: &[f32], scale: &[f32], simd: bool) {
    #[cfg(target_arch = "x86_64")]
    if simd {
        // SAFETY: `simd` is set only when the CPU has AVX2, FMA and F16C.
        unsafe { avx2::convert_scaled(dst, src, scale) };
        return;
    }
    let _ = simd;
    for ((d, s), c) in dst.iter_mut().zip(src).zip(scale) {
        *d = f32_to_f16(s * c);
    }
}

/// The vector kernels of the sweeps, on columns of stored values `V` and vectors of `V::Acc`.
/// The columns `x` hold at least `n` values rounded up to a multiple of eight, where `n` is
/// the length of the vector `y`; only the first `n` count (the others must be finite).
trait Kernels<V: Value> {
    /// `y += a x`.
    fn axpy(y: &mut [V::Acc], a: V::Acc, x: &[V]);
    /// `y += Σₖ aₖ xₖ`.
    fn axpy4(y: &mut [V::Acc], a: [V::Acc; 4], x: [&[V]; 4]);
    /// `xᵀ y`.
    fn dot(x: &[V], y: &[V::Acc]) -> V::Acc;
    /// `xₖᵀ y` for each `k`.
    fn dot4(x: [&[V]; 4], y: &[V::Acc]) -> [V::Acc; 4];
}

/// Portable kernels.
struct Scalar;

impl<V: Value> Kernels<V> for Scalar {
    #[inline(always)]
    fn axpy(y: &mut [V::Acc], a: V::Acc, x: &[V]) {
        for (y, &x) in y.iter_mut().zip(x) {
            *y += a * x.widen();
        }
    }
    #[inline(always)]
    fn axpy4(y: &mut [V::Acc], a: [V::Acc; 4], x: [&[V]; 4]) {
        assert!(x.iter().all(|x| x.len() >= y.len()));
        for (i, y) in y.iter_mut().enumerate() {
            *y += a[0] * x[0][i].widen()
                + a[1] * x[1][i].widen()
                + a[2] * x[2][i].widen()
                + a[3] * x[3][i].widen();
        }
    }
    #[inline(always)]
    fn dot(x: &[V], y: &[V::Acc]) -> V::Acc {
        y.iter().zip(x).map(|(&y, &x)| x.widen() * y).sum()
    }
    #[inline(always)]
    fn dot4(x: [&[V]; 4], y: &[V::Acc]) -> [V::Acc; 4] {
        x.map(|x| <Self as Kernels<V>>::dot(x, y))
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2;

/// binary16 bits of `x`, rounded to nearest (ties to even); overflow gives ±∞.
pub(crate) fn f32_to_f16(x: f32) -> u16 {
    let b = x.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    let a = b & 0x7fff_ffff;
    if a > 0x7f80_0000 {
        return sign | 0x7e00; // NaN
    }
    if a >= 0x4780_0000 {
        return sign | 0x7c00; // |x| ≥ 65536 (and ∞): ∞
    }
    if a >= 0x3880_0000 {
        // Normal in binary16 (|x| ≥ 2⁻¹⁴): rebias the exponent (127 → 15) and round the
        // mantissa from 23 to 10 bits; a carry moves into the exponent (up to ∞), as it should.
        let r = a - 0x3800_0000;
        let r = r + 0x0fff + ((r >> 13) & 1);
        return sign | (r >> 13) as u16;
    }
    // Subnormal or zero: a multiple of 2⁻²⁴ (the scaling by 2²⁴ is exact).
    sign | (f32::from_bits(a) * 16_777_216.0).round_ties_even() as u16
}

/// The `f32` value of binary16 bits.
pub(crate) fn f16_to_f32(h: u16) -> f32 {
    let sign = u32::from(h & 0x8000) << 16;
    let a = u32::from(h & 0x7fff);
    if a >= 0x7c00 {
        return f32::from_bits(sign | 0x7f80_0000 | ((a & 0x3ff) << 13));
    }
    if a >= 0x0400 {
        return f32::from_bits(sign | ((a << 13) + 0x3800_0000));
    }
    let v = a as f32 * (1.0 / 16_777_216.0);
    if sign != 0 {
        -v
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lop_test_support::rng::Rng;

    #[test]
    fn conversions_round_trip_and_round_to_nearest_even() {
        for h in 0..=u16::MAX {
            let x = f16_to_f32(h);
            if x.is_nan() {
                assert!(f32_to_f16(x) & 0x7c00 == 0x7c00 && f32_to_f16(x) & 0x3ff != 0);
            } else {
                assert_eq!(f32_to_f16(x), h, "{h:#06x} -> {x:e}");
            }
        }
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0xc000), -2.0);
        // Halfway between 1 and 1 + 2⁻¹⁰: ties to even (1); just above: up.
        assert_eq!(f32_to_f16(1.0 + 2f32.powi(-11)), 0x3c00);
        assert_eq!(f32_to_f16(1.0 + 2f32.powi(-11) + 2f32.powi(-20)), 0x3c01);
        assert_eq!(f32_to_f16(1.0 + 3.0 * 2f32.powi(-11)), 0x3c02);
        assert_eq!(f32_to_f16(65504.0), 0x7bff);
        assert_eq!(f32_to_f16(65520.0), 0x7c00);
        assert_eq!(f32_to_f16(1e-9), 0);
        assert_eq!(f32_to_f16(3.0 * 2f32.powi(-25)), 0x0002);
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn simd_conversion_matches_scalar() {
        if !<u16 as Value>::simd_available() {
            return;
        }
        let mut src = Vec::new();
        let mut rng = Rng::new(0x1234_5678);
        for _ in 0..4099 {
            let s = (rng.next_u64() >> 32) as u32;
            let e = (s % 40) as i32 - 30;
            src.push(((s >> 8) as f32 / 16_777_216.0 - 0.5) * 2f32.powi(e));
        }
        let scale = vec![1.5f32; src.len()];
        let mut a = vec![0u16; src.len()];
        let mut b = vec![0u16; src.len()];
        convert_scaled(&mut a, &src, &scale, true);
        convert_scaled(&mut b, &src, &scale, false);
        assert_eq!(a, b);
    }

    /// The kernels of one value type against a double-precision reference: SIMD (where the
    /// CPU has it) and portable, `dot`/`dot4`/`axpy`/`axpy4`, on 37 values (tails included).
    fn kernels_agree_for<V: Value>(to: impl Fn(f64) -> V, tol: f64)
    where
        Scalar: Kernels<V>,
        avx2_or_scalar::K: Kernels<V>,
    {
        let n: usize = 37;
        let col = |k: usize| -> Vec<V> {
            (0..n.next_multiple_of(8))
                .map(|i| match i < n {
                    true => to(((i * 7 + k * 3) % 11) as f64 / 8.0 - 0.6),
                    false => to(1.0),
                })
                .collect()
        };
        let cols: Vec<Vec<V>> = (0..4).map(col).collect();
        let y: Vec<V::Acc> = (0..n)
            .map(|i| V::Acc::from_f64((i as f64 * 0.37).sin()))
            .collect();
        let a = [0.5, -1.25, 2.0, 0.75].map(V::Acc::from_f64);
        let x4 = [&cols[0][..], &cols[1][..], &cols[2][..], &cols[3][..]];
        let want_dot = x4.map(|c| {
            c.iter()
                .zip(&y)
                .map(|(&c, y)| c.widen().to_f64() * y.to_f64())
                .sum::<f64>()
        });
        let want_axpy = |terms: usize| -> Vec<f64> {
            (0..n)
                .map(|i| {
                    y[i].to_f64()
                        + (0..terms)
                            .map(|k| a[k].to_f64() * cols[k][i].widen().to_f64())
                            .sum::<f64>()
                })
                .collect()
        };
        let want = Want {
            dot: want_dot,
            axpy: want_axpy(1),
            axpy4: want_axpy(4),
            tol,
        };
        want.check::<V, Scalar>(x4, &y, a);
        if V::simd_available() {
            want.check::<V, avx2_or_scalar::K>(x4, &y, a);
        }
    }

    /// Reference results of the kernels (double precision) and the tolerance.
    struct Want {
        dot: [f64; 4],
        axpy: Vec<f64>,
        axpy4: Vec<f64>,
        tol: f64,
    }

    impl Want {
        fn check<V: Value, K: Kernels<V>>(&self, x4: [&[V]; 4], y: &[V::Acc], a: [V::Acc; 4]) {
            let close = |got: V::Acc, want: f64| (got.to_f64() - want).abs() < self.tol;
            assert!(close(K::dot(x4[0], y), self.dot[0]));
            let d4 = K::dot4(x4, y);
            for k in 0..4 {
                assert!(close(d4[k], self.dot[k]));
            }
            let mut y1 = y.to_vec();
            K::axpy(&mut y1, a[0], x4[0]);
            let mut y4 = y.to_vec();
            K::axpy4(&mut y4, a, x4);
            for i in 0..y.len() {
                assert!(close(y1[i], self.axpy[i]));
                assert!(close(y4[i], self.axpy4[i]));
            }
        }
    }

    /// The SIMD kernels where they exist (the portable ones again elsewhere).
    mod avx2_or_scalar {
        #[cfg(target_arch = "x86_64")]
        pub(super) type K = super::super::avx2::Avx2;
        #[cfg(not(target_arch = "x86_64"))]
        pub(super) type K = super::super::Scalar;
    }

    #[test]
    fn kernels_agree() {
        kernels_agree_for::<u16>(|x| f32_to_f16(x as f32), 1e-5);
        kernels_agree_for::<f64>(|x| x, 1e-13);
    }
}
