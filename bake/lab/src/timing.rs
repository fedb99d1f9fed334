//! The one set of timing helpers every program of the lab uses: a median, a CPU clock for this
//! thread and one for the whole process, one timing loop ([`time`]) and one single measurement
//! ([`wall`]).
//!
//! Wall-clock times on a shared machine include time other processes held the core; the CPU
//! clocks do not. The programs print both, so that a figure from a loaded run can still be read
//! (BENCHMARKS.md, "Method").

use std::time::Instant;

/// The median of `values` (the upper middle one of an even count); NaN if there are none.
pub fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// CPU seconds this thread has run (`CLOCK_THREAD_CPUTIME_ID`); `None` where there is no such
/// clock.
pub fn thread_cpu() -> Option<f64> {
    Clock::Thread.read()
}

/// CPU seconds all threads of this process have run, exited threads included
/// (`CLOCK_PROCESS_CPUTIME_ID`); `None` where there is no such clock.
pub fn process_cpu() -> Option<f64> {
    Clock::Process.read()
}

/// Which CPU clock a [`time`] loop reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Clock {
    /// The calling thread's: the work a single-threaded call does.
    Thread,
    /// The whole process's: the work of every thread a call keeps busy.
    Process,
}

impl Clock {
    /// The clock's reading in seconds, or `None` where it does not exist.
    pub fn read(self) -> Option<f64> {
        #[cfg(unix)]
        {
            let id = match self {
                Clock::Thread => libc::CLOCK_THREAD_CPUTIME_ID,
                Clock::Process => libc::CLOCK_PROCESS_CPUTIME_ID,
            };
            let mut ts = libc::timespec {
                tv_sec: 0,
                tv_nsec: 0,
            };
            // SAFETY: `ts` is a valid, writable `timespec`, the only memory `clock_gettime` writes.
            let rc = unsafe { libc::clock_gettime(id, &mut ts) };
            (rc == 0).then_some(ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9)
        }
        #[cfg(not(unix))]
        {
            None
        }
    }
}

/// What a [`time`] loop measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Timing {
    /// Wall seconds of each call, in call order.
    pub walls: Vec<f64>,
    /// Mean CPU seconds per call on the loop's clock (its reading after the last call less the one
    /// before the first, over the calls); NaN where the clock does not exist or nothing ran.
    pub cpu: f64,
}

impl Timing {
    /// The fastest call's wall seconds (NaN if there were none).
    pub fn min(&self) -> f64 {
        let min = self.walls.iter().copied().fold(f64::INFINITY, f64::min);
        if min.is_finite() {
            min
        } else {
            f64::NAN
        }
    }

    /// The median call's wall seconds (NaN if there were none).
    pub fn median(&self) -> f64 {
        median(&self.walls)
    }
}

/// Calls `f` `repeats` times, recording each call's wall time and the mean CPU time per call on
/// `clock`. Stops at the first error. The clock is read once before the first call and once after
/// the last, so its own cost is in no call's wall time.
pub fn time<E>(
    repeats: usize,
    clock: Clock,
    mut f: impl FnMut() -> Result<(), E>,
) -> Result<Timing, E> {
    let mut walls = Vec::with_capacity(repeats);
    let before = clock.read();
    for _ in 0..repeats {
        let t = Instant::now();
        f()?;
        walls.push(t.elapsed().as_secs_f64());
    }
    let cpu = match (clock.read(), before) {
        (Some(after), Some(before)) if repeats > 0 => (after - before) / repeats as f64,
        _ => f64::NAN,
    };
    Ok(Timing { walls, cpu })
}

/// Runs `f` once and returns its result with its wall seconds: for work done once (a bake, a
/// whole render) or a loop of many calls timed as one (divide by the count for a time per call).
pub fn wall<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = Instant::now();
    let r = f();
    (r, t.elapsed().as_secs_f64())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_takes_the_upper_middle_and_is_nan_when_empty() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 3.0);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn the_loop_records_every_call_and_stops_at_an_error() {
        let mut calls = 0;
        let t = time(5, Clock::Thread, || {
            calls += 1;
            Ok::<(), ()>(())
        })
        .unwrap();
        assert_eq!((calls, t.walls.len()), (5, 5));
        assert!(t.min() <= t.median());
        let mut calls = 0;
        let r = time(5, Clock::Process, || {
            calls += 1;
            if calls == 2 {
                Err("stop")
            } else {
                Ok(())
            }
        });
        assert_eq!((r, calls), (Err("stop"), 2));
        let none = time(0, Clock::Thread, || Ok::<(), ()>(())).unwrap();
        assert!(none.min().is_nan() && none.median().is_nan() && none.cpu.is_nan());
    }

    #[cfg(unix)]
    #[test]
    fn the_cpu_clocks_run_and_never_go_back() {
        let (t0, p0) = (thread_cpu().unwrap(), process_cpu().unwrap());
        let mut x = 0u64;
        for i in 0..1_000_000u64 {
            x = std::hint::black_box(x.wrapping_mul(31).wrapping_add(i));
        }
        let (t1, p1) = (thread_cpu().unwrap(), process_cpu().unwrap());
        assert!(t1 >= t0 && p1 >= p0, "{t0} {t1} {p0} {p1}");
        // The process has run at least as long as this thread.
        assert!(p1 >= t1, "{p1} < {t1}");
    }
}
