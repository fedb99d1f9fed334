//! Storage on real bakes: a compact bake of `../shared/data/shapes` stays within the stated error
//! of the full bake of the same manifest (same proxy, same solve), is several times smaller, and a
//! manifest that leaves attributes out gets archives without them and clear errors from the queries
//! that need them.

#![allow(clippy::needless_range_loop)] // coordinate loops read clearer with indices

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::{render, Archives, Method, RenderSettings};
use otbake_runtime::{Blend, Kernel, Precision, Storage};
use otbake_tests::{otbake_err, otbake_ok, scratch, shared_data, write_manifest};
use std::path::Path;

const SHAPES: [&str; 4] = ["redcross", "tooth", "heart", "duck"];

fn manifest(dir: &Path, name: &str, samples: usize, storage: &str) -> Manifest {
    let data = shared_data();
    let mut body = format!(
        "[output]\ndir = \"out-{name}\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n[solver]\nkind = \"sliced\"\n"
    );
    for s in SHAPES {
        body += &format!(
            "[[input]]\nname = \"{s}\"\npath = \"{}\"\ndensity = \"inverted\"\n",
            data.join(format!("shapes/{s}.png")).display()
        );
    }
    body += storage;
    Manifest::load(&write_manifest(dir, &format!("{name}.toml"), &body)).unwrap()
}

#[test]
fn compact_bake_of_real_shapes_stays_within_the_stated_error() {
    let dir = scratch("storage-real");
    let full = manifest(&dir, "full", 6000, "");
    let compact = manifest(&dir, "compact", 6000, "[storage]\npreset = \"compact\"\n");
    bake(&full, &BakeOptions::default()).unwrap();
    bake(&compact, &BakeOptions::default()).unwrap();
    let (af, ac) = (
        Archives::load(&full).unwrap(),
        Archives::load(&compact).unwrap(),
    );
    let (mf, mc) = (af.maps().unwrap(), ac.maps().unwrap());

    // Stored values: within their bounds, and the archives several times smaller.
    for (s, (f, c)) in SHAPES.iter().zip(mf.iter().zip(&mc)) {
        assert_eq!(c.storage(), Storage::COMPACT);
        assert_eq!(f.storage(), Storage::FULL);
        let ce = c.color_error();
        for i in 0..f.n() {
            let (pf, pc, e) = (
                f.position(i).unwrap(),
                c.position(i).unwrap(),
                c.position_error(i).unwrap(),
            );
            for a in 0..2 {
                assert!((pf[a] - pc[a]).abs() <= e[a], "{s} point {i}");
            }
            let (cf, cc) = (f.color(i).unwrap(), c.color(i).unwrap());
            for a in 0..3 {
                assert!((cf[a] - cc[a]).abs() <= ce[a], "{s} color {i}");
            }
        }
        let sizes = |m: &Manifest| std::fs::metadata(m.map_archive(s)).unwrap().len();
        assert!(
            sizes(&compact) * 5 < sizes(&full) * 2,
            "{s}: {} vs {} bytes",
            sizes(&compact),
            sizes(&full)
        );
    }

    // Queries: samples within the blended bound, range counts between the shrunk and grown boxes'.
    let w = [0.1f32, 0.2, 0.3, 0.4];
    let bf = Blend::new(af.proxy().unwrap(), &mf).unwrap();
    let bc = Blend::new(ac.proxy().unwrap(), &mc).unwrap();
    let n = bf.n();
    let mut bound = vec![[0.0f32; 2]; n as usize];
    for (wk, m) in w.iter().zip(&mc) {
        for i in 0..n {
            let e = m.position_error(i).unwrap();
            for a in 0..2 {
                bound[i as usize][a] += wk * e[a];
            }
        }
    }
    let slack = 1e-6;
    let pts: Vec<_> = (0..n).map(|i| bf.sample(&w, i).unwrap()).collect();
    let mut worst = 0.0f32;
    for i in 0..n {
        let (a, b) = (pts[i as usize], bc.sample(&w, i).unwrap());
        for x in 0..2 {
            let err = (a.position[x] - b.position[x]).abs();
            assert!(err <= bound[i as usize][x] + slack, "sample {i}");
            worst = worst.max(err);
        }
    }
    for q in 0..40 {
        let c = [
            0.1 + 0.8 * ((q as f32 * 0.618) % 1.0),
            0.1 + 0.8 * ((q as f32 * 0.382) % 1.0),
        ];
        let (lo, hi) = ([c[0] - 0.1, c[1] - 0.05], [c[0] + 0.05, c[1] + 0.1]);
        let inside = |grow: f32| {
            pts.iter()
                .zip(&bound)
                .filter(|(s, e)| {
                    (0..2).all(|x| {
                        let g = grow * (e[x] + slack);
                        s.position[x] >= lo[x] - g && s.position[x] <= hi[x] + g
                    })
                })
                .count() as u32
        };
        let count = bc.range(&w, &lo, &hi).unwrap().count;
        assert!(inside(-1.0) <= count && count <= inside(1.0), "range {q}");
    }

    // Whole images: point-query renders of both differ by little (measured, and printed for the
    // record; the bound per point is what the assertions above check).
    let settings = RenderSettings {
        width: 64,
        height: 64,
        method: Method::Query,
        sigma_px: 1.0,
    };
    let imf = render(af.proxy().unwrap(), &mf, &w, &settings).unwrap();
    let imc = render(ac.proxy().unwrap(), &mc, &w, &settings).unwrap();
    let diff = imf
        .pixels
        .iter()
        .zip(&imc.pixels)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max);
    let largest = mc
        .iter()
        .flat_map(|m| m.max_position_error().into_iter().take(2))
        .fold(0.0, f32::max);
    println!(
        "largest stated position error {largest:.3e}, largest sample error {worst:.3e}, largest pixel difference {diff:.3e}"
    );
    assert!(worst > 0.0, "compact positions are quantized");
    assert!(diff < 0.02, "largest pixel difference {diff}");
    let sigma = 1.0 / 64.0;
    for q in 0..20 {
        let p = [
            0.1 + 0.8 * ((q as f32 * 0.7) % 1.0),
            0.1 + 0.8 * ((q as f32 * 0.3) % 1.0),
        ];
        let (a, b) = (
            bf.point(&w, &p, Kernel { sigma }).unwrap(),
            bc.point(&w, &p, Kernel { sigma }).unwrap(),
        );
        assert!(
            (a.density - b.density).abs() <= 0.02 * a.density.max(1.0),
            "{a:?} vs {b:?}"
        );
    }
}

