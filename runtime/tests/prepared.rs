//! A prepared blend answers every query with exactly the bits of the blend it was prepared from, and
//! region queries (one traversal per box of cells) equal per-cell point queries and the full splat
//! exactly (property tests over full and quantized storages; every comparison is on the `f32` bit
//! patterns).
#![allow(clippy::needless_range_loop)]

mod common;

use common::{fixture, fixture_with, weights, Fixture, Rng, STORAGES};
use otbake_runtime::{
    Blend, Error, Kernel, Map, PointValue, Prepared, PreparedBuffers, Proxy, Region, SplatTarget,
    MAX_DIM,
};
use proptest::prelude::*;

fn open(f: &Fixture) -> (Proxy<'_>, Vec<Map<'_>>) {
    (
        Proxy::open(&f.proxy).unwrap(),
        f.maps.iter().map(|m| Map::open(m).unwrap()).collect(),
    )
}

/// Owned buffers for `Blend::prepare`.
struct Buffers([Vec<f32>; 4]);

impl Buffers {
    fn new(blend: &Blend<'_, '_>) -> Self {
        let s = blend.prepared_sizes();
        Self([
            vec![f32::NAN; s.positions],
            vec![f32::NAN; s.colors],
            vec![f32::NAN; s.node_boxes],
            vec![f32::NAN; s.node_colors],
        ])
    }
    fn prepare<'b>(&'b mut self, blend: &Blend<'_, '_>, w: &[f32]) -> Prepared<'b> {
        let [p, c, b, nc] = &mut self.0;
        blend
            .prepare(
                w,
                PreparedBuffers {
                    positions: p,
                    colors: c,
                    node_boxes: b,
                    node_colors: nc,
                },
            )
            .unwrap()
    }
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

fn all_bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Center of every cell of `region` (axis 0 fastest), as callers compute it.
fn centers(dim: usize, region: &Region) -> Vec<Vec<f32>> {
    let cells: usize = region.size[..dim].iter().map(|&s| s as usize).product();
    (0..cells)
        .map(|cell| {
            let mut rest = cell;
            (0..dim)
                .map(|a| {
                    let i = region.start[a] as usize + rest % region.size[a] as usize;
                    rest /= region.size[a] as usize;
                    (i as f32 + 0.5) / region.res[a] as f32
                })
                .collect()
        })
        .collect()
}

