//! Error messages that name the argument, line or index at fault (issue 21's list): each names
//! the right one and says what is allowed.

use otbake_tests::{otbake_err, scratch, shared_data, write_manifest};
use std::path::Path;

fn two_shapes(dir: &Path) {
    let shapes = shared_data().join("shapes");
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n\
         [[input]]\nname = \"duck\"\npath = \"{}\"\ndensity = \"inverted\"\n\
         [[input]]\nname = \"heart\"\npath = \"{}\"\ndensity = \"inverted\"\n",
        shapes.join("duck.png").display(),
        shapes.join("heart.png").display()
    );
    write_manifest(dir, "two.toml", &body);
}

/// A manifest of one 3D input at `path` (not baked by the tests that refuse arguments).
fn one_3d(dir: &Path, path: &str) {
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n[mesh]\nresolution = 16\n\
         [[input]]\nname = \"a\"\npath = \"{path}\"\n"
    );
    write_manifest(dir, "m.toml", &body);
}

#[test]
fn slice_size_0_blames_size_not_at() {
    let dir = scratch("msg-slice");
    one_3d(
        &dir,
        &shared_data().join("meshes/torus.obj").display().to_string(),
    );
    let err = otbake_err(
        &dir,
        &[
            "slice",
            "m.toml",
            "--weights",
            "1",
            "--size",
            "0",
            "-o",
            "s.png",
        ],
    );
    assert!(
        err.contains("--size 0") && err.contains("1 to 8192"),
        "{err}"
    );
    assert!(!err.contains("--at"), "{err}");
    let err = otbake_err(
        &dir,
        &[
            "slice",
            "m.toml",
            "--weights",
            "1",
            "--at",
            "2",
            "-o",
            "s.png",
        ],
    );
    assert!(err.contains("--at 2") && !err.contains("--size"), "{err}");
}

#[test]
fn brdf_slice_size_0_blames_size_not_theta_i() {
    let dir = scratch("msg-brdf-slice");
    one_3d(
        &dir,
        &shared_data().join("meshes/torus.obj").display().to_string(),
    );
    let err = otbake_err(
        &dir,
        &[
            "brdf-slice",
            "m.toml",
            "--weights",
            "1",
            "--size",
            "0",
            "-o",
            "s.png",
        ],
    );
    assert!(
        err.contains("--size 0") && err.contains("1 to 8192"),
        "{err}"
    );
    assert!(!err.contains("--theta-i"), "{err}");
    let err = otbake_err(
        &dir,
        &[
            "brdf-slice",
            "m.toml",
            "--weights",
            "1",
            "--theta-i",
            "95",
            "-o",
            "s.png",
        ],
    );
    assert!(
        err.contains("--theta-i 95") && !err.contains("--size"),
        "{err}"
    );
}

#[test]
fn an_obj_face_index_out_of_range_names_the_line_and_the_index() {
    let dir = scratch("msg-obj-index");
    std::fs::write(
        dir.join("bad.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 12\n",
    )
    .unwrap();
    one_3d(&dir, "bad.obj");
    let err = otbake_err(&dir, &["bake", "m.toml"]);
    assert!(err.contains("bad.obj") && err.contains("line 6:"), "{err}");
    assert!(
        err.contains("vertex index 12") && err.contains("only 4 vertices"),
        "{err}"
    );
}

#[test]
fn a_negative_weight_is_named_by_value_and_position() {
    let dir = scratch("msg-weight");
    two_shapes(&dir);
    let err = otbake_err(
        &dir,
        &[
            "blend",
            "two.toml",
            "--weights",
            "0,-0.5",
            "--size",
            "8x8",
            "-o",
            "x.png",
        ],
    );
    assert!(
        err.contains("value -0.5 (position 2, for input \"heart\") is negative"),
        "{err}"
    );
    assert!(!err.contains("weight 0 is"), "{err}");
    assert!(!dir.join("x.png").exists());
}

#[test]
fn a_size_without_height_is_a_format_error_not_a_range_error() {
    let dir = scratch("msg-size");
    two_shapes(&dir);
    for (size, expect) in [
        ("100x", "the height is missing"),
        ("x100", "the width is missing"),
        ("100xabc", "the height \"abc\" is not a whole number"),
        ("100x0", "the height 0 is out of range"),
    ] {
        let out = otbake_tests::otbake(
            &dir,
            &[
                "blend",
                "two.toml",
                "--weights",
                "0.5,0.5",
                "--size",
                size,
                "-o",
                "x.png",
            ],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains("--size") && err.contains(expect),
            "{size}: {err}"
        );
    }
}

#[test]
fn the_vol_hint_for_negative_values_explains_densities_and_sdfs() {
    let dir = scratch("msg-vol");
    let mut bytes = b"VOL\x03".to_vec();
    for v in [1i32, 2, 2, 2, 1] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for v in [0f32, 0.0, 0.0, 1.0, 1.0, 1.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for v in [0.5f32, -0.25, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(dir.join("sdf.vol"), &bytes).unwrap();
    one_3d(&dir, "sdf.vol");
    let err = otbake_err(&dir, &["bake", "m.toml"]);
    assert!(
        err.contains("sdf.vol") && err.contains("(x 1, y 0, z 0) is -0.25"),
        "{err}"
    );
    assert!(
        err.contains("amount of matter per cell") && err.contains("signed distance"),
        "{err}"
    );
    assert!(err.contains("1 where the distance is < 0"), "{err}");
}
