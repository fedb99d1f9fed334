//! The multiscale hierarchy of one point cloud: nested grid cells, coarsest first.
//!
//! Points are sorted once by their Morton code in a grid over the common bounding box of both clouds
//! (side `S`, `BITS` bits per axis). The occupied cells of side `S / 2^ℓ` are then runs of equal code
//! prefixes, so every level is a partition of the sorted points into contiguous ranges, each level
//! refines the previous one, and a cell's children are a contiguous range of the next level. The last
//! level holds the points themselves (in Morton order). Each cell carries its mass, the centroid of its
//! points (the cluster's position in the coarse problem) and the tight bounding box of its points,
//! which contains every descendant's centroid: the bound the kernel truncation prunes with.
//!
//! Both clouds use the same grid, so level ℓ means the same cell size on both sides.

use rayon::prelude::*;

/// One level: a partition of the (Morton-sorted) points into cells.
#[derive(Clone, Debug)]
pub(super) struct Level<const D: usize> {
    /// Cell side of this level (the point level reports the side of the finest cell level).
    pub side: f64,
    /// Position of each cell (centroid of its points).
    pub pos: Vec<[f64; D]>,
    /// Mass of each cell (its number of points / n).
    pub mass: Vec<f64>,
    /// Tight bounding box of each cell's points (empty on the point level).
    pub lo: Vec<[f64; D]>,
    pub hi: Vec<[f64; D]>,
    /// Cells `child[c]..child[c + 1]` of the next level are the children of cell `c` (empty on the
    /// point level).
    pub child: Vec<u32>,
    /// The cell of the previous level containing each cell (all 0 on level 0).
    pub parent: Vec<u32>,
}

impl<const D: usize> Level<D> {
    pub fn len(&self) -> usize {
        self.pos.len()
    }
}

/// A cloud's levels, coarsest (one cell) first, points last.
#[derive(Clone, Debug)]
pub(super) struct Hierarchy<const D: usize> {
    /// `order[k]` is the original index of the k-th point in Morton order.
    pub order: Vec<u32>,
    pub levels: Vec<Level<D>>,
}

/// The grid both clouds share: origin and side of the cube that holds them.
#[derive(Clone, Copy, Debug)]
pub(super) struct Grid<const D: usize> {
    pub origin: [f64; D],
    pub side: f64,
}

/// Morton bits per axis: as many as fit in a u64.
pub(super) const fn bits(d: usize) -> u32 {
    let b = 64 / d as u32;
    if b > 30 {
        30
    } else {
        b
    }
}

