//! Runtime queries equal brute force over every blended point, for random archives, dimensions,
//! leaf sizes, map counts and weights (property tests).
#![allow(clippy::needless_range_loop)] // coordinate loops read clearer with indices

mod common;

use common::{fixture, weights, Fixture, Rng};
use otbake_runtime::{
    Blend, Error, Kernel, Map, PointValue, PreparedBuffers, Proxy, Region, SplatTarget,
};
use proptest::prelude::*;

fn open(f: &Fixture) -> (Proxy<'_>, Vec<Map<'_>>) {
    (
        Proxy::open(&f.proxy).unwrap(),
        f.maps.iter().map(|m| Map::open(m).unwrap()).collect(),
    )
}

/// Brute-force point query with the documented kernel.
fn brute_point(f: &Fixture, w: &[f32], p: &[f32], sigma: f32) -> (f64, [f64; 3]) {
    const TRUNC: [f64; 4] = [
        0.997_300_203_936_739_8,
        0.988_891_003_461_757_7,
        0.970_709_113_465_111_8,
        0.938_900_519_039_667_3,
    ];
    let d = f.dim;
    let s = sigma as f64;
    let norm =
        1.0 / ((2.0 * std::f64::consts::PI).powf(d as f64 / 2.0) * s.powi(d as i32) * TRUNC[d - 1]);
    let mut sum = 0.0;
    let mut c = [0.0; 3];
    for i in 0..f.n {
        let (y, col) = f.blended(w, i);
        let r2: f32 = (0..d).map(|k| (y[k] - p[k]) * (y[k] - p[k])).sum();
        if r2 <= 9.0 * sigma * sigma {
            let k = (-(r2 as f64) / (2.0 * s * s)).exp() * norm;
            sum += k;
            for a in 0..3 {
                c[a] += k * col[a] as f64;
            }
        }
    }
    let mm = f.mean_mass(w) as f64;
    (sum / f.n as f64, c.map(|v| v * mm / f.n as f64))
}

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 2e-4 * scale.max(b.abs()) + 1e-6
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn point_queries_equal_brute_force(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                       leaf in 1u32..8, k in 1usize..4, sigma in 0.01f32..0.3) {
        let f = fixture(seed, n, dim, leaf, k, [1; 32]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0xABCD);
        let w = weights(&mut rng, k);
        for _ in 0..8 {
            let p: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let v = blend.point(&w, &p, Kernel { sigma }).unwrap();
            let (dens, col) = brute_point(&f, &w, &p, sigma);
            // Scale: the largest possible single-point contribution, so near-cutoff rounding passes.
            let scale = dens.max(1.0 / (f.n as f64 * (sigma as f64).powi(dim as i32)));
            prop_assert!(close(v.density as f64, dens, scale), "density {} vs {}", v.density, dens);
            prop_assert!(close(v.mass as f64, dens * f.mean_mass(&w) as f64, scale * 2.0));
            for a in 0..3 {
                prop_assert!(close(v.color[a] as f64, col[a], scale * 4.0), "color {:?} vs {:?}", v.color, col);
            }
        }
    }

    #[test]
    fn range_queries_equal_brute_force(seed in 0u64..1000, n in 1usize..300, dim in 1usize..=4,
                                       leaf in 1u32..8, k in 1usize..4) {
        let f = fixture(seed, n, dim, leaf, k, [1; 32]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let mut rng = Rng(seed ^ 0x1234);
        let w = weights(&mut rng, k);
        for _ in 0..8 {
            let a: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let b: Vec<f32> = (0..dim).map(|_| rng.unit()).collect();
            let lo: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x.min(*y)).collect();
            let hi: Vec<f32> = a.iter().zip(&b).map(|(x, y)| x.max(*y)).collect();
            let mut count = 0u32;
            let mut c = [0.0f64; 3];
            for i in 0..f.n {
                let (y, col) = f.blended(&w, i);
                if (0..dim).all(|k| y[k] >= lo[k] && y[k] <= hi[k]) {
                    count += 1;
                    for q in 0..3 { c[q] += col[q] as f64; }
                }
            }
            let v = blend.range(&w, &lo, &hi).unwrap();
            prop_assert_eq!(v.count, count);
            let mm = f.mean_mass(&w) as f64 / f.n as f64;
            prop_assert!(close(v.mass as f64, count as f64 * mm, 1e-3));
            for q in 0..3 {
                prop_assert!(close(v.color[q] as f64, c[q] * mm, 2.0 * mm * (count as f64 + 1.0)));
            }
        }
    }

    #[test]
    fn samples_are_blended_points(seed in 0u64..1000, n in 1usize..200, dim in 1usize..=4, k in 1usize..4) {
        let f = fixture(seed, n, dim, 3, k, [1; 32]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let w = weights(&mut Rng(seed), k);
        for i in 0..n {
            let s = blend.sample(&w, i as u32).unwrap();
            let (y, c) = f.blended(&w, i);
            prop_assert_eq!(&s.position[..dim], &y[..]);
            prop_assert_eq!(s.color, c);
        }
        let past_end = matches!(blend.sample(&w, n as u32), Err(Error::IndexOutOfRange { .. }));
        prop_assert!(past_end);
    }

    #[test]
    fn splat_equals_point_queries_at_cell_centers(seed in 0u64..1000, n in 1usize..200, dim in 1usize..=3,
                                                  k in 1usize..4, res in 2u32..9) {
        let f = fixture(seed, n, dim, 2, k, [1; 32]);
        let (proxy, maps) = open(&f);
        let blend = Blend::new(proxy, &maps).unwrap();
        let w = weights(&mut Rng(seed), k);
        let kernel = Kernel { sigma: 0.7 / res as f32 };
        let cells = (res as usize).pow(dim as u32);
        let mut density = vec![0.0f32; cells];
        let mut color = vec![0.0f32; cells * 3];
        let mut r = [1u32; 4];
        r[..dim].fill(res);
        blend.splat(&w, kernel, SplatTarget { res: r, density: &mut density, color: Some(&mut color) }).unwrap();
        for cell in 0..cells {
            let mut p = vec![0.0f32; dim];
            let mut rest = cell;
            for a in 0..dim {
                p[a] = ((rest % res as usize) as f32 + 0.5) / res as f32;
                rest /= res as usize;
            }
            let v = blend.point(&w, &p, kernel).unwrap();
            let scale = 1.0 / (f.n as f64 * (kernel.sigma as f64).powi(dim as i32));
            prop_assert!(close(density[cell] as f64, v.density as f64, scale), "cell {}: {} vs {}", cell, density[cell], v.density);
            for a in 0..3 {
                prop_assert!(close(color[cell * 3 + a] as f64, v.color[a] as f64, scale * 4.0));
            }
        }
    }
}

