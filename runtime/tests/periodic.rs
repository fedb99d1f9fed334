//! Periodic blends answer every query on the torus: point queries near a border see the points
//! across it (brute force over the wrapped samples), range boxes crossing a border count the points
//! of every piece, splats wrap, samples are folded into [0,1)^d, and prepared and region queries
//! keep the exact bits of their per-cell references. Maps store lifts `p + δ` (|δ| <= ½), as the
//! baker writes them.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{weights, Rng, STORAGES};
use otbake_formats::proxy::Proxy as ProxyData;
use otbake_formats::storage::Storage;
use otbake_formats::tree::{depth, fill_node_boxes, node_count};
use otbake_formats::write::{encode_map_content, encode_proxy, MapContent};
use otbake_formats::Wrap;
use otbake_runtime::{
    AdaptiveKernel, Blend, Error, Kernel, Map, PointValue, Prepared, PreparedBuffers, Proxy,
    Region, SplatTarget, MAX_DIM,
};
use proptest::prelude::*;
use rkyv::util::AlignedVec;

/// A periodic proxy (points in [0,1)^d, many near the borders) and k maps of lifts `p + δ`.
struct Torus {
    n: usize,
    proxy: AlignedVec<16>,
    maps: Vec<AlignedVec<16>>,
    /// Per map: the stored lifts and colors.
    lifts: Vec<Vec<f32>>,
    colors: Vec<Vec<f32>>,
    mean_mass: Vec<f32>,
}

fn torus(seed: u64, n: usize, dim: usize, k: usize, storage: Storage, wrap: [u32; 2]) -> Torus {
    let mut rng = Rng(seed);
    let leaf = 1 + (seed % 5) as u32;
    let d = depth(n as u32, leaf);
    let nodes = node_count(d) as usize;
    // Half the points crowd the borders (within 0.05 of 0 or 1), so seams matter.
    let coord = |rng: &mut Rng| {
        let u = rng.unit();
        let v = if rng.next().is_multiple_of(2) {
            u
        } else {
            (1.0 + (u - 0.5) * 0.1).fract()
        };
        if v >= 1.0 {
            0.0
        } else {
            v
        }
    };
    let proxy_pos: Vec<f32> = (0..n * dim).map(|_| coord(&mut rng)).collect();
    let mut boxes = vec![0.0; nodes * 2 * dim];
    fill_node_boxes(&proxy_pos, dim, d, &mut boxes);
    let key = [11; 32];
    let proxy = encode_proxy(&ProxyData {
        dim: dim as u32,
        n: n as u32,
        leaf_size: leaf,
        depth: d,
        key,
        wrap: wrap[0],
        description: "torus",
        positions: &proxy_pos,
        node_boxes: &boxes,
    })
    .unwrap();
    let mut t = Torus {
        n,
        proxy,
        maps: vec![],
        lifts: vec![],
        colors: vec![],
        mean_mass: vec![],
    };
    for m in 0..k {
        // Each map moves points by up to half a period, in a smooth field plus noise, and stores
        // the lift p + δ.
        let phase = rng.unit() * 6.3;
        let lifts: Vec<f32> = (0..n * dim)
            .map(|i| {
                let p = proxy_pos[i];
                let smooth = 0.3 * (phase + std::f32::consts::TAU * proxy_pos[i - i % dim]).sin();
                let delta = (smooth + 0.2 * (rng.unit() - 0.5)).clamp(-0.5, 0.5);
                p + delta
            })
            .collect();
        let colors: Vec<f32> = (0..n * 3).map(|_| rng.unit() * 2.0).collect();
        let mean = 0.1 + rng.unit();
        // Spacings from their own generator (the other streams stay as they were).
        let mut srng = Rng(seed ^ (0x5EED_0000 + m as u64));
        let spacings: Vec<f32> = (0..n)
            .map(|_| 10f32.powf(-2.5 + 2.0 * srng.unit()))
            .collect();
        t.maps.push(
            encode_map_content(
                &MapContent {
                    dim: dim as u32,
                    depth: d,
                    proxy_key: key,
                    key: [m as u8; 32],
                    composite: 0,
                    mean_mass: mean,
                    wrap: Wrap::from_code(wrap[1]).unwrap(),
                    positions: &lifts,
                    colors: &colors,
                    spacings: &spacings,
                    solver_report: "",
                    transport_cost: 0.0,
                },
                storage,
            )
            .unwrap(),
        );
        t.lifts.push(lifts);
        t.colors.push(colors);
        t.mean_mass.push(mean);
    }
    t
}

