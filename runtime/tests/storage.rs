//! Quantized archives stay within the stated error of the full ones.
//!
//! The stated error ([`otbake_formats::storage`]): every stored coordinate is within
//! `Map::position_error` of its full-precision value, every color ratio within `Map::color_error`.
//! A blend moves each point by at most the weighted sum of those bounds, so every query of a
//! quantized blend must answer within the interval the full points allow when each is moved (and
//! recolored) within its bound: sample positions within the bound, range counts between the counts
//! of the shrunk and the grown box, point and splat densities between the kernel sums with every
//! distance lengthened and shortened by the bound. Property tests check all of it against the full
//! blend of the same content, over random archives, dimensions, leaf sizes, map counts and storages;
//! quantized blends are also exact for their own decoded points (boxes still contain them).
#![allow(clippy::needless_range_loop)]

mod common;

use common::{fixture, fixture_with, weights, Fixture, Rng, STORAGES};
use otbake_formats::storage::{Precision, Storage};
use otbake_runtime::{Blend, Error, Kernel, Map, PreparedBuffers, Proxy, SplatTarget, MAX_DIM};
use proptest::prelude::*;

fn open(f: &Fixture) -> (Proxy<'_>, Vec<Map<'_>>) {
    (
        Proxy::open(&f.proxy).unwrap(),
        f.maps.iter().map(|m| Map::open(m).unwrap()).collect(),
    )
}

/// f32 rounding of two differently rounded mixes of the same weights (k <= 3 terms).
fn mix_slack(v: f32) -> f64 {
    1e-6 * (1.0 + v.abs() as f64)
}

/// The full blend's points and colors, and per point the blended bounds of the quantized blend.
struct Truth {
    dim: usize,
    n: usize,
    y: Vec<[f32; MAX_DIM]>,
    c: Vec<[f32; 3]>,
    /// Per point and axis: `Σ w_k e_k` plus mix rounding.
    e: Vec<[f64; MAX_DIM]>,
    /// Per channel: `Σ w_k ec_k` plus mix rounding.
    ec: [f64; 3],
}

