//! Bake → runtime round trips on real data: queries agree with brute force over the archive's own
//! points, splat agrees with point queries, maps of another proxy are refused, damaged bytes are
//! errors, and bakes are byte-identical for any thread count.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions, Status};
use otbake::render::{render, Archives, Method, RenderSettings};
use otbake_formats::write::aligned_copy;
use otbake_runtime::{Blend, Error, Kernel, Map, Proxy};
use otbake_tests::{otbake_ok, repo_root, scratch, shared_data, write_manifest};
use std::path::PathBuf;

fn shapes_manifest(name: &str, samples: usize, seed: u64) -> Manifest {
    let dir = scratch(name);
    let data = shared_data();
    let mut body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\nseed = {seed}\n[solver]\nkind = \"sliced\"\n"
    );
    for s in ["redcross", "tooth", "heart", "duck"] {
        body += &format!(
            "[[input]]\nname = \"{s}\"\npath = \"{}\"\ndensity = \"inverted\"\n",
            data.join(format!("shapes/{s}.png")).display()
        );
    }
    Manifest::load(&write_manifest(&dir, "shapes.toml", &body)).unwrap()
}

#[test]
fn point_and_range_queries_equal_brute_force_on_a_real_bake() {
    let m = shapes_manifest("rt-brute", 3000, 0);
    bake(&m, &BakeOptions::default()).unwrap();
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    let blend = Blend::new(a.proxy().unwrap(), &maps).unwrap();
    let w = [0.1f32, 0.2, 0.3, 0.4];
    let pts: Vec<_> = (0..blend.n())
        .map(|i| blend.sample(&w, i).unwrap())
        .collect();
    let sigma = 0.02f32;
    let norm = 1.0 / (2.0 * std::f32::consts::PI * sigma * sigma) / (1.0 - (-4.5f32).exp());
    for q in 0..50 {
        let p = [
            0.1 + 0.8 * ((q as f32 * 0.618) % 1.0),
            0.1 + 0.8 * ((q as f32 * 0.382) % 1.0),
        ];
        let brute: f32 = pts
            .iter()
            .map(|s| {
                let r2 = (s.position[0] - p[0]).powi(2) + (s.position[1] - p[1]).powi(2);
                if r2 <= 9.0 * sigma * sigma {
                    norm * (-0.5 * r2 / (sigma * sigma)).exp()
                } else {
                    0.0
                }
            })
            .sum::<f32>()
            / pts.len() as f32;
        let v = blend.point(&w, &p, Kernel { sigma }).unwrap();
        assert!(
            (v.density - brute).abs() <= 1e-3 * brute.max(1.0),
            "at {p:?}: {} vs {brute}",
            v.density
        );
        let (lo, hi) = ([p[0] - 0.1, p[1] - 0.05], [p[0] + 0.05, p[1] + 0.1]);
        let count = pts
            .iter()
            .filter(|s| (0..2).all(|k| s.position[k] >= lo[k] && s.position[k] <= hi[k]))
            .count();
        assert_eq!(blend.range(&w, &lo, &hi).unwrap().count as usize, count);
    }
}

#[test]
fn splat_and_point_query_render_the_same_image() {
    let m = shapes_manifest("rt-splat", 4000, 0);
    bake(&m, &BakeOptions::default()).unwrap();
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    let w = [0.25f32; 4];
    let s = |method| RenderSettings {
        width: 48,
        height: 40,
        method,
        sigma_px: 0.8,
    };
    let q = render(a.proxy().unwrap(), &maps, &w, &s(Method::Query)).unwrap();
    let sp = render(a.proxy().unwrap(), &maps, &w, &s(Method::Splat)).unwrap();
    let max = q
        .pixels
        .iter()
        .zip(&sp.pixels)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    assert!(max < 1e-3, "largest pixel difference {max}");
    // The image is not trivially blank: ink (dark pixels) and paper (white) both appear.
    assert!(q.pixels.chunks(4).any(|p| p[0] < 0.2) && q.pixels.chunks(4).any(|p| p[0] > 0.99));
    // Both methods give the same bits on any number of threads (the splat's bands, one per
    // thread, are balanced by point counts; the query's by rows).
    for threads in [1, 2, 3, 5] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        for (method, want) in [(Method::Query, &q), (Method::Splat, &sp)] {
            let got = pool
                .install(|| render(a.proxy().unwrap(), &maps, &w, &s(method)))
                .unwrap();
            assert!(
                got.pixels
                    .iter()
                    .zip(&want.pixels)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "{method:?} on {threads} threads"
            );
        }
    }
}

