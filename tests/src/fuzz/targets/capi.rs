//! The `capi` target: the C ABI's `extern "C"` functions (runtime/capi), called from Rust as a C
//! caller would, on mutated archives (the `archive` corpus and mutations) with hostile arguments:
//! null pointers, misaligned pointers, counts and dimensions that are not the blend's, weight
//! strides, overlapping output and input buffers, handles of the wrong kind, special floats,
//! regions and resolutions that overflow.
//!
//! Every pointer this target passes points at as much live memory as its length says (the one
//! contract a C caller must keep: breaking it is undefined behaviour no library can check).
//! Findings: a status of `INTERNAL` (a panic caught at the boundary), a failure without a last
//! error message, an overlapping output that was accepted, or any crash.

use crate::fuzz::archive::{archive_cases, mutate as mutate_archive};
use crate::fuzz::{Case, Rng, Scratch, Target};
use otbake_capi::*;
use otbake_formats::write::aligned_copy;
use otbake_formats::ArchiveKind;
use std::cell::RefCell;
use std::ffi::CStr;
use std::ptr::{null, null_mut};

/// Elements in each scratch buffer: enough for every count × dimension × stride this target
/// passes (counts ≤ 64, dimensions ≤ 8, strides ≤ 16).
const CAP: usize = 1 << 12;
/// Most elements of a batch call.
const MAX_COUNT: usize = 64;

struct Buffers {
    f32s: Vec<f32>,
    f32s_out: Vec<f32>,
    f64s: Vec<f64>,
    u32s: Vec<u32>,
    points: Vec<OtbakePointValue>,
    ranges: Vec<OtbakeRangeValue>,
    samples: Vec<OtbakeSample>,
    brdf_values: Vec<OtbakeBrdfValue>,
    brdf_samples: Vec<OtbakeBrdfSample>,
}

thread_local! {
    static BUFFERS: RefCell<Buffers> = RefCell::new(Buffers {
        f32s: vec![0.0; CAP],
        f32s_out: vec![0.0; 4 * CAP],
        f64s: vec![0.0; CAP],
        u32s: vec![0; CAP],
        points: vec![OtbakePointValue::default(); MAX_COUNT],
        ranges: vec![OtbakeRangeValue::default(); MAX_COUNT],
        samples: vec![OtbakeSample::default(); MAX_COUNT],
        brdf_values: vec![OtbakeBrdfValue::default(); MAX_COUNT],
        brdf_samples: vec![OtbakeBrdfSample::default(); MAX_COUNT],
    });
}

/// Checks a status: never `INTERNAL`; a failure leaves a message.
fn check(status: OtbakeStatus, what: &str) -> bool {
    assert!(
        status != OtbakeStatus::Internal,
        "{what} returned INTERNAL: {}",
        last_error()
    );
    if status != OtbakeStatus::Ok {
        assert!(!last_error().is_empty(), "{what} failed without a message");
    }
    status == OtbakeStatus::Ok
}

fn last_error() -> String {
    let p = otbake_last_error();
    assert!(!p.is_null(), "otbake_last_error returned null");
    // SAFETY: the library returns a NUL-terminated thread-local string that stays valid until
    // the next call on this thread.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

/// A pointer to `len` elements of `buf` that is sometimes null or misaligned (with `len` kept
/// inside the buffer), as a careless C caller would pass.
fn ptr_in<T>(rng: &mut Rng, buf: &[T], len: usize) -> *const T {
    match rng.below(24) {
        0 => null(),
        1 if len < buf.len() => buf.as_ptr().cast::<u8>().wrapping_add(1).cast(),
        _ => buf.as_ptr(),
    }
}

fn ptr_out<T>(rng: &mut Rng, buf: &mut [T], len: usize) -> *mut T {
    match rng.below(24) {
        0 => null_mut(),
        1 if len < buf.len() => buf.as_mut_ptr().cast::<u8>().wrapping_add(1).cast(),
        _ => buf.as_mut_ptr(),
    }
}

/// `good` most of the time, else a neighbour or an edge value (all ≤ `max`).
fn count(rng: &mut Rng, good: usize, max: usize) -> usize {
    match rng.below(10) {
        0 => 0,
        1 => good.saturating_sub(1),
        2 => good + 1,
        3 => rng.below(max + 1),
        _ => good,
    }
    .min(max)
}

fn fill(rng: &mut Rng, v: &mut [f32], k: usize) {
    for x in v.iter_mut() {
        *x = rng.float();
    }
    // Usually valid weights at the front.
    if !rng.one_in(4) && k > 0 {
        let raw: Vec<f32> = (0..k).map(|_| 1.0 + rng.below(100) as f32).collect();
        let s: f32 = raw.iter().sum();
        for (x, r) in v.iter_mut().zip(raw) {
            *x = r / s;
        }
    }
}

/// See the module docs.
pub struct CapiTarget;

impl Target for CapiTarget {
    fn name(&self) -> &'static str {
        "capi"
    }

    fn seeds(&self, corpus: &std::path::Path) -> Vec<Case> {
        archive_cases(&corpus.join("archive"))
    }

    fn mutate(&self, rng: &mut Rng, case: &mut Case, _other: &Case) {
        let (i, kind) = if case.files.len() == 1 || rng.one_in(3) {
            (0, ArchiveKind::Proxy)
        } else {
            (1 + rng.below(case.files.len() - 1), ArchiveKind::Map)
        };
        mutate_archive(rng, &mut case.files[i].1, kind);
    }

    fn execute(&self, rng: &mut Rng, case: &Case, _scratch: &Scratch) -> bool {
        BUFFERS.with(|b| exercise(rng, case, &mut b.borrow_mut()))
    }
}

