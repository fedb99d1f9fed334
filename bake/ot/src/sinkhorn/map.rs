//! The map read off the final stage: the barycentric projection of the plan, or a one-to-one
//! matching by a sparse auction on the final kernel's support, in the caller's order. Rows whose
//! prices rise past what the support certifies are widened by exact searches, and rows a price war
//! parks are placed by sparse shortest paths ([`super::complete`], D144); short cycles along the
//! candidates then take back what the auction's ε gave away locally ([`crate::cycles`], D164).
//! An auction that still cannot match every row is an error (`SolveError::NotConverged`,
//! docs/decisions.md, D114); the barycentric map is then computed only for the cost its report
//! states.

use super::complete::{Beyond, Completion, Support};
use super::hierarchy::Hierarchy;
use super::kernel::{bounds, map_lists_mut, sort_lists_by_value, Kernel};
use super::outline::{outline_prices, Scale};
use super::potentials::absorbed;
use super::report::report_of;
use super::schedule::Plan;
use super::stages::Stages;
use super::state::{RefineInfo, State};
use super::{MapKind, SinkhornSettings, DEFAULT_AUCTION_EPS};
use crate::auction::{auction, Graph};
use crate::cost::{delta, sq};
use crate::cycles::{cancel, Cancelled, CycleSearch, Lists};
use crate::{Problem, Solution, SolveError, Wrap};
use rayon::prelude::*;

/// The solution from the stages' final state: the map, back in the caller's order (lifted on the
/// torus), its assignment if one to one, and the report.
pub(super) fn finish<const D: usize>(
    problem: &Problem<'_>,
    n: usize,
    settings: &SinkhornSettings,
    wrap: Wrap,
    plan: &Plan<D>,
    stages: Stages,
) -> Result<Solution, SolveError> {
    let Stages {
        state: st,
        mut logs,
        rebuilds,
        max_pairs,
    } = stages;
    let (hs, ht) = (&plan.hs, &plan.ht);
    let dim = D;
    let (mapped_sorted, refine) = read_map(settings, wrap, plan, st);
    let mut mapped = to_caller_order(hs, &mapped_sorted, n);
    if wrap == Wrap::Periodic {
        crate::cost::lift(dim, problem.source, &mut mapped);
    }
    crate::check_finite("mapped", dim, &mapped)?;
    let assignment = match &refine {
        Some(info) if info.unassigned == 0 => Some(info.to_original(hs, ht)),
        _ => None,
    };
    let last = logs.pop().expect("a stage ran");
    if let Some(info) = refine.as_ref().filter(|r| r.unassigned > 0) {
        // A one-to-one map was asked for: a barycentric stand-in would be a silently different
        // map (not onto the samples, contracted by the blur), so it is an error with its report.
        let mut report = report_of(
            problem,
            n,
            settings,
            &logs,
            &last,
            plan.blur_end,
            rebuilds,
            max_pairs,
            refine.as_ref(),
        );
        report.cost = crate::transport_cost(dim, problem.source, &mapped);
        return Err(SolveError::NotConverged {
            solver: super::NAME,
            residual: info.unassigned as f64 / n as f64,
            threshold: 0.0,
            iterations: report.iterations,
            hint: format!(
                "map = \"assignment\": the auction left {} of {n} points unmatched ({} phases, \
                 {} bids; {} rows widened beyond the final kernel's support, {} augmenting \
                 paths) within its limit of {} searched columns: the density is too uneven for \
                 the blur; raise truncate (it is {}) or blur_spacing, or use map = \"barycentric\" \
                 or kind = \"sliced\"",
                info.unassigned,
                info.phases,
                info.bids,
                info.completion.widened,
                info.completion.paths,
                completion_edges(n),
                settings.theta(dim)
            ),
            report: Box::new(report),
        });
    }
    let mut report = report_of(
        problem,
        n,
        settings,
        &logs,
        &last,
        plan.blur_end,
        rebuilds,
        max_pairs,
        refine.as_ref(),
    );
    report.cost = crate::transport_cost(dim, problem.source, &mapped);
    Ok(Solution {
        mapped,
        assignment,
        report,
    })
}

