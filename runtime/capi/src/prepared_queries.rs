//! The queries of a prepared blend ([`OtbakePrepared`]): point, range and sample (each once and as
//! a batch), whole-grid and region splats (planar and RGBA), point grids, and their size queries.
//! The same bits as the blend's queries for the prepared weights; no weights to pass or check.
//!
//! Batch conventions are the blend's without weights: `count` elements, points `count · dim`
//! floats, point-major; results to `out[0 .. count]`; a batch stops at the first refused element
//! (earlier results written, its index in `otbake_last_error`). Outputs must overlap neither the
//! inputs nor the prepared buffer (`OVERLAP`); inputs may lie in the buffer (e.g. its positions).
//!
//! Thread safety of every function here: any thread, concurrently with any other call on the
//! same handle except its `_free` (prepared handles are immutable); each call writes only its own
//! outputs, so calls on disjoint buffers (bands of one image) may run at the same time.

use crate::args::OtbakeSample;
use crate::args::{batch, check_dim, OtbakePointValue, OtbakeRangeValue, OtbakeRegion};
use crate::guard::{disjoint, entry, handle, mul, out, slice, slice_mut};
use crate::prepared::OtbakePrepared;
use crate::splat::resolution;
use crate::status::{Failure, OtbakeStatus};
use core::mem::{align_of, offset_of, size_of};
use otbake_runtime::{Kernel, PointValue, Region, SplatTarget};

// `otbake_prepared_point_grid` hands the caller's `OtbakePointValue` array to the runtime as
// `PointValue`s: both are `repr(C)` structs of the same fields in the same order.
const _: () = {
    assert!(size_of::<OtbakePointValue>() == size_of::<PointValue>());
    assert!(align_of::<OtbakePointValue>() == align_of::<PointValue>());
    assert!(offset_of!(OtbakePointValue, density) == offset_of!(PointValue, density));
    assert!(offset_of!(OtbakePointValue, mass) == offset_of!(PointValue, mass));
    assert!(offset_of!(OtbakePointValue, color) == offset_of!(PointValue, color));
};

/// Refuses a null output buffer that a splat needs (`slice_mut` allows null for length 0).
fn needed<T>(ptr: *mut T, name: &'static str, what: &'static str) -> Result<(), Failure> {
    if ptr.is_null() {
        return Err(Failure::arg(OtbakeStatus::NullPointer, name, what));
    }
    Ok(())
}

/// The density, mass and color of the prepared blend at `point[0..dim]` under the fixed Gaussian
/// kernel of width `sigma`, stored at `*out`: the bits `otbake_blend_point` gives for the
/// prepared weights.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (dim not the blend's),
/// `BAD_COORDINATE`, `BAD_KERNEL`, `OVERLAP` (`out` inside the buffer).
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `point` points at `dim` floats, `out` at one writable
/// `OtbakePointValue`.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_point(
    prepared: *const OtbakePrepared,
    point: *const f32,
    dim: usize,
    sigma: f32,
    out: *mut OtbakePointValue,
) -> OtbakeStatus {
    entry("otbake_prepared_point", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        // SAFETY: as above.
        let p = unsafe { slice(point, dim, "point")? };
        h.apart_one(out, "out")?;
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(h.prepared.point(p, Kernel { sigma })?.into());
        Ok(())
    })
}

/// [`otbake_prepared_point`] for `count` points: `points` holds `count · dim` floats, results go
/// to `out[0 .. count]`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `points` points at `count · dim` floats, `out` at
/// `count` writable values.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_point_batch(
    prepared: *const OtbakePrepared,
    points: *const f32,
    dim: usize,
    count: usize,
    sigma: f32,
    out: *mut OtbakePointValue,
) -> OtbakeStatus {
    entry("otbake_prepared_point_batch", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        check_dim(dim, h.prepared.dim())?;
        // SAFETY: as above.
        let p = unsafe { slice(points, mul(count, dim, "count")?, "points")? };
        // SAFETY: as above; checked disjoint from the input and the buffer below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", p)?;
        h.apart(o, "out")?;
        let kernel = Kernel { sigma };
        batch(o, |i| h.prepared.point(&p[i * dim..(i + 1) * dim], kernel))
    })
}

/// Points, mass and color of the prepared blend inside the closed box `[lo, hi]` (`dim`
/// coordinates each), stored at `*out`: the bits of `otbake_blend_range` for the prepared
/// weights.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_COORDINATE`,
/// `MISSING_ATTRIBUTE` (a colored map without node color sums), `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `lo` and `hi` point at `dim` floats each, `out` at one
/// writable `OtbakeRangeValue`.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_range(
    prepared: *const OtbakePrepared,
    lo: *const f32,
    hi: *const f32,
    dim: usize,
    out: *mut OtbakeRangeValue,
) -> OtbakeStatus {
    entry("otbake_prepared_range", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        // SAFETY: as above.
        let (l, hi) = unsafe { (slice(lo, dim, "lo")?, slice(hi, dim, "hi")?) };
        h.apart_one(out, "out")?;
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(h.prepared.range(l, hi)?.into());
        Ok(())
    })
}

