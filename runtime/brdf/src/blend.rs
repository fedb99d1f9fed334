//! [`BrdfBlend`]: a blend of BRDF maps with its reconstruction kernel, evaluated, sampled and given
//! its pdf through runtime point queries and samples (the crate docs give the formulas and kernels).

use crate::domain::{angles, direction, from_unit, to_unit};
use crate::noise::{joint_pdf, reflect, truncated_normal_3d};
use otbake_runtime::{AdaptiveKernel, Blend, Error, Kernel, Map, PointValue, Proxy};
use std::f64::consts::PI;

/// Default fixed kernel standard deviation in unit-cube units (≈ 1.8° in θ, 3.6° in φd): about a
/// hundred points of a 1M-point blend under the kernel where the BRDF is average.
pub const DEFAULT_SIGMA: f32 = 0.02;

/// Default adaptive kernel: two spacings wide (within its truncation radius a kernel holds some
/// 900 points, `(4π/3)·6³`), between 0.0005 (0.05° in θ) and 0.03 (1.5 × [`DEFAULT_SIGMA`]: in the
/// sparsest 5% of a 1M-point blend kernels stop growing, and a query reaches 0.09 of the cube at
/// most). BENCHMARKS.md has the accuracy and time at other scales; docs/decisions.md, D48, why
/// these defaults.
pub const DEFAULT_ADAPTIVE: AdaptiveKernel = AdaptiveKernel {
    scale: 2.0,
    min_sigma: 0.0005,
    max_sigma: 0.03,
};

/// How a blend of BRDF maps is reconstructed (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BrdfKernel {
    /// One width everywhere, boundary renormalization, samples without noise.
    Fixed(Kernel),
    /// Per-point widths following the blend's spacing, reflection at the faces, samples with noise.
    Adaptive(AdaptiveKernel),
}

/// Why a blend of BRDF maps could not be made or queried.
#[derive(Debug, thiserror::Error)]
pub enum BrdfBlendError {
    /// The maps are not 3D.
    #[error("the manifest's inputs are {0}-dimensional; BRDF commands need BRDF inputs (.binary MERL or .brdf Cornell files), which are 3D")]
    NotBrdf(usize),
    /// The runtime refused the maps or a query.
    #[error("{0}")]
    Runtime(Error),
}

impl From<Error> for BrdfBlendError {
    fn from(e: Error) -> Self {
        BrdfBlendError::Runtime(e)
    }
}

/// A blend of BRDF maps with its reconstruction kernel.
#[derive(Clone, Copy)]
pub struct BrdfBlend<'a, 'm> {
    /// The runtime blend (3D).
    pub blend: Blend<'a, 'm>,
    /// The reconstruction kernel.
    pub kernel: BrdfKernel,
    /// Per axis, an interval holding every blended point for any weights (the hull of the maps'
    /// bounds): mirror images of a query farther than a kernel's reach from it see no point.
    extent: ([f32; 3], [f32; 3]),
}

/// One importance sample of a blend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrdfSample {
    /// Incident direction (local frame, z = normal).
    pub wi: [f64; 3],
    /// Outgoing direction.
    pub wo: [f64; 3],
    /// Joint density of `(wi, wo)` in the product of solid angles; 0 for a failed sample.
    pub pdf: f64,
    /// `f(wi, wo)` in linear RGB.
    pub value: [f32; 3],
    /// Luminance `f_Y(wi, wo)`.
    pub luminance: f32,
}

/// Value and density at one point of the cube.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrdfValue {
    /// `f` in linear RGB.
    pub rgb: [f32; 3],
    /// `f_Y`.
    pub luminance: f32,
    /// The blend's density `ρ_w` over the unit cube.
    pub density: f32,
}