fn open(t: &Torus) -> (Proxy<'_>, Vec<Map<'_>>) {
    (
        Proxy::open(&t.proxy).unwrap(),
        t.maps.iter().map(|m| Map::open(m).unwrap()).collect(),
    )
}

fn fold(v: f64) -> f64 {
    let f = v - v.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

/// Every blended point folded onto the torus, with its color (in f64, from the runtime's own
/// blended lifts, so quantized storages compare on what they store).
fn torus_points(blend: &Blend<'_, '_>, w: &[f32]) -> Vec<(Vec<f64>, [f64; 3])> {
    (0..blend.n())
        .map(|i| {
            let s = blend.sample(w, i).unwrap();
            (
                (0..blend.dim()).map(|k| f64::from(s.position[k])).collect(),
                s.color.map(f64::from),
            )
        })
        .collect()
}

/// Shortest distance² on the torus.
fn torus_d2(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let t = (x - y).abs() % 1.0;
            let t = t.min(1.0 - t);
            t * t
        })
        .sum()
}

/// Brute-force density and premultiplied color at `q` of the periodized truncated Gaussian (every
/// image within 3σ; 3σ < ½ here, so that is the nearest image only).
fn brute_point(pts: &[(Vec<f64>, [f64; 3])], q: &[f64], sigma: f64, mean_mass: f64) -> [f64; 4] {
    let dim = q.len();
    let mass = [0.997_300_2, 0.988_891, 0.970_709_1, 0.938_900_5][dim - 1];
    let norm =
        1.0 / ((2.0 * std::f64::consts::PI).powf(dim as f64 / 2.0) * sigma.powi(dim as i32) * mass);
    let mut out = [0.0; 4];
    for (p, c) in pts {
        let r2 = torus_d2(p, q);
        if r2 <= 9.0 * sigma * sigma {
            let w = (-0.5 * r2 / (sigma * sigma)).exp() * norm / pts.len() as f64;
            out[0] += w;
            for a in 0..3 {
                out[1 + a] += w * c[a] * mean_mass;
            }
        }
    }
    out
}

/// Brute-force adaptive density and color at `q`: every point's own truncated Gaussian (width
/// `sigmas[i]`, nearest image: every `3σ_i <= 3 · max_sigma < ½` here).
fn brute_adaptive(
    pts: &[(Vec<f64>, [f64; 3])],
    sigmas: &[f32],
    q: &[f64],
    mean_mass: f64,
) -> [f64; 5] {
    let dim = q.len();
    let mass = [0.997_300_2, 0.988_891, 0.970_709_1, 0.938_900_5][dim - 1];
    let mut out = [0.0f64; 5];
    for ((p, c), &s) in pts.iter().zip(sigmas) {
        let sigma = f64::from(s);
        let norm = 1.0
            / ((2.0 * std::f64::consts::PI).powf(dim as f64 / 2.0) * sigma.powi(dim as i32) * mass)
            / pts.len() as f64;
        out[4] = out[4].max(norm);
        let r2 = torus_d2(p, q);
        if r2 <= 9.0 * sigma * sigma {
            let w = (-0.5 * r2 / (sigma * sigma)).exp() * norm;
            out[0] += w;
            for a in 0..3 {
                out[1 + a] += w * c[a] * mean_mass;
            }
        }
    }
    out
}

/// Whether `x` lies on the closed arc from `lo` to `hi` of the circle (`hi >= lo`, `hi − lo < 1`).
fn on_arc(x: f64, lo: f64, hi: f64) -> bool {
    let start = fold(lo);
    let t = fold(x - start);
    t <= hi - lo
}

fn buffers(blend: &Blend<'_, '_>) -> [Vec<f32>; 4] {
    let s = blend.prepared_sizes();
    [
        vec![f32::NAN; s.positions],
        vec![f32::NAN; s.colors],
        vec![f32::NAN; s.node_boxes],
        vec![f32::NAN; s.node_colors],
    ]
}

fn prepare<'b>(blend: &Blend<'_, '_>, w: &[f32], b: &'b mut [Vec<f32>; 4]) -> Prepared<'b> {
    let [p, c, nb, nc] = b;
    blend
        .prepare(
            w,
            PreparedBuffers {
                positions: p,
                colors: c,
                node_boxes: nb,
                node_colors: nc,
            },
        )
        .unwrap()
}

