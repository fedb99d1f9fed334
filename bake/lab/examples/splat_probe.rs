//! Times and profiles the renderer's splat with the runtime alone (it calls no baker code, so a
//! profile shows only the runtime): `Blend::splat_region_rgba` of a 256² image at σ = ½ px, equal
//! weights, over the archives in a baked 2D manifest's output directory (`proxy.otb` and the
//! named maps, in the order given).
//!
//! ```sh
//! cargo run --release -p otbake-lab --example splat_probe -- out/shapes redcross,tooth,heart,duck mixed 200
//! valgrind --tool=callgrind target/release/examples/splat_probe out/shapes redcross,tooth,heart,duck mixed 4
//! ```
//!
//! Calls: `mixed` (one thread, the whole image), `rgba` (the same from a prepared blend), `bands2`
//! (two bands of equal rows on two threads, each zeroed and splatted as the renderer does),
//! `compare:DIR2` (one splat of the same maps baked into DIR2 against this one: the largest cell
//! difference per channel, relative to the largest value of the channel in this image). Prints the
//! fastest and median wall time per call and the mean CPU time per call of the calling thread (for
//! `bands2`, of the whole process; `otbake_lab::timing`). Instruction counts per call are the
//! difference of two callgrind runs with different REPEATS.

use otbake_lab::timing::{self, Clock};
use otbake_runtime::{Blend, Error, Kernel, Map, Proxy, Region};
use std::path::Path;

fn load(dir: &Path, name: &str) -> rkyv::util::AlignedVec<16> {
    let path = dir.join(format!("{name}.otb"));
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    otbake_formats::write::aligned_copy(&bytes)
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
    // `bands2` keeps two threads busy: the CPU time of the whole process.
    let clock = if call == "bands2" {
        Clock::Process
    } else {
        Clock::Thread
    };
    let t = match call.as_str() {
        "mixed" => timing::time(repeats, clock, || {
            rgba.fill(0.0);
            blend.splat_region_rgba(&weights, kernel, Region::full(RES), &mut rgba)
        })
        .expect("splat"),
        "rgba" => {
            let sizes = blend.prepared_sizes();
            let mut store = vec![0.0f32; sizes.total()];
            let prep = blend
                .prepare(&weights, sizes.split(&mut store).expect("sized"))
                .expect("prepare");
            timing::time(repeats, clock, || {
                rgba.fill(0.0);
                prep.splat_region_rgba(kernel, Region::full(RES), &mut rgba)
            })
            .expect("splat")
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
                let t = timing::time(repeats, clock, || {
                    barrier.wait();
                    barrier.wait();
                    Ok::<(), Error>(())
                })
                .expect("cannot fail");
                stop.store(true, std::sync::atomic::Ordering::Relaxed);
                barrier.wait();
                t
            })
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
    };
    println!(
        "{call}: min {:.3} ms, median {:.3} ms, mean CPU {:.3} ms over {repeats} calls",
        t.min() * 1e3,
        t.median() * 1e3,
        if repeats == 0 { 0.0 } else { t.cpu * 1e3 }
    );
}
