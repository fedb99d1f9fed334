//! No input breaks a decoder or the runtime: every fuzz target's corpus replays without panics, and
//! a short campaign of each (the ones `otbake-fuzz` runs for hours) finds nothing.
//! `OTBAKE_WRITE_FUZZ_CORPUS=1` rewrites the corpus: the archives from small real bakes plus
//! synthetic 1D/3D/4D archives, the decoders' seeds from small real files and edge cases.

use otbake_formats::storage::{Precision, Storage};
use otbake_formats::{proxy::Proxy as ProxyData, tree, write, Wrap};
use otbake_tests::fuzz::{self as fuzzer, exercise, mutate, Config, Rng};
use otbake_tests::{fuzz_corpus, otbake_ok, repo_root, scratch, shared_data, write_manifest};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

fn corpus_dir() -> std::path::PathBuf {
    repo_root().join("tests/fuzz/corpus")
}

fn archive_dir() -> std::path::PathBuf {
    corpus_dir().join("archive")
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
    let corpus = archive_dir();
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
    let corpus = fuzz_corpus(&archive_dir());
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
    let corpus = fuzz_corpus(&archive_dir());
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

/// The decoder targets' seeds, from small real files of ../shared/data (cut or cropped) and
/// hand-made edge cases. Rewrites `tests/fuzz/corpus/{manifest,mesh,vol,merl,cornell,image}/`.
#[test]
fn write_decoder_corpus_when_asked() {
    if std::env::var_os("OTBAKE_WRITE_FUZZ_CORPUS").is_none() {
        return;
    }
    let data = shared_data();
    let corpus = corpus_dir();
    let dir = |name: &str| {
        let d = corpus.join(name);
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    };
    let put = |d: &Path, name: &str, bytes: &[u8]| std::fs::write(d.join(name), bytes).unwrap();

    // Manifests: the repository's, input paths renamed to the files the target makes.
    let d = dir("manifest");
    let rename = |line: &str| -> String {
        let Some(start) = line.find("path = \"") else {
            return line.to_string();
        };
        let rest = &line[start + 8..];
        let Some(end) = rest.find('"') else {
            return line.to_string();
        };
        let ext = rest[..end].rsplit('.').next().unwrap_or("");
        let local = match ext {
            "png" => "a.png",
            "jpg" | "jpeg" => "c.jpg",
            "exr" => "d.exr",
            "vol" => "e.vol",
            "obj" => "f.obj",
            "brdf" => "h.brdf",
            "binary" => "i.binary",
            _ => return line.to_string(),
        };
        format!("{}path = \"{local}\"{}", &line[..start], &rest[end + 1..])
    };
    let mut manifests: Vec<_> = std::fs::read_dir(repo_root().join("manifests"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    manifests.sort();
    for p in manifests {
        let text = std::fs::read_to_string(&p).unwrap();
        let out: Vec<String> = text.lines().map(rename).collect();
        put(
            &d,
            p.file_name().unwrap().to_str().unwrap(),
            (out.join("\n") + "\n").as_bytes(),
        );
    }
    for (name, text) in [
        ("edge-empty.toml", ""),
        ("edge-only-input.toml", "[[input]]\nname = \"a\"\npath = \"a.png\"\n"),
        (
            "edge-minimal.toml",
            "[output]\ndir = \"o\"\n[proxy]\nkind = \"gaussian\"\nsamples = 1\n[[input]]\nname = \"a\"\npath = \"a.png\"\n",
        ),
        (
            "edge-every-kind.toml",
            "[output]\ndir = \"o\"\n[proxy]\nkind = \"uniform\"\nsamples = 16\nleaf_size = 1\n[solver]\nkind = \"sliced\"\n\
             [mesh]\nresolution = 2\nmargin = 0.45\nfit = \"common\"\n[volume]\nfit = \"pad\"\n[brdf]\nresolution = 1024\n\
             [[input]]\nname = \"v\"\npath = \"e.vol\"\n[[input]]\nname = \"m\"\npath = \"f.obj\"\n[[input]]\nname = \"n\"\npath = \"g.obj\"\n\
             [limits]\nmemory = \"1.5GiB\"\n[storage]\npreset = \"compact\"\n",
        ),
        (
            "edge-brdfs.toml",
            "[output]\ndir = \"o\"\n[proxy]\nkind = \"input\"\ninput = \"b\"\nsamples = { resolution = 64 }\n\
             [[input]]\nname = \"b\"\npath = \"h.brdf\"\n[[input]]\nname = \"c\"\npath = \"i.binary\"\nseed = 18446744073709551615\n",
        ),
        (
            "edge-barycenter.toml",
            "[output]\ndir = \"o\"\n[proxy]\nkind = \"barycenter\"\nsamples = 100\nweights = [0.5, 0.5]\niterations = 1\n\
             [solver]\nkind = \"sinkhorn\"\n[[input]]\nname = \"x\"\npath = \"a.png\"\ndensity = \"inverted\"\nwrap = \"periodic\"\n\
             [[input]]\nname = \"y\"\npath = \"b.png\"\ndensity = \"alpha\"\nwrap = \"periodic\"\n",
        ),
        (
            "edge-unicode.toml",
            "# ünïcødé ✓\n[output]\ndir = \"ö/ü\"\n[proxy]\nkind = \"spiral\"\nsamples = 2000\nturns = 1e30\nthickness = 0.1\n\
             [[input]]\nname = \"日本\"\npath = \"c.jpg\"\n",
        ),
        (
            "edge-inline.toml",
            "output = { dir = \"o\" }\nproxy = { kind = \"gaussian\", samples = 10, sigma = 1e-300 }\ninput = [ { name = \"a\", path = \"d.exr\" } ]\n",
        ),
    ] {
        put(&d, name, text.as_bytes());
    }

    // Meshes: a real one whole (Suzanne, 500 faces) and hand-made edge cases.
    let d = dir("mesh");
    put(
        &d,
        "suzanne.obj",
        &std::fs::read(data.join("meshes/suzanne.obj")).unwrap(),
    );
    let tet = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let cube = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    for (name, text) in [
        ("tetrahedron.obj", tet.to_string()),
        ("cube-quads.obj", cube.to_string()),
        ("cube-open.obj", cube.lines().take(13).collect::<Vec<_>>().join("\n")),
        (
            "negative-indices.obj",
            "o a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n".into(),
        ),
        (
            "full-indices.obj",
            "mtllib x.mtl\ng g1\nusemtl m\ns 1\nv 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n\
             f 1/1/1 3/3/1 2/2/1\nf 1//1 2//1 4//1\nf 1/1 4/2 3/3\nf 2 3 4\n"
                .into(),
        ),
        (
            "degenerate-and-short.obj",
            format!("{tet}f 1 1 2\nf 1 2\nf 3\nl 1 2\np 1\nv 0.5 0 0\nf 1 2 5\n"),
        ),
        ("crlf-comments.obj", tet.replace('\n', " # c\r\n")),
        ("two-objects.obj", format!("o one\n{tet}o two\nv 5 5 5\nv 6 5 5\nv 5 6 5\nv 5 5 6\nf 5 7 6\nf 5 6 8\nf 5 8 7\nf 6 7 8\n")),
        ("flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n".into()),
    ] {
        put(&d, name, text.as_bytes());
    }

    // Volumes: crops of the real smoke grid, hand-made edge cases.
    let d = dir("vol");
    let smoke =
        otbake::input::vol::VolFile::read(&data.join("volumes/smoke_44x45x53.vol")).unwrap();
    let crop = |lo: [usize; 3], size: [usize; 3]| {
        let [nx, ny, _] = smoke.dims;
        let mut values = Vec::new();
        for z in lo[2]..lo[2] + size[2] {
            for y in lo[1]..lo[1] + size[1] {
                for x in lo[0]..lo[0] + size[0] {
                    values.push(smoke.data[(z * ny + y) * nx + x]);
                }
            }
        }
        let mut v = otbake::input::vol::VolFile::density(size, values);
        v.bbox = [
            0.0,
            0.0,
            0.0,
            size[0] as f32,
            size[1] as f32,
            size[2] as f32,
        ];
        v.to_bytes()
    };
    put(&d, "smoke-8.vol", &crop([18, 18, 22], [8, 8, 8]));
    put(&d, "smoke-12x6x9.vol", &crop([10, 20, 5], [12, 6, 9]));
    let vol = |dims: [usize; 3], channels: usize, bbox: [f32; 6], data: Vec<f32>| {
        otbake::input::vol::VolFile {
            dims,
            channels,
            bbox,
            data,
        }
        .to_bytes()
    };
    put(
        &d,
        "one-cell.vol",
        &vol([1, 1, 1], 1, [0., 0., 0., 1., 1., 1.], vec![1.0]),
    );
    put(
        &d,
        "two-channels.vol",
        &vol(
            [2, 1, 2],
            2,
            [0., 0., 0., 1., 1., 1.],
            (0..8).map(|i| i as f32).collect(),
        ),
    );
    put(
        &d,
        "sdf-negative.vol",
        &vol(
            [3, 3, 3],
            1,
            [-1., -1., -1., 1., 1., 1.],
            (0..27).map(|i| i as f32 - 13.0).collect(),
        ),
    );
    put(
        &d,
        "flat-box-pad.vol",
        &vol([4, 2, 1], 1, [0., 0., 0., 4., 2., 1e-30], vec![0.5; 8]),
    );
    put(
        &d,
        "all-zero.vol",
        &vol([2, 2, 2], 1, [0.; 6], vec![0.0; 8]),
    );
    put(&d, "header-only.vol", &crop([0, 0, 0], [1, 1, 1])[..48]);

    // MERL: small seeds (a full file is 35 MB; the target tabulates one when it starts).
    let d = dir("merl");
    let header: Vec<u8> = [90i32, 90, 180]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    put(&d, "header.binary", &header);
    let mut short = header.clone();
    for i in 0..64 {
        short.extend_from_slice(&(f64::from(i) * 0.01).to_le_bytes());
    }
    put(&d, "truncated.binary", &short);
    let wrong: Vec<u8> = [90i32, 90, 360]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    put(&d, "wrong-dims.binary", &wrong);
    put(&d, "short-header.binary", &header[..11]);
    put(&d, "empty.binary", b"");

    // Cornell: the real files cut after a few records, and edge cases.
    let d = dir("cornell");
    for (name, records) in [
        ("cayman", 3),
        ("garnet_red", 12),
        ("acryl_blue", 40),
        ("krylon_blue", 1),
    ] {
        let text =
            std::fs::read_to_string(data.join(format!("brdfs/cornell_{name}.brdf"))).unwrap();
        let mut out = Vec::new();
        let mut seen = 0;
        let mut in_records = false;
        for line in text.lines() {
            let numbers = line
                .split_whitespace()
                .filter(|t| t.parse::<f64>().is_ok())
                .count();
            if numbers == 35 {
                in_records = true;
                seen += 1;
                if seen > records {
                    break;
                }
            }
            if !in_records || numbers == 35 || line.starts_with('#') {
                out.push(line);
            }
        }
        put(
            &d,
            &format!("{name}-{records}.brdf"),
            (out.join("\n") + "\n").as_bytes(),
        );
    }
    let wl: Vec<String> = (0..31).map(|i| (400 + 10 * i).to_string()).collect();
    let spectrum = vec!["0.25"; 31].join(" ");
    put(
        &d,
        "edge-one-line-header.brdf",
        format!("31 {}\n0 0 0 0 {spectrum}\n", wl.join(" ")).as_bytes(),
    );
    put(
        &d,
        "edge-horizon.brdf",
        format!(
            "31\n{}\n1.5717963 -3.14159 1.5707963 6.2831853 {spectrum} # at and past pi/2\n",
            wl.join("\n")
        )
        .as_bytes(),
    );
    put(
        &d,
        "edge-no-records.brdf",
        format!("31\n{}\n", wl.join(" ")).as_bytes(),
    );

    // Images: the real shapes, small crops of the real textures in every PNG colour type and
    // depth, a JPEG, and EXRs of every compression and layout.
    let d = dir("image");
    for s in ["duck", "heart", "redcross", "tooth"] {
        put(
            &d,
            &format!("{s}.png"),
            &std::fs::read(data.join(format!("shapes/{s}.png"))).unwrap(),
        );
    }
    let texture = |name: &str| image::open(data.join("textures").join(name)).unwrap();
    let crop = |img: &image::DynamicImage, size: u32| {
        img.crop_imm(img.width() / 3, img.height() / 3, size, size)
    };
    let save = |img: image::DynamicImage, name: &str| {
        let mut bytes = std::io::Cursor::new(Vec::new());
        let format = if name.ends_with(".jpg") {
            image::ImageFormat::Jpeg
        } else {
            image::ImageFormat::Png
        };
        img.write_to(&mut bytes, format).unwrap();
        put(&d, name, bytes.get_ref());
    };
    let leaves = crop(&texture("leaves_branch_cutout_rgba.png"), 24);
    let slate = crop(&texture("marble_slate_texturecan240_gray.png"), 24);
    let pebbles = crop(&texture("pebbles_stonewall_godot.png"), 24);
    save(
        image::DynamicImage::ImageRgba8(leaves.to_rgba8()),
        "leaves-rgba8.png",
    );
    save(
        image::DynamicImage::ImageRgba16(leaves.to_rgba16()),
        "leaves-rgba16.png",
    );
    save(
        image::DynamicImage::ImageLumaA8(leaves.to_luma_alpha8()),
        "leaves-graya8.png",
    );
    save(
        image::DynamicImage::ImageLuma8(slate.to_luma8()),
        "slate-gray8.png",
    );
    save(
        image::DynamicImage::ImageLuma16(slate.to_luma16()),
        "slate-gray16.png",
    );
    save(
        image::DynamicImage::ImageRgb8(pebbles.to_rgb8()),
        "pebbles-rgb8.png",
    );
    save(
        image::DynamicImage::ImageRgb16(pebbles.to_rgb16()),
        "pebbles-rgb16.png",
    );
    save(
        image::DynamicImage::ImageRgb8(
            crop(&texture("marble_onyx003_ambientcg_1k.jpg"), 16).to_rgb8(),
        ),
        "onyx.jpg",
    );
    // Palette and 1-bit images, which only the png crate writes.
    let mut palette = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut palette, 16, 16);
        enc.set_color(png::ColorType::Indexed);
        enc.set_depth(png::BitDepth::Four);
        enc.set_palette(vec![0, 0, 0, 255, 0, 0, 0, 255, 0, 255, 255, 255]);
        enc.set_trns(vec![255, 128, 0]);
        let mut w = enc.write_header().unwrap();
        let rgb = pebbles.to_rgb8();
        let rgb = &rgb;
        let rows: Vec<u8> = (0..16)
            .flat_map(|y| {
                (0..8).map(move |x| {
                    let v = |x: u32| (rgb.get_pixel(x, y).0[0] / 64).min(3);
                    (v(2 * x) << 4) | v(2 * x + 1)
                })
            })
            .collect();
        w.write_image_data(&rows).unwrap();
    }
    put(&d, "pebbles-palette4.png", &palette);
    let mut bits = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bits, 16, 8);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::One);
        let mut w = enc.write_header().unwrap();
        let luma = slate.to_luma8();
        let rows: Vec<u8> = (0..8)
            .flat_map(|y| {
                let luma = &luma;
                (0..2).map(move |b| {
                    (0..8).fold(0u8, |acc, i| {
                        acc << 1 | u8::from(luma.get_pixel(8 * b + i, y).0[0] > 128)
                    })
                })
            })
            .collect();
        w.write_image_data(&rows).unwrap();
    }
    put(&d, "slate-1bit.png", &bits);
    // EXRs: linear crops of pebbles, in several compressions, f16 and f32, scan lines and tiles.
    use exr::prelude::*;
    let rgba = pebbles.to_rgba32f();
    let pixel = |p: Vec2<usize>| {
        let v = rgba.get_pixel(p.x() as u32 % 24, p.y() as u32 % 24).0;
        (v[0], v[1], v[2], v[3])
    };
    for (name, size, compression, blocks, half) in [
        (
            "pebbles-none-f32.exr",
            (12, 10),
            Compression::Uncompressed,
            Blocks::ScanLines,
            false,
        ),
        (
            "pebbles-zip-f16.exr",
            (16, 16),
            Compression::ZIP16,
            Blocks::ScanLines,
            true,
        ),
        (
            "pebbles-rle-f32.exr",
            (9, 7),
            Compression::RLE,
            Blocks::ScanLines,
            false,
        ),
        (
            "pebbles-piz-f16.exr",
            (8, 8),
            Compression::PIZ,
            Blocks::ScanLines,
            true,
        ),
        (
            "pebbles-tiles-f32.exr",
            (20, 12),
            Compression::ZIP1,
            Blocks::Tiles(Vec2(8, 8)),
            false,
        ),
    ] {
        let path = scratch("fuzz-corpus-exr").join(name);
        let encoding = Encoding {
            compression,
            blocks,
            line_order: LineOrder::Increasing,
        };
        let attributes = LayerAttributes::named("main");
        if half {
            let layer = Layer::new(
                size,
                attributes,
                encoding,
                SpecificChannels::rgba(|p: Vec2<usize>| {
                    let (r, g, b, a) = pixel(p);
                    (
                        f16::from_f32(r),
                        f16::from_f32(g),
                        f16::from_f32(b),
                        f16::from_f32(a),
                    )
                }),
            );
            Image::from_layer(layer).write().to_file(&path).unwrap();
        } else {
            let layer = Layer::new(size, attributes, encoding, SpecificChannels::rgba(pixel));
            Image::from_layer(layer).write().to_file(&path).unwrap();
        }
        put(&d, name, &std::fs::read(&path).unwrap());
    }
    // A grey EXR (a Y channel, no RGB): refused with the channel message.
    let path = scratch("fuzz-corpus-exr").join("y.exr");
    let y: Vec<f32> = (0..64).map(|i| i as f32 / 64.0).collect();
    let mut list = SmallVec::new();
    list.push(AnyChannel::new("Y", FlatSamples::F32(y)));
    let channels = AnyChannels::sort(list);
    Image::from_channels((8, 8), channels)
        .write()
        .to_file(&path)
        .unwrap();
    put(&d, "grey-y.exr", &std::fs::read(&path).unwrap());
}

