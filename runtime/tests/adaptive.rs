//! Density-adaptive point queries equal brute force over every blended point with its own kernel
//! width, for random archives (spacings unrelated to the points, so pruning by the node bounds must
//! be exact for any), every storage, dimension, leaf size, map count and weights; the density
//! integrates to 1; a constant width gives the fixed-kernel query; bad kernels and maps without
//! spacings are errors.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{fixture_with, weights, Fixture, Rng, STORAGES};
use otbake_formats::storage::Storage;
use otbake_runtime::{AdaptiveKernel, Blend, Error, Kernel, Map, Proxy};
use proptest::prelude::*;

fn open(f: &Fixture) -> (Proxy<'_>, Vec<Map<'_>>) {
    (
        Proxy::open(&f.proxy).unwrap(),
        f.maps.iter().map(|m| Map::open(m).unwrap()).collect(),
    )
}

const TRUNC: [f64; 4] = [
    0.997_300_203_936_739_8,
    0.988_891_003_461_757_7,
    0.970_709_113_465_111_8,
    0.938_900_519_039_667_3,
];

/// The documented width of point `i`: `clamp(scale · Σ w_k decode(code_k[i]))` in `f32`.
fn sigma_of(f: &Fixture, w: &[f32], i: usize, k: AdaptiveKernel) -> f32 {
    (k.scale * f.blended_spacing(w, i))
        .max(k.min_sigma)
        .min(k.max_sigma)
}

