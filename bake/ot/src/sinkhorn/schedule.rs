//! The plan of a solve, fixed before the first stage: both clouds' grid hierarchies, the final
//! blur from the point spacing, and the blur and level of every stage.

use super::hierarchy::{level_counts, Grid, Hierarchy, LevelCount, Sorted};
use super::{SinkhornSettings, DEFAULT_BLUR_SPACING};

/// What every stage runs on.
pub(super) struct Plan<const D: usize> {
    /// The source's and the target's hierarchies (shared grid).
    pub hs: Hierarchy<D>,
    pub ht: Hierarchy<D>,
    /// Side of the cube holding both clouds (the first blur).
    pub side: f64,
    /// Point spacing where a typical point of the denser cloud lives ([`point_spacing`]).
    pub spacing: f64,
    /// The final blur.
    pub blur_end: f64,
    /// The level holding the points themselves.
    pub point_level: usize,
    /// The blur of every stage, the last one `blur_end`.
    pub blurs: Vec<f64>,
}

impl<const D: usize> Plan<D> {
    /// The hierarchies of `xs` and `ys` on `grid` (whose side is not 0) and the stages.
    pub fn new(
        xs: &[[f64; D]],
        ys: &[[f64; D]],
        grid: &Grid<D>,
        n: usize,
        settings: &SinkhornSettings,
    ) -> Self {
        let side = grid.side;
        let t0 = std::time::Instant::now();
        // The two clouds at once: each sort and count is parallel, but not all of it is.
        let counted = |pts: &[[f64; D]]| {
            let s = Sorted::new(pts, grid);
            let c = level_counts::<D>(&s);
            (s, c)
        };
        let ((sx, cs), (sy, ct)) = rayon::join(|| counted(xs), || counted(ys));
        let spacing = point_spacing(&cs, &ct, side, n, D);
        let blur_end = settings.blur.unwrap_or(
            settings
                .blur_spacing
                .unwrap_or(DEFAULT_BLUR_SPACING[D.min(3)])
                * spacing,
        );
        let max_level = finest_cell_level(&cs, &ct, side, n, blur_end);
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            let show = |c: &[LevelCount]| {
                c.iter()
                    .take(14)
                    .map(|v| format!("{}/{:.1}", v.cells, v.shared(n)))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            eprintln!(
                "cells/shared per level: source {}; target {}; spacing {spacing:.4e}, final blur \
                 {blur_end:.4e}, finest cell level {max_level}",
                show(&cs),
                show(&ct)
            );
        }
        let (hs, ht) = rayon::join(
            || Hierarchy::from_sorted(xs, sx, grid, max_level),
            || Hierarchy::from_sorted(ys, sy, grid, max_level),
        );
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            eprintln!("  plan {:.2}s", t0.elapsed().as_secs_f64());
        }
        let point_level = hs.point_level();
        let mut plan = Self {
            hs,
            ht,
            side,
            spacing,
            blur_end,
            point_level,
            blurs: Vec::new(),
        };
        plan.blurs = plan.schedule(settings.scaling);
        plan
    }

    /// The blur schedule: from the cube's side down by `scaling` per stage, then the final blur.
    fn schedule(&self, scaling: f64) -> Vec<f64> {
        let mut blurs = Vec::new();
        let mut b = self.side;
        while b > self.blur_end {
            blurs.push(b);
            b *= scaling;
        }
        // Only the last stage runs on the points: an earlier one there would cost (b/blur_end)^d times
        // the final stage's pairs (measured in 3D: 27.7M pairs at 1.8 × the final blur against 4.9M)
        // while the cell stages before it already give the final stage a good start.
        blurs.retain(|&b| self.level_of(b) < self.point_level);
        blurs.push(self.blur_end);
        blurs
    }

    /// The level a stage at `blur` runs on: the coarsest whose cells are no larger than the blur,
    /// else the points.
    pub fn level_of(&self, blur: f64) -> usize {
        (0..self.point_level)
            .find(|&l| self.hs.levels[l].side <= blur)
            .unwrap_or(self.point_level)
    }
}

/// Points a typical point's cell must share it with on the level the spacing is read from: enough
/// for the count to be a density (16 per cell, as for the mean spacing before D130).
const SPACING_SHARED: f64 = 16.0;

/// The spacing never goes below this fraction of the occupied volume's mean spacing: below it the
/// sparse part of the cloud would see a blur so far under its own spacing that Sinkhorn there is
/// an assignment problem solved by diffusion. A 2D target with 90% of its points in a 1e-4 square
/// (the `spike` test) had a spacing of 1/6000 of the mean and its final stage stalled at 0.15 after
/// 2000 iterations; the Cornell BRDFs' lobes are 2 to 5.7 times denser than their mean.
const MIN_SPACING_OF_MEAN: f64 = 1.0 / 8.0;

