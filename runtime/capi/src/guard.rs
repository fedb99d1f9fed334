//! The boundary every entry point goes through: [`entry`] turns a body's result (or a panic) into
//! a status and records the failure's text; the checked conversions from C pointers to Rust
//! references ([`slice`], [`slice_mut`], [`out`], [`handle`]) refuse null, misaligned, oversized
//! and overlapping arguments before a reference exists.
//!
//! Architecture Invariant: these are the crate's only conversions of caller pointers into
//! references; each checks what it can (null, alignment, size, magic) and its `unsafe` block rests
//! on the one contract the C caller must keep: a non-null pointer points at as much live memory as
//! its length says, for the whole call.

use crate::status::{record, Failure, OtbakeStatus};
use core::mem::{align_of, size_of};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Runs `body` as the entry point `function`: `Ok` becomes [`OtbakeStatus::Ok`], a failure its
/// code (its text recorded for `otbake_last_error`), and a panic [`OtbakeStatus::Internal`] —
/// never an unwind across the C boundary.
pub(crate) fn entry(
    function: &'static str,
    body: impl FnOnce() -> Result<(), Failure>,
) -> OtbakeStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => OtbakeStatus::Ok,
        Ok(Err(failure)) => {
            record(function, &failure);
            failure.status()
        }
        Err(_) => {
            record(
                function,
                &Failure::arg(
                    OtbakeStatus::Internal,
                    "(none)",
                    "a panic was caught at the C boundary: please report it with the inputs",
                ),
            );
            OtbakeStatus::Internal
        }
    }
}

/// Refuses a null or misaligned pointer to `T`.
fn check_ptr<T>(ptr: *const T, name: &'static str) -> Result<(), Failure> {
    if ptr.is_null() {
        return Err(Failure::arg(
            OtbakeStatus::NullPointer,
            name,
            "is null: pass a pointer to the memory this function reads or writes",
        ));
    }
    if !(ptr as usize).is_multiple_of(align_of::<T>()) {
        return Err(Failure::arg(
            OtbakeStatus::Misaligned,
            name,
            "is not aligned for its element type (float: 4 bytes, double: 8, structs: their largest field)",
        ));
    }
    Ok(())
}

/// The byte length of `len` values of `T`, refused when it cannot be a Rust slice (over
/// `isize::MAX` bytes).
fn byte_len<T>(len: usize, name: &'static str) -> Result<usize, Failure> {
    len.checked_mul(size_of::<T>())
        .filter(|&b| b <= isize::MAX as usize)
        .ok_or(Failure::arg(
            OtbakeStatus::BadCount,
            name,
            "has a length whose size in bytes overflows: pass the number of elements, not bytes",
        ))
}

/// `a * b`, refused when it overflows (counts times dimensions).
pub(crate) fn mul(a: usize, b: usize, name: &'static str) -> Result<usize, Failure> {
    a.checked_mul(b).ok_or(Failure::arg(
        OtbakeStatus::BadCount,
        name,
        "is so large that its number of values overflows",
    ))
}

/// `len` values of `T` at `ptr`, read-only. A null pointer is allowed when `len == 0`.
///
/// # Safety
///
/// If `ptr` is non-null it must point at `len` initialized values of `T` that nothing writes
/// during the borrow `'a` (the duration of the entry point's call).
pub(crate) unsafe fn slice<'a, T>(
    ptr: *const T,
    len: usize,
    name: &'static str,
) -> Result<&'a [T], Failure> {
    if len == 0 && ptr.is_null() {
        return Ok(&[]);
    }
    check_ptr(ptr, name)?;
    byte_len::<T>(len, name)?;
    // SAFETY: `ptr` is non-null and aligned for `T` (checked above), the byte size fits `isize`
    // (checked above), and the caller guarantees `len` initialized values that nothing writes
    // during `'a` (this function's contract, which every entry point documents for C).
    Ok(unsafe { core::slice::from_raw_parts(ptr, len) })
}

/// `len` values of `T` at `ptr`, writable. A null pointer is allowed when `len == 0`.
///
/// # Safety
///
/// If `ptr` is non-null it must point at `len` initialized values of `T` that nothing else reads
/// or writes during `'a`; callers check it is disjoint from every input with [`disjoint`].
pub(crate) unsafe fn slice_mut<'a, T>(
    ptr: *mut T,
    len: usize,
    name: &'static str,
) -> Result<&'a mut [T], Failure> {
    if len == 0 && ptr.is_null() {
        return Ok(&mut []);
    }
    check_ptr(ptr, name)?;
    byte_len::<T>(len, name)?;
    // SAFETY: non-null, aligned, size within `isize` (checked above); the caller guarantees `len`
    // initialized values of `T` (plain floats and `repr(C)` structs of floats and integers, valid
    // for any bits) and exclusive access during `'a`.
    Ok(unsafe { core::slice::from_raw_parts_mut(ptr, len) })
}

