//! The memory budget: inputs, bakes and renders that would not fit are refused before they
//! allocate, with the estimate, the budget and the fix — under a low `--memory` and under
//! `ulimit -v`, always an error and exit status 1, never an abort or a signal, nothing written
//! (not even the output folder).

use otbake_tests::{otbake_bin, scratch, shared_data, temp_files, write_manifest};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// `ulimit -v` for the runs under an address-space limit, in KiB: far below what the refused
/// work needs, far above what the binary needs to start.
const ULIMIT_KIB: u64 = 2 << 20;

/// Runs otbake in `dir` with `args`, optionally under `ulimit -v`.
fn run(dir: &Path, args: &[&str], ulimit: bool) -> Output {
    if ulimit {
        let mut cmd = Command::new("sh");
        cmd.arg("-c")
            .arg(format!("ulimit -v {ULIMIT_KIB}; exec \"$0\" \"$@\""))
            .arg(otbake_bin())
            .args(args);
        cmd.current_dir(dir).output().expect("run sh")
    } else {
        Command::new(otbake_bin())
            .args(args)
            .current_dir(dir)
            .output()
            .expect("run otbake")
    }
}

/// Asserts a clean refusal: exit status 1 (not a signal, not 134), one `error:` line holding every
/// part of `expect`, no panic; returns stderr.
fn refused(dir: &Path, args: &[&str], ulimit: bool, expect: &[&str]) -> String {
    let out = run(dir, args, ulimit);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(
        out.status.code(),
        Some(1),
        "otbake {args:?} (ulimit {ulimit}): {:?}\n{err}",
        out.status
    );
    assert!(
        !err.contains("panicked") && !err.contains("memory allocation"),
        "{err}"
    );
    let line = err
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("{err}"));
    for part in expect {
        assert!(
            line.contains(part),
            "{part:?} missing (ulimit {ulimit}) from:\n{err}"
        );
    }
    assert!(
        temp_files(dir).is_empty(),
        "temporaries left: {:?}",
        temp_files(dir)
    );
    err
}

/// Archives and images in `dir` (a refused command writes none).
fn outputs(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .extension()
                .is_some_and(|x| x == "otb" || x == "png" && !p.ends_with("big.png"))
            {
                found.push(p);
            }
        }
    }
    found
}

/// A `side × side` grey PNG, streamed row by row (it compresses to a few hundred KB).
fn write_grey_png(path: &Path, side: u32) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut enc = png::Encoder::new(file, side, side);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut writer = enc.write_header().unwrap();
    let mut stream = writer.stream_writer().unwrap();
    let row = vec![128u8; side as usize];
    for _ in 0..side {
        std::io::Write::write_all(&mut stream, &row).unwrap();
    }
    stream.finish().unwrap();
}

fn two_shapes(dir: &Path, extra: &str) -> PathBuf {
    let shapes = shared_data().join("shapes");
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n{extra}\
         [[input]]\nname = \"duck\"\npath = \"{}\"\ndensity = \"inverted\"\n\
         [[input]]\nname = \"heart\"\npath = \"{}\"\ndensity = \"inverted\"\n",
        shapes.join("duck.png").display(),
        shapes.join("heart.png").display()
    );
    write_manifest(dir, "two.toml", &body)
}

#[test]
fn a_small_png_that_decodes_huge_is_refused_before_decoding() {
    let dir = scratch("limits-png");
    write_grey_png(&dir.join("big.png"), 20_000);
    let len = std::fs::metadata(dir.join("big.png")).unwrap().len();
    assert!(len < 4 << 20, "{len} bytes");
    let body = "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n\
                [[input]]\nname = \"big\"\npath = \"big.png\"\n";
    write_manifest(&dir, "m.toml", body);
    let expect = [
        "big.png",
        "20000×20000 pixels",
        "smaller image",
        "--memory SIZE",
    ];
    let err = refused(
        &dir,
        &["--memory", "1GiB", "bake", "m.toml"],
        false,
        &expect,
    );
    assert!(err.contains("1.0 GiB (from --memory)"), "{err}");
    let err = refused(&dir, &["bake", "m.toml"], true, &expect);
    assert!(err.contains("ulimit -v"), "{err}");
    assert!(outputs(&dir).is_empty(), "{:?}", outputs(&dir));
    // The manifest's own budget, named with its line.
    let limited = format!("[limits]\nmemory = \"512MiB\"\n{body}");
    write_manifest(&dir, "limited.toml", &limited);
    let err = refused(&dir, &["bake", "limited.toml"], false, &expect);
    assert!(
        err.contains("512.0 MiB (from `[limits] memory` at limited.toml:2)"),
        "{err}"
    );
    assert!(outputs(&dir).is_empty(), "{:?}", outputs(&dir));
}