#[test]
fn per_query_weights_equal_fresh_blends() {
    let f = fixture(5, 250, 2, 4, 3, [1; 32]);
    let (proxy, maps) = open(&f);
    let shared = Blend::new(proxy, &maps).unwrap();
    let mut rng = Rng(9);
    for q in 0..40 {
        let w = weights(&mut rng, 3);
        let p = [rng.unit(), rng.unit()];
        let (proxy2, maps2) = open(&f);
        let fresh = Blend::new(proxy2, &maps2).unwrap();
        let a = shared.point(&w, &p, Kernel { sigma: 0.05 }).unwrap();
        let b = fresh.point(&w, &p, Kernel { sigma: 0.05 }).unwrap();
        assert_eq!(a, b, "query {q}");
    }
}

#[test]
fn bad_arguments_are_errors() {
    let f = fixture(3, 100, 2, 4, 2, [1; 32]);
    let (proxy, maps) = open(&f);
    let blend = Blend::new(proxy, &maps).unwrap();
    let k = Kernel { sigma: 0.05 };
    let p = [0.5, 0.5];
    assert!(matches!(
        blend.point(&[1.0], &p, k),
        Err(Error::WeightCount {
            expected: 2,
            found: 1
        })
    ));
    assert!(matches!(
        blend.point(&[-0.5, 1.5], &p, k),
        Err(Error::BadWeight { index: 0 })
    ));
    assert!(matches!(
        blend.point(&[f32::NAN, 1.0], &p, k),
        Err(Error::BadWeight { index: 0 })
    ));
    assert!(matches!(
        blend.point(&[0.5, 0.6], &p, k),
        Err(Error::WeightSum { .. })
    ));
    assert!(matches!(
        blend.point(&[0.5, 0.5], &[0.5], k),
        Err(Error::PointDim {
            expected: 2,
            found: 1
        })
    ));
    assert!(matches!(
        blend.point(&[0.5, 0.5], &[f32::NAN, 0.5], k),
        Err(Error::BadCoordinate)
    ));
    for sigma in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(matches!(
            blend.point(&[0.5, 0.5], &p, Kernel { sigma }),
            Err(Error::BadSigma)
        ));
    }
    let mut small = [0.0f32; 3];
    let t = SplatTarget {
        res: [2, 2, 1, 1],
        density: &mut small,
        color: None,
    };
    assert!(matches!(
        blend.splat(&[0.5, 0.5], k, t),
        Err(Error::BufferSize {
            expected: 4,
            found: 3
        })
    ));
    let mut d = [0.0f32; 4];
    let t = SplatTarget {
        res: [0, 2, 1, 1],
        density: &mut d,
        color: None,
    };
    assert!(blend.splat(&[0.5, 0.5], k, t).is_err());
    // Maps of another proxy, or of another shape, are refused.
    let other = fixture(3, 100, 2, 4, 1, [2; 32]);
    let foreign = [Map::open(&other.maps[0]).unwrap()];
    assert!(matches!(
        Blend::new(Proxy::open(&f.proxy).unwrap(), &foreign),
        Err(Error::ProxyMismatch { map: 0 })
    ));
    let other = fixture(3, 99, 2, 4, 1, [1; 32]);
    let wrong_n = [Map::open(&other.maps[0]).unwrap()];
    assert!(matches!(
        Blend::new(Proxy::open(&f.proxy).unwrap(), &wrong_n),
        Err(Error::ShapeMismatch { .. })
    ));
    assert!(matches!(
        Blend::new(Proxy::open(&f.proxy).unwrap(), &[]),
        Err(Error::NoMaps)
    ));
}

