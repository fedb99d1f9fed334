//! What a map archive stores, and at which precision: the storage descriptor and its quantization.
//!
//! A map stores five attributes. Which ones are present and how precisely is recorded in
//! [`crate::map::Map::storage`], five code bytes a reader checks before touching any bulk data:
//!
//! | byte | attribute | codes |
//! |---|---|---|
//! | 0 | `positions` (mapped points) | 0 `f32`, 1 `u16`, 2 `u8` |
//! | 1 | `node_boxes` (boxes of the internal tree nodes) | 0 `f32`, 1 `u16` |
//! | 2 | `colors` (per-point color ratios) | 0 none, 1 `f32`, 2 `u16`, 3 `u8` |
//! | 3 | `node_colors` (per-node color sums) | 0 absent, 1 present (`f32`; only with colors) |
//! | 4 | `spacings` (per-point spacings and their node maxima, [`crate::spacing`]) | 0 absent, 1 present (`u8` codes) |
//!
//! Multi-byte values are little endian. Only internal nodes (levels `0..depth`) have stored boxes
//! and color sums; a leaf's box and color sum are derived from its points by the reader, so a
//! full-precision leaf box is exactly what would have been stored, and quantized maps need no leaf
//! arrays at all.
//!
//! # Encodings
//!
//! Every quantized value is a code `q` in `0..=M` (`M` = 255 for `u8`, 65535 for `u16`) on a grid
//! over an interval `[lo, hi]`, decoded by [`dequantize`]:
//!
//! ```text
//! step = (hi − lo) · (1/M)            (f32; 1/M is the f32 constant INV_U8 or INV_U16)
//! x̂   = hi                            if q = M
//!       min(lo + q · step, hi)        otherwise
//! ```
//!
//! The decode is monotone in `q` and always lies in `[lo, hi]`. The grids:
//!
//! * **node boxes (`u16`)**: per axis, the grid over the map's `bounds` (the box of all its points,
//!   stored in `f32`). Each internal node's box is rounded *outward* ([`quantize_down`] for `lo`,
//!   [`quantize_up`] for `hi`), so a decoded box contains the node's points, and, because the grid
//!   is shared and the decode monotone, every decoded box contains its children's decoded boxes.
//!   Pruning therefore stays exact; boxes are only up to one grid step (`extent / 65535`) looser.
//! * **positions (`u16`/`u8`)**: per axis, the grid over the *decoded* box of the point's leaf's
//!   parent (or `bounds` when the tree is a single leaf), rounded to the nearest grid value
//!   ([`quantize_nearest`]). A decoded point lies inside that decoded box, so every stored box
//!   contains the decoded points below it. A leaf's parent holds at most `2 · leaf_size` points, so
//!   the grid adapts to the local density of the map.
//! * **colors (`u16`/`u8`)**: per channel, the grid over the map's `color_range` (per-channel min
//!   and max of the color ratios, stored in `f32`), rounded to nearest. Node color sums are `f32`
//!   sums (accumulated in `f64`) of the *decoded* colors, so whole-node and per-point sums agree.
//!
//! # Error bounds
//!
//! A value quantized to nearest on a grid `[lo, hi]` with step `s` decodes within
//! [`error_bound`]`(lo, hi, s) = s/2 + 2⁻²² · max(|lo|, |hi|) + 2⁻¹³³` of the original: half a
//! step, plus the f32 rounding of the decode. So:
//!
//! * a decoded position differs from the full-precision one by at most `step/2 + 2⁻²²·max(|A|,|B|)`
//!   per axis, where `[A, B]` is the decoded box of its leaf's parent and `step = (B − A)/M`: about
//!   `(extent of ~2·leaf_size points) / 510` for `u8`, `/ 131070` for `u16`;
//! * a decoded color ratio by at most `(hi_c − lo_c)/(2M)` (+ rounding) per channel;
//! * a blend of maps moves each blended point by at most `Σ w_k e_k`, and every query answer is the
//!   answer for points and colors moved within those bounds (tests check point, range, sample and
//!   splat results against the intervals this implies).

