//! The bench's one quantile definition, and the summaries built on it.
//!
//! **Nearest rank**: the quantile `q` of `n` sorted samples is the `⌈q·n⌉`-th smallest (1-based,
//! at least the first): a value that was measured, never an interpolation, and the same rule
//! the fixed-bucket histograms follow (`cyclictest::Parsed::quantile_us` takes the smallest
//! bucket whose cumulative count reaches `⌈q·n⌉`; `hdrhistogram`'s `value_at_quantile` the
//! same within its 3 significant digits). The median is the exception where a mean of the two
//! middle samples is wanted (`median`).

/// Nearest-rank quantile `q` (0..=1) of ascending `sorted`; 0 when it is empty.
pub fn quantile_sorted(sorted: &[f64], q: f64) -> f64 {
    match nearest_rank(sorted.len(), q) {
        Some(k) => sorted[k],
        None => 0.0,
    }
}

/// The index of the nearest-rank quantile `q` among `n` sorted samples; `None` when `n` is 0.
pub fn nearest_rank(n: usize, q: f64) -> Option<usize> {
    if n == 0 {
        return None;
    }
    let k = (q * n as f64).ceil() as usize;
    Some(k.clamp(1, n) - 1)
}

/// Median of `v` (sorted in place): the middle sample, or the mean of the two middle ones;
/// `None` when empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// Median, p99 (both nearest rank), mean and max of `ns` (sorted in place), in µs; zeros when
/// empty.
pub fn summarize_ns(ns: &mut [u64]) -> (f64, f64, f64, f64) {
    if ns.is_empty() {
        return (0.0, 0.0, 0.0, 0.0);
    }
    ns.sort_unstable();
    let rank = |q: f64| ns[nearest_rank(ns.len(), q).unwrap_or(0)] as f64 / 1000.0;
    let mean = ns.iter().map(|&v| v as f64).sum::<f64>() / ns.len() as f64 / 1000.0;
    (
        rank(0.5),
        rank(0.99),
        mean,
        ns[ns.len() - 1] as f64 / 1000.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_even_and_odd() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median(&mut []), None);
    }

    #[test]
    fn quantile_by_nearest_rank() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile_sorted(&v, 0.99), 99.0);
        assert_eq!(quantile_sorted(&v, 0.5), 50.0);
        assert_eq!(quantile_sorted(&v, 0.0), 1.0);
        assert_eq!(quantile_sorted(&[], 0.5), 0.0);
    }

    #[test]
    fn summaries_by_nearest_rank() {
        let mut ns: Vec<u64> = (1..=100).map(|v| v * 1000).collect();
        let (med, p99, mean, max) = summarize_ns(&mut ns);
        assert_eq!((med, p99, max), (50.0, 99.0, 100.0));
        assert!((mean - 50.5).abs() < 1e-12);
    }
}
