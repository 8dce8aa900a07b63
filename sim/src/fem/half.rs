//! The corotational preconditioner's Cholesky factor stored in half precision (IEEE binary16),
//! with its own supernodal triangular solves.
//!
//! A preconditioner solve is memory-bound: it streams the factor twice (forward and backward)
//! and does two flops per value read. faer's single-precision factor of the 50k-tetrahedra box
//! is 64 MB, of which 11 MB are the unused upper triangles of the supernodes' dense diagonal
//! blocks. This copy keeps only the lower triangles, in 16-bit floats: 27 MB, under half the
//! traffic.
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
//! Layout, per supernode of `w` columns starting at column `s` with `m` rows below its
//! diagonal block: the strictly lower triangle of the diagonal block, column by column
//! (column `j` holds rows `j+1..w`), then the `m × w` panel below it, column-major. The
//! forward solve is column-oriented (axpys into the top of the vector and into a gathered
//! buffer of the panel's rows, four panel columns at a time); the backward solve is
//! dot products on the same columns.
//!
//! Used for factors of at least `system::HALF_MIN_VALUES` values: smaller ones are solved in
//! single precision (cache-resident, and accurate enough for one-iteration CG steps).
//!
//! The kernels use AVX2, FMA and F16C when the CPU has them (checked at run time), and portable
//! scalar code otherwise.

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;

/// One supernode of the half-precision factor.
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

/// A supernodal Cholesky factor in half precision (see the module docs).
#[derive(Debug, Clone)]
pub(crate) struct HalfFactor {
    nodes: Vec<Supernode>,
    /// Below-diagonal row indices of every supernode, concatenated.
    rows: Vec<u32>,
    /// binary16 bit patterns of the scaled factor's off-diagonal entries.
    vals: Vec<u16>,
    /// Per column: `1 / L̂_jj`.
    inv_diag: Vec<f32>,
    /// Per row: `dᵢ = A_ii^(−½)`.
    scale: Vec<f32>,
    /// Scratch: the vector being solved for (`n`), and a supernode's gathered rows or scale
    /// factors (the largest `w + m`).
    x: Vec<f32>,
    tmp: Vec<f32>,
    simd: bool,
}

impl HalfFactor {
    /// Allocates the factor for this supernodal structure (values unset).
    pub fn new(sn: &SymbolicSupernodalCholesky<u32>) -> HalfFactor {
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
        HalfFactor {
            nodes,
            rows: sn.row_idx().to_vec(),
            // Eight more: the SIMD kernels read a column's last values eight at a time.
            vals: vec![0; vals + 8],
            inv_diag: vec![0.0; n],
            scale: vec![0.0; n],
            x: vec![0.0; n],
            tmp: vec![0.0; widest],
            simd: simd_available(),
        }
    }

    /// Uses the portable kernels even where the SIMD ones could run (tests).
    #[cfg(test)]
    pub fn force_portable(&mut self, portable: bool) {
        self.simd = !portable && simd_available();
    }