/// A random region of a random grid.
fn region(rng: &mut Rng, dim: usize, max_res: u32) -> Region {
    let mut r = Region::full([1; MAX_DIM]);
    for a in 0..dim {
        let res = 1 + (rng.next() % max_res as u64) as u32;
        let start = (rng.next() % res as u64) as u32;
        let size = 1 + (rng.next() % (res - start) as u64) as u32;
        r.res[a] = res;
        r.start[a] = start;
        r.size[a] = size;
    }
    r
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn prepared_queries_equal_blend_queries(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                            leaf in 1u32..8, k in 1usize..4, sigma in 0.01f32..0.3,
                                            st in 0..STORAGES.len()) {
        let f = fixture_with(seed, n, dim, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x5eed);
        let w = weights(&mut rng, k);
        let mut buffers = Buffers::new(&blend);
        let prep = buffers.prepare(&blend, &w);
        prop_assert_eq!(prep.mean_mass().to_bits(), f.mean_mass(&w).to_bits());
        let kernel = Kernel { sigma };
        for _ in 0..8 {
            let p: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let q: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            prop_assert_eq!(bits(&prep.point(&p, kernel).unwrap()), bits(&blend.point(&w, &p, kernel).unwrap()));
            let lo: Vec<f32> = p.iter().zip(&q).map(|(a, b)| a.min(*b)).collect();
            let hi: Vec<f32> = p.iter().zip(&q).map(|(a, b)| a.max(*b)).collect();
            let (a, b) = (prep.range(&lo, &hi).unwrap(), blend.range(&w, &lo, &hi).unwrap());
            prop_assert_eq!(a.count, b.count);
            prop_assert_eq!(a.mass.to_bits(), b.mass.to_bits());
            prop_assert_eq!(a.color.map(f32::to_bits), b.color.map(f32::to_bits));
        }
        for i in 0..n as u32 {
            let (a, b) = (prep.sample(i).unwrap(), blend.sample(&w, i).unwrap());
            prop_assert_eq!(a.position.map(f32::to_bits), b.position.map(f32::to_bits));
            prop_assert_eq!(a.color.map(f32::to_bits), b.color.map(f32::to_bits));
        }
        let past_end = matches!(prep.sample(n as u32), Err(Error::IndexOutOfRange { .. }));
        prop_assert!(past_end);
        // Splats of the whole grid.
        if dim <= 3 {
            let res = 2 + (seed % 7) as u32;
            let cells = (res as usize).pow(dim as u32);
            let mut r = [1u32; MAX_DIM];
            r[..dim].fill(res);
            let kernel = Kernel { sigma: 0.7 / res as f32 };
            let mut da = vec![0.0f32; cells];
            let mut ca = vec![0.0f32; cells * 3];
            let mut db = da.clone();
            let mut cb = ca.clone();
            prep.splat(kernel, SplatTarget { res: r, density: &mut da, color: Some(&mut ca) }).unwrap();
            blend.splat(&w, kernel, SplatTarget { res: r, density: &mut db, color: Some(&mut cb) }).unwrap();
            prop_assert_eq!(all_bits(&da), all_bits(&db));
            prop_assert_eq!(all_bits(&ca), all_bits(&cb));
        }
    }

    #[test]
    fn point_grids_equal_point_queries(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                       leaf in 1u32..8, k in 1usize..4, sigma_cells in 0.2f32..3.0,
                                            st in 0..STORAGES.len()) {
        let f = fixture_with(seed, n, dim, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x9e1d);
        let w = weights(&mut rng, k);
        let mut buffers = Buffers::new(&blend);
        let prep = buffers.prepare(&blend, &w);
        let max_res = [0, 300, 40, 12, 7][dim];
        for _ in 0..3 {
            let region = region(&mut rng, dim, max_res);
            let kernel = Kernel { sigma: sigma_cells / region.res[0] as f32 };
            let cs = centers(dim, &region);
            let mut out = vec![PointValue { density: f32::NAN, mass: 1.0, color: [2.0; 3] }; cs.len()];
            prep.point_grid(kernel, region, &mut out).unwrap();
            for (c, v) in cs.iter().zip(&out) {
                let want = blend.point(&w, c, kernel).unwrap();
                prop_assert_eq!(bits(v), bits(&want), "cell at {:?}: {:?} vs {:?}", c, v, want);
            }
        }
    }

    #[test]
    fn region_splats_equal_the_full_splat(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                          leaf in 1u32..8, k in 1usize..4, sigma_cells in 0.2f32..3.0,
                                            st in 0..STORAGES.len()) {
        let f = fixture_with(seed, n, dim, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x5917);
        let w = weights(&mut rng, k);
        let mut buffers = Buffers::new(&blend);
        let prep = buffers.prepare(&blend, &w);
        let max_res = [0, 300, 40, 12, 7][dim];
        let region = region(&mut rng, dim, max_res);
        let kernel = Kernel { sigma: sigma_cells / region.res[0] as f32 };
        let full: usize = region.res[..dim].iter().map(|&r| r as usize).product();
        let mut density = vec![0.0f32; full];
        let mut color = vec![0.0f32; full * 3];
        blend.splat(&w, kernel, SplatTarget { res: region.res, density: &mut density, color: Some(&mut color) }).unwrap();
        let cells: usize = region.size[..dim].iter().map(|&r| r as usize).product();
        let mut rd = vec![0.0f32; cells];
        let mut rc = vec![0.0f32; cells * 3];
        prep.splat_region(kernel, region, &mut rd, Some(&mut rc)).unwrap();
        // Cell `cell` of the region is cell `global` of the grid.
        for cell in 0..cells {
            let (mut rest, mut global, mut stride) = (cell, 0, 1);
            for a in 0..dim {
                global += (region.start[a] as usize + rest % region.size[a] as usize) * stride;
                rest /= region.size[a] as usize;
                stride *= region.res[a] as usize;
            }
            prop_assert_eq!(rd[cell].to_bits(), density[global].to_bits(), "cell {}", cell);
            prop_assert_eq!(all_bits(&rc[cell * 3..cell * 3 + 3]), all_bits(&color[global * 3..global * 3 + 3]));
        }
    }
}