impl<const D: usize> Grid<D> {
    /// The cube over the bounding box of both clouds.
    pub fn new(a: &[[f64; D]], b: &[[f64; D]]) -> Self {
        let mut lo = [f64::INFINITY; D];
        let mut hi = [f64::NEG_INFINITY; D];
        for p in a.iter().chain(b) {
            for k in 0..D {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let side = (0..D).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        Self { origin: lo, side }
    }

    /// Morton code of a point (cells of side `side / 2^bits`): the axes' bits interleaved from
    /// the most significant down, axis 0 first in each group.
    fn code(&self, p: &[f64; D]) -> u64 {
        let b = bits(D);
        let cells = (1u64 << b) as f64;
        let max = (1u64 << b) - 1;
        let mut q = [0u64; D];
        for k in 0..D {
            let t = if self.side > 0.0 {
                (p[k] - self.origin[k]) / self.side * cells
            } else {
                0.0
            };
            q[k] = (t.max(0.0) as u64).min(max);
        }
        interleave(&q)
    }
}

/// The bits of `q` (each below 2^bits(D)) interleaved, axis 0 the most significant of each group:
/// by spreading masks in 2D and 3D (the solve's cases: a bit loop was most of sorting the points),
/// bit by bit otherwise.
fn interleave<const D: usize>(q: &[u64; D]) -> u64 {
    match D {
        2 => (spread2(q[0]) << 1) | spread2(q[1]),
        3 => (spread3(q[0]) << 2) | (spread3(q[1]) << 1) | spread3(q[2]),
        _ => interleave_bits(q),
    }
}

fn interleave_bits<const D: usize>(q: &[u64; D]) -> u64 {
    let mut code = 0u64;
    for bit in (0..bits(D)).rev() {
        for qk in q.iter() {
            code = (code << 1) | ((qk >> bit) & 1);
        }
    }
    code
}

/// The low 32 bits of `x` at the even bit positions.
fn spread2(x: u64) -> u64 {
    let mut x = x & 0xffff_ffff;
    x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

/// The low 21 bits of `x` at every third bit position.
fn spread3(x: u64) -> u64 {
    let mut x = x & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    (x | (x << 2)) & 0x1249_2492_4924_9249
}

/// A cloud's points by Morton code: (code, index), ascending (a strict total order, so the result
/// does not depend on the sort's splits). Sorted once and shared by the plan's cell counts and
/// the hierarchy.
pub(super) struct Sorted(Vec<(u64, u32)>);

impl Sorted {
    pub fn new<const D: usize>(points: &[[f64; D]], grid: &Grid<D>) -> Self {
        let mut keyed: Vec<(u64, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| (grid.code(p), i as u32))
            .collect();
        keyed.par_sort_unstable();
        Self(keyed)
    }
}

impl<const D: usize> Hierarchy<D> {
    /// Sorts `points` in Morton order and builds the cell levels `0..=max_level` plus the point
    /// level.
    #[cfg(test)]
    pub fn new(points: &[[f64; D]], grid: &Grid<D>, max_level: u32) -> Self {
        Self::from_sorted(points, Sorted::new(points, grid), grid, max_level)
    }

    /// [`Hierarchy::new`] from the points' [`Sorted`] order.
    pub fn from_sorted(
        points: &[[f64; D]],
        sorted: Sorted,
        grid: &Grid<D>,
        max_level: u32,
    ) -> Self {
        let n = points.len();
        let keyed = sorted.0;
        let order: Vec<u32> = keyed.par_iter().map(|&(_, i)| i).collect();
        let sorted: Vec<[f64; D]> = order.par_iter().map(|&i| points[i as usize]).collect();

        // Cell starts (indices into the sorted points) of every cell level, the levels at once.
        let b = bits(D);
        let starts: Vec<Vec<u32>> = (0..=max_level)
            .into_par_iter()
            .map(|level| {
                let shift = D as u32 * (b - level);
                let prefix = |k: usize| {
                    if shift >= 64 {
                        0
                    } else {
                        keyed[k].0 >> shift
                    }
                };
                let mut s = vec![0u32];
                s.extend(
                    (1..n)
                        .filter(|&k| prefix(k) != prefix(k - 1))
                        .map(|k| k as u32),
                );
                s
            })
            .collect();

        let mut levels: Vec<Level<D>> = starts
            .par_iter()
            .enumerate()
            .map(|(level, s)| {
                let side = grid.side / (1u64 << level) as f64;
                let mut lvl = cell_level(&sorted, s, n, side);
                // Children: the next level's cells starting inside this cell's range (nested
                // ranges); the last cell level's children are its points.
                lvl.child = match starts.get(level + 1) {
                    Some(next) => child_ranges(s, next, n),
                    None => s.iter().copied().chain([n as u32]).collect(),
                };
                lvl
            })
            .collect();
        // Parents from the children ranges.
        let parents: Vec<Vec<u32>> = (1..levels.len())
            .into_par_iter()
            .map(|l| parents_of(&levels[l - 1].child, levels[l].len()))
            .collect();
        for (l, parent) in (1..levels.len()).zip(parents) {
            levels[l].parent = parent;
        }
        let finest_side = levels.last().map_or(grid.side, |l| l.side);
        let point_parent = match levels.last() {
            Some(last) => parents_of(&last.child, n),
            None => vec![0; n],
        };
        let inv = 1.0 / n as f64;
        // The point level's boxes would be the points themselves: the searches never read them.
        levels.push(Level {
            side: finest_side,
            pos: sorted,
            mass: vec![inv; n],
            lo: Vec::new(),
            hi: Vec::new(),
            child: Vec::new(),
            parent: point_parent,
        });
        Self { order, levels }
    }

    /// Index of the point level.
    pub fn point_level(&self) -> usize {
        self.levels.len() - 1
    }
}

/// Centroid, mass and box of each cell `starts[c]..starts[c + 1]` of the sorted points.
fn cell_level<const D: usize>(
    sorted: &[[f64; D]],
    starts: &[u32],
    n: usize,
    side: f64,
) -> Level<D> {
    let m = starts.len();
    type Cell<const D: usize> = ([f64; D], f64, [f64; D], [f64; D]);
    let cells: Vec<Cell<D>> = (0..m)
        .into_par_iter()
        .map(|c| {
            let a = starts[c] as usize;
            let b = starts.get(c + 1).map_or(n, |&e| e as usize);
            let mut sum = [0.0; D];
            let mut lo = [f64::INFINITY; D];
            let mut hi = [f64::NEG_INFINITY; D];
            for p in &sorted[a..b] {
                for k in 0..D {
                    sum[k] += p[k];
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
            let count = (b - a) as f64;
            let mut pos = [0.0; D];
            for k in 0..D {
                // Clamp: the rounded mean of points can leave their box by an ulp.
                pos[k] = (sum[k] / count).clamp(lo[k], hi[k]);
            }
            (pos, count / n as f64, lo, hi)
        })
        .collect();
    Level {
        side,
        pos: cells.iter().map(|c| c.0).collect(),
        mass: cells.iter().map(|c| c.1).collect(),
        lo: cells.iter().map(|c| c.2).collect(),
        hi: cells.iter().map(|c| c.3).collect(),
        child: Vec::new(),
        parent: vec![0; m],
    }
}

/// For nested partitions given by their start indices, the range of `next` cells inside each cell.
fn child_ranges(starts: &[u32], next: &[u32], n: usize) -> Vec<u32> {
    let mut child = Vec::with_capacity(starts.len() + 1);
    let mut j = 0usize;
    for c in 0..starts.len() {
        child.push(j as u32);
        let end = starts.get(c + 1).map_or(n as u32, |&e| e);
        while j < next.len() && next[j] < end {
            j += 1;
        }
    }
    child.push(next.len() as u32);
    child
}

/// Inverts child ranges into a parent index per child, in parallel over fixed blocks of children
/// (each block finds its first parent by bisection, then walks the ranges).
fn parents_of(child: &[u32], len: usize) -> Vec<u32> {
    const BLOCK: usize = 1 << 14;
    let mut parent = vec![0u32; len];
    parent
        .par_chunks_mut(BLOCK)
        .enumerate()
        .for_each(|(b, out)| {
            let first = b * BLOCK;
            // The cell whose range holds `first`: the last c with child[c] <= first.
            let mut c = child
                .partition_point(|&s| s as usize <= first)
                .saturating_sub(1);
            for (k, p) in out.iter_mut().enumerate() {
                while c + 2 < child.len() && child[c + 1] as usize <= first + k {
                    c += 1;
                }
                *p = c as u32;
            }
        });
    parent
}

/// What the plan needs to know of one level of a cloud before the hierarchy is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct LevelCount {
    /// Occupied cells.
    pub cells: usize,
    /// Ordered pairs of distinct points sharing a cell, Σ n_c (n_c − 1) over the cells: divided
    /// by n, how many other points a typical point's cell holds (a point-weighted count, which a
    /// dense lobe dominates however few cells it fills; for a uniform cloud it is the mean count
    /// per cell, without the +1 bias of Σ n_c²).
    pub pairs: f64,
}

impl LevelCount {
    /// Other points in a typical point's cell: `pairs / n`.
    pub fn shared(&self, n: usize) -> f64 {
        self.pairs / n.max(1) as f64
    }
}

/// The occupied cells and the points sharing them of every level `0..=bits(D)` (for choosing the
/// final blur and the finest cell level).
#[cfg(test)]
pub(super) fn cell_counts<const D: usize>(points: &[[f64; D]], grid: &Grid<D>) -> Vec<LevelCount> {
    level_counts::<D>(&Sorted::new(points, grid))
}

/// [`cell_counts`] from the points' [`Sorted`] order.
pub(super) fn level_counts<const D: usize>(sorted: &Sorted) -> Vec<LevelCount> {
    let codes = &sorted.0;
    let b = bits(D);
    (0..=b)
        .into_par_iter()
        .map(|level| {
            let shift = D as u32 * (b - level);
            let prefix = |c: u64| if shift >= 64 { 0 } else { c >> shift };
            // Runs of equal prefixes are the cells; integer sums are exact in any order.
            let mut cells = 0usize;
            let mut pairs = 0u128;
            let mut run = 0u128;
            for (k, &(c, _)) in codes.iter().enumerate() {
                if k > 0 && prefix(c) != prefix(codes[k - 1].0) {
                    cells += 1;
                    pairs += run * (run - 1);
                    run = 0;
                }
                run += 1;
            }
            if run > 0 {
                cells += 1;
                pairs += run * (run - 1);
            }
            LevelCount {
                cells,
                pairs: pairs as f64,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spreading_masks_interleave_as_the_bit_loop() {
        let mut rng = crate::rng::SplitMix64::new(3);
        let mut next = move || rng.next_u64();
        for _ in 0..10_000 {
            let q2 = [next() >> 34, next() >> 34];
            assert_eq!(interleave(&q2), interleave_bits(&q2), "{q2:?}");
            let q3 = [next() >> 43, next() >> 43, next() >> 43];
            assert_eq!(interleave(&q3), interleave_bits(&q3), "{q3:?}");
        }
        let top2 = [(1u64 << bits(2)) - 1; 2];
        assert_eq!(interleave(&top2), interleave_bits(&top2));
        let top3 = [(1u64 << bits(3)) - 1; 3];
        assert_eq!(interleave(&top3), interleave_bits(&top3));
    }

    /// The parents found block by block are those of the ranges, over many blocks and ranges of
    /// every length from 1 (a range cut by a block's edge included).
    #[test]
    fn parents_invert_child_ranges_across_blocks() {
        let mut rng = crate::rng::SplitMix64::new(7);
        let mut child = vec![0u32];
        while (*child.last().unwrap() as usize) < 100_000 {
            let len = 1 + (rng.next_u64() % 40) as u32;
            child.push(child.last().unwrap() + len);
        }
        let len = *child.last().unwrap() as usize;
        let parent = parents_of(&child, len);
        for c in 0..child.len() - 1 {
            for p in &parent[child[c] as usize..child[c + 1] as usize] {
                assert_eq!(*p as usize, c);
            }
        }
    }

    #[test]
    fn levels_nest_and_conserve_mass() {
        let pts: Vec<[f64; 2]> = (0..500)
            .map(|i| {
                let t = i as f64 * 0.618_033_988_75;
                [t.fract(), (t * 7.3).fract().powi(2)]
            })
            .collect();
        let grid = Grid::new(&pts, &pts);
        let h = Hierarchy::new(&pts, &grid, 5);
        assert_eq!(h.levels.len(), 7);
        assert_eq!(h.levels[0].len(), 1);
        for (l, lvl) in h.levels.iter().enumerate() {
            let mass: f64 = lvl.mass.iter().sum();
            assert!((mass - 1.0).abs() < 1e-12, "level {l} mass {mass}");
            if l + 1 < h.levels.len() {
                let next = &h.levels[l + 1];
                assert_eq!(*lvl.child.last().unwrap() as usize, next.len());
                for c in 0..lvl.len() {
                    let m: f64 = (lvl.child[c]..lvl.child[c + 1])
                        .map(|k| next.mass[k as usize])
                        .sum();
                    assert!((m - lvl.mass[c]).abs() < 1e-12);
                    for k in lvl.child[c]..lvl.child[c + 1] {
                        assert_eq!(next.parent[k as usize] as usize, c);
                        for a in 0..2 {
                            assert!(next.pos[k as usize][a] >= lvl.lo[c][a]);
                            assert!(next.pos[k as usize][a] <= lvl.hi[c][a]);
                        }
                    }
                }
            }
        }
        let mut seen = h.order.clone();
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(i, &o)| i as u32 == o));
        let counts = cell_counts(&pts, &grid);
        for (l, count) in counts.iter().enumerate().take(6) {
            assert_eq!(count.cells, h.levels[l].len());
            // Σ n_c (n_c − 1) from the level's masses (n_c = mass · n).
            let pairs: f64 = h.levels[l]
                .mass
                .iter()
                .map(|m| (m * 500.0).round())
                .map(|c| c * (c - 1.0))
                .sum();
            assert_eq!(count.pairs, pairs, "level {l}");
        }
        assert_eq!(counts[0].pairs, 500.0 * 499.0);
    }
}
