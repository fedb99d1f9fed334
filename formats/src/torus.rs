//! Arithmetic on the flat torus `[0,1)^d` ([`Wrap::Periodic`]), written once for the baker and the
//! runtime: folding a coordinate onto the circle, the shortest displacement between two coordinates,
//! and the lift `p + δ` that periodic maps store.
//!
//! Both sides must agree on these to the bit: the baker stores lifts made with [`lift_point`], and the
//! runtime folds blended lifts back with [`fold`]. `core` has no float rounding without `std`, so
//! [`floor_f32`] and [`floor_f64`] are written here; they return exactly what `std`'s `floor` returns
//! for every input (signed zeros and infinities included; NaN stays NaN), so moving a caller from `std` to
//! these changes no bits.
//!
//! ```
//! use otbake_formats::torus::{delta, fold, lift_point};
//! use otbake_formats::Wrap;
//! assert_eq!(fold(1.25), 0.25);
//! assert_eq!(fold(-0.25), 0.75);
//! // From 0.9 the nearest image of 0.1 is 1.1: the shortest step crosses the seam.
//! assert!((delta(Wrap::Periodic, 0.9, 0.1) - 0.2).abs() < 1e-12);
//! assert_eq!(delta(Wrap::Clamp, 0.9, 0.1), 0.1 - 0.9);
//! let mut mapped = [0.1_f32, 0.5];
//! lift_point(&[0.9, 0.4], &mut mapped);
//! assert!((mapped[0] - 1.1).abs() < 1e-6 && mapped[1] == 0.5);
//! ```

use crate::Wrap;

/// `floor(v)` of an `f32`, bit-identical to `std`'s `f32::floor` (without `std`).
///
/// Values of magnitude `2^23` and more are integers already, and are returned unchanged, as are
/// infinities and both zeros; NaN stays NaN.
#[inline]
pub fn floor_f32(v: f32) -> f32 {
    if v.is_nan() || v == 0.0 || v.abs() >= 8_388_608.0 {
        return v;
    }
    let t = v as i32 as f32;
    if t > v {
        t - 1.0
    } else {
        t
    }
}

/// `floor(v)` of an `f64`, bit-identical to `std`'s `f64::floor` (without `std`).
///
/// Values of magnitude `2^52` and more are integers already, and are returned unchanged, as are
/// infinities and both zeros; NaN stays NaN.
#[inline]
pub fn floor_f64(v: f64) -> f64 {
    if v.is_nan() || v == 0.0 || v.abs() >= 4_503_599_627_370_496.0 {
        return v;
    }
    let t = v as i64 as f64;
    if t > v {
        t - 1.0
    } else {
        t
    }
}

/// `v` folded onto the circle `[0, 1)` (NaN stays NaN; callers pass finite values).
#[inline]
pub fn fold(v: f32) -> f32 {
    let f = v - floor_f32(v);
    // `v − floor(v)` rounds up to exactly 1 for tiny negative `v`: that point is 0 on the circle.
    if f >= 1.0 {
        0.0
    } else {
        f
    }
}

/// The shortest displacement from `from` to `to` along one axis: `to − from`, or on the torus the
/// representative of `to − from` modulo 1 in `[−½, ½)`, so `from + delta` is the nearest image of
/// `to` and a map's lift `x + delta(x, T(x))` follows the geodesic.
#[inline]
pub fn delta(wrap: Wrap, from: f64, to: f64) -> f64 {
    let d = to - from;
    match wrap {
        Wrap::Clamp => d,
        Wrap::Periodic => shortest(d),
    }
}

/// `d` reduced modulo 1 into `[−½, ½)`: the shortest of the displacements `d + m`, `m` an integer.
#[inline]
pub fn shortest(d: f64) -> f64 {
    d - floor_f64(d + 0.5)
}

/// Turns one mapped point into its lift: each coordinate `m_k` of `mapped` becomes `s_k + δ_k`, with
/// `s` the proxy point in `source` and `δ_k = delta(Periodic, s_k, m_k)`, so `|δ_k| ≤ ½` and
/// interpolating lifts follows the torus geodesic. Periodic map archives store these lifts.
///
/// Both slices hold one point (`dim` coordinates); extra coordinates of the longer one are ignored.
#[inline]
pub fn lift_point(source: &[f32], mapped: &mut [f32]) {
    for (m, &s) in mapped.iter_mut().zip(source) {
        let d = delta(Wrap::Periodic, f64::from(s), f64::from(*m));
        *m = (f64::from(s) + d) as f32;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    /// Values around every case the rounding trick has to get right: both zeros, tiny magnitudes,
    /// halves, integers, the end of the exactly-representable range, infinities and NaN.
    fn probes_f64() -> std::vec::Vec<f64> {
        let mut v = std::vec![
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            1e-300,
            -1e-300,
            0.5,
            -0.5,
            0.999_999_999_999_999_9,
            -0.999_999_999_999_999_9,
            1.0,
            -1.0,
            1.5,
            -1.5,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            9.0e18,
            -9.0e18,
            1.0e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
        ];
        let mut x = 0x9e37_79b9_7f4a_7c15_u64;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let f = (x >> 11) as f64 / (1u64 << 53) as f64;
            v.push((f - 0.5) * 16.0);
            v.push(f64::from_bits(x));
        }
        v
    }

    #[test]
    fn floors_match_std_bit_for_bit() {
        for v in probes_f64() {
            if v.is_nan() {
                // NaN payloads are not part of the contract (std may quiet a signalling NaN).
                assert!(floor_f64(v).is_nan() && floor_f32(v as f32).is_nan());
                continue;
            }
            assert_eq!(
                floor_f64(v).to_bits(),
                v.floor().to_bits(),
                "floor_f64({v:e})"
            );
            let s = v as f32;
            assert_eq!(
                floor_f32(s).to_bits(),
                s.floor().to_bits(),
                "floor_f32({s:e})"
            );
        }
        assert!(floor_f64(f64::NAN).is_nan() && floor_f32(f32::NAN).is_nan());
    }

    #[test]
    fn fold_lands_on_the_circle() {
        for v in probes_f64() {
            let s = v as f32;
            if !s.is_finite() {
                continue;
            }
            let f = fold(s);
            assert!((0.0..1.0).contains(&f), "fold({s:e}) = {f:e}");
        }
        // The tiny negative value whose `v − floor(v)` rounds to 1 folds to 0.
        assert_eq!(fold(-1e-9), 0.0);
    }

    #[test]
    fn shortest_displacement_is_the_nearest_image() {
        for v in probes_f64() {
            if !v.is_finite() || v.abs() > 1e6 {
                continue;
            }
            let s = shortest(v);
            assert!((-0.5..0.5).contains(&s), "shortest({v:e}) = {s:e}");
            let m = v - s;
            assert_eq!(m, m.round(), "shortest({v:e}) moved by a non-integer");
        }
        assert_eq!(delta(Wrap::Clamp, 0.25, 2.0), 1.75);
    }
}
