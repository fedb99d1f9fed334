//! The column test of a whole build ([`super::build`]) by one walk down both hierarchies at once.
//!
//! The test keeps, for every column j, the rows i with r_ij = C_ij − f_i ≤ m_j + θε, m_j the
//! column's minimum min_i r_ij. Searched column by column, the threshold moves with m_j, so a walk
//! can be shared only by a few neighbouring columns (and pays their spread about a fitted plane,
//! D152). But m_j is at least g_j (f is the hard c-transform of g), and on a converging solve
//! within a fraction of ε of it: with both potentials the test is one fixed threshold on the
//! reduced cost C_ij − f_i − g_j, which a walk over pairs of cells (a source cell × a target cell)
//! prunes for every pair of their points at once. The walk keeps the pairs with
//! r_ij ≤ g_j + (θ + σ)ε, whose column minima are then exact, and filters them to r_ij ≤ m_j + θε:
//! exactly the column test for every column whose m_j is within σε of g_j. The few others (a
//! column no row's minimum is near) are searched alone, as before.
//!
//! The same walk finds the row minima f (D159). Given upper bounds u_i ≥ f_i (from the previous
//! stage's kernel: the value of a column near the row's best), it keeps the wider band
//! C_ij − u_i ≤ g_j + (θ + σ)ε, which holds every row's minimizers and every pair of the band
//! above; each task then reads its rows' minima off its band and narrows it to
//! C_ij − f_i ≤ g_j + (θ + σ)ε before the column minima. With u = f (the row minima searched
//! first, as a build without bounds does) the narrowing keeps everything.
//!
//! A cell pair is pruned with the affine minorants of both sides ([`Affine`]): with
//! |x|² − f ≥ α_P + β_P·x over the source cell P and |y|² − g ≥ α_J + β_J·y over the target cell J,
//! C − f − g ≥ α_P + α_J + Σ_k (β_Pk x_k + β_Jk y_k − 2 x_k y_k), bilinear per axis and so
//! smallest at a corner of the two boxes; on the torus, at a corner for one of the image shifts.
//! That bound is loose by the spread of the points over the boxes, first order in the cells' width
//! (a pair of 4-point cells was typically more than 15ε below its best pair), so the walk stops at
//! cells of up to [`LEAF`] points and filters their points with a bound that knows each point
//! exactly and loses only a cross term ([`Walk::evaluate`]): the 1M cow's final build evaluated
//! 380M pairs for 79M kept, against 1.2G evaluations splitting down to cells of 32.
//!
//! Order and determinism: the source is cut into fixed tasks (cells of at most [`TASK_ROWS`] rows,
//! in Morton order), each walked depth first with children in index order, so every row meets the
//! target cells in index order and its list comes out sorted; the lists are counted, filtered and
//! written per task, in order, whatever the thread count.

use super::super::hierarchy::{Hierarchy, Level};
use super::bounds::{bounds, Affine, Bounds};
use super::search::search;
use super::sparse::{filter_lists, merge_pairs_in_place, pointers};
use crate::cost;
use crate::Wrap;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// The headroom σ of the walk's threshold, as a fraction of the margin θε: a column whose minimum
/// is more than σε above g_j is searched alone. On the 1M cow's final build all but 263 of the
/// 10⁶ columns were within 1ε (D158); each unit of headroom widens the walk's band by 1/θ.
const HEADROOM: f64 = 0.125;

/// A cell with at most this many descendants on the search level is not split: the walk evaluates
/// its points against the other side's ([`Walk::evaluate`], whose bound per point beats splitting
/// down to small cells: the 1M cow's final build walked 2.5 s with 64, 4.0 s with 32, 5.0 s with
/// 16; 128 as 64, 256 slower; D158).
const LEAF: u32 = 64;

// Every cell the walk bounds has a fitted minorant ([`super::bounds::OPENED`]).
const _: () = assert!(LEAF >= super::bounds::OPENED);

/// Rows per task at most (a task is one source cell walked against the whole target; a cell just
/// above the points is one task whatever its size).
const TASK_ROWS: u32 = 1024;

/// One side of the walk: a hierarchy, its search level and its cells' minorants.
struct Side<'a, const D: usize> {
    h: &'a Hierarchy<D>,
    level: usize,
    bnd: Bounds<D, Affine<D>>,
}

