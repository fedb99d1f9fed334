//! How visible the join is where copies of a tile meet: the "seam" of `shared/data/README.md`.
//!
//! Seam = mean absolute difference across the wrap-around join (last column against the first, or
//! last row against the first) / mean absolute difference between neighbouring pixels inside the
//! image. A tile whose borders continue into each other like its interior does scores about 1; 3 or
//! more is a visible seam. The ratio is scale-free, so it compares a 1024² photograph with a
//! 128² render of a blend: what it measures is whether the join looks like the rest of the image.
//!
//! Differences are taken on display values (sRGB-encoded, clamped to [0, 1]) averaged over R, G, B:
//! what a viewer sees, and what the README's figures were measured on (8-bit files).
//!
//! Rendered images come in as plain linear RGBA (`width × height × 4` values, straight alpha, as
//! `otbake::render::imageio::Rgba` holds them), so this module needs nothing from the baker.

/// The seam across each join of a tile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seam {
    /// Across the left–right join (the image tiled horizontally).
    pub horizontal: f64,
    /// Across the top–bottom join (the image tiled vertically).
    pub vertical: f64,
}

impl Seam {
    /// The worse of the two joins.
    pub fn worst(&self) -> f64 {
        self.horizontal.max(self.vertical)
    }
}

/// The seam of `width × height` display values given per pixel as `value(x, y) -> [r, g, b]` in
/// [0, 1]. NaN for images narrower or lower than 2 pixels, or flat ones (no neighbour differences).
pub fn seam_of(width: usize, height: usize, value: impl Fn(usize, usize) -> [f64; 3]) -> Seam {
    let diff = |a: [f64; 3], b: [f64; 3]| (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f64>() / 3.0;
    let mean = |pairs: &mut dyn Iterator<Item = f64>| {
        let (mut s, mut n) = (0.0, 0usize);
        for v in pairs {
            s += v;
            n += 1;
        }
        s / n as f64
    };
    let ratio = |join: f64, inside: f64| join / inside;
    let inside_h = mean(&mut (0..height).flat_map(|y| {
        let value = &value;
        (0..width.saturating_sub(1)).map(move |x| diff(value(x, y), value(x + 1, y)))
    }));
    let join_h = mean(&mut (0..height).map(|y| diff(value(width - 1, y), value(0, y))));
    let inside_v = mean(&mut (0..height.saturating_sub(1)).flat_map(|y| {
        let value = &value;
        (0..width).map(move |x| diff(value(x, y), value(x, y + 1)))
    }));
    let join_v = mean(&mut (0..width).map(|x| diff(value(x, height - 1), value(x, 0))));
    Seam {
        horizontal: ratio(join_h, inside_h),
        vertical: ratio(join_v, inside_v),
    }
}

/// How far a single pair of adjacent columns (rows) inside the image strays from the mean, as the
/// seam measure would score it: the 95th percentile over the interior pairs of (mean difference
/// across that pair) / (mean difference over all interior pairs), per axis. The join of a seamless
/// tile is just one more such pair, so seams up to this value are within the image's own noise
/// (a render from a few hundred thousand points has plenty). NaN for images too small to have one.
pub fn interior_spread(
    width: usize,
    height: usize,
    value: impl Fn(usize, usize) -> [f64; 3],
) -> Seam {
    let diff = |a: [f64; 3], b: [f64; 3]| (0..3).map(|c| (a[c] - b[c]).abs()).sum::<f64>() / 3.0;
    let p95 = |mut v: Vec<f64>| {
        if v.is_empty() {
            return f64::NAN;
        }
        let mean = v.iter().sum::<f64>() / v.len() as f64;
        v.sort_by(f64::total_cmp);
        v[(v.len() * 95 / 100).min(v.len() - 1)] / mean
    };
    let columns: Vec<f64> = (0..width.saturating_sub(1))
        .map(|x| {
            (0..height)
                .map(|y| diff(value(x, y), value(x + 1, y)))
                .sum::<f64>()
                / height as f64
        })
        .collect();
    let rows: Vec<f64> = (0..height.saturating_sub(1))
        .map(|y| {
            (0..width)
                .map(|x| diff(value(x, y), value(x, y + 1)))
                .sum::<f64>()
                / width as f64
        })
        .collect();
    Seam {
        horizontal: p95(columns),
        vertical: p95(rows),
    }
}

/// The sRGB transfer function of a linear value clamped to [0, 1]: the encoding the baker's
/// image writer uses (`otbake::render::imageio::linear_to_srgb`; a test checks they agree).
fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The display value of pixel (x, y) of a linear RGBA image `width` pixels wide: sRGB-encoded,
/// clamped to [0, 1].
fn display(width: usize, rgba: &[f32]) -> impl Fn(usize, usize) -> [f64; 3] + '_ {
    move |x, y| {
        let i = (y * width + x) * 4;
        std::array::from_fn(|c| f64::from(linear_to_srgb(rgba[i + c].clamp(0.0, 1.0))))
    }
}