#[test]
fn maps_of_another_proxy_and_damaged_bytes_are_refused() {
    let a = shapes_manifest("rt-proxy-a", 500, 0);
    let b = shapes_manifest("rt-proxy-b", 500, 1);
    bake(&a, &BakeOptions::default()).unwrap();
    bake(&b, &BakeOptions::default()).unwrap();
    let pa = aligned_copy(&std::fs::read(a.proxy_archive()).unwrap());
    let mb = aligned_copy(&std::fs::read(b.map_archive("duck")).unwrap());
    let maps = [Map::open(&mb).unwrap()];
    assert!(matches!(
        Blend::new(Proxy::open(&pa).unwrap(), &maps),
        Err(Error::ProxyMismatch { map: 0 })
    ));
    let bytes = std::fs::read(a.map_archive("duck")).unwrap();
    for cut in (0..bytes.len()).step_by(97) {
        assert!(Map::open(&aligned_copy(&bytes[..cut])).is_err());
    }
    for at in (0..bytes.len()).step_by(31) {
        let mut b = bytes.clone();
        b[at] ^= 0x41;
        assert!(
            Map::open(&aligned_copy(&b)).is_err(),
            "flip at {at} accepted"
        );
    }
}

#[test]
fn bake_is_incremental_and_thread_count_independent() {
    let bin = otbake_tests::otbake_bin();
    let mut outputs: Vec<Vec<Vec<u8>>> = Vec::new();
    for threads in ["1", "2", "4"] {
        let m = shapes_manifest(&format!("rt-threads-{threads}"), 3000, 0);
        let st = std::process::Command::new(&bin)
            .args(["bake", m.path.to_str().unwrap()])
            .env("RAYON_NUM_THREADS", threads)
            .status()
            .unwrap();
        assert!(st.success());
        let mut files: Vec<PathBuf> = vec![m.proxy_archive()];
        files.extend(m.inputs.iter().map(|i| m.map_archive(&i.name)));
        outputs.push(files.iter().map(|f| std::fs::read(f).unwrap()).collect());
        // A second bake finds everything current.
        let r = bake(&m, &BakeOptions::default()).unwrap();
        assert!(r.products.iter().all(|p| p.status == Status::Cached));
    }
    assert!(
        outputs.windows(2).all(|w| w[0] == w[1]),
        "archives differ between thread counts"
    );
}

#[test]
fn shipped_small_manifest_bakes_and_renders_a_grid() {
    let dir = scratch("rt-grid");
    let manifest = repo_root().join("manifests/shapes-small.toml");
    let out = dir.join("grid.png");
    otbake_ok(
        &dir,
        &[
            "grid",
            manifest.to_str().unwrap(),
            "--steps",
            "3",
            "--size",
            "32x32",
            "-o",
            out.to_str().unwrap(),
        ],
    );
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (96, 96));
    // One blend as EXR (linear float) and as PNG with --method splat: valid files, deterministic.
    for (file, method) in [("b.exr", "query"), ("b.png", "splat")] {
        let out = dir.join(file);
        let args = [
            "blend",
            manifest.to_str().unwrap(),
            "--weights",
            "0.1,0.2,0.3,0.4",
            "--size",
            "40x30",
            "--method",
            method,
            "-o",
            out.to_str().unwrap(),
        ];
        otbake_ok(&dir, &args);
        let first = std::fs::read(&out).unwrap();
        otbake_ok(&dir, &args);
        assert_eq!(
            std::fs::read(&out).unwrap(),
            first,
            "{file} differs between runs"
        );
        if file.ends_with(".exr") {
            assert_eq!(&first[..4], &[0x76, 0x2f, 0x31, 0x01], "EXR magic");
        } else {
            let img = image::open(&out).unwrap();
            assert_eq!((img.width(), img.height()), (40, 30));
        }
    }
    let points = dir.join("duck.npy");
    otbake_ok(
        &dir,
        &[
            "points",
            manifest.to_str().unwrap(),
            "--input",
            "duck",
            "-o",
            points.to_str().unwrap(),
        ],
    );
    let bytes = std::fs::read(&points).unwrap();
    assert!(String::from_utf8_lossy(&bytes[..128]).contains("'shape': (2000, 4)"));
    assert_eq!(bytes.len(), 128 + 2000 * 4 * 4);
}

