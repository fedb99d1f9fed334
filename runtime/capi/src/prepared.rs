//! Prepared blends ([`OtbakePrepared`]): a blend mixed once for one weight vector into one buffer
//! the caller owns (the runtime's `Blend::prepare`), then queried without weights with the blend's
//! bits for those weights. This file holds the handle, its size query, its making (optionally with
//! the two halves of the mixing on the caller's threads: `Blend::prepare_with`), its info and its
//! arrays; the queries are `prepared_queries`.
//!
//! The buffer is borrowed like archive bytes: a prepared handle reads only it (not the blend, its
//! maps or their bytes, which may be freed first), so it must stay valid and unwritten until the
//! handle is freed. The handle is immutable: a new weight vector is a new handle (the buffer may be
//! reused once the old handle is freed), which keeps the ABI's rule that every handle may be shared
//! by all threads without locks (docs/decisions.md, D68).

use crate::guard::{disjoint, entry, handle, out, overlaps, slice, slice_mut, Handle};
use crate::handles::{clear, free, publish, OtbakeBlend, OtbakeWrap};
use crate::status::{Failure, OtbakeStatus};
use core::ffi::c_void;
use core::mem::size_of;
use core::ops::Range;
use core::sync::atomic::{AtomicBool, Ordering};
use otbake_runtime::Prepared;
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Magic of a live [`OtbakePrepared`] ("OTPR").
const PREPARED_MAGIC: u32 = u32::from_le_bytes(*b"OTPR");

/// A blend mixed for one weight vector into a caller-owned buffer (opaque to C).
#[repr(C)]
pub struct OtbakePrepared {
    magic: u32,
    /// The runtime's prepared blend; `'static` stands for "as long as the caller keeps the buffer
    /// valid and unwritten".
    pub(crate) prepared: Prepared<'static>,
    /// The addresses of the caller's buffer: outputs that overlap it are refused (the handle reads
    /// it while a query writes its outputs).
    buffer: Range<usize>,
    /// Whether range queries can answer (the blend's `has_node_colors` when it was prepared).
    has_node_colors: bool,
}

impl Handle for OtbakePrepared {
    const MAGIC: u32 = PREPARED_MAGIC;
}

impl OtbakePrepared {
    /// Refuses an output array that overlaps the prepared buffer.
    pub(crate) fn apart<T>(&self, output: &[T], name: &'static str) -> Result<(), Failure> {
        if overlaps(output, self.buffer.clone()) {
            return Err(Failure::arg(
                OtbakeStatus::Overlap,
                name,
                "overlaps the prepared blend's buffer, which the handle reads: give outputs their own memory",
            ));
        }
        Ok(())
    }

    /// Refuses a single output value whose memory overlaps the prepared buffer.
    pub(crate) fn apart_one<T>(&self, ptr: *mut T, name: &'static str) -> Result<(), Failure> {
        let at = ptr as usize;
        let end = at.saturating_add(size_of::<T>());
        if at < end && at < self.buffer.end && self.buffer.start < end {
            return Err(Failure::arg(
                OtbakeStatus::Overlap,
                name,
                "points into the prepared blend's buffer, which the handle reads: give outputs their own memory",
            ));
        }
        Ok(())
    }
}

/// How many floats the buffer of a prepared blend holds, part by part (the runtime's
/// `PreparedSizes`); `otbake_prepared_new` takes one buffer of `total` floats and carves it in
/// this order.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OtbakePreparedSizes {
    /// `n · dim` blended coordinates.
    pub positions: usize,
    /// `n · 3` blended color ratios, or 0 when the blend has no color.
    pub colors: usize,
    /// `nodes · 2 · dim` blended node boxes.
    pub node_boxes: usize,
    /// `nodes · 3` blended node color sums, or 0 without color or node color sums.
    pub node_colors: usize,
    /// The sum of the four: floats the buffer must hold.
    pub total: usize,
}

/// What a prepared blend answers.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct OtbakePreparedInfo {
    /// Dimension: coordinates per query point.
    pub dim: u32,
    /// Number of points: sample indices are `0 .. n`.
    pub n: u32,
    /// Borders of the domain.
    pub wrap: OtbakeWrap,
    /// The blended mean mass `Σ w_k mean_mass_k`: a point value's `mass` is `density` times this.
    pub mean_mass: f32,
    /// Whether the blend carries color (otherwise colors are zeros).
    pub has_color: bool,
    /// Whether range queries can answer (no color, or node color sums in every map).
    pub has_node_colors: bool,
}