impl<const D: usize> Side<'_, D> {
    /// The descendants of cell `c` of level `l` on the search level.
    fn desc(&self, l: usize, c: u32) -> (u32, u32) {
        if l == self.level {
            (c, c + 1)
        } else {
            self.bnd.desc[l][c as usize]
        }
    }

    /// Whether the walk evaluates the cell's points instead of splitting it.
    fn leaf(&self, l: usize, c: u32) -> bool {
        let (a, b) = self.desc(l, c);
        l + 1 >= self.level || b - a <= LEAF
    }
}

/// Why [`column_test`] gave no pattern.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Refused {
    /// The walk's band, the pairs with C_ij − upper_i − g_j ≤ (θ + σ)ε, holds more than 4 ×
    /// `max_pairs` (with loose row bounds, a build tries again from the exact row minima).
    Band,
    /// The pattern holds more than `max_pairs` pairs.
    Kept,
}

/// A whole build's pattern and row offsets.
pub(super) struct Pattern {
    /// The pattern as sorted rows (CSR).
    pub ptr: Vec<usize>,
    pub cols: Vec<u32>,
    /// The row minima f_i = min_j (C_ij − g_j), C_ij computed as `cost::sq(x_i, y_j)`.
    pub f: Vec<f64>,
}

/// The pattern of a whole build for target potential `g`: f the row minima of g, and for every
/// column j the rows i with C_ij − f_i ≤ min_i' (C_i'j − f_i') + `margin` (the same sets, bit for
/// bit, as a search down the source for every column), with every row's minimizers (which the
/// test keeps but for rounding). `upper` bounds the row minima from above (any column's
/// C_ij − g_j does; the exact minima are the tightest): the walk keeps the pairs with
/// C_ij − upper_i ≤ g_j + (θ + σ)ε, a band that holds every pair the test needs, reads the row
/// minima off it, and narrows it to them. Refused past `max_pairs` pairs (so that memory stays
/// bounded when the blur is far above the local spacing), or when the walk's band holds more than
/// 4 × `max_pairs`, whatever the thread count.
#[allow(clippy::too_many_arguments)]
pub(super) fn column_test<const D: usize>(
    src: &Hierarchy<D>,
    tgt: &Hierarchy<D>,
    level: usize,
    upper: &[f64],
    g: &[f64],
    margin: f64,
    wrap: Wrap,
    max_pairs: usize,
) -> Result<Pattern, Refused> {
    let (xs, ys) = (&src.levels[level], &tgt.levels[level]);
    let reach = margin * (1.0 + HEADROOM);
    let s = Side {
        h: src,
        level,
        bnd: bounds(src, level, upper),
    };
    let t = Side {
        h: tgt,
        level,
        bnd: bounds(tgt, level, g),
    };
    // Per column, the smallest r_ij found (the walk's threshold on r_ij is g_j + reach).
    let lowest: Vec<AtomicU64> = (0..ys.len())
        .map(|_| AtomicU64::new(f64::INFINITY.to_bits()))
        .collect();
    // The walk's band is a superset of the test's pairs: about a fifth more when `upper` is the
    // row minima (a band of (θ + σ)ε instead of θε), more where columns go alone or the bounds
    // are loose. Its memory (4 bytes a pair kept, 16 in a task's scratch) is bounded by refusing
    // past 4 × `max_pairs` of them, counted as they are found.
    let cap = max_pairs.saturating_mul(4);
    let norm = |p: &[f64; D]| p.iter().map(|v| v * v).sum::<f64>();
    let hs: Vec<f64> = xs
        .pos
        .par_iter()
        .zip(upper)
        .map(|(x, fi)| norm(x) - fi)
        .collect();
    let ht: Vec<f64> = ys
        .pos
        .par_iter()
        .zip(g)
        .map(|(y, gj)| norm(y) - gj)
        .collect();
    // Every term of the bound is at most this large; its rounding is far below 1e-13 of it.
    let scale = xs
        .pos
        .par_iter()
        .map(norm)
        .chain(ys.pos.par_iter().map(norm))
        .chain(upper.par_iter().map(|v| v.abs()))
        .chain(g.par_iter().map(|v| v.abs()))
        .reduce(|| 0.0, f64::max)
        // Points moved by an image shift (the torus) are within 2 of the origin per axis.
        .max(if wrap == Wrap::Periodic {
            4.0 * D as f64
        } else {
            0.0
        });
    let band = AtomicUsize::new(0);
    let walk = Walk {
        s: &s,
        t: &t,
        upper,
        g,
        lowest: &lowest,
        hs: &hs,
        ht: &ht,
        slack: 1e-12 * (1.0 + 4.0 * scale),
        reach,
        shifts: shifts(wrap),
        wrap,
        band: &band,
        cap,
    };
    let t0 = std::time::Instant::now();
    let tasks = tasks(&s);
    // The walk's lists, in task order (so in row order): every row's length, and all the columns
    // in one array. Tasks run a batch at a time and their lists are appended in order; one array
    // rather than a list per task, because thousands of freed task lists stayed in the allocator's
    // heap, resident, through the rest of the solve (a quarter more peak memory on the 1M cow).
    let mut lens: Vec<u32> = Vec::with_capacity(xs.len());
    let mut cols: Vec<u32> = Vec::new();
    let mut f: Vec<f64> = Vec::with_capacity(xs.len());
    let mut minimizers: Vec<(u32, u32)> = Vec::with_capacity(xs.len());
    for batch in tasks.chunks(BATCH) {
        let found: Vec<Found> = batch
            .par_iter()
            .map_init(Scratch::default, |scratch, &(l, c)| {
                walk.task(l, c, scratch)
            })
            .collect();
        // The count only grows and counts pairs of the band only: past the cap is past it
        // whatever the thread count, and a task that stopped early stopped past it.
        if band.load(Ordering::Relaxed) > cap {
            return Err(Refused::Band);
        }
        for task in found {
            lens.extend_from_slice(&task.lens);
            cols.extend_from_slice(&task.cols);
            f.extend_from_slice(&task.f);
            minimizers.extend_from_slice(&task.minimizers);
        }
    }
    debug_assert_eq!(lens.len(), xs.len(), "the tasks cover every row once");
    let t1 = std::time::Instant::now();
    // The walk's cell bounds are as large as the pairs (both sides' minorants): freed first.
    drop((t, hs, ht));
    // What a row keeps of column j: r_ij ≤ m_j + margin, for the columns whose every such pair the
    // walk found (−∞, none, for the others: they are searched alone).
    let keep: Vec<f64> = lowest
        .par_iter()
        .zip(g)
        .map(|(m, &gj)| {
            let m = f64::from_bits(m.load(Ordering::Relaxed));
            if m + margin <= gj + reach {
                m + margin
            } else {
                f64::NEG_INFINITY
            }
        })
        .collect();
    drop(lowest);
    let alone: Vec<u32> = (0..ys.len() as u32)
        .filter(|&j| keep[j as usize] == f64::NEG_INFINITY)
        .collect();
    // The source's minorants were made for `upper`: below |x|² − f too, since f ≤ upper.
    let extra = search_alone(&s, ys, &f, &alone, margin, wrap, max_pairs).ok_or(Refused::Kept)?;
    let t2 = std::time::Instant::now();
    drop(s);
    let mut ptr = pointers(lens.iter().map(|&l| l as usize));
    drop(lens);
    filter_lists(&mut ptr, &mut cols, |i, j| {
        let r = cost::sq(wrap, &ys.pos[j as usize], &xs.pos[i]) - f[i];
        r <= keep[j as usize]
    });
    if cols.len() + extra.len() > max_pairs {
        return Err(Refused::Kept);
    }
    // The columns searched alone and the rows' minimizers, one sorted list of pairs.
    let mut added = extra;
    added.extend_from_slice(&minimizers);
    drop(minimizers);
    added.par_sort_unstable();
    added.dedup();
    merge_pairs_in_place(&mut ptr, &mut cols, None, &added);
    if std::env::var_os("OTBAKE_TRACE").is_some() {
        let secs = |a: std::time::Instant, b: std::time::Instant| (b - a).as_secs_f64();
        eprintln!(
            "  column test: {} tasks, band {}, {} pairs, {} columns alone; walk {:.2}s, alone \
             {:.2}s, filter {:.2}s",
            tasks.len(),
            band.load(Ordering::Relaxed),
            cols.len(),
            alone.len(),
            secs(t0, t1),
            secs(t1, t2),
            t2.elapsed().as_secs_f64()
        );
    }
    Ok(Pattern { ptr, cols, f })
}

