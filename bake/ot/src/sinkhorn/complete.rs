//! The auction beyond the final kernel's support ([`Beyond`]): rows widened by exact searches,
//! and the rows a price war still parks placed by shortest augmenting paths on a graph found only
//! where the paths go ([`Completion`]).
//!
//! Where the density is peaked the final kernel's support may hold no perfect matching (a set of
//! rows whose candidates are fewer than they are: a price war the auction cannot end). Left to the
//! auction's bid budget, the war ruins the prices around it (they fall without bound), and dense
//! paths over all n columns, O(n) per scan step, then had not ended in half an hour at 16M points;
//! sparse paths on the support alone find no path for some rows (D143). So the auction asks for
//! more as soon as a row's best candidate is priced past what the support certifies
//! (`auction::Graph::certified`): [`Outside::widen`] searches the row's columns within a margin of
//! its best over *all* targets at the current prices, by the kernel's exact branch-and-bound search
//! ([`kernel::search`]), and the row bids on that list, widened again (the margin doubled) if its
//! prices rise past it too. Most such rows find nothing their support lacks, and only their
//! certificate moves.
//!
//! The rows the auction still parks are placed by [`Completion::run`]: a row's edges are every
//! target within a margin of the row's best at the current prices, searched the first time a path
//! reaches the row; a search that runs out of columns before reaching a free one starts over with
//! the margin four times larger, so a path is always found (at the largest margins the graph is
//! the dense one), and a path longer than the margin is searched once more with the margin at its
//! length, so it is a shortest one. Where the auction's certificate covers the edges a path needs
//! from a row, the row's kernel candidates are read instead ([`Support`]). Time and memory follow
//! the rows the paths visit, not n.
//!
//! The paths are Dijkstra's on reduced costs from the free row, as in Jonker–Volgenant, with the
//! duals of the settled columns lowered afterwards so that the path's edges are tight. The auction's
//! duals are ε-optimal only on its support, so an edge can be slightly negative: settled columns stay
//! settled, and a path is then a valid augmenting path, if not always the shortest; the auction's
//! next phase frees whatever row the flip left out of ε-complementary slackness. Duals only fall
//! (bids and the updates here lower them), so the cell bounds of `g` computed before the auction
//! stay lower bounds for all of it.
//!
//! Determinism: free rows are taken in order, the searches are exact, and heap ties go to the lower
//! column: the result does not depend on the thread count.

use super::hierarchy::Hierarchy;
use super::kernel::{self, Affine, Bounds};
use crate::auction::{Outside, Widened};
use crate::cost;
use crate::Wrap;
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// "Unassigned" in the row→column and column→row arrays.
const NONE: u32 = u32::MAX;

/// Factor the margin grows by when a path runs out of columns.
const MARGIN_GROWTH: f64 = 4.0;

/// What the completion searches, and how much of it it may hold.
pub(super) struct Completion<'a, const D: usize> {
    /// The target hierarchy and its point level (the columns).
    pub ht: &'a Hierarchy<D>,
    pub level: usize,
    /// The rows' positions (the source points, in the hierarchy's order).
    pub x: &'a [[f64; D]],
    /// The target potential the auction's costs are relative to: cost(i, j) = C_ij − f_i − g_j.
    pub g: &'a [f64],
    pub wrap: Wrap,
    /// The first margin of a row's edges (the kernel's θε).
    pub margin: f64,
    /// Most edges held at once (over all searched rows: past it the cache of searched rows is let
    /// go); a path through a row whose own search would pass it gives up, and the solve reports
    /// the rows left unmatched.
    pub max_edges: usize,
    /// The cell bounds of `g` on `ht` ([`kernel::bounds`]): lower bounds for every price the
    /// auction reaches, since prices start at 0 and only fall.
    pub bnd: &'a Bounds<D, Affine<D>>,
    /// The auction's own graph, where it certifies a row's edges: read instead of searched.
    pub support: Option<Support<'a>>,
}

