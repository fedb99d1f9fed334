//! Run-time evaluation and importance sampling of a blend of BRDF maps (formulas in the module
//! docs of [`crate::brdf`]). Everything goes through `otbake-runtime` point queries and samples,
//! as a renderer's BSDF would.

use super::{angles, direction, from_unit, to_unit};
use otbake_runtime::{Blend, Error, Kernel, Map, Proxy};
use std::f64::consts::PI;

/// Default kernel standard deviation in unit-cube units (≈ 1.8° in θ, 3.6° in φd): about a hundred
/// points of a 1M-point blend under the kernel where the BRDF is average.
pub const DEFAULT_SIGMA: f32 = 0.02;

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
    /// Point-query kernel.
    pub kernel: Kernel,
}

/// One importance sample of a blend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrdfSample {
    /// Incident direction (local frame, z = normal).
    pub wi: [f64; 3],
    /// Outgoing direction.
    pub wo: [f64; 3],
    /// Joint density of `(wi, wo)` in the product of solid angles.
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
    /// Checks that the maps are 3D and belong to `proxy`.
    pub fn new(proxy: Proxy<'a>, maps: &'m [Map<'a>], sigma: f32) -> Result<Self, BrdfBlendError> {
        let blend = Blend::new(proxy, maps)?;
        if blend.dim() != 3 {
            return Err(BrdfBlendError::NotBrdf(blend.dim()));
        }
        if (Kernel { sigma }).prepare(3).is_none() {
            return Err(BrdfBlendError::Runtime(Error::BadSigma));
        }
        Ok(Self {
            blend,
            kernel: Kernel { sigma },
        })
    }

    /// `f`, `f_Y` and `ρ_w` at `(θi, θo, φd)` (radians; `φd` in `[0, π]`): the point query divided
    /// by [`Self::inside_fraction`].
    pub fn eval_angles(
        &self,
        weights: &[f32],
        theta_i: f64,
        theta_o: f64,
        phi_d: f64,
    ) -> Result<BrdfValue, Error> {
        let u = to_unit(theta_i, theta_o, phi_d);
        let v = self.blend.point(weights, &u, self.kernel)?;
        let inside = self.inside_fraction(&u);
        Ok(BrdfValue {
            rgb: v.color.map(|c| c / inside),
            luminance: v.mass / inside,
            density: v.density / inside,
        })
    }

    /// Boundary correction: the fraction of the kernel centred at `u` that lies inside the cube
    /// (product over axes of the 1D Gaussian mass inside `[0, 1]`, each clipped to ±3σ as the
    /// runtime's kernel is). The density has no mass outside the cube, so a plain kernel estimate
    /// falls to about half at a face (θ = 0, θ = 90°, φd = 0 or π) and a quarter at an edge;
    /// dividing by this fraction removes that bias (the usual renormalization of kernel estimates
    /// on bounded domains; approximate, since the runtime truncates to a ball, not a box).
    pub fn inside_fraction(&self, u: &[f32; 3]) -> f32 {
        use crate::sample::normal::cdf;
        let s = f64::from(self.kernel.sigma);
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

    /// Sample `index` of the blend as a pair of directions. `xi` are two uniform numbers in
    /// `[0, 1)`: the first picks `φi`, the second the sign of `φd`.
    pub fn sample(&self, weights: &[f32], index: u32, xi: [f64; 2]) -> Result<BrdfSample, Error> {
        let s = self.blend.sample(weights, index)?;
        let (ti, to, pd) = from_unit(&s.position[..3]);
        let (ti, to, pd) = (
            ti.clamp(0.0, PI / 2.0),
            to.clamp(0.0, PI / 2.0),
            pd.clamp(0.0, PI),
        );
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

/// `ρ / (π⁴ sin θi sin θo)` (0 where the Jacobian vanishes).
pub fn joint_pdf(density: f32, theta_i: f64, theta_o: f64) -> f64 {
    let j = PI.powi(4) * theta_i.sin() * theta_o.sin();
    if j > 0.0 {
        f64::from(density) / j
    } else {
        0.0
    }
}
