//! Tetrahedron geometry: signed volume, edge lengths and the mean-ratio quality metric.

pub(crate) use crate::vec3::{cross, dot, sub};

/// Six times the signed volume: `(b-a)·((c-a)×(d-a))`.
pub(crate) fn volume6(p: &[[f64; 3]; 4]) -> f64 {
    let [a, b, c, d] = *p;
    dot(sub(b, a), cross(sub(c, a), sub(d, a)))
}

/// The six edges of a tetrahedron as pairs of local corners.
pub(crate) const EDGES: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// Squared lengths of the six edges.
pub(crate) fn edge_lengths2(p: &[[f64; 3]; 4]) -> [f64; 6] {
    EDGES.map(|[i, j]| {
        let e = sub(p[j], p[i]);
        dot(e, e)
    })
}

/// Mean-ratio quality `12 (3|V|)^(2/3) / Σ l²`: 1 for a regular tetrahedron, tending to 0 as
/// it flattens. Invariant under translation, rotation and uniform scaling.
pub(crate) fn mean_ratio(p: &[[f64; 3]; 4]) -> f64 {
    let sum_l2: f64 = edge_lengths2(p).iter().sum();
    if sum_l2 <= 0.0 {
        return 0.0;
    }
    let volume = volume6(p).abs() / 6.0;
    12.0 * (3.0 * volume).powf(2.0 / 3.0) / sum_l2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_tet_has_quality_one() {
        let s = 1.0 / 2f64.sqrt();
        let p = [
            [1.0, 0.0, -s],
            [-1.0, 0.0, -s],
            [0.0, 1.0, s],
            [0.0, -1.0, s],
        ];
        assert!((mean_ratio(&p) - 1.0).abs() < 1e-12);
        // Edge length 2: volume = 8 / (6 sqrt 2).
        let v = volume6(&p).abs() / 6.0;
        assert!((v - 8.0 / (6.0 * 2f64.sqrt())).abs() < 1e-12);
    }

    #[test]
    fn flat_tet_has_quality_zero() {
        let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert_eq!(mean_ratio(&p), 0.0);
        assert_eq!(mean_ratio(&[[0.0; 3]; 4]), 0.0);
    }

    #[test]
    fn unit_corner_tet() {
        let p = [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(volume6(&p), 1.0);
        let q = mean_ratio(&p);
        // 12 * (1/2)^(2/3) / (3 + 3*2)
        assert!((q - 12.0 * 0.5f64.powf(2.0 / 3.0) / 9.0).abs() < 1e-15);
    }
}
