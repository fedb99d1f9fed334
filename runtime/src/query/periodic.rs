//! Periodic blends: every query on the torus `[0,1)^d` (tileable textures).
//!
//! A periodic map stores lifts `p + δ` of its points ([`Wrap`]), so a blend's points are lifts too:
//! real coordinates within half a period of `[0,1)^d`, each standing for all of its images
//! `y − m`, `m ∈ ℤ^d`. A query on the torus must see every image. Rather than teach each traversal
//! about the torus, a query runs the ordinary (clamped) traversal once per integer shift `m` that
//! can reach it, over the blend's points and boxes moved by `−m` ([`Shifted`]), adding into the same
//! accumulators; shifts whose moved root box is out of reach are dropped at the root for one box
//! test. A query near a border thus sees the points across it, and a range box that crosses a border
//! is split into its pieces by the shifts.
//!
//! Exactness carries over: subtracting the same `m` from a point and from every box that holds it
//! rounds monotonically, so pruning stays exact; and every query enumerates shifts in one fixed
//! order ([`Shifts`]) from a superset of the shifts that can contribute, so a region query and the
//! per-cell point query at a cell still add the same terms in the same order (same bits).
//!
//! The work is bounded for any bytes: readers accept lifts in [`LIFT_MIN`]`..=`[`LIFT_MAX`] only, query
//! positions are folded into `[0,1)`, and kernels may reach at most one period
//! ([`Error::PeriodicKernel`]), so a query tries at most 11 shifts per axis, nearly all of which
//! end at the root (in 2D a query usually runs 1 to 4 real traversals).

use crate::base::error::Error;
use crate::base::kernel::{self, Kernel};
use crate::query::adaptive::{self, Spaced};
use crate::query::point::{self, PointValue};
use crate::query::range::{self, RangeValue};
use crate::source::{Sample, Source};
use otbake_formats::torus::{floor_f32, fold};
use otbake_formats::tree::Node;
use otbake_formats::{Wrap, LIFT_MAX, LIFT_MIN, MAX_DIM};

/// A source moved by `−shift`: every position and node box minus `shift` (the image of the blend
/// one period `shift` over).
pub(crate) struct Shifted<'s, S> {
    pub(crate) inner: &'s S,
    pub(crate) shift: [f32; MAX_DIM],
}

impl<S: Source> Source for Shifted<'_, S> {
    type Leaf = S::Leaf;
    fn dim(&self) -> usize {
        self.inner.dim()
    }
    fn n(&self) -> u32 {
        self.inner.n()
    }
    fn depth(&self) -> u32 {
        self.inner.depth()
    }
    fn has_color(&self) -> bool {
        self.inner.has_color()
    }
    fn mean_mass(&self) -> f32 {
        self.inner.mean_mass()
    }
    fn leaf_state(&self) -> S::Leaf {
        self.inner.leaf_state()
    }
    #[inline]
    fn enter(&self, leaf: Node, state: &mut S::Leaf) {
        self.inner.enter(leaf, state)
    }
    #[inline]
    fn position(&self, state: &S::Leaf, i: usize) -> [f32; MAX_DIM] {
        let mut p = self.inner.position(state, i);
        for (v, m) in p.iter_mut().zip(&self.shift) {
            *v -= m;
        }
        p
    }
    #[inline]
    fn color(&self, i: usize) -> [f32; 3] {
        self.inner.color(i)
    }
    #[inline]
    fn node_box(&self, node: Node, state: &mut S::Leaf) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
        let (mut lo, mut hi) = self.inner.node_box(node, state);
        for k in 0..MAX_DIM {
            lo[k] -= self.shift[k];
            hi[k] -= self.shift[k];
        }
        (lo, hi)
    }
    #[inline]
    fn node_color(&self, node: Node) -> [f32; 3] {
        self.inner.node_color(node)
    }
}

impl<S: Spaced> Spaced for Shifted<'_, S> {
    #[inline]
    fn spacing(&self, i: usize) -> f32 {
        self.inner.spacing(i)
    }
    #[inline]
    fn node_spacing(&self, node: Node) -> f32 {
        self.inner.node_spacing(node)
    }
}

/// A blended point as a point of the domain: folded into `[0,1)^d` when periodic.
pub(crate) fn fold_sample(wrap: Wrap, mut s: Sample) -> Sample {
    if wrap == Wrap::Periodic {
        for v in &mut s.position {
            *v = fold(*v);
        }
    }
    s
}

