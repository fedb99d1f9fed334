//! The truncated Gibbs kernel of one Sinkhorn stage, in sparse row (CSR) and column (CSC) form.
//!
//! At scale ε the plan is π_ij = u_i K_ij v_j with K_ij = exp((f_i + g_j − C_ij)/ε). A pair is kept
//! when it can matter to its row or to its column:
//!
//! * row test: C_ij − g_j ≤ min_j' (C_ij' − g_j') + θε, and
//! * column test: C_ij − f_i ≤ min_i' (C_i'j − f_i') + θε,
//!
//! where f_i is set to the row minimum (the hard c-transform of g), so every kept row entry is in
//! [e^−θ, 1] and every row holds its best column. With that f the row test implies the column test
//! (C_ij − f_i ≥ g_j for all pairs, so the column minimum is at least g_j), so a build searches each
//! row only for its minimum and each column with the margin θε. Dropped entries are below e^−θ
//! relative to the best entry of both their row and their column. The tests are *exact* for the
//! given potentials, not heuristics: each is a branch-and-bound search down the other cloud's
//! [`Hierarchy`], pruning a cell when |x − box|² − max(potential in the cell) exceeds the current
//! threshold, which is a lower bound of C − potential for every descendant because the box holds all
//! descendant positions.
//!
//! On the torus (`Wrap::Periodic`) C is the squared distance to the nearest image, and a cell's bound
//! is the smallest of the bounds for the query's images `x − m` that can be nearest (per axis `x_k`
//! and `x_k ∓ 1`, towards the far side: 2^d images): C(x, y) = min_m |x − m − y|², and each term is
//! bounded below as in the Euclidean case. The hierarchy needs no change: cells are boxes of points
//! in `[0,1)^d`, and only the bound and the costs see the metric.
//!
//! Determinism: every row (column) is searched independently and rows are processed in fixed-size
//! chunks concatenated in order, so the kernel's bytes do not depend on the thread count.

use super::hierarchy::{Hierarchy, Level};
use crate::cost;
use otbake_formats::Wrap;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Rows per parallel work item (fixed: the output order never depends on the thread count).
const CHUNK: usize = 1024;

/// Smallest kernel value stored: column-test pairs can be far below e^−θ relative to their row's
/// offset; clamping keeps them representable (the scalings absorb the rest).
const K_MIN: f64 = 1e-37;

/// A sparse kernel on (source cells × target cells) of one level.
#[derive(Clone, Debug, Default)]
pub(super) struct Kernel {
    pub row_ptr: Vec<usize>,
    pub col: Vec<u32>,
    pub k: Vec<f32>,
    pub col_ptr: Vec<usize>,
    pub row: Vec<u32>,
    pub kt: Vec<f32>,
    /// Row offsets f_i of the kernel (the hard c-transform of g).
    pub f: Vec<f64>,
}

impl Kernel {
    pub fn pairs(&self) -> usize {
        self.col.len()
    }
}

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

/// Affine lower bounds of h = |y|² − potential over the descendants (at the search level) of every
/// cell above it: h_j ≥ α + β·y_j for every descendant j, with β fitted by least squares (any β is
/// valid; a good one makes the bound tight to second order) and α the exact minimum of h_j − β·y_j.
///
/// Then for a query x, C(x, y_j) − pot_j = |x|² + h_j − 2x·y_j ≥ |x|² + α + min over the cell's box
/// of (β − 2x)·y: a bound whose slack grows with the *curvature* of h over the cell, not with its
/// gradient, so cells far from the minimizer are pruned near the top of the hierarchy even when the
/// potential varies a lot (it does: g ≈ |y|² minus a convex function).
struct Bounds<const D: usize> {
    beta: Vec<Vec<[f64; D]>>,
    alpha: Vec<Vec<f64>>,
}

fn bounds<const D: usize>(h: &Hierarchy<D>, level: usize, pot: &[f64]) -> Bounds<D> {
    let pos = &h.levels[level].pos;
    let hv: Vec<f64> = pos
        .par_iter()
        .zip(pot)
        .map(|(y, p)| y.iter().map(|v| v * v).sum::<f64>() - p)
        .collect();
    let mut beta: Vec<Vec<[f64; D]>> = vec![Vec::new(); level];
    let mut alpha: Vec<Vec<f64>> = vec![Vec::new(); level];
    // Descendant ranges (into the search level) of the cells of the level below the current one.
    let mut below: Option<Vec<(u32, u32)>> = None;
    for l in (0..level).rev() {
        let child = &h.levels[l].child;
        let m = h.levels[l].len();
        let ranges: Vec<(u32, u32)> = (0..m)
            .map(|c| match &below {
                None => (child[c], child[c + 1]),
                Some(b) => (b[child[c] as usize].0, b[child[c + 1] as usize - 1].1),
            })
            .collect();
        let fit: Vec<([f64; D], f64)> = ranges
            .par_iter()
            .map(|&(a, b)| {
                affine_minorant(&pos[a as usize..b as usize], &hv[a as usize..b as usize])
            })
            .collect();
        beta[l] = fit.iter().map(|f| f.0).collect();
        alpha[l] = fit.iter().map(|f| f.1).collect();
        below = Some(ranges);
    }
    Bounds { beta, alpha }
}

