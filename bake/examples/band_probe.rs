use otbake::manifest::Manifest;
use otbake::render::Archives;
use otbake_runtime::{Blend, Kernel, Map, Region};
use rayon::prelude::*;
use std::time::Instant;

fn balanced_bands(maps: &[Map<'_>], weights: &[f32], h: usize, bands: usize) -> Vec<usize> {
    let bands = bands.clamp(1, h.max(1));
    let equal = || (0..=bands).map(|b| b * h / bands).collect();
    let Some(first) = maps.first() else {
        return equal();
    };
    let (n, depth) = (first.n(), first.depth());
    if depth == 0 || bands == 1 {
        return equal();
    }
    let level = (depth - 1).min(5);
    let mut rows = vec![0.0f64; h];
    for offset in 0..1u32 << level {
        let node = otbake_formats::tree::node_at(n, level, offset);
        let (mut lo, mut hi) = (0.0f32, 0.0f32);
        for (w, m) in weights.iter().zip(maps) {
            let (l, u) = m.view().internal_box(node.index as usize);
            lo += w * l[1];
            hi += w * u[1];
        }
        // Rows the box covers, clamped to the image (a periodic blend's lifts may lie outside).
        let row = |v: f32| ((v * h as f32).floor().max(0.0) as usize).min(h - 1);
        let (a, b) = (row(lo), row(hi).max(row(lo)));
        let share = f64::from(node.count) / (b + 1 - a) as f64;
        for r in &mut rows[a..=b] {
            *r += share;
        }
    }
    let total: f64 = rows.iter().sum();
    let mut starts = vec![0];
    let mut acc = 0.0;
    for (r, &count) in rows.iter().enumerate() {
        acc += count;
        while starts.len() < bands && acc >= total * starts.len() as f64 / bands as f64 {
            starts.push(r + 1);
        }
    }
    starts.resize(bands, h);
    starts.push(h);
    starts
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let m = Manifest::load(std::path::Path::new(&args[1]))?;
    let repeats: usize = args[2].parse()?;

    let archives = Archives::load(&m)?;
    let maps = archives.maps()?;
    let weights = vec![1.0 / maps.len() as f32; maps.len()];
    let blend = Blend::new(archives.proxy()?, &maps)?;
    let kernel = Kernel { sigma: 0.5 / 256.0 };
    let mut rgba = vec![0.0f32; 256 * 256 * 4];
    let res = [256u32, 256, 1, 1];
    let mut rows = Vec::new();
    let split = if args[3] == "auto" {
        balanced_bands(&maps, &weights, 256, 2)[1]
    } else {
        args[3].parse()?
    };
    println!("split {split}");
    for _ in 0..repeats {
        let t0 = Instant::now();
        let (a, b) = rgba.split_at_mut(split * 256 * 4);
        let bands = vec![(0usize, a), (split, b)];
        let r: Vec<(f64, f64)> = bands
            .into_par_iter()
            .map(|(first, cells)| {
                let s = t0.elapsed().as_secs_f64();
                cells.fill(0.0);
                let n = (cells.len() / 1024) as u32;
                blend
                    .splat_region_rgba(&weights, kernel, Region::rows(res, first as u32, n), cells)
                    .unwrap();
                (s, t0.elapsed().as_secs_f64())
            })
            .collect();
        let total = t0.elapsed().as_secs_f64();
        rows.push((total, r[0], r[1]));
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    for q in [0, repeats / 4, repeats / 2, 3 * repeats / 4, repeats - 1] {
        let (t, a, b) = rows[q];
        println!(
            "total {:.2} ms | band0 start {:.3} dur {:.2} | band1 start {:.3} dur {:.2}",
            t * 1e3,
            a.0 * 1e3,
            (a.1 - a.0) * 1e3,
            b.0 * 1e3,
            (b.1 - b.0) * 1e3
        );
    }
    Ok(())
}