/// Blended point `i` as stored (decoded, so quantized maps compare on what they hold) and its color.
fn stored_point(maps: &[Map<'_>], w: &[f32], dim: usize, i: usize) -> (Vec<f32>, [f32; 3]) {
    let mut p = vec![0.0f32; dim];
    let mut c = [0.0f32; 3];
    for (m, wk) in maps.iter().zip(w) {
        let y = m.position(i as u32).unwrap();
        for a in 0..dim {
            p[a] += wk * y[a];
        }
        let col = m.color(i as u32).unwrap();
        for a in 0..3 {
            c[a] += wk * col[a];
        }
    }
    (p, c)
}

/// Brute force: every point within its own `3σ_i` (the cutoff decided in `f32` as documented),
/// its normalized truncated Gaussian summed in `f64`. Also returns the largest single term, the
/// scale of rounding near a cutoff.
fn brute(
    f: &Fixture,
    maps: &[Map<'_>],
    w: &[f32],
    q: &[f32],
    k: AdaptiveKernel,
) -> (f64, [f64; 3], f64) {
    let d = f.dim;
    let mut sum = 0.0;
    let mut c = [0.0; 3];
    let mut largest = 0.0f64;
    for i in 0..f.n {
        let (y, col) = stored_point(maps, w, d, i);
        let s = sigma_of(f, w, i, k);
        let r2: f32 = (0..d).map(|a| (y[a] - q[a]) * (y[a] - q[a])).sum();
        let reach = 3.0 * s;
        let sd = f64::from(s);
        let norm = 1.0
            / ((2.0 * std::f64::consts::PI).powf(d as f64 / 2.0)
                * sd.powi(d as i32)
                * TRUNC[d - 1]);
        largest = largest.max(norm);
        if r2 <= reach * reach {
            let kv = (-f64::from(r2) / (2.0 * sd * sd)).exp() * norm;
            sum += kv;
            for a in 0..3 {
                c[a] += kv * f64::from(col[a]);
            }
        }
    }
    let n = f.n as f64;
    let mm = f64::from(f.mean_mass(w));
    (sum / n, c.map(|v| v * mm / n), largest / n)
}

fn kernel(rng: &mut Rng) -> AdaptiveKernel {
    let min_sigma = 0.002 + 0.02 * rng.unit();
    AdaptiveKernel {
        scale: 0.5 + 3.0 * rng.unit(),
        min_sigma,
        max_sigma: min_sigma + 0.2 * rng.unit(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    #[test]
    fn adaptive_queries_equal_brute_force(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                          leaf in 1u32..8, k in 1usize..4,
                                          st in 0usize..STORAGES.len()) {
        let f = fixture_with(seed, n, dim, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        prop_assert!(blend.has_spacings());
        let mut rng = Rng(seed ^ 0xADA9);
        let w = weights(&mut rng, k);
        let ak = kernel(&mut rng);
        for i in (0..n).step_by(7) {
            let got = blend.bandwidth(&w, i as u32, ak).unwrap();
            prop_assert_eq!(got.to_bits(), sigma_of(&f, &w, i, ak).to_bits());
        }
        for _ in 0..8 {
            // Anywhere, or right on a blended point (where its narrow kernel peaks).
            let q: Vec<f32> = if rng.next().is_multiple_of(2) {
                (0..dim).map(|_| rng.unit()).collect()
            } else {
                stored_point(&maps, &w, dim, rng.next() as usize % n).0
            };
            let v = blend.point_adaptive(&w, &q, ak).unwrap();
            let (dens, col, largest) = brute(&f, &maps, &w, &q, ak);
            let tol = 2e-4 * dens + 1e-4 * largest + 1e-6;
            prop_assert!((f64::from(v.density) - dens).abs() <= tol, "density {} vs {dens}", v.density);
            let mm = f64::from(f.mean_mass(&w));
            prop_assert!((f64::from(v.mass) - dens * mm).abs() <= tol * mm * 1.01);
            for a in 0..3 {
                prop_assert!((f64::from(v.color[a]) - col[a]).abs() <= tol * mm * 2.0 * 1.01 + 1e-6,
                             "color {:?} vs {:?}", v.color, col);
            }
        }
    }

    /// With `min_sigma = max_sigma = σ` every point has width σ: the fixed-kernel query's value.
    #[test]
    fn a_constant_width_is_the_fixed_kernel(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                            k in 1usize..4, sigma in 0.01f32..0.3) {
        let f = fixture_with(seed, n, dim, 3, k, [1; 32], Storage::FULL);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0xF1);
        let w = weights(&mut rng, k);
        let ak = AdaptiveKernel { scale: 1.0, min_sigma: sigma, max_sigma: sigma };
        for _ in 0..6 {
            let q: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let a = blend.point_adaptive(&w, &q, ak).unwrap();
            let b = blend.point(&w, &q, Kernel { sigma }).unwrap();
            let tol = |x: f32| 1e-5 * x.abs() + 1e-7;
            prop_assert!((a.density - b.density).abs() <= tol(b.density), "{a:?} vs {b:?}");
            prop_assert!((a.mass - b.mass).abs() <= tol(b.mass));
            for c in 0..3 {
                prop_assert!((a.color[c] - b.color[c]).abs() <= tol(b.color[c]));
            }
        }
    }
}

/// The density integrates to 1: every point's kernel carries 1/n, however wide (1D, midpoint rule
/// over a range that holds every kernel).
#[test]
fn the_density_integrates_to_one() {
    for (seed, k) in [(1u64, 1usize), (2, 3)] {
        let f = fixture_with(seed, 200, 1, 4, k, [1; 32], Storage::FULL);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let w = weights(&mut Rng(seed), k);
        let ak = AdaptiveKernel {
            scale: 2.0,
            min_sigma: 1e-3,
            max_sigma: 0.05,
        };
        let cells = 200_000;
        let (lo, hi) = (-0.2f64, 1.2f64);
        let h = (hi - lo) / cells as f64;
        let total: f64 = (0..cells)
            .map(|c| {
                let x = (lo + (c as f64 + 0.5) * h) as f32;
                f64::from(blend.point_adaptive(&w, &[x], ak).unwrap().density) * h
            })
            .sum();
        assert!((total - 1.0).abs() < 1e-3, "seed {seed}: {total}");
    }
}

#[test]
fn bad_kernels_and_missing_spacings_are_errors() {
    let f = fixture_with(5, 50, 2, 4, 2, [1; 32], Storage::FULL);
    let (proxy, maps) = open(&f);
    let blend = Blend::new(proxy, &maps).unwrap();
    let w = [0.5, 0.5];
    let good = AdaptiveKernel {
        scale: 2.0,
        min_sigma: 0.001,
        max_sigma: 0.1,
    };
    assert!(blend.point_adaptive(&w, &[0.5, 0.5], good).is_ok());
    for bad in [
        AdaptiveKernel { scale: 0.0, ..good },
        AdaptiveKernel {
            scale: -1.0,
            ..good
        },
        AdaptiveKernel {
            scale: f32::NAN,
            ..good
        },
        AdaptiveKernel {
            scale: f32::INFINITY,
            ..good
        },
        AdaptiveKernel {
            min_sigma: 0.0,
            ..good
        },
        AdaptiveKernel {
            min_sigma: f32::NAN,
            ..good
        },
        AdaptiveKernel {
            min_sigma: 1e-30,
            ..good
        },
        AdaptiveKernel {
            max_sigma: 0.0005,
            ..good
        },
        AdaptiveKernel {
            max_sigma: f32::INFINITY,
            ..good
        },
        AdaptiveKernel {
            max_sigma: f32::NAN,
            ..good
        },
    ] {
        assert_eq!(
            blend.point_adaptive(&w, &[0.5, 0.5], bad),
            Err(Error::BadSigma),
            "{bad:?}"
        );
        assert_eq!(blend.bandwidth(&w, 0, bad), Err(Error::BadSigma));
    }
    assert!(matches!(
        blend.point_adaptive(&w, &[0.5, f32::NAN], good),
        Err(Error::BadCoordinate)
    ));
    assert!(matches!(
        blend.point_adaptive(&w, &[0.5], good),
        Err(Error::PointDim { .. })
    ));
    assert!(matches!(
        blend.point_adaptive(&[0.7, 0.7], &[0.5, 0.5], good),
        Err(Error::WeightSum { .. })
    ));
    assert_eq!(
        blend.bandwidth(&w, 50, good),
        Err(Error::IndexOutOfRange { index: 50, n: 50 })
    );

    // A map baked without spacings.
    let plain = otbake_formats::write::encode_map_content(
        &otbake_formats::write::MapContent {
            dim: 2,
            depth: otbake_formats::tree::depth(50, 4),
            proxy_key: [1; 32],
            key: [9; 32],
            composite: 0,
            mean_mass: 0.5,
            wrap: otbake_formats::Wrap::Clamp,
            positions: &f.positions[0],
            colors: &f.colors[0],
            spacings: &[],
            solver_report: "",
            transport_cost: 0.0,
        },
        Storage::FULL,
    )
    .unwrap();
    let mixed = [maps[0], Map::open(&plain).unwrap()];
    let blend = Blend::new(Proxy::open(&f.proxy).unwrap(), &mixed).unwrap();
    assert!(!blend.has_spacings());
    assert!(!mixed[1].has_spacings());
    let missing = Err(Error::MissingAttribute {
        map: 1,
        attribute: "spacings",
    });
    assert_eq!(blend.point_adaptive(&w, &[0.5, 0.5], good), missing);
    assert_eq!(
        blend.bandwidth(&w, 0, good).map(|_| ()),
        missing.map(|_| ())
    );
    // Fixed-width queries do not need spacings.
    assert!(blend.point(&w, &[0.5, 0.5], Kernel { sigma: 0.05 }).is_ok());
}
