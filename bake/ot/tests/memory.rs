//! `memory::estimate_bytes` bounds what each solver really allocates: a counting allocator records
//! the peak of live heap bytes during one solve, at small n in 2D and 3D.

use otbake_ot::memory::estimate_bytes;
use otbake_ot::{
    solve, ExactSettings, Problem, SinkhornSettings, SlicedMap, SlicedSettings, SolverSettings,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

struct Counting;
static LIVE: AtomicU64 = AtomicU64::new(0);
static PEAK: AtomicU64 = AtomicU64::new(0);
/// One measurement at a time: the counters are global.
static SERIAL: Mutex<()> = Mutex::new(());

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let now = LIVE.fetch_add(layout.size() as u64, Ordering::SeqCst) + layout.size() as u64;
        PEAK.fetch_max(now, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size() as u64, Ordering::SeqCst);
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A deterministic cloud: a Gaussian-ish source (sums of uniforms) or two blobs as target.
fn cloud(n: usize, dim: usize, seed: u64, blobs: bool) -> Vec<f32> {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut u = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .flat_map(|i| {
            let centre = if blobs {
                0.3 + 0.4 * (i % 2) as f64
            } else {
                0.5
            };
            (0..dim)
                .map(|_| {
                    let g = (u() + u() + u() - 1.5) * if blobs { 0.08 } else { 0.15 };
                    (centre + g).clamp(0.0, 1.0) as f32
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// The peak of live heap bytes during one solve, above what was live before it.
fn peak_of(settings: &SolverSettings, n: usize, dim: usize) -> u64 {
    let _one = SERIAL.lock().unwrap();
    let (source, target) = (cloud(n, dim, 1, false), cloud(n, dim, 2, true));
    let problem = Problem {
        dim,
        source: &source,
        target: &target,
    };
    let before = LIVE.load(Ordering::SeqCst);
    PEAK.store(before, Ordering::SeqCst);
    let solution = solve(&problem, settings).expect("solve");
    let peak = PEAK.load(Ordering::SeqCst) - before;
    drop(solution);
    peak
}

#[test]
fn the_estimate_bounds_the_measured_peak_of_every_solver() {
    let solvers = [
        SolverSettings::Exact(ExactSettings::default()),
        SolverSettings::Sliced(SlicedSettings::default()),
        SolverSettings::Sliced(SlicedSettings {
            map: SlicedMap::Assignment,
            ..SlicedSettings::default()
        }),
        SolverSettings::Sinkhorn(SinkhornSettings::default()),
    ];
    for (dim, s) in [1, 2, 3, 4]
        .into_iter()
        .flat_map(|d| solvers.iter().map(move |s| (d, s)))
    {
        {
            let n = 3000;
            let peak = peak_of(s, n, dim);
            let estimate = estimate_bytes(s, n, dim);
            eprintln!(
                "{} dim {dim} n {n}: peak {peak}, estimate {estimate}",
                s.kind()
            );
            if std::env::var_os("MEASURE").is_some() {
                continue;
            }
            assert!(
                peak <= estimate,
                "{} dim {dim} n {n}: peak {peak} bytes above the estimate {estimate}",
                s.kind()
            );
            // And not absurdly loose: within 20x of the peak.
            assert!(
                estimate <= 20 * peak.max(1),
                "{} dim {dim}: estimate {estimate} vs peak {peak}",
                s.kind()
            );
        }
    }
}
