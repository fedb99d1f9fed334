//! Region queries on the paths images take: 2D grids with narrow kernels (σ from 0.15 to 0.8
//! cell, where points go through fixed 4×4 blocks and, near the widest, some through the general
//! paths in between), bands and tiles, regions narrower than a block. Point grids must equal
//! per-cell point queries and region splats the full splat, bit for bit, whatever the buffers held
//! before (a splat adds); and splats must equal point queries within the tolerance the `splat`
//! module states, in every dimension.
#![allow(clippy::needless_range_loop)]

mod common;

use common::{bits, fixture_colored, fixture_with, global, open, prepare, weights, Rng, STORAGES};
use otbake_runtime::{
    Blend, Kernel, PointValue, Region, SplatTarget, MAX_DIM, SPLAT_TERM_TOLERANCE,
};
use proptest::prelude::*;

/// Checks RGBA region cells (`rgba`, four per cell of `region`: color, then density) against the
/// planar buffers of the whole grid (`density`, `color`): the same bits, channel by channel.
fn assert_rgba(
    dim: usize,
    region: &Region,
    rgba: &[f32],
    density: &[f32],
    color: &[f32],
) -> Result<(), TestCaseError> {
    for cell in 0..region.cells(dim).unwrap() {
        let (g, _) = global(dim, region, cell);
        prop_assert_eq!(
            rgba[cell * 4 + 3].to_bits(),
            density[g].to_bits(),
            "{:?} cell {} density",
            region,
            cell
        );
        for a in 0..3 {
            prop_assert_eq!(
                rgba[cell * 4 + a].to_bits(),
                color[g * 3 + a].to_bits(),
                "{:?} cell {} channel {}",
                region,
                cell,
                a
            );
        }
    }
    Ok(())
}

/// Start values of a buffer a splat adds to: arbitrary, negative zeros among them.
fn start_value(i: usize) -> f32 {
    match i % 5 {
        0 => -0.0,
        1 => 0.0,
        2 => 1.5,
        3 => -2.25,
        _ => i as f32 * 1e-3,
    }
}

/// RGBA cells of `region` holding the start values the whole grid's planar buffers hold there.
fn rgba_start(dim: usize, region: &Region, density: &[f32], color: &[f32]) -> Vec<f32> {
    let cells = region.cells(dim).unwrap();
    let mut rgba = vec![0.0f32; cells * 4];
    for cell in 0..cells {
        let (g, _) = global(dim, region, cell);
        rgba[cell * 4..cell * 4 + 3].copy_from_slice(&color[g * 3..g * 3 + 3]);
        rgba[cell * 4 + 3] = density[g];
    }
    rgba
}

