//! 2D images of blends: `blend`, `grid`, `texture`, and the raw map points of `points`.

use super::budget::check_render;
use super::scene::{input_names, Open, Scene};
use anyhow::{bail, Result};
use otbake::render::imageio::write_image;
use otbake::render::memory;
use otbake::render::texture::{render_lod, render_texture, WeightField};
use otbake::render::{render, render_grid};
use otbake::{Manifest, Method, RenderSettings};
use std::path::PathBuf;

/// The image flags `blend` and `grid` share.
#[derive(clap::Args, Clone, Copy)]
pub struct ImageArgs {
    /// Image size WxH in pixels (per cell for `grid`).
    #[arg(long, default_value = "256x256", value_parser = parse_size)]
    pub(super) size: (usize, usize),
    /// Reconstruction: one point query per pixel (exact), or one splat of all points (faster;
    /// separable kernel weights, equal to the queries within a stated tolerance).
    #[arg(long, value_enum, default_value_t = Method::Query)]
    method: Method,
    /// Gaussian kernel standard deviation in pixels (truncated at 3 sigma).
    #[arg(long, default_value_t = 0.5)]
    sigma: f32,
}

impl ImageArgs {
    pub(super) fn settings(&self) -> Result<RenderSettings> {
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            bail!("--sigma {}: use a positive number of pixels", self.sigma);
        }
        Ok(RenderSettings {
            width: self.size.0,
            height: self.size.1,
            method: self.method,
            sigma_px: self.sigma,
        })
    }
}

/// `WxH`, each side 1 to 16384 pixels.
fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s:?}: expected WxH, e.g. 256x256"))?;
    let parse = |v: &str, side: &str| {
        let v = v.trim();
        if v.is_empty() {
            return Err(format!(
                "{s:?}: the {side} is missing; expected WxH, e.g. 256x256"
            ));
        }
        let n = v.parse::<usize>().map_err(|_| {
            format!("{s:?}: the {side} {v:?} is not a whole number; expected WxH, e.g. 256x256")
        })?;
        if !(1..=16384).contains(&n) {
            return Err(format!(
                "{s:?}: the {side} {n} is out of range: width and height must be 1 to 16384"
            ));
        }
        Ok(n)
    };
    Ok((parse(w, "width")?, parse(h, "height")?))
}

#[derive(clap::Args)]
pub struct BlendArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// One non-negative weight per input, in manifest order, summing to 1: e.g. 0.5,0.5.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    weights: Vec<f32>,
    #[command(flatten)]
    image: ImageArgs,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake blend`: one blend as an image.
pub fn blend(args: BlendArgs) -> Result<()> {
    let settings = args.image.settings()?;
    let (w, h) = args.image.size;
    check_render(
        &args.manifest,
        memory::image_bytes(w, h),
        || format!("blend: a {w}x{h} image"),
        "lower --size",
    )?;
    let scene = Scene::open(&args.manifest, Some(&args.weights))?;
    let maps = scene.maps()?;
    let img = render(scene.proxy()?, &maps, &args.weights, &settings)?;
    write_image(&args.output, &img)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct GridArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// Cells per side.
    #[arg(long, default_value_t = 5)]
    steps: usize,
    #[command(flatten)]
    image: ImageArgs,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake grid`: a row, triangle or square of blends in one image.
pub fn grid(args: GridArgs) -> Result<()> {
    let settings = args.image.settings()?;
    let (w, h, steps) = (args.image.size.0, args.image.size.1, args.steps);
    // The manifest's input count decides the layout; 4 (a square) bounds the others.
    let k = Manifest::load(&args.manifest).map_or(4, |m| m.inputs.len());
    check_render(
        &args.manifest,
        memory::grid_bytes(k, steps, w, h),
        || {
            format!(
                "grid: {} blends of {w}x{h} pixels (--steps {steps}, {k} inputs)",
                memory::grid_blends(k, steps)
            )
        },
        "lower --steps or --size",
    )?;
    let scene = Scene::open(&args.manifest, None)?;
    let img = render_grid(&scene.archives, args.steps, &settings)?;
    write_image(&args.output, &img)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct TextureArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// Weight field: `perlin:SCALE,SEED`, `zigzag`, or constant weights `a,b,..`.
    #[arg(long, value_parser = WeightField::parse)]
    weights: WeightField,
    /// Image size WxH in pixels.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (usize, usize),
    /// Gaussian kernel standard deviation in pixels.
    #[arg(long, default_value_t = 0.5)]
    sigma: f32,
    /// Level of detail: show this many texture tiles per image side, each pixel one range query
    /// over its footprint (instead of a point query per pixel).
    #[arg(long)]
    lod: Option<f32>,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake texture`: weights that vary per pixel, by point or (with `--lod`) range queries.
pub fn texture(args: TextureArgs) -> Result<()> {
    let TextureArgs {
        manifest,
        weights,
        size: (width, height),
        sigma,
        lod,
        output,
    } = args;
    if !(sigma.is_finite() && sigma > 0.0) {
        bail!("--sigma {sigma}: use a positive number of pixels");
    }
    let k = Manifest::load(&manifest).map_or(4, |m| m.inputs.len());
    check_render(
        &manifest,
        memory::texture_bytes(width, height, k),
        || format!("texture: a {width}x{height} image of per-pixel weights"),
        "lower --size",
    )?;
    let scene = Scene::open(&manifest, None)?;
    let maps = scene.maps()?;
    if let WeightField::Constant(w) = &weights {
        if w.len() != maps.len() {
            bail!(
                "--weights has {} values but the manifest has {} inputs: give one weight per input",
                w.len(),
                maps.len()
            );
        }
    }
    let img = match lod {
        Some(r) if !(r.is_finite() && r > 0.0) => {
            bail!("--lod {r}: use a positive number of tiles")
        }
        Some(r) => render_lod(scene.proxy()?, &maps, &weights, width, height, r)?,
        None => render_texture(scene.proxy()?, &maps, &weights, width, height, sigma)?,
    };
    write_image(&output, &img)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct PointsArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// Input name.
    #[arg(long)]
    input: String,
    /// Output .npy file.
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake points`: one input's map as a .npy of point pairs.
pub fn points(args: PointsArgs) -> Result<()> {
    let m = Scene::bake(&args.manifest, &Open::default())?;
    let input = &args.input;
    if m.input_index(input).is_none() {
        bail!(
            "--input {input:?} is not an input of {}: use one of {}",
            args.manifest.display(),
            input_names(&m)
        );
    }
    let bytes = otbake::render::points::points_npy(&m, input)?;
    otbake::fsio::write_atomic(&args.output, &bytes)?;
    Ok(())
}