/// Opens `bytes` with `open`, sometimes through a null, misaligned or short pointer.
fn open<H>(
    rng: &mut Rng,
    bytes: &[u8],
    open: unsafe extern "C" fn(*const u8, usize, *mut *mut H) -> OtbakeStatus,
    what: &str,
) -> *mut H {
    let mut h: *mut H = null_mut();
    let (ptr, len) = match rng.below(16) {
        0 => (null(), bytes.len()),
        1 => (null(), 0),
        2 if !bytes.is_empty() => (bytes[1..].as_ptr(), bytes.len() - 1),
        3 => (bytes.as_ptr(), rng.below(bytes.len() + 1)),
        _ => (bytes.as_ptr(), bytes.len()),
    };
    let out: *mut *mut H = if rng.one_in(32) { null_mut() } else { &mut h };
    // SAFETY: `ptr` is null or points at `len` bytes of `bytes`, which outlive every handle made
    // here (freed before `exercise` returns); `out` is null or points at `h`.
    let s = unsafe { open(ptr, len, out) };
    if check(s, what) {
        assert!(!h.is_null(), "{what} returned OK and a null handle");
    } else {
        assert!(h.is_null(), "{what} failed but returned a handle");
    }
    h
}

fn exercise(rng: &mut Rng, case: &Case, buf: &mut Buffers) -> bool {
    let bytes: Vec<_> = case.files.iter().map(|f| aligned_copy(&f.1)).collect();
    let proxy = open(rng, &bytes[0], otbake_proxy_open, "otbake_proxy_open");
    let maps: Vec<*mut OtbakeMap> = bytes[1..]
        .iter()
        .map(|b| open(rng, b, otbake_map_open, "otbake_map_open"))
        .collect();
    let mut info_p = std::mem::MaybeUninit::<OtbakeProxyInfo>::uninit();
    // SAFETY: `proxy` is null or a live proxy; `info_p` is writable for one struct.
    check(
        unsafe { otbake_proxy_info(proxy, info_p.as_mut_ptr()) },
        "otbake_proxy_info",
    );
    for &m in &maps {
        let mut info = std::mem::MaybeUninit::<OtbakeMapInfo>::uninit();
        let out = if rng.one_in(16) {
            null_mut()
        } else {
            info.as_mut_ptr()
        };
        // SAFETY: `m` is null or a live map; `out` is null or writable for one struct.
        check(unsafe { otbake_map_info(m, out) }, "otbake_map_info");
    }
    // The map array, sometimes with a null entry or the proxy handle in a map's place (a handle
    // of the wrong kind: the magic check refuses it).
    let mut list: Vec<*const OtbakeMap> = maps.iter().map(|&m| m.cast_const()).collect();
    if !list.is_empty() && rng.one_in(16) {
        let i = rng.below(list.len());
        list[i] = if rng.one_in(2) {
            null()
        } else {
            proxy.cast_const().cast()
        };
    }
    list.resize(OTBAKE_MAX_MAPS as usize + 1, null());
    let k = count(rng, maps.len(), OTBAKE_MAX_MAPS as usize + 1);
    let mut blend: *mut OtbakeBlend = null_mut();
    // SAFETY: `list` holds `k` (≤ its length) null or live handles or the proxy handle; `blend`
    // is writable.
    let ok = check(
        unsafe { otbake_blend_new(proxy, list.as_ptr(), k, &mut blend) },
        "otbake_blend_new",
    );
    let opened = ok;
    if ok {
        queries(rng, blend, maps.len(), buf);
        brdf(rng, proxy, &list[..maps.len()], maps.len(), buf);
    } else if rng.one_in(4) {
        // Queries on a null or wrong-kind handle are refused.
        let fake: *const OtbakeBlend = if rng.one_in(2) {
            null()
        } else {
            proxy.cast_const().cast()
        };
        queries(rng, fake, maps.len(), buf);
    }
    // SAFETY: every handle is null or live and used no more.
    unsafe {
        otbake_blend_free(blend);
        for m in maps {
            otbake_map_free(m);
        }
        otbake_proxy_free(proxy);
    }
    // Status texts exist for every code, known or not.
    let code = *rng.pick(&[0, 5, 18, OTBAKE_STATUS_COUNT, -1, i32::MAX]);
    assert!(!otbake_status_message(code).is_null());
    opened
}

