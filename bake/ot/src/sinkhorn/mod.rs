//! Multiscale, log-stabilized, ε-scaling Sinkhorn on truncated sparse kernels, with the map
//! refined to a one-to-one matching.
//!
//! The method follows Schmitzer 2019 ("Stabilized sparse scaling algorithms for entropy regularized
//! transport problems") and Feydy's multiscale GeomLoss, with one change that matters for maps:
//! every ε stage is iterated until its marginal error is below the tolerance (GeomLoss runs one
//! iteration per ε and its maps under-transport, NOTES.md).
//!
//! * **ε-scaling.** The blur (ε = blur², cost |x − y|²) starts at the side of the cube holding both
//!   clouds and shrinks by `scaling` per stage down to the final blur.
//! * **Coarse to fine.** Both clouds are sorted into a shared grid hierarchy ([`hierarchy`]); a stage
//!   at blur b runs on the coarsest level whose cells are no larger than b (cluster centroids
//!   weighted by their mass), and on the points themselves once the cells would be nearly as many as
//!   the points. Moving to a finer level extrapolates the target potential by a soft c-transform
//!   against the coarse source potential, restricted to the coarse kernel's support.
//! * **ε extrapolation.** An entropic potential is its hard c-transform plus an offset ε·L(x) (log
//!   densities and Jacobians) that barely changes with ε, so between stages the offset is scaled by
//!   ε_new/ε_old ([`shrink_offset`]) instead of being left for the iterations to remove: a smooth,
//!   long-wavelength error of a few ε is exactly what Sinkhorn removes slowest.
//! * **Truncation.** Each stage keeps only the pairs within θ·ε of their row's or column's best
//!   reduced cost, found exactly by branch and bound over the hierarchy ([`kernel`]): memory and time
//!   per iteration are linear in n for a bounded blur/spacing ratio.
//! * **Stabilization.** The kernel is built with the current potentials absorbed (its entries are in
//!   (0, 1]); the iterations update f64 scalings u, v, which are absorbed into the potentials at the
//!   end of every stage (and earlier if they drift far from the masses).
//! * **Map.** The barycentric projection T(x_i) = Σ_j π_ij y_j / Σ_j π_ij of the final plan, or, with
//!   `map = "assignment"` (the default), a one-to-one matching found by a sparse ε-scaling auction on
//!   the final kernel's support started from the Sinkhorn potentials ([`super::auction`]): every mapped
//!   point is then a target sample, and the matching is within n·ε_end of the best the support allows.
//!
//! Failure is never silent: the final stage must reach the tolerance (else
//! [`SolveError::NotConverged`]), a non-finite value is an error, and an auction that cannot match
//! every row on the kernel's support falls back to the barycentric map, which the report states.
//!
//! Determinism: every row and column update reads only the previous half-step's values and is
//! computed in a fixed order, partial sums use fixed chunks, the kernel is built in fixed chunks and
//! the auction is sequential: the output does not depend on the thread count.

mod hierarchy;
mod kernel;

use super::auction::{auction, Graph};
use super::cost::{delta, sq};
use super::{Problem, Report, Solution, SolveError, Wrap};
use hierarchy::{Grid, Hierarchy};
use kernel::Kernel;
use rayon::prelude::*;

pub(super) const NAME: &str = "sinkhorn";

/// How the map is read off the final plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// One-to-one: each source point goes to a distinct target sample (sparse auction refinement).
    Assignment,
    /// Barycentric projection of the entropic plan: smooth, slightly contracted (by about the blur).
    Barycentric,
}

impl MapKind {
    /// The manifest's word for it ("assignment" | "barycentric").
    pub fn name(self) -> &'static str {
        match self {
            MapKind::Assignment => "assignment",
            MapKind::Barycentric => "barycentric",
        }
    }
}

/// Settings of the Sinkhorn solver (manifest `[solver] kind = "sinkhorn"`).
#[derive(Clone, Debug, PartialEq)]
pub struct SinkhornSettings {
    /// Final blur (ε = blur²) in coordinate units. `None`: `blur_spacing` × the mean point
    /// spacing (V/n)^(1/d) of the denser cloud, V its occupied volume (`point_spacing`).
    pub blur: Option<f64>,
    /// Final blur as a multiple of the mean point spacing, when `blur` is not given. `None`:
    /// `DEFAULT_BLUR_SPACING` for the dimension.
    pub blur_spacing: Option<f64>,
    /// Blur ratio between consecutive stages, in (0, 1).
    pub scaling: f64,
    /// Marginal error (L1, total mass 1) the final stage iterates to; earlier stages go to
    /// `STAGE_TOLERANCE` × this. Earlier stages must be converged *more* tightly: a loosely
    /// converged stage hands the next, smaller ε a potential whose error is low-frequency, which
    /// Sinkhorn at small ε removes very slowly (measured: stage tolerance 1e-2 before a final 1e-3
    /// stage left that stage stalled at 2e-3 after 2000 iterations). Default 1e-3. 3e-3 was 20%
    /// faster and gave the same 5K cost ratios, but it lets the plan's rows err by up to ~600
    /// points' worth of mass at 250K: the duck sampled with seed 0 then left the auction a row set
    /// its support could not match, whose price war ran out of budget and fell back to the
    /// barycentric map (51 s instead of 10). At 1e-3 every shape and seed measured matched with no
    /// fallback (BENCHMARKS.md). With `map = "assignment"` the final stage goes to at most 1e-3
    /// whatever this says (`ASSIGNMENT_TOLERANCE`).
    pub tolerance: f64,
    /// Iterations allowed per stage. Intermediate stages that hit it go on (the next stage starts
    /// from their potentials, and the report counts them); the final stage must converge.
    pub max_iterations: u32,
    /// Truncation θ: pairs more than θ·ε above their row's and column's best are dropped (their
    /// kernel entries are below e^−θ of the best). Default 8: on uniform/Gaussian → shape at 5K and
    /// 50K points, θ = 8 and 12 gave the same matchings, and 8 keeps a third fewer pairs.
    pub truncate: f64,
    /// How the map is read off the plan.
    pub map: MapKind,
    /// `map = "assignment"` only: the auction's final ε as a fraction of the final Sinkhorn ε.
    /// The matching is within n·ε_auction of the best the kernel's support allows; each division
    /// by 4 is one more auction phase (about 10 bids per point). Default 1/4 (two phases): at 5K
    /// points the cost is within 0.02% of exact and the L2-UVP 0.05%; 1/16 gives 0.002% and
    /// 0.015%, 1 (one phase) 0.12% and 0.1% (BENCHMARKS.md).
    pub auction_eps: f64,
}

