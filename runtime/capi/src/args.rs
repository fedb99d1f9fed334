//! Arguments every query shares: the C value types ([`OtbakePointValue`], [`OtbakeRangeValue`],
//! [`OtbakeSample`], [`OtbakeAdaptiveKernel`], [`OtbakeRegion`]), weights per call or per batch
//! element ([`Weights`]) and the batch loop ([`batch`]).

use crate::guard::{mul, slice};
use crate::status::Failure;
use otbake_runtime::{AdaptiveKernel, PointValue, RangeValue, Region, Sample, MAX_DIM};

/// Largest dimension of a blend: query points have at most this many coordinates.
pub const OTBAKE_MAX_DIM: u32 = 4;
const _: () = assert!(OTBAKE_MAX_DIM as usize == MAX_DIM);

/// What a point query returns (the runtime's `PointValue`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OtbakePointValue {
    /// Reconstructed probability density (integrates to 1 over the domain).
    pub density: f32,
    /// `density × Σ w_k mean_mass_k`: the blended mass channel (e.g. luminance).
    pub mass: f32,
    /// Premultiplied linear RGB (zeros without color).
    pub color: [f32; 3],
}

impl From<PointValue> for OtbakePointValue {
    fn from(v: PointValue) -> Self {
        Self {
            density: v.density,
            mass: v.mass,
            color: v.color,
        }
    }
}

/// What a range query returns: integrals over the closed box (the runtime's `RangeValue`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OtbakeRangeValue {
    /// Blended points inside the box.
    pub count: u32,
    /// Integral of the mass channel over the box.
    pub mass: f32,
    /// Integral of the premultiplied color over the box.
    pub color: [f32; 3],
}

impl From<RangeValue> for OtbakeRangeValue {
    fn from(v: RangeValue) -> Self {
        Self {
            count: v.count,
            mass: v.mass,
            color: v.color,
        }
    }
}

/// One point of the blended point cloud: a sample of the barycenter (the runtime's `Sample`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OtbakeSample {
    /// Position; coordinates past the blend's dimension are 0.
    pub position: [f32; 4],
    /// Blended color-to-mass ratio (linear RGB), zeros without color.
    pub color: [f32; 3],
}

impl From<Sample> for OtbakeSample {
    fn from(s: Sample) -> Self {
        Self {
            position: s.position,
            color: s.color,
        }
    }
}

/// A density-adaptive kernel (the runtime's `AdaptiveKernel`): point `i`'s width is
/// `clamp(scale · spacing_i, min_sigma, max_sigma)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OtbakeAdaptiveKernel {
    /// Bandwidth per unit of local spacing (about 2).
    pub scale: f32,
    /// Smallest bandwidth, domain units.
    pub min_sigma: f32,
    /// Largest bandwidth, domain units (bounds every query's reach).
    pub max_sigma: f32,
}

impl From<OtbakeAdaptiveKernel> for AdaptiveKernel {
    fn from(k: OtbakeAdaptiveKernel) -> Self {
        Self {
            scale: k.scale,
            min_sigma: k.min_sigma,
            max_sigma: k.max_sigma,
        }
    }
}

/// A box of cells of a regular grid over `[0,1]^d` (the runtime's `Region`): cell `idx` has its
/// center at `(idx + 0.5) / res` per axis; entries past the blend's dimension are ignored.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OtbakeRegion {
    /// Cells per axis of the whole grid.
    pub res: [u32; 4],
    /// First cell of the region per axis.
    pub start: [u32; 4],
    /// Cells of the region per axis.
    pub size: [u32; 4],
}

impl From<OtbakeRegion> for Region {
    fn from(r: OtbakeRegion) -> Self {
        Region {
            res: r.res,
            start: r.start,
            size: r.size,
        }
    }
}

/// Weights of a batch: one vector for every element (`stride == 0`) or one per element, `stride`
/// floats apart.
pub(crate) struct Weights<'a> {
    all: &'a [f32],
    k: usize,
    stride: usize,
}

impl<'a> Weights<'a> {
    /// The weights at `ptr` for `count` elements of `k` weights each, `stride` floats apart (0: the
    /// same `k` for all).
    ///
    /// # Safety
    ///
    /// `ptr` points at the floats this reads: `k` if `stride == 0` or `count == 0`, otherwise
    /// `(count − 1) · stride + k`.
    pub(crate) unsafe fn new(
        ptr: *const f32,
        k: usize,
        stride: usize,
        count: usize,
    ) -> Result<Self, Failure> {
        if stride != 0 && stride < k {
            return Err(Failure::Count {
                name: "weight_stride",
                expected: k,
                found: stride,
            });
        }
        let len = if stride == 0 || count == 0 {
            k
        } else {
            mul(count - 1, stride, "count")?
                .checked_add(k)
                .ok_or(Failure::Count {
                    name: "count",
                    expected: usize::MAX,
                    found: count,
                })?
        };
        // SAFETY: the caller's contract: `len` readable floats.
        let all = unsafe { slice(ptr, len, "weights")? };
        Ok(Self { all, k, stride })
    }

    /// The weights of element `i` (checked by the runtime on every call).
    #[inline]
    pub(crate) fn of(&self, i: usize) -> &'a [f32] {
        let at = i * self.stride;
        &self.all[at..at + self.k]
    }

    /// All the floats read.
    pub(crate) fn floats(&self) -> &'a [f32] {
        self.all
    }
}

/// Checks that a batch gives points of the blend's dimension.
pub(crate) fn check_dim(dim: usize, expected: usize) -> Result<(), Failure> {
    if dim != expected {
        return Err(Failure::Count {
            name: "dim",
            expected,
            found: dim,
        });
    }
    Ok(())
}

/// Writes `query(i)` to `out[i]` for every element, stopping at the first failure (elements
/// before it are written; the failure names its index).
#[inline]
pub(crate) fn batch<T, U: From<T>>(
    out: &mut [U],
    mut query: impl FnMut(usize) -> Result<T, otbake_runtime::Error>,
) -> Result<(), Failure> {
    for (i, o) in out.iter_mut().enumerate() {
        *o = query(i).map_err(|e| Failure::from(e).at(i))?.into();
    }
    Ok(())
}
