//! Shortest augmenting paths (JV's Dijkstra-like search on reduced costs): what completes the
//! partial assignment of the row reductions (the sparse auctions have their own, D144).

use super::NONE;

/// Completes a partial assignment: one Dijkstra-like shortest augmenting path (over all n columns)
/// per free row, then the flip along the path. With duals that certify the partial assignment the
/// result is optimal (JV); with merely approximate duals it is still a perfect matching, found in
/// O(n) per scan step. Returns the number of paths.
pub(crate) fn augment<C>(
    n: usize,
    cost: &C,
    free: &[usize],
    x: &mut [u32],
    y: &mut [u32],
    v: &mut [f64],
) -> u32
where
    C: Fn(usize, usize) -> f64,
{
    let mut d = vec![0.0; n];
    let mut cols: Vec<usize> = (0..n).collect();
    let mut pred = vec![0usize; n];
    let mut augmentations = 0u32;
    for &start in free {
        let end = find_path(n, cost, start, y, v, &mut d, &mut cols, &mut pred);
        let mut j = end;
        loop {
            let i = pred[j];
            y[j] = i as u32;
            let prev = x[i];
            x[i] = j as u32;
            if i == start {
                break;
            }
            j = prev as usize;
        }
        augmentations += 1;
    }
    augmentations
}

/// Dijkstra on reduced costs from free row `start` to the nearest unassigned column; updates the
/// duals of the columns settled before the last distance level and returns the end column (the path
/// is in `pred`). `cols` is a permutation of the columns: [0, lo) ready, [lo, hi) to scan at the
/// current distance, [hi, n) to do.
#[allow(clippy::too_many_arguments)]
fn find_path<C>(
    n: usize,
    cost: &C,
    start: usize,
    y: &[u32],
    v: &mut [f64],
    d: &mut [f64],
    cols: &mut [usize],
    pred: &mut [usize],
) -> usize
where
    C: Fn(usize, usize) -> f64,
{
    for j in 0..n {
        cols[j] = j;
        pred[j] = start;
        d[j] = cost(start, j) - v[j];
    }
    let (mut lo, mut hi) = (0usize, 0usize);
    let mut n_ready = 0usize;
    let end = 'search: loop {
        if lo == hi {
            // FIND: move every to-do column at the minimal distance to the scan list.
            debug_assert!(lo < n, "an unassigned column always remains to be found");
            n_ready = lo;
            hi = lo + 1;
            let mut mind = d[cols[lo]];
            for k in lo + 1..n {
                let j = cols[k];
                if d[j] <= mind {
                    if d[j] < mind {
                        hi = lo;
                        mind = d[j];
                    }
                    cols.swap(k, hi);
                    hi += 1;
                }
            }
            if let Some(&j) = cols[lo..hi].iter().find(|&&j| y[j] == NONE) {
                break 'search j;
            }
        }
        // SCAN: relax the to-do columns through the row assigned to each scan column.
        while lo < hi {
            let j = cols[lo];
            lo += 1;
            let i = y[j] as usize;
            let mind = d[j];
            let h = cost(i, j) - v[j] - mind;
            // Columns moved to the scan list are swapped to `hi`, behind `k`: the loop must go on
            // from `k` over the original range, as in the paper.
            #[allow(clippy::mut_range_bound)]
            for k in hi..n {
                let j2 = cols[k];
                let r = cost(i, j2) - v[j2] - h;
                if r < d[j2] {
                    d[j2] = r;
                    pred[j2] = i;
                    // `<=` rather than `==`: rounding may put r a hair below mind.
                    if r <= mind {
                        if y[j2] == NONE {
                            break 'search j2;
                        }
                        cols.swap(k, hi);
                        hi += 1;
                    }
                }
            }
        }
    };
    let mind = d[cols[n_ready]];
    for &j in &cols[..n_ready] {
        v[j] += d[j] - mind;
    }
    end
}
