//! Proxy point clouds (paper §4.1, Fig. 3): the common distribution every input is mapped from.
//!
//! Proxies are deterministic: point `i` is a fixed function of Sobol point `i` (scrambled by the
//! seed), so the same `(shape, dim, n, seed)` gives the same bytes on any machine and thread count,
//! and a proxy can be content-hashed like any other asset.

use std::f64::consts::TAU;

use crate::sample::{check_count, map_sobol_points, normal, SampleError, Sobol};

/// Largest dimension a proxy supports (anisotropic BRDFs are 4D).
pub const MAX_PROXY_DIM: usize = 4;

/// Outer radius of the spiral around the square's center; leaves a margin of 0.05 on every side.
pub const SPIRAL_RADIUS: f64 = 0.45;

/// Largest spiral thickness: the band stays inside the unit square.
pub const SPIRAL_MAX_THICKNESS: f64 = 2.0 * (0.5 - SPIRAL_RADIUS);

/// The shape of a proxy distribution over `[0,1]^d`.
#[derive(Clone, Debug, PartialEq)]
pub enum ProxyShape {
    /// Normal with mean 0.5 and standard deviation `sigma` on each axis, independently, truncated
    /// to `[0, 1]` per axis. The paper uses `sigma = 1/6` (the box is then ±3σ).
    Gaussian { sigma: f64 },
    /// Uniform over the unit box.
    Uniform,
    /// A line-shaped 2D proxy: a band of width `thickness` along an Archimedean spiral of `turns`
    /// turns around `(0.5, 0.5)` (paper Fig. 3). See [`proxy_points`] for the parameterization.
    Spiral { turns: f64, thickness: f64 },
}

impl ProxyShape {
    /// The paper's Gaussian proxy: `sigma` = 1/6 of the side.
    pub const DEFAULT_GAUSSIAN: ProxyShape = ProxyShape::Gaussian { sigma: 1.0 / 6.0 };
    /// A spiral of 3 turns and thickness 0.01.
    pub const DEFAULT_SPIRAL: ProxyShape = ProxyShape::Spiral {
        turns: 3.0,
        thickness: 0.01,
    };
}

/// `n` proxy points in `[0,1]^dim`, point-major (`n · dim` values).
///
/// - `Gaussian { sigma }`: axis `k` of point `i` is `0.5 + σ Φ⁻¹(q)` with `q` the Sobol coordinate
///   `u` mapped linearly onto `[Φ(−0.5/σ), Φ(0.5/σ)]` (the exact inverse CDF of the truncated normal).
/// - `Uniform`: the Sobol points themselves.
/// - `Spiral { turns, thickness }` (2D only): with `Θ = 2π·turns` and `b = R/Θ`, `R` =
///   [`SPIRAL_RADIUS`], the center line is `c(θ) = (0.5, 0.5) + bθ (cos θ, sin θ)`, `θ ∈ [0, Θ]`, from
///   the center out to radius `R`. Sobol coordinate `u0` picks the arc length `u0 · L` (`L` the
///   length of the whole curve), so points are uniform along the curve; `u1` offsets the point by
///   `(u1 − ½) · thickness` along the curve's unit normal, so the band is `thickness` wide.
///   `0 <= thickness <=` [`SPIRAL_MAX_THICKNESS`].
pub fn proxy_points(
    shape: &ProxyShape,
    dim: usize,
    n: usize,
    seed: u64,
) -> Result<Vec<f32>, SampleError> {
    if dim == 0 || dim > MAX_PROXY_DIM {
        return Err(SampleError::Dims {
            dims: dim,
            max: MAX_PROXY_DIM,
        });
    }
    check_count(n)?;
    let sobol = Sobol::new(dim, seed)?;
    match *shape {
        ProxyShape::Gaussian { sigma } => {
            if !(sigma.is_finite() && sigma > 0.0) {
                return Err(SampleError::Sigma { sigma });
            }
            let gauss = TruncatedGaussian::new(sigma);
            Ok(map_sobol_points(&sobol, n, dim, |u, p| {
                for (o, &x) in p.iter_mut().zip(u) {
                    *o = gauss.position(x);
                }
            }))
        }
        ProxyShape::Uniform => Ok(map_sobol_points(&sobol, n, dim, |u, p| {
            for (o, &x) in p.iter_mut().zip(u) {
                *o = (x as f32).min(1.0);
            }
        })),
        ProxyShape::Spiral { turns, thickness } => {
            if dim != 2 {
                return Err(SampleError::SpiralDim { dim });
            }
            if !(turns.is_finite() && turns > 0.0) {
                return Err(SampleError::Turns { turns });
            }
            if !(0.0..=SPIRAL_MAX_THICKNESS).contains(&thickness) {
                return Err(SampleError::Thickness {
                    thickness,
                    max: SPIRAL_MAX_THICKNESS,
                });
            }
            let spiral = Spiral::new(turns);
            Ok(map_sobol_points(&sobol, n, dim, |u, p| {
                let [x, y] = spiral.point(u[0], (u[1] - 0.5) * thickness);
                p[0] = x.clamp(0.0, 1.0) as f32;
                p[1] = y.clamp(0.0, 1.0) as f32;
            }))
        }
    }
}

