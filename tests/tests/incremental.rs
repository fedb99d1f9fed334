//! Incremental, deterministic, crash-safe baking: no-op rebuilds do nothing, each edit rebuilds
//! exactly what it affects, kills and concurrent bakes never leave bad outputs, and build-system
//! actions give the same bytes as `otbake bake`.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions, BakeReport, Status};
use otbake_tests::{
    otbake, otbake_bin, otbake_err, otbake_ok, scratch, shared_data, temp_files, write_manifest,
};
use std::path::{Path, PathBuf};

const SHAPES: [&str; 3] = ["heart", "duck", "tooth"];

/// A manifest over copies of three shapes (so tests can edit inputs), `samples` points each.
fn setup(name: &str, samples: usize, extra_solver: &str) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    for s in SHAPES {
        std::fs::copy(
            shared_data().join(format!("shapes/{s}.png")),
            dir.join(format!("{s}.png")),
        )
        .unwrap();
    }
    let m = write_manifest(&dir, "m.toml", &body(samples, 0, extra_solver, &SHAPES));
    (dir, m)
}

fn body(samples: usize, seed: u64, extra_solver: &str, names: &[&str]) -> String {
    let mut b = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = {samples}\nseed = {seed}\n[solver]\nkind = \"sliced\"\n{extra_solver}\n"
    );
    for (name, file) in names.iter().zip(SHAPES) {
        b += &format!(
            "[[input]]\nname = \"{name}\"\npath = \"{file}.png\"\ndensity = \"inverted\"\n"
        );
    }
    b
}

fn run(m: &Path) -> BakeReport {
    bake(&Manifest::load(m).unwrap(), &BakeOptions::default()).unwrap()
}

fn statuses(r: &BakeReport) -> Vec<(String, Status)> {
    r.products
        .iter()
        .map(|p| (p.name.clone(), p.status))
        .collect()
}

fn expect(r: &BakeReport, built: &[&str]) {
    for p in &r.products {
        let want = if built.contains(&p.name.as_str()) {
            Status::Built
        } else {
            Status::Cached
        };
        assert_eq!(
            p.status,
            want,
            "{}: {:?} (all: {:?})",
            p.name,
            p.status,
            statuses(r)
        );
    }
}

fn outputs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    // A bake killed early may not have created the output directory yet.
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

#[test]
fn each_edit_rebuilds_exactly_what_it_affects() {
    let (dir, m) = setup("inc-edits", 1500, "");
    expect(&run(&m), &["proxy", "heart", "duck", "tooth"]);
    // No-op: nothing is built, everything is current.
    let r = run(&m);
    expect(&r, &[]);
    assert!(
        r.products.iter().all(|p| p.detail == "current"),
        "{:?}",
        r.products
    );

    // Edit one input: only its map.
    std::fs::copy(
        shared_data().join("shapes/redcross.png"),
        dir.join("duck.png"),
    )
    .unwrap();
    expect(&run(&m), &["duck"]);

    // A solver setting: every map, not the proxy.
    std::fs::write(&m, body(1500, 0, "step = 0.35", &SHAPES)).unwrap();
    expect(&run(&m), &["heart", "duck", "tooth"]);

    // A storage setting: every map, not the proxy (the proxy is always stored in full); going back
    // is a store hit with the same bytes.
    let full = std::fs::read(dir.join("out/heart.otb")).unwrap();
    let compact = body(1500, 0, "step = 0.35", &SHAPES) + "[storage]\npreset = \"compact\"\n";
    std::fs::write(&m, compact).unwrap();
    expect(&run(&m), &["heart", "duck", "tooth"]);
    let small = std::fs::read(dir.join("out/heart.otb")).unwrap();
    assert!(
        small.len() * 2 < full.len(),
        "{} vs {}",
        small.len(),
        full.len()
    );
    std::fs::write(&m, body(1500, 0, "step = 0.35", &SHAPES)).unwrap();
    expect(&run(&m), &[]);
    assert_eq!(std::fs::read(dir.join("out/heart.otb")).unwrap(), full);

    // A proxy setting: the proxy and every map.
    std::fs::write(&m, body(1500, 1, "step = 0.35", &SHAPES)).unwrap();
    expect(&run(&m), &["proxy", "heart", "duck", "tooth"]);

    // Renaming an input solves nothing: its archive comes from the store, byte-identical.
    let before = std::fs::read(dir.join("out/heart.otb")).unwrap();
    std::fs::write(
        &m,
        body(1500, 1, "step = 0.35", &["coeur", "duck", "tooth"]),
    )
    .unwrap();
    let r = run(&m);
    expect(&r, &[]);
    assert_eq!(r.products[1].detail, "restored from the store");
    assert_eq!(std::fs::read(dir.join("out/coeur.otb")).unwrap(), before);

    // Going back to an earlier setting is a store hit too.
    std::fs::write(&m, body(1500, 0, "step = 0.35", &SHAPES)).unwrap();
    expect(&run(&m), &[]);
}

