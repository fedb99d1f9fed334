//! The sliced solver's snap: a one-to-one matching of the flow's endpoints onto the target samples
//! (`[solver] kind = "sliced"`, `map = "assignment"`).
//!
//! Why: the sliced flow moves the source onto the target *distribution*, but its endpoints `y'_i`
//! are not the target's samples `y_j`. At weights `(0, …, 1, …, 0)` a blend is then the endpoints,
//! not the input: on the measured BRDFs, whose lobes are narrow, that was 17–90% mean error against
//! the input's grid and 6.5% of the points outside the cube (BENCHMARKS.md, "Accuracy at unit
//! weights"), while the input's own samples are within the kernel's 2–12%. Any bijection onto the
//! samples reproduces them exactly at unit weight; the snap picks the one closest to the flow, so
//! intermediate blends stay what the flow made them.
//!
//! How: a minimum-cost assignment on `|y'_i − y_j|²` over a sparse candidate graph, solved by the
//! ε-scaling auction ([`super::auction`]). Candidates of endpoint `i` are its [`NEIGHBOURS`]
//! nearest samples, the samples that have `i` among their [`NEIGHBOURS`] nearest endpoints (so
//! every sample is somebody's candidate), and one *rank pair*: endpoints and samples each sorted
//! along a Morton curve over their common box, paired by rank. The rank pairs are a permutation,
//! so the graph always holds a perfect matching (the auction then never runs a phase on a graph
//! that has none), and they are mostly short because both clouds have the same distribution.
//!
//! The auction's ε goes from the median squared distance to the `NEIGHBOURS`-th nearest sample
//! down to [`EPS_END`] × its 1% quantile, so the matching is within a small fraction of a squared
//! local spacing of the graph's best even in the densest 1% of the samples (the lobes are 60×
//! denser than the tails in spacing). Rows a phase cannot place within its bid budget are
//! completed by dense shortest augmenting paths ([`super::exact::augment`], O(n) per scan step)
//! while there are at most [`MAX_DENSE_PATHS`] of them, else paired by Morton rank with the free
//! samples; later phases free and re-place such rows as usual, and the report counts both.
//!
//! Deterministic for any thread count: the nearest-neighbour searches are per point and exact
//! (`crate::spacing::nearest`), the graph is assembled sequentially with rows sorted by column,
//! costs are computed per row, the auction is sequential, and sums use fixed chunks.

use super::auction::{auction, Graph};
use super::cost::{det_sum, sq_dist};
use super::sliced::radix_sort;
use rayon::prelude::*;

/// Nearest samples of each endpoint (and nearest endpoints of each sample) in the graph.
pub(super) const NEIGHBOURS: usize = 8;

/// The auction's final ε as a fraction of the 1% quantile of the squared distance to the
/// `NEIGHBOURS`-th nearest sample.
pub(super) const EPS_END: f64 = 1.0 / 64.0;

/// Most rows completed by dense augmenting paths at the end of a phase (each costs O(n) per scan
/// step); more are paired by Morton rank instead.
pub(super) const MAX_DENSE_PATHS: usize = 256;

/// Revision of the snap's algorithm (part of the sliced fingerprint with `map = "assignment"`):
/// bumped whenever the same settings give a different matching.
pub(super) const REVISION: u32 = 1;

/// Rows per parallel work item.
const CHUNK: usize = 4096;

/// What the snap did (deterministic: it goes into the report line).
#[derive(Clone, Debug)]
pub(super) struct Snap {
    /// Endpoint i → sample `assignment[i]`, a permutation.
    pub assignment: Vec<u32>,
    /// Candidate pairs in the graph.
    pub pairs: usize,
    pub phases: u32,
    pub bids: u64,
    /// Rows placed by dense augmenting paths.
    pub paths: u32,
    /// Rows paired by Morton rank when too many were left for dense paths.
    pub ranked: u32,
    /// Mean and largest |y'_i − y_σ(i)|.
    pub mean_move: f64,
    pub max_move: f64,
    /// Mean |y'_i − y_σ(i)|² of the matching, and of the Morton rank pairing (a bijection the
    /// graph contains, so the matching's is at most this plus ε_end).
    pub cost: f64,
    pub rank_cost: f64,
}

impl Snap {
    /// The report's words for it.
    pub fn describe(&self) -> String {
        format!(
            "snapped one-to-one onto the target samples (k={NEIGHBOURS}, {} candidate pairs, \
             auction {} phases, {} bids, {} dense augmenting paths, {} rank-paired; \
             displacement mean={:e} max={:e}, cost={:e} vs rank pairing {:e})",
            self.pairs,
            self.phases,
            self.bids,
            self.paths,
            self.ranked,
            self.mean_move,
            self.max_move,
            self.cost,
            self.rank_cost
        )
    }
}