/// A 2D grid of up to `max` cells per axis and a random region of it: whole grid, a band, a tile,
/// or a sliver narrower than a block.
fn region2(rng: &mut Rng, max: u32) -> Region {
    let res = [
        1 + (rng.next() % max as u64) as u32,
        1 + (rng.next() % max as u64) as u32,
        1,
        1,
    ];
    let mut r = Region::full(res);
    match rng.next() % 4 {
        0 => {}
        1 => {
            let first = (rng.next() % res[1] as u64) as u32;
            let rows = 1 + (rng.next() % (res[1] - first) as u64) as u32;
            r = Region::rows(res, first, rows);
        }
        _ => {
            for a in 0..2 {
                r.start[a] = (rng.next() % res[a] as u64) as u32;
                let room = res[a] - r.start[a];
                // Regions up to 8 cells wide (narrower than a block, or than the widest span) are
                // as likely as any other.
                let most = if rng.next().is_multiple_of(2) {
                    8
                } else {
                    room
                };
                r.size[a] = 1 + (rng.next() % room.min(most) as u64) as u32;
            }
        }
    }
    r
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn narrow_kernel_point_grids_equal_point_queries(seed in 0u64..10_000, n in 1usize..400,
                                                     leaf in 1u32..9, k in 1usize..4,
                                                     sigma_cells in 0.15f32..0.8,
                                                     st in 0..STORAGES.len()) {
        let f = fixture_with(seed, n, 2, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x91a7e);
        let w = weights(&mut rng, k);
        let mut store = Vec::new();
        let prep = prepare(&blend, &w, &mut store);
        for _ in 0..2 {
            let region = region2(&mut rng, 80);
            let kernel = Kernel { sigma: sigma_cells / region.res[0].max(region.res[1]) as f32 };
            let cells = region.cells(2).unwrap();
            let mut out = vec![PointValue { density: f32::NAN, mass: 3.0, color: [-0.0; 3] }; cells];
            prep.point_grid(kernel, region, &mut out).unwrap();
            for (cell, v) in out.iter().enumerate() {
                let (_, c) = global(2, &region, cell);
                let want = prep.point(&c, kernel).unwrap();
                prop_assert_eq!(bits(v), bits(&want), "{:?} cell {} at {:?}", region, cell, c);
            }
        }
    }

    /// Regions 4–7 cells wide at σ near 0.8 cell: points whose span is 5 cells wide take the
    /// batched general path, the others the blocks, interleaved in point order.
    #[test]
    fn mixed_paths_keep_point_order(seed in 0u64..10_000, n in 50usize..400, leaf in 1u32..9,
                                    sigma_cells in 0.7f32..0.8, width in 4u32..8, res in 8u32..40) {
        let f = fixture_with(seed, n, 2, leaf, 2, [1; 32], STORAGES[0]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x3e1d);
        let w = weights(&mut rng, 2);
        let mut store = Vec::new();
        let prep = prepare(&blend, &w, &mut store);
        let start = (rng.next() % (res - width + 1) as u64) as u32;
        let region = Region { res: [res, res, 1, 1], start: [start, 0, 0, 0], size: [width, res, 1, 1] };
        let kernel = Kernel { sigma: sigma_cells / res as f32 };
        let mut out = vec![PointValue::default(); region.cells(2).unwrap()];
        prep.point_grid(kernel, region, &mut out).unwrap();
        for (cell, v) in out.iter().enumerate() {
            let (_, c) = global(2, &region, cell);
            prop_assert_eq!(bits(v), bits(&prep.point(&c, kernel).unwrap()), "cell {}", cell);
        }
    }

    #[test]
    fn narrow_kernel_region_splats_equal_the_full_splat(seed in 0u64..10_000, n in 1usize..400,
                                                        leaf in 1u32..9, k in 1usize..4,
                                                        sigma_cells in 0.15f32..0.8,
                                                        st in 0..STORAGES.len()) {
        let f = fixture_with(seed, n, 2, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x5b1a7);
        let w = weights(&mut rng, k);
        let mut store = Vec::new();
        let prep = prepare(&blend, &w, &mut store);
        let region = region2(&mut rng, 80);
        let kernel = Kernel { sigma: sigma_cells / region.res[0].max(region.res[1]) as f32 };
        // Buffers start with arbitrary values, negative zeros among them: a splat adds to them,
        // and cells no point reaches must keep their bits.
        let full = (region.res[0] * region.res[1]) as usize;
        let start = |i: usize| match i % 5 { 0 => -0.0, 1 => 0.0, 2 => 1.5, 3 => -2.25, _ => i as f32 * 1e-3 };
        let mut density: Vec<f32> = (0..full).map(start).collect();
        let mut color: Vec<f32> = (0..full * 3).map(|i| start(i + 1)).collect();
        let cells = region.cells(2).unwrap();
        let mut rd = vec![0.0f32; cells];
        let mut rc = vec![0.0f32; cells * 3];
        for cell in 0..cells {
            let (g, _) = global(2, &region, cell);
            rd[cell] = density[g];
            rc[cell * 3..cell * 3 + 3].copy_from_slice(&color[g * 3..g * 3 + 3]);
        }
        blend.splat(&w, kernel, SplatTarget { res: region.res, density: &mut density, color: Some(&mut color) }).unwrap();
        prep.splat_region(kernel, region, &mut rd, Some(&mut rc)).unwrap();
        for cell in 0..cells {
            let (g, _) = global(2, &region, cell);
            prop_assert_eq!(rd[cell].to_bits(), density[g].to_bits(), "{:?} cell {}", region, cell);
            for a in 0..3 {
                prop_assert_eq!(rc[cell * 3 + a].to_bits(), color[g * 3 + a].to_bits(), "{:?} cell {} channel {}", region, cell, a);
            }
        }
    }

    /// RGBA region splats, prepared or mixed on the fly (four `f32` maps in one pass), in every
    /// dimension and storage, with kernels on both sides of the 3×3 blocks' limit (σ = ½ cell) and
    /// wide ones: the bits of the full (planar) splat, over any start values.
    #[test]
    fn rgba_region_splats_equal_the_full_splat(seed in 0u64..10_000, n in 1usize..400,
                                               dim in 1usize..=3, leaf in 1u32..9, k in 1usize..=4,
                                               sigma_cells in 0.1f32..1.2, wide in 0u32..4,
                                               st in 0..STORAGES.len() + 1) {
        let storage = STORAGES.get(st).copied().unwrap_or(otbake_runtime::Storage {
            colors: None,
            node_colors: false,
            ..otbake_runtime::Storage::FULL
        });
        let f = fixture_with(seed, n, dim, leaf, k, [1; 32], storage);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x76ba);
        let w = weights(&mut rng, k);
        let mut store = Vec::new();
        let prep = prepare(&blend, &w, &mut store);
        let region = if dim == 2 {
            region2(&mut rng, 80)
        } else {
            let mut res = [1u32; MAX_DIM];
            for r in res.iter_mut().take(dim) {
                *r = 1 + (rng.next() % [0u64, 300, 0, 14][dim]) as u32;
            }
            let mut r = Region::full(res);
            for a in 0..dim {
                r.start[a] = (rng.next() % res[a] as u64) as u32;
                r.size[a] = 1 + (rng.next() % (res[a] - r.start[a]) as u64) as u32;
            }
            r
        };
        let finest = *region.res[..dim].iter().max().unwrap();
        // One case in four a wide kernel (general paths, 3–6 cells).
        let sigma_cells = if wide == 0 { sigma_cells * 5.0 } else { sigma_cells };
        let kernel = Kernel { sigma: sigma_cells / finest as f32 };
        let full: usize = region.res[..dim].iter().map(|&r| r as usize).product();
        let mut density: Vec<f32> = (0..full).map(start_value).collect();
        let mut color: Vec<f32> = (0..full * 3).map(|i| start_value(i + 1)).collect();
        let mut a = rgba_start(dim, &region, &density, &color);
        let mut b = a.clone();
        blend.splat(&w, kernel, SplatTarget { res: region.res, density: &mut density, color: Some(&mut color) }).unwrap();
        prep.splat_region_rgba(kernel, region, &mut a).unwrap();
        assert_rgba(dim, &region, &a, &density, &color)?;
        blend.splat_region_rgba(&w, kernel, region, &mut b).unwrap();
        assert_rgba(dim, &region, &b, &density, &color)?;
    }

    /// RGBA splats of blends whose colors are negative, `−0.0` or zero: the 3×3 blocks send
    /// points with a negative or `−0.0` channel the general path (a dropped cell's `−0.0` weight
    /// would not vanish from their products), and every cell keeps the full splat's bits.
    #[test]
    fn rgba_splats_of_signed_colors_equal_the_full_splat(seed in 0u64..10_000, n in 1usize..400,
                                                         leaf in 1u32..9, k in 1usize..=4,
                                                         sigma_cells in 0.1f32..0.5,
                                                         st in 0..STORAGES.len()) {
        let color = |u: f32| if u < 0.1 { -0.0 } else if u < 0.2 { 0.0 } else { (u - 0.5) * 4.0 };
        let f = fixture_colored(seed, n, 2, leaf, k, [1; 32], STORAGES[st], color);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x51a7);
        let w = weights(&mut rng, k);
        let mut store = Vec::new();
        let prep = prepare(&blend, &w, &mut store);
        let region = region2(&mut rng, 80);
        let finest = *region.res[..2].iter().max().unwrap();
        let kernel = Kernel { sigma: sigma_cells / finest as f32 };
        let cells: usize = region.res[..2].iter().map(|&r| r as usize).product();
        let mut density: Vec<f32> = (0..cells).map(start_value).collect();
        let mut color: Vec<f32> = (0..cells * 3).map(|i| start_value(i + 1)).collect();
        let mut a = rgba_start(2, &region, &density, &color);
        let mut b = a.clone();
        blend.splat(&w, kernel, SplatTarget { res: region.res, density: &mut density, color: Some(&mut color) }).unwrap();
        prep.splat_region_rgba(kernel, region, &mut a).unwrap();
        assert_rgba(2, &region, &a, &density, &color)?;
        blend.splat_region_rgba(&w, kernel, region, &mut b).unwrap();
        assert_rgba(2, &region, &b, &density, &color)?;
    }

    /// The tolerance of `otbake_runtime::splat`'s documentation: a cell reached by `m` points
    /// differs from the point query at its center by at most `(SPLAT_TERM_TOLERANCE + 2m·2⁻²⁴)`
    /// times the sum of the absolute values of its terms (computed here in f64, over the points
    /// the runtime's own f32 cutoff test counts) — and by nothing where no point counts.
    #[test]
    fn splats_are_point_queries_within_the_stated_tolerance(seed in 0u64..10_000, n in 1usize..300,
                                                            dim in 1usize..=3, leaf in 1u32..9,
                                                            k in 1usize..4, sigma_cells in 0.15f32..2.5,
                                                            st in 0..STORAGES.len()) {
        let f = fixture_with(seed, n, dim, leaf, k, [1; 32], STORAGES[st]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x70e2);
        let w = weights(&mut rng, k);
        let mut store = Vec::new();
        let prep = prepare(&blend, &w, &mut store);
        let max_res = [0u64, 200, 48, 12][dim];
        let mut res = [1u32; MAX_DIM];
        for r in res.iter_mut().take(dim) {
            *r = 1 + (rng.next() % max_res) as u32;
        }
        let finest = *res[..dim].iter().max().unwrap();
        let kernel = Kernel { sigma: sigma_cells / finest as f32 };
        let kp = kernel.prepare(dim).unwrap();
        let region = Region::full(res);
        let cells = region.cells(dim).unwrap();
        let mut density = vec![0.0f32; cells];
        let mut color = vec![0.0f32; cells * 3];
        prep.splat_region(kernel, region, &mut density, Some(&mut color)).unwrap();
        let (pos, col) = (prep.positions(), prep.colors());
        let scale = kp.norm as f64 / n as f64;
        let mm = prep.mean_mass() as f64;
        let sigma = kernel.sigma as f64;
        let eps = 2f64.powi(-24);
        for cell in 0..cells {
            let (_, c) = global(dim, &region, cell);
            let want = prep.point(&c, kernel).unwrap();
            // The terms the runtime counts (its own f32 distance and cutoff), in f64.
            let (mut m, mut sd, mut sc) = (0usize, 0.0f64, [0.0f64; 3]);
            for i in 0..n {
                let mut r2 = 0.0f32;
                for a in 0..dim {
                    let t = pos[i * dim + a] - c[a];
                    r2 += t * t;
                }
                if r2 <= kp.radius2 {
                    let g = (-(r2 as f64) / (2.0 * sigma * sigma)).exp() * scale;
                    m += 1;
                    sd += g;
                    for a in 0..3 {
                        sc[a] += (g * col[i * 3 + a] as f64 * mm).abs();
                    }
                }
            }
            let rel = SPLAT_TERM_TOLERANCE as f64 + 2.0 * m as f64 * eps;
            let diff = (density[cell] as f64 - want.density as f64).abs();
            prop_assert!(diff <= rel * sd, "cell {} ({} points): splat {} vs point {} (diff {:e} > {:e})",
                         cell, m, density[cell], want.density, diff, rel * sd);
            for a in 0..3 {
                let diff = (color[cell * 3 + a] as f64 - want.color[a] as f64).abs();
                prop_assert!(diff <= rel * sc[a], "cell {} channel {}: splat {} vs point {}",
                             cell, a, color[cell * 3 + a], want.color[a]);
            }
        }
    }
}
