//! Proof that `otbake-runtime` needs no allocator: a `#![no_std]`, `#![no_main]` binary with its own
//! panic handler and **no global allocator** that links every runtime query. If the runtime (or
//! anything it depends on) used `alloc`, this would fail to link. Built and run by `check.sh`.
#![no_std]
#![no_main]

use core::panic::PanicInfo;
use otbake_runtime::{
    AdaptiveKernel, Blend, Error, Kernel, Map, PointValue, PreparedBuffers, Proxy, Region,
    SplatTarget,
};

/// Archive bytes the optimizer cannot see through (`black_box`), so every query stays linked.
#[repr(C, align(16))]
struct Aligned([u8; 4096]);
static BYTES: Aligned = Aligned([0; 4096]);

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    loop {}
}

/// C entry point: the C library provides only `memcpy`/`memset` and process start-up here; Rust's
/// allocator (`__rust_alloc`) is what must be absent, and no `#[global_allocator]` exists.
#[no_mangle]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
    let bytes: &[u8] = core::hint::black_box(&BYTES.0);
    // The zeroed bytes are not an archive: the run ends in an error, which is the expected exit 3.
    match core::hint::black_box(run(bytes)) {
        Ok(_) => 0,
        Err(_) => 3,
    }
}

/// `core` is precompiled with unwinding tables that name this symbol; with panic=abort it is never
/// called.
#[no_mangle]
pub extern "C" fn rust_eh_personality() {}

fn run(bytes: &[u8]) -> Result<f32, Error> {
    let proxy = Proxy::open(bytes)?;
    let maps = [Map::open(bytes)?, Map::open(bytes)?];
    let blend = Blend::new(proxy, &maps)?;
    // Stored values and their stated error bounds (decoders of every storage).
    let stored = maps[0].position(1).map_or(0.0, |p| p[0])
        + maps[0].position_error(1).map_or(0.0, |e| e[0])
        + maps[0].max_position_error()[1]
        + maps[0].color_error()[2];
    let w = core::hint::black_box([0.5f32, 0.5]);
    let kernel = Kernel { sigma: 0.01 };
    let p = blend.point(&w, &[0.5, 0.5], kernel)?;
    let r = blend.range(&w, &[0.25, 0.25], &[0.75, 0.75])?;
    let s = blend.sample(&w, 0)?;
    let adaptive = AdaptiveKernel {
        scale: 2.0,
        min_sigma: 0.001,
        max_sigma: 0.05,
    };
    let a = blend.point_adaptive(&w, &[0.5, 0.5], adaptive)?;
    let bw = blend.bandwidth(&w, 0, adaptive)?;
    let mut density = [0f32; 16];
    let mut color = [0f32; 48];
    blend.splat(
        &w,
        kernel,
        SplatTarget {
            res: [4, 4, 1, 1],
            density: &mut density,
            color: Some(&mut color),
        },
    )?;
    // A prepared blend in caller buffers (statics here: sized for small archives), and region queries.
    let mut positions = [0f32; 256];
    let mut colors = [0f32; 384];
    let mut node_boxes = [0f32; 1024];
    let mut node_colors = [0f32; 768];
    let prep = blend.prepare(
        &w,
        PreparedBuffers {
            positions: &mut positions,
            colors: &mut colors,
            node_boxes: &mut node_boxes,
            node_colors: &mut node_colors,
        },
    )?;
    let mut grid = [PointValue::default(); 16];
    prep.point_grid(kernel, Region::full([4, 4, 1, 1]), &mut grid)?;
    prep.splat_region(
        kernel,
        Region::rows([4, 4, 1, 1], 1, 2),
        &mut density[..8],
        Some(&mut color[..24]),
    )?;
    // RGBA cells: prepared, and mixed as the splat reads the maps.
    let mut rgba = [0f32; 64];
    prep.splat_region_rgba(kernel, Region::full([4, 4, 1, 1]), &mut rgba)?;
    blend.splat_region_rgba(
        &w,
        kernel,
        Region::rows([4, 4, 1, 1], 1, 2),
        &mut rgba[..32],
    )?;
    let q = prep.point(&[0.5, 0.5], kernel)?;
    Ok(p.density
        + a.density
        + bw
        + r.mass
        + s.position[0]
        + density[5]
        + color[7]
        + grid[3].density
        + rgba[9]
        + q.mass
        + stored)
}