/// Least-squares slope β of h over points y (0 where the points span no direction) and
/// α = min(h − β·y).
fn affine_minorant<const D: usize>(y: &[[f64; D]], h: &[f64]) -> ([f64; D], f64) {
    let n = y.len() as f64;
    let mut my = [0.0; D];
    let mut mh = 0.0;
    for (p, &v) in y.iter().zip(h) {
        for k in 0..D {
            my[k] += p[k];
        }
        mh += v;
    }
    my.iter_mut().for_each(|v| *v /= n);
    mh /= n;
    // Normal equations A β = r, A = Σ (y−ȳ)(y−ȳ)ᵀ, r = Σ (y−ȳ)(h−h̄).
    let mut a = [[0.0; D]; D];
    let mut r = [0.0; D];
    for (p, &v) in y.iter().zip(h) {
        let d: [f64; D] = std::array::from_fn(|k| p[k] - my[k]);
        for i in 0..D {
            r[i] += d[i] * (v - mh);
            for j in 0..D {
                a[i][j] += d[i] * d[j];
            }
        }
    }
    let beta = solve_spd(a, r);
    let alpha = y
        .iter()
        .zip(h)
        .map(|(p, &v)| v - (0..D).map(|k| beta[k] * p[k]).sum::<f64>())
        .fold(f64::INFINITY, f64::min);
    (beta, alpha)
}

/// Solves A x = r for a symmetric positive semi-definite A by Gaussian elimination, zeroing the
/// components of directions A does not span (tiny pivots).
fn solve_spd<const D: usize>(mut a: [[f64; D]; D], mut r: [f64; D]) -> [f64; D] {
    let scale = (0..D).map(|k| a[k][k]).fold(0.0, f64::max);
    let tiny = scale * 1e-12;
    let mut ok = [true; D];
    for k in 0..D {
        if a[k][k] <= tiny {
            ok[k] = false;
            continue;
        }
        for i in k + 1..D {
            let f = a[i][k] / a[k][k];
            let (top, bottom) = a.split_at_mut(i);
            for (x, y) in bottom[0][k..].iter_mut().zip(&top[k][k..]) {
                *x -= f * y;
            }
            r[i] -= f * r[k];
        }
    }
    let mut x = [0.0; D];
    for k in (0..D).rev() {
        if !ok[k] {
            continue;
        }
        let mut s = r[k];
        for j in k + 1..D {
            s -= a[k][j] * x[j];
        }
        x[k] = s / a[k][k];
    }
    if x.iter().all(|v| v.is_finite()) {
        x
    } else {
        [0.0; D]
    }
}

/// The affine lower bound of C(x, y_j) − pot_j over a cell's descendants.
#[inline]
fn cell_bound<const D: usize>(
    x: &[f64; D],
    x2: f64,
    beta: &[f64; D],
    alpha: f64,
    lo: &[f64; D],
    hi: &[f64; D],
) -> f64 {
    let mut s = x2 + alpha;
    let mut mag = x2.abs() + alpha.abs();
    for k in 0..D {
        let c = beta[k] - 2.0 * x[k];
        let t = (c * lo[k]).min(c * hi[k]);
        s += t;
        mag += t.abs();
    }
    // Rounding slack: the bound must never exceed the true value, or a pair at the threshold
    // could be pruned.
    s - mag * 1e-13
}

