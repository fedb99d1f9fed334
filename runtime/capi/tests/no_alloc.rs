//! Proof that no C ABI query allocates: a counting global allocator sees zero allocations across
//! every query and batch of a blend, a prepared blend and a BRDF blend, their error paths (which
//! write the thread's last error) included. Opening handles allocates (one box each) and happens
//! before; so does making the prepared handle (its buffer is the test's).

mod common;

use otbake_capi::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::ptr::null_mut;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Set on the thread under test only (the harness's threads allocate concurrently).
    static COUNTING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn count() {
    if COUNTING.try_with(|c| c.get()).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
    }
}

// SAFETY: forwards to the system allocator unchanged; counting has no effect on the memory.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: the caller's contract, forwarded.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Opens `a` as a proxy and its maps (handles, before counting starts).
fn open(a: &common::Archives) -> (*mut OtbakeProxy, Vec<*const OtbakeMap>) {
    let mut proxy = null_mut();
    // SAFETY: the archive bytes outlive the handles (the test holds them to the end).
    let s = unsafe { otbake_proxy_open(a.proxy.as_ptr(), a.proxy.len(), &mut proxy) };
    assert_eq!(s, OtbakeStatus::Ok);
    let maps = a
        .maps
        .iter()
        .map(|m| {
            let mut h = null_mut();
            // SAFETY: as above.
            assert_eq!(
                unsafe { otbake_map_open(m.as_ptr(), m.len(), &mut h) },
                OtbakeStatus::Ok
            );
            h.cast_const()
        })
        .collect();
    (proxy, maps)
}

