//! `otbake texture`: blended textures whose weights vary per pixel (paper §6.2, Figs. 9 and 10).
//!
//! Every pixel is one runtime point query with that pixel's own weights — exactly what a renderer's
//! texture lookup does — so a weight field costs nothing to bake: it is only evaluated at run time.

use crate::render::imageio::Rgba;
use crate::render::{composite, shade, RenderError};
use otbake_runtime::{Blend, Kernel, Map, Proxy};
use rayon::prelude::*;

/// A weight for every pixel.
#[derive(Debug, Clone, PartialEq)]
pub enum WeightField {
    /// The same weights everywhere.
    Constant(Vec<f32>),
    /// Smooth Perlin-noise weights (`scale` noise cells across the image, `seed`); 2 inputs: one
    /// field; k inputs: k fields turned into weights by a sharpened normalization.
    Perlin {
        /// Noise cells across the image width.
        scale: f32,
        /// Noise seed.
        seed: u64,
    },
    /// A strip through the inputs in order along x whose transitions zig-zag along y (Fig. 9).
    Zigzag,
}

impl WeightField {
    /// Parses `perlin:SCALE,SEED`, `zigzag` or `a,b,...`.
    pub fn parse(s: &str) -> Result<Self, String> {
        if let Some(rest) = s.strip_prefix("perlin:") {
            let (scale, seed) = rest
                .split_once(',')
                .ok_or("perlin weights are perlin:SCALE,SEED, e.g. perlin:4,7")?;
            let scale: f32 = scale
                .trim()
                .parse()
                .map_err(|_| format!("perlin scale {scale:?} is not a number"))?;
            if !(scale.is_finite() && scale > 0.0) {
                return Err(format!("perlin scale {scale} must be positive"));
            }
            let seed: u64 = seed
                .trim()
                .parse()
                .map_err(|_| format!("perlin seed {seed:?} is not an integer"))?;
            return Ok(Self::Perlin { scale, seed });
        }
        if s == "zigzag" {
            return Ok(Self::Zigzag);
        }
        let w: Result<Vec<f32>, _> = s.split(',').map(|v| v.trim().parse::<f32>()).collect();
        w.map(Self::Constant).map_err(|_| {
            format!("weights {s:?}: use perlin:SCALE,SEED, zigzag, or comma-separated numbers")
        })
    }

    /// The weights of `k` inputs at image position (`u`, `v`) in `[0,1]²` (written into `out`).
    pub fn weights(&self, k: usize, u: f32, v: f32, out: &mut [f32]) {
        match self {
            Self::Constant(w) => out.copy_from_slice(&w[..k]),
            Self::Perlin { scale, seed } => {
                if k == 1 {
                    out[0] = 1.0;
                } else if k == 2 {
                    // Noise in about [-0.7, 0.7] → a soft but decisive transition.
                    let t = (0.5 + 1.2 * perlin(u * scale, v * scale, *seed)).clamp(0.0, 1.0);
                    let t = t * t * (3.0 - 2.0 * t);
                    out[0] = 1.0 - t;
                    out[1] = t;
                } else {
                    let mut sum = 0.0;
                    for (i, o) in out.iter_mut().enumerate() {
                        let n = perlin(u * scale, v * scale, seed.wrapping_add(i as u64 * 0x9E37));
                        *o = (n + 0.8).max(0.0).powi(4);
                        sum += *o;
                    }
                    for o in out.iter_mut() {
                        *o = if sum > 0.0 { *o / sum } else { 1.0 / k as f32 };
                    }
                }
            }
            Self::Zigzag => {
                // Position along the strip, displaced by a triangle wave in v (8 teeth).
                let tooth = (v * 8.0).fract();
                let tri = 1.0 - (2.0 * tooth - 1.0).abs();
                let s = (u * (k - 1) as f32 + 0.35 * (tri - 0.5)).clamp(0.0, (k - 1) as f32);
                let i = (s.floor() as usize).min(k.saturating_sub(2));
                let f = s - i as f32;
                out.fill(0.0);
                if k == 1 {
                    out[0] = 1.0;
                } else {
                    // A sharpened ramp keeps each input pure over most of its band.
                    let f = ((f - 0.5) * 3.0 + 0.5).clamp(0.0, 1.0);
                    out[i] = 1.0 - f;
                    out[i + 1] = f;
                }
            }
        }
    }
}

/// A runtime error in `context` as a render error.
fn runtime(context: &'static str) -> impl Fn(otbake_runtime::Error) -> RenderError {
    move |source| RenderError::Runtime {
        context: context.into(),
        source,
    }
}

