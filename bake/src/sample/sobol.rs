//! An Owen-scrambled Sobol sequence with random access by index.
//!
//! Direction numbers are Joe & Kuo's `new-joe-kuo-6.21201` (S. Joe and F. Y. Kuo, "Constructing
//! Sobol sequences with better two-dimensional projections", SIAM J. Sci. Comput. 30, 2008), with
//! 32 bits, so indices up to `2^32 − 1` are valid. Points are taken in Gray-code order, as in Joe &
//! Kuo's reference generator: unscrambled, point `i` equals theirs (and SciPy's `qmc.Sobol` with
//! `scramble=False`), and for every `m` the first `2^m` points are the same set as in natural order.
//!
//! Each dimension is randomized by a nested uniform (Owen) scramble with a seed-derived key, in the
//! hash-based form of Burley, "Practical Hash-based Owen Scrambling" (JCGT 2020): reverse the bits,
//! apply a Laine–Karras style permutation in which every output bit depends only on the same and
//! lower input bits, reverse back. In the original bit order that means each binary digit is
//! flipped by a function of the digits above it, i.e. a permutation of the elementary intervals at
//! every level, so every stratification property of the sequence (one point per elementary interval,
//! (0, m, 2)-nets in the first two dimensions) survives, and the seed alone determines the output.

use super::SampleError;

/// Rows `s a m_1 … m_s` of `new-joe-kuo-6.21201` for dimensions 2..=21 (dimension 1 is the van der
/// Corput sequence, `m_k = 1`). `a` encodes the primitive polynomial's inner coefficients, top first.
const JOE_KUO: [(u32, u32, &[u32]); 20] = [
    (1, 0, &[1]),
    (2, 1, &[1, 3]),
    (3, 1, &[1, 3, 1]),
    (3, 2, &[1, 1, 1]),
    (4, 1, &[1, 1, 3, 3]),
    (4, 4, &[1, 3, 5, 13]),
    (5, 2, &[1, 1, 5, 5, 17]),
    (5, 4, &[1, 1, 5, 5, 5]),
    (5, 7, &[1, 1, 7, 11, 19]),
    (5, 11, &[1, 1, 5, 1, 1]),
    (5, 13, &[1, 1, 1, 3, 11]),
    (5, 14, &[1, 3, 5, 5, 31]),
    (6, 1, &[1, 3, 3, 9, 7, 49]),
    (6, 13, &[1, 1, 1, 15, 21, 21]),
    (6, 16, &[1, 3, 1, 13, 27, 49]),
    (6, 19, &[1, 1, 1, 15, 7, 5]),
    (6, 22, &[1, 3, 1, 15, 13, 25]),
    (6, 25, &[1, 1, 5, 5, 19, 61]),
    (7, 1, &[1, 3, 7, 11, 23, 15, 103]),
    (7, 4, &[1, 3, 7, 13, 13, 15, 69]),
];

const BITS: usize = 32;

/// A scrambled Sobol sequence over `[0,1)^dims`.
#[derive(Clone, Debug)]
pub struct Sobol {
    /// Direction numbers per dimension; `directions[d][k]` belongs to bit `k` of the Gray code.
    directions: Vec<[u32; BITS]>,
    /// Scramble key per dimension; `None` for the unscrambled sequence.
    keys: Option<Vec<u32>>,
}

impl Sobol {
    /// Number of dimensions with direction numbers.
    pub const MAX_DIMS: usize = JOE_KUO.len() + 1;
    /// Exclusive upper bound of the point index.
    pub const MAX_INDEX: u64 = 1 << BITS;

    /// The sequence in `dims` dimensions, Owen-scrambled with keys derived from `seed`.
    pub fn new(dims: usize, seed: u64) -> Result<Self, SampleError> {
        let mut sobol = Self::unscrambled(dims)?;
        sobol.keys = Some(
            (0..dims as u64)
                .map(|d| (mix64(seed ^ mix64(d.wrapping_add(0x5b0b_01d0_5eed))) >> 32) as u32)
                .collect(),
        );
        Ok(sobol)
    }

    /// The plain Sobol sequence (point 0 is the origin), for reference and tests.
    pub fn unscrambled(dims: usize) -> Result<Self, SampleError> {
        if dims == 0 || dims > Self::MAX_DIMS {
            return Err(SampleError::Dims {
                dims,
                max: Self::MAX_DIMS,
            });
        }
        let directions = (0..dims).map(directions).collect();
        Ok(Sobol {
            directions,
            keys: None,
        })
    }

    /// Number of dimensions.
    pub fn dims(&self) -> usize {
        self.directions.len()
    }