fn bits(v: &PointValue) -> [u32; 5] {
    [
        v.density.to_bits(),
        v.mass.to_bits(),
        v.color[0].to_bits(),
        v.color[1].to_bits(),
        v.color[2].to_bits(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Adaptive point queries on the torus equal brute force: each point's kernel (its own width)
    /// wraps across the borders, and the node bounds prune every image exactly.
    #[test]
    fn adaptive_queries_equal_brute_force_on_the_torus(seed in 0u64..1000, n in 1usize..250,
                                                       dim in 1usize..=3, k in 1usize..4,
                                                       st in 0usize..STORAGES.len()) {
        let t = torus(seed, n, dim, k, STORAGES[st], [1, 1]);
        let (proxy, maps) = open(&t);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0xADA);
        let w = weights(&mut rng, k);
        let ak = AdaptiveKernel { scale: 1.0 + 2.0 * rng.unit(), min_sigma: 0.003, max_sigma: 0.12 };
        let pts = torus_points(&blend, &w);
        let sigmas: Vec<f32> = (0..n as u32).map(|i| blend.bandwidth(&w, i, ak).unwrap()).collect();
        let mean_mass: f64 = w.iter().zip(&t.mean_mass).map(|(a, b)| f64::from(*a * *b)).sum();
        for _ in 0..12 {
            let q: Vec<f32> = (0..dim)
                .map(|_| match rng.next() % 4 {
                    0 => rng.unit() * 0.04,
                    1 => 1.0 - rng.unit() * 0.04,
                    2 => rng.unit(),
                    _ => rng.unit() * 4.0 - 2.0,
                })
                .collect();
            let qf: Vec<f64> = q.iter().map(|&v| fold(f64::from(v))).collect();
            let v = blend.point_adaptive(&w, &q, ak).unwrap();
            let b = brute_adaptive(&pts, &sigmas, &qf, mean_mass);
            // Cutoffs decided on folded f64 points may differ from the runtime's f32 lifts by
            // one point's term.
            let tol = 1e-3 * b[0] + 2e-3 * b[4] + 1e-6;
            prop_assert!((f64::from(v.density) - b[0]).abs() <= tol, "density at {q:?}: {} vs {}", v.density, b[0]);
            for a in 0..3 {
                prop_assert!((f64::from(v.color[a]) - b[1 + a]).abs() <= 3.0 * tol * mean_mass.max(1.0));
            }
        }
        // A kernel reaching past one period is refused.
        let wide = AdaptiveKernel { max_sigma: 0.34, ..ak };
        prop_assert_eq!(blend.point_adaptive(&w, &vec![0.5; dim], wide).map(|_| ()),
                        Err(Error::PeriodicKernel { radius: 3.0 * 0.34 }));
    }

    /// Point queries anywhere, and especially within 3σ of a border, equal brute force over the
    /// folded blended points with the torus distance; range boxes (some crossing a border, some a
    /// full period wide) count exactly the points on their arcs.
    #[test]
    fn queries_equal_brute_force_on_the_torus(seed in 0u64..1000, n in 1usize..250, dim in 1usize..=3,
                                               k in 1usize..4, st in 0usize..STORAGES.len()) {
        let t = torus(seed, n, dim, k, STORAGES[st], [1, 1]);
        let (proxy, maps) = open(&t);
        let blend = Blend::new(proxy, &maps).unwrap();
        prop_assert_eq!(blend.wrap(), Wrap::Periodic);
        let mut rng = Rng(seed ^ 0xABC);
        let w = weights(&mut rng, k);
        let pts = torus_points(&blend, &w);
        for (p, _) in &pts {
            prop_assert!(p.iter().all(|v| (0.0..1.0).contains(v)), "sample not folded: {p:?}");
        }
        let mean_mass: f64 = w.iter().zip(&t.mean_mass).map(|(a, b)| f64::from(*a * *b)).sum();
        let sigma = 0.01 + 0.1 * rng.unit();
        for _ in 0..12 {
            // Near a border, in the middle, or outside [0,1) (a query point is a torus point).
            let q: Vec<f32> = (0..dim)
                .map(|_| match rng.next() % 4 {
                    0 => rng.unit() * 0.04,
                    1 => 1.0 - rng.unit() * 0.04,
                    2 => rng.unit(),
                    _ => rng.unit() * 4.0 - 2.0,
                })
                .collect();
            let qf: Vec<f64> = q.iter().map(|&v| fold(f64::from(v))).collect();
            let v = blend.point(&w, &q, Kernel { sigma }).unwrap();
            let b = brute_point(&pts, &qf, f64::from(sigma), mean_mass);
            let tol = 1e-3 * b[0].max(1.0);
            prop_assert!((f64::from(v.density) - b[0]).abs() <= tol, "density at {q:?}: {} vs {}", v.density, b[0]);
            for a in 0..3 {
                prop_assert!((f64::from(v.color[a]) - b[1 + a]).abs() <= 1e-3 * b[1 + a].max(1.0));
            }

            let mut lo = vec![0f32; dim];
            let mut hi = vec![0f32; dim];
            for a in 0..dim {
                lo[a] = rng.unit() * 1.6 - 0.3;
                hi[a] = lo[a] + if rng.next().is_multiple_of(6) { 1.0 + rng.unit() } else { rng.unit() * 0.7 };
            }
            let want = pts
                .iter()
                .filter(|(p, _)| {
                    (0..dim).all(|a| {
                        let (l, h) = (f64::from(lo[a]), f64::from(hi[a]));
                        h - l >= 1.0 || on_arc(p[a], l, h)
                    })
                })
                .count();
            let r = blend.range(&w, &lo, &hi).unwrap();
            prop_assert_eq!(r.count as usize, want, "box {:?}..{:?}", lo, hi);
            // An inverted box is empty, as when clamped.
            let r = blend.range(&w, &hi, &lo).unwrap();
            prop_assert_eq!(r.count, 0);
        }
    }

    /// Prepared periodic blends answer with the blend's bits, point grids equal per-cell point
    /// queries, and region splats (bands) equal the full splat, bit for bit.
    #[test]
    fn prepared_and_region_queries_keep_their_bits(seed in 0u64..1000, n in 1usize..200, dim in 1usize..=3,
                                                   k in 1usize..4, st in 0usize..STORAGES.len()) {
        let t = torus(seed, n, dim, k, STORAGES[st], [1, 1]);
        let (proxy, maps) = open(&t);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x5EED);
        let w = weights(&mut rng, k);
        let mut store = buffers(&blend);
        let prep = prepare(&blend, &w, &mut store);
        prop_assert_eq!(prep.wrap(), Wrap::Periodic);
        let kernel = Kernel { sigma: 0.01 + 0.08 * rng.unit() };
        for i in 0..t.n as u32 {
            prop_assert_eq!(prep.sample(i).unwrap(), blend.sample(&w, i).unwrap());
        }
        let mut res = [1u32; MAX_DIM];
        for a in 0..dim {
            res[a] = 3 + (rng.next() % 9) as u32;
        }
        let full = Region::full(res);
        let cells: usize = res[..dim].iter().map(|&r| r as usize).product();
        let mut grid = vec![PointValue::default(); cells];
        prep.point_grid(kernel, full, &mut grid).unwrap();
        for (cell, g) in grid.iter().enumerate() {
            let mut rest = cell;
            let q: Vec<f32> = (0..dim)
                .map(|a| {
                    let i = rest % res[a] as usize;
                    rest /= res[a] as usize;
                    (i as f32 + 0.5) / res[a] as f32
                })
                .collect();
            let a = blend.point(&w, &q, kernel).unwrap();
            prop_assert_eq!(bits(g), bits(&a), "cell {}", cell);
            prop_assert_eq!(bits(&prep.point(&q, kernel).unwrap()), bits(&a));
            let lo: Vec<f32> = q.iter().map(|v| v - 0.3).collect();
            let hi: Vec<f32> = q.iter().map(|v| v + 0.2).collect();
            prop_assert_eq!(prep.range(&lo, &hi).unwrap(), blend.range(&w, &lo, &hi).unwrap());
        }
        // The full splat of the blend, of the prepared blend, and band by band.
        let mut d0 = vec![0.0f32; cells];
        let mut c0 = vec![0.0f32; cells * 3];
        blend
            .splat(&w, kernel, SplatTarget { res, density: &mut d0, color: Some(&mut c0) })
            .unwrap();
        let mut d1 = vec![0.0f32; cells];
        let mut c1 = vec![0.0f32; cells * 3];
        prep.splat(kernel, SplatTarget { res, density: &mut d1, color: Some(&mut c1) }).unwrap();
        prop_assert_eq!(d0.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), d1.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        prop_assert_eq!(c0.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), c1.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        // Bands along the last axis.
        let last = dim - 1;
        let stride: usize = res[..last].iter().map(|&r| r as usize).product();
        let mut d2 = vec![0.0f32; cells];
        let mut c2 = vec![0.0f32; cells * 3];
        let mut start = 0u32;
        while start < res[last] {
            let size = (1 + (rng.next() % 3) as u32).min(res[last] - start);
            let mut r = full;
            r.start[last] = start;
            r.size[last] = size;
            let (a, b) = (start as usize * stride, (start + size) as usize * stride);
            prep.splat_region(kernel, r, &mut d2[a..b], Some(&mut c2[3 * a..3 * b])).unwrap();
            // The same band into RGBA cells, prepared and mixed on the fly.
            let mut pr = vec![0.0f32; (b - a) * 4];
            let mut br = vec![0.0f32; (b - a) * 4];
            prep.splat_region_rgba(kernel, r, &mut pr).unwrap();
            blend.splat_region_rgba(&w, kernel, r, &mut br).unwrap();
            for cell in 0..b - a {
                let want = [c0[3 * (a + cell)], c0[3 * (a + cell) + 1], c0[3 * (a + cell) + 2], d0[a + cell]];
                for ch in 0..4 {
                    prop_assert_eq!(pr[cell * 4 + ch].to_bits(), want[ch].to_bits(), "band {} cell {}", start, cell);
                    prop_assert_eq!(br[cell * 4 + ch].to_bits(), want[ch].to_bits(), "band {} cell {}", start, cell);
                }
            }
            start += size;
        }
        prop_assert_eq!(d0.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), d2.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        prop_assert_eq!(c0.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), c2.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// The image paths (2D, narrow kernels: σ from 0.15 to 0.8 cell, regions at least four cells
    /// wide take the fixed 4×4 blocks of `plane.rs`, the others and the widest spans the general
    /// paths; RGBA splats up to σ = ½ cell the 3×3 blocks of `rgba/block3.rs`) on the torus: point
    /// grids of the whole image, of bands and of tiles touching a border equal per-cell point
    /// queries, and region splats (planar, RGBA, RGBA mixed on the fly) the same cells of the full
    /// splat, bit for bit. Half the points crowd the borders, so a region path that missed an image of the blend
    /// (a shift) would lose the terms from across the seam.
    #[test]
    fn narrow_kernel_regions_wrap_like_their_references(seed in 0u64..1000, n in 1usize..400,
                                                        k in 1usize..=4, sigma_cells in 0.15f32..0.8,
                                                        st in 0usize..STORAGES.len()) {
        let t = torus(seed, n, 2, k, STORAGES[st], [1, 1]);
        let (proxy, maps) = open(&t);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x7113);
        let w = weights(&mut rng, k);
        let mut store = buffers(&blend);
        let prep = prepare(&blend, &w, &mut store);
        let res = [16 + (rng.next() % 65) as u32, 16 + (rng.next() % 65) as u32, 1, 1];
        let kernel = Kernel { sigma: sigma_cells / res[0].max(res[1]) as f32 };
        let cells = (res[0] * res[1]) as usize;
        let mut full_d = vec![0.0f32; cells];
        let mut full_c = vec![0.0f32; cells * 3];
        prep.splat(kernel, SplatTarget { res, density: &mut full_d, color: Some(&mut full_c) })
            .unwrap();
        for shape in 0..4 {
            let mut region = Region::full(res);
            for a in 0..2 {
                let size = 1 + (rng.next() % res[a] as u64) as u32;
                (region.start[a], region.size[a]) = match shape {
                    0 => (0, res[a]),
                    // A band (axis 1) or a tile against the first or last cells of the grid.
                    1 if a == 0 => (0, res[a]),
                    1 | 2 => (0, size),
                    _ => (res[a] - size, size),
                };
            }
            let rcells = region.cells(2).unwrap();
            let mut out = vec![PointValue::default(); rcells];
            prep.point_grid(kernel, region, &mut out).unwrap();
            let mut d = vec![0.0f32; rcells];
            let mut c = vec![0.0f32; rcells * 3];
            prep.splat_region(kernel, region, &mut d, Some(&mut c)).unwrap();
            let mut pr = vec![0.0f32; rcells * 4];
            let mut br = vec![0.0f32; rcells * 4];
            prep.splat_region_rgba(kernel, region, &mut pr).unwrap();
            blend.splat_region_rgba(&w, kernel, region, &mut br).unwrap();
            for (cell, v) in out.iter().enumerate() {
                let (i, j) = (cell % region.size[0] as usize, cell / region.size[0] as usize);
                let (gi, gj) = (region.start[0] as usize + i, region.start[1] as usize + j);
                let q = [
                    (gi as f32 + 0.5) / res[0] as f32,
                    (gj as f32 + 0.5) / res[1] as f32,
                ];
                let want = blend.point(&w, &q, kernel).unwrap();
                prop_assert_eq!(bits(v), bits(&want), "{:?} cell {}", region, cell);
                let g = gj * res[0] as usize + gi;
                prop_assert_eq!(d[cell].to_bits(), full_d[g].to_bits(), "{:?} cell {}", region, cell);
                for ch in 0..3 {
                    prop_assert_eq!(c[cell * 3 + ch].to_bits(), full_c[g * 3 + ch].to_bits());
                }
                let want = [full_c[3 * g], full_c[3 * g + 1], full_c[3 * g + 2], full_d[g]];
                for ch in 0..4 {
                    prop_assert_eq!(pr[cell * 4 + ch].to_bits(), want[ch].to_bits(), "{:?} cell {} (rgba)", region, cell);
                    prop_assert_eq!(br[cell * 4 + ch].to_bits(), want[ch].to_bits(), "{:?} cell {} (rgba, mixed)", region, cell);
                }
            }
        }
    }
}

