//! The BRDF commands end to end, bad BRDF inputs, and sliced assignment maps at unit weights.

// RGB loops index several arrays at once.
#![allow(clippy::needless_range_loop)]
mod brdf_support;

use brdf_support::*;
use otbake::input::brdf::merl::{self, Merl};
use otbake::input::brdf::{grid_value, luminance};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::brdf::eval::{BrdfBlend, BrdfKernel};
use otbake::render::Archives;
use otbake_tests::{otbake_err, otbake_ok, scratch, write_manifest};

#[test]
fn brdf_commands_write_images_and_merl_files() {
    let (dir, _) = synthetic("brdf-cli", 1000);
    let m = "brdfs.toml";
    otbake_ok(
        &dir,
        &[
            "brdf-slice",
            m,
            "--weights",
            "0.5,0.5",
            "--size",
            "32",
            "--sigma",
            "0.1",
            "-o",
            "slice.png",
        ],
    );
    let img = image::open(dir.join("slice.png")).unwrap();
    assert_eq!((img.width(), img.height()), (32, 32));
    // Without --sigma: the adaptive kernel, --scale spacings wide.
    otbake_ok(
        &dir,
        &[
            "brdf-slice",
            m,
            "--weights",
            "0.5,0.5",
            "--size",
            "16",
            "--scale",
            "3",
            "-o",
            "adaptive.png",
        ],
    );
    let img = image::open(dir.join("adaptive.png")).unwrap();
    assert_eq!((img.width(), img.height()), (16, 16));
    let e = otbake_err(
        &dir,
        &[
            "brdf-slice",
            m,
            "--weights",
            "1,0",
            "--sigma",
            "0.1",
            "--scale",
            "2",
            "-o",
            "x.png",
        ],
    );
    assert!(e.contains("cannot be used with"), "{e}");
    otbake_ok(
        &dir,
        &[
            "brdf-spheres",
            m,
            "--steps",
            "3",
            "--size",
            "12",
            "--sigma",
            "0.1",
            "-o",
            "spheres.png",
        ],
    );
    let img = image::open(dir.join("spheres.png")).unwrap();
    assert_eq!(
        (img.width(), img.height()),
        (36, 12),
        "2 inputs: one row of 3 spheres"
    );
    otbake_ok(
        &dir,
        &[
            "brdf-export",
            m,
            "--weights",
            "1,0",
            "--sigma",
            "0.1",
            "-o",
            "red.out.binary",
        ],
    );
    assert_eq!(
        std::fs::metadata(dir.join("red.out.binary")).unwrap().len() as usize,
        merl::FILE_BYTES
    );
    let e = otbake_err(&dir, &["brdf-slice", m, "--weights", "1", "-o", "x.png"]);
    assert!(e.contains("one weight per input"), "{e}");
}

#[test]
fn bad_brdf_inputs_are_clear_errors() {
    let dir = scratch("brdf-bad");
    let good = Merl::from_fn(|a, b, c| RED.eval(a, b, c)).to_bytes();
    std::fs::write(dir.join("short.binary"), &good[..good.len() / 2]).unwrap();
    let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 500\n[solver]\nkind = \"exact\"\n[brdf]\nresolution = 8\n[[input]]\nname = \"short\"\npath = \"short.binary\"\n";
    write_manifest(&dir, "m.toml", body);
    let e = otbake_err(&dir, &["bake", "m.toml"]);
    assert!(e.contains("short.binary") && e.contains("truncated"), "{e}");

    write_manifest(
        &dir,
        "res.toml",
        &body.replace("resolution = 8", "resolution = 1"),
    );
    let e = otbake_err(&dir, &["bake", "res.toml"]);
    assert!(
        e.contains("res.toml:9:14") && e.contains("brdf.resolution"),
        "{e}"
    );

    std::fs::write(dir.join("ok.binary"), &good).unwrap();
    let inverted = body.replace("short.binary", "ok.binary").replace(
        "path = \"ok.binary\"",
        "path = \"ok.binary\"\ndensity = \"inverted\"",
    );
    write_manifest(&dir, "inv.toml", &inverted);
    let e = otbake_err(&dir, &["bake", "inv.toml"]);
    assert!(e.contains("inv.toml:13:") && e.contains("luminance"), "{e}");

    std::fs::write(dir.join("c.brdf"), "31\n400 410 420\n0.1 0 0.2 0 1 1\n").unwrap();
    write_manifest(&dir, "c.toml", &body.replace("short.binary", "c.brdf"));
    let e = otbake_err(&dir, &["bake", "c.toml"]);
    assert!(e.contains("c.brdf:3:") && e.contains("wavelength"), "{e}");

    // Compact maps store no spacings: the default (adaptive) kernel says what to do.
    let compact = body.replace("short.binary", "ok.binary") + "[storage]\npreset = \"compact\"\n";
    write_manifest(&dir, "compact.toml", &compact);
    let e = otbake_err(
        &dir,
        &[
            "brdf-slice",
            "compact.toml",
            "--weights",
            "1",
            "--size",
            "8",
            "-o",
            "s.png",
        ],
    );
    assert!(e.contains("no spacings") && e.contains("--sigma"), "{e}");
    let ok = otbake_ok(
        &dir,
        &[
            "brdf-slice",
            "compact.toml",
            "--weights",
            "1",
            "--size",
            "8",
            "--sigma",
            "0.1",
            "-o",
            "s.png",
        ],
    );
    assert!(ok.status.success());
}

