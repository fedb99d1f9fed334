//! The truncated Gibbs kernel of one Sinkhorn stage, in sparse row (CSR) and column (CSC) form.
//!
//! At scale ε the plan is π_ij = u_i K_ij v_j with K_ij = exp((f_i + g_j − C_ij)/ε). A pair is kept
//! when it can matter to its row or to its column:
//!
//! * row test: C_ij − g_j ≤ min_j' (C_ij' − g_j') + θε, and
//! * column test: C_ij − f_i ≤ min_i' (C_i'j − f_i') + θε,
//!
//! where f_i is set to the row minimum (the hard c-transform of g), so every kept row entry is in
//! [e^−θ, 1] and every row holds its best column. With that f the row test implies the column
//! test (C_ij − f_i ≥ g_j for all pairs, so the column minimum is at least g_j), so a build
//! searches each row only for its minimum and each column with the margin θε. Dropped entries are
//! below e^−θ relative to the best entry of both their row and their column. The tests are *exact*
//! for the given potentials, not heuristics: the column test is one walk down both hierarchies at
//! once, pruning a pair of cells when a lower bound of C − f − g over their points (from the cells'
//! boxes and minorants of the potentials) exceeds the threshold ([`pattern`]); it reads the row
//! minima off its band when it is given upper bounds of them, and otherwise they are searched
//! first, down the target's [`Hierarchy`] one row at a time, pruning cells likewise.
//!
//! On the torus (`Wrap::Periodic`) C is the squared distance to the nearest image, and a cell's bound
//! is the smallest of the bounds for the query's images `x − m` that can be nearest (per axis `x_k`
//! and `x_k ∓ 1`, towards the far side: 2^d images): C(x, y) = min_m |x − m − y|², and each term is
//! bounded below as in the Euclidean case. The hierarchy needs no change: cells are boxes of points
//! in `[0,1)^d`, and only the bound and the costs see the metric.
//!
//! Determinism: every row (column) is searched independently and rows are processed in fixed-size
//! chunks written in order, so the kernel's bytes do not depend on the thread count.
//!
//! Here: the [`Kernel`] and its whole [`build`]; `bounds` (lower bounds of a potential over the
//! cells, affine or quadratic), `search` (the branch-and-bound searches one query at a time, and
//! the row minima), `pattern` (the column test's walk over both clouds), `local` (rebuilding only
//! the rows and columns that moved) and `sparse` (filtering, merging and transposing sparse lists
//! in fixed chunks).

mod bounds;
mod local;
mod pattern;
mod search;
mod sparse;

pub(super) use bounds::{bounds, Affine, Bounds};
pub(super) use local::{rebuild_local, Local, LocalLimits};
pub(super) use search::search;
pub(in crate::sinkhorn) use sparse::{map_lists_mut, sort_lists_by_value};

use super::hierarchy::{Hierarchy, Level};
use crate::cost;
use crate::Wrap;
use rayon::prelude::*;
use search::row_minima;
use sparse::transpose;

/// Rows per parallel work item (fixed: the output order never depends on the thread count).
const CHUNK: usize = 1024;

/// Smallest kernel value stored: column-test pairs can be far below e^−θ relative to their row's
/// offset; clamping keeps them representable (the scalings absorb the rest).
const K_MIN: f64 = 1e-37;

/// A sparse kernel on (source cells × target cells) of one level, in row form only: the column
/// update scatters from the rows ([`super::iterate`]), and the few steps that need the column form
/// (moving potentials between stages) compute its pattern when they need it ([`Kernel::columns`]).
/// Keeping the column form too cost 8 more bytes per pair, half of the kernel.
#[derive(Clone, Debug, Default)]
pub(super) struct Kernel {
    pub row_ptr: Vec<usize>,
    pub col: Vec<u32>,
    pub k: Vec<f32>,
    /// Number of columns (target cells).
    pub cols: usize,
    /// Row offsets f_i of the kernel (the hard c-transform of g).
    pub f: Vec<f64>,
}