/// The final kernel's support as the auction sees it: a row's candidates hold every column whose
/// auction cost C_ij − f_i − g_j − v_j is at most `certified`, as far as the auction itself trusts
/// its graph (`auction::Graph::certified`; prices only fall, so it holds for the whole auction).
/// A path through a row needs its columns up to some value; where the certificate covers it the
/// row's candidates are read, a few hundred nanoseconds, instead of searched over the hierarchy
/// (microseconds): the paths of the auction's endgame settle thousands of columns each.
#[derive(Clone, Copy)]
pub(super) struct Support<'a> {
    pub row_ptr: &'a [usize],
    pub col: &'a [u32],
    /// The auction's row constants f_i.
    pub f: &'a [f64],
    pub certified: f64,
}

/// What one completion did (for the report and the trace).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Completed {
    /// Rows placed.
    pub paths: u32,
    /// Columns settled in all paths (the work).
    pub settled: u64,
    /// Row searches, and rows whose candidates were read from the support instead.
    pub searches: u64,
    pub read: u64,
    /// Largest margin a path needed, as a multiple of the first.
    pub widest: f64,
    /// Most edges held at once.
    pub edges: usize,
    /// Rows whose candidates the auction widened (each widening counted) and the columns those
    /// lists held: the auction's count (`auction::Matching`), since it decides what it keeps.
    pub widened: u64,
    pub wide_cols: usize,
    /// Rows whose own candidates a search certified further, with no list.
    pub certified: u64,
    /// Time spent in the row searches (for the trace only: never in a report or an archive).
    pub searching: std::time::Duration,
}

impl Completed {
    pub fn add(&mut self, other: &Completed) {
        self.paths += other.paths;
        self.settled += other.settled;
        self.searches += other.searches;
        self.read += other.read;
        self.widest = self.widest.max(other.widest);
        self.edges = self.edges.max(other.edges);
        self.widened += other.widened;
        self.wide_cols += other.wide_cols;
        self.certified += other.certified;
        self.searching += other.searching;
    }
}

/// One row's edges: every column whose value (C − pot) was at most `limit` when searched.
struct Edges {
    limit: f64,
    cols: Vec<u32>,
}

/// A column's label in one path search.
#[derive(Clone, Copy)]
struct Label {
    dist: f64,
    pred: u32,
    settled: bool,
}

/// The columns' labels of one path search, by column, and the columns it touched (what a clear
/// resets). An array and not a map: the auction's endgame paths settle tens of thousands of
/// columns each, and hashing them was most of a completion's time.
struct Labels {
    at: Vec<Label>,
    touched: Vec<u32>,
}

const UNREACHED: Label = Label {
    dist: f64::INFINITY,
    pred: NONE,
    settled: false,
};

impl Labels {
    fn new(cols: usize) -> Self {
        Self {
            at: vec![UNREACHED; cols],
            touched: Vec::new(),
        }
    }

    fn clear(&mut self) {
        for &j in &self.touched {
            self.at[j as usize] = UNREACHED;
        }
        self.touched.clear();
    }

    /// Column j's label, recorded as touched the first time.
    fn get_mut(&mut self, j: u32) -> &mut Label {
        let l = &mut self.at[j as usize];
        if l.pred == NONE && !l.settled && l.dist == f64::INFINITY {
            self.touched.push(j);
        }
        l
    }
}

/// A heap entry: smallest distance first, then the lower column.
#[derive(Clone, Copy, PartialEq)]
struct Entry(f64, u32);

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// How one path search ended.
enum Path {
    /// The free column it reached and its distance.
    Found(u32, f64),
    /// No free column within the margin.
    Exhausted,
    /// One row's edges would pass `max_edges`.
    TooLarge,
}