/// Integer shifts `m` with `m_k ∈ ranges[k]` on the first `dim` axes (0 on the others), as `f32`
/// vectors, axis 0 fastest: the one order every periodic query uses.
pub(crate) struct Shifts {
    lo: [i32; MAX_DIM],
    hi: [i32; MAX_DIM],
    next: Option<[i32; MAX_DIM]>,
}

impl Shifts {
    /// Only the zero shift: how a clamped blend runs the same code paths.
    pub(crate) fn zero() -> Self {
        Self {
            lo: [0; MAX_DIM],
            hi: [0; MAX_DIM],
            next: Some([0; MAX_DIM]),
        }
    }

    fn new(lo: [i32; MAX_DIM], hi: [i32; MAX_DIM]) -> Self {
        let empty = (0..MAX_DIM).any(|k| lo[k] > hi[k]);
        Self {
            lo,
            hi,
            next: if empty { None } else { Some(lo) },
        }
    }
}

impl Iterator for Shifts {
    type Item = [f32; MAX_DIM];
    fn next(&mut self) -> Option<[f32; MAX_DIM]> {
        let cur = self.next?;
        let mut step = cur;
        let mut k = 0;
        loop {
            if k == MAX_DIM {
                self.next = None;
                break;
            }
            if step[k] < self.hi[k] {
                step[k] += 1;
                self.next = Some(step);
                break;
            }
            step[k] = self.lo[k];
            k += 1;
        }
        Some(cur.map(|m| m as f32))
    }
}

/// Shifts `m` on axis `k` that can bring a point of `[rlo, rhi]` within `reach` of `[qlo, qhi]`
/// (`qlo − reach <= y − m <= qhi + reach`), with a margin of one shift each side for rounding (an
/// extra shift costs one root box test and adds nothing). The root box is clamped to the range a
/// validated periodic blend can have (lifts in `[LIFT_MIN, LIFT_MAX]`, weights summing to 1 within
/// a tolerance), so any bytes give at most a handful of shifts.
fn axis_range(rlo: f32, rhi: f32, qlo: f32, qhi: f32, reach: f32) -> (i32, i32) {
    let (rlo, rhi) = (
        rlo.clamp(LIFT_MIN - 1.0, LIFT_MAX + 1.0),
        rhi.clamp(LIFT_MIN - 1.0, LIFT_MAX + 1.0),
    );
    let a = floor_f32(rlo - qhi - reach).clamp(-16.0, 16.0) as i32 - 1;
    let b = -floor_f32(-(rhi - qlo + reach)).clamp(-16.0, 16.0) as i32 + 1;
    (a, b)
}

/// The shifts a query box [`qlo`, `qhi`] (within `[0, 2]` per axis) may need at distance `reach`
/// from a source whose root box is [`rlo`, `rhi`].
fn shifts_for(
    d: usize,
    (rlo, rhi): ([f32; MAX_DIM], [f32; MAX_DIM]),
    qlo: &[f32; MAX_DIM],
    qhi: &[f32; MAX_DIM],
    reach: f32,
) -> Shifts {
    let mut lo = [0; MAX_DIM];
    let mut hi = [0; MAX_DIM];
    for k in 0..d.min(MAX_DIM) {
        (lo[k], hi[k]) = axis_range(rlo[k], rhi[k], qlo[k], qhi[k], reach);
    }
    Shifts::new(lo, hi)
}

/// The box of every (blended) point of `s`.
fn root_box(s: &impl Source) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
    let mut leaf = s.leaf_state();
    s.node_box(Node::root(s.n()), &mut leaf)
}

/// The kernel's reach `3σ`, refused beyond one period.
fn periodic_reach(kernel: Kernel) -> Result<f32, Error> {
    let radius = kernel.sigma * kernel::TRUNCATION;
    if radius <= 1.0 {
        Ok(radius)
    } else {
        Err(Error::PeriodicKernel { radius })
    }
}

/// A point query at `q` (finite) with a checked kernel: the clamped query, or on the torus the sum
/// over every image of the blend.
pub(crate) fn point(
    wrap: Wrap,
    s: &impl Source,
    q: &[f32; MAX_DIM],
    kernel: Kernel,
    kp: kernel::PreparedKernel,
) -> Result<PointValue, Error> {
    if wrap == Wrap::Clamp {
        return Ok(point::point(s, q, kp));
    }
    let reach = periodic_reach(kernel)?;
    let d = s.dim();
    let mut qf = [0.0; MAX_DIM];
    for k in 0..d {
        qf[k] = fold(q[k]);
    }
    let (mut sum, mut csum) = (0.0f32, [0.0f32; 3]);
    for shift in shifts_for(d, root_box(s), &qf, &qf, reach) {
        point::accumulate(&Shifted { inner: s, shift }, &qf, kp, &mut sum, &mut csum);
    }
    Ok(point::finish(s, kp, sum, csum))
}

