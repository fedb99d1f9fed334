//! The isotropic BRDF domain `(θi, θo, φd)` and the unit cube it is baked on (crate docs, "Domain").

use std::f64::consts::{FRAC_PI_2, PI};

/// Rec. 709 / sRGB luminance weights (the same as the image inputs').
pub const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// `(θi, θo, φd)` in radians → unit-cube coordinates (axis 0 = θi, 1 = θo, 2 = φd).
pub fn to_unit(theta_i: f64, theta_o: f64, phi_d: f64) -> [f32; 3] {
    [
        (theta_i / FRAC_PI_2) as f32,
        (theta_o / FRAC_PI_2) as f32,
        (phi_d / PI) as f32,
    ]
}

/// Unit-cube coordinates → `(θi, θo, φd)` in radians.
pub fn from_unit(u: &[f32]) -> (f64, f64, f64) {
    (
        f64::from(u[0]) * FRAC_PI_2,
        f64::from(u[1]) * FRAC_PI_2,
        f64::from(u[2]) * PI,
    )
}

/// Folds an azimuth difference into `[0, π]` (isotropy and reciprocity).
pub fn fold_phi(phi: f64) -> f64 {
    let d = phi.rem_euclid(2.0 * PI);
    if d > PI {
        2.0 * PI - d
    } else {
        d
    }
}

/// Unit direction at polar angle `theta` and azimuth `phi` (z = normal).
pub fn direction(theta: f64, phi: f64) -> [f64; 3] {
    [
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    ]
}

/// `(θi, θo, φd)` of a pair of unit directions in the local frame (z = normal); `None` when either
/// lies below the horizon.
pub fn angles(wi: [f64; 3], wo: [f64; 3]) -> Option<(f64, f64, f64)> {
    if wi[2] < 0.0 || wo[2] < 0.0 {
        return None;
    }
    let ti = wi[2].clamp(-1.0, 1.0).acos();
    let to = wo[2].clamp(-1.0, 1.0).acos();
    let pd = fold_phi(wo[1].atan2(wo[0]) - wi[1].atan2(wi[0]));
    Some((ti, to, pd))
}

/// Luminance of linear RGB.
pub fn luminance(rgb: [f64; 3]) -> f64 {
    LUMINANCE[0] * rgb[0] + LUMINANCE[1] * rgb[1] + LUMINANCE[2] * rgb[2]
}