#[test]
fn bands_tile_an_image_exactly() {
    let f = fixture(42, 2000, 2, 4, 3, [1; 32]);
    let (proxy, maps) = open(&f);
    let blend = Blend::new(proxy, &maps).unwrap();
    let w = [0.2f32, 0.5, 0.3];
    let mut buffers = Buffers::new(&blend);
    let prep = buffers.prepare(&blend, &w);
    let (width, height) = (37u32, 29u32);
    let res = [width, height, 1, 1];
    let kernel = Kernel {
        sigma: 1.3 / width as f32,
    };
    let mut whole = vec![PointValue::default(); (width * height) as usize];
    prep.point_grid(kernel, Region::full(res), &mut whole)
        .unwrap();
    let mut banded = vec![PointValue::default(); whole.len()];
    for (b, band) in banded.chunks_mut(width as usize * 4).enumerate() {
        let rows = band.len() as u32 / width;
        prep.point_grid(kernel, Region::rows(res, b as u32 * 4, rows), band)
            .unwrap();
    }
    assert_eq!(
        whole.iter().map(bits).collect::<Vec<_>>(),
        banded.iter().map(bits).collect::<Vec<_>>()
    );
    assert!(whole.iter().any(|v| v.density > 0.0));
}

#[test]
fn bad_buffers_and_regions_are_errors() {
    let f = fixture(3, 100, 2, 4, 2, [1; 32]);
    let (proxy, maps) = open(&f);
    let blend = Blend::new(proxy, &maps).unwrap();
    let sizes = blend.prepared_sizes();
    assert_eq!(sizes.positions, 200);
    assert_eq!(sizes.colors, 300);
    let mut p = vec![0.0; sizes.positions];
    let mut c = vec![0.0; sizes.colors];
    let mut b = vec![0.0; sizes.node_boxes - 1];
    let mut nc = vec![0.0; sizes.node_colors];
    let short = blend.prepare(
        &[0.5, 0.5],
        PreparedBuffers {
            positions: &mut p,
            colors: &mut c,
            node_boxes: &mut b,
            node_colors: &mut nc,
        },
    );
    assert!(matches!(short, Err(Error::BufferSize { .. })));
    let mut buffers = Buffers::new(&blend);
    let [p, c, b, nc] = &mut buffers.0;
    let bad_weights = blend.prepare(
        &[0.5, 0.6],
        PreparedBuffers {
            positions: p,
            colors: c,
            node_boxes: b,
            node_colors: nc,
        },
    );
    assert!(matches!(bad_weights, Err(Error::WeightSum { .. })));
    // Longer buffers are fine.
    let mut buffers = Buffers::new(&blend);
    for v in &mut buffers.0 {
        v.push(0.0);
    }
    let prep = buffers.prepare(&blend, &[0.5, 0.5]);
    let k = Kernel { sigma: 0.05 };
    assert!(matches!(prep.point(&[0.5], k), Err(Error::PointDim { .. })));
    assert!(matches!(
        prep.point(&[0.5, f32::NAN], k),
        Err(Error::BadCoordinate)
    ));
    assert!(matches!(
        prep.point(&[0.5, 0.5], Kernel { sigma: 0.0 }),
        Err(Error::BadSigma)
    ));
    let mut out = vec![PointValue::default(); 12];
    let res = [4, 4, 1, 1];
    assert!(matches!(
        prep.point_grid(k, Region::full(res), &mut out),
        Err(Error::BufferSize {
            expected: 16,
            found: 12
        })
    ));
    assert!(prep
        .point_grid(k, Region::rows(res, 1, 3), &mut out)
        .is_ok());
    assert!(matches!(
        prep.point_grid(k, Region::rows(res, 2, 3), &mut out),
        Err(Error::BadRegion { axis: 1 })
    ));
    assert!(matches!(
        prep.point_grid(k, Region::full([0, 4, 1, 1]), &mut []),
        Err(Error::BadRegion { axis: 0 })
    ));
    // An empty region is nothing to do.
    assert!(prep.point_grid(k, Region::rows(res, 4, 0), &mut []).is_ok());
    let mut d = vec![0.0; 12];
    let mut col = vec![0.0; 35];
    assert!(matches!(
        prep.splat_region(k, Region::rows(res, 1, 3), &mut d, Some(&mut col)),
        Err(Error::BufferSize {
            expected: 36,
            found: 35
        })
    ));
    let mut d = vec![0.0; 3];
    assert!(matches!(
        prep.splat(
            k,
            SplatTarget {
                res: [2, 2, 1, 1],
                density: &mut d,
                color: None
            }
        ),
        Err(Error::BufferSize {
            expected: 4,
            found: 3
        })
    ));
    // RGBA cells: four per cell, the region inside its grid, a good kernel and (mixed on the fly)
    // good weights; the blended mean mass is the prepared one.
    let mut rgba = vec![0.0; 47];
    let w = [0.5, 0.5];
    for r in [
        prep.splat_region_rgba(k, Region::rows(res, 1, 3), &mut rgba),
        blend.splat_region_rgba(&w, k, Region::rows(res, 1, 3), &mut rgba),
    ] {
        assert!(matches!(
            r,
            Err(Error::BufferSize {
                expected: 48,
                found: 47
            })
        ));
    }
    let mut rgba = vec![0.0; 48];
    assert!(prep
        .splat_region_rgba(k, Region::rows(res, 1, 3), &mut rgba)
        .is_ok());
    assert!(blend
        .splat_region_rgba(&w, k, Region::rows(res, 1, 3), &mut rgba)
        .is_ok());
    assert!(matches!(
        blend.splat_region_rgba(&w, k, Region::rows(res, 2, 3), &mut rgba),
        Err(Error::BadRegion { axis: 1 })
    ));
    assert!(matches!(
        prep.splat_region_rgba(Kernel { sigma: -1.0 }, Region::rows(res, 1, 3), &mut rgba),
        Err(Error::BadSigma)
    ));
    assert!(matches!(
        blend.splat_region_rgba(&[0.5, 0.6], k, Region::rows(res, 1, 3), &mut rgba),
        Err(Error::WeightSum { .. })
    ));
    assert!(blend
        .splat_region_rgba(&w, k, Region::rows(res, 4, 0), &mut [])
        .is_ok());
    assert_eq!(blend.mean_mass(&w).unwrap(), prep.mean_mass());
    assert!(matches!(
        blend.mean_mass(&[0.5]),
        Err(Error::WeightCount { .. })
    ));
}

