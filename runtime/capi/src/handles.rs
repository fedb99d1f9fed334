//! The three handles made at load time — [`OtbakeProxy`], [`OtbakeMap`], [`OtbakeBlend`] — and
//! their open, info and free functions. Opening allocates the handle (one small box); nothing
//! else in the crate allocates.
//!
//! Archive bytes are borrowed, never copied: a handle holds a validated view into the caller's
//! bytes, so those bytes must stay valid and unchanged until the last handle (or blend) made from
//! them is freed. Handles are immutable after open: any number of threads may query them at once.

use crate::guard::{entry, handle, out, slice, Handle};
use crate::status::{Failure, OtbakeStatus};
use otbake_runtime::{Blend, Map, Proxy, Wrap};

/// Magic of a live [`OtbakeProxy`] ("OTPX").
const PROXY_MAGIC: u32 = u32::from_le_bytes(*b"OTPX");
/// Magic of a live [`OtbakeMap`] ("OTMP").
const MAP_MAGIC: u32 = u32::from_le_bytes(*b"OTMP");
/// Magic of a live [`OtbakeBlend`] ("OTBL").
const BLEND_MAGIC: u32 = u32::from_le_bytes(*b"OTBL");

/// Largest number of maps in one blend.
pub const OTBAKE_MAX_MAPS: u32 = 64;

/// An opened proxy archive: a view into the caller's bytes (opaque to C).
#[repr(C)]
pub struct OtbakeProxy {
    magic: u32,
    /// The runtime's view; `'static` stands for "as long as the caller keeps the bytes".
    pub(crate) proxy: Proxy<'static>,
}

/// An opened map archive: a view into the caller's bytes (opaque to C).
#[repr(C)]
pub struct OtbakeMap {
    magic: u32,
    /// The runtime's view; `'static` stands for "as long as the caller keeps the bytes".
    pub(crate) map: Map<'static>,
}

/// A blend of k maps of one proxy, validated once (opaque to C). Holds copies of the proxy's and
/// maps' views, so their handles may be freed once it exists; their bytes must outlive it.
#[repr(C)]
pub struct OtbakeBlend {
    magic: u32,
    /// The blend; its map slice is [`OtbakeBlend::maps`].
    pub(crate) blend: Blend<'static, 'static>,
    /// The maps the blend borrows, leaked from a box at creation and freed with the handle.
    maps: *mut [Map<'static>],
}

impl Handle for OtbakeProxy {
    const MAGIC: u32 = PROXY_MAGIC;
}
impl Handle for OtbakeMap {
    const MAGIC: u32 = MAP_MAGIC;
}
impl Handle for OtbakeBlend {
    const MAGIC: u32 = BLEND_MAGIC;
}

impl Drop for OtbakeBlend {
    fn drop(&mut self) {
        // SAFETY: `maps` came from `Box::into_raw` in `otbake_blend_new` and is freed only here,
        // once; `blend` borrows it but is never used again (the handle is being dropped, and
        // `Blend` has no destructor that could read it).
        drop(unsafe { Box::from_raw(self.maps) });
    }
}

/// How a domain treats its borders.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OtbakeWrap {
    /// The unit box; kernels see nothing past the borders.
    Clamp = 0,
    /// The torus `[0,1)^d`: queries wrap around the borders (tileable textures).
    Periodic = 1,
}

impl From<Wrap> for OtbakeWrap {
    fn from(w: Wrap) -> Self {
        match w {
            Wrap::Clamp => OtbakeWrap::Clamp,
            Wrap::Periodic => OtbakeWrap::Periodic,
        }
    }
}

/// What a proxy archive holds.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct OtbakeProxyInfo {
    /// Dimension of the domain (1 to 4).
    pub dim: u32,
    /// Number of points.
    pub n: u32,
    /// Leaf level of the point tree.
    pub depth: u32,
    /// Borders of the domain.
    pub wrap: OtbakeWrap,
}