/// A normal (mean 0.5, std `sigma`) truncated to `[0, 1]`, sampled by its inverse CDF.
struct TruncatedGaussian {
    sigma: f64,
    /// `Φ(−0.5/σ)`: the probability cut off below 0 (and, by symmetry, above 1).
    tail: f64,
}

impl TruncatedGaussian {
    fn new(sigma: f64) -> Self {
        TruncatedGaussian {
            sigma,
            tail: normal::cdf(-0.5 / sigma),
        }
    }

    /// Position of the uniform variate `u ∈ [0, 1)`. The upper half is mirrored onto the lower
    /// tail, where `Φ` and its inverse keep full relative accuracy.
    fn position(&self, u: f64) -> f32 {
        let width = 1.0 - 2.0 * self.tail;
        let x = if u < 0.5 {
            0.5 + self.sigma * normal::quantile(self.tail + u * width)
        } else {
            0.5 - self.sigma * normal::quantile(self.tail + (1.0 - u) * width)
        };
        (x.clamp(0.0, 1.0)) as f32
    }
}

/// The Archimedean spiral `r = bθ`, `θ ∈ [0, Θ]`, around the square's center.
struct Spiral {
    b: f64,
    theta_max: f64,
    length: f64,
}

impl Spiral {
    fn new(turns: f64) -> Self {
        let theta_max = TAU * turns;
        let b = SPIRAL_RADIUS / theta_max;
        let mut s = Spiral {
            b,
            theta_max,
            length: 0.0,
        };
        s.length = s.arc_length(theta_max);
        s
    }

    /// Arc length from the center to angle `θ`: `(b/2)(θ √(1+θ²) + asinh θ)`.
    fn arc_length(&self, theta: f64) -> f64 {
        0.5 * self.b * (theta * (1.0 + theta * theta).sqrt() + theta.asinh())
    }

    /// The angle at arc length fraction `u ∈ [0, 1]`: Newton on the convex, increasing `s(θ)`,
    /// kept inside `[0, Θ]`.
    fn angle(&self, u: f64) -> f64 {
        let target = u * self.length;
        // s(θ) ≈ bθ²/2 for large θ.
        let mut theta = (2.0 * target / self.b).sqrt().min(self.theta_max);
        for _ in 0..100 {
            let step = (self.arc_length(theta) - target) / (self.b * (1.0 + theta * theta).sqrt());
            let next = (theta - step).clamp(0.0, self.theta_max);
            let done = (next - theta).abs() <= 1e-14 * (1.0 + theta);
            theta = next;
            if done {
                break;
            }
        }
        theta
    }

    /// The point at arc length fraction `u`, moved by `offset` along the unit normal.
    fn point(&self, u: f64, offset: f64) -> [f64; 2] {
        let theta = self.angle(u);
        let (sin, cos) = theta.sin_cos();
        let r = self.b * theta;
        // Tangent ∝ (cos θ − θ sin θ, sin θ + θ cos θ), of length √(1 + θ²).
        let len = (1.0 + theta * theta).sqrt();
        let (tx, ty) = ((cos - theta * sin) / len, (sin + theta * cos) / len);
        [0.5 + r * cos - offset * ty, 0.5 + r * sin + offset * tx]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axis(pts: &[f32], d: usize, k: usize) -> impl Iterator<Item = f64> + '_ {
        pts.iter().skip(k).step_by(d).map(|&x| f64::from(x))
    }

    fn mean_std(values: impl Iterator<Item = f64>) -> (f64, f64) {
        let v: Vec<f64> = values.collect();
        let n = v.len() as f64;
        let m = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n;
        (m, var.sqrt())
    }

