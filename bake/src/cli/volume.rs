//! Blends of 3D inputs: `volume` (a .vol grid), `render` (ray-marched images), `slice` (a plane).

use super::budget::check_render;
use super::scene::Scene;
use anyhow::{bail, Result};
use otbake::render::imageio::write_image;
use otbake::render::memory;
use otbake::render::volume::{
    self as renderer, Axis, RenderSettings, SliceSettings, DEFAULT_SIGMA,
};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct VolumeArgs {
    /// Manifest of 3D inputs (.obj meshes, .vol grids).
    manifest: PathBuf,
    /// One non-negative weight per input, in manifest order, summing to 1.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    weights: Vec<f32>,
    /// Cells per axis.
    #[arg(long, default_value_t = 64)]
    res: usize,
    /// Kernel standard deviation in unit-cube units.
    #[arg(long, default_value_t = DEFAULT_SIGMA)]
    sigma: f32,
    /// Output grid (.vol).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake volume`: one blend sampled on a res³ grid.
pub fn volume(args: VolumeArgs) -> Result<()> {
    let res = args.res;
    check_render(
        &args.manifest,
        memory::volume_bytes(res),
        || format!("volume: a {res}³ grid"),
        "lower --res",
    )?;
    let scene = Scene::open(&args.manifest, Some(&args.weights))?;
    let maps = scene.maps()?;
    renderer::export(scene.proxy()?, &maps, &args.weights, args.res, args.sigma)?
        .write(&args.output)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Manifest of 3D inputs.
    manifest: PathBuf,
    /// One non-negative weight per input, in manifest order, summing to 1.
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required_unless_present = "triangle",
        conflicts_with = "triangle"
    )]
    weights: Option<Vec<f32>>,
    /// Instead of one blend: a triangle of 3-way blends with this many rows (paper Fig. 11).
    #[arg(long)]
    triangle: Option<usize>,
    /// Image side in pixels (per blend).
    #[arg(long, default_value_t = 256)]
    size: usize,
    /// Kernel standard deviation in unit-cube units.
    #[arg(long, default_value_t = DEFAULT_SIGMA)]
    sigma: f32,
    /// Camera azimuth in degrees about the y axis (0: looking along -z, 90: along -x).
    #[arg(long, default_value_t = 60.0, allow_hyphen_values = true)]
    azimuth: f64,
    /// Camera elevation in degrees.
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    elevation: f64,
    /// Extinction per unit length and unit of value (a mesh's inside is about 1).
    #[arg(long, default_value_t = 60.0)]
    extinction: f32,
    /// Ray-marching step in kernel sigmas.
    #[arg(long, default_value_t = 0.75)]
    step: f32,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake render`: one blend, or a triangle of blends, ray-marched.
pub fn render(args: RenderArgs) -> Result<()> {
    let settings = RenderSettings {
        size: args.size,
        sigma: args.sigma,
        azimuth: args.azimuth,
        elevation: args.elevation,
        extinction: args.extinction,
        step: args.step,
    };
    let size = args.size;
    let bytes = match args.triangle {
        Some(rows) => memory::grid_bytes(3, rows, size, size),
        None => memory::image_bytes(size, size),
    };
    check_render(
        &args.manifest,
        bytes,
        || match args.triangle {
            Some(rows) => format!(
                "render --triangle {rows}: {} blends of {size}x{size} pixels",
                memory::grid_blends(3, rows)
            ),
            None => format!("render: a {size}x{size} image"),
        },
        "lower --triangle or --size",
    )?;
    let scene = Scene::open(&args.manifest, args.weights.as_deref())?;
    let img = match (&args.weights, args.triangle) {
        (Some(w), _) => {
            let maps = scene.maps()?;
            renderer::render(scene.proxy()?, &maps, w, &settings)?
        }
        (None, Some(steps)) => renderer::render_triangle(&scene.archives, steps, &settings)?,
        (None, None) => bail!("give --weights a,b,.. or --triangle STEPS"),
    };
    write_image(&args.output, &img)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct SliceArgs {
    /// Manifest of 3D inputs.
    manifest: PathBuf,
    /// One non-negative weight per input, in manifest order, summing to 1.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    weights: Vec<f32>,
    /// The axis the plane is perpendicular to.
    #[arg(long, value_enum, default_value_t = Axis::Z)]
    axis: Axis,
    /// Position of the plane along the axis, in [0, 1].
    #[arg(long, default_value_t = 0.5)]
    at: f32,
    /// Image side in pixels.
    #[arg(long, default_value_t = 256)]
    size: usize,
    /// Kernel standard deviation in unit-cube units.
    #[arg(long, default_value_t = DEFAULT_SIGMA)]
    sigma: f32,
    /// Grey = value × scale (default: the slice's largest value is white).
    #[arg(long)]
    scale: Option<f32>,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake slice`: one blend on an axis-aligned plane, grey.
pub fn slice(args: SliceArgs) -> Result<()> {
    let size = args.size;
    // The settings' own checks, before anything is baked (the renderer repeats them).
    if !(1..=8192).contains(&size) {
        bail!("--size {size}: the image side must be 1 to 8192 pixels");
    }
    if !(args.at.is_finite() && (0.0..=1.0).contains(&args.at)) {
        bail!("--at {}: the plane's position must be in [0, 1]", args.at);
    }
    check_render(
        &args.manifest,
        memory::image_bytes(size, size),
        || format!("slice: a {size}x{size} image"),
        "lower --size",
    )?;
    let scene = Scene::open(&args.manifest, Some(&args.weights))?;
    let maps = scene.maps()?;
    let settings = SliceSettings {
        axis: args.axis,
        at: args.at,
        size: args.size,
        sigma: args.sigma,
        scale: args.scale,
    };
    let img = renderer::slice(scene.proxy()?, &maps, &args.weights, &settings)?;
    write_image(&args.output, &img)?;
    Ok(())
}
