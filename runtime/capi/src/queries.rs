//! The blend's point-wise queries — point (fixed and adaptive kernel), range, sample, bandwidth,
//! mean mass — each once and as a batch over arrays. No query allocates.
//!
//! Batch conventions: `count` elements; points are `count · dim` floats, point-major; weights are
//! `k` floats used for every element (`weight_stride == 0`) or one vector per element,
//! `weight_stride` floats apart; results go to `out[0 .. count]`. A batch stops at the first
//! element the runtime refuses: the elements before it are written, the status is that element's,
//! and `otbake_last_error` names its index. Outputs must not overlap inputs (`OVERLAP`).
//!
//! Thread safety of every function here: any thread, concurrently with any other query of the
//! same blend (blends are immutable); each call writes only its own `out`.

use crate::args::{
    batch, check_dim, OtbakeAdaptiveKernel, OtbakePointValue, OtbakeRangeValue, OtbakeSample,
    Weights,
};
use crate::guard::{disjoint, entry, handle, mul, out, slice, slice_mut};
use crate::handles::OtbakeBlend;
use crate::status::OtbakeStatus;
use otbake_runtime::Kernel;

/// The density, mass and color of the blend for `weights[0..k]` at `point[0..dim]` under the
/// fixed Gaussian kernel of width `sigma`, stored at `*out`.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT` (k or dim not the blend's),
/// `BAD_WEIGHTS`, `BAD_COORDINATE`, `BAD_KERNEL`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `point` at `dim` floats, `out`
/// at one writable `OtbakePointValue`.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_point(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    point: *const f32,
    dim: usize,
    sigma: f32,
    out: *mut OtbakePointValue,
) -> OtbakeStatus {
    entry("otbake_blend_point", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let (w, p) = unsafe { (slice(weights, k, "weights")?, slice(point, dim, "point")?) };
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(b.point(w, p, Kernel { sigma })?.into());
        Ok(())
    })
}

/// [`otbake_blend_point`] for `count` points: `points` holds `count · dim` floats, results go to
/// `out[0 .. count]` (batch conventions at the top of otbake.h).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at the floats the batch conventions say,
/// `points` at `count · dim` floats, `out` at `count` writable values.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_point_batch(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    points: *const f32,
    dim: usize,
    count: usize,
    sigma: f32,
    out: *mut OtbakePointValue,
) -> OtbakeStatus {
    entry("otbake_blend_point_batch", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        check_dim(dim, b.dim())?;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as above.
        let p = unsafe { slice(points, mul(count, dim, "count")?, "points")? };
        // SAFETY: as above; checked disjoint from the inputs below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", p)?;
        disjoint(o, "out", w.floats())?;
        let kernel = Kernel { sigma };
        batch(o, |i| b.point(w.of(i), &p[i * dim..(i + 1) * dim], kernel))
    })
}

/// The density, mass and color of the blend at `point[0..dim]` under the density-adaptive kernel
/// `kernel`, stored at `*out`.
///
/// Errors: those of [`otbake_blend_point`], and `MISSING_ATTRIBUTE` if a map stores no spacings.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// As [`otbake_blend_point`].
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_point_adaptive(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    point: *const f32,
    dim: usize,
    kernel: OtbakeAdaptiveKernel,
    out: *mut OtbakePointValue,
) -> OtbakeStatus {
    entry("otbake_blend_point_adaptive", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let (w, p) = unsafe { (slice(weights, k, "weights")?, slice(point, dim, "point")?) };
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(b.point_adaptive(w, p, kernel.into())?.into());
        Ok(())
    })
}

/// [`otbake_blend_point_adaptive`] for `count` points (batch conventions at the top of otbake.h).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// As [`otbake_blend_point_batch`].
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_point_adaptive_batch(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    points: *const f32,
    dim: usize,
    count: usize,
    kernel: OtbakeAdaptiveKernel,
    out: *mut OtbakePointValue,
) -> OtbakeStatus {
    entry("otbake_blend_point_adaptive_batch", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        check_dim(dim, b.dim())?;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as above.
        let p = unsafe { slice(points, mul(count, dim, "count")?, "points")? };
        // SAFETY: as above; checked disjoint from the inputs below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", p)?;
        disjoint(o, "out", w.floats())?;
        let kernel = kernel.into();
        batch(o, |i| {
            b.point_adaptive(w.of(i), &p[i * dim..(i + 1) * dim], kernel)
        })
    })
}

/// The width σ_i of point `index` under the adaptive `kernel` for `weights[0..k]`, stored at
/// `*sigma`: a sample plus truncated Gaussian noise of this width draws from the adaptive density.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_WEIGHTS`, `BAD_KERNEL`,
/// `MISSING_ATTRIBUTE`, `INDEX_OUT_OF_RANGE`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `sigma` at one writable float.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_bandwidth(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    index: u32,
    kernel: OtbakeAdaptiveKernel,
    sigma: *mut f32,
) -> OtbakeStatus {
    entry("otbake_blend_bandwidth", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        // SAFETY: as above.
        let o = unsafe { out(sigma, "sigma")? };
        o.set(b.bandwidth(w, index, kernel.into())?);
        Ok(())
    })
}

