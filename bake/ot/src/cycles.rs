//! Short alternating cycles that lower a matching's cost, cancelled along candidate lists
//! (docs/decisions.md, D164).
//!
//! An ε-complementary-slack matching (the auction's) is within n·ε of the best one, and most of
//! what it gives away is local: two rows that would each rather have the other's column, or three
//! rows around a triangle of near-ties. Swapping them along the rows' first candidates recovers
//! that for a fraction of the bids a smaller ε takes (the auction's endgame grows as 1/ε).
//!
//! Each pass looks for one cycle per row in parallel, on the matching as the pass found it, and
//! then applies them in row order, each only if its rows still hold the columns it was found on;
//! the next pass looks again from the rows that moved or were left out. The result is the same for
//! any thread count, and every applied cycle lowers the exact cost by more than a floor, so the
//! passes end.

use crate::auction::prefetch;
use rayon::prelude::*;

/// "Unassigned", in the matching and as a column's owner.
const NONE: u32 = u32::MAX;

/// Rows per parallel work item of a pass's search.
const CHUNK: usize = 2048;

/// Each row's candidates, nearest first: CSR rows of columns and their values (`f32`, ascending
/// within a row), each no more than the pair's cost given to [`cancel`] (a row's cost less its
/// least, say: a constant per row changes no cycle). They only prune the search.
pub(crate) struct Lists<'a> {
    pub row_ptr: &'a [usize],
    pub col: &'a [u32],
    pub value: &'a [f32],
}

/// How far the search looks.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CycleSearch {
    /// A row's first candidates tried for a swap with their owner.
    pub pairs: usize,
    /// A row's, and each owner's, first candidates tried for a cycle of three rows.
    pub triples: usize,
    /// Passes at most: the first over every row, each next over the rows the last one moved or
    /// left out.
    pub passes: u32,
    /// The least gain a cycle must bring, in the costs' units: more than rounding can fake.
    pub min_gain: f64,
}

/// What [`cancel`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Cancelled {
    pub passes: u32,
    /// Cycles of two rows (swaps), and of three.
    pub pairs: u64,
    pub triples: u64,
}

/// A cycle found from `rows[0]`: row `rows[t]` takes `cols[t]` (the column `rows[t + 1]` held,
/// the last row taking the first row's). Two or three rows (`len`).
#[derive(Clone, Copy, Debug)]
struct Cycle {
    rows: [u32; 3],
    cols: [u32; 3],
    len: usize,
}

/// Lowers the cost of the matching `x` (row → column, [`NONE`] for a row without one) by cycles
/// of two and three rows along `lists`. `cost(i, j)` is the exact cost of any pair, up to a
/// constant per row and per column, and no lower than 0 wherever a cycle might close (else the
/// pruning may miss it); a cycle is taken on `cost` alone.
pub(crate) fn cancel<C: Fn(usize, usize) -> f64 + Sync>(
    x: &mut [u32],
    lists: &Lists<'_>,
    cost: C,
    search: &CycleSearch,
) -> Cancelled {
    let cols = lists.col.iter().chain(x.iter()).filter(|&&j| j != NONE);
    let mut y = vec![NONE; cols.map(|&j| j as usize + 1).max().unwrap_or(0)];
    for (i, &j) in x.iter().enumerate().filter(|(_, &j)| j != NONE) {
        y[j as usize] = i as u32;
    }
    // The cost of each column's pair, kept by column: a search reads it at the candidate's
    // column (a row's candidates lie close together in memory), and reads the column's owner
    // only when a cycle may gain.
    let own: Vec<f64> = y
        .par_iter()
        .enumerate()
        .map(|(j, &i)| if i == NONE { 0.0 } else { cost(i as usize, j) })
        .collect();
    let mut m = Matching { x, y, own };
    let mut done = Cancelled::default();
    let mut rows: Vec<u32> = (0..m.x.len() as u32).collect();
    while done.passes < search.passes && !rows.is_empty() {
        done.passes += 1;
        let found: Vec<Cycle> = {
            let m = &m;
            rows.par_chunks(CHUNK)
                .flat_map_iter(|rs| {
                    rs.iter()
                        .filter_map(|&i| m.find(i as usize, lists, &cost, search))
                })
                .collect()
        };
        let mut next = Vec::new();
        for c in &found {
            if m.holds(c) {
                m.apply(c, &cost);
                next.extend_from_slice(&c.rows[..c.len]);
                match c.len {
                    2 => done.pairs += 1,
                    _ => done.triples += 1,
                }
            } else {
                // Another cycle of this pass moved one of its rows: looked for again.
                next.push(c.rows[0]);
            }
        }
        next.sort_unstable();
        next.dedup();
        rows = next;
    }
    done
}

/// The matching both ways, with the cost of each column's pair.
struct Matching<'a> {
    x: &'a mut [u32],
    y: Vec<u32>,
    own: Vec<f64>,
}