#[allow(clippy::too_many_arguments)]
/// All cells j of `h` at `level` with C(x, y_j) − pot_j ≤ min + `margin`, appended to `out` as
/// (j, C − pot_j) in search order; returns the minimum. With `fixed = Some(t)` the threshold is `t`
/// itself, whatever the minimum (the local rebuilds' absolute tests), and the return value is the
/// smallest value found (∞ if none).
fn search<const D: usize>(
    h: &Hierarchy<D>,
    level: usize,
    bnd: &Bounds<D>,
    pot: &[f64],
    x: &[f64; D],
    margin: f64,
    wrap: Wrap,
    stack: &mut Vec<(u32, u32, f64)>,
    out: &mut Vec<(u32, f64)>,
    hint: Option<u32>,
    fixed: Option<f64>,
) -> f64 {
    let start = out.len();
    let images = cost::Images::of(x, wrap);
    // An upper bound of the minimum from a likely candidate (the previous row's best: rows are in
    // Morton order, so neighbours share candidates) lets the search prune from the root.
    let mut best = match fixed {
        Some(t) => t - margin,
        None => hint.map_or(f64::INFINITY, |j| {
            cost::sq(wrap, x, &h.levels[level].pos[j as usize]) - pot[j as usize]
        }),
    };
    // In fixed mode `best` stays the threshold; `lowest` is the smallest value found.
    let mut lowest = f64::INFINITY;
    let mut keep = |out: &mut Vec<(u32, f64)>, best: &mut f64, j: u32, r: f64| {
        out.push((j, r));
        lowest = lowest.min(r);
        if fixed.is_none() {
            *best = best.min(r);
        }
    };
    stack.clear();
    stack.push((0, 0, f64::NEG_INFINITY));
    let mut kids: [(f64, u32); 16] = [(0.0, 0); 16];
    while let Some((l, c, lb)) = stack.pop() {
        if lb > best + margin {
            continue;
        }
        let l = l as usize;
        if l == level {
            let r = cost::sq(wrap, x, &h.levels[l].pos[c as usize]) - pot[c as usize];
            if r <= best + margin {
                keep(out, &mut best, c, r);
            }
            continue;
        }
        let lvl = &h.levels[l];
        let (a, b) = (lvl.child[c as usize], lvl.child[c as usize + 1]);
        let next = &h.levels[l + 1];
        if l + 1 == level && (b - a) as usize > kids.len() {
            // Many leaves (coincident points under one finest cell): evaluate them directly.
            for j in a..b {
                let r = cost::sq(wrap, x, &next.pos[j as usize]) - pot[j as usize];
                if r <= best + margin {
                    keep(out, &mut best, j, r);
                }
            }
            continue;
        }
        let mut m = 0;
        for j in a..b {
            let ju = j as usize;
            let bound = if l + 1 == level {
                cost::sq(wrap, x, &next.pos[ju]) - pot[ju]
            } else {
                images.min_of(|p, p2| {
                    cell_bound(
                        p,
                        p2,
                        &bnd.beta[l + 1][ju],
                        bnd.alpha[l + 1][ju],
                        &next.lo[ju],
                        &next.hi[ju],
                    )
                })
            };
            if bound <= best + margin {
                kids[m] = (bound, j);
                m += 1;
            }
        }
        // Push the most promising child last so it is searched first (tightens `best` early).
        kids[..m].sort_unstable_by(|p, q| q.0.total_cmp(&p.0).then(q.1.cmp(&p.1)));
        for &(bound, j) in &kids[..m] {
            stack.push((l as u32 + 1, j, bound));
        }
    }
    // Keep only what passes the final threshold.
    let thr = best + margin;
    let mut w = start;
    for r in start..out.len() {
        if out[r].1 <= thr {
            out[w] = out[r];
            w += 1;
        }
    }
    out.truncate(w);
    if fixed.is_some() {
        lowest
    } else {
        best
    }
}

/// For every cell of `from` at `level`: the cells of `to` passing the truncation test against
/// potential `pot` (sorted by index) and the minimum. Returned as CSR (ptr, idx) plus minima.
/// Returns `None` as soon as more than `max_pairs` pairs are found (so that memory stays bounded
/// when the blur is far above the local spacing); whether that happens does not depend on the
/// thread count, since the count only grows.
fn search_all<const D: usize>(
    from: &Level<D>,
    to: &Hierarchy<D>,
    level: usize,
    pot: &[f64],
    margin: f64,
    wrap: Wrap,
    max_pairs: usize,
) -> Option<(Vec<usize>, Vec<u32>, Vec<f64>)> {
    let count = AtomicUsize::new(0);
    let bnd = bounds(to, level, pot);
    let m = from.len();
    let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f64>)> = (0..m.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (a, b) = (ci * CHUNK, ((ci + 1) * CHUNK).min(m));
            let mut stack = Vec::new();
            let mut found = Vec::new();
            let mut lens = Vec::with_capacity(b - a);
            let mut idx = Vec::new();
            let mut mins = Vec::with_capacity(b - a);
            let mut hint = None;
            for i in a..b {
                if count.load(Ordering::Relaxed) > max_pairs {
                    break;
                }
                found.clear();
                let best = search(
                    to,
                    level,
                    &bnd,
                    pot,
                    &from.pos[i],
                    margin,
                    wrap,
                    &mut stack,
                    &mut found,
                    hint,
                    None,
                );
                hint = found
                    .iter()
                    .min_by(|p, q| p.1.total_cmp(&q.1).then(p.0.cmp(&q.0)))
                    .map(|e| e.0);
                found.sort_unstable_by_key(|e| e.0);
                count.fetch_add(found.len(), Ordering::Relaxed);
                lens.push(found.len() as u32);
                idx.extend(found.iter().map(|e| e.0));
                mins.push(best);
            }
            (lens, idx, mins)
        })
        .collect();
    if count.into_inner() > max_pairs {
        return None;
    }
    let total: usize = chunks.iter().map(|c| c.1.len()).sum();
    let mut ptr = Vec::with_capacity(m + 1);
    let mut idx = Vec::with_capacity(total);
    let mut mins = Vec::with_capacity(m);
    ptr.push(0);
    for (lens, ix, mn) in chunks {
        for l in lens {
            ptr.push(ptr.last().unwrap() + l as usize);
        }
        idx.extend(ix);
        mins.extend(mn);
    }
    Some((ptr, idx, mins))
}