/// `1/255` as the f32 every reader and writer multiplies by.
pub const INV_U8: f32 = 1.0 / 255.0;
/// `1/65535` as the f32 every reader and writer multiplies by.
pub const INV_U16: f32 = 1.0 / 65535.0;

/// Relative slack of [`error_bound`] for the f32 rounding of a decode (`2⁻²²`).
pub const ROUNDING_SLACK: f32 = 1.0 / 4_194_304.0;

/// Absolute slack of [`error_bound`], `2⁻¹³³` (≈ 9.2e-41): a subnormal step is rounded by up to
/// `2⁻¹⁵⁰`, which 65535 codes multiply. Irrelevant for any real data, but it keeps the bound true.
pub const TINY_SLACK: f32 = f32::from_bits(1 << 16);

/// How precisely an attribute is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// 32-bit float: the full precision, stored as is.
    F32,
    /// 16-bit code on a grid (65536 values).
    U16,
    /// 8-bit code on a grid (256 values).
    U8,
}

impl Precision {
    /// Bytes per stored value.
    pub const fn bytes(self) -> usize {
        match self {
            Self::F32 => 4,
            Self::U16 => 2,
            Self::U8 => 1,
        }
    }

    /// Largest code `M` of a quantized precision (0 for `f32`).
    pub const fn max_code(self) -> u32 {
        match self {
            Self::F32 => 0,
            Self::U16 => 65535,
            Self::U8 => 255,
        }
    }

    /// `1/M` as an f32 (0 for `f32`).
    pub const fn inv_max(self) -> f32 {
        match self {
            Self::F32 => 0.0,
            Self::U16 => INV_U16,
            Self::U8 => INV_U8,
        }
    }

    /// Whether values are codes on a grid.
    pub const fn is_quantized(self) -> bool {
        !matches!(self, Self::F32)
    }

    /// Manifest spelling: `f32`, `u16`, `u8`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::U16 => "u16",
            Self::U8 => "u8",
        }
    }

    const fn code(self) -> u8 {
        match self {
            Self::F32 => 0,
            Self::U16 => 1,
            Self::U8 => 2,
        }
    }

    const fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(Self::F32),
            1 => Some(Self::U16),
            2 => Some(Self::U8),
            _ => None,
        }
    }
}

/// What a map stores and how: the typed form of [`crate::map::Map::storage`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Storage {
    /// Mapped positions (always stored).
    pub positions: Precision,
    /// Boxes of internal nodes (always stored): `F32` or `U16`.
    pub node_boxes: Precision,
    /// Per-point color ratios, or `None` for a density-only map.
    pub colors: Option<Precision>,
    /// Per-node color sums (what range queries of color take whole nodes from). Only with colors.
    pub node_colors: bool,
    /// Per-point spacings and their per-node maxima ([`crate::spacing`]; density-adaptive point
    /// queries need them): about 1.1 bytes per point.
    pub spacings: bool,
}

impl Storage {
    /// Everything in `f32`: the reference the quantized forms are measured against.
    pub const FULL: Self = Self {
        positions: Precision::F32,
        node_boxes: Precision::F32,
        colors: Some(Precision::F32),
        node_colors: true,
        spacings: true,
    };

    /// The small form: `u8` positions on their leaf parents' boxes, `u16` node boxes, `u8` colors,
    /// node color sums kept, no spacings (about 7.6 bytes per point in 2D with color, 4.6 in 3D
    /// without; spacings would add 1.1).
    pub const COMPACT: Self = Self {
        positions: Precision::U8,
        node_boxes: Precision::U16,
        colors: Some(Precision::U8),
        node_colors: true,
        spacings: false,
    };