    /// Std of N(0.5, σ²) truncated to [0, 1]: σ √(1 − 2hφ(h) / (Φ(h) − Φ(−h))), h = 0.5/σ.
    fn truncated_std(sigma: f64) -> f64 {
        let h = 0.5 / sigma;
        let z = 1.0 - 2.0 * normal::cdf(-h);
        sigma * (1.0 - 2.0 * h * normal::pdf(h) / z).sqrt()
    }

    #[test]
    fn gaussian_matches_the_truncated_normal() {
        for (dim, sigma) in [(2, 1.0 / 6.0), (3, 1.0 / 6.0), (1, 0.4), (4, 0.05)] {
            let n = 1 << 14;
            let pts = proxy_points(&ProxyShape::Gaussian { sigma }, dim, n, 3).unwrap();
            assert_eq!(pts.len(), n * dim);
            assert!(pts.iter().all(|&x| (0.0..=1.0).contains(&x)));
            let want = truncated_std(sigma);
            for k in 0..dim {
                let (m, s) = mean_std(axis(&pts, dim, k));
                // Stratified points: mean within 1e-3 of 0.5, std within 0.5% of the truncated one.
                assert!((m - 0.5).abs() < 1e-3, "σ {sigma} axis {k}: mean {m}");
                assert!(
                    (s / want - 1.0).abs() < 5e-3,
                    "σ {sigma} axis {k}: std {s} vs {want}"
                );
            }
            // Fraction within one σ of the center: (Φ(1) − Φ(−1)) / (Φ(h) − Φ(−h)).
            let inside = axis(&pts, dim, 0)
                .filter(|x| (x - 0.5).abs() < sigma)
                .count();
            let h = 0.5 / sigma;
            let want = (1.0 - 2.0 * normal::cdf(-1.0)) / (1.0 - 2.0 * normal::cdf(-h));
            let got = inside as f64 / n as f64;
            assert!(
                (got - want.min(1.0)).abs() < 2e-3,
                "σ {sigma}: {got} vs {want}"
            );
        }
        // σ = 1/6 is nearly untruncated: std ≈ 0.98658 σ.
        assert!((truncated_std(1.0 / 6.0) / (1.0 / 6.0) - 0.98658).abs() < 1e-4);
    }

    #[test]
    fn uniform_moments() {
        let n = 1 << 14;
        let pts = proxy_points(&ProxyShape::Uniform, 3, n, 8).unwrap();
        assert!(pts.iter().all(|&x| (0.0..=1.0).contains(&x)));
        for k in 0..3 {
            let (m, s) = mean_std(axis(&pts, 3, k));
            assert!((m - 0.5).abs() < 1e-4, "axis {k}: mean {m}");
            assert!(
                (s - (1.0f64 / 12.0).sqrt()).abs() < 1e-4,
                "axis {k}: std {s}"
            );
        }
        // Joint moment: independent axes.
        let xy = pts
            .chunks_exact(3)
            .map(|p| f64::from(p[0]) * f64::from(p[2]))
            .sum::<f64>();
        assert!((xy / n as f64 - 0.25).abs() < 1e-3);
    }

