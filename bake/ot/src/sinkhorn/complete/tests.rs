//! The completion on its own: from no assignment at all it is the successive shortest paths
//! algorithm, so it must find the exact optimal assignment however small its first margin; and it
//! must stop cleanly, rows left free, when the edges would pass their limit.

use super::*;
use crate::exact::lapjv;
use crate::rng::SplitMix64;
use crate::sinkhorn::hierarchy::Grid;

fn cloud<const D: usize>(n: usize, seed: u64, peaked: bool) -> Vec<[f64; D]> {
    let mut rng = SplitMix64::new(seed);
    (0..n)
        .map(|_| {
            std::array::from_fn(|_| {
                let u = rng.next_f64();
                // A peaked cloud: most points in a narrow lobe, the rest spread out.
                if peaked {
                    0.5 + (u - 0.5).powi(5)
                } else {
                    u
                }
            })
        })
        .collect()
}

struct Case<const D: usize> {
    x: Vec<[f64; D]>,
    ht: Hierarchy<D>,
    level: usize,
    /// A zero target potential, and its cell bounds.
    g: Vec<f64>,
    bnd: Bounds<D, Affine<D>>,
}

impl<const D: usize> Case<D> {
    /// C(x_i, y_j).
    fn cost(&self, i: usize, j: usize) -> f64 {
        cost::sq(Wrap::Clamp, &self.x[i], &self.ht.levels[self.level].pos[j])
    }

    /// Every target, nearest to row i first (ties to the lower index).
    fn nearest(&self, i: usize) -> Vec<u32> {
        let mut near: Vec<u32> = (0..self.x.len() as u32).collect();
        near.sort_by(|&a, &b| {
            self.cost(i, a as usize)
                .total_cmp(&self.cost(i, b as usize))
                .then(a.cmp(&b))
        });
        near
    }

    fn completion(&self, margin: f64, max_edges: usize) -> Completion<'_, D> {
        Completion {
            ht: &self.ht,
            level: self.level,
            x: &self.x,
            g: &self.g,
            wrap: Wrap::Clamp,
            margin,
            max_edges,
            bnd: &self.bnd,
            support: None,
        }
    }
}

fn case<const D: usize>(n: usize, peaked: bool) -> Case<D> {
    let (xs, ys) = (cloud::<D>(n, 7, false), cloud::<D>(n, 8, peaked));
    let grid = Grid::new(&xs, &ys);
    let (hs, ht) = (Hierarchy::new(&xs, &grid, 6), Hierarchy::new(&ys, &grid, 6));
    let level = ht.point_level();
    let g = vec![0.0; n];
    let bnd = kernel::bounds(&ht, level, &g);
    Case {
        x: hs.levels[level].pos.clone(),
        ht,
        level,
        g,
        bnd,
    }
}

fn total<const D: usize>(c: &Case<D>, xs: &[u32]) -> f64 {
    (0..xs.len()).map(|i| c.cost(i, xs[i] as usize)).sum()
}

fn exact_cost<const D: usize>(c: &Case<D>) -> f64 {
    let cost = |i: usize, j: usize| c.cost(i, j);
    let lap = lapjv(c.x.len(), &cost, 1.0);
    (0..c.x.len()).map(|i| c.cost(i, lap.x[i] as usize)).sum()
}

fn assert_permutation(xs: &[u32], ys: &[u32]) {
    for (i, &j) in xs.iter().enumerate() {
        assert_ne!(j, NONE, "row {i} is unassigned");
        assert_eq!(ys[j as usize], i as u32, "row {i} and column {j} disagree");
    }
}

fn complete_all<const D: usize>(c: &Case<D>, margin: f64) -> (Vec<u32>, Completed) {
    let n = c.x.len();
    let completion = c.completion(margin, usize::MAX);
    let (mut xs, mut ys, mut v) = (vec![NONE; n], vec![NONE; n], vec![0.0; n]);
    let free: Vec<usize> = (0..n).collect();
    let done = completion.run(&free, &mut xs, &mut ys, &mut v);
    assert_permutation(&xs, &ys);
    (xs, done)
}

#[test]
fn from_nothing_it_is_the_exact_assignment() {
    for (peaked, margin) in [(false, 1e-9), (true, 1e-9), (false, 1e-2)] {
        let c = case::<2>(400, peaked);
        let (xs, done) = complete_all(&c, margin);
        assert_eq!(done.paths, 400);
        let (got, want) = (total(&c, &xs), exact_cost(&c));
        assert!(
            (got - want).abs() <= 1e-9 * want,
            "peaked {peaked}, margin {margin}: {got} vs exact {want}"
        );
        // The margin had to grow from 1e-9 (the first paths need none: free columns at distance 0).
        if margin < 1e-6 {
            assert!(done.widest > 1.0, "{done:?}");
        }
    }
}

#[test]
fn three_dimensions_too() {
    let c = case::<3>(300, true);
    let (xs, _) = complete_all(&c, 1e-6);
    let (got, want) = (total(&c, &xs), exact_cost(&c));
    assert!((got - want).abs() <= 1e-9 * want, "{got} vs exact {want}");
}

