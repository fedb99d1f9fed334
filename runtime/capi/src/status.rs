//! Status codes ([`OtbakeStatus`]), their messages, and the thread's last error text.
//!
//! Every entry point returns a status. Its fixed message ([`otbake_status_message`]) says what the
//! code means; the detailed text of the last failure on the calling thread
//! ([`otbake_last_error`]) names the function, the argument or the point of a batch, and the
//! runtime's own message. That text lives in a thread-local fixed buffer: recording it never
//! allocates, and threads never see each other's errors.

use core::cell::RefCell;
use core::ffi::c_char;
use core::fmt::{self, Write};
use otbake_brdf::BrdfBlendError;
use otbake_runtime::Error;

/// What an `otbake_*` call did. `OTBAKE_STATUS_OK` (0) is success; every other code is a refusal
/// that changed nothing the caller can see except the output buffers the function names.
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OtbakeStatus {
    /// Success.
    Ok = 0,
    /// A pointer argument was null where the function needs memory.
    NullPointer = 1,
    /// A pointer argument is not aligned for its type (floats: 4 bytes, doubles: 8), or archive
    /// bytes do not start at a 16-byte boundary.
    Misaligned = 2,
    /// A handle argument is not a live handle of the expected kind (e.g. a map where a blend was
    /// expected).
    BadHandle = 3,
    /// A count or length is wrong: 0 maps or more than 64, a size that overflows, an output
    /// buffer shorter than the function's size query says, or a number of weights or resolutions
    /// other than the blend's.
    BadCount = 4,
    /// An output buffer overlaps an input buffer.
    Overlap = 5,
    /// Archive bytes are shorter than the archive they start (a truncated file).
    Truncated = 6,
    /// Archive bytes are not an otbake archive of the expected kind (magic, kind).
    NotArchive = 7,
    /// The archive was written by another format version or with other rkyv flags: rebake.
    WrongVersion = 8,
    /// The archive's checksum, structure or fields are wrong: the file is corrupt.
    Corrupt = 9,
    /// A map was baked against another proxy, or disagrees with it on dimension, size, tree depth
    /// or wrap.
    ProxyMismatch = 10,
    /// A weight is negative or not finite, or the weights do not sum to 1 (within 1e-4).
    BadWeights = 11,
    /// A query point or box has a NaN or infinite coordinate.
    BadCoordinate = 12,
    /// A kernel is invalid (sigma not positive and finite; adaptive: scale, min and max sigma), or
    /// too wide for a periodic blend (3 sigma > 1).
    BadKernel = 13,
    /// A grid region or resolution is empty or leaves its grid.
    BadRegion = 14,
    /// A map lacks an attribute the query needs (node color sums, spacings).
    MissingAttribute = 15,
    /// A sample index is not below the blend's point count.
    IndexOutOfRange = 16,
    /// A BRDF function was given maps that are not 3D BRDF maps.
    NotBrdf = 17,
    /// An internal error (a panic caught at the boundary); please report it.
    Internal = 18,
}

/// Number of status codes: codes are `0 .. OTBAKE_STATUS_COUNT`.
pub const OTBAKE_STATUS_COUNT: i32 = 19;

/// The fixed message of every code, indexed by the code.
const MESSAGES: [&str; OTBAKE_STATUS_COUNT as usize] = [
    "ok\0",
    "a pointer argument is null\0",
    "a pointer argument is misaligned (floats need 4 bytes, doubles 8, archive bytes 16)\0",
    "a handle argument is not a live handle of the expected kind\0",
    "a count or length is wrong (maps, weights, points, resolutions or an output buffer)\0",
    "an output buffer overlaps an input buffer\0",
    "the archive bytes are truncated\0",
    "the bytes are not an otbake archive of the expected kind\0",
    "the archive has another format version or rkyv flags: rebake it with this otbake\0",
    "the archive is corrupt (checksum, structure or fields)\0",
    "a map belongs to another proxy (or disagrees with it on dim, n, depth or wrap)\0",
    "weights must be finite, non-negative and sum to 1\0",
    "a query coordinate is NaN or infinite\0",
    "the kernel is invalid (or too wide for a periodic blend)\0",
    "a grid region or resolution is empty or leaves its grid\0",
    "a map lacks an attribute this query needs (node color sums or spacings)\0",
    "a sample index is out of range\0",
    "the maps are not 3D BRDF maps\0",
    "internal error (a panic was caught at the C boundary): please report it\0",
];