/// The spacing points see replaces the mean only below this fraction of it (both the smaller of
/// the two clouds'): a peaked density (the Cornell BRDFs' lobes are at 0.18–0.50 of the mean
/// spacing, at 200K and 1M samples). Nearer
/// the mean a blur following the density buys nothing and costs iterations: the 250K duck (0.89
/// of its mean) took 796 iterations instead of 449, 45% more CPU time, with it (D130).
const PEAKED_BELOW_MEAN: f64 = 0.7;

/// The point spacing where a typical point lives, ρ^(−1/d) for the density ρ a point sees, of the
/// denser cloud: on the finest level where a typical point's cell holds at least
/// [`SPACING_SHARED`] other points, (n·V_cell / Σ n_c (n_c − 1))^(1/d), and at least
/// [`MIN_SPACING_OF_MEAN`] of the mean spacing (V/n)^(1/d) of the occupied volume V (the cells of
/// the finest level with at least 16 points per occupied cell on average); the mean spacing
/// itself unless the density is peaked (the smaller spacing seen below [`PEAKED_BELOW_MEAN`] of
/// the smaller mean) (docs/decisions.md, D130).
///
/// Why the density a point sees and not the cube's or the occupied volume's: a kernel row holds
/// the target points within about √θ·blur of the row's image, so a blur set from a mean spacing
/// keeps ρ/ρ̄ times too many pairs wherever a cloud is denser than its mean. A 3D mesh volume
/// filling a tenth of its cube gave 500 to 780 pairs per point from the cube's spacing (D25); a
/// BRDF's specular lobe holds most of the samples in a few cells of the occupied volume, and the
/// occupied volume's spacing put thousands of points within one blur there (D38, D117). For a
/// near-uniform cloud the two agree (the count is the mean count per cell).
pub(super) fn point_spacing(
    cs: &[LevelCount],
    ct: &[LevelCount],
    side: f64,
    n: usize,
    d: usize,
) -> f64 {
    let cell = |level: usize| (side / 2f64.powi(level as i32)).powi(d as i32);
    // (spacing seen, floored; mean spacing of the occupied volume) of one cloud.
    let spacings = |counts: &[LevelCount]| -> (f64, f64) {
        let level = (0..counts.len())
            .take_while(|&l| counts[l].shared(n) >= SPACING_SHARED)
            .last()
            .unwrap_or(0);
        // One point (or none sharing level 0): the cube's side.
        let pairs = counts[level].pairs.max(1.0);
        let seen = (n.max(1) as f64 * cell(level) / pairs).powf(1.0 / d as f64);
        let level = (0..counts.len())
            .take_while(|&l| counts[l].cells.saturating_mul(16) <= n.max(16))
            .last()
            .unwrap_or(0);
        let volume = counts[level].cells as f64 * cell(level);
        let mean = (volume / n.max(1) as f64).powf(1.0 / d as f64);
        (seen.max(MIN_SPACING_OF_MEAN * mean), mean)
    };
    let ((seen_s, mean_s), (seen_t, mean_t)) = (spacings(cs), spacings(ct));
    let (seen, mean) = (seen_s.min(seen_t), mean_s.min(mean_t));
    // Against the denser cloud's mean, not each cloud's own: a Gaussian proxy sees a spacing well
    // below its own mean (its tails fill the occupied volume), but not below the shape's mean.
    if seen < PEAKED_BELOW_MEAN * mean {
        seen
    } else {
        mean
    }
}

/// The finest cell level of the hierarchies (docs/decisions.md, D27, D131): as fine as possible
/// while both clouds have at most 3n/4 cells, and finer where a dense part needs it, down to the
/// coarsest level whose cells are no larger than the final blur, so that the last cell stage is
/// one halving of the blur above the final one even inside a lobe (but never past the level where
/// a typical point no longer shares its cell with another: the cells would be the points).
///
/// The 3n/4 rule: a 1M-point 3D Gaussian has 518K cells on the level where the cow has 217K, and
/// with a limit of n/2 that level was skipped, the final stage started 3.3x the blur away and took
/// 828 iterations and 10 kernel builds instead of 135 and 5. For a near-uniform cloud it already
/// reaches a cell side below the spacing; in a peaked BRDF the background's points fill 3n/4
/// cells while the lobe's cells still hold hundreds of points each, and the final stage started
/// 8 halvings of the blur away.
pub(super) fn finest_cell_level(
    cs: &[LevelCount],
    ct: &[LevelCount],
    side: f64,
    n: usize,
    blur_end: f64,
) -> u32 {
    let cap = (3 * n / 4).max(1);
    let by_cells = (0..cs.len())
        .take_while(|&l| cs[l].cells <= cap && ct[l].cells <= cap)
        .last()
        .unwrap_or(0);
    // The coarsest level with cells no larger than the final blur, or the finest level.
    let by_blur = (0..cs.len())
        .find(|&l| side / 2f64.powi(l as i32) <= blur_end)
        .unwrap_or(cs.len() - 1);
    let shared = (0..cs.len())
        .take_while(|&l| cs[l].shared(n) >= 1.0 || ct[l].shared(n) >= 1.0)
        .last()
        .unwrap_or(0);
    by_cells.max(by_blur.min(shared)) as u32
}
