//! Warnings in the bake report (stderr and `--json`): inputs accepted that look wrong. Each names
//! the input and its file, what looks wrong, and what to do; inputs that look right say nothing.

use otbake_tests::{otbake_ok, scratch, shared_data, write_manifest};
use std::path::Path;

/// The warnings of `otbake bake --json` on `manifest` in `dir`: (input, file, message) each, and
/// the stderr lines that start with `warning: `.
/// One warning of the JSON report: input (null for the manifest), file, message.
type Json = (Option<String>, String, String);

fn warnings(dir: &Path, manifest: &str) -> (Vec<Json>, Vec<String>) {
    let out = otbake_ok(dir, &["bake", "--json", manifest]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let json = v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| {
            (
                w["input"].as_str().map(str::to_string),
                w["file"].as_str().unwrap().to_string(),
                w["message"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let lines = String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| l.starts_with("warning: "))
        .map(str::to_string)
        .collect();
    (json, lines)
}

fn manifest(dir: &Path, inputs: &[(&str, &str, &str)]) -> String {
    let mut b = "[output]\ndir = \"out\"\n[proxy]\nkind = \"uniform\"\nsamples = 300\n[solver]\nkind = \"exact\"\n".to_string();
    for (name, path, extra) in inputs {
        b += &format!("[[input]]\nname = \"{name}\"\npath = \"{path}\"\n{extra}");
    }
    write_manifest(dir, "m.toml", &b);
    "m.toml".into()
}

/// A grey PNG of `w × h` with value `f(x, y)` in 0..=255.
fn png(dir: &Path, name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> u8) {
    image::GrayImage::from_fn(w, h, |x, y| image::Luma([f(x, y)]))
        .save(dir.join(name))
        .unwrap();
}

#[test]
fn a_periodic_image_that_does_not_tile_is_measured_and_named() {
    let dir = scratch("warn-periodic");
    // A left-to-right ramp: its left and right edges differ by the whole range.
    png(&dir, "ramp.png", 64, 64, |x, _| (40 + 3 * x) as u8);
    // A sine across x and y with whole periods: it tiles.
    png(&dir, "sine.png", 64, 64, |x, y| {
        let t = std::f64::consts::TAU / 64.0;
        (128.0 + 60.0 * (t * x as f64).sin() * (t * 2.0 * y as f64).cos()) as u8
    });
    let m = manifest(
        &dir,
        &[
            ("ramp", "ramp.png", "wrap = \"periodic\"\n"),
            ("sine", "sine.png", "wrap = \"periodic\"\n"),
        ],
    );
    let (json, lines) = warnings(&dir, &m);
    assert_eq!(json.len(), 1, "{json:?}");
    let (input, file, message) = &json[0];
    assert_eq!(input.as_deref(), Some("ramp"));
    assert!(file.ends_with("ramp.png"), "{file}");
    assert!(
        message.contains("does not tile")
            && message.contains("as much as between neighbouring pixels"),
        "{message}"
    );
    assert!(
        message.contains("use a tileable version, or remove `wrap`"),
        "{message}"
    );
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(
        lines[0].contains("input \"ramp\"") && lines[0].contains("ramp.png"),
        "{lines:?}"
    );
}

#[test]
fn the_shipped_manifests_inputs_do_not_warn() {
    // Every periodic texture the repository ships tiles; only non-square images warn.
    for name in ["textures", "terrain", "shapes"] {
        let path = otbake_tests::repo_root().join(format!("manifests/{name}.toml"));
        let m = otbake::Manifest::load(&path).unwrap();
        assert!(
            otbake::pipeline::warnings::manifest_warnings(&m).is_empty(),
            "{name}"
        );
        for spec in &m.inputs {
            let grid = otbake::pipeline::load_input(spec).unwrap();
            let w = otbake::pipeline::warnings::input_warnings(spec, &grid);
            assert!(
                w.iter().all(|w| !w.message.contains("does not tile")),
                "{name}: {w:?}"
            );
            // The one true warning: `pebbles_stonewall_godot.png` is 1024×666, and says so.
            let square = grid.dims[0] == grid.dims[1];
            assert_eq!(w.is_empty(), square, "{name} {:?}: {w:?}", grid.dims);
        }
    }
}

#[test]
fn non_square_and_extreme_aspect_images_say_they_are_stretched() {
    let dir = scratch("warn-aspect");
    png(&dir, "wide.png", 96, 64, |x, y| {
        ((x * 7 + y * 3) % 200 + 20) as u8
    });
    png(&dir, "strip.png", 1, 4000, |_, y| (y % 200 + 20) as u8);
    png(&dir, "square.png", 64, 64, |x, y| {
        ((x * 7 + y * 3) % 200 + 20) as u8
    });
    let m = manifest(
        &dir,
        &[
            ("wide", "wide.png", ""),
            ("strip", "strip.png", ""),
            ("square", "square.png", ""),
        ],
    );
    let (json, lines) = warnings(&dir, &m);
    assert_eq!(json.len(), 2, "{json:?}");
    let wide = json
        .iter()
        .find(|w| w.0.as_deref() == Some("wide"))
        .unwrap();
    assert!(
        wide.2.contains("96×64 pixels, not square") && wide.2.contains("pad it to a square"),
        "{wide:?}"
    );
    let strip = json
        .iter()
        .find(|w| w.0.as_deref() == Some("strip"))
        .unwrap();
    assert!(
        strip.2.contains("1×4000 pixels, stretched 4000:1") && strip.2.contains("crop or pad"),
        "{strip:?}"
    );
    assert_eq!(lines.len(), 2, "{lines:?}");
}

#[test]
fn an_obj_face_with_two_vertices_is_dropped_and_reported() {
    let dir = scratch("warn-obj");
    let mut obj = String::new();
    for v in 0..8 {
        obj += &format!("v {} {} {}\n", v & 1, (v >> 1) & 1, (v >> 2) & 1);
    }
    // A closed cube (six quads), and one face of two vertices on line 15.
    obj += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\nf 1 8\n";
    std::fs::write(dir.join("cube.obj"), obj).unwrap();
    let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n[mesh]\nresolution = 16\n\
                [[input]]\nname = \"cube\"\npath = \"cube.obj\"\n";
    write_manifest(&dir, "m.toml", body);
    let (json, lines) = warnings(&dir, "m.toml");
    assert_eq!(json.len(), 1, "{json:?}");
    let (input, file, message) = &json[0];
    assert_eq!(
        (input.as_deref(), file.ends_with("cube.obj")),
        (Some("cube"), true)
    );
    assert!(
        message.contains(
            "1 face(s) with fewer than three vertices (the first at line 15) were dropped"
        ),
        "{message}"
    );
    assert!(lines[0].contains("cube.obj"), "{lines:?}");
}

#[test]
fn mixed_density_modes_are_reported_with_what_the_render_does() {
    let dir = scratch("warn-modes");
    let shapes = shared_data().join("shapes");
    let (duck, heart) = (shapes.join("duck.png"), shapes.join("heart.png"));
    let m = manifest(
        &dir,
        &[
            ("photo", duck.to_str().unwrap(), "density = \"luminance\"\n"),
            ("shape", heart.to_str().unwrap(), "density = \"inverted\"\n"),
        ],
    );
    let (json, lines) = warnings(&dir, &m);
    assert_eq!(json.len(), 1, "{json:?}");
    let (input, file, message) = &json[0];
    assert_eq!(input, &None);
    assert!(file.ends_with("m.toml"), "{file}");
    assert!(
        message.contains("\"photo\" is luminance, \"shape\" is inverted"),
        "{message}"
    );
    assert!(
        message.contains("composite it additively") && message.contains("same `density`"),
        "{message}"
    );
    assert_eq!(lines.len(), 1);
    // The same inputs with one mode say nothing.
    let m = manifest(
        &dir,
        &[
            ("photo", duck.to_str().unwrap(), "density = \"inverted\"\n"),
            ("shape", heart.to_str().unwrap(), "density = \"inverted\"\n"),
        ],
    );
    assert!(warnings(&dir, &m).0.is_empty());
}

/// `density = "alpha"` on an image without transparency is a uniform density: said, with the fix;
/// an image whose alpha holds the shape says nothing.
#[test]
fn an_alpha_density_on_an_opaque_image_says_its_picture_is_lost() {
    let dir = scratch("warn-opaque-alpha");
    png(&dir, "grey.png", 32, 32, |x, y| {
        ((x * 7 + y * 3) % 200) as u8
    });
    image::RgbaImage::from_fn(32, 32, |x, _| image::Rgba([200, 100, 50, (x * 8) as u8]))
        .save(dir.join("shaped.png"))
        .unwrap();
    let m = manifest(
        &dir,
        &[
            ("grey", "grey.png", "density = \"alpha\"\n"),
            ("shaped", "shaped.png", "density = \"alpha\"\n"),
        ],
    );
    let (json, lines) = warnings(&dir, &m);
    assert_eq!(json.len(), 1, "{json:?}");
    let (input, file, message) = &json[0];
    assert_eq!(input.as_deref(), Some("grey"));
    assert!(file.ends_with("grey.png"), "{file}");
    assert!(
        message.contains("`density = \"alpha\"`, but every pixel has the same alpha")
            && message.contains("use `luminance`"),
        "{message}"
    );
    assert_eq!(lines.len(), 1, "{lines:?}");
}