/// [`otbake_prepared_range`] for `count` boxes: `lo` and `hi` hold `count · dim` floats each.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `lo` and `hi` point at `count · dim` floats each, `out`
/// at `count` writable values.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_range_batch(
    prepared: *const OtbakePrepared,
    lo: *const f32,
    hi: *const f32,
    dim: usize,
    count: usize,
    out: *mut OtbakeRangeValue,
) -> OtbakeStatus {
    entry("otbake_prepared_range_batch", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        check_dim(dim, h.prepared.dim())?;
        let len = mul(count, dim, "count")?;
        // SAFETY: as above.
        let (l, hs) = unsafe { (slice(lo, len, "lo")?, slice(hi, len, "hi")?) };
        // SAFETY: as above; checked disjoint from the inputs and the buffer below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", l)?;
        disjoint(o, "out", hs)?;
        h.apart(o, "out")?;
        batch(o, |i| {
            let r = i * dim..(i + 1) * dim;
            h.prepared.range(&l[r.clone()], &hs[r])
        })
    })
}

/// The `index`-th point of the prepared blend (a sample of the barycenter: each point carries
/// mass 1/n), stored at `*out`: the bits of `otbake_blend_sample` for the prepared weights.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `INDEX_OUT_OF_RANGE`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `out` points at one writable `OtbakeSample`.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_sample(
    prepared: *const OtbakePrepared,
    index: u32,
    out: *mut OtbakeSample,
) -> OtbakeStatus {
    entry("otbake_prepared_sample", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        h.apart_one(out, "out")?;
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(h.prepared.sample(index)?.into());
        Ok(())
    })
}

/// [`otbake_prepared_sample`] for the `count` indices `indices[0..count]`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `indices` points at `count` values, `out` at `count`
/// writable samples.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_sample_batch(
    prepared: *const OtbakePrepared,
    indices: *const u32,
    count: usize,
    out: *mut OtbakeSample,
) -> OtbakeStatus {
    entry("otbake_prepared_sample_batch", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        // SAFETY: as above.
        let idx = unsafe { slice(indices, count, "indices")? };
        // SAFETY: as above; checked disjoint from the input and the buffer below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", idx)?;
        h.apart(o, "out")?;
        batch(o, |i| h.prepared.sample(idx[i]))
    })
}

/// The number of cells of a `res[0..dim]` grid, stored at `*cells`: `otbake_prepared_splat`
/// needs `cells` density floats and `3 · cells` color floats.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (dim not the blend's),
/// `BAD_REGION`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `res` points at `dim` values, `cells` at one writable
/// size.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_grid_cells(
    prepared: *const OtbakePrepared,
    res: *const u32,
    dim: usize,
    cells: *mut usize,
) -> OtbakeStatus {
    entry("otbake_prepared_grid_cells", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        let d = h.prepared.dim();
        // SAFETY: as above.
        let r = unsafe { resolution(res, dim, d)? };
        h.apart_one(cells, "cells")?;
        // SAFETY: as above.
        let o = unsafe { out(cells, "cells")? };
        o.set(Region::full(r).cells(d)?);
        Ok(())
    })
}

/// The number of cells of `region`, stored at `*cells`: `otbake_prepared_point_grid` needs
/// `cells` values, `otbake_prepared_splat_region` `cells` density and `3 · cells` color floats,
/// `otbake_prepared_splat_region_rgba` `4 · cells` floats.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_REGION`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `cells` points at one writable size.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_region_cells(
    prepared: *const OtbakePrepared,
    region: OtbakeRegion,
    cells: *mut usize,
) -> OtbakeStatus {
    entry("otbake_prepared_region_cells", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        h.apart_one(cells, "cells")?;
        // SAFETY: as above.
        let o = unsafe { out(cells, "cells")? };
        o.set(Region::from(region).cells(h.prepared.dim())?);
        Ok(())
    })
}

/// The planar density and (unless `color` is null) color buffers of a splat, checked: non-null
/// density, disjoint from each other and from the prepared buffer.
///
/// # Safety
///
/// `density` points at `density_len` writable floats, `color` (unless null) at `color_len`, for
/// the duration of the entry point's call.
unsafe fn planar<'a>(
    h: &OtbakePrepared,
    density: *mut f32,
    density_len: usize,
    color: *mut f32,
    color_len: usize,
) -> Result<(&'a mut [f32], Option<&'a mut [f32]>), Failure> {
    needed(
        density,
        "density",
        "is null: pass the grid's density buffer",
    )?;
    // SAFETY: the caller's contract (non-null checked); checked disjoint from `color` and the
    // buffer below, before any write.
    let d = unsafe { slice_mut(density, density_len, "density")? };
    h.apart(d, "density")?;
    let c = if color.is_null() {
        None
    } else {
        // SAFETY: as above.
        let c = unsafe { slice_mut(color, color_len, "color")? };
        disjoint(c, "color", d)?;
        h.apart(c, "color")?;
        Some(c)
    };
    Ok((d, c))
}