impl Matching<'_> {
    /// Whether every row of `c` still holds the column the cycle gives the row before it.
    fn holds(&self, c: &Cycle) -> bool {
        (0..c.len).all(|t| self.y[c.cols[t] as usize] == c.rows[(t + 1) % c.len])
    }

    fn apply<C: Fn(usize, usize) -> f64>(&mut self, c: &Cycle, cost: &C) {
        for t in 0..c.len {
            let (i, j) = (c.rows[t] as usize, c.cols[t] as usize);
            self.x[i] = j as u32;
            self.y[j] = i as u32;
            self.own[j] = cost(i, j);
        }
    }

    /// The first cycle from row i that lowers the cost: a swap with the owner of one of its
    /// first `pairs` candidates, else a cycle of three through the first `triples` candidates of
    /// i and of their owners.
    fn find<C: Fn(usize, usize) -> f64>(
        &self,
        i: usize,
        lists: &Lists<'_>,
        cost: &C,
        search: &CycleSearch,
    ) -> Option<Cycle> {
        if self.x[i] == NONE {
            return None;
        }
        let a = self.x[i] as usize;
        let floor = search.min_gain;
        let first = |r: usize, n: usize| {
            let (s, e) = (lists.row_ptr[r], lists.row_ptr[r + 1]);
            let e = e.min(s + n);
            lists.col[s..e].iter().zip(&lists.value[s..e])
        };
        // A cycle of three reads the owners' lists, elsewhere in memory: fetched while the swaps
        // are tried.
        for (&b, _) in first(i, search.triples) {
            let k = self.y[b as usize];
            if k != NONE {
                let p = lists.row_ptr[k as usize];
                prefetch(lists.col.as_ptr().wrapping_add(p));
                prefetch(lists.value.as_ptr().wrapping_add(p));
            }
        }
        let own = &self.own;
        for (&b, &vb) in first(i, search.pairs) {
            let b = b as usize;
            // Values are no lower than 0 (a row's least), so a swap gains at most this.
            if b == a || own[a] + own[b] - f64::from(vb) <= floor {
                continue;
            }
            let k = self.y[b] as usize;
            if k == NONE as usize {
                continue;
            }
            if own[a] + own[b] - cost(i, b) - cost(k, a) > floor {
                return Some(Cycle {
                    rows: [i as u32, k as u32, 0],
                    cols: [b as u32, a as u32, 0],
                    len: 2,
                });
            }
        }
        for (&b, &vb) in first(i, search.triples) {
            let b = b as usize;
            if b == a {
                continue;
            }
            let k = self.y[b] as usize;
            if k == NONE as usize {
                continue;
            }
            let open = own[a] + own[b] - f64::from(vb);
            for (&c, &vc) in first(k, search.triples) {
                let c = c as usize;
                if c == b || c == a || open + own[c] - f64::from(vc) <= floor {
                    continue;
                }
                let l = self.y[c] as usize;
                if l == NONE as usize {
                    continue;
                }
                let gain = own[a] + own[b] + own[c] - cost(i, b) - cost(k, c) - cost(l, a);
                if gain > floor {
                    return Some(Cycle {
                        rows: [i as u32, k as u32, l as u32],
                        cols: [b as u32, c as u32, a as u32],
                        len: 3,
                    });
                }
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exact::lapjv;
    use crate::rng::SplitMix64;

    /// n random points either side in the unit square, each row's `near` nearest columns as its
    /// list (values: the cost less the row's least).
    struct Problem {
        src: Vec<[f64; 2]>,
        dst: Vec<[f64; 2]>,
        row_ptr: Vec<usize>,
        col: Vec<u32>,
        value: Vec<f32>,
    }

    impl Problem {
        fn new(n: usize, near: usize, seed: u64) -> Self {
            let mut rng = SplitMix64::new(seed);
            let mut point = || [rng.next_f64(), rng.next_f64()];
            let src: Vec<_> = (0..n).map(|_| point()).collect();
            let dst: Vec<_> = (0..n).map(|_| point()).collect();
            Self::with_lists(src, dst, |_| (0..n).collect(), near)
        }

        /// Each row's list: its `near` nearest of the columns `among(i)`.
        fn with_lists(
            src: Vec<[f64; 2]>,
            dst: Vec<[f64; 2]>,
            among: impl Fn(usize) -> Vec<usize>,
            near: usize,
        ) -> Self {
            let mut p = Problem {
                src,
                dst,
                row_ptr: vec![0],
                col: Vec::new(),
                value: Vec::new(),
            };
            for i in 0..p.src.len() {
                let mut by: Vec<(f64, u32)> = among(i)
                    .into_iter()
                    .map(|j| (p.cost(i, j), j as u32))
                    .collect();
                by.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                for &(c, j) in &by[..near] {
                    p.col.push(j);
                    p.value.push((c - by[0].0) as f32);
                }
                p.row_ptr.push(p.col.len());
            }
            p
        }

        fn cost(&self, i: usize, j: usize) -> f64 {
            let (a, b) = (self.src[i], self.dst[j]);
            (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
        }

        fn total(&self, x: &[u32]) -> f64 {
            x.iter()
                .enumerate()
                .map(|(i, &j)| self.cost(i, j as usize))
                .sum()
        }

        fn lists(&self) -> Lists<'_> {
            Lists {
                row_ptr: &self.row_ptr,
                col: &self.col,
                value: &self.value,
            }
        }

        fn cancel(&self, x: &mut [u32], min_gain: f64) -> Cancelled {
            let search = CycleSearch {
                pairs: 8,
                triples: 6,
                passes: 64,
                min_gain,
            };
            cancel(x, &self.lists(), |i, j| self.cost(i, j), &search)
        }

        /// Each point's column in order of the first coordinate: a poor matching with every
        /// column once.
        fn by_first_coordinate(&self) -> Vec<u32> {
            let order = |pts: &[[f64; 2]]| {
                let mut o: Vec<usize> = (0..pts.len()).collect();
                o.sort_by(|&a, &b| pts[a][0].total_cmp(&pts[b][0]));
                o
            };
            let (rows, cols) = (order(&self.src), order(&self.dst));
            let mut x = vec![0u32; rows.len()];
            for (&i, &j) in rows.iter().zip(&cols) {
                x[i] = j as u32;
            }
            x
        }
    }

    fn is_permutation(x: &[u32]) -> bool {
        let mut seen = vec![false; x.len()];
        x.iter()
            .all(|&j| (j as usize) < x.len() && !std::mem::replace(&mut seen[j as usize], true))
    }

    /// From a poor matching the cycles keep a permutation, lower the cost by at least their floor
    /// each, and stop above the optimum.
    #[test]
    fn cycles_lower_the_cost_of_a_permutation() {
        let p = Problem::new(400, 12, 7);
        let mut x = p.by_first_coordinate();
        let before = p.total(&x);
        let floor = 1e-9;
        let done = p.cancel(&mut x, floor);
        let after = p.total(&x);
        assert!(is_permutation(&x));
        assert!(done.pairs > 0 && done.triples > 0, "{done:?}");
        let taken = (done.pairs + done.triples) as f64;
        assert!(
            after <= before - taken * floor,
            "{before} → {after}, {done:?}"
        );
        let best = p.total(&lapjv(400, &|i, j| p.cost(i, j), 1.0).x);
        assert!(after >= best - 1e-12, "{after} below the optimum {best}");
    }

    /// Where every row can reach only the columns of its own cluster of three, any matching is
    /// one swap or one cycle of three from the best within each cluster, so the cycles end at the
    /// optimum from any start.
    #[test]
    fn cycles_reach_the_optimum_in_clusters_of_three() {
        let clusters = 60;
        let mut rng = SplitMix64::new(5);
        let mut jitter = |c: usize| {
            let (cx, cy) = ((c % 8) as f64, (c / 8) as f64);
            [cx + 0.3 * rng.next_f64(), cy + 0.3 * rng.next_f64()]
        };
        let n = 3 * clusters;
        let src: Vec<_> = (0..n).map(|i| jitter(i / 3)).collect();
        let dst: Vec<_> = (0..n).map(|j| jitter(j / 3)).collect();
        let p = Problem::with_lists(src, dst, |i| (0..3).map(|t| 3 * (i / 3) + t).collect(), 3);
        // Each cluster starts at one of the six permutations of its columns.
        let perms = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ];
        let mut x = vec![0u32; n];
        for c in 0..clusters {
            for t in 0..3 {
                x[3 * c + t] = (3 * c + perms[c % 6][t]) as u32;
            }
        }
        let done = p.cancel(&mut x, 1e-12);
        let best = p.total(&lapjv(n, &|i, j| p.cost(i, j), 1.0).x);
        assert!(done.pairs > 0 && done.triples > 0, "{done:?}");
        assert!(
            (p.total(&x) - best).abs() < 1e-9,
            "{} against {best}",
            p.total(&x)
        );
    }

    /// The same matching with one thread and with two.
    #[test]
    fn cycles_are_the_same_for_any_thread_count() {
        let p = Problem::new(2000, 10, 3);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut x = p.by_first_coordinate();
            let done = pool.install(|| p.cancel(&mut x, 1e-12));
            (x, done)
        };
        let (one, two) = (run(1), run(2));
        assert!(one.1.pairs + one.1.triples > 1000, "{:?}", one.1);
        assert_eq!(one, two);
    }

    /// A swap that gains less than the floor is left alone.
    #[test]
    fn a_gain_below_the_floor_is_not_taken() {
        // Rows at 0 and 1, columns at 0.25 and 1.25 on a line: straight (0 → 0.25, 1 → 1.25) the
        // matching costs 0.125, crossed 2.125; the swap gains exactly 2.
        let p = Problem {
            src: vec![[0.0, 0.0], [1.0, 0.0]],
            dst: vec![[0.25, 0.0], [1.25, 0.0]],
            row_ptr: vec![0, 2, 4],
            col: vec![0, 1, 1, 0],
            value: vec![0.0, 1.5, 0.0, 0.5],
        };
        let mut x = vec![1, 0];
        assert_eq!(p.cancel(&mut x, 2.0).pairs, 0);
        assert_eq!(x, [1, 0]);
        assert_eq!(p.cancel(&mut x, 1.9).pairs, 1);
        assert_eq!(x, [0, 1]);
    }
}