fn queries(rng: &mut Rng, blend: *const OtbakeBlend, k_good: usize, buf: &mut Buffers) {
    let mut info = std::mem::MaybeUninit::<OtbakeBlendInfo>::uninit();
    // SAFETY: `blend` is null, live or another kind of handle (refused by its magic); `info` is
    // writable for one struct.
    let dim = if check(
        unsafe { otbake_blend_info(blend, info.as_mut_ptr()) },
        "otbake_blend_info",
    ) {
        // SAFETY: OK means the library wrote it.
        let i = unsafe { info.assume_init() };
        i.dim as usize
    } else {
        2
    };
    for _ in 0..1 + rng.below(4) {
        let k = count(rng, k_good, 16);
        let d = count(rng, dim, 8);
        let wanted = 1 + rng.below(MAX_COUNT);
        let n = count(rng, wanted, MAX_COUNT);
        let stride = *rng.pick(&[0, k, k + 1, 1, 16]);
        fill(rng, &mut buf.f32s[..CAP], k);
        for x in buf.f32s[1024..1024 + n * 8].iter_mut() {
            *x = rng.float().abs().min(1.5);
        }
        for i in 0..n {
            buf.u32s[i] = match rng.below(4) {
                0 => rng.next_u64() as u32,
                _ => rng.below(64) as u32,
            };
        }
        let sigma = *rng.pick(&[
            0.05f32,
            0.2,
            0.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            1e-30,
            1e30,
        ]);
        let kernel = OtbakeAdaptiveKernel {
            scale: *rng.pick(&[2.0, 0.0, f32::NAN, 1e30]),
            min_sigma: *rng.pick(&[1e-3, 0.0, -1.0, 1e-30]),
            max_sigma: *rng.pick(&[0.05, 0.3, f32::INFINITY, 1e-4]),
        };
        let w = ptr_in(rng, &buf.f32s, k);
        let pts_at = 1024;
        let pts = ptr_in(rng, &buf.f32s[pts_at..], n * d.max(1));
        let hi = buf.f32s[pts_at + 512..].as_ptr();
        let idx = ptr_in(rng, &buf.u32s, n);
        // One call in eight writes over its own inputs (must be refused as OVERLAP).
        let overlap = rng.one_in(8);
        let mut overlapped = false;
        let status = match rng.below(13) {
            0 => {
                let out = ptr_out(rng, &mut buf.points, 1);
                // SAFETY: every pointer is null or points at as many elements as its length.
                unsafe { otbake_blend_point(blend, w, k, pts, d, sigma, out) }
            }
            1 => {
                overlapped = overlap;
                let out: *mut OtbakePointValue = if overlap {
                    buf.f32s[pts_at..].as_mut_ptr().cast()
                } else {
                    ptr_out(rng, &mut buf.points, n)
                };
                // SAFETY: as above (an overlapping `out` points into `f32s`, far from its end).
                unsafe { otbake_blend_point_batch(blend, w, k, stride, pts, d, n, sigma, out) }
            }
            2 => {
                let out = ptr_out(rng, &mut buf.points, 1);
                // SAFETY: as above.
                unsafe { otbake_blend_point_adaptive(blend, w, k, pts, d, kernel, out) }
            }
            3 => {
                let out = ptr_out(rng, &mut buf.points, n);
                // SAFETY: as above.
                unsafe {
                    otbake_blend_point_adaptive_batch(blend, w, k, stride, pts, d, n, kernel, out)
                }
            }
            4 => {
                let out = ptr_out(rng, &mut buf.f32s_out, 1);
                // SAFETY: as above.
                unsafe { otbake_blend_bandwidth(blend, w, k, buf.u32s[0], kernel, out) }
            }
            5 => {
                overlapped = overlap;
                let out: *mut f32 = if overlap {
                    buf.f32s.as_mut_ptr()
                } else {
                    ptr_out(rng, &mut buf.f32s_out, n)
                };
                // SAFETY: as above.
                unsafe { otbake_blend_bandwidth_batch(blend, w, k, stride, idx, n, kernel, out) }
            }
            6 => {
                let out = ptr_out(rng, &mut buf.ranges, 1);
                // SAFETY: as above.
                unsafe { otbake_blend_range(blend, w, k, pts, hi, d, out) }
            }
            7 => {
                let out = ptr_out(rng, &mut buf.ranges, n);
                // SAFETY: as above (`hi` has 512 + more floats, ≥ n · d).
                unsafe { otbake_blend_range_batch(blend, w, k, stride, pts, hi, d, n, out) }
            }
            8 => {
                let out = ptr_out(rng, &mut buf.samples, 1);
                // SAFETY: as above.
                unsafe { otbake_blend_sample(blend, w, k, buf.u32s[0], out) }
            }
            9 => {
                let out = ptr_out(rng, &mut buf.samples, n);
                // SAFETY: as above.
                unsafe { otbake_blend_sample_batch(blend, w, k, stride, idx, n, out) }
            }
            10 => {
                let out = ptr_out(rng, &mut buf.f32s_out, 1);
                // SAFETY: as above.
                unsafe { otbake_blend_mean_mass(blend, w, k, out) }
            }
            11 => {
                let side = *rng.pick(&[1u32, 2, 5, 16, 0, 1 << 16, u32::MAX]);
                let res = [side; 8];
                let mut cells = 0usize;
                // SAFETY: `res` has 8 ≥ d values; `cells` is writable.
                let s = unsafe { otbake_blend_grid_cells(blend, res.as_ptr(), d, &mut cells) };
                let density_len = if rng.one_in(2) {
                    cells.min(CAP)
                } else {
                    rng.below(CAP)
                };
                let color_len = if rng.one_in(3) {
                    0
                } else {
                    (3 * density_len).min(CAP)
                };
                check(s, "otbake_blend_grid_cells");
                let (density, color) = buf.f32s_out.split_at_mut(CAP);
                let color_ptr = if color_len == 0 {
                    null_mut()
                } else {
                    color.as_mut_ptr()
                };
                // SAFETY: `density` has CAP ≥ density_len floats, `color` 3 · CAP ≥ color_len.
                unsafe {
                    otbake_blend_splat(
                        blend,
                        w,
                        k,
                        sigma,
                        res.as_ptr(),
                        d,
                        density.as_mut_ptr(),
                        density_len,
                        color_ptr,
                        color_len,
                    )
                }
            }
            _ => {
                let mut region = OtbakeRegion {
                    res: [0; 4],
                    start: [0; 4],
                    size: [0; 4],
                };
                for a in 0..4 {
                    let r = *rng.pick(&[1u32, 3, 8, 0, u32::MAX]);
                    region.res[a] = r;
                    region.start[a] = if rng.one_in(4) {
                        rng.next_u64() as u32
                    } else {
                        rng.below(r.min(8) as usize + 1) as u32
                    };
                    region.size[a] = if rng.one_in(4) {
                        u32::MAX
                    } else {
                        r.saturating_sub(region.start[a]).min(8)
                    };
                }
                let mut cells = 0usize;
                // SAFETY: `cells` is writable.
                let s = unsafe { otbake_blend_region_cells(blend, region, &mut cells) };
                check(s, "otbake_blend_region_cells");
                let len = if rng.one_in(2) {
                    cells.saturating_mul(4).min(4 * CAP)
                } else {
                    rng.below(4 * CAP)
                };
                // SAFETY: `f32s_out` has 4 · CAP ≥ len floats.
                unsafe {
                    otbake_blend_splat_region_rgba(
                        blend,
                        w,
                        k,
                        sigma,
                        region,
                        buf.f32s_out.as_mut_ptr(),
                        len,
                    )
                }
            }
        };
        let ok = check(status, "a blend query");
        assert!(
            !(overlapped && ok && n > 0),
            "an overlapping output was accepted"
        );
    }
}