/// The blend of `maps`, which must be 2D (textures).
fn image_blend<'a, 'm>(
    proxy: Proxy<'a>,
    maps: &'m [Map<'a>],
) -> Result<Blend<'a, 'm>, RenderError> {
    let blend = Blend::new(proxy, maps).map_err(runtime("maps"))?;
    if blend.dim() != 2 {
        return Err(RenderError::NotAnImage(blend.dim()));
    }
    Ok(blend)
}

/// 2D gradient noise (Perlin 1985/2002), periodic with period 256 cells; values in about [-0.7, 0.7].
pub fn perlin(x: f32, y: f32, seed: u64) -> f32 {
    let hash = |ix: i64, iy: i64| -> u64 {
        let mut h = seed
            ^ (ix as u64 & 255).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (iy as u64 & 255).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
        h ^= h >> 33;
        h = h.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
        h ^ (h >> 33)
    };
    let grad = |ix: i64, iy: i64, dx: f32, dy: f32| -> f32 {
        const G: [(f32, f32); 8] = [
            (1.0, 0.0),
            (-1.0, 0.0),
            (0.0, 1.0),
            (0.0, -1.0),
            (0.707, 0.707),
            (-0.707, 0.707),
            (0.707, -0.707),
            (-0.707, -0.707),
        ];
        let g = G[(hash(ix, iy) & 7) as usize];
        g.0 * dx + g.1 * dy
    };
    let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i64, y0 as i64);
    let (u, v) = (fade(fx), fade(fy));
    let a = grad(ix, iy, fx, fy) + u * (grad(ix + 1, iy, fx - 1.0, fy) - grad(ix, iy, fx, fy));
    let b = grad(ix, iy + 1, fx, fy - 1.0)
        + u * (grad(ix + 1, iy + 1, fx - 1.0, fy - 1.0) - grad(ix, iy + 1, fx, fy - 1.0));
    a + v * (b - a)
}

/// Renders a texture of `width × height` whose pixel (x, y) is the point query of the blend with the
/// field's weights at the pixel center. The texture repeats in square tiles of `min(width, height)`
/// pixels (texture coordinates wrap), while the weight field spans the whole image: a wide image is a
/// strip of tiles whose blend changes along it. The tiles join without seams when the blend is
/// periodic (`wrap = "periodic"`: its queries see across the tile's edges); a clamped blend's tiles
/// show their edges.
pub fn render_texture<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    field: &WeightField,
    width: usize,
    height: usize,
    sigma_px: f32,
) -> Result<Rgba, RenderError> {
    let blend = image_blend(proxy, maps)?;
    let k = maps.len();
    let rule = composite(maps);
    if let WeightField::Constant(w) = field {
        blend.check_weights(w).map_err(runtime("--weights"))?;
    }
    let tile = width.min(height) as f32;
    let kernel = Kernel {
        sigma: sigma_px / tile,
    };
    let mut img = Rgba::filled(width, height, [0.0; 4]);
    img.pixels
        .par_chunks_mut(width * 4)
        .enumerate()
        .try_for_each(|(y, row)| -> Result<(), otbake_runtime::Error> {
            let mut w = vec![0.0f32; k];
            for x in 0..width {
                let (u, v) = (
                    (x as f32 + 0.5) / width as f32,
                    (y as f32 + 0.5) / height as f32,
                );
                field.weights(k, u, v, &mut w);
                let p = [
                    ((x as f32 + 0.5) / tile).fract(),
                    ((y as f32 + 0.5) / tile).fract(),
                ];
                let v = blend.point(&w, &p, kernel)?;
                row[x * 4..x * 4 + 4].copy_from_slice(&shade(rule, v.mass, v.color));
            }
            Ok(())
        })
        .map_err(runtime("point query"))?;
    Ok(img)
}

