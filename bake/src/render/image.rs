//! Rendering 2D blends to images through the runtime: per-pixel point queries or one splat, then
//! the inputs' composite rule. Both evaluate horizontal bands in parallel with the runtime's region
//! queries, which equal per-pixel queries (`query`: `Prepared::point_grid` after mixing the
//! weights once with `Blend::prepare`) or the whole-image splat (`splat`:
//! `Blend::splat_region_rgba`, which mixes the maps as it reads them; within the tolerance
//! `otbake_runtime::SPLAT_TERM_TOLERANCE` documents of point queries) bit for bit, however the
//! image is banded. Everything here goes
//! through `otbake-runtime`, exactly as an engine would, so the images are a test of the runtime
//! too.

use crate::fsio::{read_archive, ArchiveBytes, IoError};
use crate::manifest::Manifest;
use crate::render::imageio::Rgba;
use otbake_formats::Composite;
use otbake_runtime::{Blend, Kernel, Map, PointValue, Prepared, Proxy, Region, MAX_DIM};
use rayon::prelude::*;

/// How an image is reconstructed from the blended points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// One Gaussian point query per pixel (what a renderer's texture lookup does).
    Query,
    /// Splat every blended point into the image once (fastest for whole images).
    Splat,
}

/// Image size, method and kernel width.
#[derive(Debug, Clone, Copy)]
pub struct RenderSettings {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Reconstruction method.
    pub method: Method,
    /// Kernel standard deviation in pixels of the larger image side.
    pub sigma_px: f32,
}

/// Why a blend could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// An archive could not be read.
    #[error(transparent)]
    Io(#[from] IoError),
    /// An archive or the query was refused by the runtime.
    #[error("{context}: {source}")]
    Runtime {
        /// Which archive or query.
        context: String,
        /// Why.
        #[source]
        source: otbake_runtime::Error,
    },
    /// The blend is not an image.
    #[error("the manifest's inputs are {0}-dimensional; images need 2D inputs (use the volume or BRDF commands)")]
    NotAnImage(usize),
    /// Bad grid request.
    #[error("{0}")]
    Grid(String),
}

/// Archive bytes of a manifest's proxy and maps, loaded once and opened as often as needed.
pub struct Archives {
    proxy: ArchiveBytes,
    maps: Vec<(String, ArchiveBytes)>,
}

impl Archives {
    /// Reads the proxy and every map of a (baked) manifest.
    pub fn load(m: &Manifest) -> Result<Self, RenderError> {
        let proxy = read_archive(&m.proxy_archive())?;
        let maps = m
            .inputs
            .iter()
            .map(|i| Ok((i.name.clone(), read_archive(&m.map_archive(&i.name))?)))
            .collect::<Result<_, IoError>>()?;
        Ok(Self { proxy, maps })
    }

    /// Opens the proxy (validated).
    pub fn proxy(&self) -> Result<Proxy<'_>, RenderError> {
        Proxy::open(&self.proxy).map_err(|source| RenderError::Runtime {
            context: "proxy archive".into(),
            source,
        })
    }

    /// Opens every map (validated), in manifest order.
    pub fn maps(&self) -> Result<Vec<Map<'_>>, RenderError> {
        self.maps
            .iter()
            .map(|(name, bytes)| {
                Map::open(bytes).map_err(|source| RenderError::Runtime {
                    context: format!("map archive of input {name:?}"),
                    source,
                })
            })
            .collect()
    }
}

fn runtime(context: &str) -> impl FnOnce(otbake_runtime::Error) -> RenderError + '_ {
    move |source| RenderError::Runtime {
        context: context.to_string(),
        source,
    }
}

