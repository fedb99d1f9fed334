//! Blends of otbake BRDF maps as a renderer's BSDF sees them: evaluation, importance sampling and
//! the pdf of the samples ([`BrdfBlend`]), all through `otbake-runtime` point queries and samples.
//! The baker builds its BRDF images with this crate, and the C ABI and the Python package expose it,
//! so every caller evaluates a blend with the same code. It needs `std` for `f64` trigonometry, which
//! is why it is a crate of its own beside the `no_std` runtime.
//!
//! # Domain
//!
//! An isotropic BRDF depends on the two polar angles and the azimuth difference
//! `φd = φo − φi` only; with reciprocity `f(ωi, ωo) = f(ωo, ωi)` and isotropy `φd` and `−φd` give
//! the same value, so `φd` is folded into `[0, π]`. The domain `(θi, θo, φd) ∈ [0, π/2]² × [0, π]`
//! maps to the unit cube by `u = (θi / (π/2), θo / (π/2), φd / π)`: axis 0 = θi, axis 1 = θo,
//! axis 2 = φd (axis 0 fastest in the grid buffers, as for every input; see the baker's `otbake::input`).
//! Both directions point away from the surface, so the mirror direction of `ωi` is at `φd = π`.
//!
//! # Measure and value formula
//!
//! A grid cell's mass is the BRDF's **luminance at the cell centre, without any Jacobian**:
//! `mass_c = Y(f(θi, θo, φd))` with `Y = 0.2126 R + 0.7152 G + 0.0722 B`, `ratio_c = rgb / Y`
//! (0 where `Y = 0`). The baked density `ρ(u)` is therefore a pdf over the unit cube in the
//! `(θi, θo, φd)` parameter measure (uniform in angles), and `mean_mass = mean_c Y_c`. Because the
//! cube has volume 1, the cell normalization is 1 and, for a blend with weights `w`,
//!
//! ```text
//! f_rgb(ωi, ωo) = ρ_w(u) · Σ_k w_k mean_mass_k · ratio_w(u)     (= PointValue::color)
//! f_Y(ωi, ωo)   = ρ_w(u) · Σ_k w_k mean_mass_k                  (= PointValue::mass)
//! ```
//!
//! with `u = u(ωi, ωo)` as above; at weights `(1, 0, …)` this is the input grid's value smoothed
//! by the query kernel (see "Kernels" below for the two kernels: density-adaptive by default, or fixed). Why no Jacobian: evaluation — the operation a renderer calls most — then
//! never divides by `sin θ` or `cos θ`, which vanish at the pole and the horizon and would amplify
//! the kernel estimate's noise there; the paper stores plain luminance too.
//!
//! # Importance sampling
//!
//! The blend's points (`Blend::sample`) follow `ρ_w`, i.e. `f_Y` in the angle measure; with the
//! adaptive kernel (the default, "Kernels" below) a sample is point `i` plus noise of its kernel width,
//! folded into the cube, which follows the kernel estimate `ρ_w` *exactly*. A sample is
//! turned into a pair of directions by drawing `φi` uniformly in `[0, 2π)` and the sign of `φd`
//! with probability 1/2 each. The joint density of `(ωi, ωo)` in the product of solid angles
//! (`dω = sin θ dθ dφ`) is then
//!
//! ```text
//! pdf(ωi, ωo) = ρ_w(u) · 4/π³ (θi, θo, φd → u) · 1/(2π) (φi) · 1/2 (sign) / (sin θi sin θo)
//!             = ρ_w(u) / (π⁴ sin θi sin θo)
//! ```
//!
//! so that `E[f(ωi, ωo) cos θo / pdf] = ∫∫ f cos θo dωi dωo` ([`BrdfBlend::sample`] returns
//! the value and this pdf; the tests check the estimate against direct integration).
//!
//! # Kernels
//!
//! A blend is reconstructed with one of two kernels ([`BrdfKernel`]):
//!
//! * **adaptive** (the default, [`DEFAULT_ADAPTIVE`]): every blended point carries a Gaussian as
//!   wide as the blend's local spacing around it (`Blend::point_adaptive`), so a narrow specular
//!   lobe keeps its height and a query costs about the same number of points wherever it lands.
//!   The density is the *sample-point* estimate `ρ(u) = (1/n) Σ_i K_{σ_i}(u − y_i)`, made a density
//!   of the cube by reflection at its faces (below), and [`BrdfBlend::sample`] draws exactly from
//!   it: point `i`, plus noise from its own truncated Gaussian, folded back into the cube.
//! * **fixed** (`σ` everywhere, `Blend::point`): the earlier reconstruction, kept for comparison
//!   and for callers that want one width. The estimate near a face is divided by the kernel's
//!   inside fraction ([`BrdfBlend::inside_fraction`]), and `sample` returns the blended point itself,
//!   so its pdf (the smoothed density) matches the samples only approximately.
//!
//! # Faces (adaptive kernel)
//!
//! The cube's faces are where the density's domain ends: `φd = 0` and `φd = π` are folds of the
//! azimuth circle (the density is symmetric about them), `θ = 0` and `θ = π/2` the pole and the
//! horizon. A sample `u = y_i + σ_i z` that leaves the cube is reflected back (`−u`, or `2 − u`, per
//! axis), so the estimate's density at `u` in the cube is the sum of the sample-point estimate at
//! `u` and at its mirror images `−u_a`, `2 − u_a` (on every combination of axes): exactly
//! the density the folded samples have, no mass lost at a face, and no factor ½ there. A sample
//! that would need a second reflection (`u_a < −1` or `u_a > 2`, impossible unless a map holds
//! points a whole cube outside) is returned as a failed sample (pdf 0, value 0).

// RGB and 3-vector loops index several arrays at once; indices read better than zips here.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs)]

mod blend;
pub mod domain;
mod noise;
pub mod normal;

pub use blend::{
    BrdfBlend, BrdfBlendError, BrdfKernel, BrdfSample, BrdfValue, DEFAULT_ADAPTIVE, DEFAULT_SIGMA,
};
pub use noise::{joint_pdf, truncated_normal_3d};