    #[test]
    fn spiral_points_lie_on_the_band_uniformly_by_arc_length() {
        let (turns, thickness) = (3.0, 0.01);
        let n = 2000;
        let pts = proxy_points(&ProxyShape::Spiral { turns, thickness }, 2, n, 4).unwrap();
        assert!(pts.iter().all(|&x| (0.0..=1.0).contains(&x)));
        let spiral = Spiral::new(turns);
        // A fine polyline of the center line, with the arc length fraction of each vertex.
        let m = 20_000;
        let line: Vec<([f64; 2], f64)> = (0..=m)
            .map(|j| {
                let theta = spiral.theta_max * j as f64 / m as f64;
                let (s, c) = theta.sin_cos();
                let r = spiral.b * theta;
                (
                    [0.5 + r * c, 0.5 + r * s],
                    spiral.arc_length(theta) / spiral.length,
                )
            })
            .collect();
        let mut fractions = Vec::with_capacity(n);
        let mut max_dist: f64 = 0.0;
        for p in pts.chunks_exact(2) {
            let p = [f64::from(p[0]), f64::from(p[1])];
            let (mut best, mut frac) = (f64::INFINITY, 0.0);
            for w in line.windows(2) {
                let ([ax, ay], fa) = w[0];
                let ([bx, by], fb) = w[1];
                let (dx, dy) = (bx - ax, by - ay);
                let t =
                    (((p[0] - ax) * dx + (p[1] - ay) * dy) / (dx * dx + dy * dy)).clamp(0.0, 1.0);
                let d = (p[0] - ax - t * dx).hypot(p[1] - ay - t * dy);
                if d < best {
                    best = d;
                    frac = fa + t * (fb - fa);
                }
            }
            max_dist = max_dist.max(best);
            fractions.push(frac);
        }
        // Every point within half the thickness of the curve (plus polyline and f32 error), and
        // the offsets use the whole band.
        assert!(
            max_dist <= thickness / 2.0 + 1e-5,
            "max distance {max_dist}"
        );
        assert!(max_dist > 0.45 * thickness, "max distance {max_dist}");
        // Uniform by arc length: Kolmogorov–Smirnov distance of the arc-length fractions.
        fractions.sort_by(f64::total_cmp);
        let ks = fractions
            .iter()
            .enumerate()
            .map(|(i, &f)| {
                (f - i as f64 / n as f64)
                    .abs()
                    .max((f - (i + 1) as f64 / n as f64).abs())
            })
            .fold(0.0, f64::max);
        assert!(ks < 0.01, "KS distance {ks}");
        // The outer end reaches the stated radius.
        let r_max = pts
            .chunks_exact(2)
            .map(|p| (f64::from(p[0]) - 0.5).hypot(f64::from(p[1]) - 0.5))
            .fold(0.0, f64::max);
        assert!(
            (r_max - SPIRAL_RADIUS).abs() < thickness,
            "outer radius {r_max}"
        );
    }

    #[test]
    fn spiral_angle_inverts_arc_length() {
        let s = Spiral::new(2.5);
        for k in 0..=100 {
            let u = k as f64 / 100.0;
            let theta = s.angle(u);
            assert!((s.arc_length(theta) / s.length - u).abs() < 1e-12, "u {u}");
        }
    }

    #[test]
    fn bad_settings_are_errors() {
        let g = |sigma| ProxyShape::Gaussian { sigma };
        for sigma in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                proxy_points(&g(sigma), 2, 10, 0),
                Err(SampleError::Sigma { .. })
            ));
        }
        let sp = |turns, thickness| ProxyShape::Spiral { turns, thickness };
        for turns in [0.0, -2.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                proxy_points(&sp(turns, 0.01), 2, 10, 0),
                Err(SampleError::Turns { .. })
            ));
        }
        for thickness in [-0.01, 0.2, f64::NAN] {
            assert!(matches!(
                proxy_points(&sp(3.0, thickness), 2, 10, 0),
                Err(SampleError::Thickness { .. })
            ));
        }
        let err = proxy_points(&ProxyShape::DEFAULT_SPIRAL, 3, 10, 0).unwrap_err();
        assert!(matches!(err, SampleError::SpiralDim { dim: 3 }), "{err}");
        for dim in [0, 5] {
            assert!(matches!(
                proxy_points(&ProxyShape::Uniform, dim, 10, 0),
                Err(SampleError::Dims { .. })
            ));
        }
        assert!(matches!(
            proxy_points(&ProxyShape::Uniform, 2, 0, 0),
            Err(SampleError::NoSamples)
        ));
        assert!(matches!(
            proxy_points(&ProxyShape::Uniform, 1, crate::sample::MAX_SAMPLES + 1, 0),
            Err(SampleError::TooManySamples { .. })
        ));
    }

    #[test]
    fn deterministic_per_seed() {
        for shape in [
            ProxyShape::DEFAULT_GAUSSIAN,
            ProxyShape::Uniform,
            ProxyShape::DEFAULT_SPIRAL,
        ] {
            let a = proxy_points(&shape, 2, 5000, 11).unwrap();
            let b = proxy_points(&shape, 2, 5000, 11).unwrap();
            let c = proxy_points(&shape, 2, 5000, 12).unwrap();
            let bytes = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
            assert_eq!(bytes(&a), bytes(&b), "{shape:?}");
            assert_ne!(a, c, "{shape:?}");
            let single = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .build()
                .unwrap()
                .install(|| proxy_points(&shape, 2, 5000, 11).unwrap());
            assert_eq!(a, single, "{shape:?}");
        }
    }
}
