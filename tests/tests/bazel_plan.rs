//! `otbake plan --format bazel` and the hermeticity it relies on, without Bazel: the BUILD file
//! declares every file each action reads, and each action, run in a folder holding only its
//! declared inputs, bakes the bytes `otbake bake` bakes. (Real Bazel, its sandbox and its caches
//! are checked by `.ci/bazel`.)

use otbake_tests::{otbake_err, otbake_ok, scratch, shared_data, write_manifest};
use std::path::{Path, PathBuf};

/// A package: `m.toml` beside `shapes/heart.png` and `shapes/duck.png`; the proxy is the duck.
fn package(name: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    std::fs::create_dir_all(dir.join("shapes")).unwrap();
    for s in ["heart", "duck"] {
        std::fs::copy(
            shared_data().join(format!("shapes/{s}.png")),
            dir.join(format!("shapes/{s}.png")),
        )
        .unwrap();
    }
    let body =
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"input\"\ninput = \"duck\"\nsamples = 400\n\
                [solver]\nkind = \"exact\"\n\
                [[input]]\nname = \"heart\"\npath = \"shapes/heart.png\"\ndensity = \"inverted\"\n\
                [[input]]\nname = \"duck\"\npath = \"./shapes/duck.png\"\ndensity = \"inverted\"\n";
    let m = write_manifest(&dir, "m.toml", body);
    (dir, m)
}

#[test]
fn the_build_file_declares_every_file_each_action_reads() {
    let (dir, m) = package("bz-plan");
    let m = m.to_str().unwrap();
    let out = otbake_ok(&dir, &["plan", m, "--format", "bazel"]);
    let build = String::from_utf8(out.stdout).unwrap();
    for want in [
        "load(\"@otbake_rules//:otbake.bzl\", \"otbake_bake\")",
        "name = \"m\"",
        "manifest = \"m.toml\"",
        "otbake = \"//tools:otbake\"",
        // The proxy is the duck; every map's key hashes the proxy's file, so every map reads it.
        "proxy_srcs = [\"shapes/duck.png\"]",
        "\"heart\": [\"shapes/heart.png\", \"shapes/duck.png\"],",
        "\"duck\": [\"shapes/duck.png\"],",
    ] {
        assert!(build.contains(want), "missing {want:?} in:\n{build}");
    }
    let out = otbake_ok(
        &dir,
        &[
            "plan",
            m,
            "--format",
            "bazel",
            "--bazel-otbake",
            "//bin:otbake",
            "--bazel-rules",
            "//third_party/otbake:otbake.bzl",
        ],
    );
    let build = String::from_utf8(out.stdout).unwrap();
    assert!(build.contains("otbake = \"//bin:otbake\""), "{build}");
    assert!(
        build.contains("load(\"//third_party/otbake:otbake.bzl\""),
        "{build}"
    );
}

/// `path` (absolute, inside `package`) at the same place inside `sandbox`.
fn inside(package: &Path, sandbox: &Path, path: &str) -> PathBuf {
    sandbox.join(
        Path::new(path)
            .strip_prefix(package)
            .expect("inside the package"),
    )
}

#[test]
fn each_action_bakes_from_its_declared_inputs_alone() {
    let (dir, m) = package("bz-hermetic");
    let m = m.to_str().unwrap();
    otbake_ok(&dir, &["bake", m]);
    let plan = otbake_ok(&dir, &["plan", m, "--format", "json"]);
    let plan: serde_json::Value = serde_json::from_slice(&plan.stdout).unwrap();
    let package = std::path::absolute(&dir).unwrap();
    for action in plan["actions"].as_array().unwrap() {
        let id = action["id"].as_str().unwrap();
        // A sandbox: only the declared inputs, at their places in the package.
        let sandbox = scratch(&format!("bz-hermetic-{id}"));
        for input in action["inputs"].as_array().unwrap() {
            let from = input.as_str().unwrap();
            let to = inside(&package, &sandbox, from);
            std::fs::create_dir_all(to.parent().unwrap()).unwrap();
            std::fs::copy(from, &to).unwrap_or_else(|e| panic!("{id}: declared {from}: {e}"));
        }
        let argv: Vec<String> = action["argv"].as_array().unwrap()[1..]
            .iter()
            .map(|a| a.as_str().unwrap().to_string())
            .map(|a| {
                if Path::new(&a).is_absolute() {
                    inside(&package, &sandbox, &a).display().to_string()
                } else {
                    a
                }
            })
            .collect();
        let args: Vec<&str> = argv.iter().map(String::as_str).collect();
        otbake_ok(&sandbox, &args);
        let output = action["outputs"][0].as_str().unwrap();
        assert_eq!(
            std::fs::read(inside(&package, &sandbox, output)).unwrap(),
            std::fs::read(output).unwrap(),
            "{id}: the sandboxed action bakes otbake bake's bytes"
        );
    }
}

#[test]
fn an_undeclared_input_is_missed_by_name() {
    // The map of heart without the duck's file (the proxy's): bake-one names what it lacks.
    let (dir, m) = package("bz-missing");
    otbake_ok(&dir, &["bake", m.to_str().unwrap()]);
    std::fs::remove_file(dir.join("shapes/duck.png")).unwrap();
    let err = otbake_err(
        &dir,
        &[
            "bake-one",
            "m.toml",
            "--product",
            "heart",
            "--proxy",
            "out/proxy.otb",
            "-o",
            "heart.otb",
        ],
    );
    assert!(err.contains("duck.png"), "{err}");
    assert!(!dir.join("heart.otb").exists());
}

#[test]
fn inputs_outside_the_package_are_clear_errors() {
    let (dir, m) = package("bz-outside");
    let text = std::fs::read_to_string(&m).unwrap();
    let outside = text.replace("shapes/heart.png", "../bz-outside-heart.png");
    std::fs::copy(
        dir.join("shapes/heart.png"),
        dir.join("../bz-outside-heart.png"),
    )
    .unwrap();
    write_manifest(&dir, "outside.toml", &outside);
    let err = otbake_err(&dir, &["plan", "outside.toml", "--format", "bazel"]);
    assert!(
        err.contains("input \"heart\"") && err.contains("is not below the manifest's folder"),
        "{err}"
    );
    std::fs::write(dir.join("shapes/BUILD.bazel"), "").unwrap();
    let err = otbake_err(&dir, &["plan", "m.toml", "--format", "bazel"]);
    assert!(err.contains("lies in the Bazel package"), "{err}");
    // Ninja and JSON plans have no packages.
    otbake_ok(&dir, &["plan", "outside.toml", "--format", "json"]);
}
