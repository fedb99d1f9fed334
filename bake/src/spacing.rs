//! Local spacings of a map's points: the per-point data of density-adaptive kernels
//! (`otbake_runtime::AdaptiveKernel`, stored as [`otbake_formats::spacing`] codes).
//!
//! The spacing of point `y_i` estimates `(n ρ(y_i))^(−1/d)`, the side of the cube one point
//! occupies where the density is `ρ`, from the distance `r_K` to its `K`-th nearest other point:
//! about `K` points lie in the ball of radius `r_K`, of volume `V_d r_K^d ≈ K / (n ρ)`, so
//!
//! ```text
//! s_i = r_K(i) · (V_d / K)^(1/d)          (V_d the volume of the unit d-ball, K = NEIGHBOURS)
//! ```
//!
//! On the torus (`Wrap::Periodic`) distances are to the nearest image (while `r_K < ½`, which
//! holds unless a map has only a handful of points; beyond, a point may count once per image).
//! The estimate depends only
//! on the point set, not on its order: a one-to-one map's points are the input's samples, so at
//! weights `(1, 0, …)` adaptive kernels do not depend on the solver. Each point's search is
//! independent and exact (a k-d tree with box pruning), so the result is the same for any thread
//! count.

use otbake_formats::torus::fold;
use otbake_formats::tree::{depth, fill_node_boxes, node_count, Node};
use otbake_formats::{Wrap, MAX_DIM};
use rayon::prelude::*;

/// Neighbours behind each spacing: enough that one estimate varies by about 6%
/// (`1/(d·√K)` relative in `r_K`), few enough to follow a narrow lobe.
pub const NEIGHBOURS: usize = 32;

/// The estimator, hashed into every map key: changing it changes the bytes of every map.
pub const RULE: &str = "spacing: r_K (V_d/K)^(1/d), K = 32, nearest image on the torus";

/// Leaf size of the search tree.
const LEAF: u32 = 8;

/// Volume of the unit d-ball for d = 1..=4.
const BALL: [f64; 4] = [
    2.0,
    std::f64::consts::PI,
    4.0 / 3.0 * std::f64::consts::PI,
    4.934_802_2,
];

/// The spacing of every point of `positions` (`n · dim`, any order; periodic lifts are folded
/// onto the torus first). With fewer than `K + 1` points, `K` is `n − 1`; a single point's spacing
/// is 1 (the whole domain).
pub fn spacings(positions: &[f32], dim: usize, wrap: Wrap) -> Vec<f32> {
    let n = positions.len() / dim.max(1);
    if n <= 1 || !(1..=MAX_DIM).contains(&dim) {
        return vec![1.0; n];
    }
    let k = NEIGHBOURS.min(n - 1);
    let factor = (BALL[dim - 1] / k as f64).powf(1.0 / dim as f64);
    let points: Vec<f32> = match wrap {
        Wrap::Clamp => positions.to_vec(),
        Wrap::Periodic => positions.iter().map(|&v| fold(v)).collect(),
    };
    let tree = SearchTree::new(&points, dim);
    (0..n)
        .into_par_iter()
        .with_min_len(1024)
        .map(|i| {
            let q = &points[i * dim..(i + 1) * dim];
            let r2 = tree.kth_distance2(q, k, wrap);
            (f64::from(r2).sqrt() * factor) as f32
        })
        .collect()
}

/// A k-d tree over points (median splits of `crate::tree`) with the box of every node.
struct SearchTree {
    dim: usize,
    depth: u32,
    n: u32,
    /// Points in tree order.
    points: Vec<f32>,
    boxes: Vec<f32>,
}

impl SearchTree {
    fn new(points: &[f32], dim: usize) -> Self {
        let order = crate::tree::tree_order(points, dim, LEAF);
        let sorted = crate::tree::permute(points, dim, &order);
        let n = order.len() as u32;
        let depth = depth(n, LEAF);
        let mut boxes = vec![0.0; node_count(depth) as usize * 2 * dim];
        fill_node_boxes(&sorted, dim, depth, &mut boxes);
        Self {
            dim,
            depth,
            n,
            points: sorted,
            boxes,
        }
    }

    /// Squared distance from `q` to its `k`-th nearest point other than itself (`q` is one of the
    /// points; its own zero distance is the first of the `k + 1` kept). On the torus, to the
    /// nearest images.
    fn kth_distance2(&self, q: &[f32], k: usize, wrap: Wrap) -> f32 {
        // The k + 1 smallest squared distances so far, ascending.
        let mut best = [f32::INFINITY; NEIGHBOURS + 1];
        let best = &mut best[..=k];
        let shifts: &[f32] = match wrap {
            Wrap::Clamp => &[0.0],
            Wrap::Periodic => &[0.0, -1.0, 1.0],
        };
        let d = self.dim;
        let images = shifts.len().pow(d as u32);
        for image in 0..images {
            let mut qs = [0.0f32; MAX_DIM];
            let mut code = image;
            for a in 0..d {
                qs[a] = q[a] + shifts[code % shifts.len()];
                code /= shifts.len();
            }
            self.search(&qs[..d], best);
        }
        best[k]
    }

