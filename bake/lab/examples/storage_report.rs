//! Sizes and errors of a baked manifest's maps under each storage (the figures of BENCHMARKS.md).
//!
//! ```sh
//! cargo run --release -p otbake-lab --example storage_report -- manifests/onyx-rock-1m.toml
//! ```
//! Bakes the manifest (which must store in full: it is the reference) if needed, then re-encodes
//! every map under each storage with the encoder the baker uses (`encode_map_content`, so sizes are
//! those a bake with that `[storage]` writes), and reports per storage: archive size per map, the
//! stated largest position and color error, the measured largest and mean position error against the
//! full map, and, for the blend of all maps at equal weights, how far whole-grid point queries
//! (`Prepared::point_grid`: a 256² image in 2D, a 64³ grid in 3D) and 2000 range queries move, and
//! the time `Blend::prepare` takes (decoding included) and a `Blend::point` call takes on the fly
//! (decoding per read; 2000 calls at random points, σ as in the grid).

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake::render::Archives;
use otbake_formats::storage::{Precision, Storage};
use otbake_formats::tree;
use otbake_formats::write::{encode_map_content, MapContent};
use otbake_lab::timing::{self, Clock};
use otbake_runtime::{Blend, Kernel, Map, PointValue, Prepared, PreparedBuffers, Proxy, Region};
use rkyv::util::AlignedVec;

/// A map's content in full precision.
struct Content {
    dim: usize,
    depth: u32,
    key: [u8; 32],
    proxy_key: [u8; 32],
    composite: u32,
    mean_mass: f32,
    wrap: otbake_formats::Wrap,
    positions: Vec<f32>,
    colors: Vec<f32>,
    /// Decoded spacings (re-encoding their decoded values keeps the codes).
    spacings: Vec<f32>,
}

fn content(m: &Map<'_>) -> Content {
    let v = m.view();
    let mut positions = vec![0.0f32; m.n() as usize * m.dim()];
    v.for_each_position(|j, x| positions[j] = x);
    let mut colors = vec![0.0f32; if m.has_color() { m.n() as usize * 3 } else { 0 }];
    v.for_each_color(|j, x| colors[j] = x);
    let spacings = if v.has_spacings() {
        (0..m.n() as usize).map(|i| v.spacing(i)).collect()
    } else {
        Vec::new()
    };
    let a = m.archived();
    Content {
        dim: m.dim(),
        depth: m.depth(),
        key: a.key,
        proxy_key: a.proxy_key,
        composite: a.composite.to_native(),
        mean_mass: m.mean_mass(),
        wrap: m.wrap(),
        positions,
        colors,
        spacings,
    }
}

fn encode(c: &Content, s: Storage) -> AlignedVec<16> {
    encode_map_content(
        &MapContent {
            dim: c.dim as u32,
            depth: c.depth,
            proxy_key: c.proxy_key,
            key: c.key,
            composite: c.composite,
            mean_mass: c.mean_mass,
            wrap: c.wrap,
            positions: &c.positions,
            colors: &c.colors,
            spacings: &c.spacings,
            solver_report: "",
            transport_cost: 0.0,
        },
        s,
    )
    .expect("encode")
}

fn buffers(blend: &Blend<'_, '_>) -> [Vec<f32>; 4] {
    let s = blend.prepared_sizes();
    [
        vec![0.0; s.positions],
        vec![0.0; s.colors],
        vec![0.0; s.node_boxes],
        vec![0.0; s.node_colors],
    ]
}

fn prepare<'b>(blend: &Blend<'_, '_>, w: &[f32], b: &'b mut [Vec<f32>; 4]) -> Prepared<'b> {
    let [p, c, nb, nc] = b;
    blend
        .prepare(
            w,
            PreparedBuffers {
                positions: p,
                colors: c,
                node_boxes: nb,
                node_colors: nc,
            },
        )
        .expect("prepare")
}