#[test]
fn damaged_archives_never_panic() {
    let f = fixture(11, 60, 3, 2, 1, [1; 32]);
    for bytes in [&f.proxy, &f.maps[0]] {
        for cut in 0..bytes.len() {
            let b = otbake_formats::write::aligned_copy(&bytes[..cut]);
            assert!(Proxy::open(&b).is_err() && Map::open(&b).is_err());
        }
        let mut rng = Rng(1);
        for _ in 0..2000 {
            let mut b = bytes.to_vec();
            let at = (rng.next() % b.len() as u64) as usize;
            b[at] ^= 1 << (rng.next() % 8);
            let b = otbake_formats::write::aligned_copy(&b);
            // Either refused, or (a flip in the header's reserved/ignored bits cannot happen: all are
            // checked) — every single-bit flip must be refused.
            assert!(
                Proxy::open(&b).is_err() && Map::open(&b).is_err(),
                "flip at {at} accepted"
            );
        }
    }
    // Misaligned bytes are an error, not UB.
    let mut shifted = rkyv::util::AlignedVec::<16>::new();
    shifted.push(0);
    shifted.extend_from_slice(&f.proxy);
    assert!(matches!(
        Proxy::open(&shifted[1..]),
        Err(Error::Format(otbake_formats::FormatError::Misaligned))
    ));
}

