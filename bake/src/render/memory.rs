//! What a render or export will allocate, from its settings alone, so the command line can refuse
//! one beyond the budget before baking or querying anything. Every figure is the output image's
//! (or grid's) bytes times what the renderer keeps per pixel, plus the list of blends for grids.

use crate::limits::product;

/// Bytes per output pixel: the RGBA `f32` image (16) and its encoded copy on writing (at most 8 for
/// 16-bit PNG, 16 for an EXR's channels; 16 counted), plus a cell image blitted into a grid.
pub const BYTES_PER_PIXEL: u64 = 16 + 16;

/// Bytes per blend of a grid's list: its cell position and weights (`Vec<f32>` of up to 4).
const BYTES_PER_CELL: u64 = 16 + 24 + 16;

/// Blends in a grid of `k` inputs with `steps` per side: a row (2), a triangle (3) or a square (4).
pub fn grid_blends(k: usize, steps: usize) -> u64 {
    let s = steps as u64;
    match k {
        2 => s,
        3 => s.saturating_mul(s.saturating_add(1)) / 2,
        _ => s.saturating_mul(s),
    }
}

/// A grid of blends whose cells are `width × height` pixels: the cell list and the whole image
/// (a row of `steps` cells, or `steps` rows of up to `steps` cells).
pub fn grid_bytes(k: usize, steps: usize, width: usize, height: usize) -> u64 {
    let (s, w, h) = (steps as u64, width as u64, height as u64);
    let rows = if k == 2 { 1 } else { s };
    let pixels = product(&[s, rows, w, h]);
    product(&[grid_blends(k, steps), BYTES_PER_CELL])
        .saturating_add(product(&[pixels, BYTES_PER_PIXEL]))
        .saturating_add(product(&[w, h, BYTES_PER_PIXEL]))
}

/// One `width × height` image.
pub fn image_bytes(width: usize, height: usize) -> u64 {
    product(&[width as u64, height as u64, BYTES_PER_PIXEL])
}

/// A per-pixel weight field of `k` weights (`texture`): the image and the weights.
pub fn texture_bytes(width: usize, height: usize, k: usize) -> u64 {
    image_bytes(width, height).saturating_add(product(&[width as u64, height as u64, 4 * k as u64]))
}

/// A `res³` `.vol` export: the values and the file's bytes.
pub fn volume_bytes(res: usize) -> u64 {
    let r = res as u64;
    product(&[r, r, r, 4 + 4])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_count_every_pixel_and_blend() {
        assert_eq!(grid_blends(2, 5), 5);
        assert_eq!(grid_blends(3, 5), 15);
        assert_eq!(grid_blends(4, 5), 25);
        // 5 × 5 cells of 16384² pixels: 6.7 G pixels, 200 GiB.
        assert!(grid_bytes(4, 5, 16384, 16384) > 200 << 30);
        assert!(grid_bytes(4, 100_000, 256, 256) > 1 << 50);
        assert_eq!(grid_bytes(4, usize::MAX, usize::MAX, 2), u64::MAX);
        assert_eq!(image_bytes(256, 256), 256 * 256 * BYTES_PER_PIXEL);
    }
}
