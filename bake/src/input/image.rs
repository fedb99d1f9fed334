//! Image files (PNG, JPEG, OpenEXR) decoded to linear RGB + alpha and turned into a [`Grid`].
//!
//! PNG and JPEG are taken as sRGB-encoded (ICC profiles and gAMA chunks are ignored) and decoded with
//! the exact piecewise sRGB EOTF; their alpha is linear. OpenEXR is linear already; by the OpenEXR
//! convention its color is premultiplied by alpha, so it is divided by alpha (where alpha > 0) to get
//! the straight color that the density formulas of [`super::DensityChannel`] expect. The image crate
//! decodes palette and low-bit-depth PNGs to 8-bit RGB(A) or grey.

use crate::limits::{product, Budget};
use std::path::{Path, PathBuf};

use super::{DensityChannel, Grid, InputError};

/// The sRGB electro-optical transfer function: sRGB-encoded value in `[0,1]` to linear.
pub fn srgb_to_linear(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Load an image file as a density grid: axis 0 = x (left to right), axis 1 = y (top to bottom).
/// Supported: `.png`, `.jpg`, `.jpeg` (8/16-bit grey, grey+alpha, RGB, RGBA, palette) and `.exr`
/// (first layer with R, G, B and optional A channels).
pub fn load_image(path: &Path, channel: DensityChannel) -> Result<Grid, InputError> {
    load_image_within(path, channel, &Budget::for_process())
}

/// Bytes per pixel beyond the decoded file's own: the 8- or 16-bit RGBA copy (at most 8), the
/// linear `[f32; 4]` pixels (16), and the grid's mass and colour ratio (4 + 12), which exist
/// together at the peak of [`load_image`].
const BYTES_PER_PIXEL: u64 = 8 + 16 + 16;

/// Checks a `width × height` image whose decoder allocates `decoded` bytes against `budget`.
fn check_pixels(
    path: &Path,
    width: u64,
    height: u64,
    decoded: u64,
    budget: &Budget,
) -> Result<(), InputError> {
    let needed = product(&[width, height, BYTES_PER_PIXEL]).saturating_add(decoded);
    budget.check(
        needed,
        || format!("image {}: {width}×{height} pixels", path.display()),
        "use a smaller image (downscale it)",
    )?;
    Ok(())
}

/// [`load_image`], refusing before decoding an image whose header announces more pixels than
/// `budget` holds (the image crate's own limits are set to the budget too).
pub fn load_image_within(
    path: &Path,
    channel: DensityChannel,
    budget: &Budget,
) -> Result<Grid, InputError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let format = match ext.as_str() {
        "png" => Some(image::ImageFormat::Png),
        "jpg" | "jpeg" => Some(image::ImageFormat::Jpeg),
        "exr" => None,
        _ => {
            return Err(InputError::UnsupportedExtension {
                path: path.to_path_buf(),
                ext,
            })
        }
    };
    match std::fs::metadata(path) {
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(InputError::NotFound {
                path: path.to_path_buf(),
            })
        }
        Err(source) => {
            return Err(InputError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    }
    let pixels = match format {
        Some(format) => decode_srgb(path, format, budget)?,
        None => decode_exr(path, budget)?,
    };
    pixels.into_grid(path, channel)
}

/// Linear straight (non-premultiplied) RGBA pixels, row-major from the top-left corner.
struct LinearPixels {
    width: usize,
    height: usize,
    rgba: Vec<[f32; 4]>,
}

impl LinearPixels {
    fn into_grid(self, path: &Path, channel: DensityChannel) -> Result<Grid, InputError> {
        let mut mass = Vec::with_capacity(self.rgba.len());
        let mut ratio = Vec::with_capacity(self.rgba.len());
        for px in &self.rgba {
            let (m, r) = density(channel, px);
            mass.push(m);
            ratio.push(r);
        }
        if mass.iter().all(|&m| m == 0.0) {
            return Err(InputError::NoMass {
                path: path.to_path_buf(),
                channel,
            });
        }
        Grid::new(vec![self.width, self.height], mass, ratio).map_err(|e| {
            InputError::InvalidDensity {
                path: path.to_path_buf(),
                message: e.to_string(),
            }
        })
    }
}

/// Mass and color-to-mass ratio of one linear straight RGBA pixel (table in `input`'s docs).
fn density(channel: DensityChannel, px: &[f32; 4]) -> (f32, [f32; 3]) {
    let [r, g, b, a] = px.map(f64::from);
    let y = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    let to_f32 = |v: f64| v.min(f64::from(f32::MAX)) as f32;
    match channel {
        DensityChannel::Luminance => {
            let ratio = if y > 0.0 {
                [r / y, g / y, b / y].map(to_f32)
            } else {
                [0.0; 3]
            };
            ((y * a) as f32, ratio)
        }
        DensityChannel::Inverted => (((1.0 - y).max(0.0) * a) as f32, [r, g, b].map(to_f32)),
        DensityChannel::Alpha => (a as f32, [r, g, b].map(to_f32)),
    }
}

/// Checks what the PNG decoder trusts without checking: a `PLTE` chunk must hold whole RGB
/// entries, at most 256 (the png crate indexes past a palette of 3k + 1 or 3k + 2 bytes and
/// panics). Reads only the chunk headers; a file that is not a PNG is left to the decoder.
fn check_png_chunks(path: &Path) -> Result<(), InputError> {
    use std::io::{Read, Seek, SeekFrom};
    let io = |source| InputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let mut magic = [0u8; 8];
    if file.read_exact(&mut magic).is_err() || magic != *b"\x89PNG\r\n\x1a\n" {
        return Ok(());
    }
    let mut offset = 8u64;
    let mut head = [0u8; 8];
    while file.read_exact(&mut head).is_ok() {
        let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]);
        match &head[4..8] {
            b"PLTE" if len == 0 || len % 3 != 0 || len > 3 * 256 => {
                return Err(InputError::Decode {
                    path: path.to_path_buf(),
                    message: format!(
                        "its PLTE chunk at byte offset {offset} holds {len} bytes, not a whole number of RGB entries (3 bytes each, 1 to 256 of them): the palette is damaged"
                    ),
                })
            }
            b"IEND" | b"IDAT" => return Ok(()),
            _ => {}
        }
        offset += 12 + u64::from(len);
        file.seek(SeekFrom::Start(offset)).map_err(io)?;
    }
    Ok(())
}

