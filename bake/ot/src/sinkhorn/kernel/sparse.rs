//! Sparse lists in fixed chunks: mapping them in place, merging sorted lists (into a kernel's own
//! arrays, in place), and the block-parallel transpose of a pattern.
//!
//! Memory is the point of most of this: a kernel holds ~70 pairs per point, so every transient copy
//! of a pair array costs as much as the rest of the solve. Lists are therefore counted first and
//! written into their final arrays (disjoint slices, one per chunk), never gathered per chunk and
//! copied, and a pattern that gains a few entries grows in place.

use super::CHUNK;
use rayon::prelude::*;

/// Row pointers from list lengths.
pub(super) fn pointers(lens: impl ExactSizeIterator<Item = usize>) -> Vec<usize> {
    let mut ptr = Vec::with_capacity(lens.len() + 1);
    ptr.push(0);
    for l in lens {
        ptr.push(ptr.last().unwrap() + l);
    }
    ptr
}

/// Keeps the entries j of list i of (`ptr`, `idx`) for which `keep(i, j)`, in place: every fixed
/// chunk of lists is filtered within its own range in parallel, then the chunks are moved together
/// and the array shrunk to what is left.
pub(super) fn filter_lists(
    ptr: &mut Vec<usize>,
    idx: &mut Vec<u32>,
    keep: impl Fn(usize, u32) -> bool + Sync,
) {
    let m = ptr.len() - 1;
    let mut parts = Vec::with_capacity(m.div_ceil(CHUNK));
    let mut rest = &mut idx[..];
    for c in 0..m.div_ceil(CHUNK) {
        let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(m));
        let (part, r) = std::mem::take(&mut rest).split_at_mut(ptr[b] - ptr[a]);
        rest = r;
        parts.push((a, b, part));
    }
    let old = &*ptr;
    // Per chunk, its lists' new lengths.
    let kept: Vec<Vec<usize>> = parts
        .into_par_iter()
        .map(|(a, b, part)| {
            let base = old[a];
            let mut w = 0;
            (a..b)
                .map(|i| {
                    let start = w;
                    for r in old[i] - base..old[i + 1] - base {
                        let j = part[r];
                        if keep(i, j) {
                            part[w] = j;
                            w += 1;
                        }
                    }
                    w - start
                })
                .collect()
        })
        .collect();
    let mut w = 0;
    for (c, lens) in kept.iter().enumerate() {
        let a = old[c * CHUNK];
        let n: usize = lens.iter().sum();
        idx.copy_within(a..a + n, w);
        w += n;
    }
    idx.truncate(w);
    idx.shrink_to_fit();
    let lens: Vec<usize> = kept.into_iter().flatten().collect();
    *ptr = pointers(lens.into_iter());
}

/// [`merge_lists_in_place`] of `pairs` (list, entry), sorted, into the lists of (`ptr`, `idx`).
pub(super) fn merge_pairs_in_place(
    ptr: &mut Vec<usize>,
    idx: &mut Vec<u32>,
    vals: Option<&mut Vec<f32>>,
    pairs: &[(u32, u32)],
) {
    if pairs.is_empty() {
        return;
    }
    let m = ptr.len() - 1;
    let mut starts = vec![0usize; m + 1];
    for &(i, _) in pairs {
        starts[i as usize + 1] += 1;
    }
    for i in 0..m {
        starts[i + 1] += starts[i];
    }
    merge_lists_in_place(ptr, idx, vals, |i| {
        pairs[starts[i]..starts[i + 1]].iter().map(|e| e.1)
    });
}

/// `f(i, values of list i)` for every list of (`ptr`, `vals`), in place, in parallel over fixed
/// chunks of lists; returns what `f` returned per list, in order (nothing is allocated for `()`).
pub(in crate::sinkhorn) fn map_lists_mut<R, F>(ptr: &[usize], vals: &mut [f32], f: F) -> Vec<R>
where
    R: Send,
    F: Fn(usize, &mut [f32]) -> R + Sync,
{
    let m = ptr.len() - 1;
    let mut parts = Vec::with_capacity(m.div_ceil(CHUNK));
    let mut rest = vals;
    for c in 0..m.div_ceil(CHUNK) {
        let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(m));
        let (p, r) = std::mem::take(&mut rest).split_at_mut(ptr[b] - ptr[a]);
        rest = r;
        parts.push((a, b, p));
    }
    let out: Vec<Vec<R>> = parts
        .into_par_iter()
        .map(|(a, b, p)| {
            let base = ptr[a];
            (a..b)
                .map(|i| f(i, &mut p[ptr[i] - base..ptr[i + 1] - base]))
                .collect()
        })
        .collect();
    out.into_iter().flatten().collect()
}