/// An adaptive point query at `q` (finite) with a checked kernel: the clamped query, or on the
/// torus the sum over every image of the blend within the largest kernel's reach.
pub(crate) fn point_adaptive(
    wrap: Wrap,
    s: &impl Spaced,
    q: &[f32; MAX_DIM],
    k: &adaptive::Checked,
) -> Result<PointValue, Error> {
    let (mut sum, mut csum) = (0.0f32, [0.0f32; 3]);
    if wrap == Wrap::Clamp {
        adaptive::accumulate(s, q, k, &mut sum, &mut csum);
        return Ok(adaptive::finish(s, sum, csum));
    }
    let reach = k.reach();
    if reach > 1.0 {
        return Err(Error::PeriodicKernel { radius: reach });
    }
    let d = s.dim();
    let mut qf = [0.0; MAX_DIM];
    for a in 0..d {
        qf[a] = fold(q[a]);
    }
    for shift in shifts_for(d, root_box(s), &qf, &qf, reach) {
        adaptive::accumulate(&Shifted { inner: s, shift }, &qf, k, &mut sum, &mut csum);
    }
    Ok(adaptive::finish(s, sum, csum))
}

/// A range query over the closed box [`qlo`, `qhi`] (finite): the clamped query, or on the torus the
/// points of every image of the blend inside it. An axis at least one period wide covers the whole
/// circle (each point counts once); a box with `hi < lo` on some axis is empty, as when clamped
/// (a box across a border is given as, e.g., `[0.9, 1.1]`).
pub(crate) fn range(
    wrap: Wrap,
    s: &impl Source,
    qlo: &[f32; MAX_DIM],
    qhi: &[f32; MAX_DIM],
) -> RangeValue {
    let d = s.dim();
    if wrap == Wrap::Clamp || (0..d).any(|k| qhi[k] < qlo[k]) {
        return range::range(s, qlo, qhi);
    }
    let (mut lo, mut hi) = (*qlo, *qhi);
    let (rlo, rhi) = root_box(s);
    let mut mlo = [0; MAX_DIM];
    let mut mhi = [0; MAX_DIM];
    for k in 0..d {
        if hi[k] - lo[k] >= 1.0 {
            // The whole circle: every point once, through the zero shift.
            lo[k] = f32::NEG_INFINITY;
            hi[k] = f32::INFINITY;
        } else {
            let t = floor_f32(lo[k]);
            lo[k] -= t;
            hi[k] -= t;
            (mlo[k], mhi[k]) = axis_range(rlo[k], rhi[k], lo[k], hi[k], 0.0);
        }
    }
    let (mut count, mut csum) = (0u32, [0.0f32; 3]);
    for shift in Shifts::new(mlo, mhi) {
        range::accumulate(
            &Shifted { inner: s, shift },
            &lo,
            &hi,
            &mut count,
            &mut csum,
        );
    }
    range::finish(s, count, csum)
}

/// Splats `s` into the whole grid `res`: the clamped splat, or on the torus one splat per image of
/// the blend that reaches the grid (each point's kernel wraps around the borders).
pub(crate) fn splat(
    wrap: Wrap,
    s: &impl Source,
    kernel: Kernel,
    kp: kernel::PreparedKernel,
    res: &[u32; MAX_DIM],
    density: &mut [f32],
    mut color: Option<&mut [f32]>,
) -> Result<(), Error> {
    if wrap == Wrap::Clamp {
        crate::query::splat::splat(s, kernel, kp, res, density, color);
        return Ok(());
    }
    let reach = periodic_reach(kernel)?;
    let d = s.dim();
    let (clo, chi) = centers_box(d, res, &[0; MAX_DIM], res);
    let (rlo, rhi) = root_box(s);
    for shift in shifts_for(d, (rlo, rhi), &clo, &chi, reach) {
        // The splat loops over every point: skip images whose root box is out of reach (exact,
        // as at the root of a traversal).
        let mut d2 = 0.0f32;
        for k in 0..d {
            let gap = ((rlo[k] - shift[k]) - chi[k])
                .max(clo[k] - (rhi[k] - shift[k]))
                .max(0.0);
            d2 += gap * gap;
        }
        if d2 > kp.radius2 {
            continue;
        }
        let shifted = Shifted { inner: s, shift };
        crate::query::splat::splat(&shifted, kernel, kp, res, density, color.as_deref_mut());
    }
    Ok(())
}

