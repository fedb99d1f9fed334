//! The shared store (`--cache-dir`) under concurrency and faults: two different manifests baking
//! into one store at once, a bake killed while it writes the store, a full disk under the store,
//! and a corrupted stat index. Never a wrong output, never a crash: every archive that exists is
//! valid, and the next bake gives exactly the bytes of a clean bake.

use otbake::pipeline::inspect::validate;
use otbake_tests::{
    otbake, otbake_bin, otbake_ok, scratch, shared_data, temp_files, write_manifest,
};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// A manifest of two shapes in `dir` (output `out`), `samples` points each, sliced.
fn manifest(dir: &Path, samples: usize, seed: u64, shapes: [&str; 2]) -> PathBuf {
    let mut b = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\nseed = {seed}\n[solver]\nkind = \"sliced\"\n"
    );
    for s in shapes {
        let path = shared_data().join(format!("shapes/{s}.png"));
        b += &format!(
            "[[input]]\nname = \"{s}\"\npath = \"{}\"\ndensity = \"inverted\"\n",
            path.display()
        );
    }
    write_manifest(dir, "m.toml", &b)
}

/// Every `.otb` under `dir/out`, by name.
fn outputs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = std::fs::read_dir(dir.join("out"))
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "otb"))
        .collect();
    files.sort();
    files
        .iter()
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(p).unwrap(),
            )
        })
        .collect()
}

/// Every object file of a store (not temporaries).
fn objects(store: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![store.join("objects")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "otb")
                && !p.to_string_lossy().contains(".tmp-")
            {
                found.push(p);
            }
        }
    }
    found
}

/// Asserts every output and every store object is a valid archive (nothing torn).
fn all_valid(dir: &Path, store: &Path) {
    for (name, bytes) in outputs(dir) {
        assert!(validate(&bytes).is_ok(), "output {name} is torn");
    }
    for p in objects(store) {
        assert!(
            validate(&std::fs::read(&p).unwrap()).is_ok(),
            "store object {} is torn",
            p.display()
        );
    }
}

/// The outputs of a clean bake of the same manifest in a fresh directory with its own store.
fn clean(name: &str, samples: usize, seed: u64, shapes: [&str; 2]) -> Vec<(String, Vec<u8>)> {
    let dir = scratch(name);
    let m = manifest(&dir, samples, seed, shapes);
    otbake_ok(&dir, &["bake", m.to_str().unwrap()]);
    outputs(&dir)
}

