//! The remote-cache scenarios, run against any server that speaks Bazel's HTTP cache protocol:
//! the in-process fake (`remote_cache.rs`, plain `cargo test`) and real nginx (`remote_nginx.rs`,
//! run by `.ci/bazel`). Each scenario bakes a small manifest with `otbake bake --remote-cache` the
//! way two CI runners would: in two folders with their own outputs and stores.

#![allow(dead_code)] // each test binary uses the part it needs

pub mod fake;
pub mod nginx;

use otbake_tests::{otbake, scratch, shared_data};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The server locations a scenario can use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// Reads and writes.
    Cache,
    /// The same entries, read-only: PUT is refused (403).
    ReadOnly,
    /// Every request answers 500.
    Fails,
    /// GET answers 200 with bytes that are no cache entry; PUT answers 200 and stores nothing.
    Garbage,
    /// Requests wait longer than the client's timeout.
    Slow,
}

/// A cache server under test.
pub trait CacheServer {
    /// Base URL of a location (ends in `/`).
    fn url(&self, loc: Location) -> String;
    /// The bytes the server stores at `path` (`cas/<hash>`, `ac/<key>`).
    fn stored(&self, path: &str) -> Option<Vec<u8>>;
    /// Replaces what the server stores at `path` (to corrupt an entry).
    fn overwrite(&self, path: &str, bytes: &[u8]);
}

const SHAPES: [&str; 2] = ["heart", "duck"];

/// A runner's folder: copies of two shapes and a manifest of `seed` (a new seed: new keys).
pub fn runner(name: &str, seed: u64) -> (PathBuf, PathBuf) {
    let dir = scratch(name);
    let mut body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 400\nseed = {seed}\n[solver]\nkind = \"exact\"\n"
    );
    for s in SHAPES {
        std::fs::copy(
            shared_data().join(format!("shapes/{s}.png")),
            dir.join(format!("{s}.png")),
        )
        .unwrap();
        body += &format!("[[input]]\nname = \"{s}\"\npath = \"{s}.png\"\ndensity = \"inverted\"\n");
    }
    let m = dir.join("m.toml");
    std::fs::write(&m, body).unwrap();
    (dir, m)
}

/// What one `otbake bake --json` did.
pub struct Baked {
    /// The JSON report.
    pub json: Value,
    /// stderr.
    pub stderr: String,
}

impl Baked {
    /// `(name, status, detail)` per product.
    pub fn products(&self) -> Vec<(String, String, String)> {
        self.json["products"]
            .as_array()
            .expect("products")
            .iter()
            .map(|p| {
                let s = |k: &str| p[k].as_str().unwrap_or("").to_string();
                (s("name"), s("status"), s("detail"))
            })
            .collect()
    }

    /// Every product's status is `status`.
    pub fn all(&self, status: &str) {
        for (name, s, detail) in self.products() {
            assert_eq!(
                s, status,
                "{name}: {s} ({detail})\nstderr:\n{}",
                self.stderr
            );
        }
    }

    /// A count of the remote summary.
    pub fn count(&self, field: &str) -> u64 {
        self.json["remote"][field]
            .as_u64()
            .unwrap_or_else(|| panic!("remote.{field} in {}", self.json))
    }

    /// `reads` or `writes` of the remote summary: `on` or why it is off.
    pub fn access(&self, field: &str) -> String {
        self.json["remote"][field]
            .as_str()
            .unwrap_or("")
            .to_string()
    }
}