/// The walk's tasks: source cells with at most [`TASK_ROWS`] rows (or leaves), in Morton order,
/// their rows covering the search level once, in order.
fn tasks<const D: usize>(s: &Side<'_, D>) -> Vec<(usize, u32)> {
    let mut out = Vec::new();
    let mut stack = vec![(0usize, 0u32)];
    while let Some((l, c)) = stack.pop() {
        let (a, b) = s.desc(l, c);
        if s.leaf(l, c) || b - a <= TASK_ROWS {
            out.push((l, c));
            continue;
        }
        let lvl = &s.h.levels[l];
        let (ca, cb) = (lvl.child[c as usize], lvl.child[c as usize + 1]);
        stack.extend((ca..cb).rev().map(|k| (l + 1, k)));
    }
    out
}

/// Tasks walked between two appends of their lists ([`column_test`]): enough to keep both cores
/// busy, few enough that their lists are a small transient.
const BATCH: usize = 64;

/// One task's lists: every row's length, and the rows' columns one after the other; its rows'
/// minima and their minimizers (row, column).
struct Found {
    lens: Vec<u32>,
    cols: Vec<u32>,
    f: Vec<f64>,
    minimizers: Vec<(u32, u32)>,
}

/// The columns `which` searched one at a time down the source `s`: each one's rows within `margin`
/// of its minimum, as (row, column) pairs sorted by row, then column; `None` past `max_pairs`
/// pairs (whatever the thread count: the count only grows).
fn search_alone<const D: usize>(
    s: &Side<'_, D>,
    ys: &Level<D>,
    f: &[f64],
    which: &[u32],
    margin: f64,
    wrap: Wrap,
    max_pairs: usize,
) -> Option<Vec<(u32, u32)>> {
    let count = AtomicUsize::new(0);
    let mut pairs: Vec<(u32, u32)> = which
        .par_chunks(super::CHUNK)
        .flat_map_iter(|chunk| {
            let (mut stack, mut found) = (Vec::new(), Vec::new());
            let mut out = Vec::new();
            for &j in chunk {
                if count.load(Ordering::Relaxed) > max_pairs {
                    break;
                }
                found.clear();
                search(
                    s.h,
                    s.level,
                    &s.bnd,
                    &|i| f[i],
                    &ys.pos[j as usize],
                    margin,
                    wrap,
                    &mut stack,
                    &mut found,
                    None,
                    None,
                );
                count.fetch_add(found.len(), Ordering::Relaxed);
                out.extend(found.iter().map(|e| (e.0, j)));
            }
            out
        })
        .collect();
    if count.into_inner() > max_pairs {
        return None;
    }
    pairs.par_sort_unstable();
    Some(pairs)
}

