//! The volume commands end to end (render, slice, volume), bad meshes and `.vol` grids, the
//! common mesh fit, and the shipped volume manifests.

mod volume_support;

use otbake::input::mesh::shapes::{cuboid, icosphere};
use otbake::input::mesh::voxelize::{self, Fit, MeshOptions, Placement};
use otbake::input::vol::VolFile;
use otbake::input::{load_with, DensityChannel, LoadOptions};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake_runtime::Blend;
use otbake_tests::{otbake_bin, otbake_err, otbake_ok, scratch, shared_data, write_manifest};
use std::path::Path;
use volume_support::*;

#[test]
fn render_slice_and_volume_commands() {
    let dir = scratch("vol-cli");
    write_obj(&dir, "cube.obj", &cuboid([0.0; 3], [1.0; 3]));
    write_obj(&dir, "ball.obj", &icosphere([0.0; 3], 1.0, 2));
    write_obj(&dir, "long.obj", &cuboid([0.0; 3], [1.0, 0.3, 0.3]));
    let body = manifest_head(800, "exact", "resolution = 16\nmargin = 0.15")
        + &input("cube", "cube.obj")
        + &input("ball", "ball.obj")
        + &input("long", "long.obj");
    write_manifest(&dir, "m.toml", &body);
    let common = ["--size", "16", "--sigma", "0.04"];
    let run = |args: &[&str]| {
        let mut all = args.to_vec();
        all.extend(common);
        otbake_ok(&dir, &all);
    };
    run(&[
        "render",
        "m.toml",
        "--weights",
        "0.2,0.3,0.5",
        "-o",
        "one.png",
    ]);
    let img = image::open(dir.join("one.png")).unwrap();
    assert_eq!((img.width(), img.height()), (16, 16));
    run(&["render", "m.toml", "--triangle", "3", "-o", "tri.png"]);
    let img = image::open(dir.join("tri.png")).unwrap();
    // 3 rows of 16 px; 5 half-cell columns of 8 px plus the last half cell.
    assert_eq!((img.width(), img.height()), (48, 48));
    run(&[
        "slice",
        "m.toml",
        "--weights",
        "0,1,0",
        "--axis",
        "y",
        "-o",
        "slice.png",
    ]);
    let img = image::open(dir.join("slice.png")).unwrap().to_luma8();
    assert_eq!((img.width(), img.height()), (16, 16));
    // The ball's central slice: bright in the middle, dark in the corners.
    assert!(img.get_pixel(8, 8)[0] > 150 && img.get_pixel(0, 0)[0] < 30);

    // Images and grids do not depend on the thread count.
    let threads = |n: &str, out: &str, args: &[&str]| {
        let status = std::process::Command::new(otbake_bin())
            .args(args)
            .args(["-o", out])
            .current_dir(&dir)
            .env("RAYON_NUM_THREADS", n)
            .status()
            .unwrap();
        assert!(status.success());
        std::fs::read(dir.join(out)).unwrap()
    };
    let args = [
        "render",
        "m.toml",
        "--weights",
        "0.2,0.3,0.5",
        "--size",
        "24",
        "--sigma",
        "0.04",
    ];
    assert_eq!(threads("1", "r1.png", &args), threads("2", "r2.png", &args));
    let args = [
        "volume",
        "m.toml",
        "--weights",
        "0.5,0,0.5",
        "--res",
        "12",
        "--sigma",
        "0.04",
    ];
    assert_eq!(threads("1", "v1.vol", &args), threads("2", "v2.vol", &args));
    // So are bakes of mesh maps (voxelization, sampling and solve).
    let args = [
        "bake-one",
        "m.toml",
        "--product",
        "ball",
        "--proxy",
        "out/proxy.otb",
    ];
    assert_eq!(threads("1", "b1.otb", &args), threads("2", "b2.otb", &args));

    let e = otbake_err(
        &dir,
        &["render", "m.toml", "--weights", "0.5,0.5", "-o", "x.png"],
    );
    assert!(e.contains("one weight per input"), "{e}");
    let e = otbake_err(
        &dir,
        &[
            "volume",
            "m.toml",
            "--weights",
            "1,0,0",
            "--res",
            "0",
            "-o",
            "x.vol",
        ],
    );
    assert!(e.contains("--res 0"), "{e}");

    // 2D manifests are refused by the volume commands, and --triangle needs 3 inputs.
    let two = manifest_head(800, "exact", "resolution = 16")
        + &input("cube", "cube.obj")
        + &input("ball", "ball.obj");
    write_manifest(&dir, "two.toml", &two);
    let e = otbake_err(
        &dir,
        &["render", "two.toml", "--triangle", "3", "-o", "x.png"],
    );
    assert!(e.contains("exactly 3 inputs"), "{e}");
    let duck = shared_data().join("shapes/duck.png");
    let flat = "[output]\ndir = \"out2d\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n".to_string()
        + &input("duck", &duck.display().to_string());
    write_manifest(&dir, "flat.toml", &flat);
    let e = otbake_err(
        &dir,
        &["slice", "flat.toml", "--weights", "1", "-o", "x.png"],
    );
    assert!(
        e.contains("2-dimensional") && e.contains("3D inputs"),
        "{e}"
    );
}

