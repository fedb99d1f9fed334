//! Jonker–Volgenant's reductions, with the augmenting row reduction run as an ε-scaling auction
//! before its exact passes.

use super::paths::augment;
use super::{Lap, NONE};
use rayon::prelude::*;

/// ε-scaling of the augmenting row reduction: first ε as a fraction of the cost scale, divisor per
/// phase, last ε (fraction of the scale). See [`lapjv`].
const EPS_START: f64 = 0.1;
const EPS_DIVISOR: f64 = 4.0;
const EPS_END: f64 = 1e-10;
/// Row processings allowed per ε phase, per row (a safety cap; typical phases need 1–3).
const PHASE_BUDGET_PER_ROW: u64 = 64;

/// Jonker–Volgenant for an n×n cost given as a function, `scale` being a typical large cost (the
/// squared extent of the clouds; 0 if all costs are 0).
///
/// Plain JV is slow on transport problems: the column-reduction duals (each target point is cheap for
/// its nearest source point) are far from the optimal ones when mass must travel, so the augmenting
/// row reduction fights long "price wars" with tiny dual decrements and every shortest path explores a
/// large part of the graph (measured at n = 5000 on uniform → two blobs: 89% of the time in the
/// row reduction). So the row reduction is run as an auction with ε-scaling (JV's row reduction *is* an
/// auction with ε = 0; Bertsekas 1988): each bid lowers the column's dual by its margin over the
/// second-best column plus ε, which bounds the work per phase, and ε shrinks geometrically from
/// 0.1·scale to 1e-10·scale. The resulting duals are ε-optimal; rows that are not exactly at their
/// minimum reduced cost are then freed, and JV's ε = 0 row reduction (two capped passes) and its
/// Dijkstra-like shortest augmenting paths finish exactly, with short paths because the duals are
/// already nearly optimal. The auction is only a warm start: whatever it leaves, the shortest path
/// phase completes an optimal assignment, certified afterwards by [`super::duality_gap`].
///
/// Never loops forever on finite costs: every row reduction pass has a processing budget and each
/// shortest-path search ends within n FIND/SCAN rounds.
pub(crate) fn lapjv<C>(n: usize, cost: &C, scale: f64) -> Lap
where
    C: Fn(usize, usize) -> f64 + Sync,
{
    assert!(n < NONE as usize, "lapjv: n must fit in u32");
    let mut x = vec![NONE; n];
    let mut y = vec![NONE; n];
    if n <= 1 {
        let v = (0..n).map(|j| cost(0, j)).collect();
        x.iter_mut().for_each(|x| *x = 0);
        return Lap {
            x,
            v,
            phases: 0,
            row_reductions: 0,
            free_after_reduction: 0,
            augmentations: 0,
        };
    }

    // Column reduction: v_j = min_i c_ij; each row gets the last column (scanning right to left)
    // whose minimum it holds, and is "unique" if it holds no other column's minimum.
    let colmin: Vec<(f64, u32)> = (0..n)
        .into_par_iter()
        .map(|j| {
            let mut best = (cost(0, j), 0u32);
            for i in 1..n {
                let c = cost(i, j);
                if c < best.0 {
                    best = (c, i as u32);
                }
            }
            best
        })
        .collect();
    let mut v: Vec<f64> = colmin.iter().map(|c| c.0).collect();
    let mut unique = vec![true; n];
    for j in (0..n).rev() {
        let i = colmin[j].1 as usize;
        if x[i] == NONE {
            x[i] = j as u32;
            y[j] = i as u32;
        } else {
            unique[i] = false;
        }
    }

    // Reduction transfer: a row holding a single column's minimum passes its slack to that column,
    // making the column as cheap as its second-best option.
    for i in 0..n {
        if x[i] != NONE && unique[i] {
            let j1 = x[i] as usize;
            let mut m = f64::INFINITY;
            for j in (0..n).filter(|&j| j != j1) {
                m = m.min(cost(i, j) - v[j]);
            }
            v[j1] -= m;
        }
    }

    // Augmenting row reduction with ε-scaling (an auction): each phase frees the rows that are more
    // than ε above their minimum reduced cost and lets them bid.
    let mut phases = 0u32;
    let mut row_reductions = 0u64;
    if scale > 0.0 {
        let mut eps = EPS_START * scale;
        let eps_end = EPS_END * scale;
        loop {
            let free = free_slack_rows(n, cost, eps, &mut x, &mut y, &v);
            let budget = PHASE_BUDGET_PER_ROW * n as u64;
            let (_, processed) =
                augmenting_row_reduction(cost, &free, &mut x, &mut y, &mut v, eps, budget);
            row_reductions += processed;
            phases += 1;
            if eps <= eps_end {
                break;
            }
            eps = (eps / EPS_DIVISOR).max(eps_end);
        }
    }

    // Exact finish: free every row not exactly at its minimum, JV's row reduction twice (capped at
    // n processings per pass: with real-valued costs it can otherwise crawl), then shortest paths.
    let mut free = free_slack_rows(n, cost, 0.0, &mut x, &mut y, &v);
    for _ in 0..2 {
        if free.is_empty() {
            break;
        }
        let (rest, processed) =
            augmenting_row_reduction(cost, &free, &mut x, &mut y, &mut v, 0.0, n as u64);
        row_reductions += processed;
        free = rest;
    }
    let free_after_reduction = free.len();

    // Shortest augmenting paths for the remaining free rows.
    let augmentations = augment(n, cost, &free, &mut x, &mut y, &mut v);
    debug_assert!(x.iter().all(|&j| j != NONE));
    Lap {
        x,
        v,
        phases,
        row_reductions,
        free_after_reduction,
        augmentations,
    }
}