impl Kernel {
    pub fn pairs(&self) -> usize {
        self.col.len()
    }

    /// Bytes of the kernel's arrays.
    pub fn bytes(&self) -> usize {
        self.row_ptr.len() * 8 + self.col.len() * 8 + self.f.len() * 8
    }

    /// Every entry's value K_ij = exp((f_i + g_j − C_ij)/ε) for the kernel's pattern and row
    /// offsets `f`, into `k` (allocated here when the pattern is new, resized when it grew).
    fn set_values<const D: usize>(
        &mut self,
        xs: &Level<D>,
        ys: &Level<D>,
        g: &[f64],
        eps: f64,
        wrap: Wrap,
    ) {
        let Kernel {
            row_ptr, col, k, f, ..
        } = self;
        k.resize(col.len(), 0.0);
        map_lists_mut(row_ptr, k, |i, vals| {
            for (v, &j) in vals.iter_mut().zip(&col[row_ptr[i]..row_ptr[i + 1]]) {
                let ju = j as usize;
                let cost = cost::sq(wrap, &xs.pos[i], &ys.pos[ju]);
                *v = value((f[i] + g[ju] - cost) / eps);
            }
        });
    }

    /// The values for new potentials (`self.f`, `g`) of a pattern whose entries hold their values
    /// for (`then.0`, `then.1`), but for the entries a merge added ([`sparse::NEW_VALUE`]). An old
    /// entry is rescaled by its row's and its column's factor, exp((f_i − f'_i)/ε) and exp((g_j −
    /// g'_j)/ε): no cost and no exponential per pair, which were most of a local rebuild's last
    /// pass with [`Kernel::set_values`] (D157). A new entry, or one the clamp at `K_MIN` lost, is
    /// valued from its cost. The rescaled value differs from a recomputed one by rounding only (a
    /// few `f32` ulps after the rebuilds of a stage; a whole build values every pair afresh).
    fn revalue<const D: usize>(
        &mut self,
        xs: &Level<D>,
        ys: &Level<D>,
        then: (&[f64], &[f64]),
        g: &[f64],
        eps: f64,
        wrap: Wrap,
    ) {
        let (f_then, g_then) = then;
        let colf: Vec<f64> = g
            .par_iter()
            .zip(g_then)
            .map(|(gj, gt)| ((gj - gt) / eps).exp())
            .collect();
        let Kernel {
            row_ptr, col, k, f, ..
        } = self;
        map_lists_mut(row_ptr, k, |i, vals| {
            let rowf = ((f[i] - f_then[i]) / eps).exp();
            for (v, &j) in vals.iter_mut().zip(&col[row_ptr[i]..row_ptr[i + 1]]) {
                let ju = j as usize;
                *v = if *v > K_MIN as f32 {
                    ((f64::from(*v) * rowf * colf[ju]) as f32).clamp(K_MIN as f32, 1.0)
                } else {
                    // New (NaN fails the test too), or clamped.
                    let cost = cost::sq(wrap, &xs.pos[i], &ys.pos[ju]);
                    value((f[i] + g[ju] - cost) / eps)
                };
            }
        });
    }

    /// The column form of the pattern: (column pointers, rows ascending in each column).
    pub fn columns(&self) -> (Vec<usize>, Vec<u32>) {
        transpose(&self.row_ptr, &self.col, self.cols)
    }
}

/// A kernel entry from its exponent (f + g − C)/ε: the exponential in `f32`, the precision the
/// entry is stored in (its relative error, ~|x|·6e-8 from rounding the exponent, is far below
/// anything the scalings resolve). A whole build and every local rebuild value every pair: with
/// `f64` the exponentials were most of that pass (8 against 3.6 ns each).
#[inline]
pub(super) fn value(x: f64) -> f32 {
    // Clamped below at ln K_MIN first: `expf` of an exponent past −87 returns a subnormal or 0
    // by a slow path (column-test pairs can be far below), and every such entry becomes K_MIN.
    (x as f32).max(LN_K_MIN).exp().clamp(K_MIN as f32, 1.0)
}