#[test]
fn damaged_outputs_and_store_objects_are_detected_and_rebuilt() {
    let (dir, m) = setup("inc-damage", 1000, "");
    run(&m);
    let clean = outputs(&dir);
    // Damage every store object and one output: the output is rebuilt, not restored from the
    // damaged store, and damaged objects are replaced.
    let mut objects = vec![];
    let mut stack = vec![dir.join("out/.otbake/objects")];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            if e.path().is_dir() {
                stack.push(e.path());
            } else {
                objects.push(e.path());
            }
        }
    }
    assert_eq!(objects.len(), 4);
    for o in &objects {
        let mut b = std::fs::read(o).unwrap();
        let at = b.len() / 3;
        b[at] ^= 0xFF;
        std::fs::write(o, b).unwrap();
    }
    let duck = dir.join("out/duck.otb");
    let mut b = std::fs::read(&duck).unwrap();
    let at = b.len() / 2;
    b[at] ^= 0x01;
    std::fs::write(&duck, b).unwrap();
    let r = run(&m);
    expect(&r, &["duck"]);
    assert_eq!(outputs(&dir), clean);
    // The rebuilt object is intact again: deleting the output restores it from the store.
    std::fs::remove_file(&duck).unwrap();
    let r = run(&m);
    expect(&r, &[]);
    assert_eq!(outputs(&dir), clean);
}