/// The splat of a periodic blend keeps all of its mass (every kernel wraps instead of falling off
/// an edge): the density integrates to 1 over the torus, where the clamped splat of the same points
/// loses the part of each border kernel outside the square.
#[test]
fn periodic_splats_keep_the_mass_at_the_borders() {
    for wrap in [1u32, 0] {
        let t = torus(7, 400, 2, 2, Storage::FULL, [wrap, wrap]);
        let (proxy, maps) = open(&t);
        let blend = Blend::new(proxy, &maps).unwrap();
        let res = [64u32, 64, 1, 1];
        let mut d = vec![0.0f32; 64 * 64];
        blend
            .splat(
                &[0.5, 0.5],
                Kernel { sigma: 0.02 },
                SplatTarget {
                    res,
                    density: &mut d,
                    color: None,
                },
            )
            .unwrap();
        let total: f64 = d.iter().map(|&v| f64::from(v)).sum::<f64>() / (64.0 * 64.0);
        if wrap == 1 {
            assert!((total - 1.0).abs() < 0.01, "periodic mass {total}");
        } else {
            // Clamped: the lifts outside the square and the kernels across its edges are lost.
            assert!(total < 0.9, "clamped mass {total}");
        }
    }
}

#[test]
fn mismatched_wraps_and_wide_kernels_are_errors() {
    let t = torus(3, 50, 2, 1, Storage::FULL, [1, 0]);
    let (proxy, maps) = open(&t);
    assert!(matches!(
        Blend::new(proxy, &maps),
        Err(Error::WrapMismatch { map: 0 })
    ));
    let t = torus(3, 50, 2, 2, Storage::FULL, [1, 1]);
    let (proxy, maps) = open(&t);
    let blend = Blend::new(proxy, &maps).unwrap();
    let w = [0.5, 0.5];
    let wide = Kernel { sigma: 0.34 };
    assert!(matches!(
        blend.point(&w, &[0.5, 0.5], wide),
        Err(Error::PeriodicKernel { .. })
    ));
    let mut d = vec![0.0; 16];
    let target = SplatTarget {
        res: [4, 4, 1, 1],
        density: &mut d,
        color: None,
    };
    assert!(matches!(
        blend.splat(&w, wide, target),
        Err(Error::PeriodicKernel { .. })
    ));
    let mut store = buffers(&blend);
    let prep = prepare(&blend, &w, &mut store);
    let mut out = vec![PointValue::default(); 16];
    assert!(matches!(
        prep.point_grid(wide, Region::full([4, 4, 1, 1]), &mut out),
        Err(Error::PeriodicKernel { .. })
    ));
    let mut d = vec![0.0; 16];
    assert!(matches!(
        prep.splat_region(wide, Region::full([4, 4, 1, 1]), &mut d, None),
        Err(Error::PeriodicKernel { .. })
    ));
    assert!(prep.point(&[0.5, 0.5], Kernel { sigma: 0.33 }).is_ok());
    let err = Error::PeriodicKernel { radius: 1.02 }.to_string();
    assert!(err.contains("lower sigma"), "{err}");
}