/// For the elements `which` of `from` only: the cells of `to` with C − pot ≤ the element's own
/// threshold (`limit(element)`), sorted by index, with the smallest value found. Chunks of fixed
/// size, so the result does not depend on the thread count.
#[allow(clippy::too_many_arguments)]
fn search_some<const D: usize>(
    from: &Level<D>,
    to: &Hierarchy<D>,
    level: usize,
    bnd: &Bounds<D>,
    pot: &[f64],
    which: &[u32],
    limit: impl Fn(usize) -> f64 + Sync,
    wrap: Wrap,
) -> Vec<(Vec<u32>, f64)> {
    which
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let mut stack = Vec::new();
            let mut found = Vec::new();
            chunk
                .iter()
                .map(|&i| {
                    found.clear();
                    let i = i as usize;
                    let lowest = search(
                        to,
                        level,
                        bnd,
                        pot,
                        &from.pos[i],
                        0.0,
                        wrap,
                        &mut stack,
                        &mut found,
                        None,
                        Some(limit(i)),
                    );
                    let mut idx: Vec<u32> = found.iter().map(|e| e.0).collect();
                    idx.sort_unstable();
                    (idx, lowest)
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// How a local rebuild chooses what to search again, and when it gives way.
#[derive(Clone, Copy, Debug)]
pub(super) struct LocalLimits {
    /// θ: the absolute test of the searches, C − f − g ≤ θε.
    pub theta: f64,
    /// Rows and columns that moved more than τε from the reference are searched again.
    pub tau: f64,
    /// A whole build instead (`Local::TooMany`) when more than `max_moved` rows or columns moved
    /// more than `tau_whole`·ε (a loose rebuild, τ above `tau_whole`, gives way when a strict one
    /// would have to).
    pub tau_whole: f64,
    pub max_moved: usize,
    /// Refusal past this many pairs (`None`, like [`build`]).
    pub max_pairs: usize,
}

/// What a local rebuild did.
pub(super) enum Local {
    /// The new kernel, with the numbers of rows and columns searched again.
    Built(Kernel, usize, usize),
    /// More than the allowed number of rows or columns moved: build the whole kernel instead.
    TooMany,
}

/// A kernel for the new target potential `g`, built from `old` by searching again only the rows and
/// columns whose potentials moved by more than τε since the last whole build (`f0`, `g0`: the
/// potentials of that build; `old` holds its pairs and every pair added since).
///
/// Why it is enough. Every pair the whole build dropped had C − f0 − g0 > θε. A pair of a row and
/// a column that both stayed within τε of (`f0`, `g0`) therefore still has C − f − g > (θ − 2τ)ε,
/// and the old pairs are kept. A moved column is searched with the absolute test C − f − g ≤ θε
/// (against an upper bound of the new row minima, which only widens it), a moved row likewise; so
/// every pair touching a moved row or column with reduced cost ≤ θε is kept. The new f is exact:
/// a row's minimum is over its old pairs, the moved columns' new pairs, and — for a moved row — its
/// own search; a column outside those can beat it only by moving more than τε, or for rows whose
/// minimum rose by more than (θ − τ)ε, which are moved rows. So dropped pairs are more than
/// (θ − 2τ)ε above zero reduced cost, K ≤ 1 still holds, and the set only grows until the next
/// whole build. Returns `None` past `max_pairs` (like [`build`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn rebuild_local<const D: usize>(
    src: &Hierarchy<D>,
    tgt: &Hierarchy<D>,
    level: usize,
    old: &Kernel,
    g: &[f64],
    f0: &[f64],
    g0: &[f64],
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
    let (margin, moved) = (theta * eps, tau * eps);
    let whole = tau_whole * eps;
    let too_many = |d: &[f64], d0: &[f64]| {
        d.par_iter()
            .zip(d0)
            .filter(|(x, y)| (*x - *y).abs() > whole)
            .count()
            > max_moved
    };
    if too_many(g, g0) {
        return Some(Local::TooMany);
    }
    let cols: Vec<u32> = (0..nt as u32)
        .filter(|&j| (g[j as usize] - g0[j as usize]).abs() > moved)
        .collect();
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
        let bnd = bounds(src, level, &f);
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
    if too_many(&f, f0) {
        return Some(Local::TooMany);
    }
    let rows: Vec<u32> = (0..m as u32)
        .filter(|&i| (f[i as usize] - f0[i as usize]).abs() > moved)
        .collect();
    // Moved rows: every column with C − g ≤ f + θε, which also gives their exact minimum.
    if !rows.is_empty() {
        let bnd = bounds(tgt, level, g);
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
    // Rows and columns are each the old list merged with the new pairs (both sorted), valued for
    // the new (f, g): two parallel passes, no transpose. An entry's value is the same expression of
    // (i, j) in both passes, so the row and column forms hold the same bits.
    let value = |i: usize, j: usize| -> f32 {
        let c = cost::sq(wrap, &xs.pos[i], &ys.pos[j]);
        ((f[i] + g[j] - c) / eps).exp().clamp(K_MIN, 1.0) as f32
    };
    let (row_ptr, col, k) = merge_lists(&old.row_ptr, &old.col, &extra, value);
    let mut by_col: Vec<(u32, u32)> = extra.iter().map(|&(i, j)| (j, i)).collect();
    by_col.par_sort_unstable();
    let (col_ptr, row, kt) = merge_lists(&old.col_ptr, &old.row, &by_col, |j, i| value(i, j));
    let kernel = Kernel {
        row_ptr,
        col,
        k,
        col_ptr,
        row,
        kt,
        f,
    };
    Some(Local::Built(kernel, rows.len(), cols.len()))
}

/// Sparse lists (`ptr`, `idx`, each list sorted) merged with new (list, entry) pairs (sorted,
/// distinct), with `value(list, entry)` for every entry; in fixed-size chunks of lists, so the bytes
/// do not depend on the thread count.
fn merge_lists(
    ptr: &[usize],
    idx: &[u32],
    new: &[(u32, u32)],
    value: impl Fn(usize, usize) -> f32 + Sync,
) -> (Vec<usize>, Vec<u32>, Vec<f32>) {
    let m = ptr.len() - 1;
    let mut starts = vec![0usize; m + 1];
    for &(i, _) in new {
        starts[i as usize + 1] += 1;
    }
    for i in 0..m {
        starts[i + 1] += starts[i];
    }
    let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)> = (0..m.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (a, b) = (ci * CHUNK, ((ci + 1) * CHUNK).min(m));
            let mut lens = Vec::with_capacity(b - a);
            let cap = ptr[b] - ptr[a] + starts[b] - starts[a];
            let mut out = Vec::with_capacity(cap);
            let mut vals = Vec::with_capacity(cap);
            for i in a..b {
                let before = out.len();
                let (old, add) = (&idx[ptr[i]..ptr[i + 1]], &new[starts[i]..starts[i + 1]]);
                let (mut p, mut q) = (0, 0);
                while p < old.len() || q < add.len() {
                    let j = match (old.get(p), add.get(q)) {
                        (Some(&x), Some(&(_, y))) => {
                            p += usize::from(x <= y);
                            q += usize::from(y <= x);
                            x.min(y)
                        }
                        (Some(&x), None) => {
                            p += 1;
                            x
                        }
                        (None, Some(&(_, y))) => {
                            q += 1;
                            y
                        }
                        (None, None) => unreachable!("the loop runs while one side is left"),
                    };
                    out.push(j);
                    vals.push(value(i, j as usize));
                }
                lens.push((out.len() - before) as u32);
            }
            (lens, out, vals)
        })
        .collect();
    concat(chunks, m)
}

/// Chunks of lists (per chunk: list lengths, entries, values) concatenated in order, as
/// (ptr, entries, values) over `m` lists.
fn concat(
    chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)>,
    m: usize,
) -> (Vec<usize>, Vec<u32>, Vec<f32>) {
    let mut ptr = Vec::with_capacity(m + 1);
    ptr.push(0);
    let total: usize = chunks.iter().map(|c| c.1.len()).sum();
    let mut out = Vec::with_capacity(total);
    let mut vals = Vec::with_capacity(total);
    for (lens, o, v) in chunks {
        for l in lens {
            ptr.push(ptr.last().unwrap() + l as usize);
        }
        out.extend(o);
        vals.extend(v);
    }
    (ptr, out, vals)
}

