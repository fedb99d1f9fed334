//! `wrap = "periodic"` end to end on the real tileable textures of `../shared/data/textures`: a
//! periodic blend tiles (its seam, as `shared/data/README.md` measures it, is no worse than its
//! inputs'), queries near the seam equal brute force over the folded samples, `otbake texture`
//! writes tileable images, bad manifests are refused clearly, the wrap is part of the cache key, and
//! bakes are byte-identical for any thread count.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions, Status};
use otbake::render::texture::{render_texture, WeightField};
use otbake::render::Archives;
use otbake_lab::seam::{seam, seam_of_file};
use otbake_runtime::{Blend, Kernel, Wrap};
use otbake_tests::{otbake_err, otbake_ok, scratch, shared_data, write_manifest};
use std::path::PathBuf;

fn texture(name: &str) -> String {
    shared_data()
        .join("textures")
        .join(name)
        .display()
        .to_string()
}

const ONYX: &str = "marble_onyx003_ambientcg_1k.jpg";
const PEBBLES: &str = "pebbles_stonewall_godot.png";

/// A manifest of onyx and pebbles: periodic (uniform proxy) or, for comparison, the clamped
/// Gaussian-proxy bake the textures manifests used before.
fn body(periodic: bool, samples: usize, solver: &str) -> String {
    let (proxy, wrap) = if periodic {
        ("uniform", "wrap = \"periodic\"\n")
    } else {
        ("gaussian", "")
    };
    format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"{proxy}\"\nsamples = {samples}\n[solver]\nkind = \"{solver}\"\n\
         [[input]]\nname = \"onyx\"\npath = \"{}\"\n{wrap}[[input]]\nname = \"pebbles\"\npath = \"{}\"\n{wrap}",
        texture(ONYX),
        texture(PEBBLES)
    )
}

fn baked(name: &str, body: &str) -> Manifest {
    let dir = scratch(name);
    let m = Manifest::load(&write_manifest(&dir, "m.toml", body)).unwrap();
    let r = bake(&m, &BakeOptions::default()).unwrap();
    assert!(!r.failed(), "{r:?}");
    m
}

/// The worse seam (of its two joins) of a 128² tile of the blend for `w`, rendered like `otbake
/// texture` (a point query per pixel, σ = 1.5 px).
fn tile_seam(m: &Manifest, w: &[f32]) -> f64 {
    let a = Archives::load(m).unwrap();
    let maps = a.maps().unwrap();
    let field = WeightField::Constant(w.to_vec());
    let img = render_texture(a.proxy().unwrap(), &maps, &field, 128, 128, 1.5).unwrap();
    seam(img.width, img.height, &img.pixels).worst()
}

/// The test: the seam of a blended tile of two tileable textures is no worse than the
/// inputs' (each input's file, and each input rendered alone the same way). The same blend baked
/// clamped shows a seam, so the measure can fail. Measured (n = 20 000, 128² tiles, the worse join):
/// files 1.12 and 0.99, inputs rendered 0.81 and 1.39, blends ½ + ½ 0.98, ¼ + ¾ 1.26, 0.8 + 0.2
/// 0.84; the clamped ½ + ½ blend 2.65.
#[test]
fn a_periodic_blend_of_tileable_textures_tiles() {
    let m = baked("periodic-seam", &body(true, 20_000, "sliced"));
    assert_eq!(m.wrap(), Wrap::Periodic);
    let files: Vec<f64> = [ONYX, PEBBLES]
        .iter()
        .map(|f| seam_of_file(&PathBuf::from(texture(f))).unwrap().worst())
        .collect();
    let inputs = [tile_seam(&m, &[1.0, 0.0]), tile_seam(&m, &[0.0, 1.0])];
    let inputs_worst = files.iter().chain(&inputs).copied().fold(0.0, f64::max);
    for w in [[0.5f32, 0.5], [0.25, 0.75], [0.8, 0.2]] {
        let blend = tile_seam(&m, &w);
        eprintln!("periodic: files {files:?}, inputs rendered {inputs:?}, blend {w:?}: {blend:.3}");
        assert!(
            blend <= inputs_worst,
            "blend {w:?} seam {blend:.3} is worse than the inputs' ({inputs_worst:.3})"
        );
        assert!(blend < 1.5, "blend {w:?} seam {blend:.3}");
    }
    let clamped = baked("periodic-seam-clamp", &body(false, 20_000, "sliced"));
    let blend = tile_seam(&clamped, &[0.5, 0.5]);
    eprintln!("clamped blend: {blend:.3}");
    assert!(
        blend > 2.0,
        "the clamped blend's seam {blend:.3} should show"
    );
}

