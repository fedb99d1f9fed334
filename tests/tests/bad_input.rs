//! Bad input gets a clear error naming the file, field or offset, a non-zero exit, and nothing
//! half-written.

use otbake::render::imageio::{write_image, Rgba};
use otbake_tests::{otbake_err, otbake_ok, scratch, shared_data, temp_files, write_manifest};
use std::path::Path;

fn manifest_with(dir: &Path, samples: &str, input_path: &str, extra_proxy: &str) -> String {
    let body = format!(
        "[output]\ndir = \"out\"\n\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\n{extra_proxy}\n[solver]\nkind = \"exact\"\n\n\
         [[input]]\nname = \"a\"\npath = \"{input_path}\"\ndensity = \"inverted\"\n"
    );
    write_manifest(dir, "m.toml", &body);
    "m.toml".into()
}

fn duck() -> String {
    shared_data().join("shapes/duck.png").display().to_string()
}

/// Nothing was written: no archive (in the outputs or the store) and no temporaries. (The store's
/// file-stamp index may remember the input's digest: that is a cache, not an output.)
fn assert_nothing_written(dir: &Path) {
    assert!(temp_files(dir).is_empty(), "temporary files left behind");
    let mut stack = vec![dir.join("out")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            assert!(
                p.extension().is_none_or(|x| x != "otb"),
                "archive written despite the error: {}",
                p.display()
            );
            if p.is_dir() {
                stack.push(p);
            }
        }
    }
}

#[test]
fn missing_input_file_names_manifest_line_and_path() {
    let dir = scratch("bad-missing");
    let m = manifest_with(&dir, "500", "nope.png", "");
    let err = otbake_err(&dir, &["bake", &m]);
    assert!(err.contains("m.toml:13:8"), "{err}");
    assert!(
        err.contains("nope.png") && err.contains("does not exist"),
        "{err}"
    );
    assert_nothing_written(&dir);
}

#[test]
fn unsupported_extension_lists_supported_ones() {
    let dir = scratch("bad-ext");
    std::fs::write(dir.join("a.gif"), b"GIF89a").unwrap();
    let m = manifest_with(&dir, "500", "a.gif", "");
    let err = otbake_err(&dir, &["bake", &m]);
    assert!(
        err.contains("m.toml:13") && err.contains(".png, .jpg, .jpeg, .exr"),
        "{err}"
    );
    assert_nothing_written(&dir);
}

#[test]
fn unknown_manifest_key_is_located() {
    let dir = scratch("bad-key");
    let m = manifest_with(&dir, "500", &duck(), "sigmaa = 0.2");
    let err = otbake_err(&dir, &["bake", &m]);
    assert!(
        err.contains("m.toml:7:1") && err.contains("sigmaa"),
        "{err}"
    );
    assert_nothing_written(&dir);
}

#[test]
fn zero_and_absurd_sample_counts_are_refused() {
    for samples in ["0", "1000000000000", "-5"] {
        let dir = scratch("bad-samples");
        let m = manifest_with(&dir, samples, &duck(), "");
        let err = otbake_err(&dir, &["bake", &m]);
        assert!(err.contains("m.toml:6:"), "{samples}: {err}");
        assert_nothing_written(&dir);
    }
}

fn exr_with(dir: &Path, name: &str, f: impl Fn(usize, usize) -> f32) -> String {
    let mut img = Rgba::filled(16, 16, [0.0, 0.0, 0.0, 1.0]);
    for y in 0..16 {
        for x in 0..16 {
            let v = f(x, y);
            let i = (y * 16 + x) * 4;
            img.pixels[i..i + 3].fill(v);
        }
    }
    write_image(&dir.join(name), &img).unwrap();
    name.into()
}