impl Default for SinkhornSettings {
    fn default() -> Self {
        Self {
            blur: None,
            blur_spacing: None,
            scaling: 0.5,
            tolerance: 1e-3,
            max_iterations: 2000,
            truncate: 8.0,
            map: MapKind::Assignment,
            auction_eps: 0.25,
        }
    }
}

/// Revision of the solver's algorithm, part of every fingerprint (so of every map's cache key):
/// bumped whenever the same settings give different maps, so that caches from an earlier otbake
/// are rebaked rather than silently reused. 2: the auction on precomputed reduced costs and, in
/// 3D, from ε/4 (`AUCTION_START`); loose mid-stage rebuilds.
const REVISION: u32 = 2;

impl SinkhornSettings {
    pub(super) fn fingerprint(&self) -> String {
        format!(
            "sinkhorn(rev={REVISION},blur={:?},blur_spacing={:?},scaling={:?},tolerance={:?},max_iterations={},truncate={:?},map={},auction_eps={:?})",
            self.blur,
            self.blur_spacing,
            self.scaling,
            self.tolerance,
            self.max_iterations,
            self.truncate,
            self.map.name(),
            self.auction_eps
        )
    }

    fn check(&self) -> Result<(), SolveError> {
        let bad = |field: &'static str, reason: &str| {
            Err(SolveError::InvalidSettings {
                solver: NAME,
                field,
                reason: reason.to_string(),
            })
        };
        if let Some(b) = self.blur {
            if !(b.is_finite() && b > 0.0) {
                return bad("blur", "must be a positive number (coordinate units)");
            }
        }
        if !self.blur_spacing.is_none_or(|b| b.is_finite() && b > 0.0) {
            return bad("blur_spacing", "must be a positive number");
        }
        if !(self.scaling > 0.0 && self.scaling < 1.0) {
            return bad(
                "scaling",
                "must be in (0, 1); 0.5 halves the blur per stage",
            );
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return bad(
                "tolerance",
                "must be in (0, 1) (L1 marginal error, total mass 1)",
            );
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", "must be at least 1");
        }
        if !(self.truncate.is_finite() && self.truncate >= 1.0) {
            return bad(
                "truncate",
                "must be at least 1 (8 keeps entries above e^-8)",
            );
        }
        if !(self.auction_eps > 0.0 && self.auction_eps <= 1.0) {
            return bad(
                "auction_eps",
                "must be in (0, 1] (a fraction of the final Sinkhorn epsilon)",
            );
        }
        Ok(())
    }
}

/// Largest kernel, in pairs per point, before the solver refuses: beyond it the blur is far above
/// the point spacing or many points coincide, and memory would no longer be linear in n.
const MAX_PAIRS_PER_POINT: usize = 4096;

/// Largest kernel in all, whatever n: 2^27 pairs take about 2 GB in the kernel's four arrays and
/// about 9 GB of peak memory in the solve (the 1M-point 3D cow's 67M pairs peaked at 4.5 GB).
/// A BRDF whose density is concentrated in a specular peak reached 19 GB before this limit.
const MAX_PAIRS: usize = 1 << 27;

/// Default final blur in point spacings, by dimension (index 1, 2, 3; 3 also for 4D). A kernel row
/// keeps the points within about √θ·blur, so the pairs per point grow like blur_spacing^d: 1.5 in
/// 2D keeps about 60 pairs per point at θ = 8, and 1.0 in 3D about 100 (1.5 in 3D kept 315 and the
/// bake of a 50K mesh volume took 61 s instead of 13 s).
pub const DEFAULT_BLUR_SPACING: [f64; 4] = [1.5, 1.5, 1.5, 1.0];

/// Tolerance of the stages before the last, as a fraction of `tolerance`. The marginal error of a
/// stage bounds its potentials' error poorly at long wavelengths, and the next, halved ε sees that
/// error doubled in units of ε and removes it only slowly (iterations per stage grew 93, 230, 516,
/// 536 at 50K points with a factor of 1). Coarse stages are cheap, so they go further: 3e-4 before a
/// final 1e-3 (measured at 50K: the final stage then needs 60 iterations instead of 536; and 1e-4
/// before it doubled the 250K iterations without shortening the final stage).
const STAGE_TOLERANCE: f64 = 0.3;

/// Loosest final marginal error the auction of `map = "assignment"` starts from, whatever
/// `tolerance` says (so with that map, a looser tolerance only loosens the earlier stages). The
/// auction starts from the plan's target potential, and a looser plan leaves prices far from the
/// matching's. Gaussian → Gaussian at 50K with blur_spacing 0.5: tolerance 1e-2 ended Sinkhorn at
/// 6.9e-3 and took 21 s, nearly all in bids (103 s before the auction read precomputed costs);
/// clamped to 3e-3, 7.7 s; at 1e-3, 1.8 s.
const ASSIGNMENT_TOLERANCE: f64 = 1e-3;