/// Runs every query with a spread of arguments; results are ignored, panics are what is tested.
fn exercise(blend: &Blend<'_, '_>) {
    let d = blend.dim();
    let k = blend.k();
    let w: Vec<f32> = vec![1.0 / k as f32; k];
    for sigma in [1e-6f32, 0.05, 10.0, f32::MAX] {
        for p in [0.5f32, -1e30, 1e30] {
            let _ = blend.point(&w, &vec![p; d], Kernel { sigma });
        }
        let mut density = vec![0.0f32; 5usize.pow(d as u32)];
        let mut color = vec![0.0f32; density.len() * 3];
        let mut res = [1u32; 4];
        res[..d].fill(5);
        let _ = blend.splat(
            &w,
            Kernel { sigma },
            SplatTarget {
                res,
                density: &mut density,
                color: Some(&mut color),
            },
        );
    }
    let _ = blend.range(&w, &vec![0.2; d], &vec![0.8; d]);
    let _ = blend.range(&w, &vec![f32::NEG_INFINITY; d], &vec![f32::INFINITY; d]);
    let _ = blend.sample(&w, 0);
    let _ = blend.sample(&w, blend.n().saturating_sub(1));
    // The prepared blend and its region queries, on the same archive.
    let sizes = blend.prepared_sizes();
    let (mut p, mut c) = (vec![0.0; sizes.positions], vec![0.0; sizes.colors]);
    let (mut b, mut nc) = (vec![0.0; sizes.node_boxes], vec![0.0; sizes.node_colors]);
    let Ok(prep) = blend.prepare(
        &w,
        PreparedBuffers {
            positions: &mut p,
            colors: &mut c,
            node_boxes: &mut b,
            node_colors: &mut nc,
        },
    ) else {
        return;
    };
    let mut res = [1u32; 4];
    res[..d].fill(5);
    let mut region = Region::full(res);
    region.start[0] = 1;
    region.size[0] = 3;
    let cells = 3 * 5usize.pow(d as u32 - 1);
    for sigma in [1e-6f32, 0.05, 10.0, f32::MAX] {
        let kernel = Kernel { sigma };
        for q in [0.5f32, -1e30, 1e30] {
            let _ = prep.point(&vec![q; d], kernel);
        }
        let mut out = vec![PointValue::default(); cells];
        let _ = prep.point_grid(kernel, region, &mut out);
        let mut density = vec![0.0f32; cells];
        let mut color = vec![0.0f32; cells * 3];
        let _ = prep.splat_region(kernel, region, &mut density, Some(&mut color));
    }
    let _ = prep.range(&vec![0.2; d], &vec![0.8; d]);
    let _ = prep.sample(0);
}

/// Flips payload bits and then *repairs the checksum*, so the damage reaches rkyv validation and the
/// consistency checks (a forgery, not corruption). Whatever still opens must answer every query
/// without panicking.
#[test]
fn forged_archives_never_panic() {
    use otbake_formats::header::{Header, HEADER_LEN};
    use otbake_formats::ArchiveKind;
    let f = fixture(21, 40, 2, 3, 2, [1; 32]);
    let (mut opened, mut tried) = (0, 0);
    for (kind, bytes) in [
        (ArchiveKind::Proxy, &f.proxy),
        (ArchiveKind::Map, &f.maps[0]),
    ] {
        for i in HEADER_LEN..bytes.len() {
            for bit in [0, 3, 6, 7] {
                let mut b = bytes.to_vec();
                b[i] ^= 1 << bit;
                let header = Header::new(kind, &b[HEADER_LEN..]).encode();
                b[..HEADER_LEN].copy_from_slice(&header);
                let b = otbake_formats::write::aligned_copy(&b);
                tried += 1;
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    let good = Map::open(&f.maps[1]).unwrap();
                    match kind {
                        ArchiveKind::Proxy => {
                            if let Ok(p) = Proxy::open(&b) {
                                opened += 1;
                                let maps = [good, Map::open(&f.maps[0]).unwrap()];
                                if let Ok(blend) = Blend::new(p, &maps) {
                                    exercise(&blend);
                                }
                            }
                        }
                        ArchiveKind::Map => {
                            if let Ok(m) = Map::open(&b) {
                                opened += 1;
                                let maps = [m, good];
                                if let Ok(blend) = Blend::new(Proxy::open(&f.proxy).unwrap(), &maps)
                                {
                                    exercise(&blend);
                                }
                            }
                        }
                    }
                }));
                assert!(result.is_ok(), "{kind:?} byte {i} bit {bit} panicked");
            }
        }
    }
    // Most forgeries change a float and still validate: the queries really ran.
    assert!(
        opened > tried / 4,
        "{opened} of {tried} forged archives opened"
    );
}