/// `[solver] kind = "sliced"`, `map = "assignment"` (issue 6): at unit weights the blend's points
/// are exactly the input's importance samples, so the blend evaluates like an archive built on
/// those samples (what `brdf_accuracy`'s "samples" column measures: the kernel's error alone),
/// while the flow's endpoints (`map = "flow"`) are not the samples.
#[test]
fn sliced_assignment_reproduces_the_inputs_samples_at_unit_weights() {
    use otbake_formats::Wrap;
    use otbake_runtime::{AdaptiveKernel, Map, Proxy};

    let n = 3000;
    let (dir, flow) = synthetic("brdf-sliced-assignment", n);
    let body = std::fs::read_to_string(dir.join("brdfs.toml"))
        .unwrap()
        .replace("kind = \"exact\"", "kind = \"sliced\"");
    let flow_path = write_manifest(
        &dir,
        "flow.toml",
        &body.replace("dir = \"out\"", "dir = \"flow\""),
    );
    let snap_path = write_manifest(
        &dir,
        "snap.toml",
        &body.replace(
            "kind = \"sliced\"",
            "kind = \"sliced\"\nmap = \"assignment\"",
        ),
    );
    drop(flow);
    let kernel = BrdfKernel::Adaptive(AdaptiveKernel {
        scale: 2.0,
        min_sigma: 0.01,
        max_sigma: 0.3,
    });
    let dim = 3;
    let multiset = |points: &mut Vec<[u32; 3]>| points.sort();
    for (path, one_to_one) in [(snap_path, true), (flow_path, false)] {
        let m = Manifest::load(&path).unwrap();
        bake(&m, &BakeOptions::default()).unwrap();
        let archives = Archives::load(&m).unwrap();
        let maps = archives.maps().unwrap();
        let b = BrdfBlend::with_kernel(archives.proxy().unwrap(), &maps, kernel).unwrap();
        for (which, w) in [(0usize, [1.0f32, 0.0]), (1, [0.0, 1.0])] {
            let spec = &m.inputs[which];
            let grid = otbake::input::load_with(&spec.path, spec.density, &spec.options).unwrap();
            let samples = otbake::sample::importance_sample(&grid, n, spec.seed).unwrap();
            // The blend's points at unit weight against the samples, as multisets of bits.
            let mut got: Vec<[u32; 3]> = (0..n as u32)
                .map(|i| {
                    let p = b.blend.sample(&w, i).unwrap().position;
                    [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()]
                })
                .collect();
            let mut want: Vec<[u32; 3]> = samples
                .chunks_exact(dim)
                .map(|p| [p[0].to_bits(), p[1].to_bits(), p[2].to_bits()])
                .collect();
            multiset(&mut got);
            multiset(&mut want);
            assert_eq!(got == want, one_to_one, "{path:?} input {which}");
            if !one_to_one {
                continue;
            }
            // An archive whose points are the samples (brdf_accuracy's "samples"): the same
            // values up to the order of the sums, so the same error against the grid.
            let order = otbake::tree::tree_order(&samples, dim, m.proxy.leaf_size);
            let positions = otbake::tree::permute(&samples, dim, &order);
            let spacings = otbake::spacing::spacings(&positions, dim, Wrap::Clamp);
            let (proxy, identity) = otbake::pipeline::archive::identity_archives(
                &grid,
                dim,
                m.proxy.leaf_size,
                positions,
                spacings,
            )
            .unwrap();
            let own = [Map::open(&identity).unwrap()];
            let reference =
                BrdfBlend::with_kernel(Proxy::open(&proxy).unwrap(), &own, kernel).unwrap();
            let (mut err_map, mut err_samples) = (0.0, 0.0);
            for &(ti, to, pd) in &interior() {
                let got = b.eval_angles(&w, ti, to, pd).unwrap();
                let want = reference.eval_angles(&[1.0], ti, to, pd).unwrap();
                assert!(
                    (got.luminance - want.luminance).abs() <= 1e-4 * want.luminance.abs().max(1e-6),
                    "input {which} at {ti} {to} {pd}: {} vs samples {}",
                    got.luminance,
                    want.luminance
                );
                let truth = luminance(grid_value(&grid, ti, to, pd));
                err_map += (f64::from(got.luminance) / truth - 1.0).abs();
                err_samples += (f64::from(want.luminance) / truth - 1.0).abs();
            }
            let k = interior().len() as f64;
            assert!(
                (err_map - err_samples).abs() / k < 1e-4,
                "input {which}: mean error {} (map) vs {} (samples)",
                err_map / k,
                err_samples / k
            );
        }
    }
}