impl<const D: usize> Completion<'_, D> {
    /// Places the `free` rows (unassigned in `xs`) by augmenting paths, updating the assignment
    /// (`xs` row → column, `ys` column → row) and the prices `v` (relative to `g`); stops early,
    /// leaving rows free, only if the edges would pass `max_edges`.
    pub fn run(&self, free: &[usize], xs: &mut [u32], ys: &mut [u32], v: &mut [f64]) -> Completed {
        let mut search = Searcher {
            c: self,
            edges: HashMap::new(),
            held: 0,
            stack: Vec::new(),
            found: Vec::new(),
            done: Completed::default(),
        };
        let mut labels = Labels::new(ys.len());
        for &s in free {
            if xs[s] != NONE {
                continue;
            }
            let mut margin = self.margin;
            let mut widened = false;
            let (end, dist) = loop {
                labels.clear();
                match search.path(s, margin, xs, ys, v, &mut labels) {
                    // A path no longer than the margin is a shortest one: every edge left out
                    // is longer than the margin (with tight duals edges are not negative).
                    Path::Found(end, dist) if dist <= margin || widened => break (end, dist),
                    // Otherwise once more with every edge up to the path's length.
                    Path::Found(_, dist) => {
                        margin = dist;
                        widened = true;
                    }
                    Path::Exhausted => margin *= MARGIN_GROWTH,
                    Path::TooLarge => return search.done,
                }
            };
            search.done.widest = search.done.widest.max(margin / self.margin);
            // Lower the settled columns' duals so the path is tight (never raise one: the bounds
            // must stay lower bounds), then flip the path.
            for &j in &labels.touched {
                let l = labels.at[j as usize];
                if l.settled && l.dist < dist {
                    v[j as usize] -= dist - l.dist;
                }
            }
            let mut j = end;
            loop {
                let i = labels.at[j as usize].pred;
                ys[j as usize] = i;
                let prev = xs[i as usize];
                xs[i as usize] = j;
                if i as usize == s {
                    break;
                }
                j = prev;
            }
            search.done.paths += 1;
        }
        search.done
    }
}

impl<const D: usize> Completion<'_, D> {
    /// C(x_i, y_j) − g_j − v_j: the auction's reduced cost of (i, j) up to the row constant.
    fn value(&self, i: usize, j: usize, v: &[f64]) -> f64 {
        cost::sq(self.wrap, &self.x[i], &self.ht.levels[self.level].pos[j]) - self.g[j] - v[j]
    }

    /// Every column whose value for row i is at most `need`, or with `need = None` within
    /// `margin` of the row's best over all columns, into `found`; returns the best (∞ if none).
    fn search(
        &self,
        i: usize,
        need: Option<f64>,
        margin: f64,
        v: &[f64],
        stack: &mut Vec<(u32, u32, f64)>,
        found: &mut Vec<(u32, f64)>,
    ) -> f64 {
        let (g, bnd) = (self.g, self.bnd);
        kernel::search(
            self.ht,
            self.level,
            bnd,
            &|j| g[j] + v[j],
            &self.x[i],
            margin,
            self.wrap,
            stack,
            found,
            None,
            need,
        )
    }

    /// Row i's columns within `margin` of its best over all columns at prices `v`, ascending, and
    /// the value up to which the list is complete (every column left out is worth more, at these
    /// prices and at any lower ones): what the auction widens a row's candidates to when its
    /// support runs out (`auction::Widen`).
    /// `stack` and `found` are the search's buffers, kept by the caller across rows.
    pub fn widen(
        &self,
        i: usize,
        margin: f64,
        v: &[f64],
        stack: &mut Vec<(u32, u32, f64)>,
        found: &mut Vec<(u32, f64)>,
    ) -> (Vec<u32>, f64) {
        found.clear();
        let best = self.search(i, None, margin, v, stack, found);
        let mut cols: Vec<u32> = found.iter().map(|e| e.0).collect();
        cols.sort_unstable();
        (cols, best + margin)
    }
}

/// Widenings of one row before it is parked: the margin has then grown 2^20-fold.
const MAX_WIDENINGS: u32 = 20;

