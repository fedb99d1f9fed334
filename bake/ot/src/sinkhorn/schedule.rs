//! The plan of a solve, fixed before the first stage: both clouds' grid hierarchies, the final
//! blur from the point spacing, and the blur and level of every stage.

use super::hierarchy::{cell_counts, Grid, Hierarchy};
use super::{SinkhornSettings, DEFAULT_BLUR_SPACING};

/// What every stage runs on.
pub(super) struct Plan<const D: usize> {
    /// The source's and the target's hierarchies (shared grid).
    pub hs: Hierarchy<D>,
    pub ht: Hierarchy<D>,
    /// Side of the cube holding both clouds (the first blur).
    pub side: f64,
    /// Mean point spacing of the denser cloud ([`point_spacing`]).
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
        // Cell levels: as fine as possible while both clouds have at most 3n/4 cells. The last cell
        // stage should be one halving of the blur above the final one: a 1M-point 3D Gaussian has 518K
        // cells on the level where the cow has 217K, and with a limit of n/2 that level was skipped, the
        // final stage started 3.3x the blur away and took 828 iterations and 10 kernel builds instead
        // of 135 and 5 (1.7 times the time).
        let (cs, ct) = (cell_counts(xs, grid), cell_counts(ys, grid));
        let spacing = point_spacing(&cs, &ct, side, n, D);
        let blur_end = settings.blur.unwrap_or(
            settings
                .blur_spacing
                .unwrap_or(DEFAULT_BLUR_SPACING[D.min(3)])
                * spacing,
        );
        let max_level = (0..cs.len())
            .take_while(|&l| cs[l] <= (3 * n / 4).max(1) && ct[l] <= (3 * n / 4).max(1))
            .last()
            .unwrap_or(0) as u32;
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            let show = |c: &[usize]| {
                c.iter()
                    .take(12)
                    .map(|v| v.to_string())
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            eprintln!(
                "cells per level: source {}; target {}; finest cell level {max_level}",
                show(&cs),
                show(&ct)
            );
        }
        let hs = Hierarchy::new(xs, grid, max_level);
        let ht = Hierarchy::new(ys, grid, max_level);
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

/// The mean point spacing (V/n)^(1/d) of the denser cloud, V its occupied volume: the cells of
/// the finest level with at least 16 points per occupied cell on average, for each cloud.
///
/// Why the denser cloud and not the cube: a kernel row holds the target points within about
/// √θ·blur of the row's image, so a blur set from the cube's spacing keeps ρ/ρ̄ times too many
/// pairs wherever a cloud is concentrated — a 3D mesh volume filling a tenth of its cube gave 500
/// to 780 pairs per point instead of about 100.
pub(super) fn point_spacing(cs: &[usize], ct: &[usize], side: f64, n: usize, d: usize) -> f64 {
    let volume = |counts: &[usize]| -> f64 {
        let level = (0..counts.len())
            .take_while(|&l| counts[l].saturating_mul(16) <= n.max(16))
            .last()
            .unwrap_or(0);
        counts[level] as f64 * (side / 2f64.powi(level as i32)).powi(d as i32)
    };
    let v = volume(cs).min(volume(ct));
    (v / n.max(1) as f64).powf(1.0 / d as f64)
}
