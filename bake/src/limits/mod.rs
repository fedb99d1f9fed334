//! Memory budgets: how much a bake or a render may allocate, and the one check every decoder,
//! sampler, solver and renderer makes before it allocates.
//!
//! A [`Budget`] is a byte count and where it came from ([`Origin`]): `--memory` on the command
//! line, `[limits] memory` in the manifest, or the default, [`DEFAULT_FRACTION`] of the memory the
//! process really has ([`available`]: the least of `MemAvailable`, the cgroup limit and
//! `RLIMIT_AS`). Each stage estimates its peak allocation from sizes it knows before allocating
//! (image header dimensions, sample counts, grid resolutions) and calls [`Budget::check`], which
//! refuses with a [`LimitError`] naming what would be allocated, the estimate, the budget, where
//! the budget came from and how to fix it. A refused stage has allocated nothing large and written
//! nothing, so a bake never dies of an allocation abort half-way through.
//!
//! The budget never enters a product's key: it decides whether a product is made, never its bytes.
//!
//! Architecture Invariant: estimates are upper bounds of the peak *extra* allocation of one stage,
//! kept next to the code that allocates (decoders in `input/`, the solvers in `otbake_ot::memory`)
//! and checked here; nothing in this module allocates in proportion to the input.

mod detect;
mod size;

pub use detect::{available, Available, Bound, FALLBACK_BYTES};
pub use size::{format_bytes, parse_size};

use std::fmt;
use std::path::PathBuf;

/// The default budget is this fraction of [`available`]: the rest is for what estimates leave out
/// (allocator slack, thread stacks and arenas, the page cache of the archives being written) and
/// for the other processes of a build machine.
pub const DEFAULT_FRACTION: f64 = 0.5;

/// Where a budget came from, for messages.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// The `--memory` option.
    CommandLine,
    /// `[limits] memory` in a manifest, at this line.
    Manifest {
        /// The manifest file.
        file: PathBuf,
        /// 1-based line of the `memory` key.
        line: usize,
    },
    /// [`DEFAULT_FRACTION`] of what the process had when the budget was made.
    Default(Available),
    /// [`DEFAULT_FRACTION`] of what the address-space limit (`ulimit -v`) leaves, when that is
    /// below the budget asked for: past the limit an allocation aborts whatever the budget says.
    AddressSpace,
    /// No limit (library callers that opt out).
    Unlimited,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::CommandLine => f.write_str("from --memory"),
            Origin::Manifest { file, line } => {
                write!(f, "from `[limits] memory` at {}:{line}", file.display())
            }
            Origin::Default(a) => write!(
                f,
                "the default: {:.0}% of the {} the process has ({})",
                DEFAULT_FRACTION * 100.0,
                format_bytes(a.bytes),
                a.bound.name()
            ),
            Origin::AddressSpace => f.write_str(
                "capped at half the address space `ulimit -v` leaves this process, below the budget asked for",
            ),
            Origin::Unlimited => f.write_str("unlimited"),
        }
    }
}

/// How many bytes one stage may allocate, and where that figure came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Budget {
    /// The limit in bytes.
    pub bytes: u64,
    /// Where it came from.
    pub origin: Origin,
}

impl Budget {
    /// [`DEFAULT_FRACTION`] of the memory the process has now (reads `/proc` and `/sys`).
    pub fn for_process() -> Self {
        let a = available();
        Budget {
            bytes: (a.bytes as f64 * DEFAULT_FRACTION) as u64,
            origin: Origin::Default(a),
        }
    }

    /// No limit: every check passes.
    pub fn unlimited() -> Self {
        Budget {
            bytes: u64::MAX,
            origin: Origin::Unlimited,
        }
    }

    /// `bytes` from `--memory`.
    pub fn command_line(bytes: u64) -> Self {
        Budget {
            bytes,
            origin: Origin::CommandLine,
        }
    }

    /// Refuses `needed` bytes above the budget. `what` says what would be allocated ("image
    /// big.png: 20000×20000 pixels"), `fix` how to need less ("use a smaller image"); the message
    /// adds the estimate, the budget, its origin and how to raise it.
    pub fn check(
        &self,
        needed: u64,
        what: impl FnOnce() -> String,
        fix: &str,
    ) -> Result<(), LimitError> {
        let cap = detect::address_space_headroom().map(|c| (c as f64 * DEFAULT_FRACTION) as u64);
        let budget = match cap {
            Some(cap) if cap < self.bytes && needed > cap => Budget {
                bytes: cap,
                origin: Origin::AddressSpace,
            },
            _ if needed <= self.bytes => return Ok(()),
            _ => self.clone(),
        };
        if needed <= budget.bytes {
            return Ok(());
        }
        Err(LimitError {
            what: what(),
            needed,
            budget: Box::new(budget),
            fix: fix.to_string(),
        })
    }
}

/// A stage that would allocate more than its budget, refused before allocating.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{what} needs about {} of memory, more than the budget of {} ({}): {fix}, or raise the budget with `--memory SIZE` or `[limits] memory = \"SIZE\"` in the manifest",
    format_bytes(*needed),
    format_bytes(budget.bytes),
    budget.origin
)]
pub struct LimitError {
    /// What would be allocated.
    pub what: String,
    /// The estimate in bytes.
    pub needed: u64,
    /// The budget it exceeds (boxed: errors that carry this one stay small).
    pub budget: Box<Budget>,
    /// How to need less.
    pub fix: String,
}

/// `a · b · …` in bytes, saturating: sizes from headers can be anything, and a product that
/// overflows `u64` is certainly over budget.
pub fn product(factors: &[u64]) -> u64 {
    factors.iter().fold(1u64, |acc, &f| acc.saturating_mul(f))
}

/// The size of the file at `path` in bytes, 0 when it cannot be read (its decoder then says why).
pub fn file_len(path: &std::path::Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_refuses_above_the_budget_with_every_part_of_the_message() {
        let b = Budget::command_line(1 << 30);
        assert!(b.check(1 << 30, || unreachable!(), "x").is_ok());
        let e = b
            .check(
                3 << 30,
                || "image a.png: 4×4 pixels".into(),
                "use a smaller image",
            )
            .unwrap_err();
        let text = e.to_string();
        for part in [
            "image a.png: 4×4 pixels",
            "3.0 GiB",
            "1.0 GiB",
            "from --memory",
            "use a smaller image",
            "--memory SIZE",
            "[limits] memory",
        ] {
            assert!(text.contains(part), "{part:?} missing from {text}");
        }
        assert!(Budget::unlimited()
            .check(u64::MAX, || unreachable!(), "x")
            .is_ok());
    }

    #[test]
    fn the_default_is_a_fraction_of_what_the_process_has() {
        let b = Budget::for_process();
        let Origin::Default(a) = &b.origin else {
            panic!("{b:?}")
        };
        assert_eq!(b.bytes, (a.bytes as f64 * DEFAULT_FRACTION) as u64);
        assert!(b.origin.to_string().contains("50%"), "{}", b.origin);
    }

    #[test]
    fn products_saturate() {
        assert_eq!(product(&[2, 3, 4]), 24);
        assert_eq!(product(&[u64::MAX, 2]), u64::MAX);
    }
}