#[test]
fn sixteen_million_sinkhorn_samples_of_a_mesh_are_refused_before_any_work() {
    let dir = scratch("limits-sinkhorn");
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 16777216\n[solver]\nkind = \"sinkhorn\"\n\
         [[input]]\nname = \"cow\"\npath = \"{}\"\n",
        shared_data().join("meshes/spot_triangulated.obj").display()
    );
    write_manifest(&dir, "m.toml", &body);
    let expect = [
        "\"cow\"",
        "16777216 samples in 3D",
        "sinkhorn",
        "lower `[proxy] samples`",
        "kind = \"sliced\"",
    ];
    let err = refused(
        &dir,
        &["--memory", "8GiB", "bake", "m.toml"],
        false,
        &expect,
    );
    assert!(err.contains("8.0 GiB (from --memory)"), "{err}");
    refused(&dir, &["bake", "m.toml"], true, &expect);
    assert!(outputs(&dir).is_empty(), "{:?}", outputs(&dir));
    // Not even the output folder or its store: a refused bake leaves the tree as it was.
    assert!(!dir.join("out").exists(), "a refused bake created out/");
}

#[test]
fn grids_are_checked_on_their_whole_image_and_blend_count() {
    let dir = scratch("limits-grid");
    two_shapes(&dir, "");
    for ulimit in [false, true] {
        let budget: &[&str] = if ulimit { &[] } else { &["--memory", "1GiB"] };
        for (extra, expect) in [
            (
                &["--steps", "5", "--size", "16384x16384"][..],
                "5 blends of 16384x16384 pixels",
            ),
            (
                &["--steps", "100000"][..],
                "100000 blends of 256x256 pixels",
            ),
        ] {
            let mut args = budget.to_vec();
            args.extend(["grid", "two.toml", "-o", "g.png"]);
            args.extend(extra);
            refused(
                &dir,
                &args,
                ulimit,
                &[expect, "lower --steps or --size", "--memory SIZE"],
            );
        }
    }
    assert!(outputs(&dir).is_empty(), "{:?}", outputs(&dir));
}

/// `fit --render` checks its image's size before it bakes or fits anything.
#[test]
fn a_fit_render_larger_than_the_budget_is_refused_before_the_bake() {
    let dir = scratch("limits-fit-render");
    two_shapes(&dir, "");
    let target = shared_data().join("shapes/duck.png");
    let target = target.to_str().unwrap();
    for ulimit in [false, true] {
        let budget: &[&str] = if ulimit { &[] } else { &["--memory", "1GiB"] };
        let mut args = budget.to_vec();
        args.extend([
            "fit",
            "two.toml",
            "--target",
            target,
            "--render",
            "fit.png",
            "--size",
            "16384x16384",
        ]);
        refused(
            &dir,
            &args,
            ulimit,
            &[
                "fit --render: a 16384x16384 image",
                "lower --size",
                "--memory SIZE",
            ],
        );
    }
    assert!(outputs(&dir).is_empty(), "{:?}", outputs(&dir));
}

#[test]
fn a_triangle_of_100000_rows_is_refused() {
    let dir = scratch("limits-triangle");
    let meshes = shared_data().join("meshes");
    let inputs: String = ["torus", "suzanne", "fish_blub"]
        .iter()
        .map(|m| {
            format!(
                "[[input]]\nname = \"{m}\"\npath = \"{}\"\n",
                meshes.join(format!("{m}.obj")).display()
            )
        })
        .collect();
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 300\n[solver]\nkind = \"exact\"\n[mesh]\nresolution = 16\n{inputs}"
    );
    write_manifest(&dir, "m.toml", &body);
    let expect = [
        "render --triangle 100000",
        "5000050000 blends",
        "lower --triangle or --size",
    ];
    refused(
        &dir,
        &[
            "--memory",
            "1GiB",
            "render",
            "m.toml",
            "--triangle",
            "100000",
            "-o",
            "t.png",
        ],
        false,
        &expect,
    );
    refused(
        &dir,
        &["render", "m.toml", "--triangle", "100000", "-o", "t.png"],
        true,
        &expect,
    );
    assert!(outputs(&dir).is_empty(), "{:?}", outputs(&dir));
}

#[test]
fn memory_sizes_are_parsed_and_the_default_is_stated() {
    let dir = scratch("limits-help");
    let help = String::from_utf8_lossy(&run(&dir, &["--help"], false).stdout).into_owned();
    assert!(
        help.contains("--memory <SIZE>") && help.contains("Default: 50% of the memory"),
        "{help}"
    );
    assert!(help.contains("here now"), "{help}");
    two_shapes(&dir, "");
    let out = run(&dir, &["--memory", "4 parsecs", "bake", "two.toml"], false);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--memory") && err.contains("unknown unit \"parsecs\""),
        "{err}"
    );
    two_shapes(&dir, "[limits]\nmemory = \"lots\"\n");
    let out = run(&dir, &["bake", "two.toml"], false);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("two.toml:") && err.contains("`limits.memory`") && err.contains("e.g. 4GiB"),
        "{err}"
    );
    // A budget that fits bakes as before, under ulimit -v too.
    two_shapes(&dir, "[limits]\nmemory = \"1GiB\"\n");
    let out = run(&dir, &["bake", "two.toml"], true);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
