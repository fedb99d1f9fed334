//! An exponential for sums of many exponentials, e^x for x ≤ 0, written so that a loop over an
//! array of exponents vectorizes (no branch, no libm call): the soft c-transform that carries a
//! potential to the next stage takes one exponential per term of its sums, about 120 per target
//! point, and as libm calls they were most of that pass (D162). That potential is only a stage's
//! starting point, so an exponential to about 1e-12 relative is far more than it needs. Pure
//! arithmetic in a fixed order: the same bits on every thread count.

/// ln 2 split in two (Cody–Waite, fdlibm's constants): `LN2_HI` has its low 21 bits zero, so
/// n·`LN2_HI` is exact for the n here.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fee0_0000);
const LN2_LO: f64 = f64::from_bits(0x3dea_39ef_3579_3c76);

/// 1.5 · 2^52: adding it to a number below 2^51 in magnitude rounds it to an integer held in the
/// low bits of the sum's mantissa.
const SHIFTER: f64 = 6_755_399_441_055_744.0;

/// Below this exponent e^x is taken as e^−700 (≈ 1e−304): a term that small is nothing beside a
/// sum's largest term, 1.
const LOWEST: f64 = -700.0;

/// 1/k! for k = 0..=11.
const TAYLOR: [f64; 12] = [
    1.0,
    1.0,
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
];

/// e^x for x ≤ 0 (and NaN → NaN), to about 1e-12 relative; exponents below −700 give e^−700.
#[inline(always)]
fn exp_neg(x: f64) -> f64 {
    // (Not `max`, which would take a NaN to the floor: a NaN exponent stays one.)
    let x = if x < LOWEST { LOWEST } else { x };
    // n = round(x / ln 2) as the low bits of `t`, f = x − n ln 2 in [−ln2/2, ln2/2].
    let t = x * std::f64::consts::LOG2_E + SHIFTER;
    let n = t - SHIFTER;
    let f = (x - n * LN2_HI) - n * LN2_LO;
    // Taylor to degree 11 (|f|^12/12! < 1e-13 on that interval), by Horner's rule from the
    // highest term: p ← c_k + f·p, the same operations in the same order as the nested form
    // (which rustfmt took minutes to lay out).
    let mut p = TAYLOR[11];
    for &c in TAYLOR[..11].iter().rev() {
        p = c + f * p;
    }
    // 2^n from n's bits in `t` (n in [−1010, 0]: a normal number).
    let bits = t
        .to_bits()
        .wrapping_sub(SHIFTER.to_bits())
        .wrapping_add(1023)
        << 52;
    p * f64::from_bits(bits)
}

/// Σ_k e^((t_k − m)/ε) for terms t_k ≤ m, in four partial sums added in a fixed order; the terms
/// are overwritten by their exponentials.
pub(super) fn sum_exp(terms: &mut [f64], m: f64, eps: f64) -> f64 {
    let inv = 1.0 / eps;
    for t in terms.iter_mut() {
        *t = exp_neg((*t - m) * inv);
    }
    let mut acc = [0.0f64; 4];
    let chunks = terms.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for l in 0..4 {
            acc[l] += c[l];
        }
    }
    for (l, &e) in rest.iter().enumerate() {
        acc[l] += e;
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 1e-12 relative of libm from 0 down to −700, e^−700 below, NaN kept.
    #[test]
    fn exp_neg_agrees_with_libm() {
        let mut worst = 0f64;
        let mut x = 0.0f64;
        while x > -700.0 {
            for y in [x, x - 1e-9, x * 0.999_999_7] {
                let (fast, libm) = (exp_neg(y), y.exp());
                worst = worst.max((fast / libm - 1.0).abs());
            }
            x -= 0.013_7;
        }
        assert!(worst < 1e-12, "worst relative error {worst:e}");
        assert_eq!(exp_neg(-1e6), exp_neg(-700.0));
        assert_eq!(exp_neg(f64::NEG_INFINITY), exp_neg(-700.0));
        assert!(exp_neg(f64::NAN).is_nan());
        assert_eq!(exp_neg(0.0), 1.0);
    }

    /// The sum of exponentials against libm's, term by term.
    #[test]
    fn sum_exp_agrees_with_libm() {
        let terms: Vec<f64> = (0..1001).map(|k| -0.37 * f64::from(k)).collect();
        let libm: f64 = terms.iter().map(|&t| ((t - 0.0) / 0.5).exp()).sum();
        let fast = sum_exp(&mut terms.clone(), 0.0, 0.5);
        assert!((fast / libm - 1.0).abs() < 1e-13, "{fast} vs {libm}");
    }
}
