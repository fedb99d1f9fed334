//! Matching along one direction: 1D optimal transport between equal-size clouds is sorting, done
//! here by a stable radix sort on order keys, so the result is the same for any thread count.

/// Buffers of one direction, reused across iterations.
pub(crate) struct Direction {
    /// Projections of the moving points, then their 1D displacements.
    pub(crate) xp: Vec<f64>,
    /// Order keys of the moving points' projections, sorted along with `idx`.
    keys: Vec<u64>,
    /// Point indices, in key order after sorting.
    idx: Vec<u32>,
    /// Order keys of the target points' projections, sorted.
    ykeys: Vec<u64>,
    /// Radix sort scratch.
    tmp_keys: Vec<u64>,
    tmp_idx: Vec<u32>,
}

impl Direction {
    pub(crate) fn new(n: usize) -> Self {
        Self {
            xp: vec![0.0; n],
            keys: vec![0; n],
            idx: vec![0; n],
            ykeys: vec![0; n],
            tmp_keys: vec![0; n],
            tmp_idx: vec![0; n],
        }
    }

    /// Projects both clouds on `theta`, matches them by rank and leaves in `xp` the 1D displacement
    /// of every moving point (target value at its rank − its own value). Sequential: the directions
    /// of an iteration run in parallel instead.
    pub(crate) fn displacements(&mut self, dim: usize, x: &[f64], y: &[f64], theta: &[f64]) {
        for (k, p) in self.ykeys.iter_mut().zip(y.chunks_exact(dim)) {
            *k = order_key(dot(p, theta));
        }
        radix_sort(
            &mut self.ykeys,
            &mut self.tmp_keys,
            &mut Vec::new(),
            &mut Vec::new(),
        );
        for (i, ((o, k), p)) in self
            .xp
            .iter_mut()
            .zip(self.keys.iter_mut())
            .zip(x.chunks_exact(dim))
            .enumerate()
        {
            *o = dot(p, theta);
            *k = order_key(*o);
            self.idx[i] = i as u32;
        }
        // Stable, and the input is in index order: ties stay in index order.
        radix_sort(
            &mut self.keys,
            &mut self.tmp_keys,
            &mut self.idx,
            &mut self.tmp_idx,
        );
        for (&i, &yk) in self.idx.iter().zip(&self.ykeys) {
            let i = i as usize;
            self.xp[i] = key_value(yk) - self.xp[i];
        }
    }
}

#[inline]
pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// An unsigned key with the order of `f64::total_cmp`.
#[inline]
pub(crate) fn order_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 {
        !b
    } else {
        b | (1 << 63)
    }
}

/// The inverse of [`order_key`].
#[inline]
pub(crate) fn key_value(k: u64) -> f64 {
    f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
}

/// Stable LSD radix sort of `keys` (8-bit digits, digits shared by all keys skipped), permuting
/// `vals` alike when it is not empty. `tmp_*` are scratch buffers of the same lengths. O(n) per
/// digit, and — unlike a comparison sort split across threads — trivially deterministic.
pub(crate) fn radix_sort(
    keys: &mut Vec<u64>,
    tmp_keys: &mut Vec<u64>,
    vals: &mut Vec<u32>,
    tmp_vals: &mut Vec<u32>,
) {
    let n = keys.len();
    let with_vals = !vals.is_empty();
    debug_assert!(!with_vals || vals.len() == n);
    let mut hist = [[0usize; 256]; 8];
    for &k in keys.iter() {
        for (b, h) in hist.iter_mut().enumerate() {
            h[((k >> (8 * b)) & 0xFF) as usize] += 1;
        }
    }
    for (b, h) in hist.iter().enumerate() {
        if h.contains(&n) {
            continue; // every key has the same digit here
        }
        let mut offsets = [0usize; 256];
        let mut sum = 0;
        for (o, &c) in offsets.iter_mut().zip(h) {
            *o = sum;
            sum += c;
        }
        let shift = 8 * b;
        if with_vals {
            for (&k, &v) in keys.iter().zip(vals.iter()) {
                let d = ((k >> shift) & 0xFF) as usize;
                tmp_keys[offsets[d]] = k;
                tmp_vals[offsets[d]] = v;
                offsets[d] += 1;
            }
            std::mem::swap(vals, tmp_vals);
        } else {
            for &k in keys.iter() {
                let d = ((k >> shift) & 0xFF) as usize;
                tmp_keys[offsets[d]] = k;
                offsets[d] += 1;
            }
        }
        std::mem::swap(keys, tmp_keys);
    }
}