/// The fixed, NUL-terminated English message for `code` (any integer: unknown codes get a message
/// saying so). The string is static: never free it.
///
/// Thread safety: any thread, any time.
#[no_mangle]
pub extern "C" fn otbake_status_message(code: i32) -> *const c_char {
    let text = usize::try_from(code)
        .ok()
        .and_then(|i| MESSAGES.get(i))
        .copied()
        .unwrap_or("unknown otbake status code\0");
    text.as_ptr().cast()
}

/// Bytes of the last-error buffer, NUL included; longer messages are cut at a character boundary.
const LAST_ERROR_BYTES: usize = 512;

thread_local! {
    /// The text of this thread's last failure, NUL-terminated. A `const` initializer of a type
    /// without `Drop`: no allocation and no destructor registration, ever.
    static LAST_ERROR: RefCell<[u8; LAST_ERROR_BYTES]> = const { RefCell::new([0; LAST_ERROR_BYTES]) };
}

/// The empty C string, for a thread whose last-error buffer is gone (it is exiting).
static EMPTY: [u8; 1] = [0];

/// The detailed, NUL-terminated text of the last failing `otbake_*` call **on the calling thread**
/// (the function, the argument or batch index, and the runtime's message), or `""` if none
/// failed yet. Successful calls leave it unchanged. The pointer stays valid for the thread's
/// lifetime; the text changes at the thread's next failure (copy it to keep it).
///
/// Thread safety: any thread; each thread has its own text.
#[no_mangle]
pub extern "C" fn otbake_last_error() -> *const c_char {
    LAST_ERROR
        .try_with(|b| b.as_ptr().cast::<c_char>().cast_const())
        // A `static` empty C string (a `c""` literal would do, but cbindgen 0.24's parser predates them).
        .unwrap_or(EMPTY.as_ptr().cast())
}

/// A writer into a fixed buffer that keeps the last byte for the NUL and stops at a character
/// boundary when full.
struct Fixed<'b> {
    buf: &'b mut [u8; LAST_ERROR_BYTES],
    len: usize,
}

impl Write for Fixed<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for ch in s.chars() {
            let mut utf8 = [0u8; 4];
            let bytes = ch.encode_utf8(&mut utf8).as_bytes();
            if self.len + bytes.len() >= LAST_ERROR_BYTES {
                return Err(fmt::Error);
            }
            self.buf[self.len..self.len + bytes.len()].copy_from_slice(bytes);
            self.len += bytes.len();
        }
        Ok(())
    }
}

/// Why a call failed: the code and what to say about it.
#[derive(Debug)]
pub(crate) enum Failure {
    /// An argument was refused before any work: its name and what is wrong with it.
    Argument {
        /// The code.
        status: OtbakeStatus,
        /// The C parameter's name.
        name: &'static str,
        /// What is wrong and how to fix it.
        what: &'static str,
    },
    /// A count disagrees with what the handle needs.
    Count {
        /// The C parameter's name.
        name: &'static str,
        /// What the function needed.
        expected: usize,
        /// What the caller gave.
        found: usize,
    },
    /// The runtime refused, at batch element `at` if the call was a batch.
    Runtime {
        /// The runtime's error.
        error: Error,
        /// The batch index, if any.
        at: Option<usize>,
    },
    /// The maps are not BRDF maps (their dimension).
    NotBrdf(usize),
}

impl Failure {
    /// A refused argument.
    pub(crate) fn arg(status: OtbakeStatus, name: &'static str, what: &'static str) -> Self {
        Failure::Argument { status, name, what }
    }

