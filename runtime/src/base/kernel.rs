//! The reconstruction kernel: an isotropic Gaussian truncated at 3σ and renormalized, so that the
//! reconstructed density integrates to 1 like the point distribution it smooths (paper §5.2).

/// Truncation radius in standard deviations.
pub const TRUNCATION: f32 = 3.0;

/// A Gaussian reconstruction kernel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    /// Standard deviation in domain units (`[0,1]` per axis).
    pub sigma: f32,
}

/// `(2π)^(d/2)` for d = 1..=4.
const TWO_PI_POW_HALF_D: [f32; 4] = [2.506_628_3, 6.283_185_5, 15.749_61, 39.478_416];

/// Mass of a d-dimensional standard normal inside radius 3 (χ²_d CDF at 9) for d = 1..=4.
const TRUNCATED_MASS: [f32; 4] = [0.997_300_2, 0.988_891, 0.970_709_1, 0.938_900_5];

/// A kernel prepared for one dimension: everything per-point evaluation needs, precomputed.
#[derive(Clone, Copy, Debug)]
pub struct PreparedKernel {
    /// Squared truncation radius.
    pub radius2: f32,
    /// `-1 / (2σ²)`.
    pub neg_inv_two_sigma2: f32,
    /// Normalization: 1 / ((2π)^(d/2) σ^d · truncated mass).
    pub norm: f32,
}

impl Kernel {
    /// Prepares the kernel for dimension `dim` (1..=4); `None` if sigma is not positive and finite or
    /// so small that its normalization overflows.
    pub fn prepare(&self, dim: usize) -> Option<PreparedKernel> {
        let s = self.sigma;
        if !(s.is_finite() && s > 0.0 && (1..=4).contains(&dim)) {
            return None;
        }
        let mut sd = 1.0f32;
        for _ in 0..dim {
            sd *= s;
        }
        let norm = 1.0 / (TWO_PI_POW_HALF_D[dim - 1] * sd * TRUNCATED_MASS[dim - 1]);
        let radius2 = TRUNCATION * TRUNCATION * s * s;
        if !(norm.is_finite() && radius2 > 0.0 && radius2.is_finite()) {
            return None;
        }
        Some(PreparedKernel {
            radius2,
            neg_inv_two_sigma2: -0.5 / (s * s),
            norm,
        })
    }
}

/// `1 / ((2π)^(d/2) · m_d)` for dimension `dim` (1..=4; 0 otherwise): the normalization of a
/// truncated kernel of width σ is this over `σ^d` (adaptive kernels compute it per point).
pub(crate) fn unit_norm(dim: usize) -> f32 {
    match (
        TWO_PI_POW_HALF_D.get(dim.wrapping_sub(1)),
        TRUNCATED_MASS.get(dim.wrapping_sub(1)),
    ) {
        (Some(a), Some(m)) => 1.0 / (a * m),
        _ => 0.0,
    }
}

impl PreparedKernel {
    /// Unnormalized weight `exp(-r²/2σ²)` of a point at squared distance `r2 <= radius2`.
    #[inline]
    pub fn weight(&self, r2: f32) -> f32 {
        exp(r2 * self.neg_inv_two_sigma2)
    }

    /// [`Self::weight`] of every entry, in a loop of its own: the compiler vectorizes it (lane by
    /// lane the same operations, so the same bits) when nothing else shares the loop.
    #[inline(always)]
    pub fn weights<const N: usize>(&self, r2: &[f32; N]) -> [f32; N] {
        let mut out = [0.0; N];
        for (o, &r) in out.iter_mut().zip(r2) {
            *o = self.weight(r);
        }
        out
    }
}

impl PreparedKernel {
    /// A splat's per-axis factor `e^(t² · −1/2σ²)` of a squared distance `t2 <= radius2` along one
    /// axis (see `SPLAT_TERM_TOLERANCE`): [`splat_exp`] of the product [`Self::weight`] takes.
    #[inline]
    pub fn factor(&self, t2: f32) -> f32 {
        splat_exp(t2 * self.neg_inv_two_sigma2)
    }

    /// [`Self::factor`] of every entry, in a loop of its own (vectorized like [`Self::weights`]).
    #[inline(always)]
    pub fn factors<const N: usize>(&self, t2: &[f32; N]) -> [f32; N] {
        let mut out = [0.0; N];
        for (o, &t) in out.iter_mut().zip(t2) {
            *o = self.factor(t);
        }
        out
    }
}

/// `e^x` for `x` in [-4.6, 0] within 2.5e-7 relative: the splat's factors, of which a 256² image
/// computes millions, so cheaper than [`exp`] (18 operations instead of 41, a shorter chain):
/// `e^x = 2^k · e^r` with `k = round(x / ln 2)` (by adding `1.5·2²³`, whose sum's low bits are
/// `k`), `|r| <= ln2/2 (1 + 2⁻²⁰)`, and a degree-5 polynomial fitted to `e^r` at Chebyshev nodes.
/// Branch-free and cast-free, so loops vectorize lane for lane. Outside the range (lanes past
/// the cutoff, which no splat adds) the value is meaningless but the function is total.
#[inline]
pub fn splat_exp(x: f32) -> f32 {
    const ROUND: f32 = 12_582_912.0;
    const C: [f32; 6] = [
        1.000_000_1,
        1.0,
        0.499_988_65,
        0.166_665_05,
        0.041_918_05,
        0.008_369_226,
    ];
    let t = x * core::f32::consts::LOG2_E + ROUND;
    let k = t - ROUND;
    let r = x - k * core::f32::consts::LN_2;
    let p = C[0] + r * (C[1] + r * (C[2] + r * (C[3] + r * (C[4] + r * C[5]))));
    // 2^k: the bits of `t` minus those of `ROUND` are `k`; plus the exponent bias, shifted.
    let two_k = t.to_bits().wrapping_sub(ROUND.to_bits() - 127) << 23;
    f32::from_bits(two_k) * p
}