#[test]
fn queries_do_not_allocate() {
    let flat = common::archives(3, 400, 2, 2, [7; 32]);
    let cube = common::archives(4, 400, 3, 2, [8; 32]);
    let (proxy, maps) = open(&flat);
    let (bproxy, bmaps) = open(&cube);
    let (mut blend, mut brdf) = (null_mut(), null_mut());
    // SAFETY: live handles, valid out pointers.
    unsafe {
        assert_eq!(
            otbake_blend_new(proxy, maps.as_ptr(), 2, &mut blend),
            OtbakeStatus::Ok
        );
        let k = otbake_brdf_default_kernel();
        assert_eq!(
            otbake_brdf_new_adaptive(bproxy, bmaps.as_ptr(), 2, k, &mut brdf),
            OtbakeStatus::Ok
        );
    }
    let w = [0.25f32, 0.75];
    let points: Vec<f32> = (0..64).map(|i| (i as f32 * 0.37) % 1.0).collect();
    let mut values = vec![OtbakePointValue::default(); 32];
    let mut ranges = vec![OtbakeRangeValue::default(); 32];
    let mut samples = vec![OtbakeSample::default(); 32];
    let mut sigmas = vec![0.0f32; 32];
    let indices: Vec<u32> = (0..32).map(|i| i * 7).collect();
    let (mut density, mut color, mut rgba) = (
        vec![0.0f32; 16 * 16],
        vec![0.0f32; 16 * 16 * 3],
        vec![0.0f32; 16 * 4 * 4],
    );
    let dirs: Vec<f64> = (0..32)
        .flat_map(|i| [0.3, 0.1 * (i % 5) as f64, 0.8])
        .collect();
    let xi: Vec<f64> = (0..32 * 5).map(|i| (i as f64 * 0.618) % 1.0).collect();
    let mut rgb = vec![0.0f32; 32 * 3];
    let mut pdfs = vec![0.0f64; 32];
    let mut bs = vec![OtbakeBrdfSample::default(); 32];
    let kernel = OtbakeAdaptiveKernel {
        scale: 2.0,
        min_sigma: 0.005,
        max_sigma: 0.1,
    };
    let region = OtbakeRegion {
        res: [16, 16, 1, 1],
        start: [0, 4, 0, 0],
        size: [16, 4, 1, 1],
    };
    let mut cells = 0usize;
    let mut sizes = OtbakePreparedSizes::default();
    // SAFETY: a live blend handle, a valid out pointer.
    assert_eq!(
        unsafe { otbake_blend_prepared_sizes(blend, &mut sizes) },
        OtbakeStatus::Ok
    );
    let mut store = vec![0.0f32; sizes.total];
    let mut prepared = null_mut();
    // SAFETY: `store` outlives the handle (freed at the end) and is not written meanwhile.
    assert_eq!(
        unsafe {
            otbake_prepared_new(
                blend,
                w.as_ptr(),
                2,
                store.as_mut_ptr(),
                store.len(),
                None,
                null_mut(),
                &mut prepared,
            )
        },
        OtbakeStatus::Ok
    );
    let mut grid = vec![OtbakePointValue::default(); 64];
    let (mut pdensity, mut pcolor) = (vec![0.0f32; 64], vec![0.0f32; 64 * 3]);
    let mut info = std::mem::MaybeUninit::<OtbakePreparedInfo>::uninit();
    let (mut at, mut len) = (std::ptr::null::<f32>(), 0usize);

    COUNTING.with(|c| c.set(true));
    let probe = ALLOCATIONS.load(Ordering::SeqCst);
    drop(std::hint::black_box(Vec::<u8>::with_capacity(1)));
    assert_eq!(
        ALLOCATIONS.load(Ordering::SeqCst),
        probe + 1,
        "the counter sees this thread"
    );
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    // SAFETY: live handles; every pointer covers the lengths passed.
    let statuses = unsafe {
        [
            otbake_blend_point(
                blend,
                w.as_ptr(),
                2,
                points.as_ptr(),
                2,
                0.05,
                values.as_mut_ptr(),
            ),
            otbake_blend_point_batch(
                blend,
                w.as_ptr(),
                2,
                0,
                points.as_ptr(),
                2,
                32,
                0.05,
                values.as_mut_ptr(),
            ),
            otbake_blend_point_adaptive_batch(
                blend,
                w.as_ptr(),
                2,
                0,
                points.as_ptr(),
                2,
                32,
                kernel,
                values.as_mut_ptr(),
            ),
            otbake_blend_range_batch(
                blend,
                w.as_ptr(),
                2,
                0,
                points.as_ptr(),
                points.as_ptr(),
                2,
                32,
                ranges.as_mut_ptr(),
            ),
            otbake_blend_sample_batch(
                blend,
                w.as_ptr(),
                2,
                0,
                indices.as_ptr(),
                32,
                samples.as_mut_ptr(),
            ),
            otbake_blend_bandwidth_batch(
                blend,
                w.as_ptr(),
                2,
                0,
                indices.as_ptr(),
                32,
                kernel,
                sigmas.as_mut_ptr(),
            ),
            otbake_blend_grid_cells(blend, [16u32, 16].as_ptr(), 2, &mut cells),
            otbake_blend_splat(
                blend,
                w.as_ptr(),
                2,
                0.05,
                [16u32, 16].as_ptr(),
                2,
                density.as_mut_ptr(),
                256,
                color.as_mut_ptr(),
                768,
            ),
            otbake_blend_region_cells(blend, region, &mut cells),
            otbake_blend_splat_region_rgba(
                blend,
                w.as_ptr(),
                2,
                0.05,
                region,
                rgba.as_mut_ptr(),
                256,
            ),
            otbake_brdf_eval_batch(
                brdf,
                w.as_ptr(),
                2,
                0,
                dirs.as_ptr(),
                dirs.as_ptr(),
                32,
                rgb.as_mut_ptr(),
            ),
            otbake_brdf_pdf_batch(
                brdf,
                w.as_ptr(),
                2,
                0,
                dirs.as_ptr(),
                dirs.as_ptr(),
                32,
                pdfs.as_mut_ptr(),
            ),
            otbake_brdf_sample_batch(
                brdf,
                w.as_ptr(),
                2,
                0,
                indices.as_ptr(),
                xi.as_ptr(),
                32,
                bs.as_mut_ptr(),
            ),
            otbake_blend_prepared_sizes(blend, &mut sizes),
            otbake_prepared_info(prepared, info.as_mut_ptr()),
            otbake_prepared_positions(prepared, &mut at, &mut len),
            otbake_prepared_colors(prepared, &mut at, &mut len),
            otbake_prepared_point(prepared, points.as_ptr(), 2, 0.05, values.as_mut_ptr()),
            otbake_prepared_point_batch(
                prepared,
                points.as_ptr(),
                2,
                32,
                0.05,
                values.as_mut_ptr(),
            ),
            otbake_prepared_range_batch(
                prepared,
                points.as_ptr(),
                points.as_ptr(),
                2,
                32,
                ranges.as_mut_ptr(),
            ),
            otbake_prepared_sample_batch(prepared, indices.as_ptr(), 32, samples.as_mut_ptr()),
            otbake_prepared_grid_cells(prepared, [16u32, 16].as_ptr(), 2, &mut cells),
            otbake_prepared_region_cells(prepared, region, &mut cells),
            otbake_prepared_splat(
                prepared,
                0.05,
                [16u32, 16].as_ptr(),
                2,
                density.as_mut_ptr(),
                256,
                color.as_mut_ptr(),
                768,
            ),
            otbake_prepared_splat_region(
                prepared,
                0.05,
                region,
                pdensity.as_mut_ptr(),
                64,
                pcolor.as_mut_ptr(),
                192,
            ),
            otbake_prepared_splat_region_rgba(prepared, 0.05, region, rgba.as_mut_ptr(), 256),
            otbake_prepared_point_grid(prepared, 0.05, region, grid.as_mut_ptr(), 64),
        ]
    };
    // Refusals record their text in the thread's last-error buffer: no allocation either.
    // SAFETY: as above; the null and short arguments are the point.
    let refusals = unsafe {
        [
            otbake_blend_point(
                blend,
                w.as_ptr(),
                1,
                points.as_ptr(),
                2,
                0.05,
                values.as_mut_ptr(),
            ),
            otbake_blend_point_batch(
                blend,
                w.as_ptr(),
                2,
                0,
                std::ptr::null(),
                2,
                32,
                0.05,
                values.as_mut_ptr(),
            ),
            otbake_blend_sample(blend, w.as_ptr(), 2, 400, samples.as_mut_ptr()),
            otbake_brdf_eval(
                brdf,
                [0.5f32, 0.25].as_ptr(),
                2,
                dirs.as_ptr(),
                dirs.as_ptr(),
                rgb.as_mut_ptr(),
            ),
            otbake_prepared_sample(prepared, 400, samples.as_mut_ptr()),
            otbake_prepared_point_grid(prepared, 0.05, region, grid.as_mut_ptr(), 63),
        ]
    };
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    COUNTING.with(|c| c.set(false));
    assert!(
        statuses.iter().all(|&s| s == OtbakeStatus::Ok),
        "{statuses:?}"
    );
    assert_eq!(
        refusals,
        [
            OtbakeStatus::BadCount,
            OtbakeStatus::NullPointer,
            OtbakeStatus::IndexOutOfRange,
            OtbakeStatus::BadWeights,
            OtbakeStatus::IndexOutOfRange,
            OtbakeStatus::BadCount,
        ]
    );
    assert_eq!(
        after - before,
        0,
        "C ABI queries allocated {} times",
        after - before
    );
    assert!(values.iter().any(|v| v.density > 0.0) && density.iter().any(|&d| d > 0.0));
    assert!(grid.iter().any(|v| v.density > 0.0) && pdensity.iter().any(|&d| d > 0.0));
    // SAFETY: the handles are live and used by nothing else; `store` is freed after its handle.
    unsafe {
        otbake_prepared_free(prepared);
        drop(store);
        otbake_blend_free(blend);
        otbake_brdf_free(brdf);
        otbake_proxy_free(proxy);
        otbake_proxy_free(bproxy);
        for m in maps.into_iter().chain(bmaps) {
            otbake_map_free(m.cast_mut());
        }
    }
}