/// Matches the endpoints (`n · dim`) one to one onto the targets (`n · dim`), nearly minimizing
/// Σ|y'_i − y_σ(i)|². Always returns a permutation.
pub(super) fn snap(dim: usize, endpoints: &[f32], targets: &[f32]) -> Snap {
    let n = endpoints.len() / dim;
    let k = NEIGHBOURS.min(n);
    let forward = crate::spacing::nearest(targets, endpoints, dim, k);
    let backward = crate::spacing::nearest(endpoints, targets, dim, k);
    let rank = rank_pairs(dim, endpoints, targets);

    // Reverse lists: endpoint i ← every sample that has it among its nearest, in sample order.
    let mut rev_ptr = vec![0usize; n + 1];
    for &i in &backward {
        rev_ptr[i as usize + 1] += 1;
    }
    for i in 0..n {
        rev_ptr[i + 1] += rev_ptr[i];
    }
    let mut rev = vec![0u32; backward.len()];
    let mut fill = rev_ptr.clone();
    for (e, &i) in backward.iter().enumerate() {
        rev[fill[i as usize]] = (e / k) as u32;
        fill[i as usize] += 1;
    }
    drop(fill);
    drop(backward);

    // Each row: its candidates sorted by column, deduplicated; the squared distance to each, less
    // the row's smallest (f, the row constant), as f32; and the scale of the row (squared distance
    // to its k-th nearest sample).
    type Rows = (Vec<usize>, Vec<u32>, Vec<f32>, Vec<f64>, Vec<f64>);
    let chunks: Vec<Rows> = (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(n));
            let mut lens = Vec::with_capacity(b - a);
            let mut cols = Vec::with_capacity((b - a) * (2 * k + 1));
            let mut red = Vec::with_capacity((b - a) * (2 * k + 1));
            let (mut f, mut scale) = (Vec::with_capacity(b - a), Vec::with_capacity(b - a));
            let mut row: Vec<u32> = Vec::new();
            let mut h: Vec<f64> = Vec::new();
            for i in a..b {
                row.clear();
                row.extend_from_slice(&forward[i * k..(i + 1) * k]);
                row.extend_from_slice(&rev[rev_ptr[i]..rev_ptr[i + 1]]);
                row.push(rank[i]);
                row.sort_unstable();
                row.dedup();
                h.clear();
                h.extend(
                    row.iter()
                        .map(|&j| sq_dist(at(endpoints, dim, i), at(targets, dim, j as usize))),
                );
                let m = h.iter().copied().fold(f64::INFINITY, f64::min);
                red.extend(h.iter().map(|&c| (c - m) as f32));
                cols.extend_from_slice(&row);
                lens.push(row.len());
                f.push(m);
                let kth = forward[(i + 1) * k - 1] as usize;
                scale.push(sq_dist(at(endpoints, dim, i), at(targets, dim, kth)));
            }
            (lens, cols, red, f, scale)
        })
        .collect();
    drop(rev);
    drop(forward);
    let mut row_ptr = Vec::with_capacity(n + 1);
    row_ptr.push(0usize);
    let (mut col, mut red, mut f, mut scale) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (lens, c, r, fc, sc) in chunks {
        for l in lens {
            row_ptr.push(row_ptr.last().copied().unwrap_or(0) + l);
        }
        col.extend(c);
        red.extend(r);
        f.extend(fc);
        scale.extend(sc);
    }

    // ε from the scale of the rows: the median to start, a fraction of the 1% quantile to end.
    let quantile = |q: f64| -> f64 {
        let mut s = scale.clone();
        let at = ((n - 1) as f64 * q) as usize;
        *s.select_nth_unstable_by(at, f64::total_cmp).1
    };
    let floor = 1e-30;
    let eps_start = quantile(0.5).max(floor);
    let eps_end = (EPS_END * quantile(0.01)).clamp(floor, eps_start);
    drop(scale);

    let cost = |i: usize, j: usize| sq_dist(at(endpoints, dim, i), at(targets, dim, j)) - f[i];
    let graph = Graph {
        row_ptr: &row_ptr,
        col: &col,
        cols: n,
        cost,
        pair_cost: Some(&red),
    };
    let gap = super::extent_sq(dim, endpoints, targets).max(floor);
    let mut v = vec![0.0; n];
    let mut paths = 0u32;
    let mut ranked = 0u32;
    let m = auction(
        &graph,
        &mut v,
        eps_start,
        eps_end,
        4.0,
        gap,
        |free, xs, ys, v| {
            if free.len() <= MAX_DENSE_PATHS {
                let p = super::exact::augment(n, &cost, free, xs, ys, v);
                paths += p;
                p
            } else {
                let r = pair_free_by_rank(dim, endpoints, targets, free, xs, ys);
                ranked += r;
                r
            }
        },
    );
    assert_eq!(m.unassigned, 0, "the snap's completion assigns every row");
    let assignment = m.x;
    check_permutation(&assignment);

    let moved = |i: usize| sq_dist(at(endpoints, dim, i), at(targets, dim, assignment[i] as usize));
    let cost = det_sum(n, moved) / n as f64;
    let mean_move = det_sum(n, |i| moved(i).sqrt()) / n as f64;
    let max_move = (0..n)
        .into_par_iter()
        .map(moved)
        .reduce(|| 0.0, f64::max)
        .sqrt();
    let rank_cost = det_sum(n, |i| {
        sq_dist(at(endpoints, dim, i), at(targets, dim, rank[i] as usize))
    }) / n as f64;
    Snap {
        assignment,
        pairs: col.len(),
        phases: m.phases,
        bids: m.bids,
        paths,
        ranked,
        mean_move,
        max_move,
        cost,
        rank_cost,
    }
}

