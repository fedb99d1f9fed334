//! A tiny seeded PRNG (SplitMix64) and random orthonormal bases built from it.
//!
//! Only integer arithmetic, `+ - * /` and `sqrt` (all correctly rounded in IEEE 754) are used, so the
//! streams are identical on every platform; no transcendental functions from the system libm.

/// SplitMix64 (Steele, Lea, Flood 2014): 64-bit state, passes BigCrush, trivially seedable.
#[derive(Clone, Debug)]
pub(crate) struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub(crate) fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// A random vector from a rotation-invariant distribution (uniform in the unit ball, by
    /// rejection) for `dim <= 10`; above that rejection is too slow and the vector is uniform in the
    /// cube [-1,1]^dim (not rotation-invariant, still full-rank and spread over all directions).
    /// Never the zero vector.
    pub(crate) fn ball_vector(&mut self, out: &mut [f64]) {
        let dim = out.len();
        loop {
            for v in out.iter_mut() {
                *v = 2.0 * self.next_f64() - 1.0;
            }
            let r2: f64 = out.iter().map(|v| v * v).sum();
            if r2 > 1e-12 && (dim > 10 || r2 <= 1.0) {
                return;
            }
        }
    }

    /// A unit vector (uniformly distributed on the sphere for `dim <= 10`).
    pub(crate) fn unit_vector(&mut self, out: &mut [f64]) {
        self.ball_vector(out);
        let norm = out.iter().map(|v| v * v).sum::<f64>().sqrt();
        for v in out.iter_mut() {
            *v /= norm;
        }
    }

    /// `dim` orthonormal row vectors (row-major `dim*dim`): Gram–Schmidt of i.i.d. rotation-invariant
    /// vectors, hence a Haar-random rotation for `dim <= 10`.
    pub(crate) fn rotation(&mut self, dim: usize) -> Vec<f64> {
        let mut basis = vec![0.0; dim * dim];
        let mut row = 0;
        while row < dim {
            let (done, rest) = basis.split_at_mut(row * dim);
            let v = &mut rest[..dim];
            self.ball_vector(v);
            let norm0 = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            // Modified Gram–Schmidt, twice for orthogonality to rounding level.
            for _ in 0..2 {
                for q in done.chunks_exact(dim) {
                    let dot: f64 = q.iter().zip(v.iter()).map(|(a, b)| a * b).sum();
                    for (x, a) in v.iter_mut().zip(q) {
                        *x -= dot * a;
                    }
                }
            }
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm <= 1e-6 * norm0 {
                continue; // nearly dependent draw: redraw this row
            }
            for x in v.iter_mut() {
                *x /= norm;
            }
            row += 1;
        }
        basis
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_is_orthonormal() {
        let mut rng = SplitMix64::new(7);
        for dim in 1..=12 {
            let r = rng.rotation(dim);
            for a in 0..dim {
                for b in 0..dim {
                    let dot: f64 = (0..dim).map(|k| r[a * dim + k] * r[b * dim + k]).sum();
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!((dot - want).abs() < 1e-12, "dim {dim}: <{a},{b}> = {dot}");
                }
            }
        }
    }

    #[test]
    fn streams_are_seeded() {
        let a: Vec<u64> = {
            let mut r = SplitMix64::new(1);
            (0..4).map(|_| r.next_u64()).collect()
        };
        let b: Vec<u64> = {
            let mut r = SplitMix64::new(1);
            (0..4).map(|_| r.next_u64()).collect()
        };
        let c = SplitMix64::new(2).next_u64();
        assert_eq!(a, b);
        assert_ne!(a[0], c);
        // Reference value of SplitMix64 seeded with 0 (first output).
        assert_eq!(SplitMix64::new(0).next_u64(), 0xE220_A839_7B1D_CDAF);
    }

    #[test]
    fn unit_vectors_cover_the_circle() {
        // Rotation invariance, coarsely: the mean of many unit vectors is near 0 and each quadrant
        // gets about a quarter of them.
        let mut rng = SplitMix64::new(3);
        let mut quadrants = [0usize; 4];
        let mut v = [0.0; 2];
        for _ in 0..4000 {
            rng.unit_vector(&mut v);
            assert!(((v[0] * v[0] + v[1] * v[1]) - 1.0).abs() < 1e-12);
            quadrants[usize::from(v[0] < 0.0) * 2 + usize::from(v[1] < 0.0)] += 1;
        }
        for q in quadrants {
            assert!((850..1150).contains(&q), "{quadrants:?}");
        }
    }
}
