//! What the steps of a solve hand each other: the state between stages, what each stage did, and
//! what the one-to-one refinement did.

use super::complete::Completed;
use super::hierarchy::Hierarchy;
use super::kernel::Kernel;
use crate::cycles::Cancelled;

/// What one stage did (for the report).
pub(super) struct StageLog {
    pub iterations: u32,
    pub converged: bool,
    pub error: f64,
}

/// The solver's state between stages: the level and the potentials on it.
pub(super) struct State {
    pub level: usize,
    pub eps: f64,
    pub kernel: Kernel,
    /// Scalings of the current kernel.
    pub u: Vec<f64>,
    pub v: Vec<f64>,
    /// Target potential the kernel was built with.
    pub g: Vec<f64>,
    /// Each row's and column's potential when it was last searched, by the last whole build or a
    /// local rebuild since (the references of local rebuilds, `kernel::rebuild_local`).
    pub f0: Vec<f64>,
    pub g0: Vec<f64>,
    /// What the support guarantees since the last rebuild.
    pub support: Support,
}

/// How far out the pairs a kernel dropped are, for the potentials it was last rebuilt around.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Support {
    /// A whole build: every dropped pair is more than θε out.
    Whole,
    /// A local rebuild with τ = `iterate::LOCAL_MOVE`·θ: more than (θ − 2τ)ε out.
    Local,
    /// A local rebuild with τ = `iterate::LOCAL_MOVE_MID`·θ during a stage: more than (θ − 2τ_mid)ε = θε/2
    /// out. Good enough to iterate on, not to end a stage on: a stage that converges on it is
    /// rebuilt locally with τ first.
    Loose,
}

/// What the one-to-one refinement did.
pub(super) struct RefineInfo {
    /// Row → column on the point level, in the hierarchies' order.
    pub x: Vec<u32>,
    pub unassigned: usize,
    pub phases: u32,
    pub bids: u64,
    /// What the augmenting paths that completed the sparse auction did.
    pub completion: Completed,
    /// What the short cycles after the auction did.
    pub cycles: Cancelled,
}

impl RefineInfo {
    /// The matching in the caller's indices.
    pub fn to_original<const D: usize>(&self, hs: &Hierarchy<D>, ht: &Hierarchy<D>) -> Vec<u32> {
        let mut out = vec![0u32; self.x.len()];
        for (k, &j) in self.x.iter().enumerate() {
            out[hs.order[k] as usize] = ht.order[j as usize];
        }
        out
    }
}