/// What a map archive holds.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct OtbakeMapInfo {
    /// Dimension of the domain.
    pub dim: u32,
    /// Number of points.
    pub n: u32,
    /// Leaf level of the point tree.
    pub depth: u32,
    /// Borders of the domain.
    pub wrap: OtbakeWrap,
    /// The input's mean mass (what turns density into its mass channel).
    pub mean_mass: f32,
    /// Whether the map stores colors.
    pub has_color: bool,
    /// Whether it stores node color sums (range queries on colored blends need them).
    pub has_node_colors: bool,
    /// Whether it stores per-point spacings (adaptive kernels need them).
    pub has_spacings: bool,
}

/// What a blend answers.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct OtbakeBlendInfo {
    /// Dimension: coordinates per query point.
    pub dim: u32,
    /// Number of maps: weights per query.
    pub k: u32,
    /// Number of points: sample indices are `0 .. n`.
    pub n: u32,
    /// Borders of the domain.
    pub wrap: OtbakeWrap,
    /// Whether every map carries color (otherwise colors are zeros).
    pub has_color: bool,
    /// Whether range queries can answer (no color, or node color sums in every map).
    pub has_node_colors: bool,
    /// Whether adaptive-kernel queries can answer (spacings in every map).
    pub has_spacings: bool,
}

/// Stores `value` at `out` as a new handle (a box), or refuses a bad `out`.
///
/// # Safety
///
/// `out`, if non-null and aligned, points at writable memory for one pointer.
pub(crate) unsafe fn publish<H>(
    out_ptr: *mut *mut H,
    name: &'static str,
    value: H,
) -> Result<(), Failure> {
    // SAFETY: the caller's contract, passed on.
    let o = unsafe { out(out_ptr, name)? };
    o.set(Box::into_raw(Box::new(value)));
    Ok(())
}

/// Clears the out parameter `*out` (to null) if it is usable, so that a failed open leaves no
/// stale handle behind.
///
/// # Safety
///
/// As [`publish`].
pub(crate) unsafe fn clear<H>(out_ptr: *mut *mut H) {
    // SAFETY: the caller's contract, passed on.
    if let Ok(o) = unsafe { out(out_ptr, "out") } {
        o.set(core::ptr::null_mut());
    }
}

/// Opens a proxy archive from `len` bytes at `bytes`, without copying them, and stores a new
/// handle at `*out` (null on failure).
///
/// The bytes must start at a 16-byte boundary (an `mmap`, `aligned_alloc(16, …)`, or a static
/// array with `_Alignas(16)`) and must stay valid and unchanged until this handle and every blend
/// made from it are freed. Opening checks the header, checksum and structure once.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `TRUNCATED`, `NOT_ARCHIVE` (also for a map archive),
/// `WRONG_VERSION`, `CORRUPT`.
///
/// Thread safety: any thread; the handle may be shared by all threads.
///
/// # Safety
///
/// `bytes` points at `len` readable bytes (see above for how long); `out` points at writable
/// memory for one pointer.
#[no_mangle]
pub unsafe extern "C" fn otbake_proxy_open(
    bytes: *const u8,
    len: usize,
    out: *mut *mut OtbakeProxy,
) -> OtbakeStatus {
    // SAFETY: `out` is the caller's out parameter for one pointer.
    unsafe { clear(out) };
    entry("otbake_proxy_open", || {
        // SAFETY: the caller guarantees `len` bytes at `bytes` that stay valid and unchanged until
        // every handle made from them is freed: `'static` stands for that lifetime.
        let bytes: &'static [u8] = unsafe { slice(bytes, len, "bytes")? };
        let proxy = Proxy::open(bytes)?;
        let value = OtbakeProxy {
            magic: PROXY_MAGIC,
            proxy,
        };
        // SAFETY: as above.
        unsafe { publish(out, "out", value) }
    })
}

