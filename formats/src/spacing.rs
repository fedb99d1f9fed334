//! Per-point spacings: how far apart a map's points are around each point, stored as one byte per
//! point so that a reader can give every point its own kernel bandwidth (density-adaptive point
//! queries, `otbake_runtime::AdaptiveKernel`).
//!
//! # What is stored
//!
//! The baker estimates, for each mapped point `y_i` of a map, the local spacing
//! `s_i ≈ (n ρ(y_i))^(−1/d)` of the map's own point cloud (the side of the cube one point occupies
//! where the density is `ρ`) from the distance to its `K`-th nearest neighbour (see the baker's
//! `spacing` module for the estimator). Because a one-to-one map's points *are* the input's
//! samples, in any order, the spacings of a map do not depend on the solver that ordered them.
//!
//! # Code
//!
//! A spacing is a code `q` in `0..=255` on a logarithmic grid of eight steps per octave,
//!
//! ```text
//! decode(q) = 2^((q + 1)/8 − 32)      (q = 255 → 1.0, q = 0 → 2^−31.875 ≈ 2.5e-10)
//! ```
//!
//! computed exactly (a table of the eight `2^(j/8)` and a power of two), so [`decode`] is strictly
//! increasing in `q`. The writer rounds *up* ([`encode_up`]): the decoded spacing is at most 9%
//! larger than the estimate (spacings above 1 are stored as 1, below 2.5e-10 as 2.5e-10).
//!
//! # Node bounds
//!
//! Every internal node stores the largest code of the points below it (integer maximum, so exact),
//! and [`crate::open::open_map`] checks that each internal node's code is at least its children's
//! (and, above the leaves, at least every point's). Since [`decode`] is monotone, a reader's
//! blended node spacing `Σ w_k decode(Q_k)` bounds the blended spacing `Σ w_k decode(q_ki)` of every
//! point below (same order of operations, monotone rounding): pruning by it is exact.

/// `2^(j/8)` for `j = 0..8`, rounded to `f32`.
const OCTAVE: [f32; 8] = [
    1.0,
    1.090_507_7,
    1.189_207_1,
    1.296_839_6,
    core::f32::consts::SQRT_2,
    1.542_210_8,
    1.681_792_8,
    1.834_008_1,
];

/// Codes per octave of the grid.
pub const STEPS_PER_OCTAVE: u32 = 8;

/// The spacing of code `q`: `2^((q + 1)/8 − 32)`, exactly `OCTAVE[(q+1) mod 8] · 2^((q+1)/8 − 32)`.
#[inline]
pub fn decode(q: u8) -> f32 {
    let t = q as u32 + 1;
    let (octave, step) = (t / STEPS_PER_OCTAVE, t % STEPS_PER_OCTAVE);
    // 2^(octave − 32) with octave in 0..=32: a normal f32 built from its exponent bits.
    let pow2 = f32::from_bits((octave + 127 - 32) << 23);
    OCTAVE[step as usize] * pow2
}

/// The smallest code whose [`decode`] is at least `s` (255 when `s` is larger than 1 or NaN, 0
/// when `s` is at most `decode(0)`). The writer stores spacings with it, so stored spacings round up.
pub fn encode_up(s: f32) -> u8 {
    if s.is_nan() {
        return u8::MAX;
    }
    // Binary search over the monotone decode: the first q with decode(q) >= s.
    let (mut lo, mut hi) = (0u32, 255u32);
    if decode(255) < s {
        return u8::MAX;
    }
    while lo < hi {
        let mid = (lo + hi) / 2;
        if decode(mid as u8) >= s {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_is_strictly_increasing_and_exact() {
        for q in 0..255u8 {
            assert!(decode(q) < decode(q + 1), "{q}");
        }
        assert_eq!(decode(255), 1.0);
        assert_eq!(decode(7), 2f32.powi(-31));
        for q in 0..=255u8 {
            let want = 2f64.powf((q as f64 + 1.0) / 8.0 - 32.0);
            assert!((decode(q) as f64 / want - 1.0).abs() < 1e-7, "{q}");
        }
    }

    #[test]
    fn encode_rounds_up_to_the_next_code() {
        for q in 0..=255u8 {
            let v = decode(q);
            assert_eq!(encode_up(v), q, "exact values keep their code");
            if q > 0 {
                let below = f32::from_bits(v.to_bits() - 1);
                assert_eq!(encode_up(below), q, "just below a code rounds up to it");
            }
        }
        for s in [1e-3f32, 0.0123, 0.5, 0.999] {
            let q = encode_up(s);
            assert!(decode(q) >= s && (q == 0 || decode(q - 1) < s), "{s}");
            assert!(decode(q) <= s * 1.091, "within one step");
        }
        assert_eq!(encode_up(0.0), 0);
        assert_eq!(encode_up(-1.0), 0);
        assert_eq!(encode_up(2.0), 255);
        assert_eq!(encode_up(f32::INFINITY), 255);
        assert_eq!(encode_up(f32::NAN), 255);
    }
}
