//! Transport costs and deterministic parallel sums.
//!
//! Floating-point addition is not associative, so a sum whose grouping depends on rayon's work
//! splitting changes bits with the thread count (NOTES.md). Every sum here adds fixed-size chunks in
//! a fixed order: the same bits for any thread count.

use rayon::prelude::*;

/// Items per partial sum. Fixed, so the grouping of additions never depends on the thread count.
pub(crate) const CHUNK: usize = 4096;

/// Σ_{i<n} f(i), summed in chunks of [`CHUNK`] consecutive indices (each left to right), then the
/// chunk sums left to right. Deterministic for any thread count.
pub(crate) fn det_sum<F>(n: usize, f: F) -> f64
where
    F: Fn(usize) -> f64 + Sync,
{
    let partial: Vec<f64> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let end = ((c + 1) * CHUNK).min(n);
            (c * CHUNK..end).fold(0.0, |acc, i| acc + f(i))
        })
        .collect();
    partial.iter().sum()
}

/// Squared Euclidean distance between two points, in f64.
#[inline]
pub(crate) fn sq_dist(a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = f64::from(x) - f64::from(y);
            d * d
        })
        .sum()
}

/// Mean squared displacement Σ|mapped_i − source_i|²/n (f64, deterministic for any thread count);
/// 0 for empty clouds.
///
/// # Panics
/// If `dim == 0`, the lengths differ, or they are not a multiple of `dim`.
pub fn transport_cost(dim: usize, source: &[f32], mapped: &[f32]) -> f64 {
    assert!(dim > 0, "transport_cost: dim must be at least 1");
    assert_eq!(
        source.len(),
        mapped.len(),
        "transport_cost: source and mapped differ in length"
    );
    assert_eq!(
        source.len() % dim,
        0,
        "transport_cost: length is not a multiple of dim"
    );
    let n = source.len() / dim;
    if n == 0 {
        return 0.0;
    }
    let total = det_sum(n, |i| {
        sq_dist(
            &source[i * dim..(i + 1) * dim],
            &mapped[i * dim..(i + 1) * dim],
        )
    });
    total / n as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn transport_cost_is_mean_squared_displacement() {
        let s = [0.0, 0.0, 1.0, 1.0];
        let m = [3.0, 4.0, 1.0, 1.0];
        assert_eq!(transport_cost(2, &s, &m), 12.5);
        assert_eq!(transport_cost(2, &[], &[]), 0.0);
    }

    #[test]
    fn det_sum_is_thread_count_independent() {
        let f = |i: usize| ((i as f64) * 0.1).sin() * 1e-3 + 1e6 * ((i % 7) as f64);
        let n = 10 * CHUNK + 123;
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(|| det_sum(n, f));
        let four = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap()
            .install(|| det_sum(n, f));
        assert_eq!(one.to_bits(), four.to_bits());
        let sequential: f64 = (0..n).map(f).sum();
        assert!((one - sequential).abs() <= 1e-9 * sequential.abs());
    }
}
