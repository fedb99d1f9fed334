//! A structure-aware fuzzer for the runtime: mutates real archives (bit flips, special floats,
//! truncation, splices — usually repairing the checksum so the damage reaches validation and the
//! queries), opens them, and runs every query with random and hostile arguments. Any panic is a
//! finding. Deterministic for a seed, so findings replay.
//!
//! `cargo nextest`/`cargo fuzz` need nightly for coverage guidance; this runs on stable everywhere,
//! including CI, which replays the corpus and runs a short campaign on every change.

use otbake_formats::header::{Header, HEADER_LEN};
use otbake_formats::write::aligned_copy;
use otbake_formats::ArchiveKind;
use otbake_runtime::{
    AdaptiveKernel, Blend, Kernel, Map, PointValue, PreparedBuffers, Proxy, Region, SplatTarget,
};

/// SplitMix64: tiny, seedable, good enough for choosing mutations.
pub struct Rng(pub u64);

impl Rng {
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform integer below `n` (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
    /// A float that is sometimes ordinary and sometimes hostile.
    pub fn float(&mut self) -> f32 {
        const SPECIAL: [f32; 10] = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN_POSITIVE,
            1e-45,
        ];
        if self.below(4) == 0 {
            SPECIAL[self.below(SPECIAL.len())]
        } else {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32 * 1.2 - 0.1
        }
    }
}

/// Mutates archive bytes of `kind` in place.
pub fn mutate(rng: &mut Rng, bytes: &mut Vec<u8>, kind: ArchiveKind) {
    let rounds = 1 + rng.below(3);
    for _ in 0..rounds {
        if bytes.is_empty() {
            break;
        }
        let len = bytes.len();
        match rng.below(7) {
            0 => {
                let i = rng.below(len);
                if let Some(b) = bytes.get_mut(i) {
                    *b ^= 1 << rng.below(8);
                }
            }
            1 => {
                let i = rng.below(len);
                if let Some(b) = bytes.get_mut(i) {
                    *b = rng.next_u64() as u8;
                }
            }
            2 | 3 => {
                // A special float at a 4-aligned payload position (hits positions, boxes, sizes).
                let i = (HEADER_LEN + rng.below(len.saturating_sub(HEADER_LEN))) & !3;
                let v = rng.float().to_le_bytes();
                if i + 4 <= bytes.len() {
                    bytes[i..i + 4].copy_from_slice(&v);
                }
            }
            4 => {
                // A small or huge integer (sizes, offsets, counts).
                let i = (HEADER_LEN + rng.below(len.saturating_sub(HEADER_LEN))) & !3;
                let v = [
                    0u32,
                    1,
                    2,
                    7,
                    0xFFFF_FFFF,
                    0x8000_0000,
                    rng.next_u64() as u32,
                ][rng.below(7)]
                .to_le_bytes();
                if i + 4 <= bytes.len() {
                    bytes[i..i + 4].copy_from_slice(&v);
                }
            }
            5 => {
                let cut = rng.below(len);
                bytes.truncate(cut);
            }
            _ => {
                // Splice: copy a chunk of the archive over another place.
                let a = rng.below(len);
                let b = rng.below(len);
                let n = rng.below(64).min(len - a.max(b));
                let chunk: Vec<u8> = bytes[a..a + n].to_vec();
                bytes[b..b + n].copy_from_slice(&chunk);
            }
        }
    }
    // Usually repair the header so the damage is not just a checksum mismatch.
    if rng.below(10) < 8 && bytes.len() >= HEADER_LEN {
        let header = Header::new(kind, &bytes[HEADER_LEN..]).encode();
        bytes[..HEADER_LEN].copy_from_slice(&header);
    }
}