/// `e^x` for `x` in [-4.5, 0] (the truncated kernel's range), within ~2 ulp; `core` has no `exp`
/// without `std`, and the runtime depends on nothing but the archive format.
///
/// Branch-free and free of float-to-int casts (Rust's saturating casts do not vectorize), so loops
/// over many weights compile to SIMD code with lane-by-lane the same results.
#[inline]
pub fn exp(x: f32) -> f32 {
    // e^x = 2^k · e^r with k = trunc(x / ln 2 - 0.5) (a rounding of x / ln 2), |r| <= ln2 / 2.
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    // Adding and subtracting 1.5·2^23 rounds an |v| < 2^22 to the nearest integer (f32 has no
    // fraction bits left at that magnitude).
    const ROUND: f32 = 12_582_912.0;
    let x = x.clamp(-80.0, 0.0);
    let v = x * core::f32::consts::LOG2_E - 0.5;
    // v <= -0.5: truncation toward 0 is the ceiling; from the nearest integer, step up if below.
    let t = (v + ROUND) - ROUND;
    let kf = if t < v { t + 1.0 } else { t };
    let r = (x - kf * LN2_HI) - kf * LN2_LO;
    // Degree-6 Taylor polynomial of e^r on |r| <= 0.35: error < 2e-8 relative.
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
    // 2^k from the bits of 2^23 + 127 + k (an exact f32 whose low mantissa bits are k + 127).
    let biased = (kf + (127.0 + 8_388_608.0))
        .to_bits()
        .wrapping_sub(0x4B00_0000);
    f32::from_bits(biased << 23) * p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_is_accurate_on_the_kernel_range() {
        let mut worst = 0.0f64;
        for i in 0..=45_000 {
            let x = -(i as f32) * 1e-4;
            let want = (x as f64).exp();
            let got = exp(x) as f64;
            worst = worst.max(((got - want) / want).abs());
        }
        assert!(worst < 3e-7, "worst relative error {worst}");
    }

    /// The cast-based formulation `exp` had before it was made vectorizable: results must not
    /// change by a single bit (kernel sums of every query depend on them).
    fn reference_exp(x: f32) -> f32 {
        const LN2_HI: f32 = 0.693_145_75;
        const LN2_LO: f32 = 1.428_606_8e-6;
        let x = x.clamp(-80.0, 0.0);
        let kf = (x * core::f32::consts::LOG2_E - 0.5) as i32 as f32;
        let r = (x - kf * LN2_HI) - kf * LN2_LO;
        let p = 1.0
            + r * (1.0
                + r * (0.5
                    + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
        let k = kf as i32;
        f32::from_bits(((k + 127) as u32) << 23) * p
    }

    #[test]
    fn exp_equals_the_reference_bit_for_bit() {
        // Every 61st f32 from -0 down past -128 (the clamp), and every f32 of [-4.5, -4.4].
        let mut bits = 0x8000_0000u32;
        let mut checked = 0u64;
        while bits <= 0xC300_0000 {
            let x = f32::from_bits(bits);
            assert_eq!(exp(x).to_bits(), reference_exp(x).to_bits(), "x = {x:e}");
            bits += if (-4.5..=-4.4).contains(&x) { 1 } else { 61 };
            checked += 1;
        }
        assert!(checked > 10_000_000);
        for x in [
            0.0f32,
            -0.0,
            1.0,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -1e30,
            f32::MIN,
        ] {
            assert_eq!(exp(x).to_bits(), reference_exp(x).to_bits(), "x = {x:e}");
        }
    }

    #[test]
    fn splat_exp_is_accurate_on_the_kernel_range() {
        // Every 7th f32 of [-4.6, 0] (and the ends).
        let mut worst = 0.0f64;
        let mut bits = 0x8000_0000u32;
        let last = (-4.6f32).to_bits();
        while bits <= last {
            let x = f32::from_bits(bits);
            let want = (x as f64).exp();
            worst = worst.max(((splat_exp(x) as f64 - want) / want).abs());
            bits += 7;
        }
        for x in [0.0f32, -0.0, -4.6, -4.5, -f32::MIN_POSITIVE] {
            let want = (x as f64).exp();
            worst = worst.max(((splat_exp(x) as f64 - want) / want).abs());
        }
        assert!(worst < 2.6e-7, "worst relative error {worst}");
        // Total outside the range.
        for x in [f32::NEG_INFINITY, f32::NAN, -1e30, 1e30, 100.0, -200.0] {
            let _ = splat_exp(x);
        }
    }

    #[test]
    fn bad_sigmas_are_refused() {
        for s in [0.0, -1.0, f32::NAN, f32::INFINITY, 1e-30] {
            assert!(Kernel { sigma: s }.prepare(2).is_none(), "{s}");
        }
        assert!(Kernel { sigma: 0.01 }.prepare(5).is_none());
    }
}
