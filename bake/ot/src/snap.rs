//! The sliced solver's snap: a one-to-one matching of the flow's endpoints onto the target samples
//! (`[solver] kind = "sliced"`, `map = "assignment"`).
//!
//! Why: the sliced flow moves the source onto the target *distribution*, but its endpoints `y'_i`
//! are not the target's samples `y_j`. At weights `(0, …, 1, …, 0)` a blend is then the endpoints,
//! not the input: on the measured BRDFs, whose lobes are narrow, that was 17–90% mean error against
//! the input's grid and 6.5% of the points outside the cube (BENCHMARKS.md, "Accuracy at unit
//! weights"), while the input's own samples are within the kernel's 2–12%. Any bijection onto the
//! samples reproduces them exactly at unit weight; the snap looks for one that moves the endpoints
//! little, so intermediate blends stay what the flow made them.
//!
//! How: a bisection matching, then local exact re-matching.
//!
//! 1. Both clouds are split together, recursively: along the longest axis of their joint box,
//!    each at its *own* median (the left part of either takes `ceil(m/2)` points), so every cell
//!    holds as many endpoints as samples. Cells of at most [`LEAF`] points of each are matched
//!    exactly ([`hungarian`], dense on the cell). Where the flow's density is off, the two
//!    medians differ and the points between them change sides: that is the mass the snap must
//!    move, and a cut moves it the short way along its axis.
//! 2. Once per entry of [`PASSES`]: the endpoints are grouped again, by the midpoints
//!    `(y'_i + y_σ(i))/2` of their current pairs, into cells of that size (other sizes than the
//!    bisection's, so the cuts fall elsewhere), and each group is re-matched exactly onto the
//!    samples it holds. The current matching is feasible there, so the cost never rises, and
//!    pairs a cut of step 1 split get another chance. On garnet_red (1M) the passes take the mean
//!    squared move from 1.42e-4 to 1.19e-4.
//!
//! Not optimal: on two independent samples of one clustered distribution (no smooth flow to
//! follow, the hardest case) the cost is 1.8x (2D, 3000 points) to 2.1x (3D, 2000) the exact
//! assignment's; the flow's endpoints are nearer the samples than that, and every endpoint still
//! moves by about a local spacing (the report line gives the mean and largest move).
//!
//! Why not the ε-scaling auction on a nearest-neighbour graph (`auction.rs`, as Sinkhorn's
//! matching does): Sinkhorn hands its auction near-optimal prices; from zero prices, on the 1M
//! endpoints of garnet_red's flow (the 8 nearest samples of each endpoint, the 8 nearest endpoints
//! of each sample and a Morton rank pair per row, so a perfect matching exists), every ε phase
//! spent its whole bid budget (50 per row): 300M bids, 13 092 rows left to a fallback (largest
//! move 1.36). Warm-starting it from a coarser level (every 8th point along a Morton curve, the
//! coarsest solved exactly, prices carried down by a c-transform, candidates around predicted
//! positions) did not help — 2.3M bids (150 per point) at 15 625 points: a subsample's duals
//! carry its own sampling noise, price errors of many fine ε. Bisection needs no prices, its
//! work is fixed (n log n for the cuts, n · cell size² per pass for the cells), and it always
//! ends on a permutation.
//!
//! Deterministic for any thread count: cuts order points by (coordinate, index) with
//! `select_nth_unstable_by` (one result for a strict total order), cells are solved independently
//! and written back in cell order, and sums use fixed chunks.

use super::cost::{det_sum, sq_dist};
use rayon::prelude::*;
use std::ops::Range;

/// Largest cell of the bisection, matched exactly (O(LEAF³) at most). At 1M (garnet_red) cells of
/// 32 then passes of 64/48 ended at a mean squared move of 1.19e-4; cells of 64 and 128 gave
/// 1.37e-4 and 1.34e-4 with passes of their own size (their midpoint cells fall on the same cuts),
/// cells of 256 (by `exact::lapjv`, 4× the time) 1.31e-4.
pub(super) const LEAF: usize = 32;