/// What the proxy holds, stored at `*info`.
///
/// Thread safety: any thread, concurrently with any query.
///
/// # Safety
///
/// `proxy` is a live proxy handle; `info` points at writable memory for one struct.
#[no_mangle]
pub unsafe extern "C" fn otbake_proxy_info(
    proxy: *const OtbakeProxy,
    info: *mut OtbakeProxyInfo,
) -> OtbakeStatus {
    entry("otbake_proxy_info", || {
        // SAFETY: the caller's contract.
        let p = unsafe { handle(proxy, "proxy")? }.proxy;
        // SAFETY: the caller's contract.
        let o = unsafe { out(info, "info")? };
        o.set(OtbakeProxyInfo {
            dim: p.dim() as u32,
            n: p.n(),
            depth: p.depth(),
            wrap: p.wrap().into(),
        });
        Ok(())
    })
}

/// Frees a proxy handle (null: nothing). Blends made from it stay valid (they hold their own
/// copy of the view).
///
/// Thread safety: no other call may use this handle during or after the call.
///
/// # Safety
///
/// `proxy` is null or a live proxy handle, used by no other thread, and never used again.
#[no_mangle]
pub unsafe extern "C" fn otbake_proxy_free(proxy: *mut OtbakeProxy) {
    // SAFETY: the caller's contract.
    unsafe { free(proxy) }
}

/// Frees a handle `h` of this crate if it is one of type `H` (null or any other pointer: nothing).
///
/// # Safety
///
/// `h` is null or a live handle of this crate, used by nothing else, never used again.
pub(crate) unsafe fn free<H: Handle>(h: *mut H) {
    if h.is_null() {
        return;
    }
    // SAFETY: the caller's contract; `handle` checks alignment and the magic.
    if unsafe { handle(h.cast_const(), "handle") }.is_ok() {
        // SAFETY: every handle of type `H` came from `Box::into_raw` in `publish`; the caller
        // guarantees nothing uses it any more. Clearing the magic first makes a second free of a
        // still-mapped box refuse instead of freeing twice (not a guarantee: freed memory may be
        // reused).
        unsafe {
            h.cast::<u32>().write(0);
            drop(Box::from_raw(h));
        }
    }
}

/// Opens a map archive from `len` bytes at `bytes`, without copying them, and stores a new handle
/// at `*out` (null on failure). The bytes' alignment and lifetime are those of
/// [`otbake_proxy_open`].
///
/// Errors: those of [`otbake_proxy_open`] (`NOT_ARCHIVE` also for a proxy archive).
///
/// Thread safety: any thread; the handle may be shared by all threads.
///
/// # Safety
///
/// As [`otbake_proxy_open`].
#[no_mangle]
pub unsafe extern "C" fn otbake_map_open(
    bytes: *const u8,
    len: usize,
    out: *mut *mut OtbakeMap,
) -> OtbakeStatus {
    // SAFETY: `out` is the caller's out parameter for one pointer.
    unsafe { clear(out) };
    entry("otbake_map_open", || {
        // SAFETY: as in `otbake_proxy_open`.
        let bytes: &'static [u8] = unsafe { slice(bytes, len, "bytes")? };
        let map = Map::open(bytes)?;
        // SAFETY: as above.
        unsafe {
            publish(
                out,
                "out",
                OtbakeMap {
                    magic: MAP_MAGIC,
                    map,
                },
            )
        }
    })
}

/// What the map holds, stored at `*info`.
///
/// Thread safety: any thread, concurrently with any query.
///
/// # Safety
///
/// `map` is a live map handle; `info` points at writable memory for one struct.
#[no_mangle]
pub unsafe extern "C" fn otbake_map_info(
    map: *const OtbakeMap,
    info: *mut OtbakeMapInfo,
) -> OtbakeStatus {
    entry("otbake_map_info", || {
        // SAFETY: the caller's contract.
        let m = unsafe { handle(map, "map")? }.map;
        // SAFETY: the caller's contract.
        let o = unsafe { out(info, "info")? };
        o.set(OtbakeMapInfo {
            dim: m.dim() as u32,
            n: m.n(),
            depth: m.depth(),
            wrap: m.wrap().into(),
            mean_mass: m.mean_mass(),
            has_color: m.has_color(),
            has_node_colors: m.has_node_colors(),
            has_spacings: m.has_spacings(),
        });
        Ok(())
    })
}

