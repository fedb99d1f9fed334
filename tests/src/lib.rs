//! Shared helpers for the end-to-end tests: running the `otbake` binary, scratch directories,
//! synthetic inputs with known closed forms.

pub mod fuzz;

use otbake::render::imageio::{write_image, Rgba};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The workspace root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The `otbake` binary of this build profile. `cargo test --workspace` builds it (the `otbake`
/// package has integration tests); if it is missing, it is built once here.
pub fn otbake_bin() -> PathBuf {
    static BIN: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BIN.get_or_init(|| {
        // target/<profile>/deps/<test-exe> → target/<profile>/otbake
        let exe = std::env::current_exe().expect("test executable path");
        let profile_dir = exe
            .parent()
            .and_then(Path::parent)
            .expect("target/<profile>");
        let bin = profile_dir.join(format!("otbake{}", std::env::consts::EXE_SUFFIX));
        if !bin.exists() {
            let release = profile_dir.file_name().is_some_and(|n| n == "release");
            let mut cargo = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
            cargo
                .args(["build", "-p", "otbake", "--bin", "otbake"])
                .current_dir(repo_root());
            if release {
                cargo.arg("--release");
            }
            assert!(
                cargo.status().expect("run cargo build").success(),
                "building otbake failed"
            );
        }
        bin
    })
    .clone()
}

/// A fresh, empty scratch directory for one test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = repo_root()
        .join("target")
        .join("otbake-tests")
        .join(format!("{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `otbake` with `args` in `dir`.
pub fn otbake(dir: &Path, args: &[&str]) -> Output {
    Command::new(otbake_bin())
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run otbake")
}

/// Runs `otbake` and panics with its stderr unless it succeeds.
pub fn otbake_ok(dir: &Path, args: &[&str]) -> Output {
    let out = otbake(dir, args);
    assert!(
        out.status.success(),
        "otbake {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `otbake`, asserts it fails, and returns its stderr.
pub fn otbake_err(dir: &Path, args: &[&str]) -> String {
    let out = otbake(dir, args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        !out.status.success(),
        "otbake {args:?} should fail but succeeded:\n{err}"
    );
    assert!(
        err.lines().any(|l| l.starts_with("error: ")),
        "errors are one clear line, not a panic:\n{err}"
    );
    assert!(!err.contains("panicked"), "otbake panicked:\n{err}");
    err
}

/// Writes `body` as a manifest file.
pub fn write_manifest(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

/// An axis-aligned Gaussian density in `[0,1]²`, as a linear gray EXR image of `size`² pixels.
/// The luminance at pixel centre c is exp(-½ Σ ((c_k − mean_k)/sigma_k)²).
pub fn write_gaussian_exr(path: &Path, size: usize, mean: [f64; 2], sigma: [f64; 2]) {
    let mut img = Rgba::filled(size, size, [0.0, 0.0, 0.0, 1.0]);
    for y in 0..size {
        for x in 0..size {
            let c = [
                (x as f64 + 0.5) / size as f64,
                (y as f64 + 0.5) / size as f64,
            ];
            let q: f64 = (0..2).map(|k| ((c[k] - mean[k]) / sigma[k]).powi(2)).sum();
            let v = (-0.5 * q).exp() as f32;
            let i = (y * size + x) * 4;
            img.pixels[i..i + 3].fill(v);
        }
    }
    write_image(path, &img).unwrap();
}

/// Files in `dir` whose names mark them as temporaries (a half-written output would show up here).
pub fn temp_files(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p
                .file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.contains(".tmp-"))
            {
                found.push(p);
            }
        }
    }
    found
}

/// Relative path from `dir` to the shared data directory, for manifests written into scratch dirs.
pub fn shared_data() -> PathBuf {
    repo_root()
        .join("../shared/data")
        .canonicalize()
        .expect("../shared/data beside the repository")
}

/// One fuzz corpus entry: a proxy archive and the maps baked against it.
#[derive(Clone)]
pub struct CorpusCase {
    /// Proxy archive bytes.
    pub proxy: Vec<u8>,
    /// Map archive bytes.
    pub maps: Vec<Vec<u8>>,
}

/// Loads the corpus: every sub-directory of `dir` holding `proxy.otb` and `*.otb` maps.
pub fn fuzz_corpus(dir: &Path) -> Vec<CorpusCase> {
    let mut cases = Vec::new();
    let mut subdirs: Vec<_> = std::fs::read_dir(dir)
        .expect("fuzz corpus directory")
        .flatten()
        .map(|e| e.path())
        .collect();
    subdirs.sort();
    for d in subdirs.into_iter().filter(|d| d.is_dir()) {
        let mut maps: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.extension().is_some_and(|x| x == "otb")
                    && p.file_name().is_some_and(|n| n != "proxy.otb")
            })
            .collect();
        maps.sort();
        cases.push(CorpusCase {
            proxy: std::fs::read(d.join("proxy.otb")).unwrap(),
            maps: maps.iter().map(|p| std::fs::read(p).unwrap()).collect(),
        });
    }
    assert!(!cases.is_empty(), "empty fuzz corpus in {}", dir.display());
    cases
}
