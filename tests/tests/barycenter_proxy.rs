//! `[proxy] kind = "barycenter"`: at its build weights a blend is the barycenter of the inputs'
//! samples (its objective within 0.1% of the ground truth's, exact and Sinkhorn maps), its key
//! covers every input (adding one rebakes the proxy and every map), and it is deterministic for any
//! thread count. Ground truths come from the exact solver alone: for two inputs the McCann
//! interpolant of the exact matching, whose objective `t(1 − t) W2²` is the global minimum.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions, BakeReport, Status};
use otbake::render::Archives;
use otbake::solve::barycenter::{mccann, objective, w2_sq};
use otbake::solve::{ExactSettings, SolverSettings, Wrap};
use otbake_runtime::Blend;
use otbake_tests::{scratch, shared_data, write_manifest};
use std::path::Path;

const SHAPES: [&str; 3] = ["heart", "duck", "tooth"];

fn body(kind: &str, samples: usize, solver: &str, shapes: &[&str], extra: &str) -> String {
    let mut b = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"{kind}\"\nsamples = {samples}\n{extra}\n[solver]\nkind = \"{solver}\"\n"
    );
    for s in shapes {
        b += &format!(
            "[[input]]\nname = \"{s}\"\npath = \"{}\"\ndensity = \"inverted\"\n",
            shared_data().join(format!("shapes/{s}.png")).display()
        );
    }
    b
}

fn run(m: &Path) -> (Manifest, BakeReport) {
    let m = Manifest::load(m).unwrap_or_else(|e| panic!("{e}"));
    let r = bake(&m, &BakeOptions::default()).unwrap();
    assert!(!r.failed(), "{r:?}");
    (m, r)
}

/// The blend of the baked maps at `w`, and every input's samples (unit weights).
fn clouds(m: &Manifest, w: &[f32]) -> (Vec<f32>, Vec<Vec<f32>>) {
    let archives = Archives::load(m).unwrap();
    let maps = archives.maps().unwrap();
    let blend = Blend::new(archives.proxy().unwrap(), &maps).unwrap();
    let points = |w: &[f32]| -> Vec<f32> {
        (0..blend.n())
            .flat_map(|i| {
                let s = blend.sample(w, i).unwrap();
                [s.position[0], s.position[1]]
            })
            .collect()
    };
    let k = maps.len();
    let inputs = (0..k)
        .map(|j| points(&(0..k).map(|i| f32::from(i == j)).collect::<Vec<_>>()))
        .collect();
    (points(w), inputs)
}

fn exact() -> SolverSettings {
    SolverSettings::Exact(ExactSettings::default())
}

/// Objective excess of the blend at the proxy's build weights over the McCann ground truth.
fn excess_at_build_weights(solver: &str, n: usize, weights: [f64; 2]) -> f64 {
    let dir = scratch(&format!("bary-proxy-{solver}-{}", weights[0]));
    let extra = format!("weights = [{}, {}]", weights[0], weights[1]);
    let m = write_manifest(
        &dir,
        "m.toml",
        &body("barycenter", n, solver, &SHAPES[..2], &extra),
    );
    let (m, report) = run(&m);
    let detail = &report.products[0].detail;
    assert!(detail.contains("fixed point"), "{detail}");
    let w = [weights[0] as f32, weights[1] as f32];
    let (blend, inputs) = clouds(&m, &w);
    let refs: Vec<&[f32]> = inputs.iter().map(Vec::as_slice).collect();
    let got = objective(Wrap::Clamp, 2, &blend, &refs, &weights, &exact()).unwrap();
    let (d2, mapped) = w2_sq(Wrap::Clamp, 2, refs[0], refs[1], &exact()).unwrap();
    let t = weights[1];
    let truth = t * (1.0 - t) * d2;
    // The interpolant's objective, measured the same way, is the bound (a check of the measure).
    let interp = mccann(Wrap::Clamp, refs[0], &mapped, t);
    let at = objective(Wrap::Clamp, 2, &interp, &refs, &weights, &exact()).unwrap();
    assert!(
        (at.value / truth - 1.0).abs() < 1e-6,
        "{} vs {truth}",
        at.value
    );
    got.value / truth - 1.0
}

#[test]
fn the_blend_at_its_weights_is_the_barycenter_with_exact_maps() {
    for w in [[0.5, 0.5], [0.8, 0.2]] {
        let e = excess_at_build_weights("exact", 500, w);
        assert!(
            (-1e-9..=1e-3).contains(&e),
            "weights {w:?}: objective excess {e}"
        );
    }
}

#[test]
fn the_blend_at_its_weights_is_the_barycenter_with_sinkhorn_maps() {
    let e = excess_at_build_weights("sinkhorn", 1000, [0.5, 0.5]);
    assert!((-1e-9..=1e-3).contains(&e), "objective excess {e}");
}