/// Solves in the metric of `wrap` (on the torus: costs, kernel bounds and the barycentric map see the
/// nearest images, and the mapped points are lifts; see [`super::solve_in`]).
pub(super) fn solve(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    wrap: Wrap,
) -> Result<Solution, SolveError> {
    settings.check()?;
    if n >= u32::MAX as usize {
        return Err(SolveError::TooLarge {
            solver: NAME,
            n,
            max: u32::MAX as usize - 1,
            hint: "split the point cloud: point indices are 32-bit",
        });
    }
    match problem.dim {
        1 => run::<1>(problem, n, settings, wrap),
        2 => run::<2>(problem, n, settings, wrap),
        3 => run::<3>(problem, n, settings, wrap),
        4 => run::<4>(problem, n, settings, wrap),
        d => Err(SolveError::InvalidSettings {
            solver: NAME,
            field: "dim",
            reason: format!("sinkhorn handles 1 to 4 dimensions (got {d}); use kind = \"sliced\""),
        }),
    }
}

/// What one stage did (for the report).
struct StageLog {
    iterations: u32,
    converged: bool,
    error: f64,
}

/// The solver's state between stages: the level and the potentials on it.
struct State {
    level: usize,
    eps: f64,
    kernel: Kernel,
    /// Scalings of the current kernel.
    u: Vec<f64>,
    v: Vec<f64>,
    /// Target potential the kernel was built with.
    g: Vec<f64>,
    /// Potentials of the last whole kernel build (the reference of local rebuilds).
    f0: Vec<f64>,
    g0: Vec<f64>,
    /// What the support guarantees since the last rebuild.
    support: Support,
}

/// How far out the pairs a kernel dropped are, for the potentials it was last rebuilt around.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Support {
    /// A whole build: every dropped pair is more than θε out.
    Whole,
    /// A local rebuild with τ = [`LOCAL_MOVE`]·θ: more than (θ − 2τ)ε out.
    Local,
    /// A local rebuild with τ = [`LOCAL_MOVE_MID`]·θ during a stage: more than (θ − 2τ_mid)ε = θε/2
    /// out. Good enough to iterate on, not to end a stage on: a stage that converges on it is
    /// rebuilt locally with τ first.
    Loose,
}

fn run<const D: usize>(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    wrap: Wrap,
) -> Result<Solution, SolveError> {
    let pts = |data: &[f32]| -> Vec<[f64; D]> {
        data.par_chunks_exact(D)
            .map(|p| std::array::from_fn(|k| f64::from(p[k])))
            .collect()
    };
    let (xs, ys) = (pts(problem.source), pts(problem.target));
    let grid = Grid::new(&xs, &ys);
    let side = grid.side;
    if side == 0.0 {
        // Every point coincides: any map is optimal.
        return Ok(finish_identity(problem, n));
    }

    // Cell levels: as fine as possible while both clouds have at most 3n/4 cells. The last cell
    // stage should be one halving of the blur above the final one: a 1M-point 3D Gaussian has 518K
    // cells on the level where the cow has 217K, and with a limit of n/2 that level was skipped, the
    // final stage started 3.3x the blur away and took 828 iterations and 10 kernel builds (242 s)
    // instead of 135 and 5 (146 s).
    let (cs, ct) = (
        hierarchy::cell_counts(&xs, &grid),
        hierarchy::cell_counts(&ys, &grid),
    );
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
    let hs = Hierarchy::new(&xs, &grid, max_level);
    let ht = Hierarchy::new(&ys, &grid, max_level);
    let point_level = hs.point_level();

    // The blur schedule and the level of each stage.
    let mut blurs = Vec::new();
    let mut b = side;
    while b > blur_end {
        blurs.push(b);
        b *= settings.scaling;
    }
    let level_of = |blur: f64| -> usize {
        (0..point_level)
            .find(|&l| hs.levels[l].side <= blur)
            .unwrap_or(point_level)
    };
    // Only the last stage runs on the points: an earlier one there would cost (b/blur_end)^d times
    // the final stage's pairs (measured in 3D: 27.7M pairs at 1.8 × the final blur against 4.9M)
    // while the cell stages before it already give the final stage a good start.
    blurs.retain(|&b| level_of(b) < point_level);
    blurs.push(blur_end);

    let mut logs: Vec<StageLog> = Vec::with_capacity(blurs.len());
    let mut state: Option<State> = None;
    let mut rebuilds = 0u32;
    let mut max_pairs = 0usize;
    for (stage, &blur) in blurs.iter().enumerate() {
        let eps = blur * blur;
        // The map needs the points: the last stage always runs on them.
        let level = if stage + 1 == blurs.len() {
            point_level
        } else {
            level_of(blur).max(state.as_ref().map_or(0, |s| s.level))
        };
        // Target potential on the new level.
        let g = match &state {
            None => vec![0.0; ht.levels[level].len()],
            Some(st) => {
                let g_old = absorbed(&st.g, &st.v, &ht.levels[st.level].mass, st.eps);
                let f_old = absorbed(&st.kernel.f, &st.u, &hs.levels[st.level].mass, st.eps);
                let ratio = eps / st.eps;
                if level == st.level {
                    let (sx, sy) = (&hs.levels[level].pos, &ht.levels[level].pos);
                    let g_hard =
                        hard_transform(&st.kernel.col_ptr, &st.kernel.row, sy, sx, &f_old, wrap);
                    shrink_offset(&g_old, &g_hard, ratio)
                } else {
                    let (sx, sy) = (&hs.levels[st.level].pos, &ht.levels[st.level].pos);
                    let f_hard =
                        hard_transform(&st.kernel.row_ptr, &st.kernel.col, sx, sy, &g_old, wrap);
                    let f_pred = shrink_offset(&f_old, &f_hard, ratio);
                    extrapolate(&hs, &ht, st.level, level, &st.kernel, &f_pred, eps, wrap)
                }
            }
        };
        let tk = std::time::Instant::now();
        let kernel = build_kernel(&hs, &ht, level, &g, eps, settings, wrap, spacing)?;
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            eprintln!("  kernel build {:.2}s", tk.elapsed().as_secs_f64());
        }
        max_pairs = max_pairs.max(kernel.pairs());
        let (a, bm) = (&hs.levels[level].mass, &ht.levels[level].mass);
        let mut st = State {
            level,
            eps,
            u: a.clone(),
            v: bm.clone(),
            f0: kernel.f.clone(),
            g0: g.clone(),
            kernel,
            g,
            support: Support::Whole,
        };
        let t0 = std::time::Instant::now();
        let last = stage + 1 == blurs.len();
        let tol = if last {
            match settings.map {
                MapKind::Assignment => settings.tolerance.min(ASSIGNMENT_TOLERANCE),
                MapKind::Barycentric => settings.tolerance,
            }
        } else {
            settings.tolerance * STAGE_TOLERANCE
        };
        let log = iterate(
            &hs,
            &ht,
            &mut st,
            settings,
            tol,
            &mut rebuilds,
            wrap,
            spacing,
        )?;
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            eprintln!("stage {stage} blur {blur:.3e} level {level} cells {}x{} pairs {} its {} err {:.2e} {:.2}s", hs.levels[level].len(), ht.levels[level].len(), st.kernel.pairs(), log.iterations, log.error, t0.elapsed().as_secs_f64());
        }
        if last && !log.converged {
            let report = report_of(
                problem, n, settings, &logs, &log, blur_end, rebuilds, max_pairs, None,
            );
            let e = log.error;
            return Err(SolveError::NotConverged {
                solver: NAME,
                residual: e,
                threshold: settings.tolerance,
                iterations: total_iterations(&logs) + log.iterations,
                hint: format!(
                    "the final stage (blur {blur_end:e}) did not reach the marginal tolerance in \
                     max_iterations = {}: raise max_iterations, raise blur (it is {:.3} x the point \
                     spacing) or loosen tolerance",
                    settings.max_iterations,
                    blur_end / spacing
                ),
                report: Box::new(report),
            });
        }
        logs.push(log);
        state = Some(st);
    }
    let st = state.expect("at least one stage runs");
    assert_eq!(st.level, point_level, "the last stage runs on the points");

    // The map.
    let dim = D;
    let (mapped_sorted, refine) = match settings.map {
        MapKind::Barycentric => (barycentric(&st, &hs, &ht, wrap), None),
        MapKind::Assignment => {
            let g = absorbed(&st.g, &st.v, &ht.levels[point_level].mass, st.eps);
            let ta = std::time::Instant::now();
            let r = refine_assignment(&hs, &ht, &st, g, side, settings.auction_eps, wrap);
            if std::env::var_os("OTBAKE_TRACE").is_some() {
                eprintln!("  auction {:.2}s", ta.elapsed().as_secs_f64());
            }
            match r {
                Ok((x, info)) => {
                    let y = &ht.levels[point_level].pos;
                    (x.iter().map(|&j| y[j as usize]).collect(), Some(info))
                }
                Err(info) => (barycentric(&st, &hs, &ht, wrap), Some(info)),
            }
        }
    };
    // Back to the caller's order.
    let mut mapped = vec![0f32; n * dim];
    for (k, &orig) in hs.order.iter().enumerate() {
        let o = orig as usize;
        for a in 0..dim {
            mapped[o * dim + a] = mapped_sorted[k][a] as f32;
        }
    }
    if wrap == Wrap::Periodic {
        super::cost::lift(dim, problem.source, &mut mapped);
    }
    super::check_finite("mapped", dim, &mapped)?;
    let assignment = match &refine {
        Some(info) if info.unassigned == 0 => Some(info.to_original(&hs, &ht)),
        _ => None,
    };
    let last = logs.pop().expect("a stage ran");
    let mut report = report_of(
        problem,
        n,
        settings,
        &logs,
        &last,
        blur_end,
        rebuilds,
        max_pairs,
        refine.as_ref(),
    );
    report.cost = super::transport_cost(dim, problem.source, &mapped);
    Ok(Solution {
        mapped,
        assignment,
        report,
    })
}