/// A kernel from its rows (per chunk: row lengths, columns, values), with the transpose.
fn assemble(
    chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)>,
    m: usize,
    nt: usize,
    f: Vec<f64>,
) -> Kernel {
    let (row_ptr, col, k) = concat(chunks, m);
    let (col_ptr, row, src_pos) = transpose(&row_ptr, &col, nt);
    let kt = src_pos.par_iter().map(|&e| k[e]).collect();
    Kernel {
        row_ptr,
        col,
        k,
        col_ptr,
        row,
        kt,
        f,
    }
}

/// Column blocks of a transpose, filled in parallel: each block owns a contiguous range of the
/// output, so the blocks write disjoint slices, and every entry lands where the sequential fill
/// would put it (the result does not depend on the thread count).
const TRANSPOSE_BLOCKS: usize = 16;

/// Transposes a CSR pattern (rows ascending inside each column): returns (ptr, idx, position of
/// each transposed entry in the original arrays).
///
/// The rows' lists are sorted, and rows and columns are both in Morton order, so a row's columns
/// mostly fall in one block: a block skips a row by its first and last column, and cuts the rest by
/// binary search.
fn transpose(ptr: &[usize], idx: &[u32], cols: usize) -> (Vec<usize>, Vec<u32>, Vec<usize>) {
    let mut tptr = vec![0usize; cols + 1];
    for &j in idx {
        tptr[j as usize + 1] += 1;
    }
    for j in 0..cols {
        tptr[j + 1] += tptr[j];
    }
    let total = idx.len();
    // Block boundaries (columns) splitting the entries about evenly.
    let mut bounds = vec![0usize];
    for b in 1..TRANSPOSE_BLOCKS {
        let at = tptr
            .partition_point(|&t| t < total * b / TRANSPOSE_BLOCKS)
            .min(cols);
        if at > *bounds.last().unwrap() {
            bounds.push(at);
        }
    }
    bounds.push(cols);
    let mut tidx = vec![0u32; total];
    let mut src = vec![0usize; total];
    // Disjoint output slices, one per block.
    let mut parts = Vec::with_capacity(bounds.len() - 1);
    let (mut rest_idx, mut rest_src) = (&mut tidx[..], &mut src[..]);
    for w in bounds.windows(2) {
        let len = tptr[w[1]] - tptr[w[0]];
        let (a, r) = std::mem::take(&mut rest_idx).split_at_mut(len);
        let (b, s) = std::mem::take(&mut rest_src).split_at_mut(len);
        rest_idx = r;
        rest_src = s;
        parts.push((w[0], w[1], a, b));
    }
    parts
        .into_par_iter()
        .for_each(|(c0, c1, out_idx, out_src)| {
            let base = tptr[c0];
            let mut fill: Vec<usize> = tptr[c0..c1].iter().map(|&t| t - base).collect();
            let (lo, hi) = (c0 as u32, c1 as u32);
            for i in 0..ptr.len() - 1 {
                let row = &idx[ptr[i]..ptr[i + 1]];
                match (row.first(), row.last()) {
                    (Some(&first), Some(&last)) if last >= lo && first < hi => {
                        let a = if first >= lo {
                            0
                        } else {
                            row.partition_point(|&j| j < lo)
                        };
                        let b = if last < hi {
                            row.len()
                        } else {
                            row.partition_point(|&j| j < hi)
                        };
                        for (e, &j) in row.iter().enumerate().take(b).skip(a) {
                            let slot = &mut fill[(j - lo) as usize];
                            out_idx[*slot] = i as u32;
                            out_src[*slot] = ptr[i] + e;
                            *slot += 1;
                        }
                    }
                    _ => {}
                }
            }
        });
    (tptr, tidx, src)
}