/// `prepare_with` gives `prepare`'s bits whether `join` runs the halves on two threads, in
/// reverse order, or not at all (they then run after it), for full and quantized storages.
#[test]
fn prepare_with_any_join_equals_prepare() {
    for (st, storage) in STORAGES.iter().enumerate() {
        let f = fixture_with(11 + st as u64, 700, 2, 4, 3, [1; 32], *storage);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let w = [0.2f32, 0.45, 0.35];
        let sizes = blend.prepared_sizes();
        let mut want = vec![f32::NAN; sizes.total()];
        blend.prepare(&w, sizes.split(&mut want).unwrap()).unwrap();
        type Half<'a> = &'a mut (dyn FnMut() + Send);
        type Join = dyn Fn(Half<'_>, Half<'_>);
        let joins: [&Join; 3] = [
            &|a, b| {
                std::thread::scope(|s| {
                    s.spawn(a);
                    b();
                })
            },
            &|a, b| {
                b();
                a();
            },
            &|_, _| {},
        ];
        for (j, join) in joins.iter().enumerate() {
            let mut got = vec![f32::NAN; sizes.total()];
            blend
                .prepare_with(&w, sizes.split(&mut got).unwrap(), |a, b| join(a, b))
                .unwrap();
            assert_eq!(all_bits(&got), all_bits(&want), "storage {st}, join {j}");
        }
    }
}
