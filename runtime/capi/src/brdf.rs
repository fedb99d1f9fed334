//! Blends of BRDF maps ([`OtbakeBrdf`], over `otbake-brdf`'s `BrdfBlend`): evaluation, importance
//! sampling and the pdf of the samples, once and in batches. Directions are unit vectors in the
//! local shading frame (z = normal, both pointing away from the surface), as doubles.
//!
//! Batch conventions are those of the point queries (see `otbake_blend_point_batch`): per-call
//! or per-element weights, results for the elements before a refused one written.
//!
//! Thread safety: a BRDF handle is immutable after creation; any number of threads may query it at
//! once.

use crate::args::{batch, OtbakeAdaptiveKernel, Weights};
use crate::guard::{disjoint, entry, handle, mul, out, slice, slice_mut, Handle};
use crate::handles::{clear, free, map_views, publish, OtbakeBlendInfo, OtbakeMap, OtbakeProxy};
use crate::status::{Failure, OtbakeStatus};
use otbake_brdf::{BrdfBlend, BrdfKernel, BrdfSample, BrdfValue, DEFAULT_ADAPTIVE};
use otbake_runtime::{Kernel, Map};

/// Magic of a live [`OtbakeBrdf`] ("OTBR").
const BRDF_MAGIC: u32 = u32::from_le_bytes(*b"OTBR");

/// A blend of BRDF maps with its reconstruction kernel (opaque to C). Like a blend, it holds
/// copies of the views: the proxy and map handles may be freed, their bytes may not.
#[repr(C)]
pub struct OtbakeBrdf {
    magic: u32,
    brdf: BrdfBlend<'static, 'static>,
    /// The maps the blend borrows, leaked from a box at creation and freed with the handle.
    maps: *mut [Map<'static>],
}

impl Handle for OtbakeBrdf {
    const MAGIC: u32 = BRDF_MAGIC;
}

impl Drop for OtbakeBrdf {
    fn drop(&mut self) {
        // SAFETY: `maps` came from `Box::into_raw` in `new_brdf` and is freed only here, once;
        // `brdf` borrows it but is never used again (it has no destructor).
        drop(unsafe { Box::from_raw(self.maps) });
    }
}

/// One importance sample of a BRDF blend.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OtbakeBrdfSample {
    /// Incident direction.
    pub wi: [f64; 3],
    /// Outgoing direction.
    pub wo: [f64; 3],
    /// Joint density of `(wi, wo)` in the product of solid angles; 0 for a failed sample.
    pub pdf: f64,
    /// `f(wi, wo)`, linear RGB.
    pub value: [f32; 3],
    /// `f_Y(wi, wo)`, the luminance.
    pub luminance: f32,
}

impl From<BrdfSample> for OtbakeBrdfSample {
    fn from(s: BrdfSample) -> Self {
        Self {
            wi: s.wi,
            wo: s.wo,
            pdf: s.pdf,
            value: s.value,
            luminance: s.luminance,
        }
    }
}

/// Value and density of a BRDF blend at one triple of angles.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OtbakeBrdfValue {
    /// `f`, linear RGB.
    pub rgb: [f32; 3],
    /// `f_Y`.
    pub luminance: f32,
    /// The blend's density over the unit cube of `(θi, θo, φd)`.
    pub density: f32,
}

impl From<BrdfValue> for OtbakeBrdfValue {
    fn from(v: BrdfValue) -> Self {
        Self {
            rgb: v.rgb,
            luminance: v.luminance,
            density: v.density,
        }
    }
}

/// A BRDF value as the eval batch writes it: linear RGB.
#[repr(transparent)]
#[derive(Clone, Copy, Default)]
struct Rgb([f32; 3]);

impl From<[f32; 3]> for Rgb {
    fn from(v: [f32; 3]) -> Self {
        Rgb(v)
    }
}

/// The default adaptive kernel of BRDF blends (`otbake-brdf`'s `DEFAULT_ADAPTIVE`).
///
/// Thread safety: any thread.
#[no_mangle]
pub extern "C" fn otbake_brdf_default_kernel() -> OtbakeAdaptiveKernel {
    OtbakeAdaptiveKernel {
        scale: DEFAULT_ADAPTIVE.scale,
        min_sigma: DEFAULT_ADAPTIVE.min_sigma,
        max_sigma: DEFAULT_ADAPTIVE.max_sigma,
    }
}

