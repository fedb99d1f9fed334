//! The exact truncation tests as branch-and-bound searches down a hierarchy: every cell of one
//! cloud within a margin of its best in the other, one query point at a time or, for the column
//! tests, a group of neighbouring queries at once ([`search_group`]), in fixed chunks.

use super::super::hierarchy::{Hierarchy, Level};
use super::bounds::{affine_minorant, bounds, Affine, Bounds, Minorant, Quad};
use super::CHUNK;
use crate::cost;
use crate::Wrap;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// In the grouped searches ([`search_group`]), a cell with at most this many descendants on the
/// search level has them evaluated directly instead of being searched further: near the bottom of
/// the hierarchy cells hold one to eight points, and bounding every child cost more than evaluating
/// the points (a column search of the 250K cow's final build bounded 1149 children and expanded 205
/// cells to find ~77 pairs; with buckets of 32 it bounds 612, expands 77 and evaluates 538 points,
/// 26% less time; D151).
const BUCKET: u32 = 32;

/// [`BUCKET`] of the searches one query at a time ([`search`]): with the quadratic bounds of the
/// row minima a bound costs more and prunes more, and evaluating up to 64 points beat bounding
/// them (1M cow final build row minima 2.03 → 1.65 s, the final stage's local rebuilds a few
/// percent faster; 128 the same, 256 slower; D156).
const BUCKET_ONE: u32 = 64;