#[test]
fn bad_meshes_are_clear_errors_or_documented_handling() {
    let dir = scratch("vol-bad-mesh");
    let bake_err = |file: &str, text: &str| {
        std::fs::write(dir.join(file), text).unwrap();
        let body = manifest_head(300, "exact", "resolution = 8") + &input("m", file);
        write_manifest(&dir, "m.toml", &body);
        otbake_err(&dir, &["bake", "m.toml"])
    };
    let e = bake_err("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    assert!(
        e.contains("points.obj") && e.contains("no faces") && e.contains("3 vertices"),
        "{e}"
    );
    let e = bake_err(
        "nan.obj",
        "v 0 0 0\nv 1 0 0\nv 0 NaN 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\n",
    );
    assert!(e.contains("nan.obj:3") && e.contains("non-finite"), "{e}");
    let e = bake_err("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 3 2\n");
    assert!(e.contains("flat.obj") && e.contains("zero area"), "{e}");
    let e = bake_err("junk.obj", "v 0 0 0\nf 1 2 7\n");
    assert!(e.contains("junk.obj") && e.contains("cannot parse"), "{e}");

    // Degenerate triangles among good ones are dropped: the same grid, so the same map points.
    let cube = cuboid([0.0; 3], [1.0; 3]).to_obj();
    std::fs::write(dir.join("cube.obj"), &cube).unwrap();
    std::fs::write(
        dir.join("cube-degenerate.obj"),
        cube + "v 0.2 0.2 0.2\nv 0.4 0.4 0.4\nf 1 1 2\nf 1 9 10\nf 3 3 3\n",
    )
    .unwrap();
    let body = manifest_head(400, "exact", "resolution = 12\nmargin = 0.2")
        + &input("clean", "cube.obj")
        + &input("degenerate", "cube-degenerate.obj");
    let m = Manifest::load(&write_manifest(&dir, "deg.toml", &body)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    let blend = Blend::new(archives.proxy().unwrap(), &maps).unwrap();
    assert_eq!(blended(&blend, &[1.0, 0.0]), blended(&blend, &[0.0, 1.0]));

    // Surfaces with holes are accepted: the winding number fills a hole like a soap film. A ball
    // missing a cap of triangles keeps its voxels within 1%; a cube missing its top face keeps
    // nearly all of its cells and gains none.
    let opts = MeshOptions {
        resolution: 32,
        margin: 0.1,
        fit: Fit::Each,
    };
    let ball = icosphere([0.0; 3], 1.0, 3);
    let mut holed = ball.clone();
    let before = holed.triangles.len();
    holed.triangles.retain(|t| {
        let c: f64 = t
            .iter()
            .map(|&i| ball.positions[i as usize][1])
            .sum::<f64>()
            / 3.0;
        c < 0.9
    });
    assert!(holed.triangles.len() < before);
    let place = Placement::fit([-1.0; 3], [1.0; 3], 0.1);
    let full: f32 = voxelize::voxelize(&ball, &place, 32).iter().sum();
    let open: f32 = voxelize::voxelize(&holed, &place, 32).iter().sum();
    assert!((open / full - 1.0).abs() < 0.01, "{open} vs {full}");
    let mut box_open = cuboid([0.0; 3], [1.0; 3]);
    box_open.triangles.truncate(10);
    let place = Placement::fit([0.0; 3], [1.0; 3], 0.25);
    let closed = voxelize::voxelize(&cuboid([0.0; 3], [1.0; 3]), &place, 32);
    let open = voxelize::voxelize(&box_open, &place, 32);
    assert!(
        open.iter().zip(&closed).all(|(o, c)| o <= c),
        "the open box gained cells"
    );
    let (o, c) = (open.iter().sum::<f32>(), closed.iter().sum::<f32>());
    assert!(o > 0.9 * c, "{o} of {c} cells");
    // Suzanne (43 open edges) loads; its grid holds the head: 5.4% of the cube at 32³ with margin
    // 0.1 (7.7% at 128³ with margin 0.05; the same solid, scaled by (0.8 / 0.9)³).
    let suzanne = shared_data().join("meshes/suzanne.obj");
    let grid = load_with(
        &suzanne,
        DensityChannel::Luminance,
        &LoadOptions {
            mesh: MeshOptions {
                resolution: 32,
                ..opts
            },
            ..Default::default()
        },
    )
    .unwrap();
    let fraction = grid.total_mass() / grid.cells() as f64;
    assert!((0.05..0.06).contains(&fraction), "{fraction}");
}

#[test]
fn bad_vol_files_name_the_byte_offset() {
    let dir = scratch("vol-bad-grid");
    let good = VolFile::density([4, 3, 2], (0..24).map(|i| i as f32).collect()).to_bytes();
    let bake_err = |file: &str, bytes: &[u8]| {
        std::fs::write(dir.join(file), bytes).unwrap();
        let body = manifest_head(300, "exact", "") + &input("v", file);
        write_manifest(&dir, "m.toml", &body);
        otbake_err(&dir, &["bake", "m.toml"])
    };
    let mut b = good.clone();
    b[0..3].copy_from_slice(b"XYZ");
    let e = bake_err("magic.vol", &b);
    assert!(
        e.contains("magic.vol at byte offset 0") && e.contains("\"VOL\""),
        "{e}"
    );
    let mut b = good.clone();
    b[4..8].copy_from_slice(&3i32.to_le_bytes());
    let e = bake_err("u8.vol", &b);
    assert!(e.contains("byte offset 4") && e.contains("uint8"), "{e}");
    let e = bake_err("short.vol", &good[..good.len() - 8]);
    assert!(
        e.contains("short.vol at byte offset 136") && e.contains("truncated"),
        "{e}"
    );
    let mut b = good.clone();
    b.extend_from_slice(&[1, 2, 3, 4]);
    let e = bake_err("long.vol", &b);
    assert!(
        e.contains("byte offset 144") && e.contains("after the last value"),
        "{e}"
    );
    let mut b = good.clone();
    b[48 + 4 * 17..48 + 4 * 18].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = bake_err("nan.vol", &b);
    // Value 17 = x 1, y 1, z 1.
    assert!(
        e.contains("nan.vol at byte offset 116") && e.contains("(x 1, y 1, z 1)"),
        "{e}"
    );
    let mut b = good.clone();
    b[48 + 4 * 5..48 + 4 * 6].copy_from_slice(&(-2.0f32).to_le_bytes());
    let e = bake_err("neg.vol", &b);
    assert!(e.contains("byte offset 68") && e.contains(">= 0"), "{e}");
    let e = bake_err(
        "empty.vol",
        &VolFile::density([2, 2, 2], vec![0.0; 8]).to_bytes(),
    );
    assert!(e.contains("every value is 0"), "{e}");
    // A density channel is meaningless for a volume.
    std::fs::write(dir.join("ok.vol"), &good).unwrap();
    let body = manifest_head(300, "exact", "") + &input("v", "ok.vol") + "density = \"alpha\"\n";
    write_manifest(&dir, "d.toml", &body);
    let e = otbake_err(&dir, &["bake", "d.toml"]);
    assert!(
        e.contains("d.toml:13:") && e.contains("remove `density`"),
        "{e}"
    );
}

/// Under `fit = "common"` a mesh's grid depends on every mesh file (the shared box): editing one
/// mesh rebakes the others' maps, and `plan` declares every mesh as an input of each mesh action.
/// Under `fit = "each"` it rebakes only its own map.
#[test]
fn common_fit_keys_and_plans_depend_on_every_mesh() {
    use otbake::pipeline::bake::Status;
    let dir = scratch("vol-common");
    for (fit, rebaked) in [("each", vec!["b"]), ("common", vec!["a", "b"])] {
        write_obj(&dir, "a.obj", &cuboid([0.0; 3], [1.0; 3]));
        write_obj(&dir, "b.obj", &icosphere([0.0; 3], 1.0, 2));
        let body = manifest_head(300, "exact", &format!("resolution = 8\nfit = \"{fit}\""))
            .replace("dir = \"out\"", &format!("dir = \"out-{fit}\""))
            + &input("a", "a.obj")
            + &input("b", "b.obj");
        let m = Manifest::load(&write_manifest(&dir, &format!("{fit}.toml"), &body)).unwrap();
        bake(&m, &BakeOptions::default()).unwrap();
        // A bigger ball changes the union of the boxes.
        write_obj(&dir, "b.obj", &icosphere([0.0; 3], 3.0, 2));
        let report = bake(&m, &BakeOptions::default()).unwrap();
        let built: Vec<&str> = report
            .products
            .iter()
            .filter(|p| p.status == Status::Built)
            .map(|p| p.name.as_str())
            .collect();
        assert_eq!(built, rebaked, "fit = {fit}");
        let actions = otbake::pipeline::plan::actions(&m, Path::new("otbake"));
        let a = actions.iter().find(|x| x.id == "a").unwrap();
        let reads_b = a.inputs.iter().any(|p| p.ends_with("b.obj"));
        assert_eq!(reads_b, fit == "common", "fit = {fit}: {:?}", a.inputs);
    }
}

/// The shipped manifests: the 1M ones load (paths, [mesh] and [volume] settings), the small ones
/// bake and render.
#[test]
fn shipped_volume_manifests_load_and_the_small_ones_render() {
    let root = otbake_tests::repo_root().join("manifests");
    for (file, inputs) in [
        ("volumes.toml", ["cow", "fish", "torus"].as_slice()),
        ("smoke.toml", ["monkey", "smoke"].as_slice()),
    ] {
        let m = Manifest::load(&root.join(file)).unwrap();
        let names: Vec<&str> = m.inputs.iter().map(|i| i.name.as_str()).collect();
        assert_eq!(names, inputs, "{file}");
        assert_eq!(m.proxy.samples, 1_000_000, "{file}");
    }
    let dir = scratch("vol-shipped");
    let volumes = root.join("volumes-small.toml");
    let smoke = root.join("smoke-small.toml");
    let (volumes, smoke) = (volumes.to_str().unwrap(), smoke.to_str().unwrap());
    let sized = ["--size", "16", "--sigma", "0.04"];
    let mut args = vec!["render", volumes, "--triangle", "2", "-o", "tri.png"];
    args.extend(sized);
    otbake_ok(&dir, &args);
    let img = image::open(dir.join("tri.png")).unwrap();
    assert_eq!((img.width(), img.height()), (32, 32));
    let mut args = vec!["slice", smoke, "--weights", "0.5,0.5", "-o", "s.png"];
    args.extend(sized);
    otbake_ok(&dir, &args);
    let img = image::open(dir.join("s.png")).unwrap().to_luma8();
    assert!(
        img.pixels().any(|p| p[0] == 255),
        "the slice's largest value is white"
    );
}