/// Makes a BRDF handle with `kernel` (shared by both constructors).
///
/// # Safety
///
/// As [`otbake_brdf_new_adaptive`].
unsafe fn new_brdf(
    proxy: *const OtbakeProxy,
    maps: *const *const OtbakeMap,
    k: usize,
    kernel: BrdfKernel,
    out_ptr: *mut *mut OtbakeBrdf,
) -> Result<(), Failure> {
    // SAFETY: the caller's contract.
    let p = unsafe { handle(proxy, "proxy")? }.proxy;
    // SAFETY: the caller's contract.
    let views = unsafe { map_views(maps, k)? };
    let raw = Box::into_raw(views);
    // SAFETY: `raw` is the box just leaked; it is freed only by the handle's `Drop` (or below,
    // on failure), after the last use of the blend that borrows it.
    let leaked: &'static [Map<'static>] = unsafe { &*raw };
    match BrdfBlend::with_kernel(p, leaked, kernel) {
        Ok(brdf) => {
            let value = OtbakeBrdf {
                magic: BRDF_MAGIC,
                brdf,
                maps: raw,
            };
            // SAFETY: the caller's contract (on failure `value` drops and frees `raw`).
            unsafe { publish(out_ptr, "out", value) }
        }
        Err(e) => {
            // SAFETY: `raw` came from `Box::into_raw` above and nothing borrows it any more.
            drop(unsafe { Box::from_raw(raw) });
            Err(e.into())
        }
    }
}

/// Makes a blend of the `k` BRDF maps `maps[0..k]` of `proxy` reconstructed with the
/// density-adaptive `kernel` (`otbake_brdf_default_kernel()` is the baker's), and stores a new
/// handle at `*out` (null on failure).
///
/// Errors: those of `otbake_blend_new`, `NOT_BRDF` (maps that are not 3D), `BAD_KERNEL`,
/// `MISSING_ATTRIBUTE` (a map without spacings).
///
/// Thread safety: any thread; the handle may be queried by all threads at once.
///
/// # Safety
///
/// `proxy` is a live proxy handle, `maps` points at `k` live map handles, `out` at writable
/// memory for one pointer.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_new_adaptive(
    proxy: *const OtbakeProxy,
    maps: *const *const OtbakeMap,
    k: usize,
    kernel: OtbakeAdaptiveKernel,
    out: *mut *mut OtbakeBrdf,
) -> OtbakeStatus {
    // SAFETY: `out` is the caller's out parameter for one pointer.
    unsafe { clear(out) };
    entry("otbake_brdf_new_adaptive", || {
        // SAFETY: the caller's contract above.
        unsafe { new_brdf(proxy, maps, k, BrdfKernel::Adaptive(kernel.into()), out) }
    })
}

/// [`otbake_brdf_new_adaptive`] with the fixed Gaussian kernel of width `sigma` (boundary
/// renormalization, samples without noise).
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// As [`otbake_brdf_new_adaptive`].
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_new_fixed(
    proxy: *const OtbakeProxy,
    maps: *const *const OtbakeMap,
    k: usize,
    sigma: f32,
    out: *mut *mut OtbakeBrdf,
) -> OtbakeStatus {
    // SAFETY: `out` is the caller's out parameter for one pointer.
    unsafe { clear(out) };
    entry("otbake_brdf_new_fixed", || {
        // SAFETY: the caller's contract above.
        unsafe { new_brdf(proxy, maps, k, BrdfKernel::Fixed(Kernel { sigma }), out) }
    })
}

/// What the BRDF blend answers (dim is 3), stored at `*info`.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `brdf` is a live BRDF handle; `info` points at writable memory for one struct.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_info(
    brdf: *const OtbakeBrdf,
    info: *mut OtbakeBlendInfo,
) -> OtbakeStatus {
    entry("otbake_brdf_info", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(brdf, "brdf")? }.brdf.blend;
        // SAFETY: as above.
        let o = unsafe { out(info, "info")? };
        o.set(OtbakeBlendInfo {
            dim: b.dim() as u32,
            k: b.k() as u32,
            n: b.n(),
            wrap: b.wrap().into(),
            has_color: b.has_color(),
            has_node_colors: b.has_node_colors(),
            has_spacings: b.has_spacings(),
        });
        Ok(())
    })
}

/// Frees a BRDF handle (null: nothing).
///
/// Thread safety: no other call may use this handle during or after the call.
///
/// # Safety
///
/// `brdf` is null or a live BRDF handle, used by no other thread, and never used again.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_free(brdf: *mut OtbakeBrdf) {
    // SAFETY: the caller's contract.
    unsafe { free(brdf) }
}