    /// The five descriptor bytes.
    pub const fn to_codes(&self) -> [u8; 5] {
        [
            self.positions.code(),
            self.node_boxes.code(),
            match self.colors {
                None => 0,
                Some(p) => 1 + p.code(),
            },
            self.node_colors as u8,
            self.spacings as u8,
        ]
    }

    /// Decodes descriptor bytes; `None` for unknown codes, `u8` node boxes, or node color sums
    /// without colors.
    pub const fn from_codes(codes: [u8; 5]) -> Option<Self> {
        let Some(positions) = Precision::from_code(codes[0]) else {
            return None;
        };
        let node_boxes = match codes[1] {
            0 => Precision::F32,
            1 => Precision::U16,
            _ => return None,
        };
        let colors = match codes[2] {
            0 => None,
            c => match Precision::from_code(c - 1) {
                Some(p) => Some(p),
                None => return None,
            },
        };
        let node_colors = match codes[3] {
            0 => false,
            1 if colors.is_some() => true,
            _ => return None,
        };
        let spacings = match codes[4] {
            0 => false,
            1 => true,
            _ => return None,
        };
        Some(Self {
            positions,
            node_boxes,
            colors,
            node_colors,
            spacings,
        })
    }

    /// This storage for a map whose input has (`true`) or lacks color: without color nothing of
    /// color is stored.
    pub const fn for_input(self, has_color: bool) -> Self {
        if has_color {
            Self {
                node_colors: self.node_colors && self.colors.is_some(),
                ..self
            }
        } else {
            Self {
                colors: None,
                node_colors: false,
                ..self
            }
        }
    }
}

/// Grid step of `[lo, hi]` for codes up to `precision.max_code()`: `(hi − lo) · (1/M)`.
#[inline]
pub fn step(lo: f32, hi: f32, precision: Precision) -> f32 {
    (hi - lo) * precision.inv_max()
}

/// Decodes code `q` on the grid `[lo, hi]` of `step` with largest code `max` (see the module docs):
/// monotone in `q`, `lo` at 0, `hi` at `max`, never outside `[lo, hi]` when `lo <= hi`.
///
/// Written as compares and selects, without casts of unsigned values, so that loops of decodes
/// vectorize lane for lane (SSE2 has no unsigned conversion, and `f32::min` costs a NaN fix-up):
/// `v < hi ? v : hi` is `min(v, hi)` for every `v` (a NaN `v`, which finite grids never give,
/// yields `hi` as `f32::min` does), and `q as i32` is `q` for every code below `max <= 65535`.
#[inline(always)]
pub fn dequantize(lo: f32, hi: f32, step: f32, q: u32, max: u32) -> f32 {
    let v = lo + (q as i32) as f32 * step;
    let v = if v < hi { v } else { hi };
    if q >= max {
        hi
    } else {
        v
    }
}

/// Largest code whose decode is `<= x` (0 if none is).
pub fn quantize_down(x: f32, lo: f32, hi: f32, step: f32, max: u32) -> u32 {
    // Binary search on the monotone decode: at most 17 probes.
    let (mut a, mut b) = (0u32, max);
    if dequantize(lo, hi, step, 0, max) > x {
        return 0;
    }
    while a < b {
        let mid = a + (b - a).div_ceil(2);
        if dequantize(lo, hi, step, mid, max) <= x {
            a = mid;
        } else {
            b = mid - 1;
        }
    }
    a
}

/// Smallest code whose decode is `>= x` (`max` if none is).
pub fn quantize_up(x: f32, lo: f32, hi: f32, step: f32, max: u32) -> u32 {
    let (mut a, mut b) = (0u32, max);
    while a < b {
        let mid = a + (b - a) / 2;
        if dequantize(lo, hi, step, mid, max) >= x {
            b = mid;
        } else {
            a = mid + 1;
        }
    }
    a
}