/// What the auction sees beyond the final kernel's support: rows widened by exact searches, and
/// the completion of the rows it parks.
pub(super) struct Beyond<'a, 'c, const D: usize> {
    completion: &'a Completion<'c, D>,
    /// The auction's row constants: its cost is C_ij − f_i − g_j.
    f: &'a [f64],
    pub done: Completed,
    /// The widening searches' buffers (one row at a time).
    stack: Vec<(u32, u32, f64)>,
    found: Vec<(u32, f64)>,
}

impl<'a, 'c, const D: usize> Beyond<'a, 'c, D> {
    pub fn new(completion: &'a Completion<'c, D>, f: &'a [f64]) -> Self {
        Self {
            completion,
            f,
            done: Completed::default(),
            stack: Vec::new(),
            found: Vec::new(),
        }
    }
}

impl<const D: usize> Outside for Beyond<'_, '_, D> {
    /// The row's columns within `margin`·2^round of its best over all columns (every widening
    /// doubles the margin), for at most [`MAX_WIDENINGS`] rounds.
    ///
    /// Most rows past what the kernel certifies are only where every price has fallen (bids only
    /// lower prices): their search finds nothing their own candidates lack, and only the
    /// certificate moves, with no list to hold.
    fn widen(&mut self, row: usize, round: u32, v: &[f64], own: &[u32]) -> Option<Widened> {
        if round > MAX_WIDENINGS {
            return None;
        }
        let c = self.completion;
        let t0 = std::time::Instant::now();
        let margin = c.margin * f64::from(1u32 << round);
        let (cols, limit) = c.widen(row, margin, v, &mut self.stack, &mut self.found);
        self.done.searching += t0.elapsed();
        self.done.searches += 1;
        let certified = limit - self.f[row];
        if cols.iter().all(|j| own.contains(j)) {
            self.done.certified += 1;
            return Some(Widened::Own(certified));
        }
        Some(Widened::List(cols, certified))
    }

    /// The lists may hold as many columns as the paths' edges.
    fn wide_limit(&self) -> usize {
        self.completion.max_edges
    }

    fn complete(&mut self, free: &[usize], x: &mut [u32], y: &mut [u32], v: &mut [f64]) {
        let done = self.completion.run(free, x, y, v);
        if std::env::var_os("OTBAKE_TRACE").is_some() {
            eprintln!(
                "  completion: {} of {} parked rows placed, {} columns settled, {} searches, \
                 {} rows read, margin up to {}x, {} edges, {:.2}s searching",
                done.paths,
                free.len(),
                done.settled,
                done.searches,
                done.read,
                done.widest,
                done.edges,
                done.searching.as_secs_f64()
            );
        }
        self.done.add(&done);
    }
}

/// The per-completion state of the path searches: the rows' edges found so far.
struct Searcher<'a, 'c, const D: usize> {
    c: &'a Completion<'c, D>,
    edges: HashMap<u32, Edges>,
    held: usize,
    stack: Vec<(u32, u32, f64)>,
    found: Vec<(u32, f64)>,
    done: Completed,
}

/// A row's edges: its candidates in the support, or a searched list taken out of the cache.
enum Cols<'c> {
    Support(&'c [u32]),
    Searched(Vec<u32>),
}

impl std::ops::Deref for Cols<'_> {
    type Target = [u32];
    fn deref(&self) -> &[u32] {
        match self {
            Cols::Support(c) => c,
            Cols::Searched(c) => c,
        }
    }
}