fn truth(full: &Blend<'_, '_>, quantized: &[Map<'_>], w: &[f32]) -> Truth {
    let (dim, n) = (full.dim(), full.n() as usize);
    let mut t = Truth {
        dim,
        n,
        y: vec![],
        c: vec![],
        e: vec![],
        ec: [0.0; 3],
    };
    for (wk, m) in w.iter().zip(quantized) {
        for (a, e) in m.color_error().iter().enumerate() {
            t.ec[a] += *wk as f64 * *e as f64;
        }
    }
    for a in 0..3 {
        t.ec[a] += 1e-6;
    }
    for i in 0..n {
        let s = full.sample(w, i as u32).unwrap();
        let mut e = [0.0f64; MAX_DIM];
        for (wk, m) in w.iter().zip(quantized) {
            let pe = m.position_error(i as u32).unwrap();
            for a in 0..dim {
                e[a] += *wk as f64 * pe[a] as f64;
            }
        }
        for a in 0..dim {
            e[a] += mix_slack(s.position[a]);
        }
        t.y.push(s.position);
        t.c.push(s.color);
        t.e.push(e);
    }
    t
}

const TRUNC: [f64; 4] = [
    0.997_300_203_936_739_8,
    0.988_891_003_461_757_7,
    0.970_709_113_465_111_8,
    0.938_900_519_039_667_3,
];

/// The interval of (density, color) a point query at `p` may return when every point moves and
/// recolors within its bound.
fn point_interval(t: &Truth, p: &[f32], sigma: f32, mean_mass: f32) -> ([f64; 4], [f64; 4]) {
    let d = t.dim;
    let s = sigma as f64;
    let norm =
        1.0 / ((2.0 * std::f64::consts::PI).powf(d as f64 / 2.0) * s.powi(d as i32) * TRUNC[d - 1]);
    let r2max = 9.0 * s * s;
    let (mut lo, mut hi) = ([0.0f64; 4], [0.0f64; 4]);
    for i in 0..t.n {
        let r = (0..d)
            .map(|a| (t.y[i][a] as f64 - p[a] as f64).powi(2))
            .sum::<f64>()
            .sqrt();
        let delta = (0..d).map(|a| t.e[i][a] * t.e[i][a]).sum::<f64>().sqrt();
        let (near, far) = ((r - delta).max(0.0), r + delta);
        // Cutoff decided in f32 by the runtime: a hair of slack either way.
        let wmax = if near * near <= r2max * (1.0 + 1e-5) {
            (-near * near / (2.0 * s * s)).exp()
        } else {
            0.0
        };
        let wmin = if far * far <= r2max * (1.0 - 1e-5) {
            (-far * far / (2.0 * s * s)).exp()
        } else {
            0.0
        };
        lo[0] += wmin;
        hi[0] += wmax;
        for a in 0..3 {
            let c = t.c[i][a] as f64;
            lo[1 + a] += wmin * (c - t.ec[a]).max(0.0);
            hi[1 + a] += wmax * (c + t.ec[a]);
        }
    }
    let scale = norm / t.n as f64;
    let mm = mean_mass as f64;
    let widen = |v: f64, up: bool, f: f64| {
        let tol = 1e-4 * v.abs() + 1e-7 * scale * f;
        if up {
            v + tol
        } else {
            v - tol
        }
    };
    let mut l = [0.0; 4];
    let mut h = [0.0; 4];
    l[0] = widen(lo[0] * scale, false, 1.0);
    h[0] = widen(hi[0] * scale, true, 1.0);
    for a in 1..4 {
        l[a] = widen(lo[a] * scale * mm, false, mm);
        h[a] = widen(hi[a] * scale * mm, true, mm);
    }
    (l, h)
}

fn within(v: f32, lo: f64, hi: f64) -> bool {
    (v as f64) >= lo && (v as f64) <= hi
}

/// The quantized storages (every one but `FULL`).
fn quantized(st: usize) -> Storage {
    STORAGES[1 + st % (STORAGES.len() - 1)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    /// Every stored value is within its stated bound of the value it was quantized from.
    #[test]
    fn stored_values_are_within_their_bounds(seed in 0u64..1000, n in 1usize..400, dim in 1usize..=4,
                                             leaf in 1u32..9, st in 0usize..8) {
        let storage = quantized(st);
        let f = fixture_with(seed, n, dim, leaf, 2, [1; 32], storage);
        let (_, maps) = open(&f);
        for (k, m) in maps.iter().enumerate() {
            prop_assert_eq!(m.storage(), storage);
            let worst = m.max_position_error();
            let ce = m.color_error();
            for i in 0..n {
                let p = m.position(i as u32).unwrap();
                let e = m.position_error(i as u32).unwrap();
                for a in 0..dim {
                    let err = (p[a] - f.positions[k][i * dim + a]).abs();
                    prop_assert!(err <= e[a], "map {} point {} axis {}: {} > {}", k, i, a, err, e[a]);
                    prop_assert!(e[a] <= worst[a]);
                    if storage.positions == Precision::F32 {
                        prop_assert_eq!(err, 0.0);
                    }
                }
                let c = m.color(i as u32).unwrap();
                for a in 0..3 {
                    let err = (c[a] - f.colors[k][i * 3 + a]).abs();
                    prop_assert!(err <= ce[a], "map {} color {}: {} > {}", k, i, err, ce[a]);
                }
            }
        }
    }

    /// Samples, range, point and splat queries of a quantized blend stay within the intervals the
    /// stated bounds allow around the full blend's answers.
    #[test]
    fn quantized_queries_stay_within_the_stated_error(seed in 0u64..1000, n in 1usize..300,
                                                      dim in 1usize..=4, leaf in 1u32..8,
                                                      k in 1usize..4, st in 0usize..8,
                                                      sigma in 0.01f32..0.3) {
        let full = fixture(seed, n, dim, leaf, k, [1; 32]);
        let q = fixture_with(seed, n, dim, leaf, k, [1; 32], quantized(st));
        let (fp, fm) = open(&full);
        let (qp, qm) = open(&q);
        let fb = Blend::new(fp, &fm).unwrap();
        let qb = Blend::new(qp, &qm).unwrap();
        let mut rng = Rng(seed ^ 0x57a6e);
        let w = weights(&mut rng, k);
        let t = truth(&fb, &qm, &w);
        let mm = full.mean_mass(&w);

        for i in 0..n {
            let s = qb.sample(&w, i as u32).unwrap();
            for a in 0..dim {
                let err = (s.position[a] - t.y[i][a]).abs() as f64;
                prop_assert!(err <= t.e[i][a], "sample {} axis {}: {} > {}", i, a, err, t.e[i][a]);
            }
            for a in 0..3 {
                prop_assert!(((s.color[a] - t.c[i][a]).abs() as f64) <= t.ec[a] + mix_slack(t.c[i][a]));
            }
        }

        for _ in 0..6 {
            // Range: between the counts (and color sums) of the surely-inside and maybe-inside points.
            let a: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let b: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let lo: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x.min(*y)).collect();
            let hi: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x.max(*y)).collect();
            let (mut sure, mut maybe) = (0u32, 0u32);
            let (mut clo, mut chi) = ([0.0f64; 3], [0.0f64; 3]);
            for i in 0..n {
                let inside = |grow: f64| (0..dim).all(|x| {
                    t.y[i][x] as f64 >= lo[x] as f64 - grow * t.e[i][x]
                        && t.y[i][x] as f64 <= hi[x] as f64 + grow * t.e[i][x]
                });
                if inside(-1.0) {
                    sure += 1;
                    for c in 0..3 { clo[c] += (t.c[i][c] as f64 - t.ec[c]).max(0.0); }
                }
                if inside(1.0) {
                    maybe += 1;
                    for c in 0..3 { chi[c] += t.c[i][c] as f64 + t.ec[c]; }
                }
            }
            let v = qb.range(&w, &lo, &hi).unwrap();
            prop_assert!(sure <= v.count && v.count <= maybe, "count {} not in [{}, {}]", v.count, sure, maybe);
            let scale = mm as f64 / n as f64;
            for c in 0..3 {
                let tol = 1e-4 * chi[c] * scale + 1e-6;
                prop_assert!(within(v.color[c], clo[c] * scale - tol, chi[c] * scale + tol),
                    "range color {} not in [{}, {}]", v.color[c], clo[c] * scale, chi[c] * scale);
            }

            // Point query.
            let p: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let v = qb.point(&w, &p, Kernel { sigma }).unwrap();
            let (l, h) = point_interval(&t, &p, sigma, mm);
            prop_assert!(within(v.density, l[0], h[0]), "density {} not in [{}, {}]", v.density, l[0], h[0]);
            for c in 0..3 {
                prop_assert!(within(v.color[c], l[1 + c], h[1 + c]), "color {} not in [{}, {}]", v.color[c], l[1 + c], h[1 + c]);
            }
        }

        // Splat: each cell within the interval of a point query at its center.
        if dim <= 2 {
            let res = 3 + (seed % 6) as u32;
            let mut r = [1u32; MAX_DIM];
            r[..dim].fill(res);
            let cells = (res as usize).pow(dim as u32);
            let kernel = Kernel { sigma: 0.8 / res as f32 };
            let mut density = vec![0.0f32; cells];
            let mut color = vec![0.0f32; cells * 3];
            qb.splat(&w, kernel, SplatTarget { res: r, density: &mut density, color: Some(&mut color) }).unwrap();
            for cell in 0..cells {
                let center: Vec<f32> = (0..dim)
                    .map(|a| ((cell / (res as usize).pow(a as u32)) % res as usize) as f32 + 0.5)
                    .map(|c| c / res as f32)
                    .collect();
                let (l, h) = point_interval(&t, &center, kernel.sigma, mm);
                prop_assert!(within(density[cell], l[0], h[0]), "cell {}: {} not in [{}, {}]", cell, density[cell], l[0], h[0]);
                for c in 0..3 {
                    prop_assert!(within(color[cell * 3 + c], l[1 + c], h[1 + c]));
                }
            }
        }
    }

    /// A quantized blend answers exactly for its own (decoded) points: stored boxes contain them,
    /// so pruning loses nothing (range counts equal brute force over its samples).
    #[test]
    fn quantized_blends_are_exact_for_their_own_points(seed in 0u64..1000, n in 1usize..300,
                                                       dim in 1usize..=4, leaf in 1u32..8,
                                                       k in 1usize..4, st in 0usize..8) {
        let q = fixture_with(seed, n, dim, leaf, k, [1; 32], quantized(st));
        let (qp, qm) = open(&q);
        let qb = Blend::new(qp, &qm).unwrap();
        let mut rng = Rng(seed ^ 0xe8ac7);
        let w = weights(&mut rng, k);
        let pts: Vec<_> = (0..n as u32).map(|i| qb.sample(&w, i).unwrap()).collect();
        for _ in 0..8 {
            let a: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let b: Vec<f32> = (0..dim).map(|_| rng.unit() * 0.3).collect();
            let lo: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x - y).collect();
            let hi: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x + y).collect();
            let brute = pts
                .iter()
                .filter(|s| (0..dim).all(|x| s.position[x] >= lo[x] && s.position[x] <= hi[x]))
                .count();
            prop_assert_eq!(qb.range(&w, &lo, &hi).unwrap().count as usize, brute);
            // A point query's kernel sum over exactly the points within its cutoff.
            let sigma = 0.05f32;
            let kp = 9.0 * sigma * sigma;
            let near = pts
                .iter()
                .filter(|s| (0..dim).map(|x| (s.position[x] - a[x]).powi(2)).sum::<f32>() <= kp)
                .count();
            let v = qb.point(&w, &a, Kernel { sigma }).unwrap();
            prop_assert_eq!(v.density > 0.0, near > 0);
        }
    }
}