/// Where every source point goes, in the hierarchies' order, and what the refinement did (`None`
/// for the barycentric map).
fn read_map<const D: usize>(
    settings: &SinkhornSettings,
    wrap: Wrap,
    plan: &Plan<D>,
    mut st: State,
) -> (Vec<[f64; D]>, Option<RefineInfo>) {
    let (hs, ht, point_level) = (&plan.hs, &plan.ht, plan.point_level);
    let (x, y) = (&hs.levels[point_level].pos, &ht.levels[point_level].pos);
    match settings.map {
        MapKind::Barycentric => {
            let (kern, v) = (&st.kernel, &st.v);
            let weight = |p: usize, j: usize| f64::from(kern.k[p]) * v[j];
            (barycentric(x, y, kern, weight, wrap), None)
        }
        MapKind::Assignment => {
            let g = absorbed(&st.g, &st.v, &ht.levels[point_level].mass, st.eps);
            let ta = std::time::Instant::now();
            let eps = st.eps;
            let r = refine_assignment(x, y, &mut st, g, plan, settings, wrap);
            if std::env::var_os("OTBAKE_TRACE").is_some() {
                eprintln!("  auction {:.2}s", ta.elapsed().as_secs_f64());
            }
            match r {
                info if info.unassigned == 0 => {
                    (info.x.iter().map(|&j| y[j as usize]).collect(), Some(info))
                }
                info => {
                    // The kernel's values now hold the reduced costs r_ij = C_ij − g_j − f_i of
                    // the absorbed potentials, and K_ij v_j ∝ exp(−r_ij/ε) in each row (the
                    // masses are uniform on the points): the same barycentric map.
                    let kern = &st.kernel;
                    let weight = |p: usize, _| (-f64::from(kern.k[p]) / eps).exp();
                    (barycentric(x, y, kern, weight, wrap), Some(info))
                }
            }
        }
    }
}

/// Point-major `f32` coordinates in the caller's order from points in the hierarchy's order.
fn to_caller_order<const D: usize>(
    hs: &Hierarchy<D>,
    mapped_sorted: &[[f64; D]],
    n: usize,
) -> Vec<f32> {
    let dim = D;
    let mut mapped = vec![0f32; n * dim];
    for (k, &orig) in hs.order.iter().enumerate() {
        let o = orig as usize;
        for a in 0..dim {
            mapped[o * dim + a] = mapped_sorted[k][a] as f32;
        }
    }
    mapped
}

/// T(x_i) = Σ_j w_ij y_j / Σ_j w_ij on the point level, with `weight(p, j)` the plan's entry p
/// (column j) up to a factor per row (K_ij v_j: u_i cancels); on the torus
/// x_i + Σ_j w_ij δ(x_i, y_j) / Σ_j w_ij, the mean of the shortest displacements (the plan of a row
/// is concentrated within a few blurs of x_i, far less than half a period).
fn barycentric<const D: usize>(
    x: &[[f64; D]],
    y: &[[f64; D]],
    kern: &Kernel,
    weight: impl Fn(usize, usize) -> f64 + Sync,
    wrap: Wrap,
) -> Vec<[f64; D]> {
    // x_i plus the weighted mean of the shortest displacements: the plain weighted mean of the y_j
    // in the Euclidean case, and on the torus the circular mean around x_i.
    (0..kern.row_ptr.len() - 1)
        .into_par_iter()
        .map(|i| {
            let mut acc = [0.0; D];
            let mut w = 0.0;
            for p in kern.row_ptr[i]..kern.row_ptr[i + 1] {
                let j = kern.col[p] as usize;
                let kv = weight(p, j);
                w += kv;
                for a in 0..D {
                    acc[a] += kv * delta(wrap, x[i][a], y[j][a]);
                }
            }
            std::array::from_fn(|a| x[i][a] + acc[a] / w)
        })
        .collect()
}