/// `f(wi, wo)` in linear RGB for weights `weights[0..k]` and unit directions `wi[0..3]`,
/// `wo[0..3]`, stored at `rgb[0..3]`; zeros below the horizon.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_WEIGHTS`,
/// `BAD_COORDINATE`.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `brdf` is a live BRDF handle; `weights` points at `k` floats, `wi` and `wo` at 3 doubles each,
/// `rgb` at 3 writable floats.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_eval(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    wi: *const f64,
    wo: *const f64,
    rgb: *mut f32,
) -> OtbakeStatus {
    // SAFETY: the caller's contract above (count 1).
    unsafe { otbake_brdf_eval_batch_impl("otbake_brdf_eval", brdf, weights, k, 0, wi, wo, 1, rgb) }
}

/// [`otbake_brdf_eval`] for `count` direction pairs: `wi` and `wo` hold `3 · count` doubles,
/// `rgb` receives `3 · count` floats.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `brdf` is a live BRDF handle; `weights` as the batch conventions say, `wi` and `wo` point at
/// `3 · count` doubles each, `rgb` at `3 · count` writable floats.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_eval_batch(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    wi: *const f64,
    wo: *const f64,
    count: usize,
    rgb: *mut f32,
) -> OtbakeStatus {
    // SAFETY: the caller's contract above.
    unsafe {
        otbake_brdf_eval_batch_impl(
            "otbake_brdf_eval_batch",
            brdf,
            weights,
            k,
            weight_stride,
            wi,
            wo,
            count,
            rgb,
        )
    }
}

/// The body of the eval functions.
///
/// # Safety
///
/// As [`otbake_brdf_eval_batch`].
#[allow(clippy::too_many_arguments)]
unsafe fn otbake_brdf_eval_batch_impl(
    function: &'static str,
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    wi: *const f64,
    wo: *const f64,
    count: usize,
    rgb: *mut f32,
) -> OtbakeStatus {
    entry(function, || {
        // SAFETY: the caller's contract.
        let b = unsafe { handle(brdf, "brdf")? }.brdf;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as above: `[f64; 3]` has the alignment of `f64`, `count` of them are the
        // `3 · count` doubles the caller provides.
        let (i, o) = unsafe {
            (
                slice(wi.cast::<[f64; 3]>(), count, "wi")?,
                slice(wo.cast::<[f64; 3]>(), count, "wo")?,
            )
        };
        mul(count, 3, "count")?;
        // SAFETY: as above (`Rgb` is three floats, align 4); checked disjoint below.
        let out = unsafe { slice_mut(rgb.cast::<Rgb>(), count, "rgb")? };
        disjoint(out, "rgb", i)?;
        disjoint(out, "rgb", o)?;
        disjoint(out, "rgb", w.floats())?;
        batch(out, |j| b.eval(w.of(j), i[j], o[j]))
    })
}

/// The joint pdf of `otbake_brdf_sample` at `(wi, wo)` (product of solid angles), stored at
/// `*pdf`; 0 below the horizon.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// As [`otbake_brdf_eval`], with `pdf` pointing at one writable double.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_pdf(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    wi: *const f64,
    wo: *const f64,
    pdf: *mut f64,
) -> OtbakeStatus {
    // SAFETY: the caller's contract above (count 1).
    unsafe { pdf_impl("otbake_brdf_pdf", brdf, weights, k, 0, wi, wo, 1, pdf) }
}

/// [`otbake_brdf_pdf`] for `count` direction pairs (`3 · count` doubles each), pdfs to
/// `pdf[0..count]`.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// As [`otbake_brdf_eval_batch`], with `pdf` pointing at `count` writable doubles.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_pdf_batch(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    wi: *const f64,
    wo: *const f64,
    count: usize,
    pdf: *mut f64,
) -> OtbakeStatus {
    // SAFETY: the caller's contract above.
    unsafe {
        pdf_impl(
            "otbake_brdf_pdf_batch",
            brdf,
            weights,
            k,
            weight_stride,
            wi,
            wo,
            count,
            pdf,
        )
    }
}

/// The body of the pdf functions.
///
/// # Safety
///
/// As [`otbake_brdf_pdf_batch`].
#[allow(clippy::too_many_arguments)]
unsafe fn pdf_impl(
    function: &'static str,
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    wi: *const f64,
    wo: *const f64,
    count: usize,
    pdf: *mut f64,
) -> OtbakeStatus {
    entry(function, || {
        // SAFETY: the caller's contract.
        let b = unsafe { handle(brdf, "brdf")? }.brdf;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as in the eval functions.
        let (i, o) = unsafe {
            (
                slice(wi.cast::<[f64; 3]>(), count, "wi")?,
                slice(wo.cast::<[f64; 3]>(), count, "wo")?,
            )
        };
        // SAFETY: as above; checked disjoint below.
        let out = unsafe { slice_mut(pdf, count, "pdf")? };
        disjoint(out, "pdf", i)?;
        disjoint(out, "pdf", o)?;
        disjoint(out, "pdf", w.floats())?;
        batch(out, |j| b.pdf(w.of(j), i[j], o[j]))
    })
}

