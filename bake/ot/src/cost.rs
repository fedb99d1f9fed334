//! Transport costs, the metric of the domain, and deterministic parallel sums.
//!
//! Floating-point addition is not associative, so a sum whose grouping depends on rayon's work
//! splitting changes bits with the thread count. Every sum here adds fixed-size chunks in a fixed
//! order: the same bits for any thread count.
//!
//! The metric is the one place the domain's [`Wrap`] enters the solvers. On the flat torus
//! (`Wrap::Periodic`, period 1 per axis) the cost is the squared distance to the nearest image,
//! `c(x, y) = min_{m ∈ ℤ^d} |y + m − x|²`; it separates by axis. Here: the shortest displacement
//! ([`delta`]), the squared distance ([`sq_dist_in`], [`sq`]), lifts ([`lift`]), and the images of a
//! query ([`Images`]) through which any Euclidean lower bound over a box (the Sinkhorn kernel's
//! truncation bounds) becomes a torus one: the minimum over the 3^d shifts of the box, restricted to
//! the 2^d that can be nearest.

use otbake_formats::Wrap;
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

pub(crate) use otbake_formats::torus::delta;

/// Squared distance between two `f32` points in the domain's metric, in f64.
#[inline]
pub(crate) fn sq_dist_in(wrap: Wrap, a: &[f32], b: &[f32]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = delta(wrap, f64::from(x), f64::from(y));
            d * d
        })
        .sum()
}

/// Squared distance between two fixed-size points in the domain's metric.
#[inline]
pub(crate) fn sq<const D: usize>(wrap: Wrap, a: &[f64; D], b: &[f64; D]) -> f64 {
    let mut s = 0.0;
    for k in 0..D {
        let d = delta(wrap, a[k], b[k]);
        s += d * d;
    }
    s
}

/// The images `x − m` of a query point `x ∈ [0,1)^d` among which the nearest image of every point
/// of `[0,1)^d` lies, each with its squared norm: `x` alone when clamped; on the torus `x_k` or the
/// one across the far border per axis (`x_k + 1` below ½, `x_k − 1` from ½ on), `2^d` images.
///
/// This is the torus hook of box lower bounds: since `c(x, y) = min_m |x − m − y|²` and the
/// minimum is attained among these images for `y ∈ [0,1)^d`, any Euclidean lower bound over a box
/// of such `y` (a gap, an affine minorant) becomes a torus lower bound by taking its minimum over
/// the images ([`Images::min_of`]) — the minimum over the 3^d shifts, restricted to the ones that
/// can win.
pub(crate) struct Images<const D: usize> {
    at: [([f64; D], f64); 16],
    len: usize,
}

impl<const D: usize> Images<D> {
    /// The images of `x` (`D <= 4`).
    pub(crate) fn of(x: &[f64; D], wrap: Wrap) -> Self {
        let norm = |p: &[f64; D]| p.iter().map(|v| v * v).sum::<f64>();
        let mut at = [(*x, norm(x)); 16];
        let len = match wrap {
            Wrap::Clamp => 1,
            Wrap::Periodic => {
                for (code, slot) in at.iter_mut().enumerate().take(1 << D) {
                    let p: [f64; D] = std::array::from_fn(|k| {
                        if code >> k & 1 == 0 {
                            x[k]
                        } else if x[k] < 0.5 {
                            x[k] + 1.0
                        } else {
                            x[k] - 1.0
                        }
                    });
                    *slot = (p, norm(&p));
                }
                1 << D
            }
        };
        Self { at, len }
    }

    /// The smallest `f(image, |image|²)` over the images (for one image: `f(x, |x|²)` itself).
    #[inline]
    pub(crate) fn min_of(&self, f: impl Fn(&[f64; D], f64) -> f64) -> f64 {
        self.at[..self.len]
            .iter()
            .map(|(p, p2)| f(p, *p2))
            .fold(f64::INFINITY, f64::min)
    }
}

