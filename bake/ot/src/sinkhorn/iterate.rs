//! The scaling iterations of one stage, with the kernel rebuilds they trigger.

use super::hierarchy::Hierarchy;
use super::kernel::{self, Kernel};
use super::potentials::{absorbed, hard_transform};
use super::state::{StageLog, State, Support};
use super::{SinkhornSettings, CHUNK, NAME};
use crate::{Report, SolveError, Wrap};
use rayon::prelude::*;

/// Largest kernel, in pairs per point, before the solver refuses: beyond it the blur is far above
/// the point spacing or many points coincide, and memory would no longer be linear in n.
const MAX_PAIRS_PER_POINT: usize = 4096;

/// Largest kernel in all for small n: 2^27 pairs take 1 GB in the kernel's arrays (8 bytes per
/// pair since the kernel is kept in row form only). A BRDF whose density is concentrated in a
/// specular peak reached 19 GB before this limit.
const MAX_PAIRS: usize = 1 << 27;

/// Above [`MAX_PAIRS`], pairs allowed per row: 2.4 times the ~68 per point the default blur keeps
/// in 3D (and 63 in 2D), so that the limit scales with n (a 16M-point bake keeps about 1.1G pairs
/// at the defaults) while a kernel whose density is far from uniform is still refused. What
/// memory a bake may use is decided before the solve, from the estimate of the solver's peak.
const MAX_PAIRS_PER_POINT_LARGE: usize = 160;

/// Most pairs a kernel on `rows` rows may keep: [`MAX_PAIRS_PER_POINT`] per row, and in all the
/// larger of [`MAX_PAIRS`] and [`MAX_PAIRS_PER_POINT_LARGE`] per row.
pub(crate) fn pair_limit(rows: usize) -> usize {
    let rows = rows.max(1);
    MAX_PAIRS_PER_POINT
        .saturating_mul(rows)
        .min(MAX_PAIRS.max(MAX_PAIRS_PER_POINT_LARGE.saturating_mul(rows)))
}

/// Builds a stage's kernel, refusing one whose size is no longer linear in n (more than
/// [`MAX_PAIRS_PER_POINT`] per point, or [`MAX_PAIRS`] in all): the search stops as soon as it has
/// found that many pairs, so the refusal costs bounded memory.
#[allow(clippy::too_many_arguments)]
pub(super) fn build_kernel<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    level: usize,
    g: &[f64],
    eps: f64,
    settings: &SinkhornSettings,
    wrap: Wrap,
    spacing: f64,
    upper: Option<&[f64]>,
) -> Result<Kernel, SolveError> {
    let rows = hs.levels[level].len().max(1);
    let limit = pair_limit(rows);
    let truncate = settings.theta(D);
    kernel::build(hs, ht, level, g, eps, truncate, wrap, limit, upper).ok_or_else(|| {
        let blur = eps.sqrt();
        SolveError::InvalidSettings {
            solver: NAME,
            field: "blur",
            reason: format!(
                "the truncated kernel at blur {blur:e} ({:.2} x the point spacing) would keep \
                 more than {limit} pairs for {rows} points (limits: {MAX_PAIRS_PER_POINT} per \
                 point, {MAX_PAIRS} or {MAX_PAIRS_PER_POINT_LARGE} per point in all, to keep \
                 memory linear in n): many points coincide, or \
                 the density is so uneven that its dense parts hold thousands of points within one \
                 blur; lower blur (or blur_spacing) or truncate, or use kind = \"sliced\"",
                blur / spacing
            ),
        }
    })
}

/// Over-relaxed Sinkhorn (Thibault, Chizat, Dossal, Papadakis 2021): a scaling moves ω times its
/// plain update in the log domain, s ← s^(1−ω) (m / Ks)^ω. Near convergence Sinkhorn's error
/// shrinks by a constant factor per iteration that tends to 1 as ε falls; ω in (1, 2) shrinks it
/// much faster. Measured (iterations over all stages): 50K 3D cow 568 → 197, 100K duck 1834 → 453,
/// 250K cow 868 → 335 (the final stage 226 → 98 iterations, 11% less CPU; with the final stage
/// plain, 464). A safeguard returns to plain steps if the error ever grows 1000-fold (a
/// divergence; a factor 2 fired on the ordinary oscillations and cost most of the gain).
const OVER_RELAXATION: f64 = 1.8;