/// Point `i` of a point-major cloud.
#[inline]
fn at(c: &[f32], dim: usize, i: usize) -> &[f32] {
    &c[i * dim..(i + 1) * dim]
}

/// Panics unless `x` is a permutation of `0..x.len()` (the auction's own invariant; checked
/// because a solver returns only maps it has checked).
fn check_permutation(x: &[u32]) {
    let mut seen = vec![false; x.len()];
    for &j in x {
        assert!(
            !std::mem::replace(&mut seen[j as usize], true),
            "snap: sample {j} assigned twice"
        );
    }
}

/// Morton codes of `points` on the box `lo + [0, side]^dim`, `63 / dim` bits per axis (axis 0
/// the most significant of each group).
fn morton(dim: usize, points: &[f32], lo: &[f64], side: &[f64]) -> Vec<u64> {
    let bits = (63 / dim) as u32;
    let top = ((1u64 << bits) - 1) as f64;
    points
        .par_chunks_exact(dim)
        .map(|p| {
            let mut code = 0u64;
            for a in 0..dim {
                let t = if side[a] > 0.0 {
                    (f64::from(p[a]) - lo[a]) / side[a]
                } else {
                    0.0
                };
                let q = (t * top).round().clamp(0.0, top) as u64;
                for b in 0..bits {
                    code |= ((q >> b) & 1) << (b as usize * dim + (dim - 1 - a));
                }
            }
            code
        })
        .collect()
}

/// Indices of `points` sorted by Morton code (ties in index order).
fn morton_order(dim: usize, points: &[f32], lo: &[f64], side: &[f64]) -> Vec<u32> {
    let mut keys = morton(dim, points, lo, side);
    let n = keys.len();
    let mut idx: Vec<u32> = (0..n as u32).collect();
    radix_sort(&mut keys, &mut vec![0; n], &mut idx, &mut vec![0; n]);
    idx
}

/// The common box of both clouds: (low corner, side per axis).
fn common_box(dim: usize, a: &[f32], b: &[f32]) -> (Vec<f64>, Vec<f64>) {
    let mut lo = vec![f64::INFINITY; dim];
    let mut hi = vec![f64::NEG_INFINITY; dim];
    for p in a.chunks_exact(dim).chain(b.chunks_exact(dim)) {
        for k in 0..dim {
            lo[k] = lo[k].min(f64::from(p[k]));
            hi[k] = hi[k].max(f64::from(p[k]));
        }
    }
    let side = lo.iter().zip(&hi).map(|(l, h)| h - l).collect();
    (lo, side)
}

/// Endpoint i → the sample of the same rank along the Morton curve: a permutation whose pairs are
/// mostly short when both clouds have the same distribution.
fn rank_pairs(dim: usize, endpoints: &[f32], targets: &[f32]) -> Vec<u32> {
    let (lo, side) = common_box(dim, endpoints, targets);
    let oe = morton_order(dim, endpoints, &lo, &side);
    let ot = morton_order(dim, targets, &lo, &side);
    let mut pair = vec![0u32; oe.len()];
    for (&i, &j) in oe.iter().zip(&ot) {
        pair[i as usize] = j;
    }
    pair
}

