//! Lower bounds of a potential over the cells of a hierarchy: what lets the searches prune a cell
//! without visiting its points.

use super::super::hierarchy::Hierarchy;
use rayon::prelude::*;

/// Lower bounds M of h = |y|² − potential over the descendants (at the search level) of every
/// cell above it, one per cell: for a query x, C(x, y_j) − pot_j = |x|² + h_j − 2x·y_j is then at
/// least |x|² + min over the cell's box of M(y) − 2x·y.
///
/// Two kinds ([`Minorant`]): an [`Affine`] one, whose slack grows with the *curvature* of h over
/// the cell rather than its gradient (so cells far from the minimizer are pruned near the top of
/// the hierarchy even where the potential varies a lot), and a [`Quad`]ratic one, which follows
/// that curvature too. The grouped searches bound a box of queries, where the affine form has a
/// closed form; one query at a time, the quadratic form prunes more.
pub(in crate::sinkhorn) struct Bounds<const D: usize, M> {
    /// Per level above the search level, each cell's minorant.
    pub cells: Vec<Vec<M>>,
    /// Each cell's descendants on the search level, a range (cells are in Morton order).
    pub desc: Vec<Vec<(u32, u32)>>,
}

/// A lower bound of h over a cell's descendants, fitted to them.
pub(in crate::sinkhorn) trait Minorant<const D: usize>:
    Send + Sync + Sized
{
    /// A minorant of `h` over points `y` (any fit is valid; a good one is tight).
    fn fit(y: &[[f64; D]], h: &[f64]) -> Self;
    /// h ≥ `alpha`, with no slope: valid for any points whose h is at least `alpha`.
    fn flat(alpha: f64) -> Self;
    /// The lower bound of C(x, y_j) − pot_j over the cell's descendants, for a query x
    /// (x2 = |x|²) and the cell's box `lo`, `hi`.
    fn bound(&self, x: &[f64; D], x2: f64, lo: &[f64; D], hi: &[f64; D]) -> f64;
}

/// h_j ≥ α + β·y_j, β fitted by least squares (tight to second order) and α the exact minimum of
/// h_j − β·y_j.
#[derive(Clone, Copy, Debug)]
pub(in crate::sinkhorn) struct Affine<const D: usize> {
    pub beta: [f64; D],
    pub alpha: f64,
}

impl<const D: usize> Minorant<D> for Affine<D> {
    fn fit(y: &[[f64; D]], h: &[f64]) -> Self {
        let (beta, alpha) = affine_minorant(y, h);
        Affine { beta, alpha }
    }

    fn flat(alpha: f64) -> Self {
        Affine {
            beta: [0.0; D],
            alpha,
        }
    }

    #[inline]
    fn bound(&self, x: &[f64; D], x2: f64, lo: &[f64; D], hi: &[f64; D]) -> f64 {
        let mut s = x2 + self.alpha;
        let mut mag = x2.abs() + self.alpha.abs();
        for k in 0..D {
            let c = self.beta[k] - 2.0 * x[k];
            let t = (c * lo[k]).min(c * hi[k]);
            s += t;
            mag += t.abs();
        }
        // Rounding slack: the bound must never exceed the true value, or a pair at the threshold
        // could be pruned.
        s - mag * 1e-13
    }
}

/// h_j ≥ α + β·(y_j − m) + Σ_k q_k (y_jk − m_k)² about the cell's centroid m, with q ≥ 0.
///
/// h is close to convex (|y|² less a c-concave potential: exactly convex for the hard one), so over
/// a cell it is a bowl, and an affine bound gives away the bowl's depth: about the curvature times
/// the squared half-width, several ε on the cells a search opens. A separable quadratic keeps it,
/// and its minimum over the box still has a closed form axis by axis. One query at a time the 1M
/// cow's row minima searched 32% less time with it (D156); bounding a box of queries with it cost
/// more than it pruned.
#[derive(Clone, Copy, Debug)]
pub(in crate::sinkhorn) struct Quad<const D: usize> {
    pub alpha: f64,
    pub beta: [f64; D],
    pub q: [f64; D],
    pub mid: [f64; D],
}

