//! The ε stages of a solve, coarse to fine: each starts from the previous stage's potentials moved
//! to its level and scale, builds its kernel and iterates until its marginal error is below its
//! tolerance.

use super::iterate::{build_kernel, iterate, Goal};
use super::potentials::{
    absorbed, extrapolate, hard_transform, hard_transform_best, shrink_offset, upper_from_parents,
};
use super::report::{report_of, total_iterations};
use super::schedule::Plan;
use super::settings::{ASSIGNMENT_TOLERANCE, STAGE_TOLERANCE};
use super::state::{StageLog, State, Support};
use super::{MapKind, SinkhornSettings, NAME};
use crate::{Problem, Report, SolveError, Wrap};

/// What the stages leave for the map.
pub(super) struct Stages {
    /// The last stage's state (on the points).
    pub state: State,
    /// What every stage did, in order.
    pub logs: Vec<StageLog>,
    /// Kernel rebuilds over all stages.
    pub rebuilds: u32,
    /// The largest kernel, in pairs.
    pub max_pairs: usize,
}

/// Runs every stage of `plan`; errors if the last one does not converge.
pub(super) fn run<const D: usize>(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    wrap: Wrap,
    plan: &Plan<D>,
) -> Result<Stages, SolveError> {
    let (hs, ht, spacing) = (&plan.hs, &plan.ht, plan.spacing);
    let blurs = &plan.blurs;
    let mut logs: Vec<StageLog> = Vec::with_capacity(blurs.len());
    let mut state: Option<State> = None;
    let mut rebuilds = 0u32;
    let mut max_pairs = 0usize;
    for (stage, &blur) in blurs.iter().enumerate() {
        let eps = blur * blur;
        let last = stage + 1 == blurs.len();
        // The map needs the points: the last stage always runs on them.
        let level = if last {
            plan.point_level
        } else {
            plan.level_of(blur)
                .max(state.as_ref().map_or(0, |s| s.level))
        };
        // Target potential on the new level.
        let tp = std::time::Instant::now();
        let (g, upper) = match &state {
            None => (vec![0.0; ht.levels[level].len()], None),
            Some(st) => {
                let (g, upper) = next_potential(plan, st, level, eps, wrap);
                (g, Some(upper))
            }
        };
        if std::env::var_os("OTBAKE_TRACE").is_some() && state.is_some() {
            eprintln!("  next potential {:.2}s", tp.elapsed().as_secs_f64());
        }
        // The previous stage's kernel is not needed any more: free it before building the next.
        drop(state.take());
        let tk = std::time::Instant::now();
        let upper = upper.as_deref();
        let kernel = build_kernel(hs, ht, level, &g, eps, settings, wrap, spacing, upper)?;
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
        let goal = Goal {
            tolerance: stage_tolerance(settings, last),
            last,
        };
        let log = iterate(
            hs,
            ht,
            &mut st,
            settings,
            goal,
            &mut rebuilds,
            wrap,
            spacing,
        )?;
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            eprintln!("stage {stage} blur {blur:.3e} level {level} cells {}x{} pairs {} its {} err {:.2e} {:.2}s", hs.levels[level].len(), ht.levels[level].len(), st.kernel.pairs(), log.iterations, log.error, t0.elapsed().as_secs_f64());
        }
        if last && !log.converged {
            let report = report_of(
                problem,
                n,
                settings,
                &logs,
                &log,
                plan.blur_end,
                rebuilds,
                max_pairs,
                None,
            );
            return Err(final_not_converged(settings, plan, &logs, &log, report));
        }
        logs.push(log);
        state = Some(st);
    }
    let state = state.expect("at least one stage runs");
    assert_eq!(
        state.level, plan.point_level,
        "the last stage runs on the points"
    );
    Ok(Stages {
        state,
        logs,
        rebuilds,
        max_pairs,
    })
}

/// The target potential a stage on `level` at scale `eps` starts from, made from the previous
/// stage's converged state `st`: on the same level, the hard c-transform of its source potential
/// with the ε offset scaled ([`shrink_offset`]); on a finer level, the same for the source
/// potential, carried down by a soft c-transform ([`extrapolate`]). With it, upper bounds of the
/// new kernel's row minima: C − g on the old kernel's rows, or on the descendants of each old
/// row's best column ([`upper_from_parents`]).
fn next_potential<const D: usize>(
    plan: &Plan<D>,
    st: &State,
    level: usize,
    eps: f64,
    wrap: Wrap,
) -> (Vec<f64>, Vec<f64>) {
    let (hs, ht) = (&plan.hs, &plan.ht);
    let g_old = absorbed(&st.g, &st.v, &ht.levels[st.level].mass, st.eps);
    let f_old = absorbed(&st.kernel.f, &st.u, &hs.levels[st.level].mass, st.eps);
    let ratio = eps / st.eps;
    // The column form of the kernel's pattern, made for this step only.
    let (col_ptr, row) = st.kernel.columns();
    if level == st.level {
        let (sx, sy) = (&hs.levels[level].pos, &ht.levels[level].pos);
        let g_hard = hard_transform(&col_ptr, &row, sy, sx, &f_old, wrap);
        let g = shrink_offset(&g_old, &g_hard, ratio);
        let (ptr, col) = (&st.kernel.row_ptr, &st.kernel.col);
        let upper = hard_transform(ptr, col, sx, sy, &g, wrap);
        (g, upper)
    } else {
        let (sx, sy) = (&hs.levels[st.level].pos, &ht.levels[st.level].pos);
        let (ptr, col) = (&st.kernel.row_ptr, &st.kernel.col);
        let (f_hard, best) = hard_transform_best(ptr, col, sx, sy, &g_old, wrap);
        let f_pred = shrink_offset(&f_old, &f_hard, ratio);
        let g = extrapolate(
            hs,
            ht,
            (st.level, level),
            (&col_ptr, &row),
            &f_pred,
            eps,
            wrap,
        );
        let upper = upper_from_parents(hs, ht, (st.level, level), &best, &g, wrap);
        (g, upper)
    }
}

/// The marginal error a stage iterates to: the final one to `tolerance` (at most
/// [`ASSIGNMENT_TOLERANCE`] when an auction follows), earlier ones [`STAGE_TOLERANCE`] times tighter.
fn stage_tolerance(settings: &SinkhornSettings, last: bool) -> f64 {
    if last {
        match settings.map {
            MapKind::Assignment => settings.tolerance.min(ASSIGNMENT_TOLERANCE),
            MapKind::Barycentric => settings.tolerance,
        }
    } else {
        settings.tolerance * STAGE_TOLERANCE
    }
}

/// The error of a final stage that did not converge, with the run's `report`.
fn final_not_converged<const D: usize>(
    settings: &SinkhornSettings,
    plan: &Plan<D>,
    logs: &[StageLog],
    log: &StageLog,
    report: Report,
) -> SolveError {
    let (blur_end, spacing) = (plan.blur_end, plan.spacing);
    let e = log.error;
    SolveError::NotConverged {
        solver: NAME,
        residual: e,
        threshold: settings.tolerance,
        iterations: total_iterations(logs) + log.iterations,
        hint: format!(
            "the final stage (blur {blur_end:e}) did not reach the marginal tolerance in \
             max_iterations = {}: raise max_iterations, raise blur (it is {:.3} x the point \
             spacing) or loosen tolerance",
            settings.max_iterations,
            blur_end / spacing
        ),
        report: Box::new(report),
    }
}