/// The mean point spacing (V/n)^(1/d) of the denser cloud, V its occupied volume: the cells of
/// the finest level with at least 16 points per occupied cell on average, for each cloud.
///
/// Why the denser cloud and not the cube: a kernel row holds the target points within about
/// √θ·blur of the row's image, so a blur set from the cube's spacing keeps ρ/ρ̄ times too many
/// pairs wherever a cloud is concentrated — a 3D mesh volume filling a tenth of its cube gave 500
/// to 780 pairs per point instead of about 100.
fn point_spacing(cs: &[usize], ct: &[usize], side: f64, n: usize, d: usize) -> f64 {
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

/// Potentials with the scalings absorbed: p + ε log(s / mass).
fn absorbed(p: &[f64], s: &[f64], mass: &[f64], eps: f64) -> Vec<f64> {
    p.par_iter()
        .zip(s)
        .zip(mass)
        .map(|((&p, &s), &m)| p + eps * (s / m).ln())
        .collect()
}

/// The hard c-transform over a sparse support: for every row i of (`ptr`, `idx`),
/// min over its entries j of |x_i − y_j|² − pot_j.
fn hard_transform<const D: usize>(
    ptr: &[usize],
    idx: &[u32],
    x: &[[f64; D]],
    y: &[[f64; D]],
    pot: &[f64],
    wrap: Wrap,
) -> Vec<f64> {
    (0..ptr.len() - 1)
        .into_par_iter()
        .map(|i| {
            idx[ptr[i]..ptr[i + 1]]
                .iter()
                .map(|&j| sq(wrap, &x[i], &y[j as usize]) - pot[j as usize])
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
fn shrink_offset(soft: &[f64], hard: &[f64], ratio: f64) -> Vec<f64> {
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
/// kernel links to y's ancestor.
#[allow(clippy::too_many_arguments)]
fn extrapolate<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    from: usize,
    to: usize,
    kernel: &Kernel,
    f: &[f64],
    eps: f64,
    wrap: Wrap,
) -> Vec<f64> {
    let ys = &ht.levels[to];
    let (xs, a) = (&hs.levels[from].pos, &hs.levels[from].mass);
    (0..ys.len())
        .into_par_iter()
        .map(|j| {
            let mut anc = j;
            for l in (from + 1..=to).rev() {
                anc = ht.levels[l].parent[anc] as usize;
            }
            let rows = &kernel.row[kernel.col_ptr[anc]..kernel.col_ptr[anc + 1]];
            let y = &ys.pos[j];
            let mut m = f64::NEG_INFINITY;
            for &i in rows {
                let i = i as usize;
                m = m.max(f[i] - sq(wrap, &xs[i], y) + eps * a[i].ln());
            }
            let mut s = 0.0;
            for &i in rows {
                let i = i as usize;
                s += ((f[i] - sq(wrap, &xs[i], y) + eps * a[i].ln() - m) / eps).exp();
            }
            -(m + eps * s.ln())
        })
        .collect()
}

/// Most pairs a kernel on `rows` rows may keep: [`MAX_PAIRS_PER_POINT`] per row, [`MAX_PAIRS`] in all.
fn pair_limit(rows: usize) -> usize {
    MAX_PAIRS_PER_POINT
        .saturating_mul(rows.max(1))
        .min(MAX_PAIRS)
}

/// Builds a stage's kernel, refusing one whose size is no longer linear in n (more than
/// [`MAX_PAIRS_PER_POINT`] per point, or [`MAX_PAIRS`] in all): the search stops as soon as it has
/// found that many pairs, so the refusal costs bounded memory.
#[allow(clippy::too_many_arguments)]
fn build_kernel<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    level: usize,
    g: &[f64],
    eps: f64,
    settings: &SinkhornSettings,
    wrap: Wrap,
    spacing: f64,
) -> Result<Kernel, SolveError> {
    let rows = hs.levels[level].len().max(1);
    let limit = pair_limit(rows);
    kernel::build(hs, ht, level, g, eps, settings.truncate, wrap, limit).ok_or_else(|| {
        let blur = eps.sqrt();
        SolveError::InvalidSettings {
            solver: NAME,
            field: "blur",
            reason: format!(
                "the truncated kernel at blur {blur:e} ({:.2} x the mean point spacing) would keep \
                 more than {limit} pairs for {rows} points (limits: {MAX_PAIRS_PER_POINT} per \
                 point, {MAX_PAIRS} in all, to keep memory linear in n): many points coincide, or \
                 the density is so uneven that its dense parts hold thousands of points within one \
                 blur; lower blur (or blur_spacing) or truncate, or use kind = \"sliced\"",
                blur / spacing
            ),
        }
    })
}

/// Rows per parallel work item.
const CHUNK: usize = 2048;

/// Over-relaxed Sinkhorn (Thibault, Chizat, Dossal, Papadakis 2021): a scaling moves ω times its
/// plain update in the log domain, s ← s^(1−ω) (m / Ks)^ω. Near convergence Sinkhorn's error
/// shrinks by a constant factor per iteration that tends to 1 as ε falls; ω in (1, 2) shrinks it
/// much faster. Measured (iterations over all stages): 50K 3D cow 568 → 197, 100K duck 1834 → 453,
/// 250K cow 868 → 335 (the final stage 226 → 98 iterations: 37.6 → 33.6 s of CPU; with the final
/// stage plain, 464). A safeguard returns to plain steps if the error ever grows 1000-fold (a
/// divergence; a factor 2 fired on the ordinary oscillations and cost most of the gain).
const OVER_RELAXATION: f64 = 1.8;

/// Plain iterations after each kernel build before over-relaxation starts (the first iterations
/// absorb the build's hard row minima).
const RELAX_AFTER: u32 = 5;

/// Over-relaxation stops (until the next build) when the error exceeds this multiple of the
/// lowest error seen since the build.
const RELAX_GROWTH: f64 = 1e3;

/// One scaling update, over-relaxed by `omega` (1: the plain update): old^(1−ω)·plain^ω, computed
/// as plain·(plain/old)^(ω−1) with one `powf` instead of two (about 12 ns each; `pow` was 6.5% of
/// the 1M cow's CPU time with two).
#[inline]
fn relax(old: f64, plain: f64, omega: f64) -> f64 {
    if omega == 1.0 {
        plain
    } else {
        plain * (plain / old).powf(omega - 1.0)
    }
}

/// A row or column has moved (and a local rebuild searches it again) when its potential is more
/// than τε = `LOCAL_MOVE`·θε from the last whole build's.
const LOCAL_MOVE: f64 = 1.0 / 16.0;

/// A rebuild *during* a stage (the drift passed 2θε, or θε for too long) searches again only the
/// rows and columns that moved more than `LOCAL_MOVE_MID`·θε. Only the end of a stage needs the
/// tight guarantee; in the middle, the support just has to follow the potentials. After a stage
/// transition half of the points have moved more than θε/16 (the entropic offsets at the new level
/// are noise of about ε/2 around the hard potentials a build starts from), but few move more than
/// θε/4, so these rebuilds search 5–10× fewer rows and columns.
const LOCAL_MOVE_MID: f64 = 1.0 / 4.0;

/// A rebuild once the error is within this factor of the tolerance is strict even during the stage
/// (see `iterate`): the 1M cow's final stage rebuilt loosely at iteration 33 and strictly at 35.
const NEAR_END: f64 = 10.0;

/// A local rebuild gives way to a whole one when more than 1/`LOCAL_SHARE` of the rows or of the
/// columns moved (searching them would cost about as much).
const LOCAL_SHARE: usize = 2;

/// Iterations after a kernel build beyond which a drift past θε forces a rebuild (see `iterate`):
/// without it, a stage whose scalings settle between θε and 2θε on a support that cannot carry the
/// marginals stalls (disconnected supports did, at 2e-3 after 2000 iterations).
const STALE_ITERATIONS: u32 = 50;

/// Sinkhorn iterations of one stage until the row marginal error (after a column update) is below
/// the tolerance or the iteration cap is hit.
#[allow(clippy::too_many_arguments)]
fn iterate<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    st: &mut State,
    settings: &SinkhornSettings,
    tol: f64,
    rebuilds: &mut u32,
    wrap: Wrap,
    spacing: f64,
) -> Result<StageLog, SolveError> {
    let (a, b) = (
        hs.levels[st.level].mass.clone(),
        ht.levels[st.level].mass.clone(),
    );
    let mut error = f64::INFINITY;
    let mut it = 0u32;
    // The kernel holds every pair within θε of its row's or column's best *for the potentials it
    // was built with*; once a scaling has moved a potential by more than θε/4 that guarantee is
    // for (θ/2)ε only, so the kernel is rebuilt around the current potentials (Schmitzer's
    // absorption and re-truncation). The rebuild is lazy: a stage that converges with a drift
    // above θε/4 is rebuilt and iterated on, so it never *ends* on a stale support, but during the
    // iterations a drift up to 2θε is allowed (the f64 scalings hold it easily). Drift comes from a
    // few hundred boundary points whose potentials move by several ε; rebuilding for each of them
    // cost 14 full kernel searches in the final stage at 50K points, lazily it takes 2–3. (The
    // limit was θε: 2θε took the 250K 3D cow's final stage from 7 to 5 kernel builds with the same
    // iterations, and the 250K duck from 17.4 to 15.4 s of CPU.)
    let drift_soft = (settings.truncate / 4.0).exp();
    // After a local rebuild dropped pairs are only (θ − 2τ)ε out (see `kernel::rebuild_local`), so a
    // stage ends only within (θ/4 − τ)ε of it: its final guarantee stays θε/2, as after a whole build.
    let tau = settings.truncate * LOCAL_MOVE;
    let drift_soft_local = (settings.truncate / 4.0 - tau).exp();
    let drift_hard = (2.0 * settings.truncate).exp();
    let drift_stale = settings.truncate.exp();
    let mut since_build = 0u32;
    let mut u_ref: Option<Vec<f64>> = None;
    // Over-relaxation (see OVER_RELAXATION): off for the first iterations after a build, off for
    // good (until the next build) once the error grows, and off before the stage may end, so the
    // stage's last iteration is a plain Sinkhorn step with exact column marginals.
    let mut plain = false;
    let mut prev_plain = true;
    let mut lowest = f64::INFINITY;
    while it < settings.max_iterations {
        it += 1;
        // Row update; its error term is the row marginal of the previous column update.
        let (kern, v, uref) = (&st.kernel, &st.v, u_ref.as_deref());
        let omega = if plain || since_build < RELAX_AFTER {
            1.0
        } else {
            OVER_RELAXATION
        };
        let rows: Vec<(f64, f64)> =
            st.u.par_chunks_mut(CHUNK)
                .enumerate()
                .map(|(c, uc)| {
                    let mut e = 0.0;
                    let mut far = 0f64;
                    for (k, u) in uc.iter_mut().enumerate() {
                        let i = c * CHUNK + k;
                        let mut s = 0.0;
                        for p in kern.row_ptr[i]..kern.row_ptr[i + 1] {
                            s += f64::from(kern.k[p]) * v[kern.col[p] as usize];
                        }
                        e += (*u * s - a[i]).abs();
                        *u = relax(*u, a[i] / s, omega);
                        if let Some(r0) = uref {
                            let r = *u / r0[i];
                            let r = r.max(1.0 / r);
                            far = if r.is_nan() {
                                f64::INFINITY
                            } else {
                                far.max(r)
                            };
                        }
                    }
                    (e, far)
                })
                .collect();
        error = rows.iter().map(|r| r.0).sum();
        let rows_far = rows.iter().map(|r| r.1).fold(0.0, f64::max);
        if u_ref.is_none() {
            u_ref = Some(st.u.clone());
        }
        // Column update.
        let u = &st.u;
        let drift: Vec<f64> =
            st.v.par_chunks_mut(CHUNK)
                .enumerate()
                .map(|(c, vc)| {
                    let mut far = 0f64;
                    for (k, v) in vc.iter_mut().enumerate() {
                        let j = c * CHUNK + k;
                        let mut t = 0.0;
                        for p in kern.col_ptr[j]..kern.col_ptr[j + 1] {
                            t += f64::from(kern.kt[p]) * u[kern.row[p] as usize];
                        }
                        *v = relax(*v, b[j] / t, omega);
                        let r = *v / b[j];
                        let r = r.max(1.0 / r);
                        far = if r.is_nan() {
                            f64::INFINITY
                        } else {
                            far.max(r)
                        };
                    }
                    far
                })
                .collect();
        if !error.is_finite() || st.v.iter().any(|v| !v.is_finite()) {
            return Err(SolveError::NotConverged {
                solver: NAME,
                residual: error,
                threshold: settings.tolerance,
                iterations: it,
                hint: format!(
                    "a scaling became non-finite at blur {:e} (level {}); this is a bug: please \
                     report the inputs",
                    st.eps.sqrt(),
                    st.level
                ),
                report: Box::new(Report {
                    solver: NAME,
                    cost: f64::NAN,
                    iterations: it,
                    converged: false,
                    residual: error,
                    detail: "non-finite scaling".into(),
                }),
            });
        }
        let cols_far = drift.iter().fold(1f64, |a, &d| a.max(d));
        let far = rows_far.max(cols_far);
        // A dropped pair moved by its row's drift plus its column's (in units of ε): the end of a
        // stage bounds that sum by twice the soft limit, which is what the θε/2 guarantee needs,
        // rather than each part by the limit (a stage whose rows drifted a little more than the
        // limit and whose columns stayed put no longer needs a rebuild).
        let pair_drift = rows_far.max(1.0) * cols_far;
        // The error is the row marginal of the previous iteration's plan, whose columns are exact
        // only if that iteration was plain.
        let converged = it > 1 && error <= tol && prev_plain;
        if error <= tol || error > RELAX_GROWTH * lowest {
            plain = true;
        }
        lowest = lowest.min(error);
        prev_plain = omega == 1.0;
        let soft = match st.support {
            Support::Whole => drift_soft,
            Support::Local => drift_soft_local,
            // Never ends a stage.
            Support::Loose => 0.0,
        };
        if converged && pair_drift <= soft * soft {
            return Ok(StageLog {
                iterations: it,
                converged: true,
                error,
            });
        }
        since_build += 1;
        // A support that has drifted past θε may be unable to carry the marginals at all (the
        // stage would stall short of the tolerance): past θε a stage gets STALE_ITERATIONS more.
        let stale = far > drift_stale && since_build >= STALE_ITERATIONS;
        if far > drift_hard || stale || (converged && pair_drift > soft * soft) {
            // Absorb and rebuild the kernel around the new potentials: locally (only the rows and
            // columns that moved) while few moved, else whole; loosely unless the stage is ending.
            // Near the end (the error within NEAR_END of the tolerance) a rebuild is strict at
            // once: the stage would end on it, and a loose one would need a strict one after it.
            let mid = !converged && error > NEAR_END * tol;
            let g = absorbed(&st.g, &st.v, &b, st.eps);
            let tk = std::time::Instant::now();
            let rows = hs.levels[st.level].len();
            let limit = pair_limit(rows);
            let local = kernel::rebuild_local(
                hs,
                ht,
                st.level,
                &st.kernel,
                &g,
                &st.f0,
                &st.g0,
                st.eps,
                kernel::LocalLimits {
                    theta: settings.truncate,
                    tau: if mid {
                        settings.truncate * LOCAL_MOVE_MID
                    } else {
                        tau
                    },
                    // Whole once a strict local rebuild could not be local any more: the stage's
                    // end would need that whole build anyway, and it is best done now.
                    tau_whole: tau,
                    max_moved: rows.max(ht.levels[st.level].len()) / LOCAL_SHARE,
                    max_pairs: limit,
                },
                wrap,
            );
            let how = match local {
                Some(kernel::Local::Built(k, r, c)) => {
                    st.kernel = k;
                    st.support = if mid { Support::Loose } else { Support::Local };
                    format!(
                        "local ({r} rows, {c} columns{})",
                        if mid { ", loose" } else { "" }
                    )
                }
                Some(kernel::Local::TooMany) | None => {
                    // Past the pair limit the whole build decides (and reports it).
                    st.kernel =
                        build_kernel(hs, ht, st.level, &g, st.eps, settings, wrap, spacing)?;
                    st.f0 = st.kernel.f.clone();
                    st.g0 = g.clone();
                    st.support = Support::Whole;
                    "whole".to_string()
                }
            };
            if std::env::var_os("OTBAKE_TRACE").is_some() {
                eprintln!(
                    "  rebuild at it {it} (drift e^{:.2}) {how} {:.2}s",
                    far.ln(),
                    tk.elapsed().as_secs_f64()
                );
            }
            st.g = g;
            st.u = a.clone();
            st.v = b.clone();
            u_ref = None;
            since_build = 0;
            plain = false;
            lowest = f64::INFINITY;
            *rebuilds += 1;
        }
    }
    Ok(StageLog {
        iterations: it,
        converged: false,
        error,
    })
}

/// T(x_i) = Σ_j K_ij v_j y_j / Σ_j K_ij v_j (u_i cancels) on the point level; on the torus
/// x_i + Σ_j K_ij v_j δ(x_i, y_j) / Σ_j K_ij v_j, the mean of the shortest displacements (the plan of
/// a row is concentrated within a few blurs of x_i, far less than half a period).
fn barycentric<const D: usize>(
    st: &State,
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    wrap: Wrap,
) -> Vec<[f64; D]> {
    let (x, y) = (&hs.levels[st.level].pos, &ht.levels[st.level].pos);
    let kern = &st.kernel;
    // x_i plus the weighted mean of the shortest displacements: the plain weighted mean of the y_j
    // in the Euclidean case, and on the torus the circular mean around x_i.
    (0..kern.row_ptr.len() - 1)
        .into_par_iter()
        .map(|i| {
            let mut acc = [0.0; D];
            let mut w = 0.0;
            for p in kern.row_ptr[i]..kern.row_ptr[i + 1] {
                let j = kern.col[p] as usize;
                let kv = f64::from(kern.k[p]) * st.v[j];
                w += kv;
                for a in 0..D {
                    acc[a] += kv * delta(wrap, x[i][a], y[j][a]);
                }
            }
            std::array::from_fn(|a| x[i][a] + acc[a] / w)
        })
        .collect()
}

/// What the one-to-one refinement did.
struct RefineInfo {
    x: Vec<u32>,
    unassigned: usize,
    phases: u32,
    bids: u64,
    /// Dense augmenting paths that completed the sparse auction.
    paths: u32,
}

impl RefineInfo {
    /// The matching in the caller's indices.
    fn to_original<const D: usize>(&self, hs: &Hierarchy<D>, ht: &Hierarchy<D>) -> Vec<u32> {
        let mut out = vec![0u32; self.x.len()];
        for (k, &j) in self.x.iter().enumerate() {
            out[hs.order[k] as usize] = ht.order[j as usize];
        }
        out
    }
}

/// The auction's first ε as a fraction of the final Sinkhorn ε, by dimension (1D to 4D; it goes
/// down from there by 4 per phase to `auction_eps`, 1/4 by default). In 3D, at the default blur of
/// one point spacing, the Sinkhorn potentials are already good prices at ε/4: one phase there took
/// 1.58M bids (0.75 s) on the 250K cow instead of 3.23M in two phases from ε (1.75 s), and 10.8M
/// instead of 17.8M bids on the 1M cow (5.8 s instead of 10.2 s), with the same cost to 7 digits.
/// In 2D, at 1.5 spacings, the first phase pays: the 250K duck (seed 0) took 6.18M bids from ε,
/// 6.84M from ε/2 and 7.37M from ε/4.
const AUCTION_START: [f64; 4] = [1.0, 1.0, 0.25, 0.25];

/// Most rows completed by dense augmenting paths (O(n) per scan step each) after the sparse auction;
/// beyond it the support is too poor and the map falls back to the barycentric projection.
const MAX_DENSE_PATHS: usize = 2000;

/// Sparse auction on the final kernel's support, started from the Sinkhorn target potential.
///
/// The auction runs on reduced costs C_ij − f_i − g_j with prices relative to g (both start at
/// the Sinkhorn potentials, so prices start at 0): a row constant changes no bid, and the
/// candidates' reduced costs are small (a few ε), so one `f32` per pair holds them to within
/// 1e-7 of their size, far below the auction's final ε. They are computed once, in parallel, and
/// the bids read them in order instead of computing costs from positions.
fn refine_assignment<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    st: &State,
    g: Vec<f64>,
    side: f64,
    auction_eps: f64,
    wrap: Wrap,
) -> Result<(Vec<u32>, RefineInfo), RefineInfo> {
    let (x, y) = (&hs.levels[st.level].pos, &ht.levels[st.level].pos);
    let (row_ptr, col) = (&st.kernel.row_ptr, &st.kernel.col);
    let rows = row_ptr.len() - 1;
    // Per row: f_i = min over the candidates of C_ij − g_j, then the candidates' C_ij − g_j − f_i.
    let chunks: Vec<(Vec<f64>, Vec<f32>)> = (0..rows.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let (a, b) = (c * CHUNK, ((c + 1) * CHUNK).min(rows));
            let mut f = Vec::with_capacity(b - a);
            let mut red = Vec::with_capacity(row_ptr[b] - row_ptr[a]);
            let mut h = Vec::new();
            for i in a..b {
                h.clear();
                h.extend(
                    col[row_ptr[i]..row_ptr[i + 1]]
                        .iter()
                        .map(|&j| sq(wrap, &x[i], &y[j as usize]) - g[j as usize]),
                );
                let m = h.iter().copied().fold(f64::INFINITY, f64::min);
                let m = if m.is_finite() { m } else { 0.0 };
                // Rounded to f32 only once the row constant is out.
                red.extend(h.iter().map(|&h| (h - m) as f32));
                f.push(m);
            }
            (f, red)
        })
        .collect();
    let mut f = Vec::with_capacity(rows);
    let mut red = Vec::with_capacity(col.len());
    for (fc, rc) in chunks {
        f.extend(fc);
        red.extend(rc);
    }
    let cost = |i: usize, j: usize| sq(wrap, &x[i], &y[j]) - f[i] - g[j];
    let graph = Graph {
        row_ptr,
        col,
        cols: y.len(),
        cost,
        pair_cost: Some(&red),
    };
    let n_cols = y.len();
    let mut v = vec![0.0; n_cols];
    let m = auction(
        &graph,
        &mut v,
        st.eps * AUCTION_START[D.min(4) - 1],
        st.eps * auction_eps,
        4.0,
        side * side * D as f64,
        // Rows the sparse graph cannot place (it may lack a perfect matching, or a price war would
        // be slow) are completed by dense shortest augmenting paths, up to a limit.
        |free, xs, ys, v| {
            if free.len() > MAX_DENSE_PATHS {
                return 0;
            }
            super::exact::augment(n_cols, &cost, free, xs, ys, v)
        },
    );
    let info = RefineInfo {
        unassigned: m.unassigned,
        phases: m.phases,
        bids: m.bids,
        paths: m.completed,
        x: m.x,
    };
    if info.unassigned == 0 {
        Ok((info.x.clone(), info))
    } else {
        Err(info)
    }
}

