//! Region queries on image-sized grids and at the edges of exactness: whole images against their
//! references, points exactly on a cutoff tie, and grids much finer than the points (split from
//! `regions.rs`, whose proptests cover random regions).
#![allow(clippy::needless_range_loop)]

mod common;

use common::{bits, fixture_with, global, open, prepare, Rng, STORAGES};
use otbake_runtime::{Blend, Kernel, Map, PointValue, Proxy, Region, SplatTarget};

/// The shape of the benchmark (a 256² image at σ = 0.5 px, whole and in bands, thousands of points
/// in one region): the same bits as per-pixel queries and as the full splat.
#[test]
fn image_sized_regions_match_their_references() {
    let f = fixture_with(7, 6000, 2, 8, 3, [1; 32], STORAGES[0]);
    let (proxy, maps) = open(&f);
    let blend = Blend::new(proxy, &maps).unwrap();
    let w = [0.3f32, 0.3, 0.4];
    let mut store = Vec::new();
    let prep = prepare(&blend, &w, &mut store);
    let res = [256u32, 256, 1, 1];
    let kernel = Kernel { sigma: 0.5 / 256.0 };
    let mut whole = vec![PointValue::default(); 256 * 256];
    prep.point_grid(kernel, Region::full(res), &mut whole)
        .unwrap();
    let mut banded = vec![PointValue::default(); 256 * 256];
    for (b, band) in banded.chunks_mut(256 * 24).enumerate() {
        let rows = (band.len() / 256) as u32;
        prep.point_grid(kernel, Region::rows(res, b as u32 * 24, rows), band)
            .unwrap();
    }
    for (cell, (a, b)) in whole.iter().zip(&banded).enumerate() {
        let c = [
            ((cell % 256) as f32 + 0.5) / 256.0,
            ((cell / 256) as f32 + 0.5) / 256.0,
        ];
        let want = prep.point(&c, kernel).unwrap();
        assert_eq!(bits(a), bits(&want), "cell {cell}");
        assert_eq!(bits(b), bits(&want), "cell {cell} (bands)");
    }
    assert!(whole.iter().filter(|v| v.density > 0.0).count() > 1000);
    let mut density = vec![0.0f32; 256 * 256];
    let mut color = vec![0.0f32; 256 * 256 * 3];
    blend
        .splat(
            &w,
            kernel,
            SplatTarget {
                res,
                density: &mut density,
                color: Some(&mut color),
            },
        )
        .unwrap();
    let mut rd = vec![0.0f32; 256 * 256];
    let mut rc = vec![0.0f32; 256 * 256 * 3];
    for (b, (d, c)) in rd
        .chunks_mut(256 * 40)
        .zip(rc.chunks_mut(256 * 40 * 3))
        .enumerate()
    {
        let rows = (d.len() / 256) as u32;
        prep.splat_region(kernel, Region::rows(res, b as u32 * 40, rows), d, Some(c))
            .unwrap();
    }
    assert_eq!(
        rd.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        density.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(
        rc.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        color.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
    // RGBA cells in bands of 32 rows, prepared and mixed on the fly.
    for mixed in [false, true] {
        let mut rgba = vec![0.0f32; 256 * 256 * 4];
        for (b, band) in rgba.chunks_mut(256 * 32 * 4).enumerate() {
            let region = Region::rows(res, b as u32 * 32, 32);
            if mixed {
                blend.splat_region_rgba(&w, kernel, region, band).unwrap();
            } else {
                prep.splat_region_rgba(kernel, region, band).unwrap();
            }
        }
        for cell in 0..256 * 256 {
            let want = [
                color[3 * cell],
                color[3 * cell + 1],
                color[3 * cell + 2],
                density[cell],
            ];
            for a in 0..4 {
                assert_eq!(
                    rgba[cell * 4 + a].to_bits(),
                    want[a].to_bits(),
                    "cell {cell} (mixed: {mixed})"
                );
            }
        }
    }
}

/// A one-map blend (weight 1, so the blended points are `pos` exactly) with colors.
fn exact_points(pos: &[f32]) -> (rkyv::util::AlignedVec<16>, rkyv::util::AlignedVec<16>) {
    use otbake_formats::proxy::Proxy as ProxyData;
    use otbake_formats::tree::{depth, fill_node_boxes, node_count};
    use otbake_formats::write::{encode_map_content, encode_proxy, MapContent};
    let n = pos.len() / 2;
    let d = depth(n as u32, 4);
    let mut boxes = vec![0.0; node_count(d) as usize * 4];
    fill_node_boxes(pos, 2, d, &mut boxes);
    let proxy = encode_proxy(&ProxyData {
        dim: 2,
        n: n as u32,
        leaf_size: 4,
        depth: d,
        key: [5; 32],
        wrap: 0,
        description: "ties",
        positions: pos,
        node_boxes: &boxes,
    })
    .unwrap();
    let colors: Vec<f32> = (0..n * 3).map(|i| 0.25 + (i % 7) as f32 * 0.1).collect();
    let map = encode_map_content(
        &MapContent {
            dim: 2,
            depth: d,
            proxy_key: [5; 32],
            key: [6; 32],
            composite: 0,
            mean_mass: 0.7,
            wrap: otbake_formats::Wrap::Clamp,
            positions: pos,
            colors: &colors,
            spacings: &[],
            solver_report: "",
            transport_cost: 0.0,
        },
        otbake_runtime::Storage::FULL,
    )
    .unwrap();
    (proxy, map)
}

/// The block paths place a point's cells by arithmetic and judge them by exact tests; points
/// within a few ulps of the cutoff of a cell along one axis (coordinate `(n + ½ ± rc) / res`, `rc`
/// the radius in cells, so that rounding decides whether the cell counts) and on a cell's center
/// along the other (so the full test is decided by the tie) must still get exactly the per-cell
/// terms: point grids equal point queries and region splats the full splat, bit for bit. (A block
/// placement that trusted the arithmetic at these ties failed this test at σ = 0.8 cell, 50².)
#[test]
fn points_on_cutoff_ties_keep_their_bits() {
    for (res, sigma_cells) in [
        (64u32, 0.5f32),
        (37, 0.5),
        (50, 0.8),
        (29, 0.3),
        (41, 0.45),
        (23, 0.7),
    ] {
        let rc = 3.0 * sigma_cells;
        let mut pos = Vec::new();
        let mut rng = Rng(u64::from(res));
        for _ in 0..6000 {
            // One coordinate on a cell's center (distance 0 along that axis), so that the cutoff
            // is decided along the other, which sits at a tie.
            let on_tie = (rng.next() % 2) as usize;
            for axis in 0..2 {
                let n = 2 + (rng.next() % (res as u64 - 4)) as i32;
                if axis != on_tie {
                    pos.push((n as f32 + 0.5) / res as f32);
                    continue;
                }
                let side = if rng.next().is_multiple_of(2) {
                    rc
                } else {
                    -rc
                };
                let mut v = (n as f32 + 0.5 + side) / res as f32;
                // A few ulps either way of the tie.
                for _ in 0..(rng.next() % 9) {
                    v = if rng.next().is_multiple_of(2) {
                        f32::from_bits(v.to_bits() + 1)
                    } else {
                        f32::from_bits(v.to_bits() - 1)
                    };
                }
                pos.push(v.clamp(0.0, 1.0));
            }
        }
        let (p, m) = exact_points(&pos);
        let maps = [Map::open(&m).unwrap()];
        let blend = Blend::new(Proxy::open(&p).unwrap(), &maps).unwrap();
        let mut store = Vec::new();
        let prep = prepare(&blend, &[1.0], &mut store);
        let kernel = Kernel {
            sigma: sigma_cells / res as f32,
        };
        let full = Region::full([res, res, 1, 1]);
        let cells = (res * res) as usize;
        let mut out = vec![PointValue::default(); cells];
        prep.point_grid(kernel, full, &mut out).unwrap();
        for (cell, v) in out.iter().enumerate() {
            let (_, c) = global(2, &full, cell);
            let want = prep.point(&c, kernel).unwrap();
            assert_eq!(
                bits(v),
                bits(&want),
                "res {res} σ {sigma_cells} cell {cell}"
            );
        }
        let mut d0 = vec![0.0f32; cells];
        let mut c0 = vec![0.0f32; cells * 3];
        let target = SplatTarget {
            res: full.res,
            density: &mut d0,
            color: Some(&mut c0),
        };
        blend.splat(&[1.0], kernel, target).unwrap();
        let mut d1 = vec![0.0f32; cells];
        let mut c1 = vec![0.0f32; cells * 3];
        prep.splat_region(kernel, full, &mut d1, Some(&mut c1))
            .unwrap();
        // RGBA, prepared and mixed on the fly, whole and in bands of 5 rows (blocks moved inside
        // a band at its borders).
        let mut r1 = vec![0.0f32; cells * 4];
        prep.splat_region_rgba(kernel, full, &mut r1).unwrap();
        let mut r2 = vec![0.0f32; cells * 4];
        for (b, band) in r2.chunks_mut(res as usize * 5 * 4).enumerate() {
            let rows = (band.len() / (res as usize * 4)) as u32;
            let region = Region::rows(full.res, b as u32 * 5, rows);
            blend
                .splat_region_rgba(&[1.0], kernel, region, band)
                .unwrap();
        }
        for cell in 0..cells {
            assert_eq!(
                d1[cell].to_bits(),
                d0[cell].to_bits(),
                "res {res} cell {cell}"
            );
            for a in 0..3 {
                assert_eq!(c1[cell * 3 + a].to_bits(), c0[cell * 3 + a].to_bits());
            }
            let want = [c0[cell * 3], c0[cell * 3 + 1], c0[cell * 3 + 2], d0[cell]];
            for a in 0..4 {
                assert_eq!(
                    r1[cell * 4 + a].to_bits(),
                    want[a].to_bits(),
                    "res {res} σ {sigma_cells} cell {cell} (rgba)"
                );
                assert_eq!(
                    r2[cell * 4 + a].to_bits(),
                    want[a].to_bits(),
                    "res {res} σ {sigma_cells} cell {cell} (rgba bands)"
                );
            }
        }
    }
}

/// Grids far finer than f32 resolves near the points (2^18–2^24 cells per axis; at 2^22 and more
/// a coordinate times the resolution keeps at most two bits below the cell): point grids still
/// equal per-cell point queries, and RGBA splats planar ones, bit for bit.
#[test]
fn very_fine_grids_match_point_queries() {
    for (shift, sigma_cells) in [
        (22u32, 0.5f32),
        (23, 0.7),
        (24, 0.3),
        (21, 0.8),
        (20, 0.5),
        (19, 0.45),
        (18, 0.5),
    ] {
        let res = 1u32 << shift;
        let size = 24u32;
        let start = (res / 10) * 7;
        let mut rng = Rng(u64::from(shift));
        let mut pos = Vec::new();
        for _ in 0..3000 {
            for _ in 0..2 {
                let cell =
                    start as f64 - 4.0 + (rng.next() % 1_000_000) as f64 / 1e6 * (size + 8) as f64;
                pos.push((cell / res as f64) as f32);
            }
        }
        let (p, m) = exact_points(&pos);
        let maps = [Map::open(&m).unwrap()];
        let blend = Blend::new(Proxy::open(&p).unwrap(), &maps).unwrap();
        let mut store = Vec::new();
        let prep = prepare(&blend, &[1.0], &mut store);
        let kernel = Kernel {
            sigma: sigma_cells / res as f32,
        };
        let region = Region {
            res: [res, res, 1, 1],
            start: [start, start, 0, 0],
            size: [size, size, 1, 1],
        };
        let mut out = vec![PointValue::default(); (size * size) as usize];
        prep.point_grid(kernel, region, &mut out).unwrap();
        let mut nonzero = 0;
        for (cell, v) in out.iter().enumerate() {
            let (_, c) = global(2, &region, cell);
            let want = prep.point(&c, kernel).unwrap();
            nonzero += usize::from(want.density > 0.0);
            assert_eq!(
                bits(v),
                bits(&want),
                "res 2^{shift} σ {sigma_cells} cell {cell}"
            );
        }
        assert!(nonzero > 0, "res 2^{shift}: the region holds points");
        // Splats: RGBA (the 3×3 blocks up to 2^20 cells at σ <= ½ cell, the general path beyond)
        // against the planar region splat's exact spans.
        let cells = (size * size) as usize;
        let (mut d, mut c) = (vec![0.0f32; cells], vec![0.0f32; cells * 3]);
        prep.splat_region(kernel, region, &mut d, Some(&mut c))
            .unwrap();
        let mut rgba = vec![0.0f32; cells * 4];
        prep.splat_region_rgba(kernel, region, &mut rgba).unwrap();
        for cell in 0..cells {
            let want = [c[3 * cell], c[3 * cell + 1], c[3 * cell + 2], d[cell]];
            for a in 0..4 {
                assert_eq!(
                    rgba[cell * 4 + a].to_bits(),
                    want[a].to_bits(),
                    "res 2^{shift} cell {cell}"
                );
            }
        }
    }
}