/// The box of the centers `(i + 0.5) / res` of cells `start..start + size` per axis (the grid's
/// formula; used to choose shifts only, which a margin makes robust to its rounding).
fn centers_box(
    d: usize,
    res: &[u32; MAX_DIM],
    start: &[u32; MAX_DIM],
    size: &[u32; MAX_DIM],
) -> ([f32; MAX_DIM], [f32; MAX_DIM]) {
    let mut lo = [0.0; MAX_DIM];
    let mut hi = [0.0; MAX_DIM];
    for k in 0..d.min(MAX_DIM) {
        let r = res[k].max(1) as f32;
        lo[k] = (start[k] as f32 + 0.5) / r;
        hi[k] = ((start[k] as f32 + size[k].max(1) as f32) - 0.5) / r;
    }
    (lo, hi)
}

/// The shifts a region query of `s` runs: the zero shift when clamped; on the torus, those whose
/// image of the blend can reach the region's cell centers (checked kernel).
pub(crate) fn region_shifts(
    wrap: Wrap,
    s: &impl Source,
    region: &crate::base::cells::Region,
    kernel: Kernel,
) -> Result<Shifts, Error> {
    if wrap == Wrap::Clamp {
        return Ok(Shifts::zero());
    }
    let reach = periodic_reach(kernel)?;
    let d = s.dim();
    let (clo, chi) = centers_box(d, &region.res, &region.start, &region.size);
    Ok(shifts_for(d, root_box(s), &clo, &chi, reach))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fold_and_floor() {
        assert_eq!(floor_f32(-0.5), -1.0);
        assert_eq!(floor_f32(2.0), 2.0);
        assert_eq!(floor_f32(-3.0), -3.0);
        assert_eq!(floor_f32(1e20), 1e20);
        assert_eq!(fold(1.25), 0.25);
        assert_eq!(fold(-0.25), 0.75);
        assert_eq!(fold(-1e-9), 0.0);
        assert_eq!(fold(0.3), 0.3);
        assert_eq!(fold(1.0), 0.0);
        for i in 0..1000 {
            let v = (i as f32 - 500.0) * 0.0137;
            let f = fold(v);
            assert!((0.0..1.0).contains(&f), "{v} → {f}");
        }
    }

    #[test]
    fn shifts_enumerate_a_box_axis_0_fastest() {
        let got: [[f32; MAX_DIM]; 6] = {
            let mut it = Shifts::new([-1, 0, 0, 0], [1, 1, 0, 0]);
            core::array::from_fn(|_| it.next().unwrap())
        };
        assert_eq!(got[0], [-1.0, 0.0, 0.0, 0.0]);
        assert_eq!(got[2], [1.0, 0.0, 0.0, 0.0]);
        assert_eq!(got[3], [-1.0, 1.0, 0.0, 0.0]);
        assert_eq!(got[5], [1.0, 1.0, 0.0, 0.0]);
        let mut it = Shifts::new([-1, 0, 0, 0], [1, 1, 0, 0]);
        assert_eq!(it.by_ref().count(), 6);
        assert!(it.next().is_none());
        assert_eq!(Shifts::zero().count(), 1);
        assert_eq!(Shifts::new([1, 0, 0, 0], [0, 0, 0, 0]).count(), 0);
    }

    #[test]
    fn axis_ranges_cover_every_reaching_shift_and_stay_bounded() {
        // A point at y reaches the query q through shift m when |y − m − q| <= reach.
        for (rlo, rhi) in [(-0.5f32, 1.5f32), (0.2, 0.3), (-0.4, 0.1)] {
            for qi in 0..20 {
                let q = qi as f32 / 20.0;
                for reach in [0.0f32, 0.01, 0.3, 1.0] {
                    let (a, b) = axis_range(rlo, rhi, q, q, reach);
                    for m in -6..=6 {
                        let reaches = (0..=100).any(|j| {
                            let y = rlo + (rhi - rlo) * j as f32 / 100.0;
                            (y - m as f32 - q).abs() <= reach
                        });
                        assert!(
                            !reaches || (a..=b).contains(&m),
                            "{rlo} {rhi} {q} {reach} {m}"
                        );
                    }
                }
            }
        }
        for bad in [f32::NAN, f32::MAX, -f32::MAX, f32::INFINITY] {
            let (a, b) = axis_range(bad, bad, 0.5, 0.5, 1.0);
            assert!(b - a <= 12, "{bad}: {a}..{b}");
        }
    }
}