#[test]
fn json_report_and_exit_status() {
    let (dir, m) = setup("inc-json", 800, "");
    let out = otbake_ok(&dir, &["bake", "--json", m.to_str().unwrap()]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let products = v["products"].as_array().unwrap();
    assert_eq!(products.len(), 4);
    assert!(products.iter().all(|p| p["status"] == "built"));
    let out = otbake_ok(&dir, &["bake", "--json", m.to_str().unwrap()]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["products"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p["status"] == "cached"));
    // One broken input: its product fails, the others stay cached, the exit status is non-zero.
    std::fs::write(dir.join("tooth.png"), b"not a png").unwrap();
    let out = otbake(&dir, &["bake", "--json", m.to_str().unwrap()]);
    assert!(!out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let st: Vec<_> = v["products"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["status"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(st, ["cached", "cached", "cached", "failed"]);
}

#[test]
fn killed_bakes_leave_good_outputs_and_the_next_bake_repairs_them() {
    let (clean_dir, clean_m) = setup("inc-kill-clean", 60_000, "");
    otbake_ok(&clean_dir, &["bake", clean_m.to_str().unwrap()]);
    let clean = outputs(&clean_dir);
    for (round, delay_ms) in [30u64, 300, 900, 1800, 3000].into_iter().enumerate() {
        let (dir, m) = setup(&format!("inc-kill-{round}"), 60_000, "");
        let mut child = std::process::Command::new(otbake_bin())
            .args(["bake", m.to_str().unwrap()])
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill(); // SIGKILL
        let _ = child.wait();
        // Whatever exists is a complete, valid archive.
        for (name, bytes) in outputs(&dir) {
            assert!(
                otbake::pipeline::inspect::validate(&bytes).is_ok(),
                "round {round}: {name} is torn"
            );
        }
        otbake_ok(&dir, &["bake", m.to_str().unwrap()]);
        assert_eq!(
            outputs(&dir),
            clean,
            "round {round} (killed after {delay_ms} ms)"
        );
        // Temporaries of the killed process may remain; they never shadow an output.
        let _ = temp_files(&dir);
    }
}

#[test]
fn concurrent_bakes_of_one_manifest_both_succeed() {
    let (dir, m) = setup("inc-concurrent", 20_000, "");
    let spawn = || {
        std::process::Command::new(otbake_bin())
            .args(["bake", m.to_str().unwrap()])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (spawn(), spawn());
    for c in [a, b] {
        let out = c.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let (clean_dir, clean_m) = setup("inc-concurrent-clean", 20_000, "");
    otbake_ok(&clean_dir, &["bake", clean_m.to_str().unwrap()]);
    assert_eq!(outputs(&dir), outputs(&clean_dir));
}

#[test]
fn ninja_runs_the_plan_to_the_same_bytes() {
    let has_ninja = std::process::Command::new("ninja")
        .arg("--version")
        .output()
        .is_ok();
    if !has_ninja {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI installs ninja-build; it must be present"
        );
        eprintln!("ninja not installed: skipping (CI installs it)");
        return;
    }
    let (dir, m) = setup("inc-ninja", 1200, "");
    let plan = otbake_ok(&dir, &["plan", m.to_str().unwrap(), "--format", "ninja"]);
    std::fs::write(dir.join("build.ninja"), &plan.stdout).unwrap();
    let ninja = |dir: &Path| {
        let out = std::process::Command::new("ninja")
            .current_dir(dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stdout)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    ninja(&dir);
    let (clean_dir, clean_m) = setup("inc-ninja-clean", 1200, "");
    otbake_ok(&clean_dir, &["bake", clean_m.to_str().unwrap()]);
    assert_eq!(outputs(&dir), outputs(&clean_dir));
    // Nothing to do the second time.
    assert!(ninja(&dir).contains("no work to do"));
    // Editing one input reruns its action; restat keeps the others untouched.
    std::fs::copy(
        shared_data().join("shapes/redcross.png"),
        dir.join("duck.png"),
    )
    .unwrap();
    let before: Vec<_> = ["proxy", "heart", "tooth"]
        .iter()
        .map(|n| {
            std::fs::metadata(dir.join(format!("out/{n}.otb")))
                .unwrap()
                .modified()
                .unwrap()
        })
        .collect();
    ninja(&dir);
    let after: Vec<_> = ["proxy", "heart", "tooth"]
        .iter()
        .map(|n| {
            std::fs::metadata(dir.join(format!("out/{n}.otb")))
                .unwrap()
                .modified()
                .unwrap()
        })
        .collect();
    assert_eq!(before, after);
    // The JSON plan declares every action's inputs and outputs.
    let json = otbake_ok(&dir, &["plan", m.to_str().unwrap(), "--format", "json"]);
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let actions = v["actions"].as_array().unwrap();
    assert_eq!(actions.len(), 4);
    assert!(actions[1]["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .any(|p| p.as_str().unwrap().ends_with("out/proxy.otb")));
}

#[test]
fn pack_and_unpack_round_trip() {
    let (dir, m) = setup("inc-pack", 800, "");
    otbake_ok(&dir, &["bake", m.to_str().unwrap()]);
    otbake_ok(&dir, &["pack", "out/duck.otb", "-o", "duck.otb.zst"]);
    otbake_ok(&dir, &["unpack", "duck.otb.zst", "-o", "back.otb"]);
    assert_eq!(
        std::fs::read(dir.join("back.otb")).unwrap(),
        std::fs::read(dir.join("out/duck.otb")).unwrap()
    );
    assert!(
        std::fs::metadata(dir.join("duck.otb.zst")).unwrap().len()
            < std::fs::metadata(dir.join("back.otb")).unwrap().len()
    );
    std::fs::write(dir.join("bad.zst"), b"garbage").unwrap();
    let err = otbake_err(&dir, &["unpack", "bad.zst", "-o", "x.otb"]);
    assert!(err.contains("bad.zst"), "{err}");
    assert!(!dir.join("x.otb").exists());
}

/// Mounts a tmpfs at `dir` with `options`; `None` if this machine does not allow it.
fn tmpfs(dir: &Path, options: &str) -> Option<TmpfsGuard> {
    std::fs::create_dir_all(dir).unwrap();
    let ok = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", options, "tmpfs", dir.to_str().unwrap()])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    ok.then(|| TmpfsGuard(dir.to_path_buf()))
}

struct TmpfsGuard(PathBuf);

impl Drop for TmpfsGuard {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn full_or_read_only_output_disks_fail_clearly_and_keep_previous_outputs() {
    let (dir, m) = setup("inc-disk", 3000, "");
    let out = dir.join("out");
    let Some(_full) = tmpfs(&out, "size=200k") else {
        eprintln!("cannot mount tmpfs here: skipping the disk-full and read-only cases");
        return;
    };
    // 3000 points fit once (~4 × 70 KB) only partially: the bake fails with ENOSPC.
    let err = otbake_err(&dir, &["bake", m.to_str().unwrap()]);
    assert!(err.contains("No space left on device"), "{err}");
    // Whatever was completed is valid; nothing is torn; no temporaries remain.
    for (name, bytes) in outputs(&dir) {
        assert!(
            otbake::pipeline::inspect::validate(&bytes).is_ok(),
            "{name} is torn"
        );
    }
    assert!(
        temp_files(&out).is_empty(),
        "temporaries left: {:?}",
        temp_files(&out)
    );
    drop(_full);

    // A bake that succeeded, then a read-only output directory: the next (changed) bake fails
    // clearly and the previous outputs stay as they were.
    let Some(_ro) = tmpfs(&out, "size=8m") else {
        return;
    };
    otbake_ok(&dir, &["bake", m.to_str().unwrap()]);
    let good = outputs(&dir);
    assert!(std::process::Command::new("mount")
        .args(["-o", "remount,ro", out.to_str().unwrap()])
        .status()
        .unwrap()
        .success());
    std::fs::copy(
        shared_data().join("shapes/redcross.png"),
        dir.join("duck.png"),
    )
    .unwrap();
    let err = otbake_err(&dir, &["bake", m.to_str().unwrap()]);
    assert!(err.contains("Read-only file system"), "{err}");
    assert_eq!(outputs(&dir), good);
}