fn decode_srgb(
    path: &Path,
    format: image::ImageFormat,
    budget: &Budget,
) -> Result<LinearPixels, InputError> {
    use image::ImageDecoder;
    if format == image::ImageFormat::Png {
        check_png_chunks(path)?;
    }
    let decode_err = |e: image::ImageError| InputError::Decode {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let mut reader = image::ImageReader::open(path).map_err(|source| InputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    reader.set_format(format);
    let mut limits = image::Limits::no_limits();
    limits.max_alloc = Some(budget.bytes);
    reader.limits(limits);
    let decoder = reader.into_decoder().map_err(decode_err)?;
    let (w, h) = decoder.dimensions();
    check_pixels(path, w.into(), h.into(), decoder.total_bytes(), budget)?;
    let img = image::DynamicImage::from_decoder(decoder).map_err(decode_err)?;
    let (width, height) = (img.width() as usize, img.height() as usize);
    if width == 0 || height == 0 {
        return Err(empty(path, width, height));
    }
    let eight_bit = matches!(
        img,
        image::DynamicImage::ImageLuma8(_)
            | image::DynamicImage::ImageLumaA8(_)
            | image::DynamicImage::ImageRgb8(_)
            | image::DynamicImage::ImageRgba8(_)
    );
    let rgba = if eight_bit {
        let table: Vec<f32> = (0..256u32)
            .map(|v| srgb_to_linear(f64::from(v) / 255.0) as f32)
            .collect();
        img.to_rgba8()
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                [
                    table[r as usize],
                    table[g as usize],
                    table[b as usize],
                    f32::from(a) / 255.0,
                ]
            })
            .collect()
    } else {
        let table: Vec<f32> = (0..65536u32)
            .map(|v| srgb_to_linear(f64::from(v) / 65535.0) as f32)
            .collect();
        img.to_rgba16()
            .pixels()
            .map(|p| {
                let [r, g, b, a] = p.0;
                [
                    table[r as usize],
                    table[g as usize],
                    table[b as usize],
                    f32::from(a) / 65535.0,
                ]
            })
            .collect()
    };
    Ok(LinearPixels {
        width,
        height,
        rgba,
    })
}