/// The whole-grid point query of a prepared blend: 256² in 2D, 64³ in 3D, 16⁴ in 4D, 4096 in 1D.
fn grid(p: &Prepared<'_>) -> Vec<PointValue> {
    let d = p.dim();
    let r = [4096u32, 256, 64, 16][d - 1];
    let mut res = [1u32; 4];
    res[..d].fill(r);
    let region = Region::full(res);
    let mut out = vec![PointValue::default(); region.cells(d).unwrap()];
    let sigma = if d == 2 { 0.5 } else { 1.0 } / r as f32;
    p.point_grid(Kernel { sigma }, region, &mut out)
        .expect("point grid");
    out
}

/// SplitMix64 for reproducible query boxes.
struct Rng(u64);
impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// The storages compared, by name: the reference, the preset, and the preset with one part
/// changed.
fn storages() -> Vec<(&'static str, Storage)> {
    vec![
        ("full", Storage::FULL),
        ("compact", Storage::COMPACT),
        (
            "compact, u16 positions",
            Storage {
                positions: Precision::U16,
                ..Storage::COMPACT
            },
        ),
        (
            "compact, no colors",
            Storage {
                colors: None,
                node_colors: false,
                ..Storage::COMPACT
            },
        ),
        (
            "compact, no node color sums",
            Storage {
                node_colors: false,
                ..Storage::COMPACT
            },
        ),
    ]
}

/// The median wall seconds of `Blend::prepare` over 5 calls, and the mean of a `Blend::point`
/// call at `probes` (decoding on the fly).
fn timings(
    blend: &Blend<'_, '_>,
    w: &[f32],
    bufs: &mut [Vec<f32>; 4],
    probes: &[Vec<f32>],
    sigma: f32,
) -> anyhow::Result<(f64, f64)> {
    let prepare_times = timing::time(5, Clock::Thread, || {
        let _ = prepare(blend, w, bufs);
        Ok::<(), std::convert::Infallible>(())
    });
    let Ok(prepare_times) = prepare_times;
    let mut sink = 0.0f32;
    let (points, seconds) = timing::wall(|| -> anyhow::Result<()> {
        for p in probes {
            sink += blend.point(w, p, Kernel { sigma })?.density;
        }
        Ok(())
    });
    points?;
    std::hint::black_box(sink);
    Ok((prepare_times.median(), seconds / probes.len() as f64))
}

