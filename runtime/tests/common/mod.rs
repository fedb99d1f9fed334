//! Synthetic archives for runtime tests: random points in any order (the runtime's answers must not
//! depend on how well the tree fits the points, only on its boxes being right).
#![allow(dead_code, clippy::needless_range_loop)]

use otbake_formats::proxy::Proxy as ProxyData;
use otbake_formats::storage::{Precision, Storage};
use otbake_formats::tree::{depth, fill_node_boxes, node_count};
use otbake_formats::write::{encode_map_content, encode_proxy, MapContent};
use otbake_runtime::{Blend, Map, PointValue, Prepared, PreparedBuffers, Proxy, Region};
use rkyv::util::AlignedVec;

/// A tiny deterministic generator (SplitMix64) so tests need no RNG dependency.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

pub struct Fixture {
    pub dim: usize,
    pub n: usize,
    pub proxy: AlignedVec<16>,
    pub maps: Vec<AlignedVec<16>>,
    /// Per map: positions and colors, as written.
    pub positions: Vec<Vec<f32>>,
    pub colors: Vec<Vec<f32>>,
    /// Per map: spacings as written (codes round them up: see `decoded_spacing`).
    pub spacings: Vec<Vec<f32>>,
    pub mean_mass: Vec<f32>,
}

/// Storages property tests run over: full, compact, and mixes of every precision (all keeping
/// node color sums and spacings, so every query answers).
pub const STORAGES: [Storage; 5] = [
    Storage::FULL,
    Storage {
        spacings: true,
        ..Storage::COMPACT
    },
    Storage {
        positions: Precision::U16,
        node_boxes: Precision::U16,
        colors: Some(Precision::U16),
        node_colors: true,
        spacings: true,
    },
    Storage {
        positions: Precision::U8,
        node_boxes: Precision::F32,
        colors: Some(Precision::F32),
        node_colors: true,
        spacings: true,
    },
    Storage {
        positions: Precision::F32,
        node_boxes: Precision::U16,
        colors: Some(Precision::U8),
        node_colors: true,
        spacings: true,
    },
];

pub fn fixture(seed: u64, n: usize, dim: usize, leaf: u32, k: usize, key: [u8; 32]) -> Fixture {
    fixture_with(seed, n, dim, leaf, k, key, Storage::FULL)
}

/// A fixture whose maps are stored per `storage` (`positions`/`colors` keep the full values).
pub fn fixture_with(
    seed: u64,
    n: usize,
    dim: usize,
    leaf: u32,
    k: usize,
    key: [u8; 32],
    storage: Storage,
) -> Fixture {
    fixture_colored(seed, n, dim, leaf, k, key, storage, |u| u * 2.0)
}

/// [`fixture_with`] whose color channels are `color(u)` for uniform `u` in [0, 1) (the same
/// random streams otherwise).
#[allow(clippy::too_many_arguments)]
pub fn fixture_colored(
    seed: u64,
    n: usize,
    dim: usize,
    leaf: u32,
    k: usize,
    key: [u8; 32],
    storage: Storage,
    color: fn(f32) -> f32,
) -> Fixture {
    let mut rng = Rng(seed);
    let d = depth(n as u32, leaf);
    let nodes = node_count(d) as usize;
    let proxy_pos: Vec<f32> = (0..n * dim).map(|_| rng.unit()).collect();
    let mut boxes = vec![0.0; nodes * 2 * dim];
    fill_node_boxes(&proxy_pos, dim, d, &mut boxes);
    let proxy = encode_proxy(&ProxyData {
        dim: dim as u32,
        n: n as u32,
        leaf_size: leaf,
        depth: d,
        key,
        wrap: 0,
        description: "test",
        positions: &proxy_pos,
        node_boxes: &boxes,
    })
    .unwrap();
    let mut f = Fixture {
        dim,
        n,
        proxy,
        maps: vec![],
        positions: vec![],
        colors: vec![],
        spacings: vec![],
        mean_mass: vec![],
    };
    for m in 0..k {
        // Maps cluster points so queries see dense and empty regions alike.
        let center: Vec<f32> = (0..dim).map(|_| 0.2 + 0.6 * rng.unit()).collect();
        let pos: Vec<f32> = (0..n * dim)
            .map(|i| {
                (center[i % dim] + 0.3 * (rng.unit() - 0.5) * (1.0 + rng.unit())).clamp(0.0, 1.0)
            })
            .collect();
        let colors: Vec<f32> = (0..n * 3).map(|_| color(rng.unit())).collect();
        let mean = 0.1 + rng.unit();
        // Spacings from their own generator (the other streams stay as they were), over two
        // decades: adaptive kernels of every width, unrelated to where the points are.
        let mut srng = Rng(seed ^ (0x5EED_0000 + m as u64));
        let spacings: Vec<f32> = (0..n)
            .map(|_| 10f32.powf(-2.5 + 2.0 * srng.unit()))
            .collect();
        f.maps.push(
            encode_map_content(
                &MapContent {
                    dim: dim as u32,
                    depth: d,
                    proxy_key: key,
                    key: [m as u8; 32],
                    composite: 0,
                    mean_mass: mean,
                    wrap: otbake_formats::Wrap::Clamp,
                    positions: &pos,
                    colors: &colors,
                    spacings: &spacings,
                    solver_report: "",
                    transport_cost: 0.0,
                },
                storage,
            )
            .unwrap(),
        );
        f.positions.push(pos);
        f.colors.push(colors);
        f.spacings.push(spacings);
        f.mean_mass.push(mean);
    }
    f
}