/// [`otbake_blend_bandwidth`] for the `count` point indices `indices[0..count]`, widths to
/// `sigmas[0..count]` (batch conventions at the top of otbake.h).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` as the batch conventions say, `indices` points at
/// `count` values, `sigmas` at `count` writable floats.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_bandwidth_batch(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    indices: *const u32,
    count: usize,
    kernel: OtbakeAdaptiveKernel,
    sigmas: *mut f32,
) -> OtbakeStatus {
    entry("otbake_blend_bandwidth_batch", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as above.
        let idx = unsafe { slice(indices, count, "indices")? };
        // SAFETY: as above; checked disjoint from the inputs below before any write.
        let o = unsafe { slice_mut(sigmas, count, "sigmas")? };
        disjoint(o, "sigmas", idx)?;
        disjoint(o, "sigmas", w.floats())?;
        let kernel = kernel.into();
        batch(o, |i| b.bandwidth(w.of(i), idx[i], kernel))
    })
}

/// Points, mass and color of the blend inside the closed box `[lo, hi]` (`dim` coordinates each),
/// stored at `*out`.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_WEIGHTS`,
/// `BAD_COORDINATE`, `MISSING_ATTRIBUTE` (a colored map without node color sums).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `lo` and `hi` at `dim` floats
/// each, `out` at one writable `OtbakeRangeValue`.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_range(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    lo: *const f32,
    hi: *const f32,
    dim: usize,
    out: *mut OtbakeRangeValue,
) -> OtbakeStatus {
    entry("otbake_blend_range", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        // SAFETY: as above.
        let (l, h) = unsafe { (slice(lo, dim, "lo")?, slice(hi, dim, "hi")?) };
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(b.range(w, l, h)?.into());
        Ok(())
    })
}

/// [`otbake_blend_range`] for `count` boxes: `lo` and `hi` hold `count · dim` floats each
/// (batch conventions at the top of otbake.h).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` as the batch conventions say, `lo` and `hi` point at
/// `count · dim` floats each, `out` at `count` writable values.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_range_batch(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    lo: *const f32,
    hi: *const f32,
    dim: usize,
    count: usize,
    out: *mut OtbakeRangeValue,
) -> OtbakeStatus {
    entry("otbake_blend_range_batch", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        check_dim(dim, b.dim())?;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        let len = mul(count, dim, "count")?;
        // SAFETY: as above.
        let (l, h) = unsafe { (slice(lo, len, "lo")?, slice(hi, len, "hi")?) };
        // SAFETY: as above; checked disjoint from the inputs below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", l)?;
        disjoint(o, "out", h)?;
        disjoint(o, "out", w.floats())?;
        batch(o, |i| {
            let r = i * dim..(i + 1) * dim;
            b.range(w.of(i), &l[r.clone()], &h[r])
        })
    })
}

/// The `index`-th point of the blend for `weights[0..k]` (a sample of the barycenter: each point
/// carries mass 1/n), stored at `*out`.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_WEIGHTS`,
/// `INDEX_OUT_OF_RANGE`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `out` at one writable
/// `OtbakeSample`.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_sample(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    index: u32,
    out: *mut OtbakeSample,
) -> OtbakeStatus {
    entry("otbake_blend_sample", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        // SAFETY: as above.
        let o = unsafe { crate::guard::out(out, "out")? };
        o.set(b.sample(w, index)?.into());
        Ok(())
    })
}

/// [`otbake_blend_sample`] for the `count` indices `indices[0..count]` (batch conventions at the top
/// of otbake.h).
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` as the batch conventions say, `indices` points at
/// `count` values, `out` at `count` writable samples.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_sample_batch(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    indices: *const u32,
    count: usize,
    out: *mut OtbakeSample,
) -> OtbakeStatus {
    entry("otbake_blend_sample_batch", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as above.
        let idx = unsafe { slice(indices, count, "indices")? };
        // SAFETY: as above; checked disjoint from the inputs below before any write.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", idx)?;
        disjoint(o, "out", w.floats())?;
        batch(o, |i| b.sample(w.of(i), idx[i]))
    })
}

/// The blended mean mass `Σ w_k mean_mass_k` for `weights[0..k]`, stored at `*mean_mass`: a point
/// value's `mass` is its `density` times this.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_WEIGHTS`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats, `mean_mass` at one writable
/// float.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_mean_mass(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    mean_mass: *mut f32,
) -> OtbakeStatus {
    entry("otbake_blend_mean_mass", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        // SAFETY: as above.
        let o = unsafe { out(mean_mass, "mean_mass")? };
        o.set(b.mean_mass(w)?);
        Ok(())
    })
}