/// Valid archives holding extreme finite values answer every query without panicking.
#[test]
fn extreme_values_never_panic() {
    use otbake_formats::{map::Map as MapData, proxy::Proxy as ProxyData, tree, write};
    let n = 30;
    let ext = [
        f32::MAX,
        -f32::MAX,
        f32::MIN_POSITIVE,
        1e-45,
        0.0,
        -0.0,
        1e30,
        0.5,
    ];
    let pos: Vec<f32> = (0..n * 2).map(|i| ext[i % ext.len()]).collect();
    let colors: Vec<f32> = (0..n * 3).map(|i| ext[(i * 7) % ext.len()] / 4.0).collect();
    let d = tree::depth(n as u32, 2);
    let nodes = tree::node_count(d) as usize;
    let internal = tree::internal_count(d) as usize;
    let mut boxes = vec![0.0; nodes * 4];
    tree::fill_node_boxes(&pos, 2, d, &mut boxes);
    let mut sums = vec![0.0; nodes * 3];
    tree::fill_node_sums(&colors, 3, d, &mut sums);
    let sums: Vec<f32> = sums[..internal * 3]
        .iter()
        .map(|v| if v.is_finite() { *v } else { f32::MAX })
        .collect();
    let bytes = |v: &[f32]| -> Vec<u8> { v.iter().flat_map(|x| x.to_le_bytes()).collect() };
    let bounds = [boxes[0], boxes[1], boxes[2], boxes[3]];
    let pb = write::encode_proxy(&ProxyData {
        dim: 2,
        n: n as u32,
        leaf_size: 2,
        depth: d,
        key: [3; 32],
        wrap: 0,
        description: "",
        positions: &pos,
        node_boxes: &boxes,
    })
    .unwrap();
    let mb = write::encode_map(&MapData {
        dim: 2,
        n: n as u32,
        depth: d,
        proxy_key: [3; 32],
        key: [4; 32],
        composite: 0,
        mean_mass: f32::MAX,
        wrap: 0,
        storage: otbake_formats::storage::Storage {
            spacings: false,
            ..otbake_formats::storage::Storage::FULL
        }
        .to_codes(),
        bounds: &bounds,
        color_range: &[],
        positions: &bytes(&pos),
        colors: &bytes(&colors),
        node_boxes: &bytes(&boxes[..internal * 4]),
        node_colors: &sums,
        spacings: &[],
        node_spacings: &[],
        solver_report: "",
        transport_cost: 0.0,
    })
    .unwrap();
    let maps = [Map::open(&mb).unwrap(), Map::open(&mb).unwrap()];
    let blend = Blend::new(Proxy::open(&pb).unwrap(), &maps).unwrap();
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        exercise(&blend);
        // Weights summing slightly above 1 push f32::MAX coordinates to infinity.
        let w = [0.50004, 0.50004];
        let _ = blend.point(&w, &[f32::MAX, -f32::MAX], Kernel { sigma: 1.0 });
        let _ = blend.range(&w, &[-f32::MAX, 0.0], &[f32::MAX, 0.0]);
        let mut density = vec![0.0f32; 16];
        let _ = blend.splat(
            &w,
            Kernel { sigma: 0.1 },
            SplatTarget {
                res: [4, 4, 0, 0],
                density: &mut density,
                color: None,
            },
        );
    }));
    assert!(result.is_ok());
}