/// Unassigns every row whose reduced cost c(i, x_i) − v(x_i) exceeds its minimum over all columns
/// by more than `eps` (and keeps the unassigned ones); returns them in increasing order. The slacks
/// are computed in parallel, the unassignment sequentially.
fn free_slack_rows<C>(
    n: usize,
    cost: &C,
    eps: f64,
    x: &mut [u32],
    y: &mut [u32],
    v: &[f64],
) -> Vec<usize>
where
    C: Fn(usize, usize) -> f64 + Sync,
{
    let xs: &[u32] = x;
    let loose: Vec<bool> = (0..n)
        .into_par_iter()
        .map(|i| {
            if xs[i] == NONE {
                return true;
            }
            let j0 = xs[i] as usize;
            let u = cost(i, j0) - v[j0];
            (0..n).any(|j| cost(i, j) - v[j] < u - eps)
        })
        .collect();
    let mut free = Vec::new();
    for (i, _) in loose.iter().enumerate().filter(|(_, &l)| l) {
        if x[i] != NONE {
            y[x[i] as usize] = NONE;
            x[i] = NONE;
        }
        free.push(i);
    }
    free
}

/// One augmenting-row-reduction pass with bid increment `eps` (JV's pass for ε = 0, an auction
/// phase for ε > 0): each free row takes its cheapest column, lowering that column's dual to the
/// row's second-best reduced cost minus ε, and evicts the column's previous owner (processed again
/// at once if the dual went down, later otherwise). After `budget` processings, rows are assigned
/// without lowering any dual. Returns the rows still free and the number of processings.
#[allow(clippy::too_many_arguments)]
fn augmenting_row_reduction<C>(
    cost: &C,
    free: &[usize],
    x: &mut [u32],
    y: &mut [u32],
    v: &mut [f64],
    eps: f64,
    budget: u64,
) -> (Vec<usize>, u64)
where
    C: Fn(usize, usize) -> f64,
{
    let mut queue = free.to_vec();
    let mut current = 0usize;
    let mut still_free = Vec::new();
    let mut processed: u64 = 0;
    while current < queue.len() {
        processed += 1;
        let i = queue[current];
        current += 1;
        // Smallest and second smallest reduced cost of row i.
        let (mut u1, mut j1) = (cost(i, 0) - v[0], 0usize);
        let (mut u2, mut j2) = (f64::INFINITY, usize::MAX);
        for (j, &vj) in v.iter().enumerate().skip(1) {
            let h = cost(i, j) - vj;
            if h < u2 {
                if h >= u1 {
                    u2 = h;
                    j2 = j;
                } else {
                    u2 = u1;
                    j2 = j1;
                    u1 = h;
                    j1 = j;
                }
            }
        }
        let mut i0 = y[j1];
        let v1_new = v[j1] - (u2 - u1) - eps;
        let lowers = v1_new < v[j1];
        if processed <= budget {
            if lowers {
                v[j1] = v1_new;
            } else if i0 != NONE {
                j1 = j2;
                i0 = y[j2];
            }
            if i0 != NONE {
                if lowers {
                    current -= 1;
                    queue[current] = i0 as usize;
                } else {
                    still_free.push(i0 as usize);
                }
            }
        } else if i0 != NONE {
            still_free.push(i0 as usize);
        }
        if i0 != NONE {
            x[i0 as usize] = NONE;
        }
        x[i] = j1 as u32;
        y[j1] = i as u32;
    }
    (still_free, processed)
}