/// The display rule shared by all maps (additive if they disagree).
pub fn composite(maps: &[Map<'_>]) -> Composite {
    let first = maps.first().map_or(Composite::Additive, |m| m.composite());
    if maps.iter().all(|m| m.composite() == first) {
        first
    } else {
        Composite::Additive
    }
}

/// One pixel from blended mass and premultiplied color.
pub fn shade(rule: Composite, mass: f32, color: [f32; 3]) -> [f32; 4] {
    match rule {
        Composite::Additive => [color[0], color[1], color[2], 1.0],
        Composite::Alpha => {
            let a = mass.clamp(0.0, 1.0);
            let inv = if mass > 0.0 { 1.0 / mass } else { 0.0 };
            [color[0] * inv, color[1] * inv, color[2] * inv, a]
        }
        Composite::InkOnWhite => {
            let bg = 1.0 - mass.clamp(0.0, 1.0);
            [color[0] + bg, color[1] + bg, color[2] + bg, 1.0]
        }
    }
}

/// Renders the blend of `maps` for `weights` as an image.
pub fn render<'a>(
    proxy: Proxy<'a>,
    maps: &[Map<'a>],
    weights: &[f32],
    s: &RenderSettings,
) -> Result<Rgba, RenderError> {
    if proxy.dim() != 2 {
        return Err(RenderError::NotAnImage(proxy.dim()));
    }
    let blend = Blend::new(proxy, maps).map_err(runtime("maps"))?;
    blend.check_weights(weights).map_err(runtime("--weights"))?;
    let rule = composite(maps);
    let (w, h) = (s.width, s.height);
    let kernel = Kernel {
        sigma: s.sigma_px / w.max(h) as f32,
    };
    let mut img = Rgba::filled(w, h, [0.0; 4]);
    let mut res = [1u32; MAX_DIM];
    res[0] = w as u32;
    res[1] = h as u32;
    // Horizontal bands, one coherent traversal each, rendered in parallel into disjoint slices; the
    // result does not depend on the banding (region queries equal per-pixel queries exactly).
    let band = band_rows(h);
    match s.method {
        Method::Query => {
            // The blend is mixed once for these weights; the point grids then read plain arrays.
            // The buffers are kept per thread between renders (a grid renders many blends of one
            // bake): fresh ones would cost page faults on every image.
            let mut store = PREPARED.with(|b| std::mem::take(&mut *b.borrow_mut()));
            let prep = prepare_into(&blend, weights, &mut store).map_err(runtime("--weights"))?;
            let mut values = VALUES.with(|b| std::mem::take(&mut *b.borrow_mut()));
            // Every value is overwritten by `point_grid`.
            values.resize(w * h, PointValue::default());
            values
                .par_chunks_mut(w * band)
                .enumerate()
                .try_for_each(|(b, chunk)| {
                    let rows = (chunk.len() / w) as u32;
                    prep.point_grid(kernel, Region::rows(res, (b * band) as u32, rows), chunk)
                })
                .map_err(runtime("point query"))?;
            img.pixels
                .par_chunks_mut(4)
                .zip(&values)
                .for_each(|(px, v)| px.copy_from_slice(&shade(rule, v.mass, v.color)));
            VALUES.with(|b| *b.borrow_mut() = values);
            PREPARED.with(|b| *b.borrow_mut() = store);
        }
        Method::Splat => {
            // No `prepare`: each band's splat mixes the maps as its traversal reads them (the
            // points near the band only), into RGBA cells (color, then density), and shades its
            // rows while they are in cache. One band per thread, of about equally many points: a
            // band also splats the points within the kernel's reach of its borders (at σ = ½ px
            // three rows' worth per border), so more bands cost more work (8 bands of a 256²
            // image: a quarter more than 1).
            let mean_mass = blend.mean_mass(weights).map_err(runtime("--weights"))?;
            let mut rgba = SPLAT.with(|b| std::mem::take(&mut *b.borrow_mut()));
            rgba.resize(w * h * 4, 0.0);
            let starts = balanced_bands(maps, weights, h, rayon::current_num_threads());
            let mut bands = Vec::with_capacity(starts.len());
            let (mut cells, mut pixels) = (&mut rgba[..], &mut img.pixels[..]);
            for pair in starts.windows(2) {
                let len = (pair[1] - pair[0]) * w * 4;
                let (c, rest) = cells.split_at_mut(len);
                let (p, rest_p) = pixels.split_at_mut(len);
                bands.push((pair[0], c, p));
                (cells, pixels) = (rest, rest_p);
            }
            bands
                .into_par_iter()
                .try_for_each(|(first, cells, pixels)| {
                    // A splat adds to its cells: start from zeros.
                    cells.fill(0.0);
                    let rows = (cells.len() / (w * 4)) as u32;
                    let region = Region::rows(res, first as u32, rows);
                    blend.splat_region_rgba(weights, kernel, region, cells)?;
                    for (px, c) in pixels.chunks_exact_mut(4).zip(cells.chunks_exact(4)) {
                        px.copy_from_slice(&shade(rule, c[3] * mean_mass, [c[0], c[1], c[2]]));
                    }
                    Ok(())
                })
                .map_err(runtime("splat"))?;
            SPLAT.with(|b| *b.borrow_mut() = rgba);
        }
    }
    Ok(img)
}

thread_local! {
    /// Prepared-blend buffers reused by [`render`] on this thread.
    static PREPARED: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
    /// Point values of the last `query` image rendered on this thread (reused, like `PREPARED`:
    /// fresh megabytes per image cost page faults on every image).
    static VALUES: std::cell::RefCell<Vec<PointValue>> = const { std::cell::RefCell::new(Vec::new()) };
    /// RGBA cells (color, then density) of the last `splat` image rendered on this thread.
    static SPLAT: std::cell::RefCell<Vec<f32>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// First rows of `bands` horizontal bands of an image `h` rows high holding about equally many
/// blended points, then `h`: the splat's work is per point. Counted from the blend's node boxes at
/// a coarse level of the tree (at most 64 nodes, each node's points spread evenly over the rows
/// its box covers); equal bands where the tree has no internal node. Bands may be empty. This runs
/// before the bands start, and its box reads miss the cache after a render, so it is on the
/// render's critical path: at 256 nodes it was 2% of a two-thread splat render's CPU samples, and
/// 64 split the shapes' blend at the same row.
fn balanced_bands(maps: &[Map<'_>], weights: &[f32], h: usize, bands: usize) -> Vec<usize> {
    let bands = bands.clamp(1, h.max(1));
    let equal = || (0..=bands).map(|b| b * h / bands).collect();
    let Some(first) = maps.first() else {
        return equal();
    };
    let (n, depth) = (first.n(), first.depth());
    if depth == 0 || bands == 1 {
        return equal();
    }
    let level = (depth - 1).min(6);
    let mut rows = vec![0.0f64; h];
    for offset in 0..1u32 << level {
        let node = otbake_formats::tree::node_at(n, level, offset);
        let (mut lo, mut hi) = (0.0f32, 0.0f32);
        for (w, m) in weights.iter().zip(maps) {
            let (l, u) = m.view().internal_box(node.index as usize);
            lo += w * l[1];
            hi += w * u[1];
        }
        // Rows the box covers, clamped to the image (a periodic blend's lifts may lie outside).
        let row = |v: f32| ((v * h as f32).floor().max(0.0) as usize).min(h - 1);
        let (a, b) = (row(lo), row(hi).max(row(lo)));
        let share = f64::from(node.count) / (b + 1 - a) as f64;
        for r in &mut rows[a..=b] {
            *r += share;
        }
    }
    let total: f64 = rows.iter().sum();
    let mut starts = vec![0];
    let mut acc = 0.0;
    for (r, &count) in rows.iter().enumerate() {
        acc += count;
        while starts.len() < bands && acc >= total * starts.len() as f64 / bands as f64 {
            starts.push(r + 1);
        }
    }
    starts.resize(bands, h);
    starts.push(h);
    starts
}

/// `blend` mixed for `weights` into `store` (resized to the blend's `PreparedSizes`), its two halves
/// (geometry, colors) on two threads: the same bits either way.
pub(crate) fn prepare_into<'s>(
    blend: &Blend<'_, '_>,
    weights: &[f32],
    store: &'s mut Vec<f32>,
) -> Result<Prepared<'s>, otbake_runtime::Error> {
    let sizes = blend.prepared_sizes();
    store.resize(sizes.total(), 0.0);
    blend.prepare_with(
        weights,
        sizes.split(store).expect("sized by PreparedSizes::total"),
        |geometry, color| {
            rayon::join(geometry, color);
        },
    )
}

/// Rows per band of a parallel render: a few bands per thread for balance, tall enough that the
/// 3σ margin each band's traversal also visits stays small.
fn band_rows(h: usize) -> usize {
    (h / (4 * rayon::current_num_threads())).clamp(8, 64)
}

/// Cell position (column, row) and weights of every cell of a blend grid of `k` inputs.
///
/// * 2 inputs: one row of `steps` cells from input 0 to input 1;
/// * 3 inputs: a triangle of `steps` rows (input 0 at the top, 1 bottom left, 2 bottom right);
/// * 4 inputs: a `steps × steps` square with bilinear corner weights (input 0 top left, 1 top right,
///   2 bottom left, 3 bottom right), as in the paper's Fig. 7.
///
/// Returns the cells and the grid size in cells.
#[allow(clippy::type_complexity)]
pub fn grid_cells(
    k: usize,
    steps: usize,
) -> Result<(Vec<(usize, usize, Vec<f32>)>, (usize, usize)), RenderError> {
    if steps < 2 {
        return Err(RenderError::Grid(format!(
            "--steps {steps}: use at least 2"
        )));
    }
    let t = |i: usize| i as f32 / (steps - 1) as f32;
    let mut cells = Vec::new();
    match k {
        2 => {
            for c in 0..steps {
                cells.push((c, 0, vec![1.0 - t(c), t(c)]));
            }
            Ok((cells, (steps, 1)))
        }
        3 => {
            // Row r holds r + 1 cells; cell j of row r has barycentric weights
            // (steps-1-r, r-j, j) / (steps-1), centred by an offset of half a cell per missing cell.
            for r in 0..steps {
                for j in 0..=r {
                    let w = [
                        (steps - 1 - r) as f32 / (steps - 1) as f32,
                        (r - j) as f32 / (steps - 1) as f32,
                        j as f32 / (steps - 1) as f32,
                    ];
                    // Columns are doubled so that half-cell offsets stay integral.
                    cells.push((steps - 1 - r + 2 * j, r, w.to_vec()));
                }
            }
            Ok((cells, (2 * steps - 1, steps)))
        }
        4 => {
            for r in 0..steps {
                for c in 0..steps {
                    let (u, v) = (t(c), t(r));
                    cells.push((c, r, vec![(1.0 - u) * (1.0 - v), u * (1.0 - v), (1.0 - u) * v, u * v]));
                }
            }
            Ok((cells, (steps, steps)))
        }
        _ => Err(RenderError::Grid(format!(
            "the manifest has {k} inputs; `grid` lays out 2 (row), 3 (triangle) or 4 (square) inputs — use `blend` for other counts"
        ))),
    }
}

/// Renders the whole grid of blends as one image.
pub fn render_grid(
    archives: &Archives,
    steps: usize,
    s: &RenderSettings,
) -> Result<Rgba, RenderError> {
    // Opened (and checksummed) once for the whole grid, not once per cell.
    let (proxy, maps) = (archives.proxy()?, archives.maps()?);
    let (cells, (cols, rows)) = grid_cells(maps.len(), steps)?;
    let triangle = maps.len() == 3;
    // Triangle columns are in half cells.
    let cell_w = if triangle { s.width / 2 } else { s.width };
    let bg = match composite(&maps) {
        Composite::InkOnWhite => [1.0, 1.0, 1.0, 1.0],
        _ => [0.0, 0.0, 0.0, 1.0],
    };
    let mut out = Rgba::filled(
        cols * cell_w + if triangle { s.width - cell_w } else { 0 },
        rows * s.height,
        bg,
    );
    for (c, r, w) in cells {
        let img = render(proxy, &maps, &w, s)?;
        out.blit(&img, c * cell_w, r * s.height);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::grid_cells;

    #[test]
    fn grid_layouts_cover_the_simplex_with_valid_weights() {
        for (k, steps, cells, size) in [(2, 5, 5, (5, 1)), (3, 4, 10, (7, 4)), (4, 5, 25, (5, 5))] {
            let (c, s) = grid_cells(k, steps).unwrap();
            assert_eq!((c.len(), s), (cells, size));
            for (col, row, w) in &c {
                assert!(*col < s.0 && *row < s.1);
                assert_eq!(w.len(), k);
                assert!(w.iter().all(|&x| x >= 0.0));
                assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
            }
            // Every input appears alone at some cell (the corners are the inputs themselves).
            for i in 0..k {
                assert!(
                    c.iter().any(|(_, _, w)| w[i] == 1.0),
                    "input {i} has no corner"
                );
            }
        }
        // Bilinear corners follow the documented placement: 0 top left, 3 bottom right.
        let (c, _) = grid_cells(4, 3).unwrap();
        assert_eq!(c[0].2, vec![1.0, 0.0, 0.0, 0.0]);
        assert_eq!(c[8].2, vec![0.0, 0.0, 0.0, 1.0]);
        assert!(
            grid_cells(5, 3).is_err() && grid_cells(1, 3).is_err() && grid_cells(4, 1).is_err()
        );
    }
}