/// Executions of each decoder target's CI campaign: together about 10 s of CPU in a dev build
/// (FUZZING.md has the long campaigns).
const CI_EXECUTIONS: [(&str, u64); 7] = [
    ("manifest", 24_000),
    ("mesh", 12_000),
    ("vol", 32_000),
    ("merl", 12_000),
    ("cornell", 20_000),
    ("image", 16_000),
    ("capi", 24_000),
];

#[test]
fn every_target_replays_its_seeds_and_accepts_some() {
    for target in fuzzer::targets() {
        let seeds = target.seeds(&corpus_dir());
        assert!(!seeds.is_empty(), "{}: no seeds", target.name());
        let scratch = fuzzer::Scratch::new(&format!("replay-{}", target.name()));
        let accepted = seeds
            .iter()
            .enumerate()
            .filter(|(i, case)| target.execute(&mut Rng(*i as u64), case, &scratch))
            .count();
        assert!(accepted > 0, "{}: no seed is accepted", target.name());
    }
}

#[test]
fn short_campaign_of_every_decoder_finds_nothing() {
    let findings = scratch("fuzz-findings");
    for (name, executions) in CI_EXECUTIONS {
        let target = fuzzer::target(name).unwrap();
        let corpus = target.seeds(&corpus_dir());
        let config = Config {
            first: 0,
            iterations: executions,
            seed: 0xC1,
            // No watchdog in tests: a hang shows as a test that does not end.
            timeout: None,
            findings: findings.clone(),
            progress: None,
            report_every: 0,
            memory_cap: None,
        };
        let s = fuzzer::run(target.as_ref(), &corpus, &config);
        assert!(
            s.findings.is_empty(),
            "{name}: {} findings, inputs in {}",
            s.findings.len(),
            findings.display()
        );
        // Mutated inputs get through: some are accepted, most are refused somewhere.
        // MERL inputs are accepted only at full size (one execution in 20 000).
        let least = if name == "merl" { 0 } else { executions / 100 };
        assert!(
            s.accepted >= least && s.accepted < executions,
            "{name}: {} of {executions} accepted",
            s.accepted
        );
    }
}

/// The memory cap is a finding with its input, not an abort: a campaign whose cap is below what
/// decoding a seed needs stops at once, writes the input and exits 70.
#[test]
fn an_execution_past_the_memory_cap_is_a_finding_with_its_input() {
    let dir = scratch("fuzz-cap");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_otbake-fuzz"))
        .args([
            "--target",
            "image",
            "--memory-cap",
            "4096",
            "--seed",
            "3",
            "200",
        ])
        .env("OTBAKE_FUZZ_FINDINGS", &dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(70), "{err}");
    assert!(err.contains("out of memory budget"), "{err}");
    let finding = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .next()
        .unwrap()
        .path();
    let reason = std::fs::read_to_string(finding.join("reason.txt")).unwrap();
    assert!(
        reason.contains("past the cap of") && reason.contains("--replay"),
        "{reason}"
    );
    assert!(
        std::fs::read_dir(&finding).unwrap().count() >= 2,
        "the input is written"
    );
}