    /// Writes point `index` into `out` (`out.len() == dims()`), each coordinate in `[0, 1)`.
    ///
    /// # Panics
    /// If `index >= Sobol::MAX_INDEX` or `out` has the wrong length (caller bugs: the samplers cap
    /// their counts far below).
    pub fn point(&self, index: u64, out: &mut [f64]) {
        assert!(
            index < Self::MAX_INDEX,
            "Sobol index {index} is out of range (at most 2^32 - 1)"
        );
        assert_eq!(
            out.len(),
            self.dims(),
            "Sobol point buffer has the wrong length"
        );
        for (d, o) in out.iter_mut().enumerate() {
            *o = f64::from(self.coordinate(index as u32, d)) * (1.0 / 4_294_967_296.0);
        }
    }

    /// Coordinate `d` of point `index` as a 32-bit fixed-point fraction.
    fn coordinate(&self, index: u32, d: usize) -> u32 {
        let v = &self.directions[d];
        let mut gray = index ^ (index >> 1);
        let mut x = 0u32;
        while gray != 0 {
            x ^= v[gray.trailing_zeros() as usize];
            gray &= gray - 1;
        }
        match &self.keys {
            Some(keys) => owen_scramble(x, keys[d]),
            None => x,
        }
    }
}

/// Direction numbers `V_k = m_k · 2^(32−k)` (k = 1..=32) of dimension `d` (0-based).
fn directions(d: usize) -> [u32; BITS] {
    let mut v = [0u32; BITS];
    if d == 0 {
        for (k, vk) in v.iter_mut().enumerate() {
            *vk = 1 << (BITS - 1 - k);
        }
        return v;
    }
    let (s, a, m) = JOE_KUO[d - 1];
    let s = s as usize;
    for k in 0..s.min(BITS) {
        v[k] = m[k] << (BITS - 1 - k);
    }
    // m_k = 2^s m_{k−s} ⊕ m_{k−s} ⊕ ⊕_{j=1}^{s−1} 2^j a_j m_{k−j}, in shifted form.
    for k in s..BITS {
        let mut x = v[k - s] ^ (v[k - s] >> s);
        for j in 1..s {
            if (a >> (s - 1 - j)) & 1 == 1 {
                x ^= v[k - j];
            }
        }
        v[k] = x;
    }
    v
}