fn decode_exr(path: &Path, budget: &Budget) -> Result<LinearPixels, InputError> {
    use exr::prelude::*;
    // The header first: the pixel buffer below is allocated from its size.
    if let Ok(meta) = exr::meta::MetaData::read_from_file(path, false) {
        if let Some(header) = meta.headers.first() {
            let size = header.layer_size;
            check_pixels(path, size.width() as u64, size.height() as u64, 0, budget)?;
        }
    }
    // Decompressed on this thread (`non_parallel`) and inside `catch_unwind`: the exr crate's
    // codecs can panic on damaged data (B44 on a block that is not, found by fuzzing), and a panic
    // in its parallel decompressor's rayon tasks aborts the process; here it becomes an error.
    let read = || {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                |resolution: Vec2<usize>, _channels: &RgbaChannels| {
                    (
                        resolution.width(),
                        vec![[0f32; 4]; resolution.width() * resolution.height()],
                    )
                },
                |pixels: &mut (usize, Vec<[f32; 4]>),
                 pos: Vec2<usize>,
                 (r, g, b, a): (f32, f32, f32, f32)| {
                    pixels.1[pos.y() * pixels.0 + pos.x()] = [r, g, b, a];
                },
            )
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_file(path)
    };
    let image = std::panic::catch_unwind(read)
        .map_err(|panic| InputError::Exr {
            path: path.to_path_buf(),
            message: format!(
                "the OpenEXR decoder failed on damaged data ({})",
                panic
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| panic.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "no message".into())
            ),
        })?
        .map_err(|e| match e {
            exr::error::Error::Io(source) => InputError::Io {
                path: path.to_path_buf(),
                source,
            },
            other => InputError::Exr {
                path: path.to_path_buf(),
                message: other.to_string(),
            },
        })?;
    let size = image.layer_data.size;
    let (width, height) = (size.width(), size.height());
    if width == 0 || height == 0 {
        return Err(empty(path, width, height));
    }
    let mut rgba = image.layer_data.channel_data.pixels.1;
    for (i, px) in rgba.iter_mut().enumerate() {
        for (c, &v) in px.iter().enumerate() {
            if !(v.is_finite() && v >= 0.0) {
                return Err(InputError::BadPixel {
                    path: path.to_path_buf(),
                    x: i % width,
                    y: i / width,
                    channel: ["R", "G", "B", "A"][c],
                    value: v,
                });
            }
        }
        let a = px[3];
        if a > 0.0 {
            for c in &mut px[..3] {
                *c = (f64::from(*c) / f64::from(a)).min(f64::from(f32::MAX)) as f32;
            }
        }
    }
    Ok(LinearPixels {
        width,
        height,
        rgba,
    })
}

