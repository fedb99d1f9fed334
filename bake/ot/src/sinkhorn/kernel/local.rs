//! Local rebuilds: a kernel for new potentials made from the old one by searching again only the
//! rows and columns whose potentials moved.

use super::super::hierarchy::Hierarchy;
use super::bounds::{bounds, Affine, Bounds};
use super::search::search_some;
use super::sparse::merge_pairs_in_place;
use super::Kernel;
use crate::cost;
use crate::Wrap;
use rayon::prelude::*;

/// How a local rebuild chooses what to search again, and when it gives way.
#[derive(Clone, Copy, Debug)]
pub(in crate::sinkhorn) struct LocalLimits {
    /// θ: the absolute test of the searches, C − f − g ≤ θε.
    pub theta: f64,
    /// Rows and columns that moved more than τε from the reference are searched again.
    pub tau: f64,
    /// A whole build instead (`Local::TooMany`) when more than `max_moved` rows or columns moved
    /// more than `tau_whole`·ε (a loose rebuild, τ above `tau_whole`, gives way when a strict one
    /// would have to).
    pub tau_whole: f64,
    pub max_moved: usize,
    /// Refusal past this many pairs (`None`, like [`super::build`]).
    pub max_pairs: usize,
}

/// What a local rebuild did.
pub(in crate::sinkhorn) enum Local {
    /// The kernel was rebuilt in place; the numbers of rows and columns searched again.
    Built(usize, usize),
    /// More than the allowed number of rows or columns moved: build the whole kernel instead.
    TooMany,
}

/// Rebuilds `kern` in place for the new target potential `g` by searching again only the rows and
/// columns whose potentials moved by more than τε from their references (`f0`, `g0`: each row's
/// and column's potential when it was last searched, by the last whole build or a local rebuild
/// since; `kern` holds that build's pairs and every pair added since, valued for its own `f` and
/// `g_then`), and moves the references of the rows and columns it searched to their new
/// potentials. In place, because an old and a new kernel side by side were the solve's peak
/// memory; `kern` and the references are unchanged when the result is `TooMany` or `None`.
///
/// Why it is enough. The invariant: every pair the kernel lacks has C − f0_i − g0_j > θε (a whole
/// build keeps every pair within θε). A pair of a row and a column that both stayed within τε of
/// their references therefore still has C − f − g > (θ − 2τ)ε. A moved column is searched with
/// the absolute test C − f − g ≤ (θ + τ)ε (against an upper bound of the new row minima, which
/// only widens it), a moved row likewise; so a pair it does not keep has C − f − g > (θ + τ)ε,
/// and with its other side within τε of its reference (or searched too), C − f0 − g0 > θε at the
/// moved side's new reference: the invariant holds again, and a row or column searched once is not
/// searched again until it moves τε from where it was searched (the last rebuilds of a stage
/// searched the same rows again and again, D163). The new f is exact: a row's minimum is over its
/// old pairs, the moved columns' new pairs, and — for a moved row — its own search; a column
/// outside those can beat it only by moving more than τε, or for rows whose minimum rose by more
/// than (θ − τ)ε, which are moved rows. So the pairs the kernel lacks are more than (θ − 2τ)ε above
/// zero reduced cost, K ≤ 1 still holds, and the set only grows until the next whole build.
/// Returns `None` past `max_pairs` (like [`super::build`]).
#[allow(clippy::too_many_arguments)]
pub(in crate::sinkhorn) fn rebuild_local<const D: usize>(
    src: &Hierarchy<D>,
    tgt: &Hierarchy<D>,
    level: usize,
    kern: &mut Kernel,
    g_then: &[f64],
    g: &[f64],
    f0: &mut [f64],
    g0: &mut [f64],
    eps: f64,
    limits: LocalLimits,
    wrap: Wrap,
) -> Option<Local> {
    let (xs, ys) = (&src.levels[level], &tgt.levels[level]);
    let (m, nt) = (xs.len(), ys.len());
    let LocalLimits {
        theta,
        tau,
        tau_whole,
        max_moved,
        max_pairs,
    } = limits;
    let (margin, moved) = ((theta + tau) * eps, tau * eps);
    let whole = tau_whole * eps;
    let too_many = |d: &[f64], d0: &[f64]| {
        d.par_iter()
            .zip(d0)
            .filter(|(x, y)| (*x - *y).abs() > whole)
            .count()
            > max_moved
    };
    if too_many(g, &*g0) {
        return Some(Local::TooMany);
    }
    let cols: Vec<u32> = (0..nt as u32)
        .filter(|&j| (g[j as usize] - g0[j as usize]).abs() > moved)
        .collect();
    let old = &*kern;
    // Upper bounds of the new row minima over the old pairs.
    let mut f: Vec<f64> = (0..m)
        .into_par_iter()
        .map(|i| {
            old.col[old.row_ptr[i]..old.row_ptr[i + 1]]
                .iter()
                .map(|&j| cost::sq(wrap, &xs.pos[i], &ys.pos[j as usize]) - g[j as usize])
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    // Moved columns: every row with C − f − g ≤ θε.
    let col_hits = if cols.is_empty() {
        Vec::new()
    } else {
        let bnd: Bounds<D, Affine<D>> = bounds(src, level, &f);
        search_some(ys, src, level, &bnd, &f, &cols, |j| g[j] + margin, wrap)
    };
    let mut extra: Vec<(u32, u32)> = Vec::new();
    for (&j, (rows, _)) in cols.iter().zip(&col_hits) {
        for &i in rows {
            let iu = i as usize;
            let c = cost::sq(wrap, &xs.pos[iu], &ys.pos[j as usize]) - g[j as usize];
            f[iu] = f[iu].min(c);
            extra.push((i, j));
        }
    }
    if too_many(&f, &*f0) {
        return Some(Local::TooMany);
    }
    let rows: Vec<u32> = (0..m as u32)
        .filter(|&i| (f[i as usize] - f0[i as usize]).abs() > moved)
        .collect();
    // Moved rows: every column with C − g ≤ f + θε, which also gives their exact minimum.
    if !rows.is_empty() {
        let bnd: Bounds<D, Affine<D>> = bounds(tgt, level, g);
        let row_hits = search_some(xs, tgt, level, &bnd, g, &rows, |i| f[i] + margin, wrap);
        for (&i, (js, lowest)) in rows.iter().zip(row_hits) {
            f[i as usize] = f[i as usize].min(lowest);
            extra.extend(js.iter().map(|&j| (i, j)));
        }
    }
    extra.par_sort_unstable();
    extra.dedup();
    if old.pairs() + extra.len() > max_pairs {
        return None;
    }
    // Rows are the old lists merged with the new pairs (both sorted), in the kernel's own arrays,
    // then valued for the new (f, g).
    merge_pairs_in_place(&mut kern.row_ptr, &mut kern.col, Some(&mut kern.k), &extra);
    for &i in &rows {
        f0[i as usize] = f[i as usize];
    }
    for &j in &cols {
        g0[j as usize] = g[j as usize];
    }
    let f_then = std::mem::replace(&mut kern.f, f);
    kern.revalue(xs, ys, (&f_then, g_then), g, eps, wrap);
    Some(Local::Built(rows.len(), cols.len()))
}
