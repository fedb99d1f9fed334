//! Writes the queries and the answers of the Rust runtime that the C test (`c/*.c`) repeats
//! through the C ABI and compares bit for bit.
//!
//! Usage: `c_expected OUT BLEND_PROXY BLEND_MAP... -- BRDF_PROXY BRDF_MAP...`
//!
//! Every number is written as the hex of its bits (`f32` as 8 digits, `f64` as 16), so the C side
//! compares bits, not decimal renderings. One record per line: a tag, the query's arguments, `=`,
//! the answer. `blend` and `brdf` lines open the archives the following records query; `weights`
//! lines set the weights of the records after them. A `prepared` line starts the records of the
//! blend prepared for those weights (`Blend::prepare`, then `Prepared`'s queries), `pend` ends them.

use otbake_brdf::{BrdfBlend, BrdfKernel, DEFAULT_ADAPTIVE};
use otbake_runtime::{
    AdaptiveKernel, Blend, Kernel, Map, PointValue, Prepared, Proxy, Region, SplatTarget,
};
use rkyv::util::AlignedVec;
use std::fmt::Write as _;
use std::path::Path;

/// A tiny deterministic generator (SplitMix64): the queries are the same on every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn unit64(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `f32` bits as 8 hex digits.
fn h(x: f32) -> String {
    format!("{:08x}", x.to_bits())
}

/// `f64` bits as 16 hex digits.
fn hd(x: f64) -> String {
    format!("{:016x}", x.to_bits())
}

/// Joins hex renderings with spaces.
fn hs(xs: &[f32]) -> String {
    xs.iter().map(|&x| h(x)).collect::<Vec<_>>().join(" ")
}

/// Joins `f64` hex renderings with spaces.
fn hds(xs: &[f64]) -> String {
    xs.iter().map(|&x| hd(x)).collect::<Vec<_>>().join(" ")
}

/// Reads a file into 16-byte aligned memory, as the runtime needs.
fn read(path: &str) -> Result<AlignedVec<16>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
    let mut v = AlignedVec::<16>::with_capacity(bytes.len());
    v.extend_from_slice(&bytes);
    Ok(v)
}

/// The weight vectors every blend is queried with: a vertex, the center, a random mix.
fn weight_sets(k: usize, rng: &mut Rng) -> Vec<Vec<f32>> {
    let mut vertex = vec![0.0; k];
    vertex[0] = 1.0;
    let center = vec![1.0 / k as f32; k];
    let raw: Vec<f32> = (0..k).map(|_| rng.unit() + 0.05).collect();
    let sum: f32 = raw.iter().sum();
    let random = raw.iter().map(|w| w / sum).collect();
    vec![vertex, center, random]
}

/// The records of the point-cloud blend: every query kind at every weight vector.
fn blend_records(out: &mut String, blend: &Blend<'_, '_>, rng: &mut Rng) -> Result<(), String> {
    let d = blend.dim();
    let e = |e: otbake_runtime::Error| e.to_string();
    let adaptive = AdaptiveKernel {
        scale: 2.0,
        min_sigma: 0.005,
        max_sigma: 0.1,
    };
    for w in weight_sets(blend.k(), rng) {
        writeln!(out, "weights {} {}", w.len(), hs(&w)).unwrap();
        // One kernel per weight vector, so that the C test can run each section as a batch.
        let sigma = 0.02 + 0.05 * rng.unit();
        for _ in 0..24 {
            let p: Vec<f32> = (0..d).map(|_| rng.unit()).collect();
            let v = blend.point(&w, &p, Kernel { sigma }).map_err(e)?;
            let vv = [v.density, v.mass, v.color[0], v.color[1], v.color[2]];
            writeln!(out, "point {} {} = {}", h(sigma), hs(&p), hs(&vv)).unwrap();
            let a = blend.point_adaptive(&w, &p, adaptive).map_err(e)?;
            let av = [a.density, a.mass, a.color[0], a.color[1], a.color[2]];
            let ak = [adaptive.scale, adaptive.min_sigma, adaptive.max_sigma];
            writeln!(out, "adaptive {} {} = {}", hs(&ak), hs(&p), hs(&av)).unwrap();
            let lo: Vec<f32> = p.iter().map(|x| x - 0.15).collect();
            let hi: Vec<f32> = p.iter().map(|x| x + 0.1 + 0.2 * rng.unit()).collect();
            let r = blend.range(&w, &lo, &hi).map_err(e)?;
            let rv = [r.mass, r.color[0], r.color[1], r.color[2]];
            writeln!(
                out,
                "range {} {} = {} {}",
                hs(&lo),
                hs(&hi),
                r.count,
                hs(&rv)
            )
            .unwrap();
            let index = (rng.next() % u64::from(blend.n())) as u32;
            let s = blend.sample(&w, index).map_err(e)?;
            writeln!(out, "sample {index} = {} {}", hs(&s.position), hs(&s.color)).unwrap();
            let b = blend.bandwidth(&w, index, adaptive).map_err(e)?;
            writeln!(out, "bandwidth {} {index} = {}", hs(&ak), h(b)).unwrap();
        }
        splat_records(out, blend, &w)?;
        prepared_records(out, blend, &w, rng)?;
    }
    Ok(())
}