    /// Adds the points near `q` to `best` (ascending squared distances, fixed length).
    fn search(&self, q: &[f32], best: &mut [f32]) {
        let d = self.dim;
        let last = best.len() - 1;
        let mut stack = Vec::with_capacity(64);
        stack.push(Node::root(self.n));
        while let Some(node) = stack.pop() {
            if node.count == 0 || self.box_distance2(node, q) > best[last] {
                continue;
            }
            if node.level == self.depth {
                for p in self.points[node.range().start * d..node.range().end * d].chunks_exact(d) {
                    let mut r2 = 0.0f32;
                    for a in 0..d {
                        let t = p[a] - q[a];
                        r2 += t * t;
                    }
                    if r2 < best[last] {
                        // Insert in order, dropping the largest.
                        let mut j = last;
                        while j > 0 && best[j - 1] > r2 {
                            best[j] = best[j - 1];
                            j -= 1;
                        }
                        best[j] = r2;
                    }
                }
            } else {
                // The nearer child is searched first (pushed last).
                let (l, r) = node.children();
                let (dl, dr) = (self.box_distance2(l, q), self.box_distance2(r, q));
                if dl <= dr {
                    stack.push(r);
                    stack.push(l);
                } else {
                    stack.push(l);
                    stack.push(r);
                }
            }
        }
    }

    fn box_distance2(&self, node: Node, q: &[f32]) -> f32 {
        let d = self.dim;
        let b = &self.boxes[node.index as usize * 2 * d..][..2 * d];
        let mut d2 = 0.0;
        for a in 0..d {
            let gap = (b[a] - q[a]).max(q[a] - b[d + a]).max(0.0);
            d2 += gap * gap;
        }
        d2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the k-th smallest distance to the other points (nearest images on the torus).
    fn brute(points: &[f32], dim: usize, i: usize, k: usize, wrap: Wrap) -> f32 {
        let q = &points[i * dim..(i + 1) * dim];
        let mut d: Vec<f32> = points
            .chunks_exact(dim)
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, p)| {
                (0..dim)
                    .map(|a| {
                        let t = (p[a] - q[a]).abs();
                        let t = if wrap == Wrap::Periodic {
                            t.min(1.0 - t)
                        } else {
                            t
                        };
                        t * t
                    })
                    .sum::<f32>()
            })
            .collect();
        d.sort_by(f32::total_cmp);
        d[k - 1]
    }

    #[test]
    fn spacings_match_brute_force_neighbours() {
        let mut state = 12345u64;
        let mut unit = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for (dim, n) in [(1, 50), (2, 300), (3, 400), (4, 200), (2, 20)] {
            // Clustered points: half in a small ball, so spacings vary.
            let points: Vec<f32> = (0..n * dim)
                .map(|i| {
                    let u = unit();
                    if (i / dim) % 2 == 0 {
                        0.4 + 0.05 * u
                    } else {
                        u
                    }
                })
                .collect();
            for wrap in [Wrap::Clamp, Wrap::Periodic] {
                let s = spacings(&points, dim, wrap);
                let k = NEIGHBOURS.min(n - 1);
                let factor = (BALL[dim - 1] / k as f64).powf(1.0 / dim as f64);
                for (i, &got) in s.iter().enumerate() {
                    let r2 = brute(&points, dim, i, k, wrap);
                    if wrap == Wrap::Periodic && r2 >= 0.25 {
                        continue; // images may count twice past half a period (documented)
                    }
                    let want = (f64::from(r2).sqrt() * factor) as f32;
                    assert!(
                        (got - want).abs() <= 1e-6 * want.max(1e-6),
                        "dim {dim} n {n} {wrap:?} point {i}: {got} vs {want}"
                    );
                }
            }
        }
        assert_eq!(spacings(&[0.5, 0.5], 2, Wrap::Clamp), vec![1.0]);
        assert!(spacings(&[], 2, Wrap::Clamp).is_empty());
    }

    #[test]
    fn spacing_of_a_uniform_lattice_is_its_step() {
        // A 20³ lattice: the estimate is within 25% of the lattice step 1/20 (r_K on a lattice
        // jumps between shells).
        let m = 20;
        let points: Vec<f32> = (0..m * m * m)
            .flat_map(|c| {
                let f = |i: usize| (i as f32 + 0.5) / m as f32;
                [f(c % m), f((c / m) % m), f(c / (m * m))]
            })
            .collect();
        let s = spacings(&points, 3, Wrap::Periodic);
        for v in s {
            assert!((v * m as f32 - 1.0).abs() < 0.25, "{v}");
        }
    }
}