impl Fixture {
    /// Blended point i, computed the way the runtime documents (Σ w_k x_k in map order).
    pub fn blended(&self, w: &[f32], i: usize) -> (Vec<f32>, [f32; 3]) {
        let mut p = vec![0.0f32; self.dim];
        let mut c = [0.0f32; 3];
        for (k, wk) in w.iter().enumerate() {
            for a in 0..self.dim {
                p[a] += wk * self.positions[k][i * self.dim + a];
            }
            for a in 0..3 {
                c[a] += wk * self.colors[k][i * 3 + a];
            }
        }
        (p, c)
    }

    /// Blended spacing of point i as the runtime reads it: Σ w_k decode(code_k[i]) in map order.
    pub fn blended_spacing(&self, w: &[f32], i: usize) -> f32 {
        use otbake_formats::spacing::{decode, encode_up};
        let mut s = 0.0f32;
        for (k, wk) in w.iter().enumerate() {
            s += wk * decode(encode_up(self.spacings[k][i]));
        }
        s
    }

    pub fn mean_mass(&self, w: &[f32]) -> f32 {
        w.iter().zip(&self.mean_mass).map(|(a, b)| a * b).sum()
    }
}

/// Normalized random weights.
pub fn weights(rng: &mut Rng, k: usize) -> Vec<f32> {
    let raw: Vec<f32> = (0..k).map(|_| rng.unit() + 0.01).collect();
    let s: f32 = raw.iter().sum();
    raw.iter().map(|v| v / s).collect()
}

// Shared by the region tests (`regions.rs`, `regions_exact.rs`).

/// The fixture's archives, opened.
pub fn open(f: &Fixture) -> (Proxy<'_>, Vec<Map<'_>>) {
    (
        Proxy::open(&f.proxy).unwrap(),
        f.maps.iter().map(|m| Map::open(m).unwrap()).collect(),
    )
}

pub fn prepare<'b>(blend: &Blend<'_, '_>, w: &[f32], store: &'b mut Vec<f32>) -> Prepared<'b> {
    let sizes = blend.prepared_sizes();
    store.resize(sizes.total(), f32::NAN);
    let b: PreparedBuffers<'b> = sizes.split(store).unwrap();
    blend.prepare(w, b).unwrap()
}

pub fn bits(v: &PointValue) -> [u32; 5] {
    [
        v.density.to_bits(),
        v.mass.to_bits(),
        v.color[0].to_bits(),
        v.color[1].to_bits(),
        v.color[2].to_bits(),
    ]
}

/// Global cell of region cell `cell` (axis 0 fastest), and its center.
pub fn global(dim: usize, region: &Region, cell: usize) -> (usize, Vec<f32>) {
    let (mut rest, mut g, mut stride) = (cell, 0, 1);
    let mut c = vec![0.0; dim];
    for a in 0..dim {
        let i = region.start[a] as usize + rest % region.size[a] as usize;
        rest /= region.size[a] as usize;
        c[a] = (i as f32 + 0.5) / region.res[a] as f32;
        g += i * stride;
        stride *= region.res[a] as usize;
    }
    (g, c)
}