/// [`interior_spread`] of a rendered image (`width × height` linear RGBA values, straight alpha),
/// on its sRGB display values.
///
/// # Panics
/// If `rgba` holds fewer than `width * height * 4` values.
pub fn spread(width: usize, height: usize, rgba: &[f32]) -> Seam {
    assert!(
        rgba.len() >= width * height * 4,
        "{width}x{height} RGBA needs {} values",
        width * height * 4
    );
    interior_spread(width, height, display(width, rgba))
}

/// The seam of a rendered image (`width × height` linear RGBA values, straight alpha), on its
/// sRGB display values.
///
/// # Panics
/// If `rgba` holds fewer than `width * height * 4` values.
pub fn seam(width: usize, height: usize, rgba: &[f32]) -> Seam {
    assert!(
        rgba.len() >= width * height * 4,
        "{width}x{height} RGBA needs {} values",
        width * height * 4
    );
    seam_of(width, height, display(width, rgba))
}

/// The seam of an image file as stored (8-bit sRGB values), e.g. a texture input.
pub fn seam_of_file(path: &std::path::Path) -> Result<Seam, image::ImageError> {
    let img = image::open(path)?.to_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    Ok(seam_of(w, h, |x, y| {
        let p = img.get_pixel(x as u32, y as u32).0;
        p.map(|v| f64::from(v) / 255.0)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The measure reproduces the figures `shared/data/README.md` states for the texture files.
    #[test]
    fn reproduces_the_data_readme_figures() {
        let dir = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/textures");
        for (file, h, v) in [
            ("marble_onyx003_ambientcg_1k.jpg", 1.12, 1.08),
            ("marble_veined_rock058_ambientcg_1k.jpg", 1.25, 1.41),
            ("marble_texturecan106_gray.png", 0.91, 3.02),
            ("marble_slate_texturecan240_gray.png", 1.12, 1.07),
            ("pebbles_stonewall_godot.png", 0.83, 0.99),
        ] {
            let s = seam_of_file(&dir.join(file)).unwrap();
            assert!(
                (s.horizontal - h).abs() < 0.006 && (s.vertical - v).abs() < 0.006,
                "{file}: {s:?}, README says {h} / {v}"
            );
        }
    }

    /// The display encoding is the baker's own.
    #[test]
    fn srgb_encoding_matches_the_bakers() {
        for i in 0..=1100 {
            let v = i as f32 / 1000.0 - 0.05;
            assert_eq!(
                linear_to_srgb(v).to_bits(),
                otbake::render::imageio::linear_to_srgb(v).to_bits(),
                "{v}"
            );
        }
    }

    #[test]
    fn a_periodic_pattern_has_no_seam_and_a_ramp_has_one() {
        let n = 64;
        let wave = |x: usize, y: usize| {
            let t =
                (std::f64::consts::TAU * (x as f64 / n as f64 + 2.0 * y as f64 / n as f64)).sin();
            [0.5 + 0.4 * t; 3]
        };
        let s = seam_of(n, n, wave);
        assert!(
            (s.horizontal - 1.0).abs() < 0.01 && (s.vertical - 1.0).abs() < 0.01,
            "{s:?}"
        );
        let ramp = |x: usize, _y: usize| [x as f64 / n as f64; 3];
        let s = seam_of(n, n, ramp);
        assert!((s.horizontal - (n - 1) as f64).abs() < 1e-9, "{s:?}");
        assert!(s.vertical.is_nan(), "flat columns: {s:?}");
        // Every interior pair of a ramp differs alike: the spread is 1.
        let sp = interior_spread(n, n, ramp);
        assert!((sp.horizontal - 1.0).abs() < 1e-9, "{sp:?}");
        // The same ramp as a linear RGBA image: one value per display level.
        let rgba: Vec<f32> = (0..n * n)
            .flat_map(|i| {
                let v = (i % n) as f32 / n as f32;
                [v, v, v, 1.0]
            })
            .collect();
        let s = seam(n, n, &rgba);
        assert!(s.horizontal > 10.0 && s.vertical.is_nan(), "{s:?}");
        assert!((spread(n, n, &rgba).vertical).is_nan());
    }
}