/// Cell sizes of the re-matching passes over midpoints: each pass costs n · size² (a 48-cell pass
/// measured half to all of a 64-cell one's time); the fourth gained 0.5%.
pub(super) const PASSES: [usize; 4] = [64, 48, 64, 48];

/// Revision of the snap's algorithm (part of the sliced fingerprint with `map = "assignment"`):
/// bumped whenever the same settings give a different matching.
pub(super) const REVISION: u32 = 1;

/// Below this many points a cut runs on the current thread.
const PARALLEL_MIN: usize = 1 << 14;

/// What the snap did (deterministic: it goes into the report line).
#[derive(Clone, Debug)]
pub(super) struct Snap {
    /// Endpoint i → sample `assignment[i]`, a permutation.
    pub assignment: Vec<u32>,
    /// Cells matched by the bisection.
    pub cells: usize,
    /// Mean |y'_i − y_σ(i)|² after the bisection, then after each pass.
    pub costs: Vec<f64>,
    /// Mean and largest |y'_i − y_σ(i)|.
    pub mean_move: f64,
    pub max_move: f64,
}

impl Snap {
    /// Mean |y'_i − y_σ(i)|² of the final matching.
    #[cfg(test)]
    fn cost(&self) -> f64 {
        *self.costs.last().expect("the bisection's cost")
    }

    /// The report's words for it.
    pub fn describe(&self) -> String {
        let costs: Vec<String> = self.costs.iter().map(|c| format!("{c:e}")).collect();
        format!(
            "snapped one-to-one onto the target samples (bisection into {} cells of <= {LEAF}, \
             re-matching passes over midpoint cells of {:?}; mean |y'-y|^2 by pass {}; \
             displacement mean={:e} max={:e})",
            self.cells,
            &PASSES[..self.costs.len() - 1],
            costs.join(" -> "),
            self.mean_move,
            self.max_move
        )
    }
}

/// Matches the endpoints (`n · dim`) one to one onto the targets (`n · dim`), keeping
/// Σ|y'_i − y_σ(i)|² small (see the module). Always returns a permutation.
pub(super) fn snap(dim: usize, endpoints: &[f32], targets: &[f32]) -> Snap {
    let n = endpoints.len() / dim;
    let trace = std::env::var_os("OTBAKE_TRACE").is_some();
    let t0 = std::time::Instant::now();
    let mut rows: Vec<u32> = (0..n as u32).collect();
    let mut cols: Vec<u32> = (0..n as u32).collect();
    let cells = bisect(dim, endpoints, &mut rows, targets, &mut cols, 0, LEAF);
    let mut assignment = vec![0u32; n];
    match_cells(
        dim,
        endpoints,
        targets,
        &rows,
        &cols,
        &cells,
        &mut assignment,
    );
    let moved =
        |x: &[u32], i: usize| sq_dist(at(endpoints, dim, i), at(targets, dim, x[i] as usize));
    let mut costs = vec![det_sum(n, |i| moved(&assignment, i)) / n as f64];
    if trace {
        eprintln!(
            "  snap: bisection {} cells, cost {:e}, {:.2}s",
            cells.len(),
            costs[0],
            t0.elapsed().as_secs_f64()
        );
    }
    for (pass, &leaf) in PASSES.iter().enumerate() {
        let t = std::time::Instant::now();
        let mid: Vec<f32> = (0..n * dim)
            .into_par_iter()
            .map(|c| {
                let (i, a) = (c / dim, c % dim);
                0.5 * (endpoints[c] + targets[assignment[i] as usize * dim + a])
            })
            .collect();
        let mut rows: Vec<u32> = (0..n as u32).collect();
        let mut same = rows.clone();
        let cells = bisect(dim, &mid, &mut rows, &mid, &mut same, 0, leaf);
        drop(mid);
        // Each cell's rows keep the samples they hold.
        let cols: Vec<u32> = rows.iter().map(|&i| assignment[i as usize]).collect();
        match_cells(
            dim,
            endpoints,
            targets,
            &rows,
            &cols,
            &cells,
            &mut assignment,
        );
        costs.push(det_sum(n, |i| moved(&assignment, i)) / n as f64);
        if trace {
            eprintln!(
                "  snap: pass {pass}: cost {:e}, {:.2}s",
                costs[pass + 1],
                t.elapsed().as_secs_f64()
            );
        }
    }
    check_permutation(&assignment);
    let mean_move = det_sum(n, |i| moved(&assignment, i).sqrt()) / n as f64;
    let max_move = (0..n)
        .into_par_iter()
        .map(|i| moved(&assignment, i))
        .reduce(|| 0.0, f64::max)
        .sqrt();
    Snap {
        assignment,
        cells: cells.len(),
        costs,
        mean_move,
        max_move,
    }
}

