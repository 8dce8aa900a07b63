//! The cage model's hot loop: node displacements from cage displacements.
//!
//! Green coordinates reproduce the rest shape exactly (`X = Σ φᵢ Vᵢ + Σ ψⱼ nⱼ`), so a node's
//! displacement is the same sum over the *changes* of the cage:
//! `x − X = Σ φᵢ (vᵢ' − Vᵢ) + Σ ψⱼ (sⱼ n(tⱼ') − n(tⱼ))`. Displacements are millimetres where
//! positions are tenths of metres, so single precision is plenty here (relative error ~1e-7 of
//! the displacement, below a nanometre) while it halves the memory streamed and doubles the
//! lanes per instruction. Held nodes have all-zero coefficients: they never move.
//!
//! Points are grouped in panels of [`LANES`]; a panel stores its columns (φ columns then ψ
//! columns) one after the other, each holding the panel's points contiguously, so the loop keeps
//! `3 × LANES` accumulators in registers while streaming one contiguous block. On x86-64 CPUs
//! with AVX2 and FMA (checked at run time) the same loop is compiled for them.

use crate::gc::GcBinding;

/// Points per panel: 4 AVX registers per coordinate, enough independent chains to hide the
/// latency of fused multiply-adds.
const LANES: usize = 32;

/// Single-precision coefficients of every node, in panels.
#[derive(Debug, Clone)]
pub(super) struct Kernel {
    points: usize,
    columns: usize,
    coef: Vec<f32>,
    fast: bool,
}

impl Kernel {
    /// From a binding; nodes with `held[k]` get zero coefficients.
    pub(super) fn new(binding: &GcBinding, held: &[bool]) -> Kernel {
        let points = binding.point_count();
        let (nv, nt) = (binding.vertex_count(), binding.triangle_count());
        let columns = nv + nt;
        let mut coef = vec![0.0f32; points.div_ceil(LANES) * columns * LANES];
        for (p, _) in held.iter().enumerate().filter(|(_, &h)| !h) {
            let base = (p / LANES) * columns * LANES + p % LANES;
            for i in 0..nv {
                coef[base + i * LANES] = binding.phi(p, i) as f32;
            }
            for j in 0..nt {
                coef[base + (nv + j) * LANES] = binding.psi(p, j) as f32;
            }
        }
        Kernel {
            points,
            columns,
            coef,
            fast: has_avx2_fma(),
        }
    }

    /// `out[p] = Σ_c coef[p][c] · w[c]`: `w` holds the cage-vertex displacements, then the
    /// changes of the scaled normals (one per column).
    pub(super) fn apply(&self, w: &[[f32; 3]], out: &mut [[f32; 3]]) {
        assert_eq!(w.len(), self.columns, "one weight per column");
        assert_eq!(out.len(), self.points, "one output per point");
        #[cfg(target_arch = "x86_64")]
        if self.fast {
            // SAFETY: `fast` is set only when the CPU reports AVX2 and FMA.
            unsafe { apply_avx2(&self.coef, self.columns, w, out) };
            return;
        }
        apply_generic(&self.coef, self.columns, w, out);
    }
}

fn has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn apply_avx2(coef: &[f32], columns: usize, w: &[[f32; 3]], out: &mut [[f32; 3]]) {
    apply_panels::<true>(coef, columns, w, out);
}

fn apply_generic(coef: &[f32], columns: usize, w: &[[f32; 3]], out: &mut [[f32; 3]]) {
    apply_panels::<false>(coef, columns, w, out);
}

#[inline(always)]
fn apply_panels<const FMA: bool>(
    coef: &[f32],
    columns: usize,
    w: &[[f32; 3]],
    out: &mut [[f32; 3]],
) {
    let panel_len = columns * LANES;
    for (panel, out) in coef.chunks_exact(panel_len).zip(out.chunks_mut(LANES)) {
        let mut x = [0.0f32; LANES];
        let mut y = [0.0f32; LANES];
        let mut z = [0.0f32; LANES];
        let (cols, _) = panel.as_chunks::<LANES>();
        for (c, w) in cols.iter().zip(w) {
            for k in 0..LANES {
                if FMA {
                    x[k] = c[k].mul_add(w[0], x[k]);
                    y[k] = c[k].mul_add(w[1], y[k]);
                    z[k] = c[k].mul_add(w[2], z[k]);
                } else {
                    x[k] += c[k] * w[0];
                    y[k] += c[k] * w[1];
                    z[k] += c[k] * w[2];
                }
            }
        }
        for (k, o) in out.iter_mut().enumerate() {
            *o = [x[k], y[k], z[k]];
        }
    }
}

/// `y += A x` for a dense column-major `A` (`y.len()` rows, `x.len()` columns), in double
/// precision: the cage dynamics' per-step products. Compiled for AVX2 and FMA when the CPU has
/// them (checked once per call; the check is a cached load).
pub(super) fn gemv_acc(a: &[f64], x: &[f64], y: &mut [f64]) {
    assert_eq!(a.len(), x.len() * y.len(), "matrix size");
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: the CPU reports AVX2 and FMA.
        unsafe { gemv_avx2(a, x, y) };
        return;
    }
    gemv_cols::<false>(a, x, y);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn gemv_avx2(a: &[f64], x: &[f64], y: &mut [f64]) {
    gemv_cols::<true>(a, x, y);
}

#[inline(always)]
fn gemv_cols<const FMA: bool>(a: &[f64], x: &[f64], y: &mut [f64]) {
    let m = y.len();
    let fma = |acc: f64, a: f64, b: f64| if FMA { a.mul_add(b, acc) } else { acc + a * b };
    // Four columns per pass over `y`: a quarter of the loads and stores of `y`.
    let mut cols = a.chunks_exact(4 * m);
    let mut xs = x.chunks_exact(4);
    for (block, xj) in (&mut cols).zip(&mut xs) {
        let (c0, rest) = block.split_at(m);
        let (c1, rest) = rest.split_at(m);
        let (c2, c3) = rest.split_at(m);
        for i in 0..m {
            let mut acc = y[i];
            acc = fma(acc, c0[i], xj[0]);
            acc = fma(acc, c1[i], xj[1]);
            acc = fma(acc, c2[i], xj[2]);
            acc = fma(acc, c3[i], xj[3]);
            y[i] = acc;
        }
    }
    for (col, &xj) in cols.remainder().chunks_exact(m).zip(xs.remainder()) {
        for (yi, &aij) in y.iter_mut().zip(col) {
            *yi = fma(*yi, aij, xj);
        }
    }
}