/// A task's buffers, reused.
#[derive(Default)]
struct Scratch {
    /// (row − the task's first row, column) in walk order, and each pair's cost.
    pairs: Vec<(u32, u32)>,
    costs: Vec<f64>,
    /// [`Walk::evaluate`]'s per-point terms and the points it keeps.
    a: Vec<f64>,
    b: Vec<f64>,
    rows: Vec<u32>,
    cols: Vec<u32>,
    /// The kept columns' coordinates (axis by axis) and thresholds g_j + reach (cube only).
    ys: Vec<f64>,
    gs: Vec<f64>,
    /// One row's costs to them.
    cs: Vec<f64>,
}

/// What every task's walk shares.
struct Walk<'a, const D: usize> {
    s: &'a Side<'a, D>,
    t: &'a Side<'a, D>,
    /// Upper bounds of the row minima, and the target potential.
    upper: &'a [f64],
    g: &'a [f64],
    /// Per column, the smallest r_ij found (bits of an `f64`).
    lowest: &'a [AtomicU64],
    /// |x_i|² − upper_i and |y_j|² − g_j.
    hs: &'a [f64],
    ht: &'a [f64],
    /// Rounding slack of [`Walk::evaluate`]'s bound: a bound above the true value could drop a
    /// pair at the threshold.
    slack: f64,
    /// (θ + σ)ε: the threshold on the reduced cost C − f − g the cell pairs are pruned against.
    reach: f64,
    shifts: &'static [f64],
    wrap: Wrap,
    /// The band's pairs found so far over all tasks, and the most it may hold.
    band: &'a AtomicUsize,
    cap: usize,
}