fn brdf(
    rng: &mut Rng,
    proxy: *const OtbakeProxy,
    maps: &[*const OtbakeMap],
    k_good: usize,
    buf: &mut Buffers,
) {
    let mut h: *mut OtbakeBrdf = null_mut();
    let k = count(rng, k_good, maps.len());
    let status = if rng.one_in(2) {
        let kernel = if rng.one_in(3) {
            OtbakeAdaptiveKernel {
                scale: rng.float(),
                min_sigma: rng.float(),
                max_sigma: rng.float(),
            }
        } else {
            otbake_brdf_default_kernel()
        };
        // SAFETY: `maps` holds ≥ k null or live handles (or the proxy's); `h` is writable.
        unsafe { otbake_brdf_new_adaptive(proxy, maps.as_ptr(), k, kernel, &mut h) }
    } else {
        // SAFETY: as above.
        unsafe { otbake_brdf_new_fixed(proxy, maps.as_ptr(), k, rng.float(), &mut h) }
    };
    if !check(status, "otbake_brdf_new") {
        return;
    }
    let mut info = std::mem::MaybeUninit::<OtbakeBlendInfo>::uninit();
    // SAFETY: `h` is live; `info` writable.
    check(
        unsafe { otbake_brdf_info(h, info.as_mut_ptr()) },
        "otbake_brdf_info",
    );
    for _ in 0..1 + rng.below(3) {
        let k = count(rng, k_good, 16);
        let wanted = 1 + rng.below(MAX_COUNT);
        let n = count(rng, wanted, MAX_COUNT);
        let stride = *rng.pick(&[0, k, k + 1, 16]);
        fill(rng, &mut buf.f32s[..CAP], k);
        for x in buf.f64s[..5 * MAX_COUNT].iter_mut() {
            *x = match rng.below(6) {
                0 => *rng.pick(&[f64::NAN, f64::INFINITY, -1.0, 0.0, 1.0, 1e300]),
                _ => rng.unit() * 2.0 - 0.5,
            };
        }
        for i in 0..n {
            buf.u32s[i] = rng.below(80) as u32;
        }
        let w = ptr_in(rng, &buf.f32s, k);
        let d = buf.f64s.as_ptr();
        let d2 = buf.f64s[3 * MAX_COUNT..].as_ptr();
        let status = match rng.below(8) {
            0 => {
                let out = ptr_out(rng, &mut buf.f32s_out, 3);
                // SAFETY: `d`, `d2` have ≥ 3 doubles; `out` ≥ 3 floats.
                unsafe { otbake_brdf_eval(h, w, k, d, d2, out) }
            }
            1 => {
                let out = ptr_out(rng, &mut buf.f32s_out, 3 * n);
                // SAFETY: `d` and `d2` have ≥ 3 · n doubles (n ≤ 64, 5 · 64 filled, CAP long).
                unsafe { otbake_brdf_eval_batch(h, w, k, stride, d, d2, n, out) }
            }
            2 => {
                let mut pdf = 0f64;
                // SAFETY: as above; `pdf` writable.
                unsafe { otbake_brdf_pdf(h, w, k, d, d2, &mut pdf) }
            }
            3 => {
                let out = ptr_out(rng, &mut buf.f64s[8 * MAX_COUNT..], n);
                // SAFETY: as above; `out` is past the inputs, ≥ n doubles.
                unsafe { otbake_brdf_pdf_batch(h, w, k, stride, d, d2, n, out) }
            }
            4 => {
                let out = ptr_out(rng, &mut buf.brdf_values, n);
                // SAFETY: `d` has ≥ 3 · n doubles; `out` ≥ n values.
                unsafe { otbake_brdf_eval_angles_batch(h, w, k, stride, d, n, out) }
            }
            5 => {
                let out = ptr_out(rng, &mut buf.brdf_samples, 1);
                // SAFETY: `d` has ≥ 5 doubles; `out` one sample.
                unsafe { otbake_brdf_sample(h, w, k, buf.u32s[0], d, out) }
            }
            6 => {
                let out = ptr_out(rng, &mut buf.brdf_samples, n);
                let idx = ptr_in(rng, &buf.u32s, n);
                // SAFETY: `d` has ≥ 5 · n doubles, `idx` ≥ n values, `out` ≥ n samples.
                unsafe { otbake_brdf_sample_batch(h, w, k, stride, idx, d, n, out) }
            }
            _ => {
                // Output over the input directions: refused as OVERLAP.
                let out = buf.f64s.as_mut_ptr().cast::<f32>();
                // SAFETY: `out` points at ≥ 3 · n floats of `f64s` (checked disjoint first).
                let s = unsafe { otbake_brdf_eval_batch(h, w, k, stride, d, d2, n, out) };
                assert!(
                    n == 0 || s != OtbakeStatus::Ok,
                    "an overlapping BRDF output was accepted"
                );
                s
            }
        };
        check(status, "a BRDF query");
    }
    // SAFETY: `h` is live and used no more.
    unsafe { otbake_brdf_free(h) };
}
