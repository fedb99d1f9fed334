//! Writing rendered images: PNG (8-bit sRGB-encoded) or EXR (linear float), chosen by extension.

use crate::fsio::{write_atomic, IoError};
use std::path::{Path, PathBuf};

/// A linear-RGBA float image, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct Rgba {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width * height * 4` linear values; alpha straight (not premultiplied).
    pub pixels: Vec<f32>,
}

impl Rgba {
    /// An image filled with `value`.
    pub fn filled(width: usize, height: usize, value: [f32; 4]) -> Self {
        Self {
            width,
            height,
            // By doubling copies: renders pay this per image, and an iterator chain was measurably
            // slower.
            pixels: value.repeat(width * height),
        }
    }

    /// Copies `src` into this image with its top-left corner at (`x`, `y`).
    pub fn blit(&mut self, src: &Rgba, x: usize, y: usize) {
        for row in 0..src.height.min(self.height.saturating_sub(y)) {
            let w = src.width.min(self.width.saturating_sub(x));
            let d = ((y + row) * self.width + x) * 4;
            let s = row * src.width * 4;
            self.pixels[d..d + w * 4].copy_from_slice(&src.pixels[s..s + w * 4]);
        }
    }
}

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ImageWriteError {
    /// Extension other than .png or .exr.
    #[error("cannot write {}: unsupported image extension, use .png or .exr", .0.display())]
    Extension(PathBuf),
    /// Encoding failed.
    #[error("cannot encode {}: {message}", path.display())]
    Encode {
        /// Output path.
        path: PathBuf,
        /// Encoder message.
        message: String,
    },
    /// Writing failed.
    #[error(transparent)]
    Io(#[from] IoError),
}

/// Linear → sRGB transfer (IEC 61966-2-1), for 8-bit output.
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes `img` to `path` (atomically), as PNG or EXR by extension. PNG drops alpha when it is 1
/// everywhere.
pub fn write_image(path: &Path, img: &Rgba) -> Result<(), ImageWriteError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    let bytes = match ext.as_deref() {
        Some("png") => encode_png(img),
        Some("exr") => encode_exr(img),
        _ => return Err(ImageWriteError::Extension(path.to_path_buf())),
    }
    .map_err(|message| ImageWriteError::Encode {
        path: path.to_path_buf(),
        message,
    })?;
    write_atomic(path, &bytes)?;
    Ok(())
}

fn encode_png(img: &Rgba) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let opaque = img.pixels.chunks_exact(4).all(|p| p[3] >= 1.0);
    let channels = if opaque { 3 } else { 4 };
    let mut raw = Vec::with_capacity(img.width * img.height * channels);
    for p in img.pixels.chunks_exact(4) {
        for &c in &p[..3] {
            raw.push((linear_to_srgb(c) * 255.0).round() as u8);
        }
        if !opaque {
            raw.push((p[3].clamp(0.0, 1.0) * 255.0).round() as u8);
        }
    }
    let mut out = Vec::new();
    let color = if opaque {
        image::ExtendedColorType::Rgb8
    } else {
        image::ExtendedColorType::Rgba8
    };
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(&raw, img.width as u32, img.height as u32, color)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

fn encode_exr(img: &Rgba) -> Result<Vec<u8>, String> {
    use exr::prelude::*;
    let (w, h) = (img.width, img.height);
    let px = &img.pixels;
    let channels = SpecificChannels::rgba(|pos: Vec2<usize>| {
        let i = (pos.y() * w + pos.x()) * 4;
        (px[i], px[i + 1], px[i + 2], px[i + 3])
    });
    // ZIP16 in increasing line order: the default (RLE, unspecified order) is not byte-deterministic.
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    let mut cursor = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_buffered(&mut cursor)
        .map_err(|e| e.to_string())?;
    Ok(cursor.into_inner())
}
