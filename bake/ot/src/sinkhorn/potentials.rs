//! Potentials between stages: absorbing the scalings, hard c-transforms on a sparse support, the
//! ε extrapolation of the entropic offset, and the soft c-transform onto a finer level.

use super::fastexp::sum_exp;
use super::hierarchy::Hierarchy;
use crate::cost::sq;
use crate::Wrap;
use rayon::prelude::*;

/// Potentials with the scalings absorbed: p + ε log(s / mass).
pub(super) fn absorbed(p: &[f64], s: &[f64], mass: &[f64], eps: f64) -> Vec<f64> {
    p.par_iter()
        .zip(s)
        .zip(mass)
        .map(|((&p, &s), &m)| p + eps * (s / m).ln())
        .collect()
}

/// The hard c-transform over a sparse support: for every row i of (`ptr`, `idx`),
/// min over its entries j of |x_i − y_j|² − pot_j (∞ for an empty row).
pub(super) fn hard_transform<const D: usize>(
    ptr: &[usize],
    idx: &[u32],
    x: &[[f64; D]],
    y: &[[f64; D]],
    pot: &[f64],
    wrap: Wrap,
) -> Vec<f64> {
    hard_transform_best(ptr, idx, x, y, pot, wrap).0
}

/// [`hard_transform`] and, per row, the first entry attaining its minimum (`u32::MAX` for an empty
/// row).
pub(super) fn hard_transform_best<const D: usize>(
    ptr: &[usize],
    idx: &[u32],
    x: &[[f64; D]],
    y: &[[f64; D]],
    pot: &[f64],
    wrap: Wrap,
) -> (Vec<f64>, Vec<u32>) {
    (0..ptr.len() - 1)
        .into_par_iter()
        .map(|i| {
            idx[ptr[i]..ptr[i + 1]]
                .iter()
                .map(|&j| (sq(wrap, &x[i], &y[j as usize]) - pot[j as usize], j))
                .fold(
                    (f64::INFINITY, u32::MAX),
                    |a, b| if b.0 < a.0 { b } else { a },
                )
        })
        .unzip()
}

/// Candidates per row that [`upper_from_parents`] evaluates at most: a cell's descendants beyond
/// this many are sampled evenly.
const CANDIDATES: usize = 32;

/// Upper bounds of the row minima min_j (C(x_i, y_j) − `g`_j) on level `to` of the source, from a
/// coarser level `from` where every source cell's best target cell is known (`best`, `u32::MAX`
/// for none): row i's bound is the smallest C − g over the descendants on `to` of its ancestor's
/// best cell (∞ when there is none). Any column gives a bound; these are near the row's own best,
/// which is what makes the column test's walk narrow ([`super::kernel::build`]).
pub(super) fn upper_from_parents<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    (from, to): (usize, usize),
    best: &[u32],
    g: &[f64],
    wrap: Wrap,
) -> Vec<f64> {
    let (xs, ys) = (&hs.levels[to].pos, &ht.levels[to].pos);
    (0..xs.len())
        .into_par_iter()
        .map(|i| {
            let mut anc = i;
            for l in (from + 1..=to).rev() {
                anc = hs.levels[l].parent[anc] as usize;
            }
            let d = best[anc];
            if d == u32::MAX {
                return f64::INFINITY;
            }
            // The descendants of a cell are a contiguous range on every finer level.
            let (mut a, mut b) = (d as usize, d as usize + 1);
            for l in from..to {
                let child = &ht.levels[l].child;
                (a, b) = (child[a] as usize, child[b] as usize);
            }
            let step = (b - a).div_ceil(CANDIDATES).max(1);
            (a..b)
                .step_by(step)
                .map(|j| sq(wrap, &xs[i], &ys[j]) - g[j])
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Potentials for a smaller ε from converged ones: an entropic potential is its hard c-transform
/// counterpart plus an offset ε·L(x) whose shape (log densities and Jacobians) barely depends on ε,
/// so the offset is scaled by ε_new/ε_old. Without this every ε stage starts with a smooth,
/// long-wavelength potential error of a few ε, which Sinkhorn removes only in hundreds of
/// iterations (measured with the other changes of this commit: the coarse stages at 50K points took
/// 1.3–2.3 times fewer iterations, and the final stage 60 instead of 157).
pub(super) fn shrink_offset(soft: &[f64], hard: &[f64], ratio: f64) -> Vec<f64> {
    soft.iter()
        .zip(hard)
        .map(|(&s, &h)| {
            if h.is_finite() {
                h + ratio * (s - h)
            } else {
                s
            }
        })
        .collect()
}

/// Target potential on level `to` from the source potential `f` on level `from`: the soft
/// c-transform g(y) = −ε log Σ_I a_I exp((f_I − C(x_I, y))/ε) over the source cells the coarse
/// kernel links to y's ancestor (`columns`: the coarse kernel's column form, pointers and rows).
pub(super) fn extrapolate<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    (from, to): (usize, usize),
    (col_ptr, row): (&[usize], &[u32]),
    f: &[f64],
    eps: f64,
    wrap: Wrap,
) -> Vec<f64> {
    let ys = &ht.levels[to];
    let (xs, a) = (&hs.levels[from].pos, &hs.levels[from].mass);
    // ε·ln a_i once per row, not twice per pair (the logarithms were a third of this pass).
    let eps_ln_a: Vec<f64> = a.par_iter().map(|&m| eps * m.ln()).collect();
    (0..ys.len())
        .into_par_iter()
        .map_init(Vec::new, |terms: &mut Vec<f64>, j| {
            let mut anc = j;
            for l in (from + 1..=to).rev() {
                anc = ht.levels[l].parent[anc] as usize;
            }
            let rows = &row[col_ptr[anc]..col_ptr[anc + 1]];
            let y = &ys.pos[j];
            terms.clear();
            terms.extend(rows.iter().map(|&i| {
                let i = i as usize;
                f[i] - sq(wrap, &xs[i], y) + eps_ln_a[i]
            }));
            let m = terms.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let s = if m.is_finite() {
                sum_exp(terms, m, eps)
            } else {
                terms.iter().map(|&t| ((t - m) / eps).exp()).sum()
            };
            -(m + eps * s.ln())
        })
        .collect()
}