/// ω of the stages on cells. They are the slow ones: their error falls about as 1/t for hundreds
/// of iterations (the 1M cow's last cell stage took 298 at 1.8, a third of the solve's CPU time),
/// the regime where the best ω is nearer 2; 1.9 took that stage to 64 iterations (78 with the
/// probes of [`PROBE_EVERY`]) and its level-6 stage from 132 to 78 (D150). On the points 1.9 was
/// no better or worse (250K cow 101 → 107 iterations, 250K duck 22 → 39), so the final stage
/// keeps [`OVER_RELAXATION`].
const OVER_RELAXATION_CELLS: f64 = 1.9;

/// Every `PROBE_EVERY`-th over-relaxed iteration is a plain one: a stage can only end on a plain
/// step (exact column marginals), and the error seen after over-relaxed steps overstates the
/// plain one many times (the 1M cow's final stage read 1.7e-3 for 50 iterations; one plain step
/// then read 3.3e-4). Probing every 10 iterations ended that stage at 43 iterations instead of 67,
/// and the 250K cow's at 51 instead of 101 (D150).
const PROBE_EVERY: u32 = 10;

/// Plain iterations after each kernel build before over-relaxation starts (the first iterations
/// absorb the build's hard row minima).
const RELAX_AFTER: u32 = 5;

/// Over-relaxation stops (until the next build) when the error exceeds this multiple of the
/// lowest error seen since the build.
const RELAX_GROWTH: f64 = 1e3;

/// One scaling update, over-relaxed by `omega` (1: the plain update): old^(1−ω)·plain^ω, computed
/// as plain·exp((ω−1)·ln(plain/old)): one power instead of two (two `pow` were 6.5% of the 1M
/// cow's CPU time), and `ln` then `exp` cost less than `powf` (which was still 4%, D155).
#[inline]
fn relax(old: f64, plain: f64, omega: f64) -> f64 {
    if omega == 1.0 {
        plain
    } else {
        plain * ((omega - 1.0) * (plain / old).ln()).exp()
    }
}

/// A row or column has moved (and a local rebuild searches it again) when its potential is more
/// than τε = `LOCAL_MOVE`·θε from where it was last searched (by the last whole build or a local
/// rebuild since, D163). A larger τ lets a stage end on a local rebuild where a smaller one would
/// find most points moved and rebuild whole (the final stage's entropic offsets move half of the
/// points by more than θε/16), at the price of a tighter end
/// (drift within (θ/4 − τ)ε after it). θ/8 rather than θ/16 (D148): 250K cow 21.0 → 17.5 s user,
/// duck 7.9 → 6.7 s, the 1M cow 80.1 → 77.6 s wall; the 5K accuracy within 2% of before.
pub(super) const LOCAL_MOVE: f64 = 1.0 / 8.0;

/// A rebuild *during* a stage (the drift passed 2θε, or θε for too long) searches again only the
/// rows and columns that moved more than `LOCAL_MOVE_MID`·θε. Only the end of a stage needs the
/// tight guarantee; in the middle, the support just has to follow the potentials. After a stage
/// transition half of the points have moved more than θε/16 (the entropic offsets at the new level
/// are noise of about ε/2 around the hard potentials a build starts from), but few move more than
/// θε/4, so these rebuilds search 5–10× fewer rows and columns.
pub(super) const LOCAL_MOVE_MID: f64 = 1.0 / 4.0;

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

/// The drift limits of a stage, as factors of the scalings (see [`iterate`]).
struct Drift {
    /// A stage may end below it (after a whole build).
    soft: f64,
    /// A stage may end below it (after a local rebuild).
    soft_local: f64,
    /// A rebuild at once past it.
    hard: f64,
    /// A rebuild past it once the support is [`STALE_ITERATIONS`] old.
    stale: f64,
    /// τ of strict local rebuilds, in units of ε.
    tau: f64,
}