/// Maps a torus map's images to their lifts: point `i` of `mapped` becomes `source_i + δ_i`, `δ_i`
/// the shortest displacement to it ([`delta`]), so `|δ_i|` ≤ ½ per axis and interpolating the lifts
/// follows the geodesic. (Archives of periodic maps store lifts; see `otbake_formats::Wrap`.)
pub(crate) fn lift(dim: usize, source: &[f32], mapped: &mut [f32]) {
    mapped
        .par_chunks_mut(dim)
        .zip(source.par_chunks(dim))
        .for_each(|(m, s)| {
            otbake_formats::torus::lift_point(s, m);
        });
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
    use crate::rng::SplitMix64;

    /// The squared torus distance by brute force: the minimum over the 3^d shifts of `b`.
    fn brute_torus_sq(a: &[f64], b: &[f64]) -> f64 {
        let d = a.len();
        (0..3usize.pow(d as u32))
            .map(|code| {
                let mut rest = code;
                let mut s = 0.0;
                for k in 0..d {
                    let m = (rest % 3) as f64 - 1.0;
                    rest /= 3;
                    s += (b[k] + m - a[k]).powi(2);
                }
                s
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Torus distances equal the brute-force minimum over the 3^d images, and box bounds never
    /// exceed (and, for sampled boxes, nearly reach) the brute-force minimum over their points.
    #[test]
    fn torus_distance_and_box_bounds_equal_brute_force() {
        let mut rng = SplitMix64::new(5);
        for d in 1..=3usize {
            for it in 0..2000 {
                let a: Vec<f64> = (0..d).map(|_| rng.next_f64()).collect();
                let b: Vec<f64> = (0..d).map(|_| rng.next_f64()).collect();
                let brute = brute_torus_sq(&a, &b);
                let af: Vec<f32> = a.iter().map(|&v| v as f32).collect();
                let bf: Vec<f32> = b.iter().map(|&v| v as f32).collect();
                let widen = |v: &[f32]| -> Vec<f64> { v.iter().map(|&x| f64::from(x)).collect() };
                let exact_f32 = brute_torus_sq(&widen(&af), &widen(&bf));
                assert!((sq_dist_in(Wrap::Periodic, &af, &bf) - exact_f32).abs() < 1e-15);
                assert!((sq_dist_in(Wrap::Clamp, &af, &bf) - sq_dist(&af, &bf)).abs() < 1e-15);
                let a3: [f64; 1] = [a[0]];
                let b3: [f64; 1] = [b[0]];
                let one = sq(Wrap::Periodic, &a3, &b3);
                let t = (a[0] - b[0]).abs();
                assert!((one - t.min(1.0 - t).powi(2)).abs() < 1e-15);
                assert!(brute <= d as f64 / 4.0 + 1e-12);
                // The shortest displacement reaches the nearest image, within half a period.
                for k in 0..d {
                    let dl = delta(Wrap::Periodic, a[k], b[k]);
                    assert!((-0.5..0.5).contains(&dl));
                    let m = (a[k] + dl - b[k]).round();
                    assert!((a[k] + dl - (b[k] + m)).abs() < 1e-12);
                }

                // Boxes: random corners, points sampled inside both (a grid of them: every 8th case).
                if it % 8 != 0 {
                    continue;
                }
                let boxes = |rng: &mut SplitMix64| -> (Vec<f64>, Vec<f64>) {
                    let lo: Vec<f64> = (0..d).map(|_| rng.next_f64()).collect();
                    let hi: Vec<f64> = lo
                        .iter()
                        .map(|&l| l + (1.0 - l) * rng.next_f64().powi(3))
                        .collect();
                    (lo, hi)
                };
                let (blo, bhi) = boxes(&mut rng);
                let got = match d {
                    1 => torus_box_gap2::<1>(&a, &blo, &bhi),
                    2 => torus_box_gap2::<2>(&a, &blo, &bhi),
                    _ => torus_box_gap2::<3>(&a, &blo, &bhi),
                };
                // Brute force: the nearest of the 3^d shifted boxes, and points sampled in the box.
                let mut shifted = f64::INFINITY;
                for code in 0..3usize.pow(d as u32) {
                    let mut rest = code;
                    let mut s = 0.0;
                    for k in 0..d {
                        let m = (rest % 3) as f64 - 1.0;
                        rest /= 3;
                        let gap = (blo[k] + m - a[k]).max(a[k] - bhi[k] - m).max(0.0);
                        s += gap * gap;
                    }
                    shifted = shifted.min(s);
                }
                assert!((got - shifted).abs() < 1e-12, "{got} vs {shifted}");
                let g = 9usize;
                let mut best = f64::INFINITY;
                for c in 0..g.pow(d as u32) {
                    let mut rest = c;
                    let y: Vec<f64> = (0..d)
                        .map(|k| {
                            let t = (rest % g) as f64 / (g - 1) as f64;
                            rest /= g;
                            (blo[k] + t * (bhi[k] - blo[k])).min(0.999_999_999)
                        })
                        .collect();
                    best = best.min(
                        (0..d)
                            .map(|k| {
                                let t = (a[k] - y[k]).abs();
                                t.min(1.0 - t).powi(2)
                            })
                            .sum(),
                    );
                }
                assert!(got <= best + 1e-12, "bound {got} > {best}");
                let step: f64 = (0..d).map(|k| (bhi[k] - blo[k]) / (g - 1) as f64).sum();
                assert!(
                    best.sqrt() <= got.sqrt() + step + 1e-9,
                    "bound {got} vs {best}"
                );
                if d == 3 {
                    break;
                }
            }
        }
    }

    /// Squared Euclidean distance from `x` to the box [`lo`, `hi`] (0 inside).
    fn box_gap2<const D: usize>(x: &[f64; D], lo: &[f64; D], hi: &[f64; D]) -> f64 {
        let mut s = 0.0;
        for k in 0..D {
            let gap = (lo[k] - x[k]).max(x[k] - hi[k]).max(0.0);
            s += gap * gap;
        }
        s
    }

    /// The torus distance from `x` to a box: the minimum over the query's images of the Euclidean
    /// gap (what the kernel's bounds are built on).
    fn torus_box_gap2<const D: usize>(x: &[f64], lo: &[f64], hi: &[f64]) -> f64 {
        let arr = |v: &[f64]| -> [f64; D] { std::array::from_fn(|k| v[k]) };
        let (x, lo, hi) = (arr(x), arr(lo), arr(hi));
        Images::of(&x, Wrap::Periodic).min_of(|p, _| box_gap2(p, &lo, &hi))
    }

    /// For points of [0,1)^d, the nearest image is among the query's images.
    #[test]
    fn images_hold_the_nearest_image() {
        let mut rng = SplitMix64::new(9);
        for _ in 0..5000 {
            let x = [rng.next_f64(), rng.next_f64()];
            let y = [rng.next_f64(), rng.next_f64()];
            let via = Images::of(&x, Wrap::Periodic).min_of(|p, _| sq(Wrap::Clamp, p, &y));
            assert!((via - sq(Wrap::Periodic, &x, &y)).abs() < 1e-15);
            let one = Images::of(&x, Wrap::Clamp).min_of(|p, p2| {
                assert_eq!(p2, p[0] * p[0] + p[1] * p[1]);
                sq(Wrap::Clamp, p, &y)
            });
            assert_eq!(one, sq(Wrap::Clamp, &x, &y));
        }
    }

    #[test]
    fn lifts_are_nearest_images() {
        let source = [0.05f32, 0.9, 0.5, 0.5];
        let mut mapped = [0.95f32, 0.1, 0.2, 0.99];
        lift(2, &source, &mut mapped);
        let want = [-0.05f32, 1.1, 0.2, 0.99];
        for (m, w) in mapped.iter().zip(want) {
            assert!((m - w).abs() < 1e-6, "{mapped:?}");
        }
    }

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