/// Renders a minified texture by range queries (level of detail, paper §6.2 and Fig. 12): the image
/// shows `repeats × repeats` tiles of the texture, so every pixel covers a footprint of
/// `repeats / min(width, height)` of the texture per axis, and its value is the exact average of the
/// blend over that footprint — one range query (whole nodes taken from stored sums), not a sum over
/// the footprint's texels. Footprints that cross a tile edge are split and wrapped.
pub fn render_lod<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    field: &WeightField,
    width: usize,
    height: usize,
    repeats: f32,
) -> Result<Rgba, RenderError> {
    let blend = image_blend(proxy, maps)?;
    let k = maps.len();
    let rule = composite(maps);
    let per_px = repeats / width.min(height) as f32;
    let periodic = blend.wrap() == otbake_runtime::Wrap::Periodic;
    let mut img = Rgba::filled(width, height, [0.0; 4]);
    img.pixels
        .par_chunks_mut(width * 4)
        .enumerate()
        .try_for_each(|(y, row)| -> Result<(), otbake_runtime::Error> {
            let mut w = vec![0.0f32; k];
            for x in 0..width {
                field.weights(
                    k,
                    (x as f32 + 0.5) / width as f32,
                    (y as f32 + 0.5) / height as f32,
                    &mut w,
                );
                let (mut mass, mut color) = (0.0f32, [0.0f32; 3]);
                let lo = [(x as f32 * per_px).fract(), (y as f32 * per_px).fract()];
                // A periodic blend takes footprints across the tile's edges whole; a clamped one
                // gets them split into pieces inside the tile.
                let pieces = |lo: f32, len: f32| match periodic {
                    true => [Some((lo, lo + len)), None],
                    false => wrapped(lo, len),
                };
                for (ax, ay) in pieces(lo[0], per_px.min(1.0))
                    .into_iter()
                    .flatten()
                    .flat_map(|a| {
                        pieces(lo[1], per_px.min(1.0))
                            .into_iter()
                            .flatten()
                            .map(move |b| (a, b))
                    })
                {
                    let r = blend.range(&w, &[ax.0, ay.0], &[ax.1, ay.1])?;
                    mass += r.mass;
                    for (acc, c) in color.iter_mut().zip(r.color) {
                        *acc += c;
                    }
                }
                let area = per_px.min(1.0) * per_px.min(1.0);
                let px = shade(rule, mass / area, color.map(|c| c / area));
                row[x * 4..x * 4 + 4].copy_from_slice(&px);
            }
            Ok(())
        })
        .map_err(runtime("range query"))?;
    Ok(img)
}

/// The interval [`lo`, `lo + len`] on the unit circle as at most two intervals in [0, 1].
fn wrapped(lo: f32, len: f32) -> [Option<(f32, f32)>; 2] {
    let hi = lo + len;
    if hi <= 1.0 {
        [Some((lo, hi)), None]
    } else {
        [Some((lo, 1.0)), Some((0.0, hi - 1.0))]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_give_valid_weights_everywhere() {
        for field in [
            WeightField::Perlin {
                scale: 4.0,
                seed: 3,
            },
            WeightField::Zigzag,
        ] {
            for k in 1..=4 {
                let mut w = vec![0.0; k];
                for i in 0..400 {
                    let (u, v) = ((i % 20) as f32 / 19.0, (i / 20) as f32 / 19.0);
                    field.weights(k, u, v, &mut w);
                    assert!(
                        w.iter().all(|x| *x >= 0.0 && x.is_finite()),
                        "{field:?} k={k}: {w:?}"
                    );
                    assert!(
                        (w.iter().sum::<f32>() - 1.0).abs() < 1e-5,
                        "{field:?} k={k}: {w:?}"
                    );
                }
            }
        }
        // Perlin weights really vary over the image; zigzag starts at input 0 and ends at the last.
        let mut w = [0.0; 2];
        let mut seen = (f32::MAX, f32::MIN);
        for i in 0..400 {
            WeightField::Perlin {
                scale: 4.0,
                seed: 3,
            }
            .weights(2, (i % 20) as f32 / 19.0, (i / 20) as f32 / 19.0, &mut w);
            seen = (seen.0.min(w[0]), seen.1.max(w[0]));
        }
        assert!(seen.0 < 0.1 && seen.1 > 0.9, "perlin weights span {seen:?}");
        let mut w4 = [0.0; 4];
        WeightField::Zigzag.weights(4, 0.0, 0.5, &mut w4);
        assert_eq!(w4[0], 1.0);
        WeightField::Zigzag.weights(4, 1.0, 0.5, &mut w4);
        assert_eq!(w4[3], 1.0);
    }

    #[test]
    fn parsing() {
        assert_eq!(
            WeightField::parse("perlin:4,7").unwrap(),
            WeightField::Perlin {
                scale: 4.0,
                seed: 7
            }
        );
        assert_eq!(WeightField::parse("zigzag").unwrap(), WeightField::Zigzag);
        assert_eq!(
            WeightField::parse("0.5, 0.5").unwrap(),
            WeightField::Constant(vec![0.5, 0.5])
        );
        assert!(WeightField::parse("perlin:x,1").is_err());
        assert!(WeightField::parse("perlin:-1,1").is_err());
        assert!(WeightField::parse("a,b").is_err());
    }
}