/// Point `i` of a point-major cloud.
#[inline]
fn at(c: &[f32], dim: usize, i: usize) -> &[f32] {
    &c[i * dim..(i + 1) * dim]
}

/// Splits `a` (indices of points `pa`) and `b` (indices of `pb`, as many) together until at most
/// `leaf` remain: along the longest axis of their joint box, each at its own median (the left
/// part takes `ceil(m/2)` of either, ordered by coordinate, then index). Returns the cells'
/// ranges, in order, offset by `start`; the cells' contents depend only on the points.
fn bisect(
    dim: usize,
    pa: &[f32],
    a: &mut [u32],
    pb: &[f32],
    b: &mut [u32],
    start: usize,
    leaf: usize,
) -> Vec<Range<usize>> {
    let m = a.len();
    if m <= leaf {
        return std::iter::once(start..start + m).collect();
    }
    let mut lo = vec![f32::INFINITY; dim];
    let mut hi = vec![f32::NEG_INFINITY; dim];
    for (p, ids) in [(pa, &*a), (pb, &*b)] {
        for &i in ids {
            for (k, &v) in at(p, dim, i as usize).iter().enumerate() {
                lo[k] = lo[k].min(v);
                hi[k] = hi[k].max(v);
            }
        }
    }
    // Longest axis; the first of equal extents wins.
    let axis = (0..dim).fold(0, |best, k| {
        if hi[k] - lo[k] > hi[best] - lo[best] {
            k
        } else {
            best
        }
    });
    let left = m - m / 2;
    let cut = |p: &[f32], ids: &mut [u32]| {
        ids.select_nth_unstable_by(left, |&i, &j| {
            p[i as usize * dim + axis]
                .total_cmp(&p[j as usize * dim + axis])
                .then(i.cmp(&j))
        });
    };
    cut(pa, a);
    cut(pb, b);
    let (al, ar) = a.split_at_mut(left);
    let (bl, br) = b.split_at_mut(left);
    let (mut l, r) = if m >= PARALLEL_MIN {
        rayon::join(
            || bisect(dim, pa, al, pb, bl, start, leaf),
            || bisect(dim, pa, ar, pb, br, start + left, leaf),
        )
    } else {
        (
            bisect(dim, pa, al, pb, bl, start, leaf),
            bisect(dim, pa, ar, pb, br, start + left, leaf),
        )
    };
    l.extend(r);
    l
}