/// Sorts every list of (`ptr`, `idx`, `vals`) by ascending value (then entry), in place, in
/// parallel over fixed chunks of lists.
pub(in crate::sinkhorn) fn sort_lists_by_value(ptr: &[usize], idx: &mut [u32], vals: &mut [f32]) {
    let m = ptr.len() - 1;
    let mut parts = Vec::with_capacity(m.div_ceil(CHUNK));
    let (mut rest_i, mut rest_v) = (idx, vals);
    for c in 0..m.div_ceil(CHUNK) {
        let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(m));
        let len = ptr[b] - ptr[a];
        let (pi, ri) = std::mem::take(&mut rest_i).split_at_mut(len);
        let (pv, rv) = std::mem::take(&mut rest_v).split_at_mut(len);
        rest_i = ri;
        rest_v = rv;
        parts.push((a, b, pi, pv));
    }
    parts.into_par_iter().for_each(|(a, b, pi, pv)| {
        let base = ptr[a];
        // (value, entry) packed in one integer whose order is theirs: integer keys sort several
        // times faster than a comparison of the pair (this sort is one pass over every pair).
        let mut keys: Vec<u64> = Vec::new();
        for i in a..b {
            let r = ptr[i] - base..ptr[i + 1] - base;
            keys.clear();
            keys.extend(
                pv[r.clone()]
                    .iter()
                    .zip(&pi[r.clone()])
                    .map(|(&v, &j)| (u64::from(ordered_bits(v)) << 32) | u64::from(j)),
            );
            keys.sort_unstable();
            for ((v, j), &k) in pv[r.clone()].iter_mut().zip(&mut pi[r]).zip(&keys) {
                *v = from_ordered_bits((k >> 32) as u32);
                *j = k as u32;
            }
        }
    });
}

/// The bits of `x` as an unsigned integer whose order is `f32::total_cmp`'s.
#[inline]
fn ordered_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// The inverse of [`ordered_bits`].
#[inline]
fn from_ordered_bits(k: u32) -> f32 {
    f32::from_bits(if k >> 31 == 1 { k & 0x7fff_ffff } else { !k })
}

/// The sorted union of two sorted, duplicate-free lists.
pub(super) fn union<'a>(
    a: &'a [u32],
    b: impl Iterator<Item = u32> + 'a,
) -> impl Iterator<Item = u32> + 'a {
    let mut a = a.iter().copied().peekable();
    let mut b = b.peekable();
    std::iter::from_fn(move || match (a.peek().copied(), b.peek().copied()) {
        (Some(x), Some(y)) => {
            if x <= y {
                a.next();
            }
            if y <= x {
                b.next();
            }
            Some(x.min(y))
        }
        (Some(_), None) => a.next(),
        (None, Some(_)) => b.next(),
        (None, None) => None,
    })
}

/// The value [`merge_lists_in_place`] gives the entries it adds.
pub(super) const NEW_VALUE: f32 = f32::NAN;

/// Parts a merge runs in, in parallel (see [`merge_lists_in_place`]). Each part but the first
/// copies aside its old entries that the part before it overwrites (for two parts about half of
/// what the merge adds), so more parts cost more memory for a pass that waits on memory anyway.
const MERGE_PARTS: usize = 2;

/// Merges into every list of (`ptr`, `idx`) the sorted entries `new(i)`, in place: list i becomes
/// the sorted union of its entries and `new(i)`. With `vals` (one value per entry), every old entry
/// keeps its value and every new one gets [`NEW_VALUE`]. The lists' new lengths are counted first
/// (in parallel); the array then grows once, by exactly what the lists gain (a large allocation
/// grows by remapping its pages, without a copy), and the lists are merged from the last to the
/// first, each from its end, so that no entry is overwritten before it is read: a list only moves
/// towards the end, and a list ends, after the merge, no earlier than it did before. One pass over
/// the entries from the first list that gains any, runs of lists that gain nothing moved as one
/// block, in [`MERGE_PARTS`] runs of lists at once: each part writes only where its own lists
/// end up, and reads its old entries there or, below that, from a copy taken first (the part
/// before it writes over them). The result is the unions whatever the parts.
pub(super) fn merge_lists_in_place<'a, I>(
    ptr: &mut Vec<usize>,
    idx: &mut Vec<u32>,
    vals: Option<&mut Vec<f32>>,
    new: impl Fn(usize) -> I + Sync,
) where
    I: DoubleEndedIterator<Item = u32> + 'a,
{
    merge_lists_in_parts(ptr, idx, vals, new, MERGE_PARTS);
}

