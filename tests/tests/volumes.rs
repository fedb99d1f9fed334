//! 3D inputs end to end: meshes sampled uniformly inside, `.vol` round trips, a blend of two balls
//! against its closed form, runtime 3D queries against brute force, the volume commands, and bad
//! meshes and grids.

use otbake::input::mesh::shapes::{cuboid, icosphere};
use otbake::input::mesh::voxelize::{self, Fit, MeshOptions, Placement};
use otbake::input::mesh::Mesh;
use otbake::input::vol::VolFile;
use otbake::input::{load_with, DensityChannel, LoadOptions};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake::sample::importance_sample;
use otbake_runtime::{Blend, Kernel};
use otbake_tests::{otbake_bin, otbake_err, otbake_ok, scratch, shared_data, write_manifest};
use std::path::{Path, PathBuf};

fn write_obj(dir: &Path, name: &str, mesh: &Mesh) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, mesh.to_obj()).unwrap();
    p
}

fn mesh_options(resolution: usize, margin: f64) -> LoadOptions {
    LoadOptions {
        mesh: MeshOptions {
            resolution,
            margin,
            fit: Fit::Each,
        },
        ..Default::default()
    }
}

/// Per-axis means and the covariance matrix of 3D points.
fn moments(pts: &[f32]) -> ([f64; 3], [[f64; 3]; 3]) {
    let n = (pts.len() / 3) as f64;
    let mut mean = [0.0; 3];
    for p in pts.chunks_exact(3) {
        for k in 0..3 {
            mean[k] += f64::from(p[k]) / n;
        }
    }
    let mut cov = [[0.0; 3]; 3];
    for p in pts.chunks_exact(3) {
        for a in 0..3 {
            for b in 0..3 {
                cov[a][b] += (f64::from(p[a]) - mean[a]) * (f64::from(p[b]) - mean[b]) / n;
            }
        }
    }
    (mean, cov)
}

fn manifest_head(samples: usize, solver: &str, mesh: &str) -> String {
    format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n[solver]\nkind = \"{solver}\"\n[mesh]\n{mesh}\n"
    )
}

fn input(name: &str, path: &str) -> String {
    format!("[[input]]\nname = \"{name}\"\npath = \"{path}\"\n")
}

/// All blended points of a blend at `w`, point-major.
fn blended(blend: &Blend<'_, '_>, w: &[f32]) -> Vec<f32> {
    (0..blend.n())
        .flat_map(|i| {
            let p = blend.sample(w, i).unwrap().position;
            [p[0], p[1], p[2]]
        })
        .collect()
}