/// Pairs the free rows with the free columns by Morton rank (both in Morton order of their
/// points). Returns how many rows it assigned (all of them).
fn pair_free_by_rank(
    dim: usize,
    endpoints: &[f32],
    targets: &[f32],
    free: &[usize],
    x: &mut [u32],
    y: &mut [u32],
) -> u32 {
    let open: Vec<u32> = (0..y.len() as u32)
        .filter(|&j| y[j as usize] == u32::MAX)
        .collect();
    debug_assert_eq!(open.len(), free.len());
    let gather = |c: &[f32], ids: &mut dyn Iterator<Item = usize>| -> Vec<f32> {
        ids.flat_map(|i| c[i * dim..(i + 1) * dim].iter().copied())
            .collect()
    };
    let pe = gather(endpoints, &mut free.iter().copied());
    let pt = gather(targets, &mut open.iter().map(|&j| j as usize));
    let (lo, side) = common_box(dim, &pe, &pt);
    let oe = morton_order(dim, &pe, &lo, &side);
    let ot = morton_order(dim, &pt, &lo, &side);
    for (&a, &b) in oe.iter().zip(&ot) {
        let (i, j) = (free[a as usize], open[b as usize]);
        x[i] = j;
        y[j as usize] = i as u32;
    }
    free.len() as u32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::rng::SplitMix64;

    /// `n` points in `[0,1)^dim`, clustered (half in a small ball) so spacings vary.
    fn cloud(rng: &mut SplitMix64, n: usize, dim: usize) -> Vec<f32> {
        (0..n * dim)
            .map(|c| {
                let u = rng.next_f64() as f32;
                if (c / dim) % 2 == 0 {
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

    #[test]
    fn snap_is_a_permutation_no_worse_than_the_rank_pairing() {
        for (dim, n) in [(2, 3000), (3, 2000), (1, 500)] {
            let mut rng = SplitMix64::new(dim as u64);
            let t = cloud(&mut rng, n, dim);
            // Endpoints: the targets jittered by about a spacing and shuffled.
            let mut e: Vec<f32> = t
                .iter()
                .map(|&v| v + 0.01 * (rng.next_f64() as f32 - 0.5))
                .collect();
            for i in (1..n).rev() {
                let j = (rng.next_u64() % (i as u64 + 1)) as usize;
                for a in 0..dim {
                    e.swap(i * dim + a, j * dim + a);
                }
            }
            let s = snap(dim, &e, &t);
            let mapped: Vec<f32> = s
                .assignment
                .iter()
                .flat_map(|&j| t[j as usize * dim..(j as usize + 1) * dim].to_vec())
                .collect();
            assert_eq!(as_multiset(dim, &mapped), as_multiset(dim, &t));
            assert!(s.cost <= s.rank_cost, "{dim}D: {}", s.describe());
            assert!(s.max_move.is_finite() && s.mean_move <= s.max_move);
        }
    }

    #[test]
    fn snap_recovers_a_hidden_permutation() {
        // Endpoints = targets permuted, slightly moved (far less than a spacing): the identity
        // through the hidden permutation is the optimum, and the snap finds it.
        let (dim, n) = (3, 4000);
        let mut rng = SplitMix64::new(77);
        let t = cloud(&mut rng, n, dim);
        let perm: Vec<usize> = {
            let mut p: Vec<usize> = (0..n).collect();
            for i in (1..n).rev() {
                p.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
            }
            p
        };
        let e: Vec<f32> = (0..n * dim)
            .map(|c| t[perm[c / dim] * dim + c % dim] + 1e-6 * (rng.next_f64() as f32 - 0.5))
            .collect();
        let s = snap(dim, &e, &t);
        let hidden: f64 = (0..n)
            .map(|i| sq_dist(&e[i * dim..(i + 1) * dim], &t[perm[i] * dim..(perm[i] + 1) * dim]))
            .sum::<f64>()
            / n as f64;
        assert!(s.cost <= hidden * (1.0 + 1e-9), "{} vs {hidden}", s.cost);
        assert!(s.assignment.iter().zip(&perm).all(|(&a, &p)| a as usize == p));
    }

    #[test]
    fn completion_by_rank_pairs_every_free_row() {
        let dim = 2;
        let e = [0.1f32, 0.1, 0.9, 0.9, 0.5, 0.5];
        let t = [0.88f32, 0.9, 0.1, 0.12, 0.5, 0.52];
        let mut x = vec![u32::MAX, u32::MAX, 2];
        let mut y = vec![u32::MAX, u32::MAX, 2];
        assert_eq!(pair_free_by_rank(dim, &e, &t, &[0, 1], &mut x, &mut y), 2);
        assert_eq!(x, vec![1, 0, 2]);
        assert_eq!(y, vec![1, 0, 2]);
    }
}