impl<'a, 'm> BrdfBlend<'a, 'm> {
    /// A blend with the fixed kernel of width `sigma`; checks that the maps are 3D and belong to
    /// `proxy`.
    pub fn new(proxy: Proxy<'a>, maps: &'m [Map<'a>], sigma: f32) -> Result<Self, BrdfBlendError> {
        Self::with_kernel(proxy, maps, BrdfKernel::Fixed(Kernel { sigma }))
    }

    /// A blend with the default adaptive kernel ([`DEFAULT_ADAPTIVE`]).
    pub fn adaptive(proxy: Proxy<'a>, maps: &'m [Map<'a>]) -> Result<Self, BrdfBlendError> {
        Self::with_kernel(proxy, maps, BrdfKernel::Adaptive(DEFAULT_ADAPTIVE))
    }

    /// A blend with `kernel`; checks that the maps are 3D and belong to `proxy`, that the kernel is
    /// valid and, for an adaptive kernel, that every map stores spacings.
    pub fn with_kernel(
        proxy: Proxy<'a>,
        maps: &'m [Map<'a>],
        kernel: BrdfKernel,
    ) -> Result<Self, BrdfBlendError> {
        let blend = Blend::new(proxy, maps)?;
        if blend.dim() != 3 {
            return Err(BrdfBlendError::NotBrdf(blend.dim()));
        }
        match kernel {
            BrdfKernel::Fixed(k) => {
                if k.prepare(3).is_none() {
                    return Err(Error::BadSigma.into());
                }
            }
            BrdfKernel::Adaptive(k) => {
                // The runtime checks the kernel (and the spacings) on every call: ask once here.
                let mut w = vec![0.0; maps.len()];
                w[0] = 1.0;
                blend.bandwidth(&w, 0, k)?;
            }
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for m in maps {
            let (l, h) = m.view().bounds();
            for a in 0..3 {
                lo[a] = lo[a].min(l[a]);
                hi[a] = hi[a].max(h[a]);
            }
        }
        Ok(Self {
            blend,
            kernel,
            extent: (lo, hi),
        })
    }

    /// `f`, `f_Y` and `ρ_w` at `(θi, θo, φd)` (radians; `φd` in `[0, π]`): with the adaptive kernel
    /// the reflected sample-point estimate (module docs); with the fixed kernel the point query
    /// divided by [`Self::inside_fraction`].
    pub fn eval_angles(
        &self,
        weights: &[f32],
        theta_i: f64,
        theta_o: f64,
        phi_d: f64,
    ) -> Result<BrdfValue, Error> {
        let u = to_unit(theta_i, theta_o, phi_d);
        match self.kernel {
            BrdfKernel::Fixed(kernel) => {
                let v = self.blend.point(weights, &u, kernel)?;
                let inside = self.inside_fraction(&u);
                Ok(BrdfValue {
                    rgb: v.color.map(|c| c / inside),
                    luminance: v.mass / inside,
                    density: v.density / inside,
                })
            }
            BrdfKernel::Adaptive(kernel) => {
                let v = self.reflected(weights, u.map(reflect), kernel)?;
                Ok(BrdfValue {
                    rgb: v.color,
                    luminance: v.mass,
                    density: v.density,
                })
            }
        }
    }

    /// The adaptive estimate at `u` (in the cube) plus its mirror images `−u_a`, `2 − u_a`: every
    /// combination within a kernel's reach of the points' extent (the others see no point).
    fn reflected(
        &self,
        weights: &[f32],
        u: [f32; 3],
        kernel: AdaptiveKernel,
    ) -> Result<PointValue, Error> {
        let reach = 3.0 * kernel.max_sigma;
        let (lo, hi) = self.extent;
        let mut images = [[0.0f32; 3]; 3];
        let mut count = [0usize; 3];
        for a in 0..3 {
            for c in [u[a], -u[a], 2.0 - u[a]] {
                // The image itself always (it also checks the weights and the kernel).
                if count[a] == 0 || (c >= lo[a] - reach && c <= hi[a] + reach) {
                    images[a][count[a]] = c;
                    count[a] += 1;
                }
            }
        }
        let mut out = PointValue::default();
        for &x in &images[0][..count[0]] {
            for &y in &images[1][..count[1]] {
                for &z in &images[2][..count[2]] {
                    let v = self.blend.point_adaptive(weights, &[x, y, z], kernel)?;
                    out.density += v.density;
                    out.mass += v.mass;
                    for c in 0..3 {
                        out.color[c] += v.color[c];
                    }
                }
            }
        }
        Ok(out)
    }

    /// Boundary correction of the fixed kernel: the fraction of the kernel centred at `u` that lies
    /// inside the cube (product over axes of the 1D Gaussian mass inside `[0, 1]`, each clipped to
    /// ±3σ as the runtime's kernel is). The density has no mass outside the cube, so a plain kernel
    /// estimate falls to about half at a face (θ = 0, θ = 90°, φd = 0 or π) and a quarter at an
    /// edge; dividing by this fraction removes that bias (the usual renormalization of kernel
    /// estimates on bounded domains; approximate, since the runtime truncates to a ball, not a box).
    /// 1 for the adaptive kernel, which reflects instead.
    pub fn inside_fraction(&self, u: &[f32; 3]) -> f32 {
        use crate::normal::cdf;
        let BrdfKernel::Fixed(kernel) = self.kernel else {
            return 1.0;
        };
        let s = f64::from(kernel.sigma);
        let full = cdf(3.0) - cdf(-3.0);
        u.iter()
            .map(|&q| {
                let q = f64::from(q);
                let hi = ((1.0 - q) / s).min(3.0);
                let lo = (-q / s).max(-3.0);
                ((cdf(hi) - cdf(lo)) / full).max(1e-3) as f32
            })
            .product()
    }

    /// `f(wi, wo)` in linear RGB for unit directions in the local frame; 0 below the horizon.
    pub fn eval(&self, weights: &[f32], wi: [f64; 3], wo: [f64; 3]) -> Result<[f32; 3], Error> {
        match angles(wi, wo) {
            Some((ti, to, pd)) => Ok(self.eval_angles(weights, ti, to, pd)?.rgb),
            None => {
                self.blend.check_weights(weights)?;
                Ok([0.0; 3])
            }
        }
    }

    /// The joint pdf of [`Self::sample`] at `(wi, wo)`: `ρ_w(u) / (π⁴ sin θi sin θo)`.
    pub fn pdf(&self, weights: &[f32], wi: [f64; 3], wo: [f64; 3]) -> Result<f64, Error> {
        match angles(wi, wo) {
            Some((ti, to, pd)) => {
                let v = self.eval_angles(weights, ti, to, pd)?;
                Ok(joint_pdf(v.density, ti, to))
            }
            None => Ok(0.0),
        }
    }

    /// Sample `index` of the blend as a pair of directions. `xi` are five uniform numbers in
    /// `[0, 1)`: the first picks `φi`, the second the sign of `φd`, and with the adaptive kernel the
    /// last three the noise added to the blended point (a direction and a radius of point `index`'s
    /// truncated Gaussian); the fixed kernel ignores them and returns the blended point itself.
    /// Draw `index` uniformly in `0..n` to sample the blend.
    pub fn sample(&self, weights: &[f32], index: u32, xi: [f64; 5]) -> Result<BrdfSample, Error> {
        let s = self.blend.sample(weights, index)?;
        let (ti, to, pd) = match self.kernel {
            BrdfKernel::Fixed(_) => {
                let (ti, to, pd) = from_unit(&s.position[..3]);
                (
                    ti.clamp(0.0, PI / 2.0),
                    to.clamp(0.0, PI / 2.0),
                    pd.clamp(0.0, PI),
                )
            }
            BrdfKernel::Adaptive(kernel) => {
                let sigma = f64::from(self.blend.bandwidth(weights, index, kernel)?);
                let z = truncated_normal_3d([xi[2], xi[3], xi[4]]);
                let mut u = [0.0f32; 3];
                for a in 0..3 {
                    let v = f64::from(s.position[a]) + sigma * z[a];
                    if !(-1.0..=2.0).contains(&v) {
                        return Ok(BrdfSample {
                            wi: [0.0, 0.0, 1.0],
                            wo: [0.0, 0.0, 1.0],
                            pdf: 0.0,
                            value: [0.0; 3],
                            luminance: 0.0,
                        });
                    }
                    u[a] = reflect(v as f32);
                }
                from_unit(&u)
            }
        };
        let phi_i = 2.0 * PI * xi[0];
        let phi_o = if xi[1] < 0.5 { phi_i + pd } else { phi_i - pd };
        let v = self.eval_angles(weights, ti, to, pd)?;
        Ok(BrdfSample {
            wi: direction(ti, phi_i),
            wo: direction(to, phi_o),
            pdf: joint_pdf(v.density, ti, to),
            value: v.rgb,
            luminance: v.luminance,
        })
    }
}