/// The code whose decode is nearest to `x` (the lower one on a tie).
pub fn quantize_nearest(x: f32, lo: f32, hi: f32, step: f32, max: u32) -> u32 {
    let q = quantize_down(x, lo, hi, step, max);
    if q < max {
        let below = (x - dequantize(lo, hi, step, q, max)).abs();
        let above = (dequantize(lo, hi, step, q + 1, max) - x).abs();
        if above < below {
            return q + 1;
        }
    }
    q
}

/// The largest difference between a value in `[lo, hi]` and its nearest decode on the grid of
/// `step`: `step/2 + 2⁻²²·max(|lo|, |hi|) + 2⁻¹³³`: half a grid step plus the f32 rounding of the
/// decode (and of a subnormal step).
#[inline]
pub fn error_bound(lo: f32, hi: f32, step: f32) -> f32 {
    0.5 * step.abs() + ROUNDING_SLACK * lo.abs().max(hi.abs()) + TINY_SLACK
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_bad_codes_are_refused() {
        let all = [Precision::F32, Precision::U16, Precision::U8];
        for p in all {
            for b in [Precision::F32, Precision::U16] {
                for c in [
                    None,
                    Some(Precision::F32),
                    Some(Precision::U16),
                    Some(Precision::U8),
                ] {
                    for (nc, sp) in [(false, false), (false, true), (true, false), (true, true)] {
                        let s = Storage {
                            positions: p,
                            node_boxes: b,
                            colors: c,
                            node_colors: nc,
                            spacings: sp,
                        };
                        let back = Storage::from_codes(s.to_codes());
                        if nc && c.is_none() {
                            assert_eq!(back, None);
                        } else {
                            assert_eq!(back, Some(s));
                        }
                    }
                }
            }
        }
        assert_eq!(Storage::from_codes([3, 0, 0, 0, 0]), None);
        assert_eq!(Storage::from_codes([0, 2, 0, 0, 0]), None);
        assert_eq!(Storage::from_codes([0, 0, 4, 0, 0]), None);
        assert_eq!(Storage::from_codes([0, 0, 1, 2, 0]), None);
        assert_eq!(Storage::from_codes([0, 0, 1, 1, 2]), None);
        assert_eq!(Storage::COMPACT.for_input(false).colors, None);
        assert!(!Storage::COMPACT.for_input(false).node_colors);
    }

    /// Decoding is monotone, hits both ends, and the outward/nearest searches do what they say.
    #[test]
    fn grids_are_monotone_and_searches_are_exact() {
        let cases = [
            (0.0f32, 1.0f32),
            (-0.3, 0.7),
            (0.123_456, 0.123_457),
            (5.0, 5.0),
            (1e-40, 3e-40),
            (-1e30, 1e30),
        ];
        for (lo, hi) in cases {
            for p in [Precision::U8, Precision::U16] {
                let s = step(lo, hi, p);
                let m = p.max_code();
                assert_eq!(dequantize(lo, hi, s, 0, m), lo);
                assert_eq!(dequantize(lo, hi, s, m, m), hi);
                let mut prev = lo;
                for q in 0..=m {
                    let v = dequantize(lo, hi, s, q, m);
                    assert!(v >= prev && v <= hi, "{lo} {hi} {q}");
                    prev = v;
                }
                for t in 0..=200 {
                    let x = lo + (hi - lo) * (t as f32 / 200.0);
                    let x = x.clamp(lo, hi);
                    let d = quantize_down(x, lo, hi, s, m);
                    assert!(dequantize(lo, hi, s, d, m) <= x);
                    assert!(d == m || dequantize(lo, hi, s, d + 1, m) > x);
                    let u = quantize_up(x, lo, hi, s, m);
                    assert!(dequantize(lo, hi, s, u, m) >= x);
                    assert!(u == 0 || dequantize(lo, hi, s, u - 1, m) < x);
                    let q = quantize_nearest(x, lo, hi, s, m);
                    let err = (dequantize(lo, hi, s, q, m) - x).abs();
                    assert!(err <= error_bound(lo, hi, s), "{lo} {hi} {x} {err}");
                }
            }
        }
    }
}