/// Builds the truncated kernel of one level for target potential `g` at scale `eps`, keeping pairs
/// within `theta`·ε of their row's or column's best (see the module docs), in the metric of `wrap`.
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
) -> Option<Kernel> {
    let (xs, ys) = (&src.levels[level], &tgt.levels[level]);
    let margin = theta * eps;
    // f = row minima (the hard c-transform of g), with each row's best column. The row test needs
    // no search of its own: with f_i the row minimum, C_ij − f_i ≥ g_j for every pair, so the
    // column minimum min_i' (C_i'j − f_i') is at least g_j, and a pair within θε of its row's best
    // (C_ij − f_i ≤ g_j + θε) is within θε of its column's best too. A search with margin 0 finds
    // only the minimizers, and halves the cost of a build.
    let (rptr, ridx, f) = search_all(xs, tgt, level, g, 0.0, wrap, max_pairs)?;
    // Column test against f.
    let (cptr, cidx, _) = search_all(ys, src, level, &f, margin, wrap, max_pairs)?;
    // Column-test pairs as rows, then the union with the row-test pairs, row by row.
    let (eptr, eidx, _) = transpose(&cptr, &cidx, xs.len());
    let m = xs.len();
    let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f32>)> = (0..m.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (a, b) = (ci * CHUNK, ((ci + 1) * CHUNK).min(m));
            let mut lens = Vec::with_capacity(b - a);
            let mut col = Vec::new();
            let mut k = Vec::new();
            for i in a..b {
                let (r, e) = (&ridx[rptr[i]..rptr[i + 1]], &eidx[eptr[i]..eptr[i + 1]]);
                let before = col.len();
                let (mut p, mut q) = (0, 0);
                while p < r.len() || q < e.len() {
                    let j = match (r.get(p), e.get(q)) {
                        (Some(&x), Some(&y)) if x == y => {
                            p += 1;
                            q += 1;
                            x
                        }
                        (Some(&x), Some(&y)) if x < y => {
                            p += 1;
                            x
                        }
                        (Some(_), Some(&y)) => {
                            q += 1;
                            y
                        }
                        (Some(&x), None) => {
                            p += 1;
                            x
                        }
                        (None, Some(&y)) => {
                            q += 1;
                            y
                        }
                        (None, None) => unreachable!(),
                    };
                    let ju = j as usize;
                    let c = cost::sq(wrap, &xs.pos[i], &ys.pos[ju]);
                    let v = ((f[i] + g[ju] - c) / eps).exp().clamp(K_MIN, 1.0);
                    col.push(j);
                    k.push(v as f32);
                }
                lens.push((col.len() - before) as u32);
            }
            (lens, col, k)
        })
        .collect();
    Some(assemble(chunks, m, ys.len(), f))
}