#[test]
fn adding_an_input_rebakes_the_proxy_and_every_map() {
    let dir = scratch("bary-proxy-add");
    let m = write_manifest(
        &dir,
        "m.toml",
        &body("barycenter", 300, "exact", &SHAPES[..2], ""),
    );
    let (_, first) = run(&m);
    assert!(first.products.iter().all(|p| p.status == Status::Built));
    let (_, again) = run(&m);
    assert!(
        again.products.iter().all(|p| p.status == Status::Cached),
        "{again:?}"
    );
    write_manifest(
        &dir,
        "m.toml",
        &body("barycenter", 300, "exact", &SHAPES, ""),
    );
    let (_, added) = run(&m);
    let statuses: Vec<_> = added
        .products
        .iter()
        .map(|p| (p.name.as_str(), p.status))
        .collect();
    assert_eq!(
        statuses,
        [
            ("proxy", Status::Built),
            ("heart", Status::Built),
            ("duck", Status::Built),
            ("tooth", Status::Built)
        ]
    );
    // A gaussian proxy's key does not depend on the inputs: adding one bakes only its map.
    let dir = scratch("bary-proxy-add-gaussian");
    let m = write_manifest(
        &dir,
        "m.toml",
        &body("gaussian", 300, "exact", &SHAPES[..2], ""),
    );
    run(&m);
    write_manifest(&dir, "m.toml", &body("gaussian", 300, "exact", &SHAPES, ""));
    let (_, added) = run(&m);
    let built: Vec<_> = added
        .products
        .iter()
        .filter(|p| p.status == Status::Built)
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(built, ["tooth"]);
}

#[test]
fn the_barycenter_proxy_is_the_same_for_any_thread_count() {
    let bytes = |threads: usize| {
        let dir = scratch(&format!("bary-proxy-threads-{threads}"));
        let m = write_manifest(
            &dir,
            "m.toml",
            &body(
                "barycenter",
                400,
                "sinkhorn",
                &SHAPES,
                "weights = [0.2, 0.3, 0.5]",
            ),
        );
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| run(&m));
        std::fs::read(dir.join("out/proxy.otb")).unwrap()
    };
    assert_eq!(bytes(1), bytes(2));
}

#[test]
fn bad_barycenter_settings_are_errors_at_their_line() {
    let dir = scratch("bary-proxy-bad");
    for (extra, want) in [
        ("weights = [0.5]", "1 weights for 2 inputs"),
        ("weights = [0.7, 0.7]", "sum to 1.4"),
        ("weights = [1.5, -0.5]", "-0.5"),
        ("iterations = 0", "1 to 1000"),
    ] {
        let text = body("barycenter", 100, "exact", &SHAPES[..2], extra);
        let e = Manifest::parse(&dir.join("m.toml"), &text).unwrap_err();
        assert!(e.message.contains(want) && e.line == 6, "{extra}: {e}");
    }
    let text = body(
        "gaussian",
        100,
        "exact",
        &SHAPES[..2],
        "weights = [0.5, 0.5]",
    );
    let e = Manifest::parse(&dir.join("m.toml"), &text).unwrap_err();
    assert!(e.message.contains("only to kind = \"barycenter\""), "{e}");
}

#[test]
fn a_periodic_barycenter_proxy_lives_on_the_torus() {
    let dir = scratch("bary-proxy-periodic");
    let mut b = String::from(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"barycenter\"\nsamples = 300\n[solver]\nkind = \"exact\"\n",
    );
    for (name, file) in [
        ("onyx", "marble_onyx003_ambientcg_1k.jpg"),
        ("pebbles", "pebbles_stonewall_godot.png"),
    ] {
        b += &format!(
            "[[input]]\nname = \"{name}\"\npath = \"{}\"\nwrap = \"periodic\"\n",
            shared_data().join("textures").join(file).display()
        );
    }
    let (m, _) = run(&write_manifest(&dir, "m.toml", &b));
    assert_eq!(m.wrap(), Wrap::Periodic);
    let archives = Archives::load(&m).unwrap();
    let proxy = archives.proxy().unwrap();
    assert_eq!(proxy.wrap(), Wrap::Periodic);
    for i in 0..proxy.n() {
        let p = proxy.position(i).unwrap();
        assert!(
            (0.0..1.0).contains(&p[0]) && (0.0..1.0).contains(&p[1]),
            "{p:?}"
        );
    }
    // At its weights the blend is the torus barycenter: the McCann bound on the torus.
    let (blend, inputs) = clouds(&m, &[0.5, 0.5]);
    let refs: Vec<&[f32]> = inputs.iter().map(Vec::as_slice).collect();
    let got = objective(Wrap::Periodic, 2, &blend, &refs, &[0.5, 0.5], &exact()).unwrap();
    let (d2, _) = w2_sq(Wrap::Periodic, 2, refs[0], refs[1], &exact()).unwrap();
    assert!(
        got.value / (0.25 * d2) - 1.0 <= 1e-3,
        "{} vs {}",
        got.value,
        0.25 * d2
    );
}