/// Frees a map handle (null: nothing). Blends made from it stay valid.
///
/// Thread safety: no other call may use this handle during or after the call.
///
/// # Safety
///
/// `map` is null or a live map handle, used by no other thread, and never used again.
#[no_mangle]
pub unsafe extern "C" fn otbake_map_free(map: *mut OtbakeMap) {
    // SAFETY: the caller's contract.
    unsafe { free(map) }
}

/// The checked map views of a blend's or BRDF's `k` map handles, in a new box.
///
/// # Safety
///
/// `maps` points at `k` pointers, each null or a live map handle.
pub(crate) unsafe fn map_views(
    maps: *const *const OtbakeMap,
    k: usize,
) -> Result<Box<[Map<'static>]>, Failure> {
    if k == 0 || k > OTBAKE_MAX_MAPS as usize {
        return Err(Failure::Count {
            name: "k",
            expected: OTBAKE_MAX_MAPS as usize,
            found: k,
        });
    }
    // SAFETY: the caller's contract: `k` readable pointers.
    let handles = unsafe { slice(maps, k, "maps")? };
    let mut views = Vec::with_capacity(k);
    for &h in handles {
        // SAFETY: the caller's contract: each is null or a live map handle.
        views.push(unsafe { handle(h, "maps[i]")? }.map);
    }
    Ok(views.into_boxed_slice())
}

/// Makes a blend of the `k` maps `maps[0..k]` of `proxy` (1 ≤ k ≤ 64) and stores a new handle at
/// `*out` (null on failure). Checks once that every map belongs to the proxy; the map and proxy
/// handles may be freed afterwards (the blend copies their views), their bytes may not.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE` (a null or non-map entry of `maps`),
/// `BAD_COUNT` (k = 0 or k > 64), `PROXY_MISMATCH` (a map of another proxy, with its index in
/// `otbake_last_error`).
///
/// Thread safety: any thread; the blend may be queried by all threads at once.
///
/// # Safety
///
/// `proxy` is a live proxy handle, `maps` points at `k` live map handles, `out` at writable memory
/// for one pointer.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_new(
    proxy: *const OtbakeProxy,
    maps: *const *const OtbakeMap,
    k: usize,
    out: *mut *mut OtbakeBlend,
) -> OtbakeStatus {
    // SAFETY: `out` is the caller's out parameter for one pointer.
    unsafe { clear(out) };
    entry("otbake_blend_new", || {
        // SAFETY: the caller's contract.
        let p = unsafe { handle(proxy, "proxy")? }.proxy;
        // SAFETY: the caller's contract.
        let views = unsafe { map_views(maps, k)? };
        let raw = Box::into_raw(views);
        // SAFETY: `raw` is the box just leaked; it is freed only by the handle's `Drop` (or
        // below, on failure), after the last use of the blend that borrows it.
        let leaked: &'static [Map<'static>] = unsafe { &*raw };
        match Blend::new(p, leaked) {
            Ok(blend) => {
                let value = OtbakeBlend {
                    magic: BLEND_MAGIC,
                    blend,
                    maps: raw,
                };
                // SAFETY: the caller's contract (on failure `value` drops and frees `raw`).
                unsafe { publish(out, "out", value) }
            }
            Err(e) => {
                // SAFETY: `raw` came from `Box::into_raw` above and nothing borrows it any more.
                drop(unsafe { Box::from_raw(raw) });
                Err(e.into())
            }
        }
    })
}

/// What the blend answers, stored at `*info`.
///
/// Thread safety: any thread, concurrently with any query.
///
/// # Safety
///
/// `blend` is a live blend handle; `info` points at writable memory for one struct.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_info(
    blend: *const OtbakeBlend,
    info: *mut OtbakeBlendInfo,
) -> OtbakeStatus {
    entry("otbake_blend_info", || {
        // SAFETY: the caller's contract.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: the caller's contract.
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

/// Frees a blend handle (null: nothing).
///
/// Thread safety: no other call may use this handle during or after the call.
///
/// # Safety
///
/// `blend` is null or a live blend handle, used by no other thread, and never used again.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_free(blend: *mut OtbakeBlend) {
    // SAFETY: the caller's contract.
    unsafe { free(blend) }
}