impl<'c, const D: usize> Searcher<'_, 'c, D> {
    /// Row i's edges, taken out of the cache (hand them back with [`Self::put_back`]): every
    /// column whose value is at most `need`, or with `need = None` within `margin` of the row's
    /// best, searched unless the cache already holds them; `None` past `max_edges`.
    ///
    /// A cached list holds every column up to its `limit` *at the prices of its search*, and stays
    /// complete up to that limit: prices only fall, so values only rise, and a column left out
    /// stays out.
    fn take_edges(
        &mut self,
        i: u32,
        need: Option<f64>,
        margin: f64,
        v: &[f64],
    ) -> Option<Cols<'c>> {
        if let (Some(sp), Some(t)) = (self.c.support, need) {
            let iu = i as usize;
            if t - sp.f[iu] <= sp.certified {
                self.done.read += 1;
                return Some(Cols::Support(&sp.col[sp.row_ptr[iu]..sp.row_ptr[iu + 1]]));
            }
        }
        let held = match (self.edges.get(&i), need) {
            (Some(e), Some(t)) => e.limit >= t,
            _ => false,
        };
        if !held {
            self.found.clear();
            let t0 = std::time::Instant::now();
            let best = self.c.search(
                i as usize,
                need,
                margin,
                v,
                &mut self.stack,
                &mut self.found,
            );
            let limit = need.unwrap_or(best + margin);
            self.done.searching += t0.elapsed();
            self.done.searches += 1;
            if self.found.len() > self.c.max_edges {
                return None;
            }
            let old = self.edges.get(&i).map_or(0, |e| e.cols.len());
            self.held = self.held - old + self.found.len();
            if self.held > self.c.max_edges {
                // The cache only saves searching again: let it go, not the path (a path reads
                // each row's edges once).
                self.edges.clear();
                self.held = self.found.len();
            }
            self.done.edges = self.done.edges.max(self.held);
            let mut cols: Vec<u32> = self.found.iter().map(|e| e.0).collect();
            cols.sort_unstable();
            self.edges.insert(i, Edges { limit, cols });
        }
        self.edges
            .get_mut(&i)
            .map(|e| Cols::Searched(std::mem::take(&mut e.cols)))
    }

    fn put_back(&mut self, i: u32, cols: Cols<'c>) {
        if let (Some(e), Cols::Searched(cols)) = (self.edges.get_mut(&i), cols) {
            e.cols = cols;
        }
    }

    /// Dijkstra from free row `s` on the reduced costs, each row's edges within `margin` of its
    /// best, to the nearest free column.
    fn path(
        &mut self,
        s: usize,
        margin: f64,
        xs: &[u32],
        ys: &[u32],
        v: &[f64],
        labels: &mut Labels,
    ) -> Path {
        let mut heap = BinaryHeap::new();
        let Some(first) = self.take_edges(s as u32, None, margin, v) else {
            return Path::TooLarge;
        };
        let base = first
            .iter()
            .map(|&j| self.c.value(s, j as usize, v))
            .fold(f64::INFINITY, f64::min);
        for &j in first.iter() {
            let dist = self.c.value(s, j as usize, v) - base;
            *labels.get_mut(j) = Label {
                dist,
                pred: s as u32,
                settled: false,
            };
            heap.push(Entry(dist, j));
        }
        self.put_back(s as u32, first);
        while let Some(Entry(dist, j)) = heap.pop() {
            let label = labels.get_mut(j);
            if label.settled || dist > label.dist {
                continue;
            }
            label.settled = true;
            self.done.settled += 1;
            let i = ys[j as usize];
            if i == NONE {
                return Path::Found(j, dist);
            }
            debug_assert_eq!(xs[i as usize], j);
            // Relax through the row assigned to j: its other columns at their reduced cost
            // relative to j's.
            let h = self.c.value(i as usize, j as usize, v);
            let Some(cols) = self.take_edges(i, Some(h + margin), margin, v) else {
                return Path::TooLarge;
            };
            for &j2 in cols.iter() {
                let nd = dist + self.c.value(i as usize, j2 as usize, v) - h;
                let l = labels.get_mut(j2);
                if !l.settled && nd < l.dist {
                    l.dist = nd;
                    l.pred = i;
                    heap.push(Entry(nd, j2));
                }
            }
            self.put_back(i, cols);
        }
        Path::Exhausted
    }
}

#[cfg(test)]
mod tests;