impl<const D: usize> Minorant<D> for Quad<D> {
    /// Least squares of h ≈ a + β·(y − m) + Σ q_k (y_k − m_k)² (2D + 1 unknowns), q clamped at 0,
    /// then α = min(h − β·(y − m) − Σ q_k (y_k − m_k)²).
    fn fit(y: &[[f64; D]], h: &[f64]) -> Self {
        let step = fit_step(y.len());
        let (ys, hs) = (y.iter().step_by(step), h.iter().step_by(step));
        let n = ys.len() as f64;
        let mut mid = [0.0; D];
        for p in ys.clone() {
            for k in 0..D {
                mid[k] += p[k];
            }
        }
        mid.iter_mut().for_each(|v| *v /= n);
        // Features 1, d_k, d_k² (d = y − m), at most 9 of them (D ≤ 4); the upper triangle of
        // the normal equations is accumulated and mirrored.
        let dim = 2 * D + 1;
        let mut a = [[0.0f64; MAX_FEATURES]; MAX_FEATURES];
        let mut r = [0.0f64; MAX_FEATURES];
        let mut phi = [0.0f64; MAX_FEATURES];
        phi[0] = 1.0;
        for (p, &v) in ys.zip(hs) {
            for k in 0..D {
                let d = p[k] - mid[k];
                phi[1 + k] = d;
                phi[1 + D + k] = d * d;
            }
            for i in 0..dim {
                r[i] += phi[i] * v;
                for j in i..dim {
                    a[i][j] += phi[i] * phi[j];
                }
            }
        }
        for i in 1..dim {
            let (top, bottom) = a.split_at_mut(i);
            for (j, row) in top.iter().enumerate() {
                bottom[0][j] = row[i];
            }
        }
        let x = solve_spd_dyn(&mut a, &mut r, dim);
        let beta: [f64; D] = std::array::from_fn(|k| x[1 + k]);
        let q: [f64; D] = std::array::from_fn(|k| x[1 + D + k].max(0.0));
        let alpha = y
            .iter()
            .zip(h)
            .map(|(p, &v)| {
                v - (0..D)
                    .map(|k| {
                        let d = p[k] - mid[k];
                        beta[k] * d + q[k] * d * d
                    })
                    .sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min);
        Quad {
            alpha,
            beta,
            q,
            mid,
        }
    }

    fn flat(alpha: f64) -> Self {
        Quad {
            alpha,
            beta: [0.0; D],
            q: [0.0; D],
            mid: [0.0; D],
        }
    }

    /// The lower bound of C(x, y_j) − pot_j over a cell's descendants: |x|² + α + Σ_k the minimum
    /// over t_k = y_k − m_k in the box of (β_k − 2x_k) t_k + q_k t_k² − 2x_k m_k (the parabola's
    /// vertex, clamped to the box).
    #[inline]
    fn bound(&self, x: &[f64; D], x2: f64, lo: &[f64; D], hi: &[f64; D]) -> f64 {
        let mut s = x2 + self.alpha;
        let mut mag = x2.abs() + self.alpha.abs();
        for k in 0..D {
            let (m, q) = (self.mid[k], self.q[k]);
            let c = self.beta[k] - 2.0 * x[k];
            let (tl, th) = (lo[k] - m, hi[k] - m);
            let t = if q > 0.0 {
                (-0.5 * c / q).clamp(tl, th)
            } else if c > 0.0 {
                tl
            } else {
                th
            };
            let (lin, sq, off) = (c * t, q * t * t, 2.0 * x[k] * m);
            s += lin + sq - off;
            mag += lin.abs() + sq + off.abs();
        }
        // Rounding slack, as in `Affine::bound`.
        s - mag * 1e-13
    }
}

/// Points a minorant's least squares reads at most: a larger cell's fit reads every
/// `fit_step`-th of its descendants (in Morton order, so spread over the whole cell). The fit only
/// has to be close, since α is then the exact minimum over every point, so the bound stays valid;
/// the whole fit read every point of a large cell two or three times on every level.
const FIT_POINTS: usize = 256;

fn fit_step(len: usize) -> usize {
    len.div_ceil(FIT_POINTS).max(1)
}

/// The most descendants of a cell whose children the searches ([`super::search`]'s bucket) and
/// the walk ([`super::pattern`]'s leaf) never bound: both evaluate such a cell's points. A larger
/// value here than theirs only fits more cells; a smaller one would leave cells they bound flat
/// (valid, looser).
pub(super) const OPENED: u32 = 64;

/// Most least-squares features of a [`Quad`] fit: 2D + 1 for D ≤ 4.
const MAX_FEATURES: usize = 9;

/// Every cell's minorant of h = |y|² − `pot` over its descendants on `level`.
///
/// The searches and the walk bound a cell only when they open its parent, and they open only
/// cells of more than [`OPENED`] descendants (smaller ones have their points evaluated): a cell
/// whose parent is smaller is never bounded, and gets the flat minorant (β = 0, α = min h), valid
/// if ever read, for one pass over its points instead of a fit. Those are most cells (the levels
/// just above the points), and their fits were half of every `bounds`.
pub(in crate::sinkhorn) fn bounds<const D: usize, M: Minorant<D>>(
    h: &Hierarchy<D>,
    level: usize,
    pot: &[f64],
) -> Bounds<D, M> {
    let pos = &h.levels[level].pos;
    let hv: Vec<f64> = pos
        .par_iter()
        .zip(pot)
        .map(|(y, p)| y.iter().map(|v| v * v).sum::<f64>() - p)
        .collect();
    // Descendant ranges (into the search level) of every cell, from the level above the search
    // level up.
    let mut desc: Vec<Vec<(u32, u32)>> = vec![Vec::new(); level];
    for l in (0..level).rev() {
        let child = &h.levels[l].child;
        let below = desc.get(l + 1).filter(|_| l + 1 < level);
        desc[l] = (0..h.levels[l].len())
            .map(|c| match below {
                None => (child[c], child[c + 1]),
                Some(b) => (b[child[c] as usize].0, b[child[c + 1] as usize - 1].1),
            })
            .collect();
    }
    let cells: Vec<Vec<M>> = (0..level)
        .map(|l| {
            let parent = &h.levels[l].parent;
            desc[l]
                .par_iter()
                .enumerate()
                .map(|(c, &(a, b))| {
                    let (y, hc) = (&pos[a as usize..b as usize], &hv[a as usize..b as usize]);
                    let opened = l == 0 || {
                        let (pa, pb) = desc[l - 1][parent[c] as usize];
                        pb - pa > OPENED
                    };
                    if opened {
                        M::fit(y, hc)
                    } else {
                        M::flat(hc.iter().copied().fold(f64::INFINITY, f64::min))
                    }
                })
                .collect()
        })
        .collect();
    Bounds { cells, desc }
}

/// Least-squares slope β of h over points y (0 where the points span no direction; fitted to
/// every [`fit_step`]-th point of a large cell) and α = min(h − β·y) over all of them.
pub(super) fn affine_minorant<const D: usize>(y: &[[f64; D]], h: &[f64]) -> ([f64; D], f64) {
    let step = fit_step(y.len());
    let (ys, hs) = (y.iter().step_by(step), h.iter().step_by(step));
    let n = ys.len() as f64;
    let mut my = [0.0; D];
    let mut mh = 0.0;
    for (p, &v) in ys.clone().zip(hs.clone()) {
        for k in 0..D {
            my[k] += p[k];
        }
        mh += v;
    }
    my.iter_mut().for_each(|v| *v /= n);
    mh /= n;
    // Normal equations A β = r, A = Σ (y−ȳ)(y−ȳ)ᵀ, r = Σ (y−ȳ)(h−h̄).
    let mut a = [[0.0; D]; D];
    let mut r = [0.0; D];
    for (p, &v) in ys.zip(hs) {
        let d: [f64; D] = std::array::from_fn(|k| p[k] - my[k]);
        for i in 0..D {
            r[i] += d[i] * (v - mh);
            for j in 0..D {
                a[i][j] += d[i] * d[j];
            }
        }
    }
    let beta = solve_spd(a, r);
    let alpha = y
        .iter()
        .zip(h)
        .map(|(p, &v)| v - (0..D).map(|k| beta[k] * p[k]).sum::<f64>())
        .fold(f64::INFINITY, f64::min);
    (beta, alpha)
}

/// Solves A x = r for a symmetric positive semi-definite A ([`solve_spd_dyn`]).
fn solve_spd<const D: usize>(a: [[f64; D]; D], r: [f64; D]) -> [f64; D] {
    if D > MAX_FEATURES {
        return [0.0; D];
    }
    let mut a9 = [[0.0; MAX_FEATURES]; MAX_FEATURES];
    let mut r9 = [0.0; MAX_FEATURES];
    for k in 0..D {
        a9[k][..D].copy_from_slice(&a[k]);
        r9[k] = r[k];
    }
    let x = solve_spd_dyn(&mut a9, &mut r9, D);
    std::array::from_fn(|k| x[k])
}

/// Solves the first `dim` equations of a symmetric positive semi-definite system by Gaussian
/// elimination, zeroing the unknowns of tiny pivots (directions the points do not span); all zero
/// if anything is not finite.
fn solve_spd_dyn(
    a: &mut [[f64; MAX_FEATURES]; MAX_FEATURES],
    r: &mut [f64; MAX_FEATURES],
    dim: usize,
) -> [f64; MAX_FEATURES] {
    let scale = (0..dim).map(|k| a[k][k]).fold(0.0, f64::max);
    let tiny = scale * 1e-12;
    let mut ok = [true; MAX_FEATURES];
    for k in 0..dim {
        if a[k][k] <= tiny {
            ok[k] = false;
            continue;
        }
        for i in k + 1..dim {
            let f = a[i][k] / a[k][k];
            let (top, bottom) = a.split_at_mut(i);
            for (x, y) in bottom[0][k..dim].iter_mut().zip(&top[k][k..dim]) {
                *x -= f * y;
            }
            r[i] -= f * r[k];
        }
    }
    let mut x = [0.0; MAX_FEATURES];
    for k in (0..dim).rev() {
        if !ok[k] {
            continue;
        }
        let mut s = r[k];
        for j in k + 1..dim {
            s -= a[k][j] * x[j];
        }
        x[k] = s / a[k][k];
    }
    if x.iter().all(|v| v.is_finite()) {
        x
    } else {
        [0.0; MAX_FEATURES]
    }
}