/// Nested uniform scramble of a 32-bit fraction (Burley 2020): in reversed bit order every step is a
/// bijection whose output bit `k` depends only on input bits `<= k` (xor with a multiple by an even
/// constant, addition, multiplication by an odd number), i.e. each original digit is flipped by a
/// function of the more significant digits and the key.
fn owen_scramble(x: u32, key: u32) -> u32 {
    let mut v = x.reverse_bits();
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(key);
    v = v.wrapping_mul((key >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits()
}

/// SplitMix64 finalizer: seeds to well-mixed keys.
fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixed(sobol: &Sobol, index: u64) -> Vec<u32> {
        let mut p = vec![0.0; sobol.dims()];
        sobol.point(index, &mut p);
        p.iter()
            .map(|&x| {
                let f = x * 4_294_967_296.0;
                assert_eq!(f.fract(), 0.0);
                f as u32
            })
            .collect()
    }

    #[test]
    fn first_points_match_the_reference() {
        let s = Sobol::unscrambled(2).unwrap();
        let mut p = [0.0; 2];
        let want = [
            [0.0, 0.0],
            [0.5, 0.5],
            [0.75, 0.25],
            [0.25, 0.75],
            [0.375, 0.375],
            [0.875, 0.875],
            [0.625, 0.125],
            [0.125, 0.625],
        ];
        for (i, w) in want.iter().enumerate() {
            s.point(i as u64, &mut p);
            assert_eq!(&p, w, "point {i}");
        }
    }

    /// Reference values from SciPy 1.18 `qmc.Sobol(d=21, scramble=False, bits=32)` (Joe–Kuo
    /// 6.21201), times 2^32; they pin every direction-number row, including bits beyond 2^24.
    #[test]
    fn all_dimensions_match_scipy() {
        let s = Sobol::unscrambled(Sobol::MAX_DIMS).unwrap();
        let cases: [(u64, [u32; 21]); 4] = [
            (
                8,
                [
                    805306368, 1342177280, 4026531840, 1879048192, 2415919104, 1342177280,
                    1879048192, 4026531840, 4026531840, 1342177280, 2952790016, 268435456,
                    4026531840, 4026531840, 3489660928, 4026531840, 3489660928, 3489660928,
                    4026531840, 1342177280, 805306368,
                ],
            ),
            (
                1_000_003,
                [
                    1187450880, 2413424640, 334991360, 1796354048, 3773812736, 2341023744,
                    948097024, 1145868288, 216535040, 18903040, 3815354368, 2925629440, 2247200768,
                    1216950272, 3861630976, 2001866752, 828977152, 2179633152, 3620204544,
                    2715676672, 3393581056,
                ],
            ),
            (
                16_777_259,
                [
                    2080375168, 2877325184, 1364536704, 1096510848, 2072664960, 1836587904,
                    3953087872, 305663360, 597133184, 2179433088, 11352448, 160145024, 2666762880,
                    2702463360, 133546368, 3186454400, 2578764672, 36213632, 1619986304,
                    1000956544, 4209154432,
                ],
            ),
            (
                3_000_000_017,
                [
                    2559450583, 4098318889, 330020855, 1683259733, 1592647243, 44323257,
                    3808236037, 2288381495, 1834926823, 973412927, 895332955, 3415259003,
                    1088245513, 3059342837, 2312202851, 3401505191, 1144814885, 2868775327,
                    4072018113, 3472785721, 1097861535,
                ],
            ),
        ];
        for (index, want) in cases {
            assert_eq!(fixed(&s, index), want, "point {index}");
        }
    }

    /// Every dimension, scrambled or not: the first 2^m points put exactly one point in each
    /// interval [k/2^m, (k+1)/2^m); also for the block [2^m, 2^(m+1)).
    #[test]
    fn one_point_per_elementary_interval() {
        for sobol in [
            Sobol::unscrambled(Sobol::MAX_DIMS).unwrap(),
            Sobol::new(Sobol::MAX_DIMS, 7).unwrap(),
        ] {
            for m in [1u32, 4, 10] {
                let n = 1u64 << m;
                for start in [0, n] {
                    let mut seen = vec![vec![false; n as usize]; sobol.dims()];
                    let mut p = vec![0.0; sobol.dims()];
                    for i in start..start + n {
                        sobol.point(i, &mut p);
                        for (d, &x) in p.iter().enumerate() {
                            let k = (x * n as f64) as usize;
                            assert!(!seen[d][k], "m {m}: dim {d} interval {k} twice");
                            seen[d][k] = true;
                        }
                    }
                }
            }
        }
    }

    /// The first two dimensions form a (0, m, 2)-net: every elementary box of area 2^-m, of any
    /// aspect ratio 2^-a × 2^-(m−a), holds exactly one of the first 2^m points.
    #[test]
    fn first_two_dimensions_are_a_0_m_2_net() {
        for sobol in [Sobol::unscrambled(2).unwrap(), Sobol::new(2, 99).unwrap()] {
            for m in [2u32, 6, 11] {
                let n = 1usize << m;
                let pts: Vec<[f64; 2]> = (0..n as u64)
                    .map(|i| {
                        let mut p = [0.0; 2];
                        sobol.point(i, &mut p);
                        p
                    })
                    .collect();
                for a in 0..=m {
                    let (nx, ny) = (1usize << a, 1usize << (m - a));
                    let mut count = vec![0u32; n];
                    for p in &pts {
                        let (x, y) = ((p[0] * nx as f64) as usize, (p[1] * ny as f64) as usize);
                        count[x + nx * y] += 1;
                    }
                    assert!(count.iter().all(|&c| c == 1), "m {m}, a {a}");
                }
            }
        }
    }

    #[test]
    fn seeds_are_deterministic_and_distinct() {
        let a = Sobol::new(4, 42).unwrap();
        let b = Sobol::new(4, 42).unwrap();
        let c = Sobol::new(4, 43).unwrap();
        let (mut pa, mut pb, mut pc) = ([0.0; 4], [0.0; 4], [0.0; 4]);
        let mut differ = 0;
        for i in 0..64 {
            a.point(i, &mut pa);
            b.point(i, &mut pb);
            c.point(i, &mut pc);
            assert_eq!(pa, pb);
            differ += pa.iter().zip(&pc).filter(|(x, y)| x != y).count();
        }
        assert!(
            differ > 250,
            "only {differ} of 256 coordinates changed with the seed"
        );
        // Dimensions get different keys: scrambled dims 0 and 1 are not the same sequence
        // (unscrambled they agree for the first points).
        a.point(1, &mut pa);
        assert_ne!(pa[0], pa[1]);
    }

    #[test]
    fn large_indices_work_and_stay_in_range() {
        let s = Sobol::new(3, 5).unwrap();
        let mut p = [0.0; 3];
        for index in [
            1u64 << 24,
            (1 << 24) + 12345,
            (1 << 28) - 1,
            1 << 28,
            u32::MAX as u64,
        ] {
            s.point(index, &mut p);
            assert!(p.iter().all(|&x| (0.0..1.0).contains(&x)), "{index}: {p:?}");
        }
        // Points 2^24 .. 2^24 + 2^10 are a stratified block too.
        let mut seen = [false; 1024];
        for i in 0..1024u64 {
            s.point((1 << 24) + i, &mut p);
            let k = (p[2] * 1024.0) as usize;
            assert!(!seen[k]);
            seen[k] = true;
        }
    }

    #[test]
    fn bad_dimensions_are_errors() {
        assert!(matches!(Sobol::new(0, 1), Err(SampleError::Dims { .. })));
        let err = Sobol::new(Sobol::MAX_DIMS + 1, 1).unwrap_err();
        assert!(err.to_string().contains("21"), "{err}");
    }

    #[test]
    #[should_panic(expected = "out of range")]
    fn index_past_2_pow_32_panics() {
        let mut p = [0.0];
        Sobol::new(1, 0).unwrap().point(1 << 32, &mut p);
    }
}