fn fold(v: f64) -> f64 {
    let f = v - v.floor();
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

/// On a real periodic bake, point queries within 3σ of the borders and corners equal brute force
/// over the folded blended samples with the torus distance, and range boxes across a border count
/// the points of every piece.
#[test]
fn queries_near_the_seam_equal_brute_force_on_a_real_bake() {
    let m = baked("periodic-brute", &body(true, 4000, "sinkhorn"));
    let a = Archives::load(&m).unwrap();
    let maps = a.maps().unwrap();
    let blend = Blend::new(a.proxy().unwrap(), &maps).unwrap();
    assert_eq!(blend.wrap(), Wrap::Periodic);
    let w = [0.3f32, 0.7];
    let pts: Vec<[f64; 2]> = (0..blend.n())
        .map(|i| {
            let s = blend.sample(&w, i).unwrap();
            [f64::from(s.position[0]), f64::from(s.position[1])]
        })
        .collect();
    assert!(pts.iter().flatten().all(|v| (0.0..1.0).contains(v)));
    let sigma = 0.02f64;
    let norm = 1.0 / (2.0 * std::f64::consts::PI * sigma * sigma) / (1.0 - (-4.5f64).exp());
    let circ = |a: f64, b: f64| {
        let t = (a - b).abs();
        t.min(1.0 - t)
    };
    let mut near_border = 0;
    for q in 0..60 {
        let u = (q as f64 * 0.618_034).fract();
        let v = (q as f64 * 0.414_214).fract();
        // Points within 0.03 of an edge or a corner, and a few anywhere.
        let p = match q % 4 {
            0 => [0.03 * u, v],
            1 => [u, 1.0 - 0.03 * v],
            2 => [1.0 - 0.03 * u, 0.03 * v],
            _ => [u, v],
        };
        near_border += (q % 4 != 3) as usize;
        let brute: f64 = pts
            .iter()
            .map(|s| {
                let r2 = circ(s[0], p[0]).powi(2) + circ(s[1], p[1]).powi(2);
                if r2 <= 9.0 * sigma * sigma {
                    norm * (-0.5 * r2 / (sigma * sigma)).exp()
                } else {
                    0.0
                }
            })
            .sum::<f64>()
            / pts.len() as f64;
        let pf = [p[0] as f32, p[1] as f32];
        let got = f64::from(
            blend
                .point(
                    &w,
                    &pf,
                    Kernel {
                        sigma: sigma as f32,
                    },
                )
                .unwrap()
                .density,
        );
        assert!(
            (got - brute).abs() <= 1e-3 * brute.max(1.0),
            "at {p:?}: {got} vs {brute}"
        );
        // A box across the left/right (and sometimes the top/bottom) border.
        let (lo, hi) = ([p[0] - 0.05, p[1] - 0.1], [p[0] + 0.04, p[1] + 0.02]);
        let count = pts
            .iter()
            .filter(|s| {
                (0..2).all(|k| {
                    let t = fold(s[k] - fold(lo[k]));
                    t <= hi[k] - lo[k]
                })
            })
            .count();
        let lof = [lo[0] as f32, lo[1] as f32];
        let hif = [hi[0] as f32, hi[1] as f32];
        assert_eq!(
            blend.range(&w, &lof, &hif).unwrap().count as usize,
            count,
            "box {lo:?}..{hi:?}"
        );
    }
    assert!(near_border >= 45);
}

/// `otbake texture` on a periodic manifest writes images whose tiles join without a seam (the file
/// as written, 8-bit sRGB), and `inspect` names the wrap.
#[test]
fn the_texture_command_writes_tileable_images() {
    let dir = scratch("periodic-cli");
    write_manifest(&dir, "m.toml", &body(true, 8000, "sliced"));
    otbake_ok(
        &dir,
        &[
            "texture",
            "m.toml",
            "--weights",
            "0.5,0.5",
            "--size",
            "96x96",
            "-o",
            "tile.png",
        ],
    );
    let s = seam_of_file(&dir.join("tile.png")).unwrap();
    assert!(s.worst() < 1.5, "{s:?}");
    let out = otbake_ok(&dir, &["inspect", "out/onyx.otb"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("wrap=periodic"), "{text}");
    let out = otbake_ok(&dir, &["inspect", "out/proxy.otb"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("wrap=periodic"));
}

/// Bad combinations are refused before anything is baked, naming the manifest line and the fix.
#[test]
fn bad_periodic_manifests_are_refused_clearly() {
    let dir = scratch("periodic-bad");
    let good = body(true, 500, "sliced");
    // Only the second input is periodic.
    let mixed = good.replacen("wrap = \"periodic\"\n", "", 1);
    write_manifest(&dir, "mixed.toml", &mixed);
    let err = otbake_err(&dir, &["bake", "mixed.toml"]);
    assert!(err.contains("mixed.toml:14:8"), "{err}");
    assert!(err.contains("on every input"), "{err}");
    // A Gaussian proxy.
    write_manifest(
        &dir,
        "gauss.toml",
        &good.replace("\"uniform\"", "\"gaussian\""),
    );
    let err = otbake_err(&dir, &["bake", "gauss.toml"]);
    assert!(err.contains("gauss.toml:4:8"), "{err}");
    assert!(err.contains("kind = \"uniform\""), "{err}");
    // A periodic volume.
    let vol = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"uniform\"\nsamples = 500\n[solver]\nkind = \"sliced\"\n\
         [[input]]\nname = \"smoke\"\npath = \"{}\"\nwrap = \"periodic\"\n",
        shared_data().join("volumes/smoke_44x45x53.vol").display()
    );
    write_manifest(&dir, "vol.toml", &vol);
    let err = otbake_err(&dir, &["bake", "vol.toml"]);
    assert!(
        err.contains("vol.toml:11:8") && err.contains("remove `wrap`"),
        "{err}"
    );
    // A misspelt value.
    write_manifest(&dir, "typo.toml", &good.replace("\"periodic\"", "\"tile\""));
    let err = otbake_err(&dir, &["bake", "typo.toml"]);
    assert!(
        err.contains("typo.toml:11:8") && err.contains("periodic"),
        "{err}"
    );
    assert!(!dir.join("out").exists(), "nothing is written");
}

/// The wrap is part of the proxy's and every map's key: turning it off rebakes everything (with a
/// uniform proxy either way), turning it back on restores from the store; and periodic bakes are
/// byte-identical for any thread count.
#[test]
fn wrap_is_keyed_and_bakes_are_thread_count_independent() {
    let periodic = body(true, 3000, "sinkhorn");
    let clamped = periodic.replace("wrap = \"periodic\"\n", "");
    let dir = scratch("periodic-key");
    let m = Manifest::load(&write_manifest(&dir, "m.toml", &periodic)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let first: Vec<Vec<u8>> = ["proxy", "onyx", "pebbles"]
        .iter()
        .map(|f| std::fs::read(dir.join(format!("out/{f}.otb"))).unwrap())
        .collect();
    let m2 = Manifest::load(&write_manifest(&dir, "m.toml", &clamped)).unwrap();
    let r = bake(&m2, &BakeOptions::default()).unwrap();
    assert!(
        r.products.iter().all(|p| p.status == Status::Built),
        "{r:?}"
    );
    let m3 = Manifest::load(&write_manifest(&dir, "m.toml", &periodic)).unwrap();
    let r = bake(&m3, &BakeOptions::default()).unwrap();
    assert!(
        r.products.iter().all(|p| p.status == Status::Cached),
        "{r:?}"
    );

    for threads in ["1", "2"] {
        let d = scratch(&format!("periodic-threads-{threads}"));
        write_manifest(&d, "m.toml", &periodic);
        let out = std::process::Command::new(otbake_tests::otbake_bin())
            .args(["bake", "m.toml"])
            .current_dir(&d)
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(out.status.success());
        for (f, want) in ["proxy", "onyx", "pebbles"].iter().zip(&first) {
            let got = std::fs::read(d.join(format!("out/{f}.otb"))).unwrap();
            assert!(&got == want, "{f}.otb differs with {threads} threads");
        }
    }
}

/// The shipped texture manifests are periodic, with a uniform proxy.
#[test]
fn shipped_texture_manifests_are_periodic() {
    for name in ["textures.toml", "terrain.toml"] {
        let m = Manifest::load(&otbake_tests::repo_root().join("manifests").join(name)).unwrap();
        assert_eq!(m.wrap(), Wrap::Periodic, "{name}");
        assert_eq!(
            m.proxy.source,
            otbake::manifest::ProxySource::Shape(otbake::proxy::ProxyShape::Uniform),
            "{name}"
        );
    }
}