/// Runs one half of a preparation: `run(task)` with a task pointer the join was given.
pub type OtbakeTaskFn = unsafe extern "C" fn(task: *mut c_void);

/// The caller's way to run the two independent halves of a preparation (positions and node boxes;
/// colors and node color sums), for instance on two threads of its job system: it calls `run(a)`
/// and `run(b)`, each at most once, in any order or at the same time on two threads, and returns
/// only after every call it made has returned (never calling `run` later). A half it does not call
/// is run after it returns. `context` is the pointer given to `otbake_prepared_new`. May be null (no join: the halves run
/// one after the other on the calling thread).
pub type OtbakeJoinFn = Option<
    unsafe extern "C" fn(context: *mut c_void, run: OtbakeTaskFn, a: *mut c_void, b: *mut c_void),
>;

/// One half of a preparation, as a join's task pointer points at it.
struct Task<'a> {
    /// The runtime's half.
    half: &'a mut (dyn FnMut() + Send),
    /// Set when the half panicked (then the buffer is incomplete and the call fails).
    panicked: &'a AtomicBool,
}

/// The [`OtbakeTaskFn`] handed to a join: runs the half at `task`, catching a panic (which must
/// not unwind into C) and recording it.
///
/// # Safety
///
/// `task` is null or one of the two task pointers the join was given, called during the join's
/// call, at most once per pointer (the join's contract).
unsafe extern "C" fn run_task(task: *mut c_void) {
    if task.is_null() {
        return;
    }
    // SAFETY: a non-null task pointer is one of the two `&mut Task` that `otbake_prepared_new`
    // passed to the join, alive until the join returns (the contract: every call happens before
    // it returns), and each is used by one call at a time (at most once per pointer); the two
    // tasks are distinct objects whose halves write disjoint buffers (`Send` halves).
    let t = unsafe { &mut *task.cast::<Task<'_>>() };
    if catch_unwind(AssertUnwindSafe(|| (t.half)())).is_err() {
        t.panicked.store(true, Ordering::SeqCst);
    }
}

/// The sizes of the buffer `otbake_prepared_new` needs for this blend, stored at `*sizes`: allocate
/// `sizes->total` floats (4-byte aligned; any contents).
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `blend` is a live blend handle; `sizes` points at writable memory for one struct.
#[no_mangle]
pub unsafe extern "C" fn otbake_blend_prepared_sizes(
    blend: *const OtbakeBlend,
    sizes: *mut OtbakePreparedSizes,
) -> OtbakeStatus {
    entry("otbake_blend_prepared_sizes", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let o = unsafe { out(sizes, "sizes")? };
        let s = b.prepared_sizes();
        o.set(OtbakePreparedSizes {
            positions: s.positions,
            colors: s.colors,
            node_boxes: s.node_boxes,
            node_colors: s.node_colors,
            total: s.total(),
        });
        Ok(())
    })
}

