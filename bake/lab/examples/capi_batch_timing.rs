//! Times one batch of 65,536 point queries (the centers of a 256² grid) through the C ABI
//! against the same batch in Rust, interleaved in one run.
//!
//! ```sh
//! cargo run --release -p otbake-lab --example capi_batch_timing -- manifests/shapes.toml [REPEATS]
//! ```
//! Bakes what is missing first. The Rust batch is a loop of `Blend::point` into a buffer; the C
//! batch is `otbake_blend_point_batch` called through an `extern "C"` function pointer the
//! optimizer cannot see through — the exported symbol a C caller links, with its argument checks,
//! status and panic guard. Repetitions alternate which batch goes first; the program prints the
//! median wall and thread-CPU time of each and their ratios (C / Rust), and checks that both
//! batches give the same bits.
//!
//! With a third argument `rust` or `c` it runs only that batch REPEATS times and times nothing, for
//! instruction counts that load does not move: per batch, half the difference of two callgrind runs
//! (`valgrind --tool=callgrind --callgrind-out-file=/dev/null target/release/examples/capi_batch_timing
//! MANIFEST N c` for N = 1 and 3; likewise `rust`). `prepare` runs `otbake_prepared_new` REPEATS
//! times (one thread, no join), `prepared` prepares once and runs `otbake_prepared_point_batch` of
//! the same points REPEATS times: what a prepared blend costs and saves per batch.

use otbake::manifest::Manifest;
use otbake::pipeline::bake::{bake, BakeOptions};
use otbake_capi::{
    otbake_blend_free, otbake_blend_new, otbake_blend_point_batch, otbake_blend_prepared_sizes,
    otbake_map_free, otbake_map_open, otbake_prepared_free, otbake_prepared_new,
    otbake_prepared_point_batch, otbake_proxy_free, otbake_proxy_open, OtbakeBlend,
    OtbakePointValue, OtbakePrepared, OtbakePreparedSizes, OtbakeStatus,
};
use otbake_lab::timing::{self, median};
use otbake_runtime::{Blend, Kernel, Map, PointValue, Proxy};
use rkyv::util::AlignedVec;
use std::ptr::null_mut;

/// The C ABI's batch entry point, as C sees it.
type PointBatch = unsafe extern "C" fn(
    *const OtbakeBlend,
    *const f32,
    usize,
    usize,
    *const f32,
    usize,
    usize,
    f32,
    *mut OtbakePointValue,
) -> OtbakeStatus;

