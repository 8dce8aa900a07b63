//! One linear tetrahedron (thesis §4.2, eqs. 4.4–4.15), written with the shape-function
//! gradients instead of an explicit 6×12 `B` matrix.
//!
//! With `N_i = a_i + b_i·x` (eq. 4.4) the gradients `b_i = ∇N_i` are constant over the element:
//! rows 1..3 of `Dm⁻¹`, where `Dm = [X₁−X₀, X₂−X₀, X₃−X₀]` holds the rest edges, and
//! `b₀ = −(b₁+b₂+b₃)`. Everything the thesis builds from `B` follows from them:
//!
//! - deformation gradient `F = Σᵢ xᵢ ⊗ bᵢ = Ds Dm⁻¹`;
//! - small strain `ε = sym(∇u) = sym(F) − I` (`B u` of eq. 4.7 in tensor form);
//! - stress `σ = λ tr(ε) I + 2μ ε` (eq. 4.9), with `λ = Eν/((1+ν)(1−2ν))`,
//!   `μ = E/(2(1+ν))` — the product in `λ`, not the sum printed in eq. 4.10;
//! - internal force on node `i`, `(K_e u)_i = V σ bᵢ`, and the 3×3 stiffness block
//!   `K_ij = V (λ bᵢ bⱼᵀ + μ bⱼ bᵢᵀ + μ (bᵢ·bⱼ) I)`, which is `V Bᵀ C B` (eq. 4.15) regrouped
//!   by node pairs.
//!
//! The corotational (warped) element rotates the rest frame by `R`: its force is
//! `R K_e (Rᵀx − X)`, i.e. the stress of `ε = sym(RᵀF) − I` pushed forward by `R`, and its
//! stiffness `R K_e Rᵀ` has blocks of exactly the form above with the rotated gradients
//! `cᵢ = R bᵢ` (because `R (bᵢbⱼᵀ) Rᵀ = (Rbᵢ)(Rbⱼ)ᵀ` and `R I Rᵀ = I`): no 12×12 product is ever
//! formed.

/// 3×3 matrix, row-major: `m[row][col]`.
pub(crate) type Mat3 = [[f64; 3]; 3];

/// Rest data of one tetrahedron.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Element {
    /// Node indices (positively oriented).
    pub nodes: [u32; 4],
    /// Shape-function gradients `bᵢ = ∇Nᵢ` at rest, 1/m.
    pub grad: [[f64; 3]; 4],
    /// Rest volume, m³ (positive).
    pub volume: f64,
}

impl Element {
    /// Builds the element from its rest corners. Returns `None` when the element is degenerate
    /// or inverted: `6V <= 1e-12 · (longest edge)³`, the mesh validator's threshold.
    pub fn new(nodes: [u32; 4], corners: [[f64; 3]; 4]) -> Option<Element> {
        let [x0, x1, x2, x3] = corners;
        let dm = [sub(x1, x0), sub(x2, x0), sub(x3, x0)]; // columns of Dm, stored as rows
                                                          // Dm with columns e1, e2, e3: det = e1 · (e2 × e3).
        let det = dot(dm[0], cross(dm[1], dm[2]));
        let mut longest: f64 = 0.0;
        for a in 0..4 {
            for b in a + 1..4 {
                longest = longest.max(norm(sub(corners[a], corners[b])));
            }
        }
        if !(det > 1e-12 * longest.powi(3)) {
            return None;
        }
        // Rows of Dm⁻¹ are (e2×e3, e3×e1, e1×e2) / det.
        let inv_det = 1.0 / det;
        let b1 = scale(cross(dm[1], dm[2]), inv_det);
        let b2 = scale(cross(dm[2], dm[0]), inv_det);
        let b3 = scale(cross(dm[0], dm[1]), inv_det);
        let b0 = scale(add(add(b1, b2), b3), -1.0);
        Some(Element {
            nodes,
            grad: [b0, b1, b2, b3],
            volume: det / 6.0,
        })
    }