/// The auction's first ε as a fraction of the final Sinkhorn ε (it goes down from there by 4 per
/// phase to `auction_eps`; by default one phase, at 1/2 in 2D and 1/4 in 3D, D164). The Sinkhorn
/// potentials are already good prices at ε/4: in 3D one phase took 1.58M bids on the 250K cow
/// instead of 3.23M in two phases from ε, and 10.8M instead of 17.8M on the 1M cow, with the same
/// cost to 7 digits. In 2D two phases from ε took 16% fewer bids on the 250K duck at seed 0, but
/// at seed 1 the second phase freed 131K rows and its last free row was still bidding after 100M
/// bids; one phase from ε/4 took 7.39M bids and widened no row (D145).
const AUCTION_START: f64 = 0.25;

/// How far the cycles after the auction look (D164): a swap with the owners of a row's first 8
/// candidates, cycles of three through the first 6 of the row's and of each owner's. More found
/// no more than the noise at 5K points (16 and 8: the same cost ratios to 2e-5) and took a third
/// longer. The least gain, 1e-6 ε, is far above the rounding of the costs (the lists' `f32` values
/// only prune) and far below anything a map shows.
fn cycle_search(eps: f64) -> CycleSearch {
    CycleSearch {
        pairs: 8,
        triples: 6,
        passes: 16,
        min_gain: 1e-6 * eps,
    }
}

/// The part of the truncation's margin θε up to which the auction trusts the final kernel to hold
/// a row's best columns (`auction::Graph::certified`): a whole build drops only pairs more than θε
/// out, a local rebuild more than 3θε/4 (τ = θ/8 either side), less the potentials' drift since.
/// A row whose prices rose past it is searched exactly (about one kernel row search). Four times
/// θε, because prices fall everywhere as bids go on: at θε the 2D duck (250K, whose auction starts
/// at ε) widened 103K rows, past the limit, and cayman at 1M 64–100% of its rows; at 4θε the duck
/// and the 1M cow widen none, cayman 3.6% (D144).
const CERTIFIED: f64 = 4.0;

/// Columns the rows widened beyond the final kernel may hold at once, and edges the completion's
/// paths may hold at once, per point and per solve: 4 bytes each (and 28 per widened row), within
/// what a kernel rebuild held at the solve's peak (24 bytes per pair, of which the auction keeps
/// 8); cayman at 1M widened 36K rows with 243K columns, the 16M cow at `truncate = 4` reached
/// the limit (D144). A solve that needs
/// more has a support far too poor for the blur, and fails naming the fixes (D114, D144).
const COMPLETION_EDGES_PER_POINT: usize = 24;
const COMPLETION_EDGES_FIXED: usize = 1 << 20;

fn completion_edges(n: usize) -> usize {
    COMPLETION_EDGES_PER_POINT * n + COMPLETION_EDGES_FIXED
}

