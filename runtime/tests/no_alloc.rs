//! Proof that queries never allocate: a counting global allocator sees zero allocations across
//! open, blend construction and every query.

mod common;

use otbake_runtime::{
    AdaptiveKernel, Blend, Kernel, Map, PointValue, PreparedBuffers, Proxy, Region, SplatTarget,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Set on the thread under test only: the test harness's own threads allocate concurrently
    /// (output capture, bookkeeping), which made a global count flaky.
    static COUNTING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn count() {
    if COUNTING.try_with(|c| c.get()).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn queries_do_not_allocate() {
    let f = common::fixture(7, 500, 2, 4, 3, [3; 32]);
    let mut density = vec![0.0f32; 32 * 32];
    let mut color = vec![0.0f32; 32 * 32 * 3];
    let mut grid = vec![PointValue::default(); 32 * 8];
    let mut rgba = vec![0.0f32; 32 * 32 * 4];
    let mut buffers: [Vec<f32>; 4] = Default::default();
    {
        let proxy = Proxy::open(&f.proxy).unwrap();
        let maps: Vec<Map<'_>> = f.maps.iter().map(|m| Map::open(m).unwrap()).collect();
        let s = Blend::new(proxy, &maps).unwrap().prepared_sizes();
        for (b, len) in buffers
            .iter_mut()
            .zip([s.positions, s.colors, s.node_boxes, s.node_colors])
        {
            b.resize(len, 0.0);
        }
    }
    COUNTING.with(|c| c.set(true));
    // The counter sees this thread's allocations.
    let probe = ALLOCATIONS.load(Ordering::SeqCst);
    drop(std::hint::black_box(Vec::<u8>::with_capacity(1)));
    assert_eq!(ALLOCATIONS.load(Ordering::SeqCst), probe + 1);
    let before = ALLOCATIONS.load(Ordering::SeqCst);

    let proxy = Proxy::open(&f.proxy).unwrap();
    let maps = [
        Map::open(&f.maps[0]).unwrap(),
        Map::open(&f.maps[1]).unwrap(),
        Map::open(&f.maps[2]).unwrap(),
    ];
    let blend = Blend::new(proxy, &maps).unwrap();
    let w = [0.2f32, 0.3, 0.5];
    let mut acc = 0.0f32;
    for q in 0..100 {
        let p = [(q as f32 * 0.37) % 1.0, (q as f32 * 0.61) % 1.0];
        acc += blend.point(&w, &p, Kernel { sigma: 0.03 }).unwrap().density;
        acc += blend
            .range(&w, &[p[0] - 0.1, p[1] - 0.1], &[p[0] + 0.1, p[1] + 0.1])
            .unwrap()
            .mass;
        acc += blend.sample(&w, q).unwrap().position[0];
        let ak = AdaptiveKernel {
            scale: 2.0,
            min_sigma: 0.002,
            max_sigma: 0.05,
        };
        acc += blend.point_adaptive(&w, &p, ak).unwrap().density;
        acc += blend.bandwidth(&w, q, ak).unwrap();
        // Errors do not allocate either.
        assert!(blend
            .point(&[0.5, 0.5, 0.5], &p, Kernel { sigma: 0.03 })
            .is_err());
    }
    blend
        .splat(
            &w,
            Kernel { sigma: 0.02 },
            SplatTarget {
                res: [32, 32, 1, 1],
                density: &mut density,
                color: Some(&mut color),
            },
        )
        .unwrap();

    // Prepared blends and region queries live in the caller's buffers.
    let [p, c, b, nc] = &mut buffers;
    let prep = blend
        .prepare(
            &w,
            PreparedBuffers {
                positions: p,
                colors: c,
                node_boxes: b,
                node_colors: nc,
            },
        )
        .unwrap();
    let k = Kernel { sigma: 0.02 };
    acc += prep.point(&[0.5, 0.5], k).unwrap().density;
    acc += prep.range(&[0.2, 0.2], &[0.7, 0.7]).unwrap().mass;
    acc += prep.sample(3).unwrap().position[1];
    let res = [32, 32, 1, 1];
    prep.point_grid(k, Region::rows(res, 8, 8), &mut grid)
        .unwrap();
    prep.splat_region(
        k,
        Region::rows(res, 0, 8),
        &mut density[..256],
        Some(&mut color[..768]),
    )
    .unwrap();
    prep.splat(
        k,
        SplatTarget {
            res,
            density: &mut density,
            color: None,
        },
    )
    .unwrap();
    acc += grid.iter().map(|v| v.density).sum::<f32>();
    // RGBA cells, prepared and mixed on the fly (the 3×3 blocks at σ = ½ cell, and the general
    // path).
    for sigma in [0.5 / 32.0, 0.02] {
        let k = Kernel { sigma };
        prep.splat_region_rgba(k, Region::full(res), &mut rgba)
            .unwrap();
        blend
            .splat_region_rgba(&w, k, Region::rows(res, 4, 8), &mut rgba[..32 * 8 * 4])
            .unwrap();
    }
    acc += rgba.iter().sum::<f32>();

    let after = ALLOCATIONS.load(Ordering::SeqCst);
    COUNTING.with(|c| c.set(false));
    assert_eq!(
        after - before,
        0,
        "the runtime allocated {} times",
        after - before
    );
    assert!(acc > 0.0 && density.iter().sum::<f32>() > 0.0);
}
