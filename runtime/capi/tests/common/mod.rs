//! Synthetic archives for the C ABI's Rust tests: a proxy and k maps of random points (with
//! colors, node color sums and spacings), in 16-byte aligned memory.
#![allow(dead_code)]

use otbake_formats::proxy::Proxy as ProxyData;
use otbake_formats::storage::Storage;
use otbake_formats::tree::{depth, fill_node_boxes, node_count};
use otbake_formats::write::{encode_map_content, encode_proxy, MapContent};
use rkyv::util::AlignedVec;

/// A tiny deterministic generator (SplitMix64).
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

/// Archive bytes of one proxy and its maps.
pub struct Archives {
    pub proxy: AlignedVec<16>,
    pub maps: Vec<AlignedVec<16>>,
}

/// A proxy of `n` random points in `dim` dimensions with key `key`, and `k` maps of it.
pub fn archives(seed: u64, n: usize, dim: usize, k: usize, key: [u8; 32]) -> Archives {
    let mut rng = Rng(seed);
    let d = depth(n as u32, 4);
    let pos: Vec<f32> = (0..n * dim).map(|_| rng.unit()).collect();
    let mut boxes = vec![0.0; node_count(d) as usize * 2 * dim];
    fill_node_boxes(&pos, dim, d, &mut boxes);
    let proxy = encode_proxy(&ProxyData {
        dim: dim as u32,
        n: n as u32,
        leaf_size: 4,
        depth: d,
        key,
        wrap: 0,
        description: "capi test",
        positions: &pos,
        node_boxes: &boxes,
    })
    .unwrap();
    let maps = (0..k)
        .map(|m| {
            let pos: Vec<f32> = (0..n * dim).map(|_| rng.unit()).collect();
            let colors: Vec<f32> = (0..n * 3).map(|_| rng.unit()).collect();
            let spacings: Vec<f32> = (0..n).map(|_| 0.01 + 0.05 * rng.unit()).collect();
            encode_map_content(
                &MapContent {
                    dim: dim as u32,
                    depth: d,
                    proxy_key: key,
                    key: [m as u8 + 1; 32],
                    composite: 0,
                    mean_mass: 0.5 + rng.unit(),
                    wrap: otbake_formats::Wrap::Clamp,
                    positions: &pos,
                    colors: &colors,
                    spacings: &spacings,
                    solver_report: "",
                    transport_cost: 0.0,
                },
                Storage::FULL,
            )
            .unwrap()
        })
        .collect();
    Archives { proxy, maps }
}
