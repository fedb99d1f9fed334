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
//! A sparse graph may admit no perfect matching; then duals fall without bound. Every phase has a
//! processing budget, and running out of it is reported (the caller falls back), never looped on.

use rayon::prelude::*;

/// Rows per parallel work item of the ε-complementary-slackness check.
const CHECK_CHUNK: usize = 4096;

/// "Unassigned".
const NONE: u32 = u32::MAX;

/// Bids per row one phase may spend in all before its free rows are parked (see [`auction`]).
pub(crate) const BIDS_PER_ROW: u64 = 50;

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
}

/// Result of [`auction`].
#[derive(Clone, Debug)]
pub(crate) struct Matching {
    /// Row → column, `u32::MAX` for rows left unassigned when a phase ran out of budget.
    pub x: Vec<u32>,
    pub unassigned: usize,
    pub phases: u32,
    pub bids: u64,
    /// Rows the `complete` callback assigned.
    pub completed: u32,
}

/// Runs the ε-scaling auction from duals `v` with bid increments from `eps_start` down to `eps_end`
/// (divided by `divisor` per phase). `gap` is the second-best margin used for rows with a single
/// candidate (a large cost, e.g. the squared extent).
///
/// A phase that spends [`BIDS_PER_ROW`] × rows bids is in a price war the graph cannot end (a set
/// of rows with too few candidate columns between them) or would end only slowly; its free rows are
/// parked, and at the end of the phase `complete` assigns them by other means (dense augmenting
/// paths) and returns how many it assigned. The next phase then goes on from that assignment.
pub(crate) fn auction<C, F>(
    graph: &Graph<'_, C>,
    v: &mut [f64],
    eps_start: f64,
    eps_end: f64,
    divisor: f64,
    gap: f64,
    mut complete: F,
) -> Matching
where
    C: Fn(usize, usize) -> f64 + Sync,
    F: FnMut(&[usize], &mut [u32], &mut [u32], &mut [f64]) -> u32,
{
    let rows = graph.row_ptr.len() - 1;
    let mut x = vec![NONE; rows];
    let mut y = vec![NONE; graph.cols];
    let mut eps = eps_start.max(eps_end);
    let mut phases = 0u32;
    let mut bids = 0u64;
    let mut completed = 0u32;
    // The highest dual: bids only lower duals, so it is recomputed only after `complete`.
    let highest = |v: &[f64]| v.par_iter().copied().reduce(|| f64::NEG_INFINITY, f64::max);
    let mut v_hi = highest(v);
    loop {
        phases += 1;
        // Free every row that violates ε-complementary slackness (all rows in the first phase).
        // The check reads only the duals and the assignment, so it runs in parallel over fixed
        // chunks; the queue comes out in row order for any thread count.
        let mut queue: Vec<usize> = {
            let (xr, vr) = (&x, &*v);
            (0..rows.div_ceil(CHECK_CHUNK))
                .into_par_iter()
                .flat_map_iter(|c| {
                    (c * CHECK_CHUNK..((c + 1) * CHECK_CHUNK).min(rows)).filter(move |&i| {
                        if xr[i] == NONE {
                            return true;
                        }
                        let (u1, _, _, _) = best_two(graph, vr, v_hi, i);
                        let mine = (graph.cost)(i, xr[i] as usize) - vr[xr[i] as usize];
                        mine > u1 + eps
                    })
                })
                .collect()
        };
        for &i in &queue {
            if x[i] != NONE {
                y[x[i] as usize] = NONE;
                x[i] = NONE;
            }
        }
        let mut parked = Vec::new();
        let mut head = 0usize;
        let budget = BIDS_PER_ROW * rows as u64;
        let mut spent = 0u64;
        while head < queue.len() {
            if spent >= budget {
                parked.extend_from_slice(&queue[head..]);
                break;
            }
            let i = queue[head];
            head += 1;
            spent += 1;
            bids += 1;
            let (u1, j1, u2, _) = best_two(graph, v, v_hi, i);
            if j1 == usize::MAX {
                parked.push(i); // a row without candidates
                continue;
            }
            let second = if u2.is_finite() { u2 } else { u1 + gap };
            v[j1] -= second - u1 + eps;
            let prev = y[j1];
            y[j1] = i as u32;
            x[i] = j1 as u32;
            if prev != NONE {
                x[prev as usize] = NONE;
                queue.push(prev as usize);
            }
        }
        if !parked.is_empty() {
            parked.sort_unstable();
            parked.dedup();
            parked.retain(|&i| x[i] == NONE);
            completed += complete(&parked, &mut x, &mut y, v);
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
        completed,
    }
}

/// Smallest and second-smallest reduced cost of row i over its candidates: (u1, j1, u2, j2).
/// `v_hi` is at least every dual (what lets a sorted row stop early).
fn best_two<C: Fn(usize, usize) -> f64 + Sync>(
    graph: &Graph<'_, C>,
    v: &[f64],
    v_hi: f64,
    i: usize,
) -> (f64, usize, f64, usize) {
    let r = graph.row_ptr[i]..graph.row_ptr[i + 1];
    let cols = &graph.col[r.clone()];
    match graph.pair_cost {
        Some(pc) if graph.sorted => {
            let (mut u1, mut j1) = (f64::INFINITY, usize::MAX);
            let (mut u2, mut j2) = (f64::INFINITY, usize::MAX);
            for (&j, &c) in cols.iter().zip(&pc[r]) {
                let c = f64::from(c);
                // Every later candidate costs at least c − v_hi.
                if c - v_hi >= u2 {
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
        };
        let mut v = vec![0.0; n];
        let m = auction(&g, &mut v, 0.5, 1e-9, 4.0, 10.0, |_, _, _, _| 0);
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

    /// A graph without a perfect matching ends with rows unassigned instead of looping.
    #[test]
    fn infeasible_graph_is_reported() {
        // Two rows both limited to column 0.
        let row_ptr = [0usize, 1, 2];
        let col = [0u32, 0];
        let g = Graph {
            row_ptr: &row_ptr,
            col: &col,
            cols: 2,
            cost: |_, _| 1.0,
            pair_cost: None,
            sorted: false,
        };
        let mut v = vec![0.0; 2];
        let mut asked = Vec::new();
        let m = auction(&g, &mut v, 0.1, 1e-6, 4.0, 1.0, |free, _, _, _| {
            asked.extend_from_slice(free);
            0
        });
        assert_eq!(m.unassigned, 1);
        assert!(
            !asked.is_empty(),
            "the parked row is handed to the completion"
        );
    }
}
