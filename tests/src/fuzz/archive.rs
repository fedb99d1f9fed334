//! The `archive` target: mutates real archives (bit flips, special floats, truncation, splices —
//! usually repairing the checksum so the damage reaches validation and the queries), opens them
//! with the runtime's `Proxy::open`/`Map::open`, and runs every query with random and hostile
//! arguments.

use super::Rng;
use otbake_formats::header::{Header, HEADER_LEN};
use otbake_formats::write::aligned_copy;
use otbake_formats::ArchiveKind;
use otbake_runtime::{
    AdaptiveKernel, Blend, Kernel, Map, PointValue, PreparedBuffers, Proxy, Region, SplatTarget,
};

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

/// The `archive` target: a proxy and its maps (`corpus/archive/CASE/`), one of them mutated, then
/// opened and queried by [`exercise`]. Accepted: every archive still opened.
pub struct ArchiveTarget;

impl super::Target for ArchiveTarget {
    fn name(&self) -> &'static str {
        "archive"
    }

    fn seeds(&self, corpus: &std::path::Path) -> Vec<super::Case> {
        archive_cases(&corpus.join("archive"))
    }

    fn mutate(&self, rng: &mut Rng, case: &mut super::Case, _other: &super::Case) {
        // File 0 is the proxy; a map two times in three.
        let (i, kind) = if case.files.len() == 1 || rng.one_in(3) {
            (0, ArchiveKind::Proxy)
        } else {
            (1 + rng.below(case.files.len() - 1), ArchiveKind::Map)
        };
        mutate(rng, &mut case.files[i].1, kind);
    }

    fn execute(&self, rng: &mut Rng, case: &super::Case, _scratch: &super::Scratch) -> bool {
        let maps: Vec<&[u8]> = case.files[1..].iter().map(|f| f.1.as_slice()).collect();
        exercise(rng, &case.files[0].1, &maps) == 2
    }
}

/// Archive cases: every sub-directory of `dir` holding `proxy.otb` and `*.otb` maps, the proxy
/// first.
pub fn archive_cases(dir: &std::path::Path) -> Vec<super::Case> {
    crate::fuzz_corpus(dir)
        .into_iter()
        .map(|c| {
            let mut files = vec![("proxy.otb".to_string(), c.proxy)];
            files.extend(
                c.maps
                    .into_iter()
                    .enumerate()
                    .map(|(i, m)| (format!("map{i}.otb"), m)),
            );
            super::Case { files }
        })
        .collect()
}