#[cfg(test)]
mod tests {
    use super::super::hierarchy::Grid;
    use super::*;

    fn pts(seed: f64, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let t = (i as f64 + seed) * 0.754_877_666;
                [t.fract(), ((i as f64 + seed) * 0.569_840_29).fract() * 0.5]
            })
            .collect()
    }

    /// Smooth potentials with large gradients (like real ones), optionally with noise.
    fn potential(ys: &[[f64; 2]], rough: f64) -> Vec<f64> {
        ys.iter()
            .enumerate()
            .map(|(j, y)| {
                0.9 * (y[0] * y[0] + y[1] * y[1]) - 0.6 * y[0]
                    + 0.3 * y[1]
                    + rough * 1e-3 * ((j as f64 * 12.9898).sin() * 43758.5453).fract()
            })
            .collect()
    }

    /// The block-parallel transpose equals a sequential counting transpose, for patterns with empty
    /// rows, empty columns, rows spanning many blocks and fewer columns than blocks.
    #[test]
    fn transpose_equals_sequential() {
        for (rows, cols) in [(0usize, 3usize), (5, 2), (300, 1000), (2000, 700)] {
            let mut ptr = vec![0usize];
            let mut idx = Vec::new();
            for i in 0..rows {
                let len = (i * 7919) % 13;
                let mut row: Vec<u32> = (0..len)
                    .map(|t| (((i * 31 + t * t * 17) % cols.max(1)) as u32).min(cols as u32 - 1))
                    .collect();
                if i % 5 == 0 {
                    row.extend((0..cols as u32).step_by(97));
                }
                row.sort_unstable();
                row.dedup();
                idx.extend(&row);
                ptr.push(idx.len());
            }
            let mut want: Vec<Vec<(u32, usize)>> = vec![Vec::new(); cols];
            for i in 0..rows {
                for e in ptr[i]..ptr[i + 1] {
                    want[idx[e] as usize].push((i as u32, e));
                }
            }
            let (tptr, tidx, src) = transpose(&ptr, &idx, cols);
            for j in 0..cols {
                let got: Vec<(u32, usize)> =
                    (tptr[j]..tptr[j + 1]).map(|e| (tidx[e], src[e])).collect();
                assert_eq!(got, want[j], "{rows}x{cols} column {j}");
            }
            assert_eq!(tptr[cols], idx.len());
        }
    }

    /// The truncation keeps exactly the pairs a dense scan keeps.
    #[allow(clippy::needless_range_loop)]
    #[test]
    fn truncation_equals_dense_scan() {
        let (a, b) = (pts(0.3, 700), pts(0.7, 700));
        let grid = Grid::new(&a, &b);
        let (hs, ht) = (Hierarchy::new(&a, &grid, 5), Hierarchy::new(&b, &grid, 5));
        for (level, rough) in [(2usize, 0.0), (4, 1.0), (5, 0.0), (6, 0.0), (6, 1.0)] {
            let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
            let g = potential(&ys.pos, rough);
            let eps = 1e-3;
            let theta = 8.0;
            let kern = build(&hs, &ht, level, &g, eps, theta, Wrap::Clamp, usize::MAX).unwrap();
            let f: Vec<f64> = (0..xs.len())
                .map(|i| {
                    (0..ys.len())
                        .map(|j| sq(&xs.pos[i], &ys.pos[j]) - g[j])
                        .fold(f64::INFINITY, f64::min)
                })
                .collect();
            for i in 0..xs.len() {
                let cols = &kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
                for j in 0..ys.len() {
                    let c = sq(&xs.pos[i], &ys.pos[j]);
                    let row_ok = c - g[j] <= f[i] + theta * eps;
                    let colmin = (0..xs.len())
                        .map(|i2| sq(&xs.pos[i2], &ys.pos[j]) - f[i2])
                        .fold(f64::INFINITY, f64::min);
                    let col_ok = c - f[i] <= colmin + theta * eps;
                    assert_eq!(
                        cols.contains(&(j as u32)),
                        row_ok || col_ok,
                        "level {level} pair ({i},{j})"
                    );
                }
                assert_eq!(kern.f[i], f[i]);
            }
            // The transpose holds the same entries.
            for j in 0..ys.len() {
                for e in kern.col_ptr[j]..kern.col_ptr[j + 1] {
                    let i = kern.row[e] as usize;
                    let pos = (kern.row_ptr[i]..kern.row_ptr[i + 1])
                        .find(|&p| kern.col[p] as usize == j)
                        .unwrap();
                    assert_eq!(kern.k[pos], kern.kt[e]);
                }
            }
        }
    }

    /// A local rebuild after some potentials moved keeps its promise against a dense scan: f is
    /// the exact row minimum (so K ≤ 1), and every pair with reduced cost ≤ (θ − 2τ)ε is kept.
    #[allow(clippy::needless_range_loop)]
    #[test]
    fn local_rebuild_keeps_every_pair_it_promises() {
        let (a, b) = (pts(0.3, 900), pts(0.7, 900));
        let grid = Grid::new(&a, &b);
        let (hs, ht) = (Hierarchy::new(&a, &grid, 5), Hierarchy::new(&b, &grid, 5));
        let level = hs.point_level();
        let (xs, ys) = (&hs.levels[level], &ht.levels[level]);
        let (eps, theta, tau) = (1e-3, 8.0, 0.5);
        // A c-concave g0 (the c-transform of a c-transform), as Sinkhorn's potentials nearly are:
        // every column is some row's best, so moving one changes rows' minima.
        let rough = potential(&ys.pos, 1.0);
        let f_raw: Vec<f64> = (0..xs.len())
            .map(|i| {
                (0..ys.len())
                    .map(|j| sq(&xs.pos[i], &ys.pos[j]) - rough[j])
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let g0: Vec<f64> = (0..ys.len())
            .map(|j| {
                (0..xs.len())
                    .map(|i| sq(&xs.pos[i], &ys.pos[j]) - f_raw[i])
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let whole = build(&hs, &ht, level, &g0, eps, theta, Wrap::Clamp, usize::MAX).unwrap();
        // Every column moves a little (below τε); a patch of columns moves by up to ±12ε, and one
        // column by 40ε (it becomes the best column of rows that never saw it).
        let g: Vec<f64> = g0
            .iter()
            .zip(&ys.pos)
            .enumerate()
            .map(|(j, (&v, y))| {
                let small = 0.4 * eps * ((j as f64 * 0.37).sin());
                let patch = if (y[0] - 0.5).abs() < 0.15 && y[1] < 0.25 {
                    12.0 * eps * ((j as f64 * 1.3).sin())
                } else {
                    0.0
                };
                let jump = if j == 17 { 40.0 * eps } else { 0.0 };
                v + small + patch + jump
            })
            .collect();
        let Some(Local::Built(kern, rows, cols)) = rebuild_local(
            &hs,
            &ht,
            level,
            &whole,
            &g,
            &whole.f,
            &g0,
            eps,
            LocalLimits {
                theta,
                tau,
                tau_whole: tau,
                max_moved: xs.len(),
                max_pairs: usize::MAX,
            },
            Wrap::Clamp,
        ) else {
            panic!("the local rebuild was refused");
        };
        assert!(
            rows > 0 && cols > 0 && cols < ys.len() / 4,
            "{rows} rows, {cols} cols"
        );
        for i in 0..xs.len() {
            let f = (0..ys.len())
                .map(|j| sq(&xs.pos[i], &ys.pos[j]) - g[j])
                .fold(f64::INFINITY, f64::min);
            assert_eq!(kern.f[i], f, "row {i}: f is the exact row minimum");
            let kept = &kern.col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
            for j in 0..ys.len() {
                let reduced = sq(&xs.pos[i], &ys.pos[j]) - f - g[j];
                assert!(reduced >= -1e-12, "pair ({i},{j}) below its row minimum");
                if reduced <= (theta - 2.0 * tau) * eps {
                    assert!(kept.contains(&(j as u32)), "pair ({i},{j}) at {reduced:e}");
                }
            }
        }
        // Entries and their transpose hold the values of the new potentials.
        for j in 0..ys.len() {
            for e in kern.col_ptr[j]..kern.col_ptr[j + 1] {
                let i = kern.row[e] as usize;
                let c = sq(&xs.pos[i], &ys.pos[j]);
                let want = ((kern.f[i] + g[j] - c) / eps).exp().clamp(K_MIN, 1.0) as f32;
                assert_eq!(kern.kt[e], want);
            }
        }
    }
}
