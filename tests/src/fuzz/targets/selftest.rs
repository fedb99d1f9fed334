//! Targets that fail on purpose, to check the harness's own promises: a panic, a hang past the
//! watchdog's timeout, a crash that kills the process (an abort), and memory past the cap are
//! each reported as a finding with the input that caused it. They are not part of `--target all`
//! (see [`crate::fuzz::target`]); `tests/tests/fuzz_harness.rs` runs each through the `otbake-fuzz`
//! binary, so the supervisor and the watchdog are tested as a campaign uses them.
//!
//! Their corpus is built in: the cases `fine` and `trigger` (a file of that text each). Mutation
//! leaves a case as it is, so which executions fail depends only on which case they pick, and a
//! finding's written input must be the `trigger` file.

use crate::fuzz::{Case, Rng, Scratch, Target};
use std::path::Path;

/// How a self-test target fails on its `trigger` case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failure {
    /// `panic!` (a finding the campaign reports and continues after).
    Panic,
    /// Sleeps far past any timeout (the watchdog ends the campaign with exit code 70).
    Hang,
    /// `std::process::abort` (the supervisor writes the input from the child's last record).
    Abort,
    /// Holds 64 MiB live (past a smaller `--memory-cap`: the cap ends the campaign).
    Memory,
}

/// See the module docs.
pub struct SelfTest(pub Failure);

/// The self-test targets, by name.
pub fn all() -> Vec<SelfTest> {
    [
        Failure::Panic,
        Failure::Hang,
        Failure::Abort,
        Failure::Memory,
    ]
    .into_iter()
    .map(SelfTest)
    .collect()
}

/// The input every self-test target fails on.
pub const TRIGGER: &[u8] = b"trigger";

impl Target for SelfTest {
    fn name(&self) -> &'static str {
        match self.0 {
            Failure::Panic => "selftest-panic",
            Failure::Hang => "selftest-hang",
            Failure::Abort => "selftest-abort",
            Failure::Memory => "selftest-memory",
        }
    }

    fn seeds(&self, _corpus: &Path) -> Vec<Case> {
        vec![
            Case::single("fine", b"fine".to_vec()),
            Case::single("trigger", TRIGGER.to_vec()),
        ]
    }

    fn mutate(&self, _rng: &mut Rng, _case: &mut Case, _other: &Case) {}

    fn execute(&self, _rng: &mut Rng, case: &Case, _scratch: &Scratch) -> bool {
        if case.bytes() != TRIGGER {
            return true;
        }
        match self.0 {
            Failure::Panic => panic!("selftest: a panic on purpose"),
            Failure::Hang => loop {
                std::thread::sleep(std::time::Duration::from_secs(3600));
            },
            Failure::Abort => std::process::abort(),
            Failure::Memory => {
                let held = vec![1u8; 64 << 20];
                std::hint::black_box(&held);
                false
            }
        }
    }
}