/// `f`, `f_Y` and the density at the angles `(θi, θo, φd)` (radians; `φd` in `[0, π]`) for
/// `weights[0..k]`, stored at `*out`. `angles` holds `3 · count` doubles, `out` receives `count`
/// values (`count = 1` for a single evaluation).
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `brdf` is a live BRDF handle; `weights` as the batch conventions say, `angles` points at
/// `3 · count` doubles, `out` at `count` writable values.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_eval_angles_batch(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    angles: *const f64,
    count: usize,
    out: *mut OtbakeBrdfValue,
) -> OtbakeStatus {
    entry("otbake_brdf_eval_angles_batch", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(brdf, "brdf")? }.brdf;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as in the eval functions.
        let a = unsafe { slice(angles.cast::<[f64; 3]>(), count, "angles")? };
        // SAFETY: as above; checked disjoint below.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", a)?;
        disjoint(o, "out", w.floats())?;
        batch(o, |j| b.eval_angles(w.of(j), a[j][0], a[j][1], a[j][2]))
    })
}

/// Sample `index` of the blend for `weights[0..k]` as a pair of directions with its value and
/// pdf, stored at `*out`. `xi` holds five uniform numbers in `[0, 1)` (the azimuth, the sign of
/// `φd`, and with the adaptive kernel the noise); draw `index` uniformly in `0 .. n`.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `BAD_COUNT`, `BAD_WEIGHTS`,
/// `INDEX_OUT_OF_RANGE`.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `brdf` is a live BRDF handle; `weights` points at `k` floats, `xi` at 5 doubles, `out` at one
/// writable sample.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_sample(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    index: u32,
    xi: *const f64,
    out: *mut OtbakeBrdfSample,
) -> OtbakeStatus {
    // SAFETY: the caller's contract above (count 1; `index` is read from the caller's stack).
    unsafe {
        sample_impl(
            "otbake_brdf_sample",
            brdf,
            weights,
            k,
            0,
            &index,
            xi,
            1,
            out,
        )
    }
}

/// [`otbake_brdf_sample`] for `count` indices `indices[0..count]` with `5 · count` uniform numbers
/// `xi`, samples to `out[0..count]`.
///
/// Thread safety: any thread, concurrently with every other call on the same BRDF blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `brdf` is a live BRDF handle; `weights` as the batch conventions say, `indices` points at
/// `count` values, `xi` at `5 · count` doubles, `out` at `count` writable samples.
#[no_mangle]
pub unsafe extern "C" fn otbake_brdf_sample_batch(
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    indices: *const u32,
    xi: *const f64,
    count: usize,
    out: *mut OtbakeBrdfSample,
) -> OtbakeStatus {
    // SAFETY: the caller's contract above.
    unsafe {
        sample_impl(
            "otbake_brdf_sample_batch",
            brdf,
            weights,
            k,
            weight_stride,
            indices,
            xi,
            count,
            out,
        )
    }
}

/// The body of the sample functions.
///
/// # Safety
///
/// As [`otbake_brdf_sample_batch`].
#[allow(clippy::too_many_arguments)]
unsafe fn sample_impl(
    function: &'static str,
    brdf: *const OtbakeBrdf,
    weights: *const f32,
    k: usize,
    weight_stride: usize,
    indices: *const u32,
    xi: *const f64,
    count: usize,
    out: *mut OtbakeBrdfSample,
) -> OtbakeStatus {
    entry(function, || {
        // SAFETY: the caller's contract.
        let b = unsafe { handle(brdf, "brdf")? }.brdf;
        // SAFETY: as above.
        let w = unsafe { Weights::new(weights, k, weight_stride, count)? };
        // SAFETY: as above.
        let idx = unsafe { slice(indices, count, "indices")? };
        mul(count, 5, "count")?;
        // SAFETY: as above: `[f64; 5]` has the alignment of `f64`.
        let x = unsafe { slice(xi.cast::<[f64; 5]>(), count, "xi")? };
        // SAFETY: as above; checked disjoint below.
        let o = unsafe { slice_mut(out, count, "out")? };
        disjoint(o, "out", idx)?;
        disjoint(o, "out", x)?;
        disjoint(o, "out", w.floats())?;
        batch(o, |j| b.sample(w.of(j), idx[j], x[j]))
    })
}