#[allow(clippy::too_many_arguments)]
/// All cells j of `h` at `level` with C(x, y_j) − pot_j ≤ min + `margin`, appended to `out` as
/// (j, C − pot_j) in search order; returns the minimum. With `fixed = Some(t)` the threshold is `t`
/// itself, whatever the minimum (the local rebuilds' absolute tests), and the return value is the
/// smallest value found (∞ if none).
pub(in crate::sinkhorn) fn search<const D: usize, M: Minorant<D>, P: Fn(usize) -> f64>(
    h: &Hierarchy<D>,
    level: usize,
    bnd: &Bounds<D, M>,
    pot: &P,
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
            cost::sq(wrap, x, &h.levels[level].pos[j as usize]) - pot(j as usize)
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
        // Only the root, when the search level is the root's (cells below are evaluated by their
        // parents).
        if l == level {
            let r = cost::sq(wrap, x, &h.levels[l].pos[c as usize]) - pot(c as usize);
            if r <= best + margin {
                keep(out, &mut best, c, r);
            }
            continue;
        }
        // A cell just above the search level (its children are the candidates themselves, as
        // many as coincide) or with few descendants: its candidates are evaluated directly.
        let (da, db) = bnd.desc[l][c as usize];
        if l + 1 == level || db - da <= BUCKET_ONE {
            let pts = &h.levels[level];
            for j in da..db {
                let r = cost::sq(wrap, x, &pts.pos[j as usize]) - pot(j as usize);
                if r <= best + margin {
                    keep(out, &mut best, j, r);
                }
            }
            continue;
        }
        let lvl = &h.levels[l];
        let (a, b) = (lvl.child[c as usize], lvl.child[c as usize + 1]);
        let next = &h.levels[l + 1];
        let mut m = 0;
        for j in a..b {
            let ju = j as usize;
            // A cell above the search level (the level below is never the search level here).
            let cell = &bnd.cells[l + 1][ju];
            let bound = images.min_of(|p, p2| cell.bound(p, p2, &next.lo[ju], &next.hi[ju]));
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
pub(super) fn search_all<const D: usize>(
    from: &Level<D>,
    to: &Hierarchy<D>,
    level: usize,
    pot: &[f64],
    margin: f64,
    wrap: Wrap,
    max_pairs: usize,
) -> Option<(Vec<usize>, Vec<u32>, Vec<f64>)> {
    let count = AtomicUsize::new(0);
    // The grouped searches bound a box of queries with the affine minorants, the single ones one
    // query with the quadratic ones ([`Quad`]).
    let walk = if margin > 0.0 {
        Walk::Grouped(bounds(to, level, pot))
    } else {
        Walk::Single(bounds(to, level, pot))
    };
    let m = from.len();
    // Column tests (a margin of θε) search in groups ([`search_group`]); a search for the
    // minimum alone (the row minima) one query at a time: a group pays the spread of its queries'
    // minima about the fitted plane (the potential's curvature over the group) as extra margin,
    // small next to θε but most of the walk of a search with margin 0 (the 1M cow's row minima
    // took 4.65 s in groups of 8 and 2.93 s one at a time; its column tests 4.82 s instead of
    // 5.73 s, D152).
    let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f64>)> = (0..m.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (a, b) = (ci * CHUNK, ((ci + 1) * CHUNK).min(m));
            let mut stack = Vec::new();
            let mut lens = Vec::with_capacity(b - a);
            let mut idx = Vec::new();
            let mut mins = Vec::with_capacity(b - a);
            let mut push = |list: &mut Vec<(u32, f64)>, min: f64| {
                list.sort_unstable_by_key(|e| e.0);
                count.fetch_add(list.len(), Ordering::Relaxed);
                lens.push(list.len() as u32);
                idx.extend(list.iter().map(|e| e.0));
                mins.push(min);
            };
            match &walk {
                Walk::Grouped(bnd) => {
                    let mut found = vec![Vec::new(); GROUP];
                    let mut best = [f64::INFINITY; GROUP];
                    let mut hints: Vec<u32> = Vec::with_capacity(GROUP);
                    for group in from.pos[a..b].chunks(GROUP) {
                        if count.load(Ordering::Relaxed) > max_pairs {
                            break;
                        }
                        let g = group.len();
                        let (found, best) = (&mut found[..g], &mut best[..g]);
                        search_group(
                            to, level, bnd, pot, group, margin, wrap, &mut stack, found, best,
                            &hints,
                        );
                        hints.clear();
                        for (list, &min) in found.iter_mut().zip(&*best) {
                            if let Some(e) = list.iter().find(|e| e.1 == min) {
                                hints.push(e.0);
                            }
                            push(list, min);
                        }
                        hints.sort_unstable();
                        hints.dedup();
                    }
                }
                Walk::Single(bnd) => {
                    let mut found = Vec::new();
                    let mut hint = None;
                    for x in &from.pos[a..b] {
                        if count.load(Ordering::Relaxed) > max_pairs {
                            break;
                        }
                        found.clear();
                        let best = search(
                            to,
                            level,
                            bnd,
                            &|j| pot[j],
                            x,
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
                        push(&mut found, best);
                    }
                }
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

/// How [`search_all`] walks the hierarchy, with the cell bounds the walk needs.
enum Walk<const D: usize> {
    /// In groups of neighbouring queries, on affine minorants (the column tests).
    Grouped(Bounds<D, Affine<D>>),
    /// One query at a time, on quadratic minorants (the row minima).
    Single(Bounds<D, Quad<D>>),
}

/// For the elements `which` of `from` only: the cells of `to` with C − pot ≤ the element's own
/// threshold (`limit(element)`), sorted by index, with the smallest value found. Chunks of fixed
/// size, so the result does not depend on the thread count.
#[allow(clippy::too_many_arguments)]
pub(super) fn search_some<const D: usize, M: Minorant<D>>(
    from: &Level<D>,
    to: &Hierarchy<D>,
    level: usize,
    bnd: &Bounds<D, M>,
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
                        &|j| pot[j],
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

/// Queries [`search_all`] searches together: consecutive cells of the query level (Morton order,
/// so a group is a few neighbours). One walk down the hierarchy serves the whole group: the
/// cells' bounds, the stack and the pruning are paid once per group instead of once per query,
/// and a leaf that survives is evaluated for every query it can hold a pair of (each query checks
/// its own bound first). The walk, not the evaluations, was most of a whole build (D152).
const GROUP: usize = 8;

/// The per-axis image shifts besides 0 that can hold the nearest image (C on the torus is the
/// minimum over the shifts of x by −1, 0, +1 per axis; every point is in [0, 1)).
fn shifts(wrap: Wrap) -> &'static [f64] {
    match wrap {
        Wrap::Clamp => &[],
        Wrap::Periodic => &[1.0, -1.0],
    }
}

/// A lower bound of C(x, y_j) − pot_j − b·x over every query x in the box [`qlo`, `qhi`] and every
/// descendant y_j of a cell (its affine minorant `cell` and box `lo`, `hi`), for a slope
/// `b` across the queries.
///
/// With h_j = |y_j|² − pot_j ≥ α + β·y_j, C − pot_j − b·x ≥ α + Σ_k (x_k² − (2y_k + b_k) x_k +
/// β_k y_k), which is linear in y and so smallest at a corner of the cell's box, axis by axis; for
/// a corner value y_e the term is (x_k − c)² − c² + β_k y_e with c = y_e + b_k/2, smallest over the
/// query box at the clamped distance from c. On the torus every image z = x − m (m ∈ {−1, 0, 1}^d)
/// gets the same bound (with b·x = b·z + b·m) and the minimum over the images is again taken axis
/// by axis. For one query and b = 0 this is [`Affine::bound`] in another form.
#[inline]
#[allow(clippy::too_many_arguments)]
fn group_bound<const D: usize>(
    qlo: &[f64; D],
    qhi: &[f64; D],
    b: &[f64; D],
    shifts: &[f64],
    cell: &Affine<D>,
    lo: &[f64; D],
    hi: &[f64; D],
) -> f64 {
    let (beta, alpha) = (&cell.beta, cell.alpha);
    let mut s = alpha;
    let mut mag = alpha.abs();
    // The term of axis k for a corner value y and the query interval [za, zb], and its size.
    let term = |k: usize, y: f64, za: f64, zb: f64, m: f64| {
        let c = y + 0.5 * b[k];
        let d = (za - c).max(c - zb).max(0.0);
        let t = d * d - c * c + beta[k] * y - b[k] * m;
        (
            t,
            d * d + c * c + (beta[k] * y).abs() + za.abs() + zb.abs() + b[k].abs(),
        )
    };
    let smaller = |p: (f64, f64), q: (f64, f64)| if q.0 < p.0 { q } else { p };
    for k in 0..D {
        let (za, zb) = (qlo[k], qhi[k]);
        let mut best = smaller(term(k, lo[k], za, zb, 0.0), term(k, hi[k], za, zb, 0.0));
        for &m in shifts {
            let (za, zb) = (za - m, zb - m);
            best = smaller(best, term(k, lo[k], za, zb, m));
            best = smaller(best, term(k, hi[k], za, zb, m));
        }
        s += best.0;
        mag += best.1;
    }
    // Rounding slack, as in `Affine::bound`: a bound above the true value could prune a pair at the
    // threshold.
    s - mag * 1e-13
}

/// [`search`] for a group of queries at once: for each query q, every cell j of `h` at `level`
/// with C(x_q, y_j) − pot_j ≤ min_q + `margin` into `out[q]` as (j, value) in search order, and
/// min_q into `best[q]`. The same sets and values as one [`search`] per query: only the walk is
/// shared, and every bound it prunes with is a lower bound for each query of the group.
///
/// The queries' minima differ by far more than the margin across a group (they follow the
/// potential's slope), so the walk compares bounds of C − pot − b·x with the largest
/// min_q − b·x_q, for a slope b fitted to upper bounds of the minima: the values of the `hints`
/// (the previous group's minimizers) or, without hints, the minima found at the first leaf, the
/// walk then starting over with it. The test stays exact for any b: a cell is pruned only if for
/// every query q and descendant j, C_qj − pot_j − b·x_q > min_q − b·x_q + margin.
#[allow(clippy::too_many_arguments)]
fn search_group<const D: usize>(
    h: &Hierarchy<D>,
    level: usize,
    bnd: &Bounds<D, Affine<D>>,
    pot: &[f64],
    queries: &[[f64; D]],
    margin: f64,
    wrap: Wrap,
    stack: &mut Vec<(u32, u32, f64)>,
    out: &mut [Vec<(u32, f64)>],
    best: &mut [f64],
    hints: &[u32],
) {
    let g = queries.len();
    let shifts = shifts(wrap);
    let images: [cost::Images<D>; GROUP] =
        std::array::from_fn(|q| cost::Images::of(&queries[q.min(g - 1)], wrap));
    let mut qlo = queries[0];
    let mut qhi = queries[0];
    for x in &queries[1..] {
        for k in 0..D {
            qlo[k] = qlo[k].min(x[k]);
            qhi[k] = qhi[k].max(x[k]);
        }
    }
    for q in 0..g {
        out[q].clear();
        best[q] = f64::INFINITY;
    }
    let pts = &h.levels[level];
    // Evaluates the cells `range` of the search level for query q (what its own threshold keeps).
    let eval =
        |q: usize, range: std::ops::Range<u32>, out: &mut Vec<(u32, f64)>, best: &mut f64| {
            let x = &queries[q];
            let mut t = *best + margin;
            for j in range {
                let r = cost::sq(wrap, x, &pts.pos[j as usize]) - pot[j as usize];
                if r <= t {
                    out.push((j, r));
                    if r < *best {
                        *best = r;
                        t = r + margin;
                    }
                }
            }
        };
    let dot = |b: &[f64; D], x: &[f64; D]| (0..D).map(|k| b[k] * x[k]).sum::<f64>();
    // The group's threshold for slope b: the largest min_q − b·x_q, plus the margin (∞ until every
    // query has a value).
    let threshold = |best: &[f64], b: &[f64; D]| {
        (0..g).fold(f64::NEG_INFINITY, |t, q| {
            t.max(best[q] - dot(b, &queries[q]))
        }) + margin
    };
    // Upper bounds of the minima from likely candidates (the previous group's minimizers: the
    // queries are in Morton order, so neighbours share candidates), not kept (the walk finds them
    // again): the slope, and pruning from the root.
    for (q, x) in queries.iter().enumerate() {
        for &j in hints {
            let r = cost::sq(wrap, x, &pts.pos[j as usize]) - pot[j as usize];
            best[q] = best[q].min(r);
        }
    }
    let mut slope = [0.0; D];
    let mut fitted = g == 1;
    if !hints.is_empty() && !fitted {
        fitted = true;
        slope = affine_minorant(queries, &best[..g]).0;
    }
    let mut thr = threshold(best, &slope);
    stack.clear();
    stack.push((0, 0, f64::NEG_INFINITY));
    let mut kids: [(f64, u32); 16] = [(0.0, 0); 16];
    while let Some((l, c, lb)) = stack.pop() {
        if lb > thr {
            continue;
        }
        let l = l as usize;
        let cu = c as usize;
        if l == level {
            // Only the root, when the search level is the root's.
            for q in 0..g {
                eval(q, c..c + 1, &mut out[q], &mut best[q]);
            }
        } else if l + 1 == level || bnd.desc[l][cu].1 - bnd.desc[l][cu].0 <= BUCKET {
            let (da, db) = bnd.desc[l][cu];
            let lvl = &h.levels[l];
            let cell = &bnd.cells[l][cu];
            let (lo, hi) = (&lvl.lo[cu], &lvl.hi[cu]);
            for q in 0..g {
                let own = images[q].min_of(|p, p2| cell.bound(p, p2, lo, hi));
                if own <= best[q] + margin {
                    eval(q, da..db, &mut out[q], &mut best[q]);
                }
            }
        } else {
            let lvl = &h.levels[l];
            let (a, b) = (lvl.child[cu], lvl.child[cu + 1]);
            let next = &h.levels[l + 1];
            let mut m = 0;
            for j in a..b {
                let ju = j as usize;
                let bound = group_bound(
                    &qlo,
                    &qhi,
                    &slope,
                    shifts,
                    &bnd.cells[l + 1][ju],
                    &next.lo[ju],
                    &next.hi[ju],
                );
                if bound <= thr {
                    kids[m] = (bound, j);
                    m += 1;
                }
            }
            // The most promising child last, so it is searched first (tightens the thresholds
            // early).
            kids[..m].sort_unstable_by(|p, q| q.0.total_cmp(&p.0).then(q.1.cmp(&p.1)));
            for &(bound, j) in &kids[..m] {
                stack.push((l as u32 + 1, j, bound));
            }
            continue;
        }
        if !fitted && best[..g].iter().all(|v| v.is_finite()) {
            // The first leaf gave every query a value: fit the slope and start over (what was
            // found is found again; the minima so far stay valid upper bounds).
            fitted = true;
            slope = affine_minorant(queries, &best[..g]).0;
            for list in out.iter_mut() {
                list.clear();
            }
            stack.clear();
            stack.push((0, 0, f64::NEG_INFINITY));
        }
        thr = threshold(best, &slope);
    }
    // Keep only what passes each query's final threshold.
    for q in 0..g {
        let t = best[q] + margin;
        out[q].retain(|e| e.1 <= t);
    }
}
