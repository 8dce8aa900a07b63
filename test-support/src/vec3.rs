//! `[f64; 3]` arithmetic for tests, written out component by component (the evaluation order
//! is fixed, so results are bit-for-bit reproducible).

/// `a − b`.
pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a + b`.
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `s a`.
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// `a · b`.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `|a|`.
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `|a − b|`.
pub fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(sub(a, b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identities() {
        let (a, b) = ([1.0, 2.0, 3.0], [-4.0, 0.5, 2.0]);
        assert_eq!(sub(add(a, b), b), a);
        assert_eq!(scale(a, 2.0), add(a, a));
        assert_eq!(dot(a, b), -4.0 + 1.0 + 6.0);
        assert_eq!(dot(cross(a, b), a), 0.0);
        assert_eq!(dot(cross(a, b), b), 0.0);
        assert_eq!(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        assert_eq!(norm([3.0, 4.0, 12.0]), 13.0);
        assert_eq!(dist(a, a), 0.0);
    }
}
