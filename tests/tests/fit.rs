//! `otbake fit`: weights of a blend recovered from its rendered image, an input's unit vector, a
//! large residual for a target outside the span, and clear errors for a target of another
//! dimension or wrap. Small n (exact maps): the accuracy at large n is the bench's business.

use otbake_tests::{otbake_err, otbake_ok, scratch, shared_data, write_manifest};
use std::path::{Path, PathBuf};

const SHAPES: [&str; 3] = ["heart", "duck", "tooth"];

fn setup(name: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    let mut b = String::from(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 1500\n[solver]\nkind = \"exact\"\n",
    );
    for s in SHAPES {
        b += &format!(
            "[[input]]\nname = \"{s}\"\npath = \"{}\"\ndensity = \"inverted\"\n",
            shared_data().join(format!("shapes/{s}.png")).display()
        );
    }
    let m = write_manifest(&dir, "m.toml", &b);
    (dir, m)
}

/// `otbake fit` on `target`: its output and the JSON it wrote.
fn fit_run(
    dir: &Path,
    m: &Path,
    target: &Path,
    extra: &[&str],
) -> (std::process::Output, serde_json::Value) {
    let json = dir.join("w.json");
    let mut args = vec![
        "fit",
        m.to_str().unwrap(),
        "--target",
        target.to_str().unwrap(),
        "-o",
        json.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = otbake_ok(dir, &args);
    let v = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    (out, v)
}

/// `otbake fit` on `target`: (weights, relative residual) from its JSON output.
fn fit(dir: &Path, m: &Path, target: &Path, extra: &[&str]) -> (Vec<f64>, f64) {
    let (out, v) = fit_run(dir, m, target, extra);
    let printed = String::from_utf8_lossy(&out.stdout);
    assert!(printed.contains("residual"), "{printed}");
    assert_eq!(v["inputs"], serde_json::json!(SHAPES));
    let w: Vec<f64> = v["weights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9 && w.iter().all(|&x| x >= 0.0));
    (w, v["relative_residual"].as_f64().unwrap())
}

#[test]
fn fit_recovers_blend_weights_unit_vectors_and_flags_outsiders() {
    let (dir, m) = setup("fit");
    let mut blend_residual = 0.0f64;
    for w in [[0.2, 0.3, 0.5], [0.6, 0.4, 0.0]] {
        let target = dir.join("target.png");
        let weights = format!("{},{},{}", w[0], w[1], w[2]);
        otbake_ok(
            &dir,
            &[
                "blend",
                m.to_str().unwrap(),
                "--weights",
                &weights,
                "--size",
                "128x128",
                "-o",
                target.to_str().unwrap(),
            ],
        );
        let (got, rel) = fit(&dir, &m, &target, &[]);
        for k in 0..3 {
            assert!(
                (got[k] - w[k]).abs() <= 0.02,
                "blend at {w:?}: fitted {got:?}"
            );
        }
        blend_residual = blend_residual.max(rel);
    }
    // An input is its own unit vector (it is sampled exactly as its map's target was).
    let (got, rel) = fit(&dir, &m, &shared_data().join("shapes/duck.png"), &[]);
    assert!(got[1] > 0.999, "duck: {got:?}");
    assert!(rel < 1e-3, "duck: residual {rel}");
    // A shape that is no blend of these three lies far from their span.
    let render = dir.join("fitted.png");
    let (_, rel) = fit(
        &dir,
        &m,
        &shared_data().join("shapes/redcross.png"),
        &["--render", render.to_str().unwrap(), "--size", "64x64"],
    );
    assert!(
        rel > 0.2 && rel > 2.5 * blend_residual,
        "redcross: {rel} vs blends' {blend_residual}"
    );
    assert!(std::fs::metadata(&render).unwrap().len() > 0);
}

#[test]
fn targets_of_another_dimension_or_wrap_are_errors() {
    let (dir, m) = setup("fit-errors");
    let mesh = shared_data().join("meshes/torus.obj");
    let e = otbake_err(
        &dir,
        &[
            "fit",
            m.to_str().unwrap(),
            "--target",
            mesh.to_str().unwrap(),
        ],
    );
    assert!(
        e.contains("3-dimensional") && e.contains("2-dimensional"),
        "{e}"
    );
    let duck = shared_data().join("shapes/duck.png");
    let e = otbake_err(
        &dir,
        &[
            "fit",
            m.to_str().unwrap(),
            "--target",
            duck.to_str().unwrap(),
            "--wrap",
            "periodic",
        ],
    );
    assert!(
        e.contains("wrap") && e.contains("periodic") && e.contains("clamp"),
        "{e}"
    );
    let e = otbake_err(
        &dir,
        &["fit", m.to_str().unwrap(), "--target", "missing.png"],
    );
    assert!(e.contains("missing.png"), "{e}");
}

/// `fit --density alpha` on a target without transparency warns (stderr and the JSON) that its
/// density is uniform; the fit still runs, and the default density says nothing.
#[test]
fn an_alpha_density_on_an_opaque_target_is_a_warning() {
    let (dir, m) = setup("fit-opaque-alpha");
    let target = shared_data().join("shapes/duck.png");
    let run = |extra: &[&str]| {
        let (out, v) = fit_run(&dir, &m, &target, extra);
        (String::from_utf8_lossy(&out.stderr).into_owned(), v)
    };
    let (err, v) = run(&["--density", "alpha"]);
    assert!(
        err.contains("warning: target ")
            && err.contains("`--density alpha`, but every pixel has the same alpha"),
        "{err}"
    );
    assert_eq!(v["warnings"].as_array().unwrap().len(), 1, "{v}");
    let (err, v) = run(&[]);
    assert!(!err.contains("warning:"), "{err}");
    assert_eq!(v["warnings"], serde_json::json!([]));
}