#[test]
fn a_manifest_stores_only_what_it_asks_for() {
    let dir = scratch("storage-only");
    let m = manifest(
        &dir,
        "lean",
        1500,
        "[storage]\npositions = \"u16\"\nnode_boxes = \"u16\"\ncolors = \"u8\"\nnode_colors = false\n",
    );
    bake(&m, &BakeOptions::default()).unwrap();
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    let want = Storage {
        positions: Precision::U16,
        node_boxes: Precision::U16,
        colors: Some(Precision::U8),
        node_colors: false,
        spacings: true,
    };
    assert!(maps
        .iter()
        .all(|m| m.storage() == want && !m.has_node_colors()));
    // Point renders work; level of detail (range queries of color) is refused with a clear error.
    let out = otbake_ok(&dir, &["inspect", m.map_archive("duck").to_str().unwrap()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("positions=u16 node_boxes=u16 colors=u8 node_colors=no spacings=yes")
            && text.contains("node_colors=0 B"),
        "{text}"
    );
    otbake_ok(
        &dir,
        &[
            "texture",
            "lean.toml",
            "--weights",
            "0.25,0.25,0.25,0.25",
            "--size",
            "16x16",
            "-o",
            "t.png",
        ],
    );
    let err = otbake_err(
        &dir,
        &[
            "texture",
            "lean.toml",
            "--weights",
            "0.25,0.25,0.25,0.25",
            "--size",
            "16x16",
            "--lod",
            "2",
            "-o",
            "l.png",
        ],
    );
    assert!(
        err.contains("node color sums") && err.contains("[storage]"),
        "{err}"
    );

    // Density only: no colors at all, and the images still render.
    let m = manifest(
        &dir,
        "density",
        1500,
        "[storage]\npreset = \"compact\"\ncolors = \"none\"\n",
    );
    bake(&m, &BakeOptions::default()).unwrap();
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    assert!(maps.iter().all(|m| !m.has_color() && m.color(0).is_none()));
    let blend = Blend::new(a.proxy().unwrap(), &maps).unwrap();
    assert!(!blend.has_color());
    let r = blend.range(&[0.25; 4], &[0.0, 0.0], &[1.0, 1.0]).unwrap();
    assert_eq!(r.count, blend.n());
    let bytes = std::fs::metadata(m.map_archive("duck")).unwrap().len();
    // 2 bytes per point (u8 positions) and 8 per internal node (u16 boxes), plus a header.
    let internal = (1u64 << otbake_formats::tree::depth(1500, 8)) - 1;
    assert!(bytes <= 1500 * 2 + internal * 8 + 1024, "{bytes} bytes");
}

/// Quantized archives are the same bytes for any thread count (and the encoder is deterministic).
#[test]
fn compact_bakes_are_thread_count_independent() {
    let bin = otbake_tests::otbake_bin();
    let mut outputs: Vec<Vec<Vec<u8>>> = Vec::new();
    for threads in ["1", "3"] {
        let dir = scratch(&format!("storage-threads-{threads}"));
        let m = manifest(&dir, "c", 3000, "[storage]\npreset = \"compact\"\n");
        let st = std::process::Command::new(&bin)
            .args(["bake", m.path.to_str().unwrap()])
            .env("RAYON_NUM_THREADS", threads)
            .status()
            .unwrap();
        assert!(st.success());
        let files = SHAPES.iter().map(|s| m.map_archive(s));
        outputs.push(files.map(|f| std::fs::read(f).unwrap()).collect());
    }
    assert_eq!(
        outputs[0], outputs[1],
        "archives differ between thread counts"
    );
}
