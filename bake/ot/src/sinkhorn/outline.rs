//! The auction's starting prices, lowered away from the target's outline (docs/decisions.md, D169).
//!
//! The auction starts from the final stage's potentials, and nearly all of its bids are its
//! endgame: the last few hundred free rows lie inside the source, the last free columns on the
//! target's outline (the duck, the heart, the tooth and the 3D cow alike, D167), and the auction
//! lowers the interior's prices some 20 auction ε below the outline's one bid at a time before the
//! chains of displaced rows reach the outline. The entropic plan is what leaves those columns free:
//! where the target's density ends, each row's blur spills past the outline, so the outline's
//! columns are the first choice of fewer rows than they hold (0.79 within 1.5 spacings, D167).
//!
//! So the prices start already lowered where the target has no outline near: each column's
//! *outline score* on a few coarse scales (how far the local mean of the target's mass lies from the
//! column, in units of the scale: about 0 inside, 0.4–0.8 on an outline) is raised by a ramp, the
//! ramps of the scales are summed, and all prices are shifted so that the highest is 0. Prices only
//! start lower than the potentials, never higher, so the certificate of the final kernel's support
//! (prices may fall a set amount before a row must be widened) still holds; a profile too deep would
//! spend that allowance, which bounds the depth (D168: 48 auction ε in the middle widened 42K rows).
//!
//! The local mean at scale s is a ratio of two Gaussian blurs of the target (mass, mass·position)
//! at width s, computed on a grid of side s: the cells two levels finer than s are splatted onto it
//! multilinearly, blurred axis by axis, and read back multilinearly at every column.

use super::hierarchy::Hierarchy;
use rayon::prelude::*;

/// Fewer target points than this start from flat prices: their endgame is small, and the
/// profile's misfit costs as many bids as it saves (20K points: duck 55.0K → 63.5K bids, cow 74.7K
/// → 85.6K, heart 63.1K → 61.9K; 35K: duck 210K → 141K, heart 131K → 120K, cow 176K → 175K, tooth
/// 153K → 169K; 50K and up, every shape measured fewer, D169). It also leaves the maps of small
/// bakes as they were (a 1000-point barycenter's excess 9.1e-4 against 1.14e-3 with a profile).
const MIN_POINTS: usize = 32_768;

/// The scales, in point spacings: every cell level whose side lies in this range (for a 2D cloud
/// of 250K points, the four levels 3–6 above the points, sides 6–47 spacings).
const SCALES: (f64, f64) = (4.0, 64.0);

/// Full depth per scale, in auction ε per point across the cloud (the shared cube's side over the
/// point spacing), by dimension (index 1, 2, 3; 3 also for 4D; 0: no profile). The endgame's chains
/// run from the middle to the outline, so their depth grows with the points across: the fewest
/// bids came at 3 auction ε per scale for the 50K duck (332 points across) and 7 for the 250K duck
/// (753), 1.6 for the 50K cow (68) and 3 for the 250K cow (127) (D169).
const DEPTH_PER_ACROSS: [f64; 4] = [0.0, 0.0, 0.009, 0.024];

/// The share of the support's certificate the whole profile may take (the bids lower the prices
/// further): 500K duck points (1065 across, 9.6 auction ε per scale) took 16.1M bids and 5.9 s of
/// auction from flat prices, 9.6M and 4.6 s from 8 per scale, the most this share allows (D169).
const CERTIFIED_SHARE: f64 = 0.5;

/// Past this share of the certificate the endgame's bowl is deeper than the certificate holds,
/// and a profile only turns bids into widened rows and searches: the 1M duck (1506 across, 13.5
/// auction ε per scale) widened 292K rows with or without one, and its auction took 82 s from flat
/// prices, 221 s from 7 auction ε per scale (D169). There the prices start flat.
const CERTIFIED_LIMIT: f64 = 0.75;