/// Opens proxy and map bytes and runs every query with random arguments. Returns how many archives
/// opened (0, 1 or 2). Panics only if the runtime does.
pub fn exercise(rng: &mut Rng, proxy: &[u8], maps: &[&[u8]]) -> usize {
    let proxy = aligned_copy(proxy);
    let map_bytes: Vec<_> = maps.iter().map(|m| aligned_copy(m)).collect();
    let mut opened = 0;
    let p = Proxy::open(&proxy);
    let ms: Vec<Map<'_>> = map_bytes.iter().filter_map(|b| Map::open(b).ok()).collect();
    opened += p.is_ok() as usize + ms.len().min(1);
    // Every map's stored-attribute reads and stated error bounds (decoders of any storage).
    for m in &ms {
        let i = rng.next_u64() as u32 % (m.n() + 2);
        let _ = (m.position(i), m.color(i), m.position_error(i));
        let _ = (m.max_position_error(), m.color_error(), m.storage());
    }
    let Ok(p) = p else { return opened };
    let Ok(blend) = Blend::new(p, &ms) else {
        return opened;
    };
    let d = blend.dim();
    let k = blend.k();
    for _ in 0..4 {
        let w: Vec<f32> = match rng.below(5) {
            0 => (0..k + rng.below(2)).map(|_| rng.float()).collect(),
            _ => {
                let raw: Vec<f32> = (0..k)
                    .map(|_| (rng.next_u64() % 1000) as f32 + 1.0)
                    .collect();
                let s: f32 = raw.iter().sum();
                raw.iter().map(|v| v / s).collect()
            }
        };
        let pt: Vec<f32> = (0..d + (rng.below(8) == 0) as usize)
            .map(|_| rng.float())
            .collect();
        let sigma = [0.01, 0.1, rng.float(), 1e-30, 1e30][rng.below(5)];
        let _ = blend.point(&w, &pt, Kernel { sigma });
        let adaptive = AdaptiveKernel {
            scale: [2.0, rng.float(), 1e30][rng.below(3)],
            min_sigma: [1e-3, rng.float(), 1e-30][rng.below(3)],
            max_sigma: [0.05, 0.3, rng.float(), 1e30][rng.below(4)],
        };
        let _ = blend.point_adaptive(&w, &pt, adaptive);
        let _ = blend.bandwidth(&w, rng.next_u64() as u32 % (blend.n() + 2), adaptive);
        let lo: Vec<f32> = (0..d).map(|_| rng.float()).collect();
        let hi: Vec<f32> = (0..d).map(|_| rng.float()).collect();
        let _ = blend.range(&w, &lo, &hi);
        let _ = blend.sample(&w, rng.next_u64() as u32 % (blend.n() + 2));
        let r = 1 + rng.below(6) as u32;
        let cells = (r as usize).pow(d as u32);
        let mut density = vec![0.0f32; if rng.below(8) == 0 { cells + 1 } else { cells }];
        let mut color = vec![0.0f32; cells * 3];
        let mut res = [1u32; 4];
        res[..d].fill(r);
        let _ = blend.splat(
            &w,
            Kernel {
                sigma: sigma.abs().min(0.5),
            },
            SplatTarget {
                res,
                density: &mut density,
                color: Some(&mut color),
            },
        );
        // RGBA cells mixed on the fly, over a region of the grid (maybe a bad one).
        let mut region = Region::full(res);
        region.start[0] = rng.below(r as usize + 1) as u32;
        region.size[0] = r.saturating_sub(region.start[0]).max(rng.below(2) as u32);
        let rcells = region.cells(d).unwrap_or(0);
        let mut rgba = vec![0.0f32; rcells * 4 + (rng.below(8) == 0) as usize];
        let _ = blend.splat_region_rgba(&w, Kernel { sigma }, region, &mut rgba);
    }
    // Prepared once (decoding every map into f32 buffers), then its queries.
    let sizes = blend.prepared_sizes();
    let short = rng.below(10) == 0;
    let mut bufs = [
        vec![0.0f32; sizes.positions],
        vec![0.0f32; sizes.colors],
        vec![0.0f32; sizes.node_boxes.saturating_sub(short as usize)],
        vec![0.0f32; sizes.node_colors],
    ];
    let [bp, bc, bb, bn] = &mut bufs;
    let raw: Vec<f32> = (0..k)
        .map(|_| (rng.next_u64() % 100) as f32 + 1.0)
        .collect();
    let sum: f32 = raw.iter().sum();
    let w: Vec<f32> = raw.iter().map(|v| v / sum).collect();
    let prepared = blend.prepare(
        &w,
        PreparedBuffers {
            positions: bp,
            colors: bc,
            node_boxes: bb,
            node_colors: bn,
        },
    );
    if let Ok(prep) = prepared {
        let kernel = Kernel {
            sigma: [0.05, 0.2, rng.float().abs()][rng.below(3)],
        };
        let pt: Vec<f32> = (0..d).map(|_| rng.float()).collect();
        let _ = prep.point(&pt, kernel);
        let _ = prep.range(&pt, &pt);
        let _ = prep.sample(rng.next_u64() as u32 % (prep.n() + 2));
        let r = 1 + rng.below(5) as u32;
        let mut res = [1u32; 4];
        res[..d].fill(r);
        let cells = (r as usize).pow(d as u32);
        let mut grid = vec![PointValue::default(); cells];
        let _ = prep.point_grid(kernel, Region::full(res), &mut grid);
        let mut density = vec![0.0f32; cells];
        let mut color = vec![0.0f32; cells * 3];
        let _ = prep.splat_region(kernel, Region::full(res), &mut density, Some(&mut color));
        let mut rgba = vec![0.0f32; cells * 4];
        let _ = prep.splat_region_rgba(kernel, Region::full(res), &mut rgba);
    }
    opened
}