    /// The status code of the failure.
    pub(crate) fn status(&self) -> OtbakeStatus {
        match self {
            Failure::Argument { status, .. } => *status,
            Failure::Count { .. } => OtbakeStatus::BadCount,
            Failure::Runtime { error, .. } => runtime_status(error),
            Failure::NotBrdf(_) => OtbakeStatus::NotBrdf,
        }
    }

    /// The failure at batch element `i` (a runtime error without an index gets it).
    pub(crate) fn at(self, i: usize) -> Self {
        match self {
            Failure::Runtime { error, at: None } => Failure::Runtime { error, at: Some(i) },
            other => other,
        }
    }
}

impl From<Error> for Failure {
    fn from(error: Error) -> Self {
        Failure::Runtime { error, at: None }
    }
}

impl From<BrdfBlendError> for Failure {
    fn from(e: BrdfBlendError) -> Self {
        match e {
            BrdfBlendError::NotBrdf(dim) => Failure::NotBrdf(dim),
            BrdfBlendError::Runtime(error) => error.into(),
        }
    }
}

/// The code of a runtime error. Exhaustive on purpose: a new runtime error must be given a code.
fn runtime_status(e: &Error) -> OtbakeStatus {
    use otbake_formats::FormatError as F;
    match e {
        Error::Format(f) => match f {
            F::TooShort { .. } | F::LengthMismatch { .. } => OtbakeStatus::Truncated,
            F::BadMagic | F::WrongKind { .. } => OtbakeStatus::NotArchive,
            F::WrongVersion { .. } | F::WrongFlags { .. } => OtbakeStatus::WrongVersion,
            F::Misaligned => OtbakeStatus::Misaligned,
            F::ChecksumMismatch | F::Invalid | F::Inconsistent { .. } => OtbakeStatus::Corrupt,
        },
        Error::ProxyMismatch { .. } | Error::ShapeMismatch { .. } | Error::WrapMismatch { .. } => {
            OtbakeStatus::ProxyMismatch
        }
        Error::PeriodicKernel { .. } | Error::BadSigma => OtbakeStatus::BadKernel,
        Error::NoMaps
        | Error::WeightCount { .. }
        | Error::PointDim { .. }
        | Error::BufferSize { .. } => OtbakeStatus::BadCount,
        Error::BadWeight { .. } | Error::WeightSum { .. } => OtbakeStatus::BadWeights,
        Error::BadCoordinate => OtbakeStatus::BadCoordinate,
        Error::BadRegion { .. } => OtbakeStatus::BadRegion,
        Error::MissingAttribute { .. } => OtbakeStatus::MissingAttribute,
        Error::IndexOutOfRange { .. } => OtbakeStatus::IndexOutOfRange,
    }
}

/// Writes `function: failure` into this thread's last-error buffer.
pub(crate) fn record(function: &str, failure: &Failure) {
    let _ = LAST_ERROR.try_with(|cell| {
        if let Ok(mut buf) = cell.try_borrow_mut() {
            let mut w = Fixed {
                buf: &mut buf,
                len: 0,
            };
            // A message too long for the buffer is cut; the cut text is still useful.
            let _ = write!(w, "{function}: ");
            let _ = match failure {
                Failure::Argument { name, what, .. } => write!(w, "argument `{name}`: {what}"),
                Failure::Count {
                    name,
                    expected,
                    found,
                } => write!(
                    w,
                    "argument `{name}` is {found}, this call needs {expected}: pass the count the size query or the handle's info gives"
                ),
                Failure::Runtime { error, at: Some(i) } => write!(w, "element {i} of the batch: {error}"),
                Failure::Runtime { error, at: None } => write!(w, "{error}"),
                Failure::NotBrdf(dim) => write!(
                    w,
                    "the maps are {dim}-dimensional; BRDF functions need maps baked from BRDF inputs (3D)"
                ),
            };
            let end = w.len;
            buf[end] = 0;
        }
    });
}
