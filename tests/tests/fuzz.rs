//! The runtime is unbreakable: the fuzz corpus replays without panics, and a short fuzzing campaign
//! (the same one `otbake-fuzz` runs for hours) finds nothing. `OTBAKE_WRITE_FUZZ_CORPUS=1` rewrites the
//! corpus from small real bakes plus synthetic 1D/3D/4D archives.

use otbake_formats::storage::{Precision, Storage};
use otbake_formats::{proxy::Proxy as ProxyData, tree, write, Wrap};
use otbake_tests::fuzz::{exercise, mutate, Rng};
use otbake_tests::{fuzz_corpus, otbake_ok, repo_root, scratch, shared_data, write_manifest};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

fn corpus_dir() -> std::path::PathBuf {
    repo_root().join("tests/fuzz/corpus")
}

fn synthetic(dir: &Path, dim: usize, n: usize, k: usize, color: bool, storage: Storage) {
    synthetic_in(dir, dim, n, k, color, storage, Wrap::Clamp)
}

/// Synthetic archives; periodic ones hold proxy points in [0,1) and maps of lifts `p + δ`,
/// `|δ| <= ½`, as the baker writes them.
fn synthetic_in(
    dir: &Path,
    dim: usize,
    n: usize,
    k: usize,
    color: bool,
    storage: Storage,
    wrap: Wrap,
) {
    std::fs::create_dir_all(dir).unwrap();
    let mut rng = Rng(dim as u64 * 100 + n as u64);
    let depth = tree::depth(n as u32, 2);
    let nodes = tree::node_count(depth) as usize;
    let unit = |rng: &mut Rng| (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
    let proxy: Vec<f32> = (0..n * dim).map(|_| unit(&mut rng)).collect();
    let mut boxes = vec![0.0; nodes * 2 * dim];
    tree::fill_node_boxes(&proxy, dim, depth, &mut boxes);
    let key = [dim as u8; 32];
    let p = write::encode_proxy(&ProxyData {
        dim: dim as u32,
        n: n as u32,
        leaf_size: 2,
        depth,
        key,
        wrap: wrap as u32,
        description: "fuzz",
        positions: &proxy,
        node_boxes: &boxes,
    })
    .unwrap();
    std::fs::write(dir.join("proxy.otb"), &p).unwrap();
    for m in 0..k {
        let pos: Vec<f32> = (0..n * dim)
            .map(|i| match wrap {
                Wrap::Clamp => unit(&mut rng),
                Wrap::Periodic => proxy[i] + unit(&mut rng) - 0.5,
            })
            .collect();
        let colors: Vec<f32> = if color {
            (0..n * 3).map(|_| unit(&mut rng)).collect()
        } else {
            vec![]
        };
        // Spacings over three decades, so adaptive queries see every bandwidth regime.
        let spacings: Vec<f32> = (0..n)
            .map(|_| 10f32.powf(-3.0 + 3.0 * unit(&mut rng)))
            .collect();
        let bytes = write::encode_map_content(
            &write::MapContent {
                dim: dim as u32,
                depth,
                proxy_key: key,
                key: [m as u8; 32],
                composite: (m % 3) as u32,
                mean_mass: 0.3,
                wrap,
                positions: &pos,
                colors: &colors,
                spacings: &spacings,
                solver_report: "fuzz",
                transport_cost: 0.0,
            },
            storage,
        )
        .unwrap();
        std::fs::write(dir.join(format!("m{m}.otb")), &bytes).unwrap();
    }
}

#[test]
fn write_corpus_when_asked() {
    if std::env::var_os("OTBAKE_WRITE_FUZZ_CORPUS").is_none() {
        return;
    }
    let corpus = corpus_dir();
    let _ = std::fs::remove_dir_all(&corpus);
    // Real bakes: ink shapes (exact) and a luminance EXR-free color image proxy (sliced).
    let dir = scratch("fuzz-corpus");
    let data = shared_data();
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"gaussian\"\nsamples = 40\nleaf_size = 2\n[solver]\nkind = \"exact\"\n\
         [[input]]\nname = \"duck\"\npath = \"{}\"\ndensity = \"inverted\"\n[[input]]\nname = \"heart\"\npath = \"{}\"\ndensity = \"inverted\"\n",
        data.join("shapes/duck.png").display(),
        data.join("shapes/heart.png").display()
    );
    write_manifest(&dir, "m.toml", &body);
    otbake_ok(&dir, &["bake", "m.toml"]);
    let real = corpus.join("shapes-2d");
    std::fs::create_dir_all(&real).unwrap();
    for f in ["proxy", "duck", "heart"] {
        std::fs::copy(
            dir.join(format!("out/{f}.otb")),
            real.join(format!("{f}.otb")),
        )
        .unwrap();
    }
    // The same bake stored compact.
    write_manifest(
        &dir,
        "m.toml",
        &format!("{body}[storage]\npreset = \"compact\"\n"),
    );
    otbake_ok(&dir, &["bake", "m.toml"]);
    let real = corpus.join("shapes-2d-compact");
    std::fs::create_dir_all(&real).unwrap();
    for f in ["proxy", "duck", "heart"] {
        std::fs::copy(
            dir.join(format!("out/{f}.otb")),
            real.join(format!("{f}.otb")),
        )
        .unwrap();
    }
    synthetic(&corpus.join("synthetic-1d"), 1, 17, 2, true, Storage::FULL);
    synthetic(&corpus.join("synthetic-3d"), 3, 33, 3, false, Storage::FULL);
    synthetic(&corpus.join("synthetic-4d"), 4, 9, 1, true, Storage::FULL);
    // Quantized storage: every code path of the decoders (u8 and u16 positions and colors, u16
    // boxes, missing node color sums, a single-leaf tree decoding on `bounds`).
    synthetic(&corpus.join("compact-2d"), 2, 45, 2, true, Storage::COMPACT);
    synthetic(
        &corpus.join("u16-3d"),
        3,
        29,
        2,
        true,
        Storage {
            positions: Precision::U16,
            node_boxes: Precision::F32,
            colors: Some(Precision::U16),
            node_colors: false,
            spacings: true,
        },
    );
    synthetic(
        &corpus.join("compact-1leaf-2d"),
        2,
        2,
        2,
        true,
        Storage::COMPACT,
    );
    // Periodic (format 3): a real bake of two tileable textures on a uniform proxy, and synthetic
    // lifts in 1D (full) and 2D (compact).
    let body = format!(
        "[output]\ndir = \"out\"\n[proxy]\nkind = \"uniform\"\nsamples = 40\nleaf_size = 2\n[solver]\nkind = \"exact\"\n\
         [[input]]\nname = \"onyx\"\npath = \"{}\"\nwrap = \"periodic\"\n[[input]]\nname = \"pebbles\"\npath = \"{}\"\nwrap = \"periodic\"\n",
        data.join("textures/marble_onyx003_ambientcg_1k.jpg").display(),
        data.join("textures/pebbles_stonewall_godot.png").display()
    );
    write_manifest(&dir, "m.toml", &body);
    otbake_ok(&dir, &["bake", "m.toml"]);
    let real = corpus.join("textures-periodic");
    std::fs::create_dir_all(&real).unwrap();
    for f in ["proxy", "onyx", "pebbles"] {
        std::fs::copy(
            dir.join(format!("out/{f}.otb")),
            real.join(format!("{f}.otb")),
        )
        .unwrap();
    }
    synthetic_in(
        &corpus.join("periodic-1d"),
        1,
        23,
        2,
        true,
        Storage::FULL,
        Wrap::Periodic,
    );
    synthetic_in(
        &corpus.join("periodic-compact-2d"),
        2,
        41,
        3,
        true,
        Storage::COMPACT,
        Wrap::Periodic,
    );
}

