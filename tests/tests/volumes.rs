//! 3D inputs end to end: meshes sampled uniformly inside, `.vol` round trips, a blend of two balls
//! against its closed form, and runtime 3D queries against brute force (the commands and bad
//! inputs are in `volume_commands.rs`).

mod volume_support;

use otbake::input::mesh::shapes::{cuboid, icosphere};
use otbake::input::mesh::voxelize::Placement;
use otbake::input::vol::VolFile;
use otbake::input::{load_with, DensityChannel};
use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake::sample::importance_sample;
use otbake_runtime::{Blend, Kernel};
use otbake_tests::{otbake_ok, scratch, shared_data, write_manifest};
use std::path::Path;
use volume_support::*;

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