/// The bounds are tight enough to mean something: on a dense compact map the largest actual error
/// reaches at least half its point's stated bound, and u8 positions really are quantized.
#[test]
fn stated_bounds_are_tight() {
    let f = fixture_with(11, 3000, 2, 8, 1, [1; 32], Storage::COMPACT);
    let (_, maps) = open(&f);
    let m = &maps[0];
    let (mut worst, mut moved) = (0.0f32, 0);
    for i in 0..3000u32 {
        let (p, e) = (m.position(i).unwrap(), m.position_error(i).unwrap());
        for a in 0..2 {
            let err = (p[a] - f.positions[0][i as usize * 2 + a]).abs();
            worst = worst.max(err / e[a]);
            moved += (err > 0.0) as usize;
        }
    }
    assert!(
        (0.5..=1.0).contains(&worst),
        "largest error / bound = {worst}"
    );
    assert!(moved > 3000, "only {moved} of 6000 coordinates changed");
    let ce = m.color_error();
    assert!(ce.iter().all(|&e| e > 0.0 && e < 2.0 / 255.0), "{ce:?}");
}

#[test]
fn range_queries_without_node_color_sums_are_errors() {
    let no_sums = Storage {
        node_colors: false,
        ..Storage::COMPACT
    };
    let f = fixture_with(5, 200, 2, 4, 2, [1; 32], Storage::COMPACT);
    let g = fixture_with(5, 200, 2, 4, 2, [1; 32], no_sums);
    // Map 1 of the blend lacks node color sums.
    let proxy = Proxy::open(&f.proxy).unwrap();
    let maps = [
        Map::open(&f.maps[0]).unwrap(),
        Map::open(&g.maps[1]).unwrap(),
    ];
    assert!(!maps[1].has_node_colors());
    let blend = Blend::new(proxy, &maps).unwrap();
    assert!(!blend.has_node_colors());
    let w = [0.5, 0.5];
    let missing = Error::MissingAttribute {
        map: 1,
        attribute: "node color sums",
    };
    assert_eq!(
        blend.range(&w, &[0.2, 0.2], &[0.8, 0.8]),
        Err(missing.clone())
    );
    assert!(missing.to_string().contains("[storage]"));
    // Everything else still answers, colors included.
    let v = blend.point(&w, &[0.5, 0.5], Kernel { sigma: 0.1 }).unwrap();
    assert!(v.density > 0.0 && v.color.iter().any(|&c| c > 0.0));
    assert!(blend.sample(&w, 3).is_ok());
    let sizes = blend.prepared_sizes();
    assert_eq!(sizes.node_colors, 0);
    assert!(sizes.colors > 0);
    let mut bufs = [
        vec![0.0; sizes.positions],
        vec![0.0; sizes.colors],
        vec![0.0; sizes.node_boxes],
        vec![],
    ];
    let [p, c, b, nc] = &mut bufs;
    let prep = blend
        .prepare(
            &w,
            PreparedBuffers {
                positions: p,
                colors: c,
                node_boxes: b,
                node_colors: nc,
            },
        )
        .unwrap();
    assert_eq!(
        prep.range(&[0.2, 0.2], &[0.8, 0.8]),
        Err(Error::MissingAttribute {
            map: 1,
            attribute: "node color sums",
        })
    );
    assert_eq!(
        prep.point(&[0.5, 0.5], Kernel { sigma: 0.1 }).unwrap(),
        v,
        "prepared answers equal the blend's"
    );
    // A blend with a colorless map has no color, so range queries need no color sums.
    let none = fixture_with(
        5,
        200,
        2,
        4,
        2,
        [1; 32],
        Storage {
            colors: None,
            node_colors: false,
            ..Storage::COMPACT
        },
    );
    let maps = [
        Map::open(&g.maps[0]).unwrap(),
        Map::open(&none.maps[1]).unwrap(),
    ];
    assert!(!maps[1].has_color() && maps[1].color(0).is_none());
    let blend = Blend::new(Proxy::open(&f.proxy).unwrap(), &maps).unwrap();
    assert!(!blend.has_color() && blend.has_node_colors());
    let r = blend.range(&w, &[0.0, 0.0], &[1.0, 1.0]).unwrap();
    assert_eq!((r.count, r.color), (200, [0.0; 3]));
}