#[test]
fn per_pixel_weights_equal_single_weight_queries() {
    use otbake::render::texture::{render_texture, WeightField};
    let m = shapes_manifest("rt-texture", 3000, 0);
    bake(&m, &BakeOptions::default()).unwrap();
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    let (w, h, sigma_px) = (48usize, 32usize, 0.8f32);
    for field in [
        WeightField::Perlin {
            scale: 3.0,
            seed: 5,
        },
        WeightField::Zigzag,
    ] {
        let img = render_texture(a.proxy().unwrap(), &maps, &field, w, h, sigma_px).unwrap();
        let blend = Blend::new(a.proxy().unwrap(), &maps).unwrap();
        let mut weights = vec![0.0f32; 4];
        let mut distinct = std::collections::BTreeSet::new();
        for (y, x) in [(0, 0), (5, 7), (16, 24), (31, 47), (20, 3), (9, 40)] {
            // Square tiles of min(w, h) pixels; the weight field spans the whole image.
            let tile = h as f32;
            field.weights(
                4,
                (x as f32 + 0.5) / w as f32,
                (y as f32 + 0.5) / h as f32,
                &mut weights,
            );
            distinct.insert(weights.iter().map(|v| v.to_bits()).collect::<Vec<_>>());
            let p = [
                ((x as f32 + 0.5) / tile).fract(),
                ((y as f32 + 0.5) / tile).fract(),
            ];
            let v = blend
                .point(
                    &weights,
                    &p,
                    Kernel {
                        sigma: sigma_px / tile,
                    },
                )
                .unwrap();
            let want = otbake::render::shade(otbake::render::composite(&maps), v.mass, v.color);
            let i = (y * w + x) * 4;
            assert_eq!(
                &img.pixels[i..i + 4],
                &want[..],
                "{field:?} pixel ({x}, {y})"
            );
        }
        assert!(distinct.len() > 3, "{field:?}: weights hardly vary");
    }
}

#[test]
fn level_of_detail_pixels_conserve_the_blend_mass() {
    use otbake::render::texture::{render_lod, WeightField};
    // Gray luminance inputs (additive display, color ratio 1): a pixel's red value is the average
    // mass over its footprint, with no clamping.
    let dir = scratch("rt-lod");
    otbake_tests::write_gaussian_exr(&dir.join("a.exr"), 64, [0.4, 0.45], [0.1, 0.15]);
    otbake_tests::write_gaussian_exr(&dir.join("b.exr"), 64, [0.6, 0.5], [0.12, 0.08]);
    let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 3000\n[solver]\nkind = \"sliced\"\n\
                [[input]]\nname = \"a\"\npath = \"a.exr\"\n[[input]]\nname = \"b\"\npath = \"b.exr\"\n";
    let m = Manifest::load(&write_manifest(&dir, "m.toml", body)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    let w = [0.3f32, 0.7];
    let mean_mass: f32 = maps.iter().zip(w).map(|(m, w)| m.mean_mass() * w).sum();
    // One tile across 24 pixels: each pixel is the exact average over its 1/24 × 1/24 footprint, so
    // the pixels' values times their area add up to the blend's whole mass.
    let n = 24;
    let img = render_lod(
        a.proxy().unwrap(),
        &maps,
        &WeightField::Constant(w.to_vec()),
        n,
        n,
        1.0,
    )
    .unwrap();
    let total: f32 = img.pixels.chunks(4).map(|p| p[0] / (n * n) as f32).sum();
    assert!(
        (total - mean_mass).abs() < 1e-3 * mean_mass,
        "{total} vs {mean_mass}"
    );
    // And the footprints really differ: the image is not flat.
    let (lo, hi) = img
        .pixels
        .chunks(4)
        .fold((f32::MAX, 0.0f32), |(l, h), p| (l.min(p[0]), h.max(p[0])));
    assert!(hi > 4.0 * lo.max(1e-6), "flat LOD image: {lo}..{hi}");
}