    /// Fills the factor from faer's supernodal values `l` of `A = L Lᵀ` (its layout: per
    /// supernode, the `(w + m) × w` block column-major) and `A`'s diagonal. Returns false if a
    /// scaled entry is not finite or the diagonal not positive (then the factor must not be
    /// used).
    pub fn fill(
        &mut self,
        sn: &SymbolicSupernodalCholesky<u32>,
        l: &[f32],
        diag: impl Fn(usize) -> f64,
    ) -> bool {
        for (i, d) in self.scale.iter_mut().enumerate() {
            let a = diag(i);
            if !(a > 0.0 && a.is_finite()) {
                return false;
            }
            *d = (1.0 / a.sqrt()) as f32;
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
                ok &= d > 0.0 && d.is_finite();
                self.inv_diag[s + j] = 1.0 / d;
                let below = w - 1 - j;
                convert_scaled(
                    &mut tri[at..at + below],
                    &col[j + 1..w],
                    &tmp[j + 1..w],
                    self.simd,
                );
                at += below;
                convert_scaled(
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
            *x = *r as f32 * d;
        }
        #[cfg(target_arch = "x86_64")]
        if self.simd {
            // SAFETY: `simd` is set only when the CPU has AVX2, FMA and F16C.
            unsafe { self.sweeps_avx2() };
        } else {
            self.sweeps::<Scalar>();
        }
        #[cfg(not(target_arch = "x86_64"))]
        self.sweeps::<Scalar>();
        for ((r, x), d) in rhs.iter_mut().zip(&self.x).zip(&self.scale) {
            *r = f64::from(x * d);
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn sweeps_avx2(&mut self) {
        self.sweeps::<avx2::Avx2>();
    }

    /// Forward (`L̂ y = x`) and backward (`L̂ᵀ x = y`) substitution on `x`.
    #[inline(always)]
    fn sweeps<K: Kernels>(&mut self) {
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
            acc.fill(0.0);
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
                x[r as usize] -= a;
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

/// Whether the SIMD kernels can run here.
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

/// The vector kernels of the sweeps, on binary16 columns and `f32` vectors. The columns `x`
/// hold at least `n` values rounded up to a multiple of eight, where `n` is the length of the
/// `f32` vector `y`; only the first `n` count (the others must be finite).
trait Kernels {
    /// `y += a x`.
    fn axpy(y: &mut [f32], a: f32, x: &[u16]);
    /// `y += Σₖ aₖ xₖ`.
    fn axpy4(y: &mut [f32], a: [f32; 4], x: [&[u16]; 4]);
    /// `xᵀ y`.
    fn dot(x: &[u16], y: &[f32]) -> f32;
    /// `xₖᵀ y` for each `k`.
    fn dot4(x: [&[u16]; 4], y: &[f32]) -> [f32; 4];
}

/// Portable kernels.
struct Scalar;

impl Kernels for Scalar {
    #[inline(always)]
    fn axpy(y: &mut [f32], a: f32, x: &[u16]) {
        for (y, &x) in y.iter_mut().zip(x) {
            *y += a * f16_to_f32(x);
        }
    }
    #[inline(always)]
    fn axpy4(y: &mut [f32], a: [f32; 4], x: [&[u16]; 4]) {
        assert!(x.iter().all(|x| x.len() >= y.len()));
        for (i, y) in y.iter_mut().enumerate() {
            *y += a[0] * f16_to_f32(x[0][i])
                + a[1] * f16_to_f32(x[1][i])
                + a[2] * f16_to_f32(x[2][i])
                + a[3] * f16_to_f32(x[3][i]);
        }
    }
    #[inline(always)]
    fn dot(x: &[u16], y: &[f32]) -> f32 {
        y.iter().zip(x).map(|(y, &x)| f16_to_f32(x) * y).sum()
    }
    #[inline(always)]
    fn dot4(x: [&[u16]; 4], y: &[f32]) -> [f32; 4] {
        x.map(|x| Self::dot(x, y))
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! AVX2 + FMA + F16C kernels: eight lanes, binary16 converted by `vcvtph2ps`.

    use std::arch::x86_64::*;

    use super::{f32_to_f16, Kernels};

    pub(super) struct Avx2;

    /// Lanes `0..rem` set (all of them for `rem` ≥ 8), for a vector's tail.
    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn tail_mask(rem: usize) -> __m256i {
        _mm256_cmpgt_epi32(
            _mm256_set1_epi32(rem as i32),
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        )
    }

    /// Eight binary16 values from `p` as `f32` lanes.
    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn load8(p: *const u16) -> __m256 {
        // SAFETY: the caller guarantees 8 readable values at `p`.
        unsafe { _mm256_cvtph_ps(_mm_loadu_si128(p.cast())) }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn hsum(v: __m256) -> f32 {
        let s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
        let s = _mm_add_ps(s, _mm_movehl_ps(s, s));
        let s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 1));
        _mm_cvtss_f32(s)
    }

    /// `y += Σₖ aₖ xₖ` over `K` columns, each holding at least `y.len()` rounded up to eight
    /// values.
    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn axpy_n<const K: usize>(y: &mut [f32], a: [f32; K], x: [&[u16]; K]) {
        let n = y.len();
        assert!(x.iter().all(|x| x.len() >= n.next_multiple_of(8)));
        let va = a.map(|a| _mm256_set1_ps(a));
        let mut i = 0;
        while i < n {
            let rem = n - i;
            // SAFETY: `y` is read and written below `n` (the last vector masked); each column
            // has eight readable values at `i` < `n` by the length asserted above.
            unsafe {
                let py = y.as_mut_ptr().add(i);
                let mask = tail_mask(rem);
                let mut v = if rem >= 8 {
                    _mm256_loadu_ps(py)
                } else {
                    _mm256_maskload_ps(py, mask)
                };
                for k in 0..K {
                    v = _mm256_fmadd_ps(va[k], load8(x[k].as_ptr().add(i)), v);
                }
                if rem >= 8 {
                    _mm256_storeu_ps(py, v);
                } else {
                    _mm256_maskstore_ps(py, mask, v);
                }
            }
            i += 8;
        }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn axpy(y: &mut [f32], a: f32, x: &[u16]) {
        // SAFETY: the caller runs on a CPU with these features.
        unsafe { axpy_n(y, [a], [x]) }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn axpy4(y: &mut [f32], a: [f32; 4], x: [&[u16]; 4]) {
        // SAFETY: as in `axpy`.
        unsafe { axpy_n(y, a, x) }
    }

    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn dot(x: &[u16], y: &[f32]) -> f32 {
        let n = y.len();
        assert!(x.len() >= n.next_multiple_of(8));
        let (mut s0, mut s1) = (_mm256_setzero_ps(), _mm256_setzero_ps());
        let mut i = 0;
        // SAFETY: every access is below `n`.
        unsafe {
            while i + 16 <= n {
                s0 = _mm256_fmadd_ps(
                    load8(x.as_ptr().add(i)),
                    _mm256_loadu_ps(y.as_ptr().add(i)),
                    s0,
                );
                s1 = _mm256_fmadd_ps(
                    load8(x.as_ptr().add(i + 8)),
                    _mm256_loadu_ps(y.as_ptr().add(i + 8)),
                    s1,
                );
                i += 16;
            }
            if i + 8 <= n {
                s0 = _mm256_fmadd_ps(
                    load8(x.as_ptr().add(i)),
                    _mm256_loadu_ps(y.as_ptr().add(i)),
                    s0,
                );
                i += 8;
            }
        }
        if i < n {
            // SAFETY: as in `axpy`; the masked lanes of `y` are zero, and the padding of `x`
            // finite.
            unsafe {
                let vy = _mm256_maskload_ps(y.as_ptr().add(i), tail_mask(n - i));
                s1 = _mm256_fmadd_ps(load8(x.as_ptr().add(i)), vy, s1);
            }
        }
        hsum(_mm256_add_ps(s0, s1))
    }

    #[inline]
    #[target_feature(enable = "avx2,fma,f16c")]
    unsafe fn dot4(x: [&[u16]; 4], y: &[f32]) -> [f32; 4] {
        let n = y.len();
        assert!(x.iter().all(|x| x.len() >= n.next_multiple_of(8)));
        let mut s = [_mm256_setzero_ps(); 4];
        let mut i = 0;
        // SAFETY: every access is below `n`, and each column has at least `n` values.
        unsafe {
            while i + 8 <= n {
                let vy = _mm256_loadu_ps(y.as_ptr().add(i));
                for k in 0..4 {
                    s[k] = _mm256_fmadd_ps(load8(x[k].as_ptr().add(i)), vy, s[k]);
                }
                i += 8;
            }
        }
        if i < n {
            // SAFETY: as in `dot`.
            unsafe {
                let vy = _mm256_maskload_ps(y.as_ptr().add(i), tail_mask(n - i));
                for k in 0..4 {
                    s[k] = _mm256_fmadd_ps(load8(x[k].as_ptr().add(i)), vy, s[k]);
                }
            }
        }
        s.map(|s| hsum(s))
    }

    /// `dst[i] = f16(src[i] · scale[i])`, rounded to nearest even.
    #[target_feature(enable = "avx2,fma,f16c")]
    pub(super) unsafe fn convert_scaled(dst: &mut [u16], src: &[f32], scale: &[f32]) {
        let n = dst.len().min(src.len()).min(scale.len());
        let mut i = 0;
        // SAFETY: every access is below `n`.
        unsafe {
            while i + 8 <= n {
                let v = _mm256_mul_ps(
                    _mm256_loadu_ps(src.as_ptr().add(i)),
                    _mm256_loadu_ps(scale.as_ptr().add(i)),
                );
                let h = _mm256_cvtps_ph::<_MM_FROUND_TO_NEAREST_INT>(v);
                _mm_storeu_si128(dst.as_mut_ptr().add(i).cast(), h);
                i += 8;
            }
        }
        for i in i..n {
            dst[i] = f32_to_f16(src[i] * scale[i]);
        }
    }

    impl Kernels for Avx2 {
        #[inline(always)]
        fn axpy(y: &mut [f32], a: f32, x: &[u16]) {
            // SAFETY: only instantiated inside `sweeps_avx2`, which requires the features.
            unsafe { axpy(y, a, x) }
        }
        #[inline(always)]
        fn axpy4(y: &mut [f32], a: [f32; 4], x: [&[u16]; 4]) {
            // SAFETY: as above.
            unsafe { axpy4(y, a, x) }
        }
        #[inline(always)]
        fn dot(x: &[u16], y: &[f32]) -> f32 {
            // SAFETY: as above.
            unsafe { dot(x, y) }
        }
        #[inline(always)]
        fn dot4(x: [&[u16]; 4], y: &[f32]) -> [f32; 4] {
            // SAFETY: as above.
            unsafe { dot4(x, y) }
        }
    }
}

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
        if !simd_available() {
            return;
        }
        let mut src = Vec::new();
        let mut s = 0x1234_5678u32;
        for _ in 0..4099 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
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

    #[test]
    fn kernels_agree() {
        let n: usize = 37;
        let col = |k: usize| -> Vec<u16> {
            (0..n.next_multiple_of(8))
                .map(|i| match i < n {
                    true => f32_to_f16(((i * 7 + k * 3) % 11) as f32 / 8.0 - 0.6),
                    false => f32_to_f16(1.0),
                })
                .collect()
        };
        let cols: Vec<Vec<u16>> = (0..4).map(col).collect();
        let y: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
        let a = [0.5, -1.25, 2.0, 0.75];
        let x4 = [&cols[0][..], &cols[1][..], &cols[2][..], &cols[3][..]];
        let want_dot = x4.map(|c| {
            c.iter()
                .zip(&y)
                .map(|(&c, y)| f64::from(f16_to_f32(c)) * f64::from(*y))
                .sum::<f64>()
        });
        let mut want_axpy = y.clone();
        for k in 0..4 {
            for i in 0..n {
                want_axpy[i] += a[k] * f16_to_f32(cols[k][i]);
            }
        }
        let check = |dot: f32, dot4: [f32; 4], axpy: Vec<f32>, axpy4: Vec<f32>| {
            assert!((f64::from(dot) - want_dot[0]).abs() < 1e-5);
            for k in 0..4 {
                assert!((f64::from(dot4[k]) - want_dot[k]).abs() < 1e-5);
            }
            for i in 0..n {
                assert!((axpy4[i] - want_axpy[i]).abs() < 1e-5);
                assert!((axpy[i] - (y[i] + a[0] * f16_to_f32(cols[0][i]))).abs() < 1e-6);
            }
        };
        let run = |dot: fn(&[u16], &[f32]) -> f32,
                   dot4: fn([&[u16]; 4], &[f32]) -> [f32; 4],
                   axpy: fn(&mut [f32], f32, &[u16]),
                   axpy4: fn(&mut [f32], [f32; 4], [&[u16]; 4])| {
            let mut y1 = y.clone();
            axpy(&mut y1, a[0], x4[0]);
            let mut y4 = y.clone();
            axpy4(&mut y4, a, x4);
            check(dot(x4[0], &y), dot4(x4, &y), y1, y4);
        };
        run(Scalar::dot, Scalar::dot4, Scalar::axpy, Scalar::axpy4);
        #[cfg(target_arch = "x86_64")]
        if simd_available() {
            run(
                avx2::Avx2::dot,
                avx2::Avx2::dot4,
                avx2::Avx2::axpy,
                avx2::Avx2::axpy4,
            );
        }
    }
}