/// Matches each cell's rows (`rows[cell]`, endpoints) exactly onto its columns (`cols[cell]`,
/// samples) and writes the result into `assignment`.
fn match_cells(
    dim: usize,
    endpoints: &[f32],
    targets: &[f32],
    rows: &[u32],
    cols: &[u32],
    cells: &[Range<usize>],
    assignment: &mut [u32],
) {
    let solved: Vec<Vec<u32>> = cells
        .par_iter()
        .map(|cell| {
            let (r, c) = (&rows[cell.clone()], &cols[cell.clone()]);
            let m = r.len();
            let mut cost = vec![0.0; m * m];
            for (a, &i) in r.iter().enumerate() {
                for (b, &j) in c.iter().enumerate() {
                    cost[a * m + b] =
                        sq_dist(at(endpoints, dim, i as usize), at(targets, dim, j as usize));
                }
            }
            hungarian(m, &cost)
        })
        .collect();
    for (cell, x) in cells.iter().zip(solved) {
        for (k, &j) in x.iter().enumerate() {
            assignment[rows[cell.start + k] as usize] = cols[cell.start + j as usize];
        }
    }
}

/// The optimal assignment of a dense `m × m` cost (row-major): shortest augmenting paths with
/// potentials (Kuhn–Munkres in Jonker–Volgenant's form), O(m³), exact. For the snap's cells,
/// where `exact::lapjv`'s ε-scaling start and parallel scans cost more than they save.
fn hungarian(m: usize, cost: &[f64]) -> Vec<u32> {
    const NONE: usize = usize::MAX;
    // Columns 0..m, plus a virtual column m that holds the row being inserted.
    let (mut u, mut v) = (vec![0.0f64; m], vec![0.0f64; m + 1]);
    let mut owner = vec![NONE; m + 1];
    let mut way = vec![m; m + 1];
    let mut minv = vec![0.0f64; m + 1];
    let mut used = vec![false; m + 1];
    for row in 0..m {
        owner[m] = row;
        let mut j0 = m;
        minv.fill(f64::INFINITY);
        used.fill(false);
        loop {
            used[j0] = true;
            let i0 = owner[j0];
            let (mut delta, mut j1) = (f64::INFINITY, NONE);
            for j in 0..m {
                if !used[j] {
                    let cur = cost[i0 * m + j] - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            for j in 0..=m {
                if used[j] {
                    u[owner[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if owner[j0] == NONE {
                break;
            }
        }
        // Flip the path back to the virtual column.
        while j0 != m {
            let j1 = way[j0];
            owner[j0] = owner[j1];
            j0 = j1;
        }
    }
    let mut x = vec![0u32; m];
    for (j, &i) in owner[..m].iter().enumerate() {
        x[i] = j as u32;
    }
    x
}

/// Panics unless `x` is a permutation of `0..x.len()` (checked because a solver returns only maps
/// it has checked).
fn check_permutation(x: &[u32]) {
    let mut seen = vec![false; x.len()];
    for &j in x {
        assert!(
            !std::mem::replace(&mut seen[j as usize], true),
            "snap: sample {j} assigned twice"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    /// `n` points in `[0,1)^dim`, clustered (half in a small box) so spacings vary.
    fn cloud(rng: &mut SplitMix64, n: usize, dim: usize) -> Vec<f32> {
        (0..n * dim)
            .map(|c| {
                let u = rng.next_f64() as f32;
                if (c / dim).is_multiple_of(2) {
                    0.3 + 0.1 * u
                } else {
                    u
                }
            })
            .collect()
    }

    fn as_multiset(dim: usize, points: &[f32]) -> Vec<Vec<u32>> {
        let mut v: Vec<Vec<u32>> = points
            .chunks_exact(dim)
            .map(|p| p.iter().map(|x| x.to_bits()).collect())
            .collect();
        v.sort();
        v
    }

    fn exact_cost(dim: usize, e: &[f32], t: &[f32]) -> f64 {
        let n = e.len() / dim;
        let cost = |i: usize, j: usize| sq_dist(at(e, dim, i), at(t, dim, j));
        let lap = crate::exact::lapjv(n, &cost, crate::extent_sq(dim, e, t));
        (0..n).map(|i| cost(i, lap.x[i] as usize)).sum::<f64>() / n as f64
    }

    /// Mean squared distance of the pairing in sorted order along `axis` (what one slice of the
    /// sliced flow matches; a bijection that ignores the other axes).
    fn sorted_pairing_cost(dim: usize, e: &[f32], t: &[f32], axis: usize) -> f64 {
        let n = e.len() / dim;
        let order = |p: &[f32]| {
            let mut o: Vec<usize> = (0..n).collect();
            o.sort_by(|&i, &j| {
                p[i * dim + axis]
                    .total_cmp(&p[j * dim + axis])
                    .then(i.cmp(&j))
            });
            o
        };
        let (oe, ot) = (order(e), order(t));
        oe.iter()
            .zip(&ot)
            .map(|(&i, &j)| sq_dist(at(e, dim, i), at(t, dim, j)))
            .sum::<f64>()
            / n as f64
    }

    /// Two independent samples of one clustered distribution, the hardest case for a local
    /// matching (no smooth displacement to follow, and in 2D the optimal matching is not local):
    /// a permutation onto the samples, every pass no worse than the one before, cheaper than the
    /// sorted pairing along any axis, and within 2.5x of the optimal cost (measured: 1.78x in 2D
    /// at n = 3000, 2.08x in 3D at n = 2000; printed).
    #[test]
    fn snap_is_a_permutation_near_the_optimal_cost() {
        for (dim, n) in [(2, 3000), (3, 2000), (1, 700)] {
            let mut rng = SplitMix64::new(dim as u64);
            let e = cloud(&mut rng, n, dim);
            let t = cloud(&mut rng, n, dim);
            let s = snap(dim, &e, &t);
            let mapped: Vec<f32> = s
                .assignment
                .iter()
                .flat_map(|&j| at(&t, dim, j as usize).to_vec())
                .collect();
            assert_eq!(as_multiset(dim, &mapped), as_multiset(dim, &t));
            assert!(
                s.costs.windows(2).all(|c| c[1] <= c[0] * (1.0 + 1e-12)),
                "{}",
                s.describe()
            );
            for axis in 0..dim {
                let sorted = sorted_pairing_cost(dim, &e, &t, axis);
                assert!(
                    s.cost() <= sorted * (1.0 + 1e-12),
                    "{dim}D axis {axis}: {sorted}"
                );
            }
            let best = exact_cost(dim, &e, &t);
            eprintln!("{dim}D: cost / exact = {}", s.cost() / best);
            assert!(
                s.cost() <= 2.5 * best,
                "{dim}D: {} vs exact {best}",
                s.describe()
            );
            assert!(s.mean_move <= s.max_move);
        }
    }

    #[test]
    fn snap_recovers_a_hidden_permutation() {
        // Endpoints = targets permuted and moved far less than a spacing: the hidden permutation
        // is the optimum, and the snap finds it.
        let (dim, n) = (3, 3000);
        let mut rng = SplitMix64::new(77);
        let t = cloud(&mut rng, n, dim);
        let mut perm: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            perm.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
        }
        let e: Vec<f32> = (0..n * dim)
            .map(|c| t[perm[c / dim] * dim + c % dim] + 1e-6 * (rng.next_f64() as f32 - 0.5))
            .collect();
        let s = snap(dim, &e, &t);
        assert!(s
            .assignment
            .iter()
            .zip(&perm)
            .all(|(&a, &p)| a as usize == p));
    }

    /// Cells' contents depend only on the points: the same cells for any thread count.
    #[test]
    fn snap_is_the_same_for_any_thread_count() -> Result<(), Box<dyn std::error::Error>> {
        let (dim, n) = (2, 40_000);
        let mut rng = SplitMix64::new(5);
        let e = cloud(&mut rng, n, dim);
        let t = cloud(&mut rng, n, dim);
        let run = |k: usize| -> Result<Vec<u32>, Box<dyn std::error::Error>> {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(k).build()?;
            Ok(pool.install(|| snap(dim, &e, &t)).assignment)
        };
        assert_eq!(run(1)?, run(3)?);
        Ok(())
    }
}