/// The ramp from an outline score to its share of the depth: 0 below `LOW` (the sampling noise of
/// an interior column's score), 1 from `LOW + WIDTH` (a straight outline scores about 0.75).
const LOW: f64 = 0.1;
const WIDTH: f64 = 0.45;

/// Largest grid (slots) a scale is computed on; a finer scale past it is skipped.
const MAX_SLOTS: usize = 1 << 20;

/// The Gaussian's taps on the grid: exp(−k²) at k = 0, 1, 2 slots (width one slot, the score's
/// scale; the tap at 3 slots would weigh 1e-4).
const TAPS: [f64; 3] = [1.0, 0.367_879_441_171_442_3, 0.018_315_638_888_734_18];

/// What the profile's depth is measured against.
#[derive(Clone, Copy, Debug)]
pub(super) struct Scale {
    /// Point spacing and the side of the cube holding both clouds.
    pub spacing: f64,
    pub side: f64,
    /// The auction's final ε (the least a bid lowers a price by).
    pub step: f64,
    /// How far a row's prices may fall before it must be widened (the support's certificate).
    pub certified: f64,
}

/// Starting prices of the target's points (the point level of `ht`, in its order): 0 on the
/// outline, lower inside; all zero where the dimension has no profile or no level is a scale.
pub(super) fn outline_prices<const D: usize>(
    ht: &Hierarchy<D>,
    point_level: usize,
    scale: Scale,
) -> Vec<f64> {
    let y = &ht.levels[point_level].pos;
    let mut v = vec![0.0; y.len()];
    let Scale {
        spacing,
        side,
        step,
        certified,
    } = scale;
    if y.len() < MIN_POINTS || !(spacing > 0.0 && step > 0.0) {
        return v;
    }
    // Cell levels (the children two levels down are what is blurred) whose side is a scale.
    let levels: Vec<usize> = (1..point_level.saturating_sub(2))
        .filter(|&l| (SCALES.0..=SCALES.1).contains(&(ht.levels[l].side / spacing)))
        .collect();
    if levels.is_empty() {
        return v;
    }
    let depth = DEPTH_PER_ACROSS[D.min(3)] * side / spacing * step;
    let whole = depth * levels.len() as f64;
    if !(depth > 0.0 && whole <= CERTIFIED_LIMIT * certified) {
        return v;
    }
    let depth = depth.min(CERTIFIED_SHARE * certified / levels.len() as f64);
    for level in levels {
        let Some(field) = Blurred::new(&ht.levels[level + 2], ht.levels[level].side) else {
            continue;
        };
        v.par_iter_mut().zip(y.par_iter()).for_each(|(v, p)| {
            *v += depth * ((field.score(p) - LOW) / WIDTH).clamp(0.0, 1.0);
        });
    }
    let top = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if top.is_finite() {
        v.iter_mut().for_each(|p| *p -= top);
    }
    v
}

/// Mass and mass·position of one cloud, Gaussian-blurred at width `side` on a grid of that side.
struct Blurred<const D: usize> {
    origin: [f64; D],
    side: f64,
    dims: [usize; D],
    /// Per slot: mass, then mass·position per axis.
    fields: Vec<[f64; 4]>,
}