#[test]
fn past_the_edge_limit_rows_stay_free() {
    let c = case::<2>(300, true);
    let n = c.x.len();
    let completion = c.completion(1e-9, 50);
    let (mut xs, mut ys, mut v) = (vec![NONE; n], vec![NONE; n], vec![0.0; n]);
    let free: Vec<usize> = (0..n).collect();
    let done = completion.run(&free, &mut xs, &mut ys, &mut v);
    let placed = xs.iter().filter(|&&j| j != NONE).count();
    assert_eq!(placed, done.paths as usize);
    assert!(placed < n, "{done:?}");
    assert!(done.edges <= 50);
    // What was placed is still a matching.
    for (i, &j) in xs.iter().enumerate() {
        if j != NONE {
            assert_eq!(ys[j as usize], i as u32);
        }
    }
}

/// The auction on a support with holes (each row keeps only its 3 nearest targets, so a peaked
/// target leaves rows with too few columns between them), its lists and edges limited to
/// `max_edges`: the matching, its cost and the exact assignment's.
fn auction_with_holes(max_edges: usize) -> (crate::auction::Matching, f64, f64) {
    use crate::auction::{auction, Graph};
    let c = case::<2>(400, true);
    let n = c.x.len();
    let sq = |i: usize, j: usize| c.cost(i, j);
    let mut row_ptr = vec![0usize];
    let mut col = Vec::new();
    for i in 0..n {
        col.extend_from_slice(&c.nearest(i)[..3]);
        row_ptr.push(col.len());
    }
    let f: Vec<f64> = (0..n).map(|i| sq(i, col[row_ptr[i]] as usize)).collect();
    let g = &c.g;
    let graph = Graph {
        row_ptr: &row_ptr,
        col: &col,
        cols: n,
        cost: |i: usize, j: usize| sq(i, j) - f[i] - g[j],
        pair_cost: None,
        sorted: false,
        certified: 1e-4,
    };
    let completion = c.completion(1e-4, max_edges);
    let mut beyond = Beyond::new(&completion, &f);
    let mut v = vec![0.0; n];
    let m = auction(&graph, &mut v, 1e-2, 1e-9, 4.0, 2.0, &mut beyond);
    assert_eq!(m.unassigned, 0, "{:?}", beyond.done);
    let mut ys = vec![NONE; n];
    for (i, &j) in m.x.iter().enumerate() {
        ys[j as usize] = i as u32;
    }
    assert_permutation(&m.x, &ys);
    let (got, want) = (total(&c, &m.x), exact_cost(&c));
    (m, got, want)
}

/// The auction on a support with holes ends with the exact assignment's cost: the rows past what
/// the support certifies are widened, and nothing is left unmatched.
#[test]
fn the_auction_beyond_a_support_with_holes_is_optimal() {
    let (m, got, want) = auction_with_holes(usize::MAX);
    assert!(m.widened > 0, "the holes were widened: {m:?}");
    // Within n·ε_end of the best, and the best is the exact assignment's.
    assert!(
        got - want <= m.x.len() as f64 * 1e-9 + 1e-12 * want,
        "{got} vs exact {want}"
    );
}

/// Lists a row replaced do not count against the lists' limit: with a limit a little above the
/// most columns the rows' newest lists held at once, well below what all the lists made held (a
/// limit on those had parked rows), no row is parked for it, and the result is the same matching.
#[test]
fn replaced_lists_leave_room_for_later_rows() {
    let (all, ..) = auction_with_holes(usize::MAX);
    let limit = all.wide_held + all.wide_held / 8;
    assert!(2 * all.wide_cols > 3 * limit, "{all:?}");
    let (m, got, want) = auction_with_holes(limit);
    assert_eq!(m.parked.refused, 0, "{m:?}");
    assert_eq!(m.x, all.x);
    assert!(got - want <= m.x.len() as f64 * 1e-9 + 1e-12 * want);
}

/// With the auction's support given (each row's 12 nearest targets, certified up to the nearest
/// left-out target of any row) the paths read the rows the support covers instead of searching
/// them, and the result is still the exact assignment.
#[test]
fn rows_the_support_certifies_are_read_and_the_result_is_exact() {
    let c = case::<2>(400, true);
    let n = c.x.len();
    let sq = |i: usize, j: usize| c.cost(i, j);
    let (mut row_ptr, mut col, mut f) = (vec![0usize], Vec::new(), Vec::new());
    let mut certified = f64::INFINITY;
    for i in 0..n {
        let near = c.nearest(i);
        let fi = sq(i, near[0] as usize);
        certified = certified.min(sq(i, near[12] as usize) - fi);
        f.push(fi);
        let mut own = near[..12].to_vec();
        own.sort_unstable();
        col.extend_from_slice(&own);
        row_ptr.push(col.len());
    }
    let completion = Completion {
        support: Some(Support {
            row_ptr: &row_ptr,
            col: &col,
            f: &f,
            certified: certified * 0.999,
        }),
        ..c.completion(1e-9, usize::MAX)
    };
    let (mut xs, mut ys, mut v) = (vec![NONE; n], vec![NONE; n], vec![0.0; n]);
    let free: Vec<usize> = (0..n).collect();
    let done = completion.run(&free, &mut xs, &mut ys, &mut v);
    assert_permutation(&xs, &ys);
    assert!(done.read > 0, "{done:?}");
    let (got, want) = (total(&c, &xs), exact_cost(&c));
    assert!((got - want).abs() <= 1e-9 * want, "{got} vs exact {want}");
}