/// ADDS the kernel reconstruction of the prepared blend (fixed kernel `sigma`) to every cell of a
/// `res[0..dim]` grid: `density[0 .. cells]` and, unless `color` is null, `color[0 .. 3 · cells]`
/// (premultiplied RGB), axis 0 fastest — the bits `otbake_blend_splat` adds for the prepared
/// weights.
///
/// Errors: `NULL_POINTER` (density), `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (dim, or a buffer
/// other than `otbake_prepared_grid_cells` says), `BAD_KERNEL`, `BAD_REGION`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `res` points at `dim` values, `density` at
/// `density_len` writable floats and `color` (unless null) at `color_len`.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn otbake_prepared_splat(
    prepared: *const OtbakePrepared,
    sigma: f32,
    res: *const u32,
    dim: usize,
    density: *mut f32,
    density_len: usize,
    color: *mut f32,
    color_len: usize,
) -> OtbakeStatus {
    entry("otbake_prepared_splat", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        // SAFETY: as above.
        let r = unsafe { resolution(res, dim, h.prepared.dim())? };
        // SAFETY: as above.
        let (d, c) = unsafe { planar(h, density, density_len, color, color_len)? };
        h.prepared.splat(
            Kernel { sigma },
            SplatTarget {
                res: r,
                density: d,
                color: c,
            },
        )?;
        Ok(())
    })
}

/// ADDS the splat of the prepared blend (fixed kernel `sigma`) to the cells of `region` only:
/// `density[0 .. cells]` and, unless `color` is null, `color[0 .. 3 · cells]`, the region's
/// cells axis 0 fastest — exactly the bits `otbake_prepared_splat` adds to those cells of the
/// whole grid.
///
/// Errors: `NULL_POINTER` (density), `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (a buffer other than
/// `otbake_prepared_region_cells` says), `BAD_KERNEL`, `BAD_REGION`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `density` points at `density_len` writable floats and
/// `color` (unless null) at `color_len`.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_splat_region(
    prepared: *const OtbakePrepared,
    sigma: f32,
    region: OtbakeRegion,
    density: *mut f32,
    density_len: usize,
    color: *mut f32,
    color_len: usize,
) -> OtbakeStatus {
    entry("otbake_prepared_splat_region", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        // SAFETY: as above.
        let (d, c) = unsafe { planar(h, density, density_len, color, color_len)? };
        h.prepared
            .splat_region(Kernel { sigma }, region.into(), d, c)?;
        Ok(())
    })
}

/// ADDS the splat of the prepared blend (fixed kernel `sigma`) to the cells of `region` as RGBA:
/// `rgba[0 .. 4 · cells]`, per cell the premultiplied RGB and then the density — the bits
/// `otbake_blend_splat_region_rgba` adds for the prepared weights.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (`rgba_len` other than
/// `4 · otbake_prepared_region_cells`), `BAD_KERNEL`, `BAD_REGION`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `rgba` points at `rgba_len` writable floats.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_splat_region_rgba(
    prepared: *const OtbakePrepared,
    sigma: f32,
    region: OtbakeRegion,
    rgba: *mut f32,
    rgba_len: usize,
) -> OtbakeStatus {
    entry("otbake_prepared_splat_region_rgba", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        needed(rgba, "rgba", "is null: pass the region's RGBA buffer")?;
        // SAFETY: as above (non-null checked); checked apart from the buffer before any write.
        let o = unsafe { slice_mut(rgba, rgba_len, "rgba")? };
        h.apart(o, "rgba")?;
        h.prepared
            .splat_region_rgba(Kernel { sigma }, region.into(), o)?;
        Ok(())
    })
}

/// Point queries at the centers of every cell of `region` (fixed kernel `sigma`), written to
/// `out[0 .. out_len]`, `out_len` the region's cells (`otbake_prepared_region_cells`), axis 0
/// fastest: `out[c]` is the bits of `otbake_prepared_point` at cell `c`'s center, at the cost of
/// one traversal for the whole region. Keeps some 50 KB of scratch on the calling thread's stack.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (`out_len` not the region's
/// cells), `BAD_KERNEL`, `BAD_REGION`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `out` points at `out_len` writable values.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_point_grid(
    prepared: *const OtbakePrepared,
    sigma: f32,
    region: OtbakeRegion,
    out: *mut OtbakePointValue,
    out_len: usize,
) -> OtbakeStatus {
    entry("otbake_prepared_point_grid", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        needed(
            out,
            "out",
            "is null: pass the region's cells of OtbakePointValue",
        )?;
        // SAFETY: as above (non-null checked); checked apart from the buffer before any write.
        let o = unsafe { slice_mut(out, out_len, "out")? };
        h.apart(o, "out")?;
        // SAFETY: `OtbakePointValue` and the runtime's `PointValue` are both `repr(C)` structs of
        // the same fields (two `f32`, then `[f32; 3]`) in the same order, so they have one layout
        // (asserted at compile time above) and every bit pattern is valid for both; the new slice
        // covers exactly `o`'s memory and replaces `o` (not used again) for the call.
        let values: &mut [PointValue] =
            unsafe { core::slice::from_raw_parts_mut(o.as_mut_ptr().cast(), o.len()) };
        h.prepared
            .point_grid(Kernel { sigma }, region.into(), values)?;
        Ok(())
    })
}