impl Drift {
    fn new(truncate: f64) -> Self {
        let soft = (truncate / 4.0).exp();
        // After a local rebuild dropped pairs are only (θ − 2τ)ε out (see `kernel::rebuild_local`),
        // so a stage ends only within (θ/4 − τ)ε of it: its final guarantee stays θε/2, as after a
        // whole build.
        let tau = truncate * LOCAL_MOVE;
        let soft_local = (truncate / 4.0 - tau).exp();
        let hard = (2.0 * truncate).exp();
        let stale = truncate.exp();
        Self {
            soft,
            soft_local,
            hard,
            stale,
            tau,
        }
    }
}

/// What a stage iterates to.
#[derive(Clone, Copy, Debug)]
pub(super) struct Goal {
    /// Row marginal error (L1) the stage ends below.
    pub tolerance: f64,
    /// The last stage, whose plan the map is read off: it ends only on a support within its drift
    /// limits. An earlier one ends on its tolerance alone, and a stale support waits twice
    /// [`STALE_ITERATIONS`] once the stage is near its end: its plan only seeds the next stage,
    /// whose kernel is built whole around the potentials it hands on, so a strict rebuild and the
    /// iterations after it would be paid for nothing (docs/decisions.md, D161).
    pub last: bool,
}

/// Sinkhorn iterations of one stage until the row marginal error (after a column update) is below
/// the tolerance or the iteration cap is hit.
///
/// The kernel holds every pair within θε of its row's or column's best *for the potentials it was
/// built with*; once a scaling has moved a potential by more than θε/4 that guarantee is for (θ/2)ε
/// only, so the kernel is rebuilt around the current potentials (Schmitzer's absorption and
/// re-truncation, [`Rebuild`]). The rebuild is lazy: a last stage that converges with a drift
/// above θε/4 is rebuilt and iterated on, so it never *ends* on a stale support ([`Goal`]), but
/// during the iterations a drift up to 2θε is allowed (the f64 scalings hold it easily). Drift
/// comes from a few hundred boundary points whose potentials move by several ε; rebuilding for
/// each of them cost 14 full kernel searches in the final stage at 50K points, lazily it takes
/// 2–3. (The limit was θε: 2θε took the 250K 3D cow's final stage from 7 to 5 kernel builds with
/// the same iterations, and cut the 250K duck's CPU time by 11%.)
#[allow(clippy::too_many_arguments)]
pub(super) fn iterate<const D: usize>(
    hs: &Hierarchy<D>,
    ht: &Hierarchy<D>,
    st: &mut State,
    settings: &SinkhornSettings,
    goal: Goal,
    rebuilds: &mut u32,
    wrap: Wrap,
    spacing: f64,
) -> Result<StageLog, SolveError> {
    let (a, b) = (&hs.levels[st.level].mass[..], &ht.levels[st.level].mass[..]);
    let mut sw = Sweep::new(&st.kernel);
    if std::env::var_os("OTBAKE_TRACE").is_some() {
        eprintln!(
            "  kernel {} MB, column sums {} MB",
            st.kernel.bytes() >> 20,
            sw.bytes() >> 20
        );
    }
    let tol = goal.tolerance;
    let mut error = f64::INFINITY;
    let mut it = 0u32;
    let drift = Drift::new(settings.theta(D));
    let mut since_build = 0u32;
    let mut u_ref: Option<Vec<f64>> = None;
    // Over-relaxation (see OVER_RELAXATION): off for the first iterations after a build, off for
    // good (until the next build) once the error grows, off for one probe in every PROBE_EVERY,
    // and off before the stage may end, so the stage's last iteration is a plain Sinkhorn step
    // with exact column marginals.
    let mut plain = false;
    let mut prev_plain = true;
    let mut lowest = f64::INFINITY;
    let relaxed = if st.level < hs.point_level() {
        OVER_RELAXATION_CELLS
    } else {
        OVER_RELAXATION
    };
    while it < settings.max_iterations {
        it += 1;
        let probe = since_build >= RELAX_AFTER
            && (since_build - RELAX_AFTER) % PROBE_EVERY == PROBE_EVERY - 1;
        let omega = if plain || since_build < RELAX_AFTER || probe {
            1.0
        } else {
            relaxed
        };
        // Row and column update; the error is the row marginal of the previous column update.
        let swept = sweep(st, &mut sw, (a, b), u_ref.as_deref(), omega);
        error = swept.error;
        if std::env::var("OTBAKE_TRACE").as_deref() == Ok("2") {
            trace_iteration(st, b, u_ref.as_deref(), it, omega, &swept);
        }
        let (rows_far, cols_far) = (swept.rows_far, swept.cols_far);
        if u_ref.is_none() {
            u_ref = Some(st.u.clone());
        }
        if !error.is_finite() || !swept.finite {
            return Err(non_finite(st, settings, it, error));
        }
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
            Support::Whole => drift.soft,
            Support::Local => drift.soft_local,
            // Never ends the last stage.
            Support::Loose => 0.0,
        };
        // An earlier stage's plan only seeds the next stage, whose kernel is built whole from its
        // potentials: it ends on its tolerance whatever the drift (see `Goal::last`).
        if converged && (pair_drift <= soft * soft || !goal.last) {
            return Ok(StageLog {
                iterations: it,
                converged: true,
                error,
            });
        }
        since_build += 1;
        // A support that has drifted past θε may be unable to carry the marginals at all (the
        // stage would stall short of the tolerance): past θε a stage gets STALE_ITERATIONS more.
        // An earlier stage about to end gets twice that (see `Goal::last`).
        let patience = if !goal.last && lowest <= NEAR_END * tol {
            2 * STALE_ITERATIONS
        } else {
            STALE_ITERATIONS
        };
        let stale = far > drift.stale && since_build >= patience;
        if far > drift.hard || stale || (converged && pair_drift > soft * soft) {
            // Absorb and rebuild the kernel around the new potentials: locally (only the rows and
            // columns that moved) while few moved, else whole; loosely unless the stage is ending.
            // Near the end (the error within NEAR_END of the tolerance) a rebuild is strict at
            // once: the stage would end on it, and a loose one would need a strict one after it.
            let mid = !converged && error > NEAR_END * tol;
            let rebuild = Rebuild {
                mid,
                tau: drift.tau,
                it,
                far,
            };
            rebuild.run(hs, ht, st, settings, (a, b), wrap, spacing)?;
            sw = Sweep::new(&st.kernel);
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

/// Row blocks of a sweep, fixed whatever the thread count: each block scatters its rows' share of
/// the column sums into its own array, and the arrays are added in block order, so the sums (and
/// the maps) do not depend on the thread count.
const BLOCKS: usize = 8;

/// The column sums of one sweep: per block of rows, its rows and the column range its rows touch.
pub(super) struct Sweep {
    blocks: Vec<Block>,
}

struct Block {
    rows: std::ops::Range<usize>,
    /// First column of `sums`.
    first: usize,
    sums: Vec<f64>,
}

impl Sweep {
    /// Blocks splitting the pairs of `kern` about evenly, each summing over the columns its rows
    /// touch (rows and columns are both in Morton order, so a block's columns are a narrow range
    /// for nearly every map).
    pub fn new(kern: &Kernel) -> Self {
        let rows = kern.row_ptr.len() - 1;
        let total = kern.pairs();
        let mut cuts = vec![0usize];
        for b in 1..BLOCKS {
            let at = kern
                .row_ptr
                .partition_point(|&p| p < total * b / BLOCKS)
                .min(rows);
            if at > *cuts.last().unwrap() {
                cuts.push(at);
            }
        }
        if *cuts.last().unwrap() < rows || cuts.len() == 1 {
            cuts.push(rows);
        }
        let blocks = cuts
            .windows(2)
            .map(|w| {
                let cols = &kern.col[kern.row_ptr[w[0]]..kern.row_ptr[w[1]]];
                let lo = cols.iter().copied().min().unwrap_or(0) as usize;
                let hi = cols.iter().copied().max().map_or(0, |c| c as usize + 1);
                Block {
                    rows: w[0]..w[1],
                    first: lo,
                    sums: vec![0.0; hi.saturating_sub(lo)],
                }
            })
            .collect();
        Self { blocks }
    }

    /// Bytes of the column sums.
    pub fn bytes(&self) -> usize {
        self.blocks.iter().map(|b| b.sums.len() * 8).sum()
    }
}

/// What one sweep found.
struct Swept {
    /// Row marginal error of the plan before the sweep.
    error: f64,
    /// Largest drift factor of u against `uref`, and of v against the masses.
    rows_far: f64,
    cols_far: f64,
    /// Every new v is finite.
    finite: bool,
}

/// One Sinkhorn iteration in one pass over the kernel's rows: u_i ← relax(u_i, a_i / (K v)_i), and
/// at once K_ij u_i (new u) added to column j's sum; then v_j ← relax(v_j, b_j / Σ_i K_ij u_i).
/// The error is the row marginal of the plan before the update (Σ_i |u_i (K v)_i − a_i|, summed in
/// row order per block, blocks in order). Reading each pair once per iteration instead of twice
/// (rows, then the column form) halves the memory traffic and the kernel's size.
fn sweep(
    st: &mut State,
    sw: &mut Sweep,
    (a, b): (&[f64], &[f64]),
    uref: Option<&[f64]>,
    omega: f64,
) -> Swept {
    let (kern, v) = (&st.kernel, &st.v);
    let mut u_parts = Vec::with_capacity(sw.blocks.len());
    let mut rest = &mut st.u[..];
    for blk in &sw.blocks {
        let (p, r) = std::mem::take(&mut rest).split_at_mut(blk.rows.len());
        rest = r;
        u_parts.push(p);
    }
    let rows: Vec<(f64, f64)> = sw
        .blocks
        .par_iter_mut()
        .zip(u_parts)
        .map(|(blk, us)| {
            blk.sums.iter_mut().for_each(|s| *s = 0.0);
            let mut e = 0.0;
            let mut far = 0f64;
            for (i, u) in blk.rows.clone().zip(us.iter_mut()) {
                let r = kern.row_ptr[i]..kern.row_ptr[i + 1];
                let (cols, ks) = (&kern.col[r.clone()], &kern.k[r]);
                let s = row_dot(cols, ks, v);
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
                let w = *u;
                for (&j, &k) in cols.iter().zip(ks) {
                    blk.sums[j as usize - blk.first] += f64::from(k) * w;
                }
            }
            (e, far)
        })
        .collect();
    let error = rows.iter().map(|r| r.0).sum();
    let rows_far = rows.iter().map(|r| r.1).fold(0.0, f64::max);
    let blocks = &sw.blocks;
    let cols: Vec<(f64, bool)> =
        st.v.par_chunks_mut(CHUNK)
            .enumerate()
            .map(|(c, vc)| {
                let mut far = 0f64;
                let mut finite = true;
                // The chunk's column sums, block by block in block order (each block adds the
                // slice of its range that overlaps the chunk).
                let (c0, c1) = (c * CHUNK, c * CHUNK + vc.len());
                let mut sums = [0.0f64; CHUNK];
                for blk in blocks {
                    let (lo, hi) = (c0.max(blk.first), c1.min(blk.first + blk.sums.len()));
                    if lo < hi {
                        let src = &blk.sums[lo - blk.first..hi - blk.first];
                        for (acc, s) in sums[lo - c0..hi - c0].iter_mut().zip(src) {
                            *acc += s;
                        }
                    }
                }
                for (k, v) in vc.iter_mut().enumerate() {
                    let j = c0 + k;
                    let t = sums[k];
                    *v = relax(*v, b[j] / t, omega);
                    finite &= v.is_finite();
                    let r = *v / b[j];
                    let r = r.max(1.0 / r);
                    far = if r.is_nan() {
                        f64::INFINITY
                    } else {
                        far.max(r)
                    };
                }
                (far, finite)
            })
            .collect();
    Swept {
        error,
        rows_far,
        cols_far: cols.iter().map(|c| c.0).fold(1f64, f64::max),
        finite: cols.iter().all(|c| c.1),
    }
}

/// Σ_p k_p v[col_p] over one kernel row, in four interleaved partial sums (added in a fixed order):
/// one running sum made every pair wait for the previous pair's addition.
#[inline]
fn row_dot(cols: &[u32], ks: &[f32], v: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (c4, k4) = (cols.chunks_exact(4), ks.chunks_exact(4));
    let (cr, kr) = (c4.remainder(), k4.remainder());
    for (c, k) in c4.zip(k4) {
        for l in 0..4 {
            acc[l] += f64::from(k[l]) * v[c[l] as usize];
        }
    }
    for (l, (&j, &k)) in cr.iter().zip(kr).enumerate() {
        acc[l] += f64::from(k) * v[j as usize];
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

/// One line per iteration (`OTBAKE_TRACE=2`): the error, the largest drifts (log) and how many
/// rows and columns drifted more than ε and 4ε, which tell a slide of the whole potential from a
/// few points running away.
fn trace_iteration(st: &State, b: &[f64], u_ref: Option<&[f64]>, it: u32, omega: f64, sw: &Swept) {
    let count = |x: &[f64], r: &[f64], t: f64| {
        x.iter()
            .zip(r)
            .filter(|(x, r)| (*x / *r).ln().abs() > t)
            .count()
    };
    let (r1, r4) = u_ref.map_or((0, 0), |r| (count(&st.u, r, 1.0), count(&st.u, r, 4.0)));
    let (c1, c4) = (count(&st.v, b, 1.0), count(&st.v, b, 4.0));
    eprintln!(
        "    it {it} omega {omega:.2} err {:.3e} drift {:.2} {:.2} rows >1 {r1} >4 {r4} columns >1 \
         {c1} >4 {c4}",
        sw.error,
        sw.rows_far.ln(),
        sw.cols_far.ln()
    );
}

/// The error of a scaling that became non-finite.
fn non_finite(st: &State, settings: &SinkhornSettings, it: u32, error: f64) -> SolveError {
    SolveError::NotConverged {
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
    }
}

/// A kernel rebuild during a stage: what triggered it and how strict it is.
struct Rebuild {
    /// During the stage (loose: τ = `LOCAL_MOVE_MID`·θ) rather than near or at its end.
    mid: bool,
    /// τ of strict local rebuilds.
    tau: f64,
    /// The iteration and the drift factor (for the trace).
    it: u32,
    far: f64,
}

impl Rebuild {
    /// Absorbs the scalings into the potentials and rebuilds the kernel around them: locally if
    /// few rows and columns moved, else whole; then resets the scalings to the masses `(a, b)`.
    #[allow(clippy::too_many_arguments)]
    fn run<const D: usize>(
        &self,
        hs: &Hierarchy<D>,
        ht: &Hierarchy<D>,
        st: &mut State,
        settings: &SinkhornSettings,
        (a, b): (&[f64], &[f64]),
        wrap: Wrap,
        spacing: f64,
    ) -> Result<(), SolveError> {
        let Rebuild { mid, tau, it, far } = *self;
        let g = absorbed(&st.g, &st.v, b, st.eps);
        let tk = std::time::Instant::now();
        let rows = hs.levels[st.level].len();
        let limit = pair_limit(rows);
        let theta = settings.theta(D);
        let local = kernel::rebuild_local(
            hs,
            ht,
            st.level,
            &mut st.kernel,
            &st.g,
            &g,
            &mut st.f0,
            &mut st.g0,
            st.eps,
            kernel::LocalLimits {
                theta,
                tau: if mid { theta * LOCAL_MOVE_MID } else { tau },
                // Whole once a strict local rebuild could not be local any more: the stage's
                // end would need that whole build anyway, and it is best done now.
                tau_whole: tau,
                max_moved: rows.max(ht.levels[st.level].len()) / LOCAL_SHARE,
                max_pairs: limit,
            },
            wrap,
        );
        let how = match local {
            Some(kernel::Local::Built(r, c)) => {
                st.support = if mid { Support::Loose } else { Support::Local };
                format!(
                    "local ({r} rows, {c} columns{})",
                    if mid { ", loose" } else { "" }
                )
            }
            Some(kernel::Local::TooMany) | None => {
                // Past the pair limit the whole build decides (and reports it). The old kernel
                // goes first: two whole kernels at once were the solve's peak memory.
                // The old kernel's rows bound the new row minima from above.
                let (xs, ys) = (&hs.levels[st.level].pos, &ht.levels[st.level].pos);
                let upper = hard_transform(&st.kernel.row_ptr, &st.kernel.col, xs, ys, &g, wrap);
                st.kernel = Kernel::default();
                st.kernel = build_kernel(
                    hs,
                    ht,
                    st.level,
                    &g,
                    st.eps,
                    settings,
                    wrap,
                    spacing,
                    Some(&upper),
                )?;
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
        st.u = a.to_vec();
        st.v = b.to_vec();
        Ok(())
    }
}
