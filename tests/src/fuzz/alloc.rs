//! A counting global allocator with a per-execution cap, so an execution that allocates far past
//! its decoder's memory budget is a finding (written before the process exits) instead of a machine
//! that swaps or an allocation abort that loses the input.
//!
//! The fuzz binary and the fuzz test install it with `#[global_allocator]`; with no cap armed it
//! only counts. [`arm`] sets the cap for one execution: live bytes may grow by at most that much
//! over what was live when it was armed, in any thread (rayon workers included).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// The allocator: [`System`] plus the counters.
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static LIMIT: AtomicUsize = AtomicUsize::new(usize::MAX);
static ARMED: AtomicBool = AtomicBool::new(false);
static TRIPPED: AtomicBool = AtomicBool::new(false);

/// Whether [`Counting`] is the global allocator (it sets this on its first allocation): without
/// it the cap cannot be checked and the harness says so.
pub fn installed() -> bool {
    LIVE.load(Ordering::Relaxed) > 0
}

/// Caps the growth of live bytes at `extra` from now on.
pub fn arm(extra: usize) {
    let base = LIVE.load(Ordering::Relaxed);
    LIMIT.store(base.saturating_add(extra), Ordering::Relaxed);
    ARMED.store(true, Ordering::Release);
}

/// Removes the cap.
pub fn disarm() {
    ARMED.store(false, Ordering::Release);
}

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    if ARMED.load(Ordering::Acquire)
        && now > LIMIT.load(Ordering::Relaxed)
        && !TRIPPED.swap(true, Ordering::AcqRel)
    {
        ARMED.store(false, Ordering::Release);
        // Allocating here is fine: the cap is off, and System serves the report's allocations.
        super::harness::fatal(&format!(
            "out of memory budget: an allocation of {by} bytes brought live memory to {now} bytes, \
             past the cap of {} bytes",
            LIMIT.load(Ordering::Relaxed)
        ));
    }
}

// SAFETY: every method forwards to `System` with the caller's arguments and only updates
// counters; the layout contracts are the caller's, passed on unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > layout.size() {
            grew(new_size - layout.size());
        } else {
            LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
