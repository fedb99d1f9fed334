//! Splats: the kernel reconstruction of a whole grid (planar density and color buffers), or of a
//! region of it into RGBA cells — the per-frame call of a renderer whose weights change every
//! frame, band by band on its own threads. Size queries say how many cells the caller's buffers
//! need; nothing here allocates.
//!
//! Thread safety: any thread, concurrently with any other query of the same blend; calls on
//! disjoint buffers (e.g. disjoint bands of one image) may run at the same time.

use crate::args::OtbakeRegion;
use crate::guard::{entry, handle, out, slice, slice_mut};
use crate::handles::OtbakeBlend;
use crate::status::{Failure, OtbakeStatus};
use otbake_runtime::{Kernel, Region, SplatTarget, MAX_DIM};

/// The grid resolution `res[0..dim]` as the runtime's fixed array (unused axes 1).
///
/// # Safety
///
/// `res` points at `dim` readable values.
pub(crate) unsafe fn resolution(
    res: *const u32,
    dim: usize,
    blend_dim: usize,
) -> Result<[u32; MAX_DIM], Failure> {
    if dim != blend_dim {
        return Err(Failure::Count {
            name: "dim",
            expected: blend_dim,
            found: dim,
        });
    }
    // SAFETY: the caller's contract.
    let r = unsafe { slice(res, dim, "res")? };
    let mut full = [1u32; MAX_DIM];
    full[..dim].copy_from_slice(r);
    Ok(full)
}

/// The number of cells of a `res[0..dim]` grid, stored at `*cells`: `otbake_blend_splat` needs
/// `cells` density floats and `3 · cells` color floats.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (dim not the blend's),
/// `BAD_REGION` (a resolution of 0, or a cell count that overflows).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `res` points at `dim` values, `cells` at one writable size.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_grid_cells(
    blend: *const OtbakeBlend,
    res: *const u32,
    dim: usize,
    cells: *mut usize,
) -> OtbakeStatus {
    entry("otbake_blend_grid_cells", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let r = unsafe { resolution(res, dim, b.dim())? };
        // SAFETY: as above.
        let o = unsafe { out(cells, "cells")? };
        o.set(Region::full(r).cells(b.dim())?);
        Ok(())
    })
}

/// The number of cells of `region`, stored at `*cells`: `otbake_blend_splat_region_rgba` needs
/// `4 · cells` floats.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_REGION`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `cells` points at one writable size.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_region_cells(
    blend: *const OtbakeBlend,
    region: OtbakeRegion,
    cells: *mut usize,
) -> OtbakeStatus {
    entry("otbake_blend_region_cells", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let o = unsafe { out(cells, "cells")? };
        o.set(Region::from(region).cells(b.dim())?);
        Ok(())
    })
}

/// ADDS the kernel reconstruction of the blend for `weights[0..k]` (fixed kernel `sigma`) to every
/// cell of a `res[0..dim]` grid: `density[0 .. cells]` (zero it first for a fresh image) and, if
/// `color` is not null, `color[0 .. 3 · cells]` (premultiplied RGB); axis 0 fastest. Each cell
/// gets what a point query at its center returns, within the runtime's splat tolerance.
///
/// Errors: `NULL_POINTER` (density), `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (k, dim, or a buffer
/// shorter or longer than `otbake_blend_grid_cells` says), `BAD_WEIGHTS`, `BAD_KERNEL`,
/// `BAD_REGION`, `OVERLAP` (density and color overlap).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `res` at `dim` values,
/// `density` at `density_len` writable floats and `color` (unless null) at `color_len`.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_splat(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    sigma: f32,
    res: *const u32,
    dim: usize,
    density: *mut f32,
    density_len: usize,
    color: *mut f32,
    color_len: usize,
) -> OtbakeStatus {
    entry("otbake_blend_splat", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        // SAFETY: as above.
        let r = unsafe { resolution(res, dim, b.dim())? };
        if density.is_null() {
            return Err(Failure::arg(
                OtbakeStatus::NullPointer,
                "density",
                "is null: pass the grid's density buffer",
            ));
        }
        // SAFETY: as above (non-null checked); checked disjoint from `color` below.
        let d = unsafe { slice_mut(density, density_len, "density")? };
        let c = if color.is_null() {
            None
        } else {
            // SAFETY: as above.
            let c = unsafe { slice_mut(color, color_len, "color")? };
            crate::guard::disjoint(c, "color", d)?;
            crate::guard::disjoint(c, "color", w)?;
            Some(c)
        };
        crate::guard::disjoint(d, "density", w)?;
        b.splat(
            w,
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

/// ADDS the splat of the blend for `weights[0..k]` (fixed kernel `sigma`) to the cells of `region`
/// only, as RGBA: `rgba[0 .. 4 · cells]` holds, per cell (axis 0 fastest), the premultiplied RGB
/// and then the density where alpha goes — the same bits `otbake_blend_splat` adds to those cells
/// of the whole grid. The maps are mixed for the weights as the region reads them: no prepared
/// buffers, so this is the call to make once per frame with new weights (split an image into
/// bands of rows, one call per band and thread).
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (k, or `rgba_len` other than
/// `4 · otbake_blend_region_cells`), `BAD_WEIGHTS`, `BAD_KERNEL`, `BAD_REGION`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `rgba` at `rgba_len` writable
/// floats.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_splat_region_rgba(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    sigma: f32,
    region: OtbakeRegion,
    rgba: *mut f32,
    rgba_len: usize,
) -> OtbakeStatus {
    entry("otbake_blend_splat_region_rgba", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        if rgba.is_null() {
            return Err(Failure::arg(
                OtbakeStatus::NullPointer,
                "rgba",
                "is null: pass the region's RGBA buffer",
            ));
        }
        // SAFETY: as above; checked disjoint from the weights below.
        let out = unsafe { slice_mut(rgba, rgba_len, "rgba")? };
        crate::guard::disjoint(out, "rgba", w)?;
        b.splat_region_rgba(w, Kernel { sigma }, region.into(), out)?;
        Ok(())
    })
}