/// FNV-1a (64 bits) of the bits of `xs`, each `f32` as its four little-endian bytes: what the C
/// test computes over the arrays a prepared handle points at.
fn fnv(xs: &[f32]) -> u64 {
    let mut hash = 0xcbf2_9ce4_8422_2325u64;
    for x in xs {
        for b in x.to_bits().to_le_bytes() {
            hash = (hash ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }
    hash
}

/// The records of the blend prepared for `w`: its buffer size, mean mass and arrays, point,
/// range and sample queries, a point grid, and whole-grid, region and RGBA region splats.
fn prepared_records(
    out: &mut String,
    blend: &Blend<'_, '_>,
    w: &[f32],
    rng: &mut Rng,
) -> Result<(), String> {
    let d = blend.dim();
    let e = |e: otbake_runtime::Error| e.to_string();
    let sizes = blend.prepared_sizes();
    let mut store = vec![0.0f32; sizes.total()];
    let buffers = sizes.split(&mut store).ok_or("sized by total")?;
    let p: Prepared<'_> = blend.prepare(w, buffers).map_err(e)?;
    writeln!(
        out,
        "prepared {} {} {} {:016x} {} {:016x}",
        sizes.total(),
        h(p.mean_mass()),
        p.positions().len(),
        fnv(p.positions()),
        p.colors().len(),
        fnv(p.colors())
    )
    .unwrap();
    let sigma = 0.02 + 0.05 * rng.unit();
    for _ in 0..24 {
        let q: Vec<f32> = (0..d).map(|_| rng.unit()).collect();
        let v = p.point(&q, Kernel { sigma }).map_err(e)?;
        let vv = [v.density, v.mass, v.color[0], v.color[1], v.color[2]];
        writeln!(out, "ppoint {} {} = {}", h(sigma), hs(&q), hs(&vv)).unwrap();
        let lo: Vec<f32> = q.iter().map(|x| x - 0.2 * rng.unit()).collect();
        let hi: Vec<f32> = q.iter().map(|x| x + 0.05 + 0.2 * rng.unit()).collect();
        let r = p.range(&lo, &hi).map_err(e)?;
        let rv = [r.mass, r.color[0], r.color[1], r.color[2]];
        writeln!(
            out,
            "prange {} {} = {} {}",
            hs(&lo),
            hs(&hi),
            r.count,
            hs(&rv)
        )
        .unwrap();
        let index = (rng.next() % u64::from(p.n())) as u32;
        let s = p.sample(index).map_err(e)?;
        writeln!(
            out,
            "psample {index} = {} {}",
            hs(&s.position),
            hs(&s.color)
        )
        .unwrap();
    }
    let res = [20u32, 14, 1, 1];
    let kernel = Kernel { sigma: 0.04 };
    // A point grid of an inner box of the grid.
    let mut region = Region::full(res);
    region.start[..2].copy_from_slice(&[3, 2]);
    region.size[..2].copy_from_slice(&[11, 9]);
    let cells = 11 * 9;
    let mut values = vec![PointValue::default(); cells];
    p.point_grid(kernel, region, &mut values).map_err(e)?;
    writeln!(
        out,
        "pgrid {} {} {} 3 2 11 9 {cells}",
        h(kernel.sigma),
        res[0],
        res[1]
    )
    .unwrap();
    for v in &values {
        let vv = [v.density, v.mass, v.color[0], v.color[1], v.color[2]];
        writeln!(out, "cell {}", hs(&vv)).unwrap();
    }
    // The whole grid, planar.
    let all = (res[0] * res[1]) as usize;
    let (mut density, mut color) = (vec![0.0f32; all], vec![0.0f32; 3 * all]);
    p.splat(
        kernel,
        SplatTarget {
            res,
            density: &mut density,
            color: Some(&mut color),
        },
    )
    .map_err(e)?;
    writeln!(
        out,
        "psplat {} {} {} {all}",
        h(kernel.sigma),
        res[0],
        res[1]
    )
    .unwrap();
    for c in 0..all {
        writeln!(
            out,
            "cell {} {}",
            h(density[c]),
            hs(&color[3 * c..3 * c + 3])
        )
        .unwrap();
    }
    // A band of rows, planar and RGBA.
    let band = Region::rows(res, 4, 6);
    let bcells = (res[0] * 6) as usize;
    let (mut density, mut color) = (vec![0.0f32; bcells], vec![0.0f32; 3 * bcells]);
    p.splat_region(kernel, band, &mut density, Some(&mut color))
        .map_err(e)?;
    writeln!(
        out,
        "pregion {} {} {} 4 6 {bcells}",
        h(kernel.sigma),
        res[0],
        res[1]
    )
    .unwrap();
    for c in 0..bcells {
        writeln!(
            out,
            "cell {} {}",
            h(density[c]),
            hs(&color[3 * c..3 * c + 3])
        )
        .unwrap();
    }
    let mut rgba = vec![0.0f32; 4 * bcells];
    p.splat_region_rgba(kernel, band, &mut rgba).map_err(e)?;
    writeln!(
        out,
        "prgba {} {} {} 4 6 {bcells}",
        h(kernel.sigma),
        res[0],
        res[1]
    )
    .unwrap();
    for c in 0..bcells {
        writeln!(out, "cell {}", hs(&rgba[4 * c..4 * c + 4])).unwrap();
    }
    writeln!(out, "pend").unwrap();
    Ok(())
}

/// A whole-grid splat (planar) and an RGBA region splat of a band of it.
fn splat_records(out: &mut String, blend: &Blend<'_, '_>, w: &[f32]) -> Result<(), String> {
    let e = |e: otbake_runtime::Error| e.to_string();
    let res = [24u32, 16, 1, 1];
    let cells = (res[0] * res[1]) as usize;
    let sigma = 0.03f32;
    let mut density = vec![0.0f32; cells];
    let mut color = vec![0.0f32; cells * 3];
    blend
        .splat(
            w,
            Kernel { sigma },
            SplatTarget {
                res,
                density: &mut density,
                color: Some(&mut color),
            },
        )
        .map_err(e)?;
    writeln!(out, "splat {} {} {} {cells}", h(sigma), res[0], res[1]).unwrap();
    for c in 0..cells {
        writeln!(
            out,
            "cell {} {}",
            h(density[c]),
            hs(&color[3 * c..3 * c + 3])
        )
        .unwrap();
    }
    let region = Region::rows(res, 5, 7);
    let rcells = (res[0] * 7) as usize;
    let mut rgba = vec![0.0f32; rcells * 4];
    blend
        .splat_region_rgba(w, Kernel { sigma }, region, &mut rgba)
        .map_err(e)?;
    writeln!(out, "rgba {} {} {} 5 7 {rcells}", h(sigma), res[0], res[1]).unwrap();
    for c in 0..rcells {
        writeln!(out, "cell {}", hs(&rgba[4 * c..4 * c + 4])).unwrap();
    }
    Ok(())
}

/// The records of the BRDF blend: eval, pdf, angles and samples at every weight vector.
fn brdf_records(out: &mut String, brdf: &BrdfBlend<'_, '_>, rng: &mut Rng) -> Result<(), String> {
    let e = |e: otbake_runtime::Error| e.to_string();
    let dir = |rng: &mut Rng| {
        let t = rng.unit64() * 1.5;
        let p = rng.unit64() * std::f64::consts::TAU;
        [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
    };
    for w in weight_sets(brdf.blend.k(), rng) {
        writeln!(out, "weights {} {}", w.len(), hs(&w)).unwrap();
        for _ in 0..16 {
            let (wi, wo) = (dir(rng), dir(rng));
            let f = brdf.eval(&w, wi, wo).map_err(e)?;
            writeln!(out, "eval {} {} = {}", hds(&wi), hds(&wo), hs(&f)).unwrap();
            let pdf = brdf.pdf(&w, wi, wo).map_err(e)?;
            writeln!(out, "pdf {} {} = {}", hds(&wi), hds(&wo), hd(pdf)).unwrap();
            let ang = [rng.unit64() * 1.5, rng.unit64() * 1.5, rng.unit64() * 3.1];
            let v = brdf.eval_angles(&w, ang[0], ang[1], ang[2]).map_err(e)?;
            let vv = [v.rgb[0], v.rgb[1], v.rgb[2], v.luminance, v.density];
            writeln!(out, "angles {} = {}", hds(&ang), hs(&vv)).unwrap();
            let index = (rng.next() % u64::from(brdf.blend.n())) as u32;
            let xi: Vec<f64> = (0..5).map(|_| rng.unit64()).collect();
            let xa = [xi[0], xi[1], xi[2], xi[3], xi[4]];
            let s = brdf.sample(&w, index, xa).map_err(e)?;
            let sv = [s.value[0], s.value[1], s.value[2], s.luminance];
            writeln!(
                out,
                "bsample {index} {} = {} {} {} {}",
                hds(&xi),
                hds(&s.wi),
                hds(&s.wo),
                hd(s.pdf),
                hs(&sv)
            )
            .unwrap();
        }
    }
    Ok(())
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: c_expected OUT BLEND_PROXY BLEND_MAP... -- BRDF_PROXY BRDF_MAP...";
    let split = args.iter().position(|a| a == "--").ok_or(usage)?;
    let (first, second) = (&args[..split], &args[split + 1..]);
    if first.len() < 3 || second.len() < 2 {
        return Err(usage.into());
    }
    let out_path = Path::new(&first[0]);
    let mut rng = Rng(17);
    let mut out = String::new();

    let files = &first[1..];
    let bytes: Vec<AlignedVec<16>> = files.iter().map(|f| read(f)).collect::<Result<_, _>>()?;
    let e = |e: otbake_runtime::Error| e.to_string();
    let proxy = Proxy::open(&bytes[0]).map_err(e)?;
    let maps: Vec<Map<'_>> = bytes[1..]
        .iter()
        .map(|b| Map::open(b))
        .collect::<Result<_, _>>()
        .map_err(e)?;
    let blend = Blend::new(proxy, &maps).map_err(e)?;
    writeln!(out, "blend {} {}", maps.len(), files.join(" ")).unwrap();
    blend_records(&mut out, &blend, &mut rng)?;

    let bytes: Vec<AlignedVec<16>> = second.iter().map(|f| read(f)).collect::<Result<_, _>>()?;
    let proxy = Proxy::open(&bytes[0]).map_err(e)?;
    let maps: Vec<Map<'_>> = bytes[1..]
        .iter()
        .map(|b| Map::open(b))
        .collect::<Result<_, _>>()
        .map_err(e)?;
    for (tag, kernel) in [
        ("adaptive", BrdfKernel::Adaptive(DEFAULT_ADAPTIVE)),
        ("fixed", BrdfKernel::Fixed(Kernel { sigma: 0.05 })),
    ] {
        let brdf = BrdfBlend::with_kernel(proxy, &maps, kernel).map_err(|e| e.to_string())?;
        let params = match kernel {
            BrdfKernel::Adaptive(a) => hs(&[a.scale, a.min_sigma, a.max_sigma]),
            BrdfKernel::Fixed(k) => h(k.sigma),
        };
        writeln!(
            out,
            "brdf {tag} {params} {} {}",
            maps.len(),
            second.join(" ")
        )
        .unwrap();
        brdf_records(&mut out, &brdf, &mut rng)?;
    }

    // Whole or nothing: the C test never reads a half-written file.
    let tmp = out_path.with_extension("tmp");
    std::fs::write(&tmp, out).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, out_path).map_err(|e| format!("{}: {e}", out_path.display()))?;
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("c_expected: {e}");
        std::process::exit(1);
    }
}
