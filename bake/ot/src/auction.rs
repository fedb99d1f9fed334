//! Sparse ε-scaling auction (Bertsekas 1988, "The auction algorithm: a distributed relaxation
//! method for the assignment problem"; Gauss–Seidel form) on a candidate graph given in CSR form.
//!
//! Used to turn an entropic plan into a one-to-one matching: the candidates are the pairs the
//! Sinkhorn kernel kept, the starting column duals are the Sinkhorn target potentials (already
//! ε-optimal for the entropic scale), and ε shrinks geometrically so the final matching is within
//! n·ε_end of the best one the graph allows. Minimization form: row i prefers the column with the
//! smallest reduced cost C_ij − v_j and a bid lowers that column's dual by the margin over the row's
//! second-best column plus ε.
//!
//! A sparse graph may admit no perfect matching; then duals fall without bound. Every phase parks
//! its free rows for the caller's completion once its bids stall (no free column taken for a
//! while) or its budget runs out; what the completion cannot place is reported, never looped on.

mod wider;

use rayon::prelude::*;
use std::collections::VecDeque;
use wider::Wider;

/// Rows per parallel work item of the ε-complementary-slackness check.
const CHECK_CHUNK: usize = 4096;

/// Queued rows whose candidates a bid fetches ahead (see [`auction`]).
const AHEAD: usize = 2;

/// Candidates per cache line (4-byte columns and costs).
const LINE: usize = 16;

/// "Unassigned".
const NONE: u32 = u32::MAX;

/// Bids per row one phase may spend in all before its free rows are parked (see [`auction`]).
pub(crate) const BIDS_PER_ROW: u64 = 50;

/// Bids in a row that take no free column, at least, before a phase parks its free rows for
/// [`Outside::complete`] ...
const STALL_BIDS: u64 = 4096;

/// ... and at least this many per row. The auction's endgame is long (the last free rows' bids
/// travel far in steps of ε: the 250K duck's last rows took 200K–800K bids each, without a free
/// column taken, and ended), but a price war on a support without a perfect matching never ends
/// and only ruins the prices around it: its rows are parked after this many bids instead of the
/// whole budget ([`BIDS_PER_ROW`] per row). At the start of a phase, with many rows free, a free
/// column is taken every few bids.
const STALL_PER_ROW: u64 = 8;

/// The candidate graph and its costs.
pub(crate) struct Graph<'a, C: Fn(usize, usize) -> f64 + Sync> {
    pub row_ptr: &'a [usize],
    pub col: &'a [u32],
    pub cols: usize,
    /// The cost of any (row, column) pair.
    pub cost: C,
    /// The candidates' costs in `col`'s order, if the caller has them (they must equal `cost` up to
    /// a constant per row, and to far less than the final ε): bids then read them sequentially
    /// instead of computing each from two positions, one of them a random read. Nearly all of an
    /// auction's time is these reads (1M 3D points: 15.6M bids over about 68 candidates each).
    pub pair_cost: Option<&'a [f32]>,
    /// Each row's `pair_cost` is ascending: a row's scan stops at the first candidate whose cost
    /// less the highest dual cannot beat the second best so far (the same result, read early).
    pub sorted: bool,
    /// How far the graph is known to hold each row's best columns: every column left out of a
    /// row costs more than this (∞ for a complete graph). Duals start at most 0 and only fall, so a
    /// left-out column's reduced cost stays above it; a row whose best candidate is above it may
    /// have a better column outside the graph, and bidding on would only start a price war (the
    /// rows around a hole in a truncated kernel's support): its candidates are widened at once
    /// ([`Outside::widen`]), before the prices around it are ruined.
    pub certified: f64,
}

/// What the auction asks of the world outside its graph.
pub(crate) trait Outside {
    /// Row `row`'s candidates beyond the graph (whose own are `own`), for its `round`-th widening
    /// (0 first), at prices `v`, and the reduced cost up to which they are complete (every column
    /// left out costs more, at these prices and any lower ones). `None`: no wider list (past the
    /// last widening); the row is parked.
    fn widen(&mut self, row: usize, round: u32, v: &[f64], own: &[u32]) -> Option<Widened>;
    /// Columns the widened rows' lists may hold at once (the memory they may take): a row whose
    /// new list would pass it is parked. Lists a row has replaced do not count (see [`Wider`]).
    fn wide_limit(&self) -> usize;
    /// Assigns what it can of the parked `free` rows at the end of a phase (updating the
    /// assignment `x`, `y` and the prices `v`, which may only fall).
    fn complete(&mut self, free: &[usize], x: &mut [u32], y: &mut [u32], v: &mut [f64]);
}