/// [`merge_lists_in_place`] in up to `parts` parts.
pub(super) fn merge_lists_in_parts<'a, I>(
    ptr: &mut Vec<usize>,
    idx: &mut Vec<u32>,
    mut vals: Option<&mut Vec<f32>>,
    new: impl Fn(usize) -> I + Sync,
    parts: usize,
) where
    I: DoubleEndedIterator<Item = u32> + 'a,
{
    // A list with nothing to add keeps its length without reading it (most lists, in a local
    // rebuild).
    let lens: Vec<usize> = (0..ptr.len() - 1)
        .into_par_iter()
        .map(|i| match new(i).next() {
            None => ptr[i + 1] - ptr[i],
            Some(_) => union(&idx[ptr[i]..ptr[i + 1]], new(i)).count(),
        })
        .collect();
    let m = lens.len();
    let new_ptr = pointers(lens.into_iter());
    let total = new_ptr[m];
    debug_assert!(total >= idx.len());
    idx.reserve_exact(total - idx.len());
    idx.resize(total, 0);
    if let Some(v) = vals.as_deref_mut() {
        v.reserve_exact(total - v.len());
        v.resize(total, NEW_VALUE);
    }
    let first = (0..m).find(|&i| new_ptr[i + 1] != ptr[i + 1]).unwrap_or(m);
    // Parts: runs of lists splitting what is written (from the first list that gains) about
    // evenly.
    let from = new_ptr[first];
    let mut cuts = vec![first];
    for p in 1..parts.max(1) {
        let at = new_ptr.partition_point(|&q| q < from + (total - from) * p / parts);
        if at > *cuts.last().unwrap() && at < m {
            cuts.push(at);
        }
    }
    cuts.push(m);
    let old = &*ptr;
    // Each part's old entries below where its lists start, copied aside before any part writes
    // (the parts before it write there), then its destination, a disjoint slice.
    let heads: Vec<(usize, Vec<u32>, Vec<f32>)> = cuts
        .windows(2)
        .map(|w| {
            let (a, b) = (old[w[0]], old[w[1]].min(new_ptr[w[0]]));
            let v = vals.as_deref().map_or(Vec::new(), |v| v[a..b].to_vec());
            (a, idx[a..b].to_vec(), v)
        })
        .collect();
    let mut work = Vec::with_capacity(heads.len());
    let (mut rest_i, mut rest_v) = (&mut idx[from..], vals.map(|v| &mut v[from..]));
    for (w, (head_at, head_idx, head_vals)) in cuts.windows(2).zip(heads) {
        let len = new_ptr[w[1]] - new_ptr[w[0]];
        let (di, ri) = std::mem::take(&mut rest_i).split_at_mut(len);
        rest_i = ri;
        let dv = rest_v.take().map(|v| {
            let (d, r) = v.split_at_mut(len);
            rest_v = Some(r);
            d
        });
        work.push(Part {
            lists: (w[0], w[1]),
            base: new_ptr[w[0]],
            idx: di,
            vals: dv,
            head_at,
            head_idx,
            head_vals,
        });
    }
    work.into_par_iter()
        .for_each(|mut part| part.merge(old, &new_ptr, &new));
    *ptr = new_ptr;
}

/// One part of [`merge_lists_in_parts`]: its lists, where their new entries go, and its old
/// entries that lie below that (`head_*`, from `head_at` on).
struct Part<'s> {
    lists: (usize, usize),
    base: usize,
    idx: &'s mut [u32],
    vals: Option<&'s mut [f32]>,
    head_at: usize,
    head_idx: Vec<u32>,
    head_vals: Vec<f32>,
}

