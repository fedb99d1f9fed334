//! Branch-and-bound searches down a hierarchy, one query point at a time: every cell of one cloud
//! within a margin of its best in the other, or below a fixed threshold; and the row minima of a
//! whole build, every query in fixed chunks. (The column test of a whole build walks both clouds
//! at once: [`super::pattern`].)

use super::super::hierarchy::{Hierarchy, Level};
use super::bounds::{bounds, Bounds, Minorant, Quad};
use super::CHUNK;
use crate::cost;
use crate::Wrap;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A cell with at most this many descendants on the search level has them evaluated directly
/// instead of being searched further: near the bottom of the hierarchy cells hold one to eight
/// points, and bounding every child cost more than evaluating the points. With the quadratic
/// bounds of the row minima a bound costs more and prunes more, and evaluating up to 64 points beat
/// bounding them (1M cow final build row minima 2.03 → 1.65 s with 64 instead of 32, the final
/// stage's local rebuilds a few percent faster; 128 the same, 256 slower; D151, D156).
const BUCKET_ONE: u32 = 64;

// Every cell a search bounds has a fitted minorant ([`super::bounds::OPENED`]).
const _: () = assert!(BUCKET_ONE >= super::bounds::OPENED);

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

/// The row minima: for every cell of `from` at `level`, the minimum over the cells j of `to` of
/// C − `pot`_j and the cells attaining it (sorted by index), as CSR (ptr, idx) plus minima. One
/// query at a time on quadratic minorants ([`Quad`]): a group of queries pays the spread of their
/// minima about a fitted plane as extra margin, most of the walk of a search with margin 0 (the 1M
/// cow's row minima took 4.65 s in groups of 8 and 2.93 s one at a time, D152). Returns `None` as
/// soon as more than `max_pairs` pairs are found (ties can be many where points coincide); whether
/// that happens does not depend on the thread count, since the count only grows.
pub(super) fn row_minima<const D: usize>(
    from: &Level<D>,
    to: &Hierarchy<D>,
    level: usize,
    pot: &[f64],
    wrap: Wrap,
    max_pairs: usize,
) -> Option<(Vec<usize>, Vec<u32>, Vec<f64>)> {
    let count = AtomicUsize::new(0);
    let bnd: Bounds<D, Quad<D>> = bounds(to, level, pot);
    let m = from.len();
    let chunks: Vec<(Vec<u32>, Vec<u32>, Vec<f64>)> = (0..m.div_ceil(CHUNK))
        .into_par_iter()
        .map(|ci| {
            let (a, b) = (ci * CHUNK, ((ci + 1) * CHUNK).min(m));
            let mut stack = Vec::new();
            let mut lens = Vec::with_capacity(b - a);
            let mut idx = Vec::new();
            let mut mins = Vec::with_capacity(b - a);
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
                    &bnd,
                    &|j| pot[j],
                    x,
                    0.0,
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