/// `otbake bake --json m [extra...]`, which must succeed.
pub fn bake(dir: &Path, m: &Path, extra: &[&str]) -> Baked {
    let mut args = vec!["bake", "--json", m.to_str().unwrap()];
    args.extend_from_slice(extra);
    let out = otbake(dir, &args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(
        out.status.success(),
        "otbake {args:?} failed (a cache never fails a bake):\n{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    let json = serde_json::from_slice(&out.stdout).expect("one JSON report");
    Baked { json, stderr }
}

/// A bake through the cache at `url`.
pub fn bake_via(dir: &Path, m: &Path, url: &str) -> Baked {
    bake(dir, m, &["--remote-cache", url, "--remote-timeout", "2"])
}

/// The archives of a runner's output folder: (file name, bytes), sorted.
pub fn outputs(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = std::fs::read_dir(dir.join("out"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "otb"))
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect();
    files.sort();
    assert_eq!(files.len(), 3, "proxy and two maps in {}", dir.display());
    files
}

/// The outputs of a plain local bake (no cache) of a runner of `seed`.
pub fn local_outputs(name: &str, seed: u64) -> Vec<(String, Vec<u8>)> {
    let (dir, m) = runner(name, seed);
    bake(&dir, &m, &[]).all("built");
    outputs(&dir)
}

/// Lower-case hex sha256.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// Fills the server's cache from a runner of `seed` and returns that runner's outputs.
pub fn populate(s: &dyn CacheServer, name: &str, seed: u64) -> Vec<(String, Vec<u8>)> {
    let (dir, m) = runner(name, seed);
    let a = bake_via(&dir, &m, &s.url(Location::Cache));
    a.all("built");
    assert_eq!(a.count("uploaded"), 3, "{}", a.json);
    outputs(&dir)
}

/// Cold, warm, and no-op: a second runner gets every product from the cache, byte-identical.
pub fn cold_then_warm(s: &dyn CacheServer, tag: &str) {
    let (a_dir, a_m) = runner(&format!("{tag}-cold"), 0);
    let a = bake_via(&a_dir, &a_m, &s.url(Location::Cache));
    a.all("built");
    assert_eq!(
        (a.count("misses"), a.count("uploaded")),
        (3, 3),
        "{}",
        a.json
    );
    assert_eq!(a.access("writes"), "on");
    let cold = outputs(&a_dir);
    assert_eq!(
        cold,
        local_outputs(&format!("{tag}-local"), 0),
        "a cache changes no byte"
    );

    let (b_dir, b_m) = runner(&format!("{tag}-warm"), 0);
    let b = bake_via(&b_dir, &b_m, &s.url(Location::Cache));
    b.all("cached");
    for (name, _, detail) in b.products() {
        assert_eq!(detail, "restored from the remote cache", "{name}");
    }
    assert_eq!((b.count("hits"), b.count("misses")), (3, 0), "{}", b.json);
    assert_eq!(
        outputs(&b_dir),
        cold,
        "the warm runner's archives are the cold one's"
    );

    // Everything is now local: the server is not even asked.
    let again = bake_via(&b_dir, &b_m, &s.url(Location::Cache));
    again.all("cached");
    assert_eq!(again.count("hits") + again.count("misses"), 0);
}

/// A server that is off, failing or slow: one note, a local bake, the local bytes.
pub fn falls_back(url: &str, tag: &str, why: &str) {
    let (dir, m) = runner(tag, 0);
    let b = bake_via(&dir, &m, url);
    b.all("built");
    assert_eq!(b.count("hits"), 0);
    assert!(b.access("reads").contains(why), "{}", b.json);
    assert_eq!(
        b.json["remote"]["notes"].as_array().unwrap().len(),
        1,
        "{}",
        b.json
    );
    assert_eq!(
        b.count("skipped"),
        2,
        "after the first failure the server is not asked again"
    );
    assert!(b.stderr.contains("goes on locally"), "{}", b.stderr);
    assert_eq!(outputs(&dir), local_outputs(&format!("{tag}-local"), 0));
}

/// Entries that are no records: each rejected, every product baked locally.
pub fn rejects_garbage(s: &dyn CacheServer, tag: &str) {
    let (dir, m) = runner(tag, 0);
    let b = bake_via(&dir, &m, &s.url(Location::Garbage));
    b.all("built");
    assert_eq!((b.count("hits"), b.count("rejected")), (0, 3), "{}", b.json);
    assert!(b.stderr.contains("not an ActionResult"), "{}", b.stderr);
    assert_eq!(outputs(&dir), local_outputs(&format!("{tag}-local"), 0));
}

/// A read-only location: hits read, new products baked and not uploaded, the bake succeeds.
pub fn read_only(s: &dyn CacheServer, tag: &str) {
    let cold = populate(s, &format!("{tag}-fill"), 0);
    let (b_dir, b_m) = runner(&format!("{tag}-hit"), 0);
    let b = bake_via(&b_dir, &b_m, &s.url(Location::ReadOnly));
    b.all("cached");
    assert_eq!(outputs(&b_dir), cold);

    let (c_dir, c_m) = runner(&format!("{tag}-new"), 1);
    let c = bake_via(&c_dir, &c_m, &s.url(Location::ReadOnly));
    c.all("built");
    assert_eq!(
        (c.count("misses"), c.count("uploaded")),
        (3, 0),
        "{}",
        c.json
    );
    assert!(c.access("writes").contains("403"), "{}", c.json);
    assert!(c.stderr.contains("read-only"), "{}", c.stderr);
    assert_eq!(c.access("reads"), "on");
}

/// A stored blob whose bytes no longer match its key: detected, never used, baked locally, and
/// the upload of the local bake repairs the server's copy.
pub fn corrupt_blob(s: &dyn CacheServer, tag: &str) {
    let cold = populate(s, &format!("{tag}-fill"), 0);
    let (_, duck) = cold.iter().find(|(n, _)| n == "duck.otb").unwrap();
    let cas = format!("cas/{}", sha256_hex(duck));
    let mut bad = s.stored(&cas).expect("the duck's blob is on the server");
    assert_eq!(&bad, duck);
    let mid = bad.len() / 2;
    bad[mid] ^= 0x40;
    s.overwrite(&cas, &bad);

    let (b_dir, b_m) = runner(&format!("{tag}-read"), 0);
    let b = bake_via(&b_dir, &b_m, &s.url(Location::Cache));
    for (name, status, detail) in b.products() {
        let want = if name == "duck" { "built" } else { "cached" };
        assert_eq!(status, want, "{name}: {detail}");
    }
    assert_eq!((b.count("hits"), b.count("rejected")), (2, 1), "{}", b.json);
    assert!(b.stderr.contains("corrupt"), "{}", b.stderr);
    assert_eq!(outputs(&b_dir), cold, "nothing corrupt was written");
    assert_eq!(
        s.stored(&cas).as_deref(),
        Some(&duck[..]),
        "the upload repaired it"
    );
}

/// A URL nothing listens on.
pub fn dead_url() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = l.local_addr().unwrap().port();
    drop(l);
    format!("http://127.0.0.1:{port}/")
}

/// A slow location: the client's timeout ends the wait and the bake goes on locally.
pub fn slow(s: &dyn CacheServer, tag: &str) {
    populate(s, &format!("{tag}-fill"), 0);
    falls_back(&s.url(Location::Slow), tag, "timed out");
}