impl Part<'_> {
    /// The old entry at `k`.
    fn old(&self, k: usize) -> u32 {
        if k < self.base {
            self.head_idx[k - self.head_at]
        } else {
            self.idx[k - self.base]
        }
    }

    fn old_val(&self, k: usize) -> f32 {
        match &self.vals {
            Some(_) if k < self.base => self.head_vals[k - self.head_at],
            Some(v) => v[k - self.base],
            None => NEW_VALUE,
        }
    }

    /// Moves the old entries `a..b` to start at `to` (≥ `a`, ≥ `base`): what lies in the slice
    /// first (the higher addresses), then what lies in the head.
    fn move_run(&mut self, (a, b): (usize, usize), to: usize) {
        let mid = a.max(self.base).min(b);
        // A run wholly below `base` (in the head) has no part in the slice.
        if mid < b {
            let (s, d) = (mid - self.base..b - self.base, to + (mid - a) - self.base);
            self.idx.copy_within(s.clone(), d);
            if let Some(v) = self.vals.as_deref_mut() {
                v.copy_within(s, d);
            }
        }
        if a < mid {
            let (h, d) = (a - self.head_at..mid - self.head_at, to - self.base);
            self.idx[d..d + h.len()].copy_from_slice(&self.head_idx[h.clone()]);
            if let Some(v) = self.vals.as_deref_mut() {
                v[d..d + h.len()].copy_from_slice(&self.head_vals[h]);
            }
        }
    }

    fn merge<'a, I>(&mut self, ptr: &[usize], new_ptr: &[usize], new: &(impl Fn(usize) -> I + Sync))
    where
        I: DoubleEndedIterator<Item = u32> + 'a,
    {
        let (first, mut end) = self.lists;
        // A list whose length is unchanged is unchanged (the union holds the old entries), and a
        // run of such lists moves by one offset: one copy for the run. Most lists gain nothing in
        // a local rebuild, and moving them entry by entry was most of the merge.
        let same = |i: usize| new_ptr[i + 1] - new_ptr[i] == ptr[i + 1] - ptr[i];
        while end > first {
            let i = end - 1;
            if same(i) {
                let mut a = i;
                while a > first && same(a - 1) {
                    a -= 1;
                }
                self.move_run((ptr[a], ptr[end]), new_ptr[a]);
                end = a;
                continue;
            }
            end = i;
            let (lo, mut r) = (ptr[i], ptr[i + 1]);
            let mut w = new_ptr[i + 1];
            let mut add = new(i).rev().peekable();
            loop {
                let old = (r > lo).then(|| self.old(r - 1));
                // The entry, and where its value comes from (an old entry's own, or none).
                let (e, from) = match (old, add.peek().copied()) {
                    (Some(a), Some(b)) => {
                        let from = (a >= b).then_some(r - 1);
                        if a >= b {
                            r -= 1;
                        }
                        if b >= a {
                            add.next();
                        }
                        (a.max(b), from)
                    }
                    (Some(a), None) => {
                        r -= 1;
                        (a, Some(r))
                    }
                    (None, Some(b)) => {
                        add.next();
                        (b, None)
                    }
                    (None, None) => break,
                };
                w -= 1;
                let value = from.map_or(NEW_VALUE, |k| self.old_val(k));
                self.idx[w - self.base] = e;
                if let Some(v) = self.vals.as_deref_mut() {
                    v[w - self.base] = value;
                }
            }
            debug_assert_eq!(w, new_ptr[i], "list {i}: lens[{i}] is not its union's size");
        }
    }
}

/// Column blocks of a transpose, filled in parallel: each block owns a contiguous range of the
/// output, so the blocks write disjoint slices, and every entry lands where the sequential fill
/// would put it (the result does not depend on the thread count).
const TRANSPOSE_BLOCKS: usize = 16;

/// Transposes a CSR pattern (rows ascending inside each column): returns (ptr, idx).
///
/// The rows' lists are sorted, and rows and columns are both in Morton order, so a row's columns
/// mostly fall in one block: a block skips a row by its first and last column, and cuts the rest by
/// binary search.
pub(super) fn transpose(ptr: &[usize], idx: &[u32], cols: usize) -> (Vec<usize>, Vec<u32>) {
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
    // Disjoint output slices, one per block.
    let mut parts = Vec::with_capacity(bounds.len() - 1);
    let mut rest_idx = &mut tidx[..];
    for w in bounds.windows(2) {
        let len = tptr[w[1]] - tptr[w[0]];
        let (a, r) = std::mem::take(&mut rest_idx).split_at_mut(len);
        rest_idx = r;
        parts.push((w[0], w[1], a));
    }
    parts.into_par_iter().for_each(|(c0, c1, out_idx)| {
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
                    for &j in &row[a..b] {
                        let slot = &mut fill[(j - lo) as usize];
                        out_idx[*slot] = i as u32;
                        *slot += 1;
                    }
                }
                _ => {}
            }
        }
    });
    (tptr, tidx)
}