#[test]
fn image_without_mass_is_refused() {
    let dir = scratch("bad-nomass");
    let file = exr_with(&dir, "black.exr", |_, _| 0.0);
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 100\n[solver]\nkind = \"exact\"\n\
         [[input]]\nname = \"a\"\npath = \"{file}\"\n"
    );
    write_manifest(&dir, "m.toml", &body);
    let err = otbake_err(&dir, &["bake", "m.toml"]);
    assert!(err.contains("black.exr"), "{err}");
    assert!(
        err.to_lowercase().contains("zero") || err.contains("mass"),
        "{err}"
    );
    assert_nothing_written(&dir);
}

#[test]
fn nan_inf_and_negative_pixels_are_refused_with_their_position() {
    for (name, bad) in [
        ("nan.exr", f32::NAN),
        ("inf.exr", f32::INFINITY),
        ("neg.exr", -1.0),
    ] {
        let dir = scratch("bad-exr");
        let file = exr_with(&dir, name, |x, y| if (x, y) == (5, 9) { bad } else { 0.5 });
        let body = format!(
            "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 100\n[solver]\nkind = \"exact\"\n\
             [[input]]\nname = \"a\"\npath = \"{file}\"\n"
        );
        write_manifest(&dir, "m.toml", &body);
        let err = otbake_err(&dir, &["bake", "m.toml"]);
        assert!(err.contains(name), "{err}");
        assert!(
            err.contains('5') && err.contains('9'),
            "pixel (5, 9) not named: {err}"
        );
        assert_nothing_written(&dir);
    }
}

#[test]
fn bad_weights_are_refused_and_write_nothing() {
    let dir = scratch("bad-weights");
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n\
         [[input]]\nname = \"a\"\npath = \"{}\"\ndensity = \"inverted\"\n\
         [[input]]\nname = \"b\"\npath = \"{}\"\ndensity = \"inverted\"\n",
        duck(),
        shared_data().join("shapes/heart.png").display()
    );
    write_manifest(&dir, "m.toml", &body);
    otbake_ok(&dir, &["bake", "m.toml"]);
    for (weights, expect) in [
        ("1", "one weight per input"),
        ("0.5,0.25,0.25", "one weight per input"),
        ("-0.5,1.5", "negative"),
        ("0.5,0.6", "sum"),
        ("NaN,1", "weight"),
    ] {
        let err = otbake_err(
            &dir,
            &[
                "blend",
                "m.toml",
                "--weights",
                weights,
                "--size",
                "8x8",
                "-o",
                "x.png",
            ],
        );
        assert!(
            err.to_lowercase().contains(expect),
            "--weights {weights}: {err}"
        );
        assert!(!dir.join("x.png").exists());
    }
    assert!(temp_files(&dir).is_empty());
}

#[test]
fn damaged_archives_are_explained_by_inspect() {
    let dir = scratch("bad-archive");
    let m = manifest_with(&dir, "300", &duck(), "");
    otbake_ok(&dir, &["bake", &m]);
    let good = std::fs::read(dir.join("out/a.otb")).unwrap();
    let out = otbake_ok(&dir, &["inspect", "out/a.otb"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("map            dim=2 n=300"));

    std::fs::write(dir.join("trunc.otb"), &good[..good.len() - 7]).unwrap();
    let err = otbake_err(&dir, &["inspect", "trunc.otb"]);
    assert!(
        err.contains("trunc.otb") && err.contains("truncated"),
        "{err}"
    );

    let mut flipped = good.clone();
    let at = good.len() / 2;
    flipped[at] ^= 0x10;
    std::fs::write(dir.join("flip.otb"), &flipped).unwrap();
    let err = otbake_err(&dir, &["inspect", "flip.otb"]);
    assert!(err.contains("checksum"), "{err}");

    let mut version = good.clone();
    version[8] = 99;
    std::fs::write(dir.join("ver.otb"), &version).unwrap();
    let err = otbake_err(&dir, &["inspect", "ver.otb"]);
    assert!(err.contains("version 99"), "{err}");

    // A damaged output is rebuilt by the next bake, not trusted.
    std::fs::write(dir.join("out/a.otb"), &flipped).unwrap();
    otbake_ok(&dir, &["bake", &m]);
    assert_eq!(std::fs::read(dir.join("out/a.otb")).unwrap(), good);
}
