//! Just enough double-double arithmetic (an unevaluated sum `hi + lo` of two `f64`, ~106
//! significant bits) to evaluate the solid angle of a triangle seen from a point very close to
//! one of its edges, where the plain `f64` formula cancels (see `closed_form`).
//!
//! Error-free transformations after Dekker (1971) and Knuth (TAOCP vol. 2); products use
//! Veltkamp splitting, not a fused multiply-add, because the default x86-64 target has no FMA
//! instruction and the software fallback is slow. Valid while no intermediate overflows
//! (magnitudes below ~1e290), far beyond any cage.

/// `hi + lo` with `|lo| ≤ ulp(hi)/2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Dd {
    pub(crate) hi: f64,
    pub(crate) lo: f64,
}

/// `a + b = s + e` exactly (Knuth).
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a + b = s + e` exactly, for `|a| ≥ |b|` or `a = 0` (Dekker).
#[inline]
fn fast_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// `a = hi + lo` with both halves of at most 26 significant bits (Veltkamp).
#[inline]
fn split(a: f64) -> (f64, f64) {
    let c = 134_217_729.0 * a; // 2^27 + 1
    let hi = c - (c - a);
    (hi, a - hi)
}

/// `a · b = p + e` exactly (Dekker).
#[inline]
pub(crate) fn two_prod(a: f64, b: f64) -> Dd {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    Dd { hi: p, lo: e }
}

impl Dd {
    /// Sum, accurate also when `self ≈ −other` (the "IEEE" double-double addition).
    #[inline]
    pub(crate) fn add(self, other: Dd) -> Dd {
        let (s1, s2) = two_sum(self.hi, other.hi);
        let (t1, t2) = two_sum(self.lo, other.lo);
        let (s1, s2) = fast_two_sum(s1, s2 + t1);
        let (hi, lo) = fast_two_sum(s1, s2 + t2);
        Dd { hi, lo }
    }

    /// Difference, as [`Dd::add`].
    #[inline]
    pub(crate) fn sub(self, other: Dd) -> Dd {
        self.add(Dd {
            hi: -other.hi,
            lo: -other.lo,
        })
    }

    /// Product.
    #[inline]
    pub(crate) fn mul(self, other: Dd) -> Dd {
        let p = two_prod(self.hi, other.hi);
        let e = p.lo + (self.hi * other.lo + self.lo * other.hi);
        let (hi, lo) = fast_two_sum(p.hi, e);
        Dd { hi, lo }
    }

    /// Product with an `f64`.
    #[inline]
    pub(crate) fn mul_f64(self, b: f64) -> Dd {
        let p = two_prod(self.hi, b);
        let e = p.lo + self.lo * b;
        let (hi, lo) = fast_two_sum(p.hi, e);
        Dd { hi, lo }
    }

    /// Square root of a non-negative value (one Newton correction of the `f64` root).
    #[inline]
    pub(crate) fn sqrt(self) -> Dd {
        let x = self.hi.sqrt();
        if !(x > 0.0) {
            return Dd { hi: x, lo: 0.0 };
        }
        let sq = two_prod(x, x);
        let r = ((self.hi - sq.hi) - sq.lo + self.lo) / (2.0 * x);
        let (hi, lo) = fast_two_sum(x, r);
        Dd { hi, lo }
    }
}

/// `a · b` of two `f64` vectors, exact up to the final double-double rounding.
#[inline]
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> Dd {
    two_prod(a[0], b[0])
        .add(two_prod(a[1], b[1]))
        .add(two_prod(a[2], b[2]))
}

/// `a × b` of two `f64` vectors, each component exact up to the final double-double rounding.
#[inline]
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [Dd; 3] {
    [
        two_prod(a[1], b[2]).sub(two_prod(a[2], b[1])),
        two_prod(a[2], b[0]).sub(two_prod(a[0], b[2])),
        two_prod(a[0], b[1]).sub(two_prod(a[1], b[0])),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_and_sums_are_exact() {
        let a = 1.0 + f64::EPSILON;
        let p = two_prod(a, a); // 1 + 2ε + ε²
        assert_eq!(p.hi, 1.0 + 2.0 * f64::EPSILON);
        assert_eq!(p.lo, f64::EPSILON * f64::EPSILON);
        let d = p.sub(Dd { hi: 1.0, lo: 0.0 });
        assert_eq!(d.hi, 2.0 * f64::EPSILON);
        assert_eq!(d.lo, f64::EPSILON * f64::EPSILON);
    }

    #[test]
    fn sqrt_is_double_double_accurate() {
        let two = Dd { hi: 2.0, lo: 0.0 };
        let r = two.sqrt();
        let back = r.mul(r).sub(two);
        assert!(back.hi.abs() < 1e-30, "{back:?}");
        assert_eq!(Dd { hi: 0.0, lo: 0.0 }.sqrt().hi, 0.0);
    }

    #[test]
    fn cancelling_cross_product() {
        // (2^27 + 1)(2^27 − 1) − 2^27·2^27 = −1, which plain f64 rounds to 0.
        let (p, m, q) = (134_217_729.0, 134_217_727.0, 134_217_728.0);
        let a = [p, q, 0.0];
        let b = [q, m, 0.0];
        assert_eq!(a[0] * b[1] - a[1] * b[0], 0.0);
        let c = cross(a, b);
        assert_eq!((c[2].hi, c[2].lo), (-1.0, 0.0));
        let d = dot([p, 1.0, 0.0], [m, 0.0, 1.0]); // 2^54 − 1
        assert_eq!((d.hi, d.lo), (18_014_398_509_481_984.0, -1.0));
    }
}