#[test]
fn corpus_replays_without_panics() {
    let corpus = fuzz_corpus(&corpus_dir());
    assert!(corpus.len() >= 4);
    for (i, case) in corpus.iter().enumerate() {
        let refs: Vec<&[u8]> = case.maps.iter().map(|m| m.as_slice()).collect();
        // Unmutated corpus entries open and answer queries.
        let opened = exercise(&mut Rng(i as u64), &case.proxy, &refs);
        assert_eq!(opened, 2, "corpus entry {i} does not open");
    }
}

#[test]
fn short_fuzz_campaign_finds_nothing() {
    let corpus = fuzz_corpus(&corpus_dir());
    let mut rng = Rng(0xF022);
    let mut still_opened = 0;
    for i in 0..20_000 {
        let case = &corpus[rng.below(corpus.len())];
        let mut proxy = case.proxy.clone();
        let mut maps = case.maps.clone();
        let kind = if rng.below(3) == 0 {
            mutate(&mut rng, &mut proxy, otbake_formats::ArchiveKind::Proxy);
            "proxy"
        } else {
            let m = rng.below(maps.len());
            mutate(&mut rng, &mut maps[m], otbake_formats::ArchiveKind::Map);
            "map"
        };
        let mut q = Rng(rng.next_u64());
        let refs: Vec<&[u8]> = maps.iter().map(|m| m.as_slice()).collect();
        let r = catch_unwind(AssertUnwindSafe(|| exercise(&mut q, &proxy, &refs)));
        assert!(
            r.is_ok(),
            "iteration {i}: a mutated {kind} made the runtime panic"
        );
        still_opened += (r.unwrap() == 2) as usize;
    }
    // The mutations are not all rejected at the checksum: queries really ran on damaged data.
    assert!(
        still_opened > 2000,
        "only {still_opened} mutated sets opened"
    );
}