/// Reads an archive into 16-byte aligned memory.
fn read(path: &std::path::Path) -> anyhow::Result<AlignedVec<16>> {
    let bytes = std::fs::read(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let mut v = AlignedVec::<16>::with_capacity(bytes.len());
    v.extend_from_slice(&bytes);
    Ok(v)
}

/// Opens a C blend of the archives (the handles free at the end of `main`'s scope).
fn c_blend(proxy: &[u8], maps: &[AlignedVec<16>]) -> anyhow::Result<*mut OtbakeBlend> {
    let mut p = null_mut();
    let mut handles = Vec::new();
    let mut blend = null_mut();
    // SAFETY: the bytes outlive the blend (main holds them until after `otbake_blend_free`);
    // every out pointer is valid; the proxy and map handles are freed once the blend exists.
    unsafe {
        anyhow::ensure!(otbake_proxy_open(proxy.as_ptr(), proxy.len(), &mut p) == OtbakeStatus::Ok);
        for m in maps {
            let mut h = null_mut();
            anyhow::ensure!(otbake_map_open(m.as_ptr(), m.len(), &mut h) == OtbakeStatus::Ok);
            handles.push(h.cast_const());
        }
        let s = otbake_blend_new(p, handles.as_ptr(), handles.len(), &mut blend);
        otbake_proxy_free(p);
        for h in handles {
            otbake_map_free(h.cast_mut());
        }
        anyhow::ensure!(s == OtbakeStatus::Ok, "otbake_blend_new: {s:?}");
    }
    Ok(blend)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .map(String::as_str)
        .unwrap_or("manifests/shapes.toml");
    let repeats: usize = args.get(2).map(|r| r.parse()).transpose()?.unwrap_or(15);
    let m = Manifest::load(std::path::Path::new(path))?;
    bake(&m, &BakeOptions::default())?;
    let proxy_bytes = read(&m.proxy_archive())?;
    let map_bytes: Vec<AlignedVec<16>> = m
        .inputs
        .iter()
        .map(|i| read(&m.map_archive(&i.name)))
        .collect::<anyhow::Result<_>>()?;

    let proxy = Proxy::open(&proxy_bytes)?;
    let maps: Vec<Map<'_>> = map_bytes
        .iter()
        .map(|b| Map::open(b))
        .collect::<Result<_, _>>()?;
    let blend = Blend::new(proxy, &maps)?;
    let c = c_blend(&proxy_bytes, &map_bytes)?;
    let k = maps.len();
    let weights = vec![1.0 / k as f32; k];
    const SIDE: usize = 256;
    let kernel = Kernel {
        sigma: 0.5 / SIDE as f32,
    };
    let points: Vec<f32> = (0..SIDE * SIDE)
        .flat_map(|i| {
            [
                ((i % SIDE) as f32 + 0.5) / SIDE as f32,
                ((i / SIDE) as f32 + 0.5) / SIDE as f32,
            ]
        })
        .collect();
    let count = SIDE * SIDE;
    println!(
        "manifest {path}: k = {k}, n = {}, {count} point queries (256² centers), sigma = 0.5 px, equal weights, {repeats} interleaved repetitions",
        blend.n()
    );

    let mut rust_out = vec![PointValue::default(); count];
    let mut c_out = vec![OtbakePointValue::default(); count];
    let batch: PointBatch = std::hint::black_box(otbake_blend_point_batch);
    let mut rust_batch = || -> anyhow::Result<()> {
        for (o, p) in rust_out.iter_mut().zip(points.chunks_exact(2)) {
            *o = blend.point(&weights, p, kernel)?;
        }
        Ok(())
    };
    let mut c_batch = || -> anyhow::Result<()> {
        // SAFETY: `c` is a live blend; the buffers hold `count` points and values.
        let s = unsafe {
            batch(
                c,
                weights.as_ptr(),
                k,
                0,
                points.as_ptr(),
                2,
                count,
                kernel.sigma,
                c_out.as_mut_ptr(),
            )
        };
        anyhow::ensure!(s == OtbakeStatus::Ok, "otbake_blend_point_batch: {s:?}");
        Ok(())
    };
    match args.get(3).map(String::as_str) {
        None => {}
        Some(only @ ("prepare" | "prepared")) => {
            let mut sizes = OtbakePreparedSizes::default();
            // SAFETY: `c` is a live blend; `sizes` is a valid out pointer.
            let s = unsafe { otbake_blend_prepared_sizes(c, &mut sizes) };
            anyhow::ensure!(s == OtbakeStatus::Ok, "otbake_blend_prepared_sizes: {s:?}");
            let mut store = vec![0.0f32; sizes.total];
            let prepare = |store: &mut [f32]| -> anyhow::Result<*mut OtbakePrepared> {
                let mut p = null_mut();
                // SAFETY: `c` is live; `store` outlives the handle (freed before the next
                // prepare into it) and nothing writes it meanwhile.
                let s = unsafe {
                    otbake_prepared_new(
                        c,
                        weights.as_ptr(),
                        k,
                        store.as_mut_ptr(),
                        store.len(),
                        None,
                        null_mut(),
                        &mut p,
                    )
                };
                anyhow::ensure!(s == OtbakeStatus::Ok, "otbake_prepared_new: {s:?}");
                Ok(p)
            };
            if only == "prepare" {
                for _ in 0..repeats {
                    let p = prepare(&mut store)?;
                    // SAFETY: nothing else uses the handle.
                    unsafe { otbake_prepared_free(p) };
                }
            } else {
                let p = prepare(&mut store)?;
                let mut out = vec![OtbakePointValue::default(); count];
                for _ in 0..repeats {
                    // SAFETY: `p` is live; the buffers hold `count` points and values.
                    let s = unsafe {
                        otbake_prepared_point_batch(
                            p,
                            points.as_ptr(),
                            2,
                            count,
                            kernel.sigma,
                            out.as_mut_ptr(),
                        )
                    };
                    anyhow::ensure!(s == OtbakeStatus::Ok, "otbake_prepared_point_batch: {s:?}");
                }
                // SAFETY: nothing else uses the handle; `store` goes after it.
                unsafe { otbake_prepared_free(p) };
            }
            println!("ran {only} {repeats} times");
            // SAFETY: no batch uses the blend any more; the bytes are still alive.
            unsafe { otbake_blend_free(c) };
            return Ok(());
        }
        Some(only @ ("rust" | "c")) => {
            for _ in 0..repeats {
                if only == "rust" {
                    rust_batch()?
                } else {
                    c_batch()?
                }
            }
            println!("ran the {only} batch {repeats} times");
            // SAFETY: no batch uses the blend any more; the bytes are still alive.
            unsafe { otbake_blend_free(c) };
            return Ok(());
        }
        Some(other) => anyhow::bail!(
            "the third argument is `rust`, `c`, `prepare` or `prepared`, not `{other}`"
        ),
    }
    // One warm-up each: pages of the archives and buffers are resident before timing.
    rust_batch()?;
    c_batch()?;
    let (mut rust_wall, mut c_wall, mut rust_cpu, mut c_cpu, mut pair) =
        (vec![], vec![], vec![], vec![], vec![]);
    // One call timed on this thread's CPU clock: its wall and CPU seconds.
    let one = |f: &mut dyn FnMut() -> anyhow::Result<()>| -> anyhow::Result<(f64, f64)> {
        let t = timing::time(1, timing::Clock::Thread, f)?;
        Ok((t.walls[0], t.cpu))
    };
    for r in 0..repeats {
        let (rw, rc, cw, cc);
        if r % 2 == 0 {
            (rw, rc) = one(&mut rust_batch)?;
            (cw, cc) = one(&mut c_batch)?;
        } else {
            (cw, cc) = one(&mut c_batch)?;
            (rw, rc) = one(&mut rust_batch)?;
        }
        rust_wall.push(rw);
        c_wall.push(cw);
        rust_cpu.push(rc);
        c_cpu.push(cc);
        pair.push(cc / rc);
    }
    for (r, c) in rust_out.iter().zip(&c_out) {
        let same = r.density.to_bits() == c.density.to_bits()
            && r.mass.to_bits() == c.mass.to_bits()
            && r.color.map(f32::to_bits) == c.color.map(f32::to_bits);
        anyhow::ensure!(
            same,
            "the C batch gave other bits than the Rust batch: {r:?} vs {c:?}"
        );
    }
    let ms = |v: &[f64]| median(v) * 1e3;
    println!(
        "Rust batch: median wall {:.2} ms, median thread CPU {:.2} ms",
        ms(&rust_wall),
        ms(&rust_cpu)
    );
    println!(
        "C batch:    median wall {:.2} ms, median thread CPU {:.2} ms",
        ms(&c_wall),
        ms(&c_cpu)
    );
    let mut sorted = pair.clone();
    sorted.sort_by(f64::total_cmp);
    println!(
        "C / Rust: {:.4} (median wall), {:.4} (median thread CPU), {:.4} (median of per-pair CPU ratios; range {:.4}–{:.4}); same bits: yes",
        median(&c_wall) / median(&rust_wall),
        median(&c_cpu) / median(&rust_cpu),
        median(&pair),
        sorted.first().copied().unwrap_or(f64::NAN),
        sorted.last().copied().unwrap_or(f64::NAN),
    );
    // SAFETY: no batch uses the blend any more; the bytes are still alive.
    unsafe { otbake_blend_free(c) };
    Ok(())
}