fn total_iterations(logs: &[StageLog]) -> u32 {
    logs.iter().map(|l| l.iterations).sum()
}

#[allow(clippy::too_many_arguments)]
fn report_of(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    earlier: &[StageLog],
    last: &StageLog,
    blur_end: f64,
    rebuilds: u32,
    max_pairs: usize,
    refine: Option<&RefineInfo>,
) -> Report {
    let capped = earlier.iter().filter(|l| !l.converged).count();
    let iterations = total_iterations(earlier) + last.iterations;
    let (map, refined_ok) = match (settings.map, refine) {
        (MapKind::Barycentric, _) => ("barycentric".to_string(), true),
        (MapKind::Assignment, Some(r)) if r.unassigned == 0 => (
            format!(
                "assignment (auction: {} phases, {} bids, {} dense augmenting paths)",
                r.phases, r.bids, r.paths
            ),
            true,
        ),
        (MapKind::Assignment, Some(r)) => (
            format!(
                "barycentric FALLBACK: the auction left {} of {n} rows unmatched on the kernel \
                 support ({} phases, {} bids)",
                r.unassigned, r.phases, r.bids
            ),
            false,
        ),
        (MapKind::Assignment, None) => ("none".to_string(), false),
    };
    Report {
        solver: NAME,
        // Set by the caller once the map exists (NaN in the reports of failed runs).
        cost: f64::NAN,
        iterations,
        converged: last.converged && refined_ok,
        residual: last.error,
        detail: format!(
            "sinkhorn: n={n}, dim={}, final blur={blur_end:e}, stages={} ({capped} capped before \
             the last), iterations={iterations}, kernel rebuilds={rebuilds}, max pairs={max_pairs}, \
             final marginal error={:e}, map={map}",
            problem.dim,
            earlier.len() + 1,
            last.error
        ),
    }
}

/// All points coincide: the identity matching is optimal.
fn finish_identity(problem: &Problem<'_>, n: usize) -> Solution {
    Solution {
        mapped: problem.target.to_vec(),
        assignment: Some((0..n as u32).collect()),
        report: Report {
            solver: NAME,
            cost: 0.0,
            iterations: 0,
            converged: true,
            residual: 0.0,
            detail: format!("sinkhorn: n={n}, all points coincide: identity matching"),
        },
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod torus_tests;