fn empty(path: &Path, width: usize, height: usize) -> InputError {
    InputError::EmptyImage {
        path: PathBuf::from(path),
        width,
        height,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A unique path in the system temp dir; the file is removed when the guard drops.
    struct TempFile(PathBuf);

    impl TempFile {
        fn new(name: &str, ext: &str) -> Self {
            static COUNTER: AtomicUsize = AtomicUsize::new(0);
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            TempFile(std::env::temp_dir().join(format!(
                "otbake-input-{}-{n}-{name}.{ext}",
                std::process::id()
            )))
        }
    }

    impl Drop for TempFile {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn close(a: f32, b: f64, tol: f64) -> bool {
        (f64::from(a) - b).abs() <= tol
    }

    #[test]
    fn srgb_eotf_known_values() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert_eq!(srgb_to_linear(1.0), 1.0);
        assert!((srgb_to_linear(0.5) - 0.214_041_140_5).abs() < 1e-9);
        // Linear segment and its continuity with the power segment.
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-15);
        assert!((srgb_to_linear(0.04045) - srgb_to_linear(0.040_450_001)).abs() < 1e-8);
        // 8-bit code 128 (0.50196) → 0.21586.
        assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_5).abs() < 1e-6);
    }

    /// A 3x2 RGBA PNG with known pixels, decoded under every density channel.
    #[test]
    fn png_decodes_to_linear_values_and_masses() {
        let file = TempFile::new("rgba", "png");
        // Row-major from the top-left; (x, y).
        let px: [[u8; 4]; 6] = [
            [255, 255, 255, 255], // (0,0) white
            [0, 0, 0, 255],       // (1,0) black
            [128, 128, 128, 255], // (2,0) grey 0.2158605
            [255, 0, 0, 128],     // (0,1) red, alpha 128/255
            [0, 255, 0, 0],       // (1,1) transparent green
            [0, 0, 255, 255],     // (2,1) blue
        ];
        let mut img = image::RgbaImage::new(3, 2);
        for (i, p) in px.iter().enumerate() {
            img.put_pixel(i as u32 % 3, i as u32 / 3, image::Rgba(*p));
        }
        img.save(&file.0).unwrap();

        let grey = srgb_to_linear(128.0 / 255.0);
        let a_red = 128.0 / 255.0;
        let tol = 1e-6;

        let lum = load_image(&file.0, DensityChannel::Luminance).unwrap();
        assert_eq!(lum.dims, vec![3, 2]);
        let want = [1.0, 0.0, grey, 0.2126 * a_red, 0.0, 0.0722];
        for (i, (&m, w)) in lum.mass.iter().zip(want).enumerate() {
            assert!(close(m, w, tol), "luminance mass of cell {i}: {m} vs {w}");
        }
        // ratio = rgb / Y: white → 1, red → 1/0.2126, blue → 1/0.0722, black → 0.
        assert!(lum.ratio[0].iter().all(|&c| close(c, 1.0, tol)));
        assert_eq!(lum.ratio[1], [0.0; 3]);
        assert!(close(lum.ratio[3][0], 1.0 / 0.2126, 1e-4));
        assert_eq!(&lum.ratio[3][1..], &[0.0, 0.0]);
        assert!(close(lum.ratio[5][2], 1.0 / 0.0722, 1e-3));
        // Displayed color = mass · ratio = rgb · alpha.
        assert!(close(lum.mass[3] * lum.ratio[3][0], a_red, tol));
        // The transparent green pixel has color but no displayed mass.
        assert!(close(lum.ratio[4][1], 1.0 / 0.7152, 1e-4));

        let inv = load_image(&file.0, DensityChannel::Inverted).unwrap();
        let want = [
            0.0,
            1.0,
            1.0 - grey,
            (1.0 - 0.2126) * a_red,
            0.0,
            1.0 - 0.0722,
        ];
        for (i, (&m, w)) in inv.mass.iter().zip(want).enumerate() {
            assert!(close(m, w, tol), "inverted mass of cell {i}: {m} vs {w}");
        }
        assert_eq!(inv.ratio[3], [1.0, 0.0, 0.0]);
        assert!(inv.ratio[2].iter().all(|&c| close(c, grey, tol)));

        let alpha = load_image(&file.0, DensityChannel::Alpha).unwrap();
        let want = [1.0, 1.0, 1.0, a_red, 0.0, 1.0];
        for (i, (&m, w)) in alpha.mass.iter().zip(want).enumerate() {
            assert!(close(m, w, tol), "alpha mass of cell {i}: {m} vs {w}");
        }
        assert_eq!(alpha.ratio[4], [0.0, 1.0, 0.0]);
    }

    /// 16-bit grey PNGs decode through the exact EOTF too.
    #[test]
    fn png_16bit_grey() {
        let file = TempFile::new("grey16", "png");
        let img =
            image::ImageBuffer::<image::Luma<u16>, _>::from_raw(2, 1, vec![0u16, 32768]).unwrap();
        img.save(&file.0).unwrap();
        let g = load_image(&file.0, DensityChannel::Luminance).unwrap();
        assert_eq!(g.mass[0], 0.0);
        assert!(close(g.mass[1], srgb_to_linear(32768.0 / 65535.0), 1e-6));
        assert!(g.ratio[1].iter().all(|&c| close(c, 1.0, 1e-5)));
    }

    #[test]
    fn real_shape_mass_is_on_the_dark_shape() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/shapes/heart.png");
        let path = if path.exists() {
            path
        } else {
            PathBuf::from("/work/shared/data/shapes/heart.png")
        };
        let raw = image::open(&path).unwrap().to_rgba8();
        let g = load_image(&path, DensityChannel::Inverted).unwrap();
        assert_eq!(g.dims, vec![128, 128]);
        // Split the pixels into dark (sRGB luma < 128) and light ones; nearly all mass is dark.
        let (mut dark, mut light, mut n_dark) = (0.0f64, 0.0f64, 0usize);
        for (p, &m) in raw.pixels().zip(&g.mass) {
            let [r, gg, b, _] = p.0.map(u32::from);
            if r + gg + b < 3 * 128 {
                dark += f64::from(m);
                n_dark += 1;
            } else {
                light += f64::from(m);
            }
        }
        // The heart covers about 60% of the square; the rest is white.
        assert!(
            n_dark > 500 && n_dark < 128 * 128 * 9 / 10,
            "{n_dark} dark pixels"
        );
        assert!(
            dark / (dark + light) > 0.95,
            "dark share {}",
            dark / (dark + light)
        );
        // White background pixels have no mass; the shape's interior has nearly full mass.
        assert_eq!(g.mass[0], 0.0);
        let max = g.mass.iter().cloned().fold(0.0, f32::max);
        assert!(max > 0.9, "max mass {max}");
    }

    #[test]
    fn exr_round_trip_and_premultiplied_alpha() {
        let file = TempFile::new("ok", "exr");
        // (x, y) → (r, g, b, a), premultiplied.
        let value = |x: usize, y: usize| {
            let v = (x + 3 * y) as f32 * 0.25;
            let a = if x == 2 { 0.5 } else { 1.0 };
            (v * a, 2.0 * v * a, 0.0f32, a)
        };
        exr::prelude::write_rgba_file(&file.0, 3, 2, value).unwrap();
        let g = load_image(&file.0, DensityChannel::Luminance).unwrap();
        assert_eq!(g.dims, vec![3, 2]);
        for y in 0..2 {
            for x in 0..3 {
                let (r, gg, b, _) = value(x, y);
                let want = 0.2126 * f64::from(r) + 0.7152 * f64::from(gg) + 0.0722 * f64::from(b);
                let m = g.mass[x + 3 * y];
                assert!(close(m, want, 1e-6), "({x},{y}): {m} vs {want}");
            }
        }
        // Straight color under `alpha`: premultiplied (0.25, 0.5, 0) at a = 0.5 is (0.5, 1, 0).
        let a = load_image(&file.0, DensityChannel::Alpha).unwrap();
        assert_eq!(a.mass[2], 0.5);
        assert_eq!(a.ratio[2], [0.5, 1.0, 0.0]);
        assert_eq!(a.ratio[1], [0.25, 0.5, 0.0]);
    }

    #[test]
    fn exr_bad_values_name_the_pixel() {
        for (name, bad, channel) in [
            ("nan", f32::NAN, "G"),
            ("inf", f32::INFINITY, "G"),
            ("neg", -0.5, "G"),
        ] {
            let file = TempFile::new(name, "exr");
            exr::prelude::write_rgba_file(&file.0, 4, 3, |x, y| {
                let g = if (x, y) == (2, 1) { bad } else { 0.5f32 };
                (0.5f32, g, 0.5f32, 1.0f32)
            })
            .unwrap();
            let err = load_image(&file.0, DensityChannel::Luminance).unwrap_err();
            assert!(
                matches!(err, InputError::BadPixel { x: 2, y: 1, channel: c, .. } if c == channel),
                "{name}: {err:?}"
            );
            let msg = err.to_string();
            assert!(msg.contains(&file.0.display().to_string()), "{msg}");
            assert!(
                msg.contains("x 2, y 1") && msg.contains("channel G"),
                "{msg}"
            );
        }
    }

    #[test]
    fn file_errors() {
        let missing = std::env::temp_dir().join("otbake-definitely-missing-file.png");
        let err = load_image(&missing, DensityChannel::Luminance).unwrap_err();
        assert!(matches!(err, InputError::NotFound { .. }), "{err:?}");
        assert!(err
            .to_string()
            .contains("otbake-definitely-missing-file.png"));

        let err = load_image(Path::new("texture.tga"), DensityChannel::Luminance).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, InputError::UnsupportedExtension { .. }));
        for ext in [".png", ".jpg", ".jpeg", ".exr", "texture.tga"] {
            assert!(msg.contains(ext), "{msg}");
        }

        let garbage = TempFile::new("garbage", "png");
        std::fs::write(&garbage.0, b"not a png at all").unwrap();
        let err = load_image(&garbage.0, DensityChannel::Luminance).unwrap_err();
        assert!(matches!(err, InputError::Decode { .. }), "{err:?}");
        assert!(err.to_string().contains(&garbage.0.display().to_string()));
    }

    #[test]
    fn all_zero_density_is_an_error() {
        let file = TempFile::new("white", "png");
        image::RgbImage::from_pixel(4, 4, image::Rgb([255, 255, 255]))
            .save(&file.0)
            .unwrap();
        let err = load_image(&file.0, DensityChannel::Inverted).unwrap_err();
        assert!(matches!(err, InputError::NoMass { .. }), "{err:?}");
        let msg = err.to_string();
        assert!(
            msg.starts_with("the density channel `inverted` of "),
            "{msg}"
        );
        assert!(
            msg.ends_with("is zero everywhere: choose another `density`"),
            "{msg}"
        );
        assert!(msg.contains(&file.0.display().to_string()), "{msg}");
        // The same file is fine under `luminance`.
        assert!(load_image(&file.0, DensityChannel::Luminance).is_ok());
    }

    #[test]
    fn jpeg_decodes() {
        let file = TempFile::new("grey", "jpg");
        image::GrayImage::from_pixel(8, 8, image::Luma([128]))
            .save(&file.0)
            .unwrap();
        let g = load_image(&file.0, DensityChannel::Luminance).unwrap();
        assert_eq!(g.dims, vec![8, 8]);
        // JPEG is lossy; a flat block stays within a couple of codes.
        let want = srgb_to_linear(128.0 / 255.0);
        assert!(g.mass.iter().all(|&m| close(m, want, 0.01)));
    }

    /// A PNG chunk: length, type, data, CRC-32.
    fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
        let crc = !kind.iter().chain(data).fold(!0u32, |mut c, &b| {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xEDB8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            c
        });
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        out.extend_from_slice(kind);
        out.extend_from_slice(data);
        out.extend_from_slice(&crc.to_be_bytes());
        out
    }

    /// Found by the fuzzer (`image` target): a palette of 3k + 2 bytes made the png crate index
    /// past it and panic. It is refused, naming the chunk and its offset.
    #[test]
    fn a_palette_of_partial_entries_is_refused_not_a_panic() {
        // A 1×1 palette image: IHDR, PLTE, one stored-zlib IDAT row (filter 0, index 0), IEND.
        let png = |palette: &[u8]| {
            let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
            b.extend(chunk(b"IHDR", &[0, 0, 0, 1, 0, 0, 0, 1, 8, 3, 0, 0, 0]));
            b.extend(chunk(b"PLTE", palette));
            let idat = [
                0x78, 0x01, 0x01, 0x02, 0x00, 0xFD, 0xFF, 0, 0, 0x00, 0x02, 0x00, 0x01,
            ];
            b.extend(chunk(b"IDAT", &idat));
            b.extend(chunk(b"IEND", &[]));
            b
        };
        let good = TempFile::new("palette-good", "png");
        std::fs::write(&good.0, png(&[255, 255, 255, 0, 0, 0])).unwrap();
        let g = load_image(&good.0, DensityChannel::Luminance).unwrap();
        assert_eq!(g.mass, vec![1.0]);
        for bad in [&[255u8, 255, 255, 0, 0][..], &[][..], &[7u8; 771][..]] {
            let file = TempFile::new("palette-bad", "png");
            std::fs::write(&file.0, png(bad)).unwrap();
            let e = load_image(&file.0, DensityChannel::Luminance).unwrap_err();
            let msg = e.to_string();
            assert!(
                msg.contains(&file.0.display().to_string())
                    && msg.contains("PLTE chunk at byte offset 33")
                    && msg.contains(&format!("holds {} bytes", bad.len())),
                "{msg}"
            );
        }
    }

    /// Found by the fuzzer (`image` target, overflow checks on): a ZIP EXR relabelled B44 (3 bytes
    /// changed) made the exr crate's B44 decoder overflow inside its parallel decompressor's rayon
    /// task, and a panic there aborts the process. Decoded on the calling thread under
    /// `catch_unwind`, it is an error naming the file.
    #[test]
    fn a_damaged_exr_block_is_an_error_not_an_abort() {
        let fixture = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../tests/fuzz/corpus/image/finding-b44-overflow.exr");
        let file = TempFile::new("b44", "exr");
        std::fs::copy(&fixture, &file.0).unwrap();
        match load_image(&file.0, DensityChannel::Luminance) {
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains(&file.0.display().to_string()), "{msg}");
            }
            // Without overflow checks the B44 arithmetic wraps instead of panicking.
            Ok(_) if cfg!(debug_assertions) => panic!("the damaged block was decoded"),
            Ok(_) => {}
        }
    }
}