/// Pairs a task finds between two updates of the shared count (few updates, and a task past the
/// cap stops within this many pairs).
const REPORT: usize = 1 << 16;

impl<const D: usize> Walk<'_, D> {
    /// The pairs of the rows of source cell (`l`, `c`) with r_ij ≤ g_j + reach, every row's columns
    /// ascending, and the rows' minima and minimizers; the columns' smallest r_ij updated. Walks
    /// the band of C_ij − upper_i first, then reads each row's minimum off it and keeps what is
    /// within the limit of C_ij − f_i. Stops early (with what it has) once the shared count of
    /// the band is past the cap.
    fn task(&self, l: usize, c: u32, scratch: &mut Scratch) -> Found {
        let (s, t) = (self.s, self.t);
        let (ra, rb) = s.desc(l, c);
        scratch.pairs.clear();
        scratch.costs.clear();
        let mut reported = 0usize;
        let mut stack = vec![(l as u8, c, 0u8, 0u32)];
        while let Some((lp, p, lj, j)) = stack.pop() {
            let (lp, lj) = (lp as usize, lj as usize);
            let (p_leaf, j_leaf) = (s.leaf(lp, p), t.leaf(lj, j));
            if p_leaf && j_leaf {
                self.evaluate((lp, p), (lj, j), ra, scratch);
                if scratch.pairs.len() - reported >= REPORT {
                    let now = scratch.pairs.len() - reported;
                    reported = scratch.pairs.len();
                    if self.band.fetch_add(now, Ordering::Relaxed) + now > self.cap {
                        break;
                    }
                }
                continue;
            }
            let count = |side: &Side<'_, D>, l: usize, c: u32| {
                let (a, b) = side.desc(l, c);
                b - a
            };
            // Split the larger cell (a leaf is never split); its children in reverse, so that the
            // first is walked first.
            if !p_leaf && (j_leaf || count(s, lp, p) >= count(t, lj, j)) {
                let lvl = &s.h.levels[lp];
                let (a, b) = (lvl.child[p as usize], lvl.child[p as usize + 1]);
                for k in (a..b).rev() {
                    if self.bound((lp + 1, k), (lj, j)) <= self.reach {
                        stack.push((lp as u8 + 1, k, lj as u8, j));
                    }
                }
            } else {
                let lvl = &t.h.levels[lj];
                let (a, b) = (lvl.child[j as usize], lvl.child[j as usize + 1]);
                for k in (a..b).rev() {
                    if self.bound((lp, p), (lj + 1, k)) <= self.reach {
                        stack.push((lp as u8, p, lj as u8 + 1, k));
                    }
                }
            }
        }
        self.band
            .fetch_add(scratch.pairs.len() - reported, Ordering::Relaxed);
        let m = (rb - ra) as usize;
        let Scratch { pairs, costs, .. } = scratch;
        // Each row's minimum over its band, which holds the row's minimizers (their C_ij − g_j is
        // at most upper_i).
        let mut f = vec![f64::INFINITY; m];
        for (&(i, j), &c) in pairs.iter().zip(costs.iter()) {
            let v = c - self.g[j as usize];
            let fi = &mut f[i as usize];
            if v < *fi {
                *fi = v;
            }
        }
        // The band narrowed to r_ij = C_ij − f_i ≤ g_j + reach, in place and in walk order; the
        // minimizers besides (sorted with the columns searched alone, in `column_test`).
        let mut minimizers = Vec::new();
        let mut w = 0;
        for q in 0..pairs.len() {
            let ((i, j), c) = (pairs[q], costs[q]);
            let (iu, gj) = (i as usize, self.g[j as usize]);
            if c - gj <= f[iu] {
                minimizers.push((ra + i, j));
            }
            let r = c - f[iu];
            if r <= gj + self.reach {
                lower(&self.lowest[j as usize], r);
                pairs[w] = (i, j);
                w += 1;
            }
        }
        pairs.truncate(w);
        // The pairs in walk order hold every row's columns ascending: a stable counting sort by
        // row keeps that order.
        let mut lens = vec![0u32; m];
        for &(i, _) in pairs.iter() {
            lens[i as usize] += 1;
        }
        let mut at: Vec<usize> = Vec::with_capacity(m);
        let mut sum = 0usize;
        for &len in &lens {
            at.push(sum);
            sum += len as usize;
        }
        let mut cols = vec![0u32; pairs.len()];
        for &(i, j) in pairs.iter() {
            let slot = &mut at[i as usize];
            cols[*slot] = j;
            *slot += 1;
        }
        Found {
            lens,
            cols,
            f,
            minimizers,
        }
    }

    /// Every pair of the points of source cell `p` and target cell `j` with
    /// C_ij − upper_i ≤ g_j + reach into `pairs` (rows relative to `base`), each row's columns
    /// ascending, with its cost into `costs`.
    ///
    /// Before the pairs, the cells' points are filtered by a bound that knows each of them
    /// exactly: with x_c, y_c the boxes' centres, u = x − x_c and v = y − y_c, f = upper,
    /// C − f − g = A_i + B_j + 2 x_c·y_c − 2 u_i·v_j, A_i = |x_i|² − f_i − 2 x_i·y_c and
    /// B_j = |y_j|² − g_j − 2 x_c·y_j, and −2 u_i·v_j ≥ −2 Σ_k |u_ik| w_k for the half-widths w of
    /// the target box (likewise per column). The cell bound of the walk loses the spread of the
    /// points over the boxes, first order in the cells' width; this one only the cross term. On
    /// the torus the same holds with the target points moved by the pair's image shift
    /// ([`Walk::shift`]); without one, every pair is evaluated.
    fn evaluate(&self, p: (usize, u32), j: (usize, u32), base: u32, scratch: &mut Scratch) {
        let (s, t) = (self.s, self.t);
        let (xs, ys) = (&s.h.levels[s.level], &t.h.levels[t.level]);
        let (rows, cols) = (s.desc(p.0, p.1), t.desc(j.0, j.1));
        let Scratch {
            pairs,
            costs,
            a: av,
            b: bv,
            rows: kr,
            cols: kc,
            ys: yk,
            gs: gk,
            cs: ck,
        } = scratch;
        kr.clear();
        kc.clear();
        let shift = (p.0 < s.level && j.0 < t.level)
            .then(|| self.shift(p, j))
            .flatten();
        if let Some(m) = shift {
            let (sl, tl) = (&s.h.levels[p.0], &t.h.levels[j.0]);
            let (pu, ju) = (p.1 as usize, j.1 as usize);
            let xc: [f64; D] = std::array::from_fn(|k| 0.5 * (sl.lo[pu][k] + sl.hi[pu][k]));
            // The target cell's centre moved by the image shift (the points likewise, below).
            let yc: [f64; D] = std::array::from_fn(|k| 0.5 * (tl.lo[ju][k] + tl.hi[ju][k]) + m[k]);
            let wx: [f64; D] = std::array::from_fn(|k| 0.5 * (sl.hi[pu][k] - sl.lo[pu][k]));
            let wy: [f64; D] = std::array::from_fn(|k| 0.5 * (tl.hi[ju][k] - tl.lo[ju][k]));
            let dot = |a: &[f64; D], b: &[f64; D]| (0..D).map(|k| a[k] * b[k]).sum::<f64>();
            let c0 = 2.0 * dot(&xc, &yc);
            av.clear();
            av.extend((rows.0..rows.1).map(|i| {
                let x = &xs.pos[i as usize];
                self.hs[i as usize] - 2.0 * dot(x, &yc)
            }));
            // B_j for the moved point y' = y + m: |y'|² − |y|² = m·(y + y').
            bv.clear();
            bv.extend((cols.0..cols.1).map(|jj| {
                let y = &ys.pos[jj as usize];
                let moved: [f64; D] = std::array::from_fn(|k| y[k] + m[k]);
                let grow: f64 = (0..D).map(|k| m[k] * (y[k] + moved[k])).sum();
                self.ht[jj as usize] + grow - 2.0 * dot(&xc, &moved)
            }));
            let min_a = av.iter().copied().fold(f64::INFINITY, f64::min);
            let min_b = bv.iter().copied().fold(f64::INFINITY, f64::min);
            let cross: f64 = (0..D).map(|k| wx[k] * wy[k]).sum();
            let top = self.reach + self.slack;
            if min_a + min_b + c0 - 2.0 * cross > top {
                return;
            }
            for (q, (&ai, i)) in av.iter().zip(rows.0..rows.1).enumerate() {
                let x = &xs.pos[i as usize];
                let spread: f64 = (0..D).map(|k| (x[k] - xc[k]).abs() * wy[k]).sum();
                if ai + min_b + c0 - 2.0 * spread <= top {
                    kr.push(q as u32);
                }
            }
            for (q, (&bj, jj)) in bv.iter().zip(cols.0..cols.1).enumerate() {
                let y = &ys.pos[jj as usize];
                let spread: f64 = (0..D).map(|k| wx[k] * (y[k] + m[k] - yc[k]).abs()).sum();
                if bj + min_a + c0 - 2.0 * spread <= top {
                    kc.push(q as u32);
                }
            }
        } else {
            kr.extend(0..rows.1 - rows.0);
            kc.extend(0..cols.1 - cols.0);
        }
        if self.wrap == Wrap::Clamp {
            // The kept columns' coordinates (axis by axis) and thresholds gathered once for all
            // rows; per row the costs in one pass (it vectorizes), then each pair written whether
            // kept or not, the end moved only past a kept one: about one pair in five is kept, in
            // no pattern a branch predictor could learn. The same costs, bit for bit, as
            // `cost::sq` (0 + d0² + d1² + …).
            let m = kc.len();
            yk.clear();
            yk.resize(D * m, 0.0);
            gk.clear();
            for (q, &qj) in kc.iter().enumerate() {
                let ju = (cols.0 + qj) as usize;
                for k in 0..D {
                    yk[k * m + q] = ys.pos[ju][k];
                }
                gk.push(self.g[ju] + self.reach);
            }
            ck.resize(m, 0.0);
            for &qi in kr.iter() {
                let i = rows.0 + qi;
                let (x, fi) = (&xs.pos[i as usize], self.upper[i as usize]);
                ck.iter_mut().for_each(|c| *c = 0.0);
                for k in 0..D {
                    let xk = x[k];
                    for (c, &y) in ck.iter_mut().zip(&yk[k * m..(k + 1) * m]) {
                        let d = xk - y;
                        *c += d * d;
                    }
                }
                let start = pairs.len();
                pairs.resize(start + m, (0, 0));
                costs.resize(start + m, 0.0);
                let (op, oc) = (&mut pairs[start..], &mut costs[start..]);
                let mut w = 0;
                for ((&c, &t), &qj) in ck.iter().zip(gk.iter()).zip(kc.iter()) {
                    op[w] = (i - base, cols.0 + qj);
                    oc[w] = c;
                    w += usize::from(c - fi <= t);
                }
                pairs.truncate(start + w);
                costs.truncate(start + w);
            }
            return;
        }
        for &qi in kr.iter() {
            let i = rows.0 + qi;
            let (x, fi) = (&xs.pos[i as usize], self.upper[i as usize]);
            for &qj in kc.iter() {
                let jj = cols.0 + qj;
                let ju = jj as usize;
                let c = cost::sq(self.wrap, &ys.pos[ju], x);
                if c - fi <= self.g[ju] + self.reach {
                    pairs.push((i - base, jj));
                    costs.push(c);
                }
            }
        }
    }

    /// The image shift m with C(x, y) = |x − y − m|² for every x in source cell `p` and y in target
    /// cell `j` (both above the search level): 0 on the cube; on the torus, per axis, the
    /// nearest image's shift round(x_k − y_k) when it is the same over the two boxes, else `None`
    /// (cells straddling half a period apart, which the walk's threshold has pruned long before
    /// at any useful ε).
    fn shift(&self, p: (usize, u32), j: (usize, u32)) -> Option<[f64; D]> {
        if self.wrap == Wrap::Clamp {
            return Some([0.0; D]);
        }
        let (sl, tl) = (&self.s.h.levels[p.0], &self.t.h.levels[j.0]);
        let (pu, ju) = (p.1 as usize, j.1 as usize);
        let mut m = [0.0; D];
        for (k, mk) in m.iter_mut().enumerate() {
            // `cost::delta` is d − floor(d + ½), d = x − y: one shift over d's whole interval.
            let lo = (sl.lo[pu][k] - tl.hi[ju][k] + 0.5).floor();
            let hi = (sl.hi[pu][k] - tl.lo[ju][k] + 0.5).floor();
            if lo != hi {
                return None;
            }
            *mk = lo;
        }
        Some(m)
    }

    /// A lower bound of C_ij − upper_i − g_j over the points of source cell `p` and target cell `j`
    /// (both above the search level).
    #[inline]
    fn bound(&self, p: (usize, u32), j: (usize, u32)) -> f64 {
        let (sl, tl) = (&self.s.h.levels[p.0], &self.t.h.levels[j.0]);
        let (pu, ju) = (p.1 as usize, j.1 as usize);
        pair_bound(
            &self.s.bnd.cells[p.0][pu],
            (&sl.lo[pu], &sl.hi[pu]),
            &self.t.bnd.cells[j.0][ju],
            (&tl.lo[ju], &tl.hi[ju]),
            self.shifts,
        )
    }
}