/// The single value at `ptr`, writable (an out parameter).
///
/// # Safety
///
/// If `ptr` is non-null it must point at memory for one `T` that nothing else uses during `'a`.
/// The value need not be initialized: callers only write it (`T` is `Copy`, so an overwrite drops
/// nothing).
pub(crate) unsafe fn out<'a, T: Copy>(
    ptr: *mut T,
    name: &'static str,
) -> Result<Out<'a, T>, Failure> {
    check_ptr(ptr.cast_const(), name)?;
    Ok(Out {
        ptr,
        _life: core::marker::PhantomData,
    })
}

/// A checked out parameter: write-only, so the caller's memory may be uninitialized.
pub(crate) struct Out<'a, T: Copy> {
    ptr: *mut T,
    _life: core::marker::PhantomData<&'a mut T>,
}

impl<T: Copy> Out<'_, T> {
    /// Stores `value`.
    pub(crate) fn set(self, value: T) {
        // SAFETY: `out` checked the pointer is non-null and aligned, and its caller guarantees
        // memory for one `T` used by nothing else during the call; `write` reads nothing.
        unsafe { self.ptr.write(value) }
    }
}

/// Refuses an output buffer that overlaps an input buffer (Rust may not alias them; C callers
/// sometimes reuse one array for both).
pub(crate) fn disjoint<T, U>(output: &[T], name: &'static str, input: &[U]) -> Result<(), Failure> {
    let i = input.as_ptr_range();
    if overlaps(output, i.start as usize..i.end as usize) {
        return Err(Failure::arg(
            OtbakeStatus::Overlap,
            name,
            "overlaps an input array: give outputs their own memory",
        ));
    }
    Ok(())
}

/// Whether `output` shares a byte with the address range `bytes` (empty ranges share none).
pub(crate) fn overlaps<T>(output: &[T], bytes: core::ops::Range<usize>) -> bool {
    let o = output.as_ptr_range();
    let (o0, o1) = (o.start as usize, o.end as usize);
    o0 < o1 && bytes.start < bytes.end && o0 < bytes.end && bytes.start < o1
}

/// A handle type: its box starts with a magic number, checked on every use.
pub(crate) trait Handle {
    /// The magic number of live handles of this type.
    const MAGIC: u32;
}

/// The handle at `ptr`, refused when null, misaligned or of another kind.
///
/// # Safety
///
/// If `ptr` is non-null, aligned and not a dangling pointer, it must point at a handle this crate
/// made (of any kind: every handle is `repr(C)` with its magic first) that is not freed during
/// `'a`.
pub(crate) unsafe fn handle<'a, H: Handle>(
    ptr: *const H,
    name: &'static str,
) -> Result<&'a H, Failure> {
    check_ptr(ptr, name)?;
    // SAFETY: non-null and aligned (checked above); the caller guarantees a live handle of this
    // crate, and every handle type is `repr(C)` with a `u32` magic at offset 0, so reading the
    // magic through `H` reads that field whatever kind of handle it is.
    let magic = unsafe { ptr.cast::<u32>().read() };
    if magic != H::MAGIC {
        return Err(Failure::arg(
            OtbakeStatus::BadHandle,
            name,
            "is not a live handle of the kind this function takes (another kind, or freed)",
        ));
    }
    // SAFETY: as above, and the magic says it is an `H`.
    Ok(unsafe { &*ptr })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::CStr;

    #[test]
    fn a_panic_becomes_a_status() {
        let s = entry("otbake_test", || panic!("boom"));
        assert_eq!(s, OtbakeStatus::Internal);
        // SAFETY: this thread's NUL-terminated last-error text.
        let text = unsafe { CStr::from_ptr(crate::status::otbake_last_error()) };
        assert!(
            text.to_str().unwrap().starts_with("otbake_test: "),
            "{text:?}"
        );
    }

    #[test]
    fn long_messages_are_cut_whole_characters() {
        let what: &'static str = "ünïcödé ".repeat(100).leak();
        let s = entry("otbake_test", || {
            Err(Failure::arg(OtbakeStatus::BadCount, "x", what))
        });
        assert_eq!(s, OtbakeStatus::BadCount);
        // SAFETY: as above.
        let text = unsafe { CStr::from_ptr(crate::status::otbake_last_error()) };
        let t = text.to_str().expect("cut at a character boundary");
        assert!(t.len() < 512 && t.len() > 400, "{}", t.len());
    }
}