    /// Displacement gradient `∇u = Σᵢ uᵢ ⊗ bᵢ = F − I` for the nodal displacements `u`.
    /// Built from displacements rather than positions, so small strains keep their full
    /// relative precision however far the body is from the origin.
    #[inline]
    pub fn displacement_gradient(&self, u: &[[f64; 3]]) -> Mat3 {
        let mut g = [[0.0; 3]; 3];
        for (k, &n) in self.nodes.iter().enumerate() {
            let u = u[n as usize];
            let b = self.grad[k];
            for r in 0..3 {
                for c in 0..3 {
                    g[r][c] += u[r] * b[c];
                }
            }
        }
        g
    }
}

/// Lamé parameters `(λ, μ)` from Young's modulus and Poisson's ratio.
pub(crate) fn lame(young: f64, poisson: f64) -> (f64, f64) {
    let lambda = young * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson));
    let mu = young / (2.0 * (1.0 + poisson));
    (lambda, mu)
}

/// Stress of the small strain `ε = sym(h)`, where `h` is `∇u` (linear) or `RᵀF − I`
/// (corotational): `σ = λ tr(ε) I + 2μ ε`, symmetric.
#[inline]
pub(crate) fn stress(h: &Mat3, lambda: f64, mu: f64) -> Mat3 {
    let tr = lambda * (h[0][0] + h[1][1] + h[2][2]);
    let mut s = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            s[r][c] = mu * (h[r][c] + h[c][r]);
        }
        s[r][r] += tr;
    }
    s
}

/// The 3×3 stiffness block between element nodes `i` and `j` with (possibly rotated)
/// gradients `ci`, `cj`: `V (λ cᵢ cⱼᵀ + μ cⱼ cᵢᵀ + μ (cᵢ·cⱼ) I)`, with `vl = Vλ`, `vm = Vμ`.
#[inline]
pub(crate) fn stiffness_block(ci: [f64; 3], cj: [f64; 3], vl: f64, vm: f64) -> Mat3 {
    let d = vm * dot(ci, cj);
    let mut k = [[0.0; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            k[a][b] = vl * ci[a] * cj[b] + vm * cj[a] * ci[b];
        }
        k[a][a] += d;
    }
    k
}

/// The element's stiffness applied to the nodal vectors `p` (matrix-free): with
/// `G = Σⱼ pⱼ ⊗ cⱼ`, `(K_e p)ᵢ = (Vλ tr(G) I + Vμ (G + Gᵀ)) cᵢ`, which expands to
/// `Σⱼ K_ij pⱼ` with the blocks of [`stiffness_block`]. The reference for the batched product
/// of `super::batch`, which runs this arithmetic on several elements at once.
#[cfg(test)]
pub(crate) fn apply_stiffness(
    c: &[[f64; 3]; 4],
    vl: f64,
    vm: f64,
    p: &[[f64; 3]; 4],
) -> [[f64; 3]; 4] {
    let mut g = [[0.0; 3]; 3];
    for j in 0..4 {
        for a in 0..3 {
            for b in 0..3 {
                g[a][b] += p[j][a] * c[j][b];
            }
        }
    }
    let tr = vl * (g[0][0] + g[1][1] + g[2][2]);
    let mut s = [[0.0; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            s[a][b] = vm * (g[a][b] + g[b][a]);
        }
        s[a][a] += tr;
    }
    [
        mat_vec(&s, c[0]),
        mat_vec(&s, c[1]),
        mat_vec(&s, c[2]),
        mat_vec(&s, c[3]),
    ]
}

#[inline]
pub(crate) fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `mᵀ v`.
#[inline]
pub(crate) fn mat_t_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `a bᵀ`.
#[inline]
pub(crate) fn mat_mul_t(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] = a[r][0] * b[c][0] + a[r][1] * b[c][1] + a[r][2] * b[c][2];
        }
    }
    m
}

/// `aᵀ b`.
#[inline]
pub(crate) fn mat_t_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            m[r][c] = a[0][r] * b[0][c] + a[1][r] * b[1][c] + a[2][r] * b[2][c];
        }
    }
    m
}