/// What [`Outside::widen`] found.
pub(crate) enum Widened {
    /// Nothing the graph's own candidates lack: they are certified up to this reduced cost.
    Own(f64),
    /// These columns (ascending), complete up to this reduced cost.
    List(Vec<u32>, f64),
}

/// Result of [`auction`].
#[derive(Clone, Debug)]
pub(crate) struct Matching {
    /// Row → column, `u32::MAX` for rows left unassigned when a phase ran out of budget.
    pub x: Vec<u32>,
    pub unassigned: usize,
    pub phases: u32,
    pub bids: u64,
    /// Rows given a list beyond the graph (each widening counted), the columns those lists held,
    /// and the most columns held at once (what the lists' limit bounds).
    pub widened: u64,
    pub wide_cols: usize,
    pub wide_held: usize,
    pub parked: Parked,
}

/// Why rows were parked for [`Outside::complete`] (for the trace).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Parked {
    /// Free when a phase stalled or spent its budget.
    pub stalled: u64,
    /// Whose list would have passed [`Outside::wide_limit`].
    pub refused: u64,
    /// That [`Outside::widen`] could not widen further.
    pub unwidened: u64,
}

/// Runs the ε-scaling auction from duals `v` with bid increments from `eps_start` down to `eps_end`
/// (divided by `divisor` per phase). `gap` is the second-best margin used for rows with a single
/// candidate (a large cost, e.g. the squared extent).
///
/// A row whose best candidate costs more than `graph.certified` (its best may lie outside the
/// graph) has its candidates widened by `outside.widen` and bids again, as often as it runs past
/// what its list certifies; a row that cannot be widened is parked. A phase whose bids take no
/// free column for [`STALL_PER_ROW`] × rows bids in a row, or that spends [`BIDS_PER_ROW`] × rows
/// in all, is in a price war the graph cannot end or would end only slowly; its free rows are
/// parked too. At the end of the phase `outside.complete` assigns the parked
/// rows by other means (augmenting paths). The next phase then goes on from that assignment.
pub(crate) fn auction<C, O>(
    graph: &Graph<'_, C>,
    v: &mut [f64],
    eps_start: f64,
    eps_end: f64,
    divisor: f64,
    gap: f64,
    outside: &mut O,
) -> Matching
where
    C: Fn(usize, usize) -> f64 + Sync,
    O: Outside,
{
    let mut wider = Wider::default();
    let rows = graph.row_ptr.len() - 1;
    let mut x = vec![NONE; rows];
    let mut y = vec![NONE; graph.cols];
    let mut eps = eps_start.max(eps_end);
    let mut phases = 0u32;
    let limit = outside.wide_limit();
    let (mut stalled, mut unwidened) = (0u64, 0u64);
    let mut bids = 0u64;
    // The highest dual: bids only lower duals, so it is recomputed only after `complete`.
    let highest = |v: &[f64]| v.par_iter().copied().reduce(|| f64::NEG_INFINITY, f64::max);
    let mut v_hi = highest(v);
    // Per row, an upper bound of its candidates' duals (∞: none yet), what lets its sorted scan
    // stop early where the bound over all duals cannot: see [`best_two`].
    let mut row_hi = vec![f64::INFINITY; rows];
    loop {
        phases += 1;
        // Free every row that violates ε-complementary slackness (all rows in the first phase).
        // The check reads only the duals and the assignment, so it runs in parallel over fixed
        // chunks; the queue comes out in row order for any thread count.
        // A ring of free rows, first in first out: a row is in it at most once (it is queued
        // when it is freed or widened, taken when it bids), so it holds at most `rows` entries,
        // where a growing list held one per eviction (8 bytes per bid: 4.7 GB at 590M bids).
        let mut queue: VecDeque<u32> = {
            let (xr, vr, wr) = (&x, &*v, &wider);
            (0..rows.div_ceil(CHECK_CHUNK))
                .into_par_iter()
                .flat_map_iter(|c| {
                    (c * CHECK_CHUNK..((c + 1) * CHECK_CHUNK).min(rows))
                        .filter(move |&i| {
                            if xr[i] == NONE {
                                return true;
                            }
                            let (u1, _, _, _) = best_two(graph, wr, vr, v_hi, i, None);
                            let mine = (graph.cost)(i, xr[i] as usize) - vr[xr[i] as usize];
                            mine > u1 + eps
                        })
                        .map(|i| i as u32)
                })
                .collect::<Vec<u32>>()
                .into()
        };
        for &i in &queue {
            let i = i as usize;
            if x[i] != NONE {
                y[x[i] as usize] = NONE;
                x[i] = NONE;
            }
        }
        let mut parked = Vec::new();
        let budget = BIDS_PER_ROW * rows as u64;
        let stall = STALL_BIDS.max(STALL_PER_ROW * rows as u64);
        let (mut spent, mut since) = (0u64, 0u64);
        while let Some(i) = queue.pop_front() {
            let i = i as usize;
            // The next rows' data, fetched ahead: a bid mostly waits on memory, and a row's
            // candidates are found through its pointer. Three rows ahead the pointer, two rows
            // ahead the first two cache lines of the candidates and of their costs (a bid reads
            // about 20), so the misses overlap this bid's and the next one's. (A demand read of
            // the next row's first candidate stalled the bid on its miss; one row ahead and one
            // line each left the duck's auction 9% slower, D163.)
            if let Some(&k) = queue.get(AHEAD) {
                prefetch(graph.row_ptr.as_ptr().wrapping_add(k as usize));
            }
            for &k in queue.range(..AHEAD.min(queue.len())) {
                let p = graph.row_ptr[k as usize];
                for line in [0, LINE] {
                    prefetch(graph.col.as_ptr().wrapping_add(p + line));
                    if let Some(c) = graph.pair_cost {
                        prefetch(c.as_ptr().wrapping_add(p + line));
                    }
                }
            }
            if spent >= budget || since >= stall {
                stalled += 1 + queue.len() as u64;
                parked.push(i);
                parked.extend(queue.drain(..).map(|i| i as usize));
                break;
            }
            spent += 1;
            since += 1;
            bids += 1;
            let (u1, j1, u2, _) = best_two(graph, &wider, v, v_hi, i, Some(&mut row_hi[i]));
            let (certified, round) = wider
                .get(i)
                .map_or((graph.certified, 0), |(_, c, r)| (c, r + 1));
            if j1 == usize::MAX || u1 > certified {
                // A row without candidates, or whose best may lie outside its list: widened and
                // queued again, or parked.
                let own = &graph.col[graph.row_ptr[i]..graph.row_ptr[i + 1]];
                match outside.widen(i, round, v, own) {
                    Some(found) => {
                        if wider.set(rows, i, found, round, limit) {
                            queue.push_back(i as u32);
                        } else {
                            parked.push(i);
                        }
                    }
                    None => {
                        unwidened += 1;
                        parked.push(i);
                    }
                }
                continue;
            }
            let second = if u2.is_finite() { u2 } else { u1 + gap };
            v[j1] -= second - u1 + eps;
            let prev = y[j1];
            y[j1] = i as u32;
            x[i] = j1 as u32;
            if prev != NONE {
                x[prev as usize] = NONE;
                queue.push_back(prev);
            } else {
                since = 0;
            }
        }
        if !parked.is_empty() {
            parked.sort_unstable();
            parked.dedup();
            parked.retain(|&i| x[i] == NONE);
            outside.complete(&parked, &mut x, &mut y, v);
            v_hi = highest(v);
        }
        if eps <= eps_end {
            break;
        }
        eps = (eps / divisor).max(eps_end);
    }
    let unassigned = x.iter().filter(|&&j| j == NONE).count();
    Matching {
        x,
        unassigned,
        phases,
        bids,
        widened: wider.lists,
        wide_cols: wider.listed,
        wide_held: wider.held,
        parked: Parked {
            stalled,
            refused: wider.refused,
            unwidened,
        },
    }
}