impl<const D: usize> Blurred<D> {
    /// The blur of `cells` (mass and centroid each) at width `side`; `None` past [`MAX_SLOTS`] or
    /// for an empty cloud.
    fn new(cells: &super::hierarchy::Level<D>, side: f64) -> Option<Self> {
        if D > 3 || cells.pos.is_empty() || !side.is_finite() || side <= 0.0 {
            return None;
        }
        let mut lo = [f64::INFINITY; D];
        let mut hi = [f64::NEG_INFINITY; D];
        for p in &cells.pos {
            for k in 0..D {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        // Three slots of margin: the blur's reach (two) plus the splat's (one).
        let origin: [f64; D] = std::array::from_fn(|k| lo[k] - 3.0 * side);
        let mut dims = [0usize; D];
        let mut slots = 1usize;
        for k in 0..D {
            let span = ((hi[k] - lo[k]) / side).ceil();
            if !(span.is_finite() && span < MAX_SLOTS as f64) {
                return None;
            }
            dims[k] = span as usize + 7;
            slots = slots.checked_mul(dims[k]).filter(|&s| s <= MAX_SLOTS)?;
        }
        let mut out = Self {
            origin,
            side,
            dims,
            fields: vec![[0.0; 4]; slots],
        };
        for (p, &m) in cells.pos.iter().zip(&cells.mass) {
            let mut value = [m, 0.0, 0.0, 0.0];
            for k in 0..D {
                value[k + 1] = m * p[k];
            }
            for &(slot, w) in &out.corners(p)[..1 << D] {
                for (f, x) in out.fields[slot].iter_mut().zip(value) {
                    *f += w * x;
                }
            }
        }
        for axis in 0..D {
            out.blur_axis(axis);
        }
        Some(out)
    }

    /// The multilinear weights of `p` on its 2^D nearest slot centres (the first 2^D entries).
    fn corners(&self, p: &[f64; D]) -> [(usize, f64); 8] {
        let mut base = [0usize; D];
        let mut frac = [0.0; D];
        for k in 0..D {
            // Slot centres at (i + ½)·side; a point off the grid (a column outside the cells'
            // box) is clamped onto its edge, where the fields are near zero anyway.
            let t = ((p[k] - self.origin[k]) / self.side - 0.5).max(0.0);
            let i = (t as usize).min(self.dims[k] - 2);
            base[k] = i;
            frac[k] = (t - i as f64).clamp(0.0, 1.0);
        }
        let mut out = [(0usize, 0.0); 8];
        for (corner, o) in out.iter_mut().enumerate().take(1 << D) {
            let (mut slot, mut stride, mut w) = (0usize, 1usize, 1.0);
            for k in 0..D {
                let up = (corner >> k) & 1;
                slot += (base[k] + up) * stride;
                stride *= self.dims[k];
                w *= if up == 1 { frac[k] } else { 1.0 - frac[k] };
            }
            *o = (slot, w);
        }
        out
    }

    /// One axis of the separable Gaussian blur (taps [`TAPS`], zero past the grid's edges).
    fn blur_axis(&mut self, axis: usize) {
        let stride: usize = self.dims[..axis].iter().product();
        let len = self.dims[axis];
        let src = self.fields.clone();
        self.fields
            .par_iter_mut()
            .enumerate()
            .for_each(|(slot, out)| {
                let at = (slot / stride) % len;
                let mut sum = [0.0; 4];
                for (k, &w) in TAPS.iter().enumerate() {
                    let mut add = |s: usize| {
                        for (a, x) in sum.iter_mut().zip(src[s]) {
                            *a += w * x;
                        }
                    };
                    if k == 0 {
                        add(slot);
                        continue;
                    }
                    if at >= k {
                        add(slot - k * stride);
                    }
                    if at + k < len {
                        add(slot + k * stride);
                    }
                }
                *out = sum;
            });
    }

    /// How far the blurred mean position around `p` lies from `p`, in grid sides.
    fn score(&self, p: &[f64; D]) -> f64 {
        let mut sum = [0.0; 4];
        for &(slot, w) in &self.corners(p)[..1 << D] {
            for (a, x) in sum.iter_mut().zip(self.fields[slot]) {
                *a += w * x;
            }
        }
        if sum[0].is_nan() || sum[0] <= 0.0 {
            return 0.0;
        }
        let d2: f64 = (0..D).map(|k| (sum[k + 1] / sum[0] - p[k]).powi(2)).sum();
        // A non-finite score (no point is, but the prices must never be) counts as inside.
        let score = d2.sqrt() / self.side;
        if score.is_finite() {
            score
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::hierarchy::{Grid, Hierarchy};
    use super::*;
    use crate::rng::SplitMix64;

    /// A jittered grid of `k`² points over the unit square, those `keep` accepts.
    fn jittered(k: usize, keep: impl Fn(&[f64; 2]) -> bool) -> Vec<[f64; 2]> {
        let mut rng = SplitMix64::new(7);
        let mut unit = move || rng.next_f64();
        let h = 1.0 / k as f64;
        let mut out = Vec::new();
        for i in 0..k {
            for j in 0..k {
                let p = [(i as f64 + unit()) * h, (j as f64 + unit()) * h];
                if keep(&p) {
                    out.push(p);
                }
            }
        }
        out
    }

    #[test]
    fn a_straight_outline_scores_about_half_a_scale_and_the_inside_nothing() {
        let pts = jittered(200, |_| true);
        let grid = Grid::new(&pts, &pts);
        let h = Hierarchy::new(&pts, &grid, 7);
        // Cells of side 1/16 (12.5 spacings), blurred from their grandchildren.
        let field = Blurred::new(&h.levels[6], h.levels[4].side).expect("a small grid");
        let inside = field.score(&[0.5, 0.5]);
        let edge = field.score(&[0.0, 0.5]);
        let corner = field.score(&[0.0, 0.0]);
        assert!(inside < 0.05, "inside scored {inside}");
        // A half-plane's mean lies σ·√(2/π) in: σ² = ½ (the Gaussian) + ⅓ (splat and read-back).
        assert!((0.65..0.85).contains(&edge), "the edge scored {edge}");
        assert!(
            corner > edge * 1.3,
            "the corner scored {corner} (edge {edge})"
        );
    }

    #[test]
    fn prices_are_zero_on_the_outline_and_lowest_in_the_middle() {
        let disc = |p: &[f64; 2]| (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2) < 0.4 * 0.4;
        let pts = jittered(260, disc);
        let grid = Grid::new(&pts, &pts);
        let h = Hierarchy::new(&pts, &grid, 8);
        let point_level = h.levels.len() - 1;
        let spacing = (std::f64::consts::PI * 0.16 / pts.len() as f64).sqrt();
        let scale = Scale {
            spacing,
            side: grid.side,
            step: 1.0,
            certified: 1e9,
        };
        let v = outline_prices(&h, point_level, scale);
        let y = &h.levels[point_level].pos;
        let low = v.iter().copied().fold(f64::INFINITY, f64::min);
        let high = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(high, 0.0);
        // Every scale at (nearly) full depth in the middle.
        let per_scale = DEPTH_PER_ACROSS[2] * grid.side / spacing;
        assert!(
            low < -3.0 * per_scale,
            "lowest {low}, per scale {per_scale}"
        );
        for (p, &price) in y.iter().zip(&v) {
            let r = ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)).sqrt();
            if r < 0.1 {
                assert!(price < 0.9 * low, "middle point at r {r}: {price} vs {low}");
            }
            if r > 0.395 {
                assert!(
                    price > 0.3 * low,
                    "outline point at r {r}: {price} vs {low}"
                );
            }
        }
        // Between the share and the limit, the profile is capped at the share.
        let scales = (1..point_level - 2)
            .filter(|&l| (SCALES.0..=SCALES.1).contains(&(h.levels[l].side / spacing)))
            .count() as f64;
        let certified = per_scale * scales / (0.5 * (CERTIFIED_SHARE + CERTIFIED_LIMIT));
        let capped = outline_prices(&h, point_level, Scale { certified, ..scale });
        let low = capped.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(
            low < 0.0 && low >= -CERTIFIED_SHARE * certified - 1e-9,
            "capped at {low}"
        );
        // Past the certificate's limit, no profile at all.
        let certified = per_scale;
        let flat = outline_prices(&h, point_level, Scale { certified, ..scale });
        assert!(flat.iter().all(|&p| p == 0.0));
        // And below MIN_POINTS.
        let few = jittered(160, disc);
        assert!(few.len() < MIN_POINTS);
        let h = Hierarchy::new(&few, &grid, 8);
        let flat = outline_prices(&h, h.levels.len() - 1, scale);
        assert!(flat.iter().all(|&p| p == 0.0));
    }
}