/// `slot` ← min(`slot`, `r`), for an `f64` stored as bits.
#[inline]
fn lower(slot: &AtomicU64, r: f64) {
    let mut cur = slot.load(Ordering::Relaxed);
    while r < f64::from_bits(cur) {
        match slot.compare_exchange_weak(cur, r.to_bits(), Ordering::Relaxed, Ordering::Relaxed) {
            Ok(_) => break,
            Err(now) => cur = now,
        }
    }
}

/// The per-axis image shifts besides 0 that can hold the nearest image (C on the torus is the
/// minimum over the shifts of x − y by −1, 0, +1 per axis; every point is in [0, 1)).
pub(super) fn shifts(wrap: Wrap) -> &'static [f64] {
    match wrap {
        Wrap::Clamp => &[],
        Wrap::Periodic => &[1.0, -1.0],
    }
}

/// A lower bound of C(x, y) − f(x) − g(y) over x in the box `pb` and y in the box `jb`, from the
/// minorants |x|² − f ≥ α_P + β_P·x (`p`) and |y|² − g ≥ α_J + β_J·y (`j`): α_P + α_J plus, per
/// axis, the smallest of β_P x + β_J y − 2xy (+ m² − 2mx + 2my for an image shift m on the torus,
/// from (x − y − m)² = x² + y² + m² − 2xy − 2mx + 2my) over the corners of the two intervals: the
/// term is bilinear in (x, y), so its minimum over a rectangle is at a corner.
#[inline]
pub(super) fn pair_bound<const D: usize>(
    p: &Affine<D>,
    pb: (&[f64; D], &[f64; D]),
    j: &Affine<D>,
    jb: (&[f64; D], &[f64; D]),
    shifts: &[f64],
) -> f64 {
    let mut s = p.alpha + j.alpha;
    let mut mag = p.alpha.abs() + j.alpha.abs();
    for k in 0..D {
        let (bp, bj) = (p.beta[k], j.beta[k]);
        let xs = [pb.0[k], pb.1[k]];
        let ys = [jb.0[k], jb.1[k]];
        let corner =
            |x: f64, y: f64, m: f64| bp * x + bj * y - 2.0 * x * y + m * (m - 2.0 * x + 2.0 * y);
        let mut best = f64::INFINITY;
        for &x in &xs {
            for &y in &ys {
                best = best.min(corner(x, y, 0.0));
                for &m in shifts {
                    best = best.min(corner(x, y, m));
                }
            }
        }
        let (ax, ay) = (xs[0].abs().max(xs[1].abs()), ys[0].abs().max(ys[1].abs()));
        s += best;
        mag += bp.abs() * ax + bj.abs() * ay + 2.0 * (ax + 1.0) * (ay + 1.0) + 1.0;
    }
    // Rounding slack, as in `Affine::bound`: a bound above the true value could prune a pair at the
    // threshold.
    s - mag * 1e-13
}