fn main() -> anyhow::Result<()> {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "manifests/onyx-rock-1m.toml".into());
    let m = Manifest::load(std::path::Path::new(&path))?;
    anyhow::ensure!(
        m.storage == Storage::FULL,
        "{path}: the reference must be stored in full (remove its [storage] section)"
    );
    let (baked, seconds) = timing::wall(|| bake(&m, &BakeOptions::default()));
    baked?;
    eprintln!("bake check/bake: {seconds:.1} s");
    let archives = Archives::load(&m)?;
    let proxy: Proxy<'_> = archives.proxy()?;
    let full_maps = archives.maps()?;
    let contents: Vec<Content> = full_maps.iter().map(content).collect();
    let (dim, n, k) = (proxy.dim(), proxy.n(), full_maps.len());
    let w = vec![1.0 / k as f32; k];
    let leaves = 1u64 << proxy.depth();
    println!(
        "{path}: {k} map(s), n = {n}, dim = {dim}, depth = {} ({leaves} leaves, {} internal nodes)\n",
        proxy.depth(),
        tree::internal_count(proxy.depth())
    );

    let full_blend = Blend::new(proxy, &full_maps)?;
    let mut full_bufs = buffers(&full_blend);
    let full_prep = prepare(&full_blend, &w, &mut full_bufs);
    let full_grid = grid(&full_prep);
    let max_density = full_grid.iter().map(|v| v.density).fold(0.0, f32::max);
    let mean_density =
        full_grid.iter().map(|v| v.density as f64).sum::<f64>() / full_grid.len() as f64;
    let max_color = full_grid.iter().flat_map(|v| v.color).fold(0.0, f32::max);
    let mut rng = Rng(7);
    let boxes: Vec<(Vec<f32>, Vec<f32>)> = (0..2000)
        .map(|_| {
            let side = 1.0 / 16.0 + rng.unit() * (0.25 - 1.0 / 16.0);
            let lo: Vec<f32> = (0..dim).map(|_| rng.unit() * (1.0 - side)).collect();
            let hi = lo.iter().map(|x| x + side).collect();
            (lo, hi)
        })
        .collect();
    let full_ranges: Vec<_> = boxes
        .iter()
        .map(|(lo, hi)| full_prep.range(lo, hi).expect("range"))
        .collect();

    let colored = full_maps.iter().all(|m| m.has_color());
    println!("| storage | bytes per map | stated max position error | measured max / mean position error | stated max color error | point grid: max / mean density error (of max / mean density) | point grid: max color error (of max color) | range: max count error, mean relative | prepare | Blend::point |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut rng = Rng(11);
    let probes: Vec<Vec<f32>> = (0..2000)
        .map(|_| (0..dim).map(|_| 0.1 + 0.8 * rng.unit()).collect())
        .collect();
    let sigma = if dim == 2 {
        0.5 / 256.0
    } else {
        1.0 / [4096.0, 256.0, 64.0, 16.0][dim - 1]
    };
    for (name, s) in storages() {
        let bytes: Vec<AlignedVec<16>> = contents.iter().map(|c| encode(c, s)).collect();
        let maps: Vec<Map<'_>> = bytes
            .iter()
            .map(|b| Map::open(b))
            .collect::<Result<_, _>>()?;
        let size = bytes.iter().map(|b| b.len()).max().unwrap_or(0);
        let stated = maps
            .iter()
            .flat_map(|m| m.max_position_error().into_iter().take(dim))
            .fold(0.0f32, f32::max);
        let stated_color = maps
            .iter()
            .flat_map(|m| m.color_error())
            .fold(0.0f32, f32::max);
        let (mut worst, mut sum) = (0.0f32, 0.0f64);
        for (m, c) in maps.iter().zip(&contents) {
            m.view().for_each_position(|j, x| {
                let e = (x - c.positions[j]).abs();
                worst = worst.max(e);
                sum += e as f64;
            });
        }
        let mean = sum / (k as f64 * n as f64 * dim as f64);
        let blend = Blend::new(archives.proxy()?, &maps)?;
        let mut bufs = buffers(&blend);
        let (prepare_median, per_point) = timings(&blend, &w, &mut bufs, &probes, sigma)?;
        let prep = prepare(&blend, &w, &mut bufs);
        let g = grid(&prep);
        let (mut dmax, mut dsum, mut cmax) = (0.0f32, 0.0f64, 0.0f32);
        for (a, b) in g.iter().zip(&full_grid) {
            let e = (a.density - b.density).abs();
            dmax = dmax.max(e);
            dsum += e as f64;
            for (x, y) in a.color.iter().zip(b.color) {
                cmax = cmax.max((x - y).abs());
            }
        }
        let dmean = dsum / g.len() as f64;
        let range = if colored && !blend.has_node_colors() {
            "refused (no node color sums)".to_string()
        } else {
            let (mut cmax_err, mut rel) = (0i64, 0.0f64);
            for ((lo, hi), f) in boxes.iter().zip(&full_ranges) {
                let r = prep.range(lo, hi).expect("range");
                let e = (r.count as i64 - f.count as i64).abs();
                cmax_err = cmax_err.max(e);
                rel += e as f64 / (f.count.max(1)) as f64;
            }
            format!("{cmax_err}, {:.1e}", rel / boxes.len() as f64)
        };
        let color_err = if blend.has_color() {
            format!(
                "{:.1e} ({:.1e})",
                cmax,
                cmax / max_color.max(f32::MIN_POSITIVE)
            )
        } else {
            "no colors".into()
        };
        println!(
            "| {name} | {} ({:.2} MB, {:.2} B/point) | {stated:.1e} | {worst:.1e} / {mean:.1e} | {} | {:.1e} / {:.1e} ({:.1e} / {:.1e}) | {color_err} | {range} | {:.1} ms | {:.1} µs |",
            size,
            size as f64 / 1e6,
            size as f64 / n as f64,
            if s.colors.is_some() && colored { format!("{stated_color:.1e}") } else { "—".into() },
            dmax,
            dmean,
            dmax / max_density,
            dmean / mean_density,
            prepare_median * 1e3,
            per_point * 1e6,
        );
    }
    Ok(())
}