pub(crate) use crate::vec3::{add, cross, dot, norm, scale, sub};

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_tet() -> Element {
        Element::new(
            [0, 1, 2, 3],
            [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [0., 0., 1.]],
        )
        .unwrap()
    }

    #[test]
    fn gradients_reproduce_linear_fields() {
        let corners = [
            [0.1, -0.2, 0.05],
            [1.3, 0.1, -0.2],
            [0.2, 0.9, 0.3],
            [-0.1, 0.2, 1.1],
        ];
        let e = Element::new([0, 1, 2, 3], corners).unwrap();
        // Σ bᵢ = 0, and an affine motion x = A X + t has ∇u = A − I.
        let a = [[1.1, 0.2, -0.3], [0.05, 0.9, 0.1], [0.0, -0.2, 1.3]];
        let u = corners.map(|p| sub(add(mat_vec(&a, p), [0.3, -0.1, 2.0]), p));
        let g = e.displacement_gradient(&u);
        for r in 0..3 {
            let s: f64 = e.grad.iter().map(|b| b[r]).sum();
            assert!(s.abs() < 1e-12);
            for c in 0..3 {
                let want = a[r][c] - if r == c { 1.0 } else { 0.0 };
                assert!((g[r][c] - want).abs() < 1e-12, "{g:?}");
            }
        }
    }

    #[test]
    fn degenerate_and_inverted_are_rejected() {
        let flat = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.], [1., 1., 0.]];
        assert!(Element::new([0, 1, 2, 3], flat).is_none());
        let inverted = [[0., 0., 0.], [0., 1., 0.], [1., 0., 0.], [0., 0., 1.]];
        assert!(Element::new([0, 1, 2, 3], inverted).is_none());
    }

    /// The block formula equals `V Bᵀ C B` built literally from eqs. 4.8, 4.9 and 4.15.
    #[test]
    fn blocks_match_b_transpose_c_b() {
        let e = unit_tet();
        let (l, m) = lame(1000.0, 0.3);
        let mut c = [[0.0; 6]; 6];
        for r in 0..3 {
            for s in 0..3 {
                c[r][s] = l;
            }
            c[r][r] = l + 2.0 * m;
            c[r + 3][r + 3] = m;
        }
        let b_of = |g: [f64; 3]| -> [[f64; 3]; 6] {
            let [b, cc, d] = g;
            [
                [b, 0., 0.],
                [0., cc, 0.],
                [0., 0., d],
                [cc, b, 0.],
                [0., d, cc],
                [d, 0., b],
            ]
        };
        for i in 0..4 {
            for j in 0..4 {
                let (bi, bj) = (b_of(e.grad[i]), b_of(e.grad[j]));
                let k = stiffness_block(e.grad[i], e.grad[j], e.volume * l, e.volume * m);
                for a in 0..3 {
                    for b in 0..3 {
                        let mut want = 0.0;
                        for p in 0..6 {
                            for q in 0..6 {
                                want += bi[p][a] * c[p][q] * bj[q][b];
                            }
                        }
                        want *= e.volume;
                        assert!((k[a][b] - want).abs() < 1e-9, "{i}{j} {a}{b}");
                    }
                }
            }
        }
    }

    #[test]
    fn matrix_free_product_matches_blocks() {
        let e = Element::new(
            [0, 1, 2, 3],
            [[0.1, 0., 0.], [1., 0.2, 0.], [0., 1., 0.3], [0.2, 0., 1.]],
        )
        .unwrap();
        let (vl, vm) = (e.volume * 37.0, e.volume * 11.0);
        let p = [
            [0.3, -1.0, 2.0],
            [0.5, 0.1, -0.7],
            [-1.2, 0.4, 0.9],
            [0.8, 0.6, -0.2],
        ];
        let out = apply_stiffness(&e.grad, vl, vm, &p);
        for i in 0..4 {
            let mut want = [0.0; 3];
            for j in 0..4 {
                want = add(
                    want,
                    mat_vec(&stiffness_block(e.grad[i], e.grad[j], vl, vm), p[j]),
                );
            }
            for a in 0..3 {
                assert!((out[i][a] - want[a]).abs() < 1e-12, "{out:?} {want:?}");
            }
        }
    }

    #[test]
    fn lame_uses_the_product() {
        let (l, m) = lame(140.0, 0.023);
        assert!((l - 140.0 * 0.023 / (1.023 * 0.954)).abs() < 1e-12);
        assert!((m - 140.0 / 2.046).abs() < 1e-12);
    }
}