#[test]
fn two_manifests_bake_into_one_store_at_once() {
    let store = scratch("store-shared");
    let (a, b) = (scratch("store-shared-a"), scratch("store-shared-b"));
    let ma = manifest(&a, 20_000, 0, ["duck", "heart"]);
    // Shares the duck's input file and the proxy settings with `a`, so both write the same keys.
    let mb = manifest(&b, 20_000, 0, ["duck", "tooth"]);
    for round in 0..3 {
        let spawn = |dir: &Path, m: &Path| {
            Command::new(otbake_bin())
                .args([
                    "bake",
                    "--force",
                    m.to_str().unwrap(),
                    "--cache-dir",
                    store.to_str().unwrap(),
                ])
                .current_dir(dir)
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        };
        let children = [spawn(&a, &ma), spawn(&b, &mb)];
        for c in children {
            let out = c.wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "round {round}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        all_valid(&a, &store);
        all_valid(&b, &store);
    }
    // And a bake that restores from the shared store gives the clean bytes.
    for (dir, m) in [(&a, &ma), (&b, &mb)] {
        std::fs::remove_dir_all(dir.join("out")).unwrap();
        let out = otbake_ok(
            dir,
            &[
                "bake",
                "--json",
                m.to_str().unwrap(),
                "--cache-dir",
                store.to_str().unwrap(),
            ],
        );
        assert!(String::from_utf8_lossy(&out.stdout).contains("restored from the store"));
    }
    assert_eq!(
        outputs(&a),
        clean("store-shared-clean-a", 20_000, 0, ["duck", "heart"])
    );
    assert_eq!(
        outputs(&b),
        clean("store-shared-clean-b", 20_000, 0, ["duck", "tooth"])
    );
    assert!(temp_files(&store).is_empty(), "{:?}", temp_files(&store));
}

#[test]
fn a_bake_killed_while_writing_the_store_leaves_no_torn_object() {
    let want = clean("store-kill-clean", 60_000, 1, ["duck", "heart"]);
    for (round, delay_ms) in [20u64, 150, 400, 800, 1500].into_iter().enumerate() {
        let dir = scratch(&format!("store-kill-{round}"));
        let store = dir.join("store");
        let m = manifest(&dir, 60_000, 1, ["duck", "heart"]);
        let mut child = Command::new(otbake_bin())
            .args([
                "bake",
                m.to_str().unwrap(),
                "--cache-dir",
                store.to_str().unwrap(),
            ])
            .current_dir(&dir)
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill(); // SIGKILL, wherever it is
        let _ = child.wait();
        all_valid(&dir, &store);
        // A torn object would be found by the next bake, which restores or rebuilds it.
        otbake_ok(
            &dir,
            &[
                "bake",
                m.to_str().unwrap(),
                "--cache-dir",
                store.to_str().unwrap(),
            ],
        );
        assert_eq!(
            outputs(&dir),
            want,
            "round {round} (killed after {delay_ms} ms)"
        );
        all_valid(&dir, &store);
    }
}

#[test]
fn a_full_disk_under_the_store_fails_clearly_and_the_next_bake_repairs() {
    // The full disk is simulated with a file-size limit (`ulimit -f`, RLIMIT_FSIZE), which any user
    // may set: a write past it fails with EFBIG as one on a full disk fails with ENOSPC. SIGXFSZ,
    // whose default action would kill any program, is ignored by the shell (`trap '' XFSZ`), and an
    // ignored signal stays ignored across `exec`.
    let dir = scratch("store-full");
    let store = dir.join("store");
    let m = manifest(&dir, 20_000, 2, ["duck", "heart"]);
    // 200 KiB: the proxy (~480 KB at 20K points) cannot be written.
    let out = Command::new("sh")
        .arg("-c")
        .arg("trap '' XFSZ; ulimit -f 200; exec \"$0\" \"$@\"")
        .arg(otbake_bin())
        .args([
            "bake",
            m.to_str().unwrap(),
            "--cache-dir",
            store.to_str().unwrap(),
        ])
        .current_dir(&dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{:?}: {err}", out.status);
    let line = err
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("{err}"));
    assert!(
        line.contains("cannot write") && line.contains("store"),
        "{line}"
    );
    all_valid(&dir, &store);
    assert!(
        temp_files(&dir).is_empty(),
        "temporaries left: {:?}",
        temp_files(&dir)
    );
    otbake_ok(
        &dir,
        &[
            "bake",
            m.to_str().unwrap(),
            "--cache-dir",
            store.to_str().unwrap(),
        ],
    );
    assert_eq!(
        outputs(&dir),
        clean("store-full-clean", 20_000, 2, ["duck", "heart"])
    );
}

#[test]
fn a_corrupted_stat_index_never_gives_a_wrong_output() {
    let want = clean("store-index-clean", 5_000, 3, ["duck", "heart"]);
    let dir = scratch("store-index");
    let store = dir.join("store");
    let m = manifest(&dir, 5_000, 3, ["duck", "heart"]);
    let bake = |dir: &Path| {
        otbake_ok(
            dir,
            &[
                "bake",
                m.to_str().unwrap(),
                "--cache-dir",
                store.to_str().unwrap(),
            ],
        )
    };
    bake(&dir);
    let index = store.join("stat-index");
    let good = std::fs::read(&index).unwrap();
    assert!(!good.is_empty());
    let mut flipped = good.clone();
    for i in (0..flipped.len()).step_by(7) {
        flipped[i] ^= 0x5a;
    }
    let mut shifted = vec![0u8; 3];
    shifted.extend_from_slice(&good);
    // One hex digit of every recorded value changed: every line still parses, as another digest.
    let text = String::from_utf8(good.clone()).unwrap();
    let redigit: String = text
        .lines()
        .map(|l| {
            let mut c: Vec<char> = l.chars().collect();
            c[0] = if c[0] == '0' { '1' } else { '0' };
            c.into_iter().collect::<String>() + "\n"
        })
        .collect();
    for (what, bytes) in [
        ("another digit", redigit.into_bytes()),
        ("truncated", good[..good.len() / 2].to_vec()),
        ("bit flips", flipped),
        ("shifted", shifted),
        (
            "garbage",
            (0..4096u32)
                .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
                .collect(),
        ),
        ("empty", Vec::new()),
    ] {
        // The index is corrupted and an output is replaced by another valid archive of the same
        // size class: only the stamps and keys can tell, and a bad index must not hide it.
        std::fs::write(&index, &bytes).unwrap();
        std::fs::copy(dir.join("out/heart.otb"), dir.join("out/duck.otb")).unwrap();
        let out = otbake(
            &dir,
            &[
                "bake",
                m.to_str().unwrap(),
                "--cache-dir",
                store.to_str().unwrap(),
            ],
        );
        assert!(
            out.status.success(),
            "{what}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(outputs(&dir), want, "{what}");
    }
}
