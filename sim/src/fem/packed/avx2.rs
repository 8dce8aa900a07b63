//! AVX2 + FMA (+ F16C) kernels: eight `f32` lanes, binary16 converted by `vcvtph2ps`;
//! four `f64` lanes.

use std::arch::x86_64::*;

use super::{f32_to_f16, Kernels, PackedFactor};

pub(super) struct Avx2;

/// The half-precision sweeps with these kernels.
#[target_feature(enable = "avx2,fma,f16c")]
pub(super) unsafe fn sweeps_half(f: &mut PackedFactor<u16>) {
    f.sweeps::<Avx2>();
}

/// The double-precision sweeps with these kernels.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn sweeps_double(f: &mut PackedFactor<f64>) {
    f.sweeps::<Avx2>();
}

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

impl Kernels<u16> for Avx2 {
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

/// Lanes `0..rem` set (all of them for `rem` ≥ 4), for an `f64` vector's tail.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn tail_mask_pd(rem: usize) -> __m256i {
    _mm256_cmpgt_epi64(
        _mm256_set1_epi64x(rem.min(4) as i64),
        _mm256_setr_epi64x(0, 1, 2, 3),
    )
}

#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn hsum_pd(v: __m256d) -> f64 {
    let s = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd(v, 1));
    _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)))
}

/// `y += Σₖ aₖ xₖ` over `K` `f64` columns, each holding at least `y.len()` rounded up to
/// four values.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn axpy_n_pd<const K: usize>(y: &mut [f64], a: [f64; K], x: [&[f64]; K]) {
    let n = y.len();
    assert!(x.iter().all(|x| x.len() >= n.next_multiple_of(4)));
    let va = a.map(|a| _mm256_set1_pd(a));
    let mut i = 0;
    while i < n {
        let rem = n - i;
        // SAFETY: `y` is read and written below `n` (the last vector masked); each column
        // has four readable values at `i` < `n` by the length asserted above.
        unsafe {
            let py = y.as_mut_ptr().add(i);
            let mask = tail_mask_pd(rem);
            let mut v = if rem >= 4 {
                _mm256_loadu_pd(py)
            } else {
                _mm256_maskload_pd(py, mask)
            };
            for k in 0..K {
                v = _mm256_fmadd_pd(va[k], _mm256_loadu_pd(x[k].as_ptr().add(i)), v);
            }
            if rem >= 4 {
                _mm256_storeu_pd(py, v);
            } else {
                _mm256_maskstore_pd(py, mask, v);
            }
        }
        i += 4;
    }
}

/// `xₖᵀ y` for `K` `f64` columns.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn dot_n_pd<const K: usize>(x: [&[f64]; K], y: &[f64]) -> [f64; K] {
    let n = y.len();
    assert!(x.iter().all(|x| x.len() >= n.next_multiple_of(4)));
    let mut s = [_mm256_setzero_pd(); K];
    let mut i = 0;
    // SAFETY: every access is below `n` (the last vector of `y` masked), and each column
    // has at least `n` rounded up to four values.
    unsafe {
        while i < n {
            let vy = if n - i >= 4 {
                _mm256_loadu_pd(y.as_ptr().add(i))
            } else {
                _mm256_maskload_pd(y.as_ptr().add(i), tail_mask_pd(n - i))
            };
            for k in 0..K {
                s[k] = _mm256_fmadd_pd(_mm256_loadu_pd(x[k].as_ptr().add(i)), vy, s[k]);
            }
            i += 4;
        }
    }
    s.map(|s| hsum_pd(s))
}

/// `xᵀ y` for one `f64` column, with four accumulators: the backward sweep's diagonal
/// blocks are a chain of these dots, each waiting for the last, so their latency counts.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn dot_pd(x: &[f64], y: &[f64]) -> f64 {
    let n = y.len();
    assert!(x.len() >= n.next_multiple_of(4));
    let mut s = [_mm256_setzero_pd(); 4];
    let mut i = 0;
    // SAFETY: every access is below `n` (the last vector of `y` masked), and `x` has at
    // least `n` rounded up to four values.
    unsafe {
        let (px, py) = (x.as_ptr(), y.as_ptr());
        while i + 16 <= n {
            for k in 0..4 {
                let v = _mm256_loadu_pd(py.add(i + 4 * k));
                s[k] = _mm256_fmadd_pd(_mm256_loadu_pd(px.add(i + 4 * k)), v, s[k]);
            }
            i += 16;
        }
        let mut k = 0;
        while i < n {
            let vy = if n - i >= 4 {
                _mm256_loadu_pd(py.add(i))
            } else {
                _mm256_maskload_pd(py.add(i), tail_mask_pd(n - i))
            };
            s[k] = _mm256_fmadd_pd(_mm256_loadu_pd(px.add(i)), vy, s[k]);
            k += 1;
            i += 4;
        }
        let s01 = _mm256_add_pd(s[0], s[1]);
        let s23 = _mm256_add_pd(s[2], s[3]);
        hsum_pd(_mm256_add_pd(s01, s23))
    }
}

impl Kernels<f64> for Avx2 {
    #[inline(always)]
    fn axpy(y: &mut [f64], a: f64, x: &[f64]) {
        // SAFETY: only instantiated inside `sweeps_double`, which requires the features.
        unsafe { axpy_n_pd(y, [a], [x]) }
    }
    #[inline(always)]
    fn axpy4(y: &mut [f64], a: [f64; 4], x: [&[f64]; 4]) {
        // SAFETY: as above.
        unsafe { axpy_n_pd(y, a, x) }
    }
    #[inline(always)]
    fn dot(x: &[f64], y: &[f64]) -> f64 {
        // SAFETY: as above.
        unsafe { dot_pd(x, y) }
    }
    #[inline(always)]
    fn dot4(x: [&[f64]; 4], y: &[f64]) -> [f64; 4] {
        // SAFETY: as above.
        unsafe { dot_n_pd(x, y) }
    }
}