/// Archive sizes follow the layout: compact 2D with color takes 2 + 3 bytes per point plus
/// 8 + 12 bytes per internal node; full takes 8 + 12 and 16 + 12, and its spacings one byte per
/// point and one per internal node (compact stores none).
#[test]
fn archive_sizes_follow_the_layout() {
    let n = 4096usize;
    let leaf = 8;
    let internal = (1usize << otbake_formats::tree::depth(n as u32, leaf)) - 1;
    let size = |s: Storage| fixture_with(1, n, 2, leaf, 1, [1; 32], s).maps[0].len();
    let overhead = 512;
    let compact = size(Storage::COMPACT);
    let bulk = n * (2 + 3) + internal * (8 + 12);
    assert!(
        compact >= bulk && compact <= bulk + overhead,
        "{compact} vs {bulk}"
    );
    let full = size(Storage::FULL);
    let bulk = n * (8 + 12 + 1) + internal * (16 + 12 + 1);
    assert!(full >= bulk && full <= bulk + overhead, "{full} vs {bulk}");
    let density_only = size(Storage {
        colors: None,
        node_colors: false,
        ..Storage::COMPACT
    });
    let bulk = n * 2 + internal * 8;
    assert!(density_only >= bulk && density_only <= bulk + overhead);
    let spaced = size(Storage {
        spacings: true,
        ..Storage::COMPACT
    });
    let bulk = n * (2 + 3 + 1) + internal * (8 + 12 + 1);
    assert!(
        spaced >= bulk && spaced <= bulk + overhead,
        "{spaced} vs {bulk}"
    );
}