/// Mixes the blend for `weights[0..k]` once into the caller's `buffer` (`buffer_len` floats, at
/// least `otbake_blend_prepared_sizes`'s `total`; its contents on entry are ignored) and stores a
/// new prepared handle at `*out` (null on failure). Its queries answer with exactly the bits the
/// blend's queries give for these weights, without mixing k maps at every node they visit.
///
/// Costs one pass over every map (about `k · (dim + 3) · n` multiply-adds) and one over the tree's
/// leaves: worth it for point grids, many point queries or several splats with one weight vector.
/// For one splat per frame with new weights, `otbake_blend_splat_region_rgba` is faster (it mixes
/// only what it reads and needs no buffer).
///
/// The buffer must stay valid, and must not be written, until this handle is freed (reading it is
/// fine: `otbake_prepared_positions` points into it); it must not overlap the weights or the
/// archive bytes. The handle reads nothing else: the blend, its maps and their archive bytes may
/// be freed before it. With another weight vector, free this handle and make a new one (the
/// buffer may be reused).
///
/// `join` may be null (the two halves of the mixing run one after the other on this thread), or
/// an [`OtbakeJoinFn`] that runs them, for instance on two threads; `join_context` is passed to it
/// unchanged. The result is the same bits either way.
///
/// Errors: `NULL_POINTER`, `MISALIGNED` (weights or buffer not 4-byte aligned), `BAD_HANDLE`,
/// `BAD_COUNT` (k not the blend's, `buffer_len` below the size query's `total`), `BAD_WEIGHTS`,
/// `OVERLAP` (the buffer overlaps the weights), `INTERNAL`.
///
/// Thread safety: any thread, concurrently with every other call on the same blend except its
/// `_free`; the new handle may be queried by all threads at once.
///
/// # Safety
///
/// `blend` is a live blend handle; `weights` points at `k` floats; `buffer` at `buffer_len`
/// writable floats that stay valid and unwritten by anything else until the new handle is freed;
/// `join`, if not null, keeps the contract of [`OtbakeJoinFn`]; `out` points at writable memory
/// for one pointer.
#[no_mangle]
#[allow(clippy::too_many_arguments)]
pub unsafe extern "C" fn otbake_prepared_new(
    blend: *const OtbakeBlend,
    weights: *const f32,
    k: usize,
    buffer: *mut f32,
    buffer_len: usize,
    join: OtbakeJoinFn,
    join_context: *mut c_void,
    out: *mut *mut OtbakePrepared,
) -> OtbakeStatus {
    // SAFETY: `out` is the caller's out parameter for one pointer.
    unsafe { clear(out) };
    entry("otbake_prepared_new", || {
        // SAFETY: the caller's contract above.
        let b = unsafe { handle(blend, "blend")? }.blend;
        // SAFETY: as above.
        let w = unsafe { slice(weights, k, "weights")? };
        if buffer.is_null() {
            return Err(Failure::arg(
                OtbakeStatus::NullPointer,
                "buffer",
                "is null: pass otbake_blend_prepared_sizes' total floats of memory",
            ));
        }
        let sizes = b.prepared_sizes();
        if buffer_len < sizes.total() {
            return Err(Failure::Count {
                name: "buffer_len",
                expected: sizes.total(),
                found: buffer_len,
            });
        }
        // SAFETY: `buffer` is non-null (checked above) and the caller guarantees `buffer_len`
        // writable floats that nothing else writes until the handle is freed: `'static` stands for
        // that lifetime. Its prior contents may be uninitialized: the preparation writes every
        // float of the prefix it uses before anything reads it, and nothing reads the rest.
        let store: &'static mut [f32] = unsafe { slice_mut(buffer, buffer_len, "buffer")? };
        disjoint(store, "buffer", w)?;
        let range = {
            let r = store.as_ptr_range();
            r.start as usize..r.end as usize
        };
        // The handle pointer must not land in the buffer the handle reads.
        let slot = out.cast::<u8>().cast_const() as usize;
        if slot < range.end && range.start < slot.saturating_add(size_of::<*mut OtbakePrepared>()) {
            return Err(Failure::arg(
                OtbakeStatus::Overlap,
                "out",
                "points into the buffer: give the handle pointer its own memory",
            ));
        }
        let buffers = sizes.split(store).ok_or(Failure::Count {
            name: "buffer_len",
            expected: sizes.total(),
            found: buffer_len,
        })?;
        let prepared = match join {
            None => b.prepare(w, buffers)?,
            Some(join) => {
                let panicked = AtomicBool::new(false);
                let prepared = b.prepare_with(w, buffers, |geometry, color| {
                    let mut a = Task {
                        half: geometry,
                        panicked: &panicked,
                    };
                    let mut c = Task {
                        half: color,
                        panicked: &panicked,
                    };
                    let (pa, pc) = (
                        (&mut a as *mut Task<'_>).cast::<c_void>(),
                        (&mut c as *mut Task<'_>).cast::<c_void>(),
                    );
                    // SAFETY: the caller's contract for `join`: it calls `run_task` with `pa` or
                    // `pc`, each at most once, and returns after every call it made returned, so
                    // the tasks (alive to the end of this closure) outlive every use.
                    unsafe { join(join_context, run_task, pa, pc) };
                })?;
                if panicked.load(Ordering::SeqCst) {
                    return Err(Failure::arg(
                        OtbakeStatus::Internal,
                        "join",
                        "a half of the preparation panicked: please report it with the inputs",
                    ));
                }
                prepared
            }
        };
        let value = OtbakePrepared {
            magic: PREPARED_MAGIC,
            prepared,
            buffer: range,
            has_node_colors: b.has_node_colors(),
        };
        // SAFETY: the caller's contract for `out` (checked apart from the buffer above).
        unsafe { publish(out, "out", value) }
    })
}

/// What the prepared blend answers, stored at `*info`.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `OVERLAP` (`info` inside the buffer).
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `info` points at writable memory for one struct.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_info(
    prepared: *const OtbakePrepared,
    info: *mut OtbakePreparedInfo,
) -> OtbakeStatus {
    entry("otbake_prepared_info", || {
        // SAFETY: the caller's contract above.
        let h = unsafe { handle(prepared, "prepared")? };
        h.apart_one(info, "info")?;
        // SAFETY: as above.
        let o = unsafe { out(info, "info")? };
        let p = h.prepared;
        o.set(OtbakePreparedInfo {
            dim: p.dim() as u32,
            n: p.n(),
            wrap: p.wrap().into(),
            mean_mass: p.mean_mass(),
            has_color: p.has_color(),
            has_node_colors: h.has_node_colors,
        });
        Ok(())
    })
}

/// Stores at `*values` and `*len` where array `which` of a prepared handle lives.
///
/// # Safety
///
/// As [`otbake_prepared_positions`].
unsafe fn array_of(
    function: &'static str,
    prepared: *const OtbakePrepared,
    which: for<'x> fn(&'x Prepared<'static>) -> &'x [f32],
    values: *mut *const f32,
    len: *mut usize,
) -> OtbakeStatus {
    entry(function, || {
        // SAFETY: the caller's contract.
        let h = unsafe { handle(prepared, "prepared")? };
        h.apart_one(values, "values")?;
        h.apart_one(len, "len")?;
        // SAFETY: as above.
        let (v, l) = unsafe { (out(values, "values")?, out(len, "len")?) };
        let a = which(&h.prepared);
        v.set(a.as_ptr());
        l.set(a.len());
        Ok(())
    })
}

/// Where the blended coordinates live: `*values` points at `*len = n · dim` floats inside the
/// caller's buffer, point-major in the tree order of `otbake_prepared_sample`'s indices (a
/// periodic blend's are lifts, within half a period of `[0,1)^dim`). Read-only; valid until the
/// handle is freed.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// `prepared` is a live prepared handle; `values` and `len` point at writable memory for one
/// pointer and one size.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_positions(
    prepared: *const OtbakePrepared,
    values: *mut *const f32,
    len: *mut usize,
) -> OtbakeStatus {
    // SAFETY: the caller's contract, passed on.
    unsafe {
        array_of(
            "otbake_prepared_positions",
            prepared,
            |p| p.positions(),
            values,
            len,
        )
    }
}

/// Where the blended color ratios live: `*values` points at `*len = n · 3` floats inside the
/// caller's buffer (`*len` is 0 without color), in the order of the positions. Read-only; valid
/// until the handle is freed.
///
/// Errors: `NULL_POINTER`, `MISALIGNED`, `BAD_HANDLE`, `OVERLAP`.
///
/// Thread safety: any thread, concurrently with every other call on the same handle except
/// its `_free` (the handle is immutable); the call writes only its own outputs.
///
/// # Safety
///
/// As [`otbake_prepared_positions`].
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_colors(
    prepared: *const OtbakePrepared,
    values: *mut *const f32,
    len: *mut usize,
) -> OtbakeStatus {
    // SAFETY: the caller's contract, passed on.
    unsafe {
        array_of(
            "otbake_prepared_colors",
            prepared,
            |p| p.colors(),
            values,
            len,
        )
    }
}

/// Frees a prepared handle (null: nothing). The buffer is the caller's again: it may be freed or
/// reused for the next `otbake_prepared_new`.
///
/// Thread safety: no other call may use this handle during or after the call.
///
/// # Safety
///
/// `prepared` is null or a live prepared handle, used by no other thread, and never used again.
#[no_mangle]
pub unsafe extern "C" fn otbake_prepared_free(prepared: *mut OtbakePrepared) {
    // SAFETY: the caller's contract.
    unsafe { free(prepared) }
}
