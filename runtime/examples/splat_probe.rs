//! Times and profiles the renderer's splat with the runtime alone (no baker, so it rebuilds in
//! seconds after a runtime change): `Blend::splat_region_rgba` of a 256² image at σ = ½ px, equal
//! weights, over the archives in a baked 2D manifest's output directory (`proxy.otb` and the
//! named maps, in the order given).
//!
//! ```sh
//! cargo run --release -p otbake-runtime --example splat_probe -- out/shapes redcross,tooth,heart,duck mixed 200
//! valgrind --tool=callgrind target/release/examples/splat_probe out/shapes redcross,tooth,heart,duck mixed 4
//! ```
//!
//! Calls: `mixed` (one thread, the whole image), `rgba` (the same from a prepared blend), `bands2`
//! (two bands of equal rows on two threads, each zeroed and splatted as the renderer does),
//! `compare:DIR2` (one splat of the same maps baked into DIR2 against this one: the largest cell
//! difference per channel, relative to the largest value of the channel in this image). Prints the
//! fastest and median wall time per call and the mean CPU time per call of the calling thread
//! (Linux `schedstat`; for `bands2`, of the process, in 10 ms ticks). Instruction counts per call are the
//! difference of two callgrind runs with different REPEATS.

use otbake_runtime::{Blend, Kernel, Map, Proxy, Region};
use std::path::Path;
use std::time::Instant;

fn load(dir: &Path, name: &str) -> rkyv::util::AlignedVec<16> {
    let path = dir.join(format!("{name}.otb"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    otbake_formats::write::aligned_copy(&bytes)
}

/// CPU time of this thread (`self`) or of the whole process (all tasks), in seconds.
fn cpu(process: bool) -> f64 {
    let read = |p: &Path| -> f64 {
        std::fs::read_to_string(p)
            .ok()
            .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
            .map_or(0.0, |ns| ns * 1e-9)
    };
    if !process {
        return read(Path::new("/proc/thread-self/schedstat"));
    }
    // utime + stime of the process, dead threads included, in clock ticks (USER_HZ = 100).
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let f: Vec<&str> = s.rsplit(')').next()?.split_whitespace().collect();
            Some((f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?) * 0.01)
        })
        .unwrap_or(0.0)
}

const RES: [u32; 4] = [256, 256, 1, 1];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: splat_probe DIR MAP1,MAP2,.. mixed|rgba|bands2|compare:DIR2 [REPEATS]";
    let (Some(dir), Some(names), Some(call)) = (args.get(1), args.get(2), args.get(3)) else {
        panic!("{usage}");
    };
    let repeats: usize = args.get(4).map_or(100, |r| r.parse().expect(usage));
    let dir = Path::new(dir);
    let names: Vec<&str> = names.split(',').collect();
    let proxy_bytes = load(dir, "proxy");
    let map_bytes: Vec<_> = names.iter().map(|n| load(dir, n)).collect();
    let proxy = Proxy::open(&proxy_bytes).expect("proxy");
    let maps: Vec<Map> = map_bytes
        .iter()
        .map(|b| Map::open(b).expect("map"))
        .collect();
    let blend = Blend::new(proxy, &maps).expect("blend");
    let weights = vec![1.0 / maps.len() as f32; maps.len()];
    let kernel = Kernel { sigma: 0.5 / 256.0 };
    let mut rgba = vec![0.0f32; 256 * 256 * 4];
    let mut times = Vec::with_capacity(repeats);
    let process = call == "bands2";
    let c0 = cpu(process);
    match call.as_str() {
        "mixed" => {
            for _ in 0..repeats {
                let t = Instant::now();
                rgba.fill(0.0);
                blend
                    .splat_region_rgba(&weights, kernel, Region::full(RES), &mut rgba)
                    .expect("splat");
                times.push(t.elapsed().as_secs_f64());
            }
        }
        "rgba" => {
            let sizes = blend.prepared_sizes();
            let mut store = vec![0.0f32; sizes.total()];
            let prep = blend
                .prepare(&weights, sizes.split(&mut store).expect("sized"))
                .expect("prepare");
            for _ in 0..repeats {
                let t = Instant::now();
                rgba.fill(0.0);
                prep.splat_region_rgba(kernel, Region::full(RES), &mut rgba)
                    .expect("splat");
                times.push(t.elapsed().as_secs_f64());
            }
        }
        "bands2" => {
            let (top, bottom) = rgba.split_at_mut(128 * 256 * 4);
            let (blend, weights) = (&blend, &weights);
            // Threads spawned per call cost tens of microseconds: a pool of two long-lived
            // threads, released by a barrier per call.
            let barrier = std::sync::Barrier::new(3);
            let stop = std::sync::atomic::AtomicBool::new(false);
            std::thread::scope(|s| {
                for (first, cells) in [(0u32, top), (128u32, bottom)] {
                    let (barrier, stop) = (&barrier, &stop);
                    s.spawn(move || loop {
                        barrier.wait();
                        if stop.load(std::sync::atomic::Ordering::Relaxed) {
                            return;
                        }
                        cells.fill(0.0);
                        blend
                            .splat_region_rgba(
                                weights,
                                kernel,
                                Region::rows(RES, first, 128),
                                cells,
                            )
                            .expect("splat");
                        barrier.wait();
                    });
                }
                for _ in 0..repeats {
                    let t = Instant::now();
                    barrier.wait();
                    barrier.wait();
                    times.push(t.elapsed().as_secs_f64());
                }
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                barrier.wait();
            });
        }
        other => {
            let Some(dir2) = other.strip_prefix("compare:") else {
                panic!("{usage}");
            };
            let dir2 = Path::new(dir2);
            let proxy2_bytes = load(dir2, "proxy");
            let map2_bytes: Vec<_> = names.iter().map(|n| load(dir2, n)).collect();
            let proxy2 = Proxy::open(&proxy2_bytes).expect("proxy");
            let maps2: Vec<Map> = map2_bytes
                .iter()
                .map(|b| Map::open(b).expect("map"))
                .collect();
            let blend2 = Blend::new(proxy2, &maps2).expect("blend");
            let mut rgba2 = vec![0.0f32; 256 * 256 * 4];
            blend
                .splat_region_rgba(&weights, kernel, Region::full(RES), &mut rgba)
                .expect("splat");
            blend2
                .splat_region_rgba(&weights, kernel, Region::full(RES), &mut rgba2)
                .expect("splat");
            for (ch, name) in ["r", "g", "b", "density"].iter().enumerate() {
                let max = rgba
                    .iter()
                    .skip(ch)
                    .step_by(4)
                    .fold(0.0f32, |a, v| a.max(v.abs()));
                let (mut worst, mut sum) = (0.0f32, 0.0f64);
                for (a, b) in rgba.iter().zip(&rgba2).skip(ch).step_by(4) {
                    worst = worst.max((a - b).abs());
                    sum += f64::from((a - b).abs());
                }
                println!(
                    "{name}: max |difference| {:.3e} of max value {max:.3e} ({:.3}%), mean {:.3e}",
                    worst,
                    100.0 * worst / max,
                    sum / (256.0 * 256.0)
                );
            }
            return;
        }
    }
    let c = (cpu(process) - c0) / repeats.max(1) as f64;
    times.sort_by(f64::total_cmp);
    println!(
        "{call}: min {:.3} ms, median {:.3} ms, mean CPU {:.3} ms over {repeats} calls",
        times.first().copied().unwrap_or(f64::NAN) * 1e3,
        times.get(times.len() / 2).copied().unwrap_or(f64::NAN) * 1e3,
        c * 1e3
    );
}