/// Sparse auction on the final kernel's support, started from the Sinkhorn target potential.
///
/// The auction runs on reduced costs C_ij − f_i − g_j with prices relative to g (both start at
/// the Sinkhorn potentials, so prices start at 0): a row constant changes no bid, and the
/// candidates' reduced costs are small (a few ε), so one `f32` per pair holds them to within
/// 1e-7 of their size, far below the auction's final ε. They are computed once, in parallel, and
/// the bids read them in order instead of computing costs from positions. The matching is in the
/// result's `x` when `unassigned` is 0.
fn refine_assignment<const D: usize>(
    x: &[[f64; D]],
    y: &[[f64; D]],
    st: &mut State,
    g: Vec<f64>,
    plan: &Plan<D>,
    settings: &SinkhornSettings,
    wrap: Wrap,
) -> RefineInfo {
    let eps = st.eps;
    let side = plan.side;
    let kern = &mut st.kernel;
    // Per row: f_i = min over the candidates of C_ij − g_j, then the candidates' C_ij − g_j − f_i,
    // written over the kernel's values (which the auction no longer needs: no second pair array).
    let col = &kern.col;
    let t0 = std::time::Instant::now();
    let f = map_lists_mut(&kern.row_ptr, &mut kern.k, |i, red| {
        let cols = &col[kern.row_ptr[i]..kern.row_ptr[i + 1]];
        let h = |j: u32| sq(wrap, &x[i], &y[j as usize]) - g[j as usize];
        let m = cols.iter().map(|&j| h(j)).fold(f64::INFINITY, f64::min);
        let m = if m.is_finite() { m } else { 0.0 };
        // Rounded to f32 only once the row constant is out.
        for (r, &j) in red.iter_mut().zip(cols) {
            *r = (h(j) - m) as f32;
        }
        m
    });
    // Each row's candidates by ascending reduced cost: a bid then stops reading a row at the
    // first candidate that cannot beat its second best (prices only fall), which is most of them.
    let t1 = std::time::Instant::now();
    sort_lists_by_value(&kern.row_ptr, &mut kern.col, &mut kern.k);
    let t2 = std::time::Instant::now();
    let (row_ptr, col, red) = (&kern.row_ptr, &kern.col, &kern.k);
    let cost = |i: usize, j: usize| sq(wrap, &x[i], &y[j]) - f[i] - g[j];
    let certified = CERTIFIED * settings.theta(D) * eps;
    let graph = Graph {
        row_ptr,
        col,
        cols: y.len(),
        cost,
        pair_cost: Some(red),
        sorted: true,
        certified,
    };
    let bnd = bounds(&plan.ht, plan.point_level, &g);
    let setup = [t1 - t0, t2 - t1, t2.elapsed()].map(|t| t.as_secs_f64());
    let completion = Completion {
        ht: &plan.ht,
        level: plan.point_level,
        x,
        g: &g,
        wrap,
        margin: settings.theta(D) * eps,
        max_edges: completion_edges(x.len()),
        bnd: &bnd,
        support: Some(Support {
            row_ptr,
            col,
            f: &f,
            certified,
        }),
    };
    // Rows the support cannot place are widened by exact searches; what the auction still parks
    // (a price war) is placed by augmenting paths on edges searched where the paths go.
    let mut beyond = Beyond::new(&completion, &f);
    let step = eps
        * settings
            .auction_eps
            .unwrap_or(DEFAULT_AUCTION_EPS[D.min(3)]);
    // On the torus the target has no outline to start from (and the grid would need its images).
    let mut v = if wrap == Wrap::Periodic {
        vec![0.0; y.len()]
    } else {
        let scale = Scale {
            spacing: plan.spacing,
            side,
            step,
            certified,
        };
        outline_prices(&plan.ht, plan.point_level, scale)
    };
    let mut m = auction(
        &graph,
        &mut v,
        eps * AUCTION_START,
        step,
        4.0,
        side * side * D as f64,
        &mut beyond,
    );
    let mut completed = beyond.done;
    completed.widened = m.widened;
    completed.wide_cols = m.wide_cols;
    // What ε-complementary slackness gave away locally, taken back by short cycles (D164).
    let tc = std::time::Instant::now();
    let cycles = if m.unassigned == 0 {
        let lists = Lists {
            row_ptr,
            col,
            value: red,
        };
        cancel(&mut m.x, &lists, graph.cost, &cycle_search(eps))
    } else {
        Cancelled::default()
    };
    if std::env::var_os("OTBAKE_TRACE").is_some() {
        eprintln!(
            "  auction's costs {:.2}s, sorted {:.2}s, bounds {:.2}s\n  auction: {} phases, {} \
             bids, {} rows certified further, {} widened ({} columns, {} at once), {} searches \
             {:.2}s; parked: {} at a stall, {} past the lists' limit, {} past the last \
             widening; {} swaps, {} three-row cycles in {} passes {:.2}s",
            setup[0],
            setup[1],
            setup[2],
            m.phases,
            m.bids,
            completed.certified,
            completed.widened,
            completed.wide_cols,
            m.wide_held,
            completed.searches,
            completed.searching.as_secs_f64(),
            m.parked.stalled,
            m.parked.refused,
            m.parked.unwidened,
            cycles.pairs,
            cycles.triples,
            cycles.passes,
            tc.elapsed().as_secs_f64(),
        );
    }
    RefineInfo {
        cycles,
        unassigned: m.unassigned,
        phases: m.phases,
        bids: m.bids,
        completion: completed,
        x: m.x,
    }
}