/// ln [`K_MIN`], rounded down (its exponential is below `K_MIN`, which the clamp then gives).
const LN_K_MIN: f32 = -85.2;

/// Squared Euclidean distance (the tests' reference; the solver uses [`cost::sq`]).
#[cfg(test)]
#[inline]
pub(super) fn sq<const D: usize>(a: &[f64; D], b: &[f64; D]) -> f64 {
    let mut s = 0.0;
    for k in 0..D {
        let d = a[k] - b[k];
        s += d * d;
    }
    s
}

/// Builds the truncated kernel of one level for target potential `g` at scale `eps`, keeping pairs
/// within `theta`·ε of their row's or column's best (see the module docs), in the metric of `wrap`.
/// `upper`, when given, bounds every row's minimum min_j (C_ij − g_j) from above (the value of a
/// column the row is likely to be best at, from the previous stage's kernel): the walk of the
/// column test then finds the row minima too. Without it, or when its band is too wide, the row
/// minima are searched first. The kernel is the same either way.
#[allow(clippy::too_many_arguments)]
pub(super) fn build<const D: usize>(
    src: &Hierarchy<D>,
    tgt: &Hierarchy<D>,
    level: usize,
    g: &[f64],
    eps: f64,
    theta: f64,
    wrap: Wrap,
    max_pairs: usize,
    upper: Option<&[f64]>,
) -> Option<Kernel> {
    let (xs, ys) = (&src.levels[level], &tgt.levels[level]);
    let margin = theta * eps;
    let t0 = std::time::Instant::now();
    // With f_i the row minimum, C_ij − f_i ≥ g_j for every pair, so the column minimum
    // min_i' (C_i'j − f_i') is at least g_j, and a pair within θε of its row's best
    // (C_ij − f_i ≤ g_j + θε) is within θε of its column's best too: the column test alone is
    // the pattern.
    let tried = upper
        .filter(|u| u.len() == xs.len() && u.iter().all(|v| v.is_finite()))
        .map(|u| pattern::column_test(src, tgt, level, u, g, margin, wrap, max_pairs));
    let t1 = std::time::Instant::now();
    let how = match &tried {
        None => "not tried",
        Some(Ok(_)) => "kept",
        Some(Err(_)) => "too wide",
    };
    let pattern = match tried {
        Some(Ok(p)) => p,
        Some(Err(pattern::Refused::Kept)) => return None,
        // The row minima first (a search with margin 0 finds only the minimizers), then the walk
        // with the tightest bounds there are.
        Some(Err(pattern::Refused::Band)) | None => {
            let (_, _, f) = row_minima(xs, tgt, level, g, wrap, max_pairs)?;
            pattern::column_test(src, tgt, level, &f, g, margin, wrap, max_pairs).ok()?
        }
    };
    let t2 = std::time::Instant::now();
    let mut kern = Kernel {
        row_ptr: pattern.ptr,
        col: pattern.cols,
        k: Vec::new(),
        cols: ys.len(),
        f: pattern.f,
    };
    kern.set_values(xs, ys, g, eps, wrap);
    if std::env::var_os("OTBAKE_TRACE").is_some() {
        let s = |a: std::time::Instant, b: std::time::Instant| (b - a).as_secs_f64();
        eprintln!(
            "  build: bounded walk {:.2}s ({}), exact walk {:.2}s, values {:.2}s",
            s(t0, t1),
            how,
            s(t1, t2),
            t2.elapsed().as_secs_f64()
        );
    }
    Some(kern)
}

#[cfg(test)]
mod tests;
#[cfg(test)]
pub(super) use tests::build_three_ways;