#[test]
fn cube_and_sphere_meshes_are_sampled_uniformly_inside() {
    let dir = scratch("vol-uniform");
    // A cube of side 2 anywhere in space, margin 1/4: it lands on [1/4, 3/4]³, on cell faces of
    // the 32³ grid, so the voxelization is exact and no sample may leave the cube.
    let cube = write_obj(
        &dir,
        "cube.obj",
        &cuboid([-3.0, 1.0, 5.0], [-1.0, 3.0, 7.0]),
    );
    let grid = load_with(&cube, DensityChannel::Luminance, &mesh_options(32, 0.25)).unwrap();
    let pts = importance_sample(&grid, 20_000, 3).unwrap();
    assert!(
        pts.iter().all(|&x| (0.25..=0.75).contains(&x)),
        "a sample left the cube"
    );
    let (mean, cov) = moments(&pts);
    for a in 0..3 {
        assert!((mean[a] - 0.5).abs() < 2e-3, "mean {mean:?}");
        // Uniform on an interval of length 1/2: variance 1/48.
        assert!(
            (cov[a][a] * 48.0 - 1.0).abs() < 0.02,
            "variance {:?}",
            cov[a][a]
        );
        for b in 0..a {
            assert!(cov[a][b].abs() < 5e-4, "covariance {cov:?}");
        }
    }

    // A ball of radius 1 (icosphere, 5120 triangles), margin 0.1: radius 0.4 around the center.
    // Samples fill voxels whose centers are inside, so they reach at most half a cell diagonal
    // beyond the sphere; E|x − c|² = 3/5 r² for a uniform ball.
    let ball = write_obj(&dir, "ball.obj", &icosphere([10.0, -2.0, 0.5], 1.0, 4));
    let res = 48;
    let grid = load_with(&ball, DensityChannel::Luminance, &mesh_options(res, 0.1)).unwrap();
    let pts = importance_sample(&grid, 20_000, 5).unwrap();
    let (mean, cov) = moments(&pts);
    let r = 0.4;
    let slack = 3f64.sqrt() / 2.0 / res as f64;
    let dist = |p: &[f32]| {
        (0..3)
            .map(|k| (f64::from(p[k]) - 0.5).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    let far = pts.chunks_exact(3).map(dist).fold(0.0, f64::max);
    assert!(
        far <= r + slack,
        "a sample at distance {far} > {r} + {slack}"
    );
    assert!(far > r - slack, "samples do not reach the surface: {far}");
    for a in 0..3 {
        assert!((mean[a] - 0.5).abs() < 2e-3, "mean {mean:?}");
        assert!((cov[a][a] / (r * r / 5.0) - 1.0).abs() < 0.03, "{cov:?}");
    }
    let trace: f64 = (0..3).map(|k| cov[k][k]).sum();
    assert!(
        (trace / (0.6 * r * r) - 1.0).abs() < 0.03,
        "E|x-c|² {trace}"
    );

    // End to end through a bake (exact solver): the map's points are the cube's samples.
    let body =
        manifest_head(1500, "exact", "resolution = 32\nmargin = 0.25") + &input("cube", "cube.obj");
    let m = Manifest::load(&write_manifest(&dir, "m.toml", &body)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    let blend = Blend::new(archives.proxy().unwrap(), &maps).unwrap();
    let pts = blended(&blend, &[1.0]);
    assert!(pts.iter().all(|&x| (0.25..=0.75).contains(&x)));
    let (mean, _) = moments(&pts);
    assert!(mean.iter().all(|m| (m - 0.5).abs() < 0.01), "{mean:?}");
}

/// Uniform balls are translated and scaled copies of each other, so the transport between them
/// (and from one Gaussian proxy to each) is affine, and every blend is a uniform ball whose center
/// and radius interpolate linearly (displacement interpolation). A matching that is not optimal
/// shrinks the blend instead (independent pairs: rms radius √(½(rA² + rB²))/2 at t = ½).
#[test]
fn blend_of_two_balls_interpolates_center_and_radius() {
    let dir = scratch("vol-balls");
    let (ca, ra) = ([0.3, 0.4, 0.5], 0.15);
    let (cb, rb) = ([0.65, 0.6, 0.5], 0.25);
    write_obj(&dir, "a.obj", &icosphere(ca, ra, 3));
    write_obj(&dir, "b.obj", &icosphere(cb, rb, 3));
    // One box for both: their relative placement is kept.
    let body = manifest_head(
        2000,
        "exact",
        "resolution = 40\nfit = \"common\"\nmargin = 0.05",
    ) + &input("a", "a.obj")
        + &input("b", "b.obj");
    let m = Manifest::load(&write_manifest(&dir, "m.toml", &body)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    let blend = Blend::new(archives.proxy().unwrap(), &maps).unwrap();

    // The common placement of the union box [0.15, 0.9] × [0.25, 0.85] × [0.25, 0.75].
    let (lo, hi) = ([0.15, 0.25, 0.25], [0.9, 0.85, 0.75]);
    let place = Placement::fit(lo, hi, 0.05);
    let rms = |pts: &[f32], c: [f64; 3]| {
        let n = (pts.len() / 3) as f64;
        (pts.chunks_exact(3)
            .map(|p| {
                (0..3)
                    .map(|k| (f64::from(p[k]) - c[k]).powi(2))
                    .sum::<f64>()
            })
            .sum::<f64>()
            / n)
            .sqrt()
    };
    let (a_pts, b_pts) = (blended(&blend, &[1.0, 0.0]), blended(&blend, &[0.0, 1.0]));
    let (ma, mb) = (moments(&a_pts).0, moments(&b_pts).0);
    let (rms_a, rms_b) = (rms(&a_pts, ma), rms(&b_pts, mb));
    // The inputs themselves: placed centers and radii (rms = √(3/5) r), up to voxelization.
    for (m, c, got, r) in [(ma, ca, rms_a, ra), (mb, cb, rms_b, rb)] {
        let want = place.apply(c);
        assert!(
            (0..3).all(|k| (m[k] - want[k]).abs() < 0.01),
            "{m:?} vs {want:?}"
        );
        let want = (0.6f64).sqrt() * r * place.scale;
        assert!((got / want - 1.0).abs() < 0.05, "rms {got} vs {want}");
    }
    for t in [0.25f32, 0.5, 0.75] {
        let w = [1.0 - t, t];
        let pts = blended(&blend, &w);
        let t = f64::from(t);
        let (mean, _) = moments(&pts);
        let want = [0, 1, 2].map(|k| (1.0 - t) * ma[k] + t * mb[k]);
        assert!(
            (0..3).all(|k| (mean[k] - want[k]).abs() < 1e-4),
            "t {t}: center {mean:?} vs {want:?}"
        );
        let (got, want) = (rms(&pts, mean), (1.0 - t) * rms_a + t * rms_b);
        assert!(
            (got / want - 1.0).abs() < 0.03,
            "t {t}: rms radius {got} vs interpolated {want}"
        );
        let random = (((1.0 - t) * rms_a).powi(2) + (t * rms_b).powi(2)).sqrt();
        assert!(
            got > random * 1.15,
            "t {t}: {got} is no larger than a random matching's {random}"
        );
        // A uniform ball: 95% of the points within 0.983 r (the 0.95 quantile of r·U^(1/3)).
        let mut d: Vec<f64> = pts
            .chunks_exact(3)
            .map(|p| {
                (0..3)
                    .map(|k| (f64::from(p[k]) - mean[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .collect();
        d.sort_by(f64::total_cmp);
        let r_t = want / 0.6f64.sqrt();
        let q95 = d[d.len() * 95 / 100];
        assert!(
            (q95 / (0.983 * r_t) - 1.0).abs() < 0.05,
            "t {t}: 95% radius {q95} vs {}",
            0.983 * r_t
        );
    }
}

#[test]
fn runtime_3d_queries_equal_brute_force() {
    let dir = scratch("vol-brute");
    write_obj(&dir, "cube.obj", &cuboid([0.0; 3], [1.0, 0.6, 0.8]));
    write_obj(&dir, "ball.obj", &icosphere([0.0; 3], 1.0, 2));
    // A Gaussian blob as a .vol grid.
    let n = 12;
    let data = (0..n * n * n)
        .map(|i| {
            let c = [i % n, (i / n) % n, i / (n * n)].map(|x| (x as f64 + 0.5) / n as f64);
            let q: f64 = [0.4, 0.55, 0.5]
                .iter()
                .zip(c)
                .map(|(m, x)| ((x - m) / 0.15).powi(2))
                .sum();
            (-0.5 * q).exp() as f32
        })
        .collect();
    VolFile::density([n; 3], data)
        .write(&dir.join("blob.vol"))
        .unwrap();
    // The uniform box proxy here (the other tests use the Gaussian one).
    let body = manifest_head(1500, "exact", "resolution = 16")
        .replace("kind = \"gaussian\"", "kind = \"uniform\"")
        + &input("cube", "cube.obj")
        + &input("ball", "ball.obj")
        + &input("blob", "blob.vol");
    let m = Manifest::load(&write_manifest(&dir, "m.toml", &body)).unwrap();
    bake(&m, &BakeOptions::default()).unwrap();
    let archives = Archives::load(&m).unwrap();
    let maps = archives.maps().unwrap();
    let proxy = archives.proxy().unwrap();
    assert!(proxy.archived().description.contains("Uniform"));
    let blend = Blend::new(proxy, &maps).unwrap();
    let w = [0.2f32, 0.3, 0.5];
    let pts = blended(&blend, &w);
    let sigma = 0.05f32;
    let s = f64::from(sigma);
    // Normalized Gaussian truncated at 3σ: χ²₃ CDF at 9 = 0.970709.
    let norm = 1.0 / ((2.0 * std::f64::consts::PI).powf(1.5) * s.powi(3) * 0.970_709_1);
    let mean_mass: f64 = maps
        .iter()
        .zip(w)
        .map(|(m, w)| f64::from(w) * f64::from(m.mean_mass()))
        .sum();
    for q in 0..40 {
        // Half the queries at the blend's own points, half spread over the cube.
        let p: [f32; 3] = if q % 2 == 0 {
            let i = (q * 37) % blend.n() as usize;
            [pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]]
        } else {
            let f = q as f32;
            [(f * 0.618) % 1.0, (f * 0.382) % 1.0, (f * 0.7548) % 1.0]
        };
        let sum: f64 = pts
            .chunks_exact(3)
            .map(|y| (0..3).map(|k| f64::from(y[k] - p[k]).powi(2)).sum::<f64>())
            .filter(|&r2| r2 <= 9.0 * s * s)
            .map(|r2| (-0.5 * r2 / (s * s)).exp())
            .sum();
        let brute = sum * norm / f64::from(blend.n());
        let v = blend.point(&w, &p, Kernel { sigma }).unwrap();
        assert!(
            (f64::from(v.density) - brute).abs() <= 1e-4 * brute.max(1.0),
            "at {p:?}: {} vs {brute}",
            v.density
        );
        assert!(
            (f64::from(v.mass) - brute * mean_mass).abs() <= 1e-4 * (brute * mean_mass).max(1.0)
        );
        let (lo, hi) = (p.map(|x| x - 0.1), p.map(|x| x + 0.07));
        let count = pts
            .chunks_exact(3)
            .filter(|y| (0..3).all(|k| y[k] >= lo[k] && y[k] <= hi[k]))
            .count();
        assert_eq!(blend.range(&w, &lo, &hi).unwrap().count as usize, count);
    }
}

#[test]
fn vol_files_round_trip_and_volume_exports_the_blend() {
    // The shared Mitsuba grid: parse and write back, byte for byte.
    let smoke = shared_data().join("volumes/smoke_44x45x53.vol");
    let bytes = std::fs::read(&smoke).unwrap();
    let v = VolFile::parse(&smoke, &bytes).unwrap();
    assert_eq!(v.to_bytes(), bytes);
    let dir = scratch("vol-export");
    v.write(&dir.join("copy.vol")).unwrap();
    assert_eq!(std::fs::read(dir.join("copy.vol")).unwrap(), bytes);

    // A blob baked alone and exported at weight 1 comes back with its mass and center.
    let n = 16;
    let center = [0.45, 0.5, 0.55];
    let data: Vec<f32> = (0..n * n * n)
        .map(|i| {
            let c = [i % n, (i / n) % n, i / (n * n)].map(|x| (x as f64 + 0.5) / n as f64);
            let q: f64 = (0..3).map(|k| ((c[k] - center[k]) / 0.12).powi(2)).sum();
            (2.0 * (-0.5 * q).exp()) as f32
        })
        .collect();
    let mean_in = data.iter().map(|&x| f64::from(x)).sum::<f64>() / data.len() as f64;
    VolFile::density([n; 3], data)
        .write(&dir.join("blob.vol"))
        .unwrap();
    let body = manifest_head(3000, "exact", "") + &input("blob", "blob.vol");
    write_manifest(&dir, "m.toml", &body);
    otbake_ok(
        &dir,
        &[
            "volume",
            "m.toml",
            "--weights",
            "1",
            "--res",
            "16",
            "--sigma",
            "0.04",
            "-o",
            "out.vol",
        ],
    );
    let out = VolFile::read(&dir.join("out.vol")).unwrap();
    assert_eq!((out.dims, out.channels), ([16; 3], 1));
    assert_eq!(out.bbox, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0]);
    let total: f64 = out.data.iter().map(|&x| f64::from(x)).sum();
    let mean_out = total / out.data.len() as f64;
    assert!(
        (mean_out / mean_in - 1.0).abs() < 0.03,
        "mean {mean_out} vs {mean_in}"
    );
    for k in 0..3 {
        let c: f64 = out
            .data
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let idx = [i % n, (i / n) % n, i / (n * n)][k];
                f64::from(x) * (idx as f64 + 0.5) / n as f64
            })
            .sum::<f64>()
            / total;
        assert!((c - center[k]).abs() < 0.01, "axis {k}: center {c}");
    }
    // Its bytes are a valid .vol that reads back identically.
    let bytes = std::fs::read(dir.join("out.vol")).unwrap();
    assert_eq!(
        VolFile::parse(Path::new("out.vol"), &bytes)
            .unwrap()
            .to_bytes(),
        bytes
    );
}

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