/// Asks the processor to bring the cache line holding `p` (the address is not dereferenced;
/// nothing where the architecture has no such hint).
#[inline(always)]
pub(crate) fn prefetch<T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of every x86-64 processor, and a prefetch never faults, whatever the
    // address: it reads nothing the program sees.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.cast::<i8>());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Smallest and second-smallest reduced cost of row i over its candidates (its widened list if it
/// has one): (u1, j1, u2, j2).
///
/// `v_hi` is at least every dual, and `row_hi` (when given) at least every dual of the row's own
/// candidates: what lets a sorted row stop early (every later candidate costs at least its pair
/// cost less the bound). Duals only fall, so a bound once computed stays one; a row whose scan
/// still read more than half of its candidates reads the rest too and sets its bound to their
/// largest dual now. In the auction's endgame the prices around the last free rows have fallen
/// far below the highest dual (free columns keep theirs), and with `v_hi` alone every bid there
/// read nearly its whole row.
fn best_two<C: Fn(usize, usize) -> f64 + Sync>(
    graph: &Graph<'_, C>,
    wider: &Wider,
    v: &[f64],
    v_hi: f64,
    i: usize,
    row_hi: Option<&mut f64>,
) -> (f64, usize, f64, usize) {
    if let Some((Some(cols), certified, _)) = wider.get(i) {
        let (u1, j1, u2, j2) = two_smallest(cols.iter().map(|&j| {
            let j = j as usize;
            (j, (graph.cost)(i, j) - v[j])
        }));
        // Every column left out of the list costs more than it certifies: the second best is at
        // most that (a list of one column must not bid its price down by the whole `gap`).
        return (u1, j1, u2.min(certified.max(u1)), j2);
    }
    let r = graph.row_ptr[i]..graph.row_ptr[i + 1];
    let cols = &graph.col[r.clone()];
    match graph.pair_cost {
        Some(pc) if graph.sorted => {
            let hi = row_hi.as_deref().map_or(v_hi, |&h| h.min(v_hi));
            let (mut u1, mut j1) = (f64::INFINITY, usize::MAX);
            let (mut u2, mut j2) = (f64::INFINITY, usize::MAX);
            let mut read = cols.len();
            for (k, (&j, &c)) in cols.iter().zip(&pc[r]).enumerate() {
                let c = f64::from(c);
                // Every later candidate costs at least c − hi.
                if c - hi >= u2 {
                    read = k;
                    break;
                }
                let (j, h) = (j as usize, c - v[j as usize]);
                if h < u1 {
                    u2 = u1;
                    j2 = j1;
                    u1 = h;
                    j1 = j;
                } else if h < u2 {
                    u2 = h;
                    j2 = j;
                }
            }
            if let Some(bound) = row_hi {
                if 2 * read > cols.len() {
                    *bound = cols
                        .iter()
                        .map(|&j| v[j as usize])
                        .fold(f64::NEG_INFINITY, f64::max);
                }
            }
            (u1, j1, u2, j2)
        }
        Some(pc) => two_smallest(
            cols.iter()
                .zip(&pc[r])
                .map(|(&j, &c)| (j as usize, f64::from(c) - v[j as usize])),
        ),
        None => two_smallest(cols.iter().map(|&j| {
            let j = j as usize;
            (j, (graph.cost)(i, j) - v[j])
        })),
    }
}

/// The two smallest values of (column, value) pairs, first wins ties: (u1, j1, u2, j2).
#[inline]
fn two_smallest(candidates: impl Iterator<Item = (usize, f64)>) -> (f64, usize, f64, usize) {
    let (mut u1, mut j1) = (f64::INFINITY, usize::MAX);
    let (mut u2, mut j2) = (f64::INFINITY, usize::MAX);
    for (j, h) in candidates {
        if h < u1 {
            u2 = u1;
            j2 = j1;
            u1 = h;
            j1 = j;
        } else if h < u2 {
            u2 = h;
            j2 = j;
        }
    }
    (u1, j1, u2, j2)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An [`Outside`] from two closures.
    struct Hooks<W, F> {
        widen: W,
        complete: F,
    }

    impl<W, F> Outside for Hooks<W, F>
    where
        W: FnMut(usize, u32, &[f64]) -> Option<Widened>,
        F: FnMut(&[usize], &mut [u32], &mut [u32], &mut [f64]),
    {
        fn widen(&mut self, row: usize, round: u32, v: &[f64], _: &[u32]) -> Option<Widened> {
            (self.widen)(row, round, v)
        }
        fn wide_limit(&self) -> usize {
            usize::MAX
        }
        fn complete(&mut self, free: &[usize], x: &mut [u32], y: &mut [u32], v: &mut [f64]) {
            (self.complete)(free, x, y, v)
        }
    }

    fn nothing_outside() -> impl Outside {
        Hooks {
            widen: |_: usize, _: u32, _: &[f64]| None,
            complete: |_: &[usize], _: &mut [u32], _: &mut [u32], _: &mut [f64]| {},
        }
    }

    /// On a complete graph the auction with a tiny final ε finds the optimal assignment (checked
    /// against all permutations of a small problem).
    #[test]
    fn dense_auction_is_optimal_on_small_problems() {
        let n = 6;
        let pts: Vec<(f64, f64)> = (0..2 * n)
            .map(|i| {
                let t = i as f64 * 0.618_033_988_75;
                (t.fract(), (t * 3.7).fract())
            })
            .collect();
        let cost = |i: usize, j: usize| {
            let (a, b) = (pts[i], pts[n + j]);
            (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)
        };
        let row_ptr: Vec<usize> = (0..=n).map(|i| i * n).collect();
        let col: Vec<u32> = (0..n * n).map(|e| (e % n) as u32).collect();
        let g = Graph {
            row_ptr: &row_ptr,
            col: &col,
            cols: n,
            cost,
            pair_cost: None,
            sorted: false,
            certified: f64::INFINITY,
        };
        let mut v = vec![0.0; n];
        let m = auction(&g, &mut v, 0.5, 1e-9, 4.0, 10.0, &mut nothing_outside());
        assert_eq!(m.unassigned, 0);
        let total: f64 = (0..n).map(|i| cost(i, m.x[i] as usize)).sum();
        // Brute force over all permutations.
        let mut perm: Vec<usize> = (0..n).collect();
        let mut best = f64::INFINITY;
        permute(&mut perm, 0, &mut |p| {
            best = best.min((0..n).map(|i| cost(i, p[i])).sum());
        });
        assert!((total - best).abs() < 1e-7, "{total} vs {best}");
    }

    fn permute(p: &mut Vec<usize>, k: usize, f: &mut dyn FnMut(&[usize])) {
        if k == p.len() {
            f(p);
            return;
        }
        for i in k..p.len() {
            p.swap(k, i);
            permute(p, k + 1, f);
            p.swap(k, i);
        }
    }

    /// A sorted row's early stop (against the highest dual and the row's own bound) reads less but
    /// bids exactly as a full scan: the same bids, matching and duals on a sparse geometric
    /// problem with a long endgame (the rows' 10 nearest columns, starting from zero duals).
    #[test]
    fn sorted_early_stop_bids_as_a_full_scan() {
        let n = 900;
        let at = |k: usize, s: f64| {
            let t = (k as f64 + s) * 0.754_877_666;
            (t.fract(), ((k as f64 + s) * 0.569_840_29).fract())
        };
        let cost = |i: usize, j: usize| {
            let (a, b) = (at(i, 0.3), at(j, 0.7));
            (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)
        };
        let (mut row_ptr, mut col, mut pc) = (vec![0usize], Vec::new(), Vec::new());
        for i in 0..n {
            let mut near: Vec<(f32, u32)> = (0..n).map(|j| (cost(i, j) as f32, j as u32)).collect();
            near.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.cmp(&q.1)));
            for &(c, j) in &near[..10] {
                pc.push(c);
                col.push(j);
            }
            row_ptr.push(col.len());
        }
        let run = |sorted: bool| {
            let g = Graph {
                row_ptr: &row_ptr,
                col: &col,
                cols: n,
                cost,
                pair_cost: Some(&pc),
                sorted,
                certified: f64::INFINITY,
            };
            let mut v = vec![0.0; n];
            let m = auction(&g, &mut v, 1e-4, 1e-4, 4.0, 1.0, &mut nothing_outside());
            (m.x, m.bids, m.unassigned, v)
        };
        let (fast, full) = (run(true), run(false));
        assert!(fast.1 > 5 * n as u64, "a long auction: {} bids", fast.1);
        assert_eq!(fast.1, full.1, "bids");
        assert_eq!(fast.2, full.2, "unassigned");
        assert_eq!(fast.0, full.0, "matching");
        assert!(fast
            .3
            .iter()
            .zip(&full.3)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    /// Two rows whose only candidate is column 0 of two.
    fn two_rows_on_one_column<C: Fn(usize, usize) -> f64 + Sync>(
        cost: C,
        certified: f64,
    ) -> Graph<'static, C> {
        Graph {
            row_ptr: &[0, 1, 2],
            col: &[0, 0],
            cols: 2,
            cost,
            pair_cost: None,
            sorted: false,
            certified,
        }
    }

    /// Two rows, one candidate column: the loser's best is priced past what the graph certifies
    /// within a few bids, and its candidates are widened at once instead of bidding the budget
    /// away; with the second column in its wider list it takes it, and nothing is left to complete.
    #[test]
    fn a_row_priced_past_the_certified_margin_is_widened_at_once() {
        let g = two_rows_on_one_column(|_, j| j as f64 * 0.25, 1.0);
        let mut v = vec![0.0; 2];
        let (mut widened, mut completed) = (Vec::new(), 0);
        let mut hooks = Hooks {
            widen: |i: usize, round: u32, _: &[f64]| {
                widened.push((i, round));
                Some(Widened::List(vec![0, 1], f64::INFINITY))
            },
            complete: |free: &[usize], _: &mut [u32], _: &mut [u32], _: &mut [f64]| {
                completed += free.len()
            },
        };
        let m = auction(&g, &mut v, 0.1, 0.1, 4.0, 0.5, &mut hooks);
        assert_eq!(widened.len(), 1, "{widened:?}");
        assert_eq!(widened[0].1, 0);
        assert_eq!(completed, 0);
        assert_eq!(m.unassigned, 0);
        assert_eq!(
            m.x[widened[0].0], 1,
            "the widened row took the column outside the graph"
        );
        // Each bid lowers the price by the gap (0.5) plus ε: past 1 after two bids.
        assert!(m.bids < 10, "{}", m.bids);
    }

    /// A war on a support without a perfect matching (3000 rows, two candidate columns) is parked
    /// once it has gone the stall without taking a free column, not after the whole bid budget.
    #[test]
    fn a_war_that_takes_no_free_column_is_parked_at_the_stall() {
        let rows = 3000;
        let row_ptr: Vec<usize> = (0..=rows).map(|i| 2 * i).collect();
        let col: Vec<u32> = (0..2 * rows).map(|e| (e % 2) as u32).collect();
        let g = Graph {
            row_ptr: &row_ptr,
            col: &col,
            cols: rows,
            cost: |_, j| j as f64 * 0.25,
            pair_cost: None,
            sorted: false,
            certified: f64::INFINITY,
        };
        let mut v = vec![0.0; rows];
        let mut parked = Vec::new();
        let mut hooks = Hooks {
            widen: |_: usize, _: u32, _: &[f64]| None,
            complete: |free: &[usize], _: &mut [u32], _: &mut [u32], _: &mut [f64]| {
                parked.extend_from_slice(free)
            },
        };
        let m = auction(&g, &mut v, 0.1, 0.1, 4.0, 1.0, &mut hooks);
        let stall = STALL_BIDS.max(STALL_PER_ROW * rows as u64);
        assert!(stall < BIDS_PER_ROW * rows as u64);
        // Two bids take the two columns; then every bid displaces a row.
        assert_eq!(m.bids, 2 + stall);
        assert_eq!(parked.len(), rows - 2);
        assert_eq!(m.unassigned, rows - 2);
    }

    /// A graph without a perfect matching ends with rows unassigned instead of looping.
    #[test]
    fn infeasible_graph_is_reported() {
        let g = two_rows_on_one_column(|_, _| 1.0, f64::INFINITY);
        let mut v = vec![0.0; 2];
        let mut asked = Vec::new();
        let mut hooks = Hooks {
            widen: |_: usize, _: u32, _: &[f64]| None,
            complete: |free: &[usize], _: &mut [u32], _: &mut [u32], _: &mut [f64]| {
                asked.extend_from_slice(free)
            },
        };
        let m = auction(&g, &mut v, 0.1, 1e-6, 4.0, 1.0, &mut hooks);
        assert_eq!(m.unassigned, 1);
        assert!(
            !asked.is_empty(),
            "the parked row is handed to the completion"
        );
    }
}
