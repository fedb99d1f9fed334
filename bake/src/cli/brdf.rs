//! BRDF blends: `brdf-slice`, `brdf-spheres`, `brdf-export`.

use super::budget::check_render;
use super::scene::Scene;
use anyhow::{bail, Result};
use otbake::render::brdf::eval::{BrdfBlend, BrdfBlendError, BrdfKernel, DEFAULT_ADAPTIVE};
use otbake::render::imageio::write_image;
use otbake::render::memory;
use otbake_runtime::{AdaptiveKernel, Error as RuntimeError, Kernel, Map, Proxy};
use std::path::PathBuf;

/// The kernel flags every BRDF command shares.
#[derive(clap::Args)]
pub struct KernelArgs {
    /// A fixed kernel of this standard deviation in unit-cube units (e.g. 0.02), instead of
    /// the default density-adaptive kernel.
    #[arg(long, conflicts_with = "scale")]
    sigma: Option<f32>,
    /// Width of the adaptive kernel in local spacings of the blend.
    #[arg(long, default_value_t = DEFAULT_ADAPTIVE.scale)]
    scale: f32,
}

impl KernelArgs {
    /// The BRDF commands' blend: a fixed kernel if `--sigma` is given, else the adaptive one
    /// `--scale` spacings wide (which needs maps baked with spacings).
    fn blend<'a, 'm>(&self, proxy: Proxy<'a>, maps: &'m [Map<'a>]) -> Result<BrdfBlend<'a, 'm>> {
        let kernel = match self.sigma {
            Some(sigma) => BrdfKernel::Fixed(Kernel { sigma }),
            None => BrdfKernel::Adaptive(AdaptiveKernel {
                scale: self.scale,
                ..DEFAULT_ADAPTIVE
            }),
        };
        match BrdfBlend::with_kernel(proxy, maps, kernel) {
            Err(BrdfBlendError::Runtime(RuntimeError::MissingAttribute {
                map,
                attribute: "spacings",
            })) => bail!(
                "map {map} stores no spacings, which the default (density-adaptive) kernel needs: rebake with `spacings = true` in `[storage]`, or pass --sigma 0.02 for a fixed kernel"
            ),
            Err(BrdfBlendError::Runtime(RuntimeError::BadSigma)) => bail!(
                "--sigma must be a positive number (e.g. 0.02) and --scale a positive number of spacings (e.g. 2)"
            ),
            other => Ok(other?),
        }
    }
}

#[derive(clap::Args)]
pub struct SliceArgs {
    /// Manifest of BRDF inputs.
    manifest: PathBuf,
    /// One non-negative weight per input, in manifest order, summing to 1.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    weights: Vec<f32>,
    /// Incident polar angle in degrees.
    #[arg(long, default_value_t = 45.0)]
    theta_i: f64,
    /// Image side in pixels.
    #[arg(long, default_value_t = 256)]
    size: usize,
    #[command(flatten)]
    kernel: KernelArgs,
    /// Exposure (default: 99th percentile of the disk's luminance → 1).
    #[arg(long)]
    exposure: Option<f32>,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake brdf-slice`: one θi slice of a blend on the unit disk.
pub fn slice(args: SliceArgs) -> Result<()> {
    if !(1..=8192).contains(&args.size) {
        bail!(
            "--size {}: the image side must be 1 to 8192 pixels",
            args.size
        );
    }
    if !(0.0..90.0).contains(&args.theta_i) {
        bail!(
            "--theta-i {}: the incident angle must be in [0, 90) degrees",
            args.theta_i
        );
    }
    let size = args.size;
    check_render(
        &args.manifest,
        memory::image_bytes(size, size),
        || format!("brdf-slice: a {size}x{size} image"),
        "lower --size",
    )?;
    let scene = Scene::open(&args.manifest, Some(&args.weights))?;
    let maps = scene.maps()?;
    let b = args.kernel.blend(scene.proxy()?, &maps)?;
    let theta_i = args.theta_i.to_radians();
    let img = otbake::render::brdf::slice(&b, &args.weights, theta_i, args.size, args.exposure)?;
    write_image(&args.output, &img)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct SpheresArgs {
    /// Manifest of BRDF inputs.
    manifest: PathBuf,
    /// Spheres per side.
    #[arg(long, default_value_t = 5)]
    steps: usize,
    /// Sphere diameter in pixels.
    #[arg(long, default_value_t = 64)]
    size: usize,
    #[command(flatten)]
    kernel: KernelArgs,
    /// Output image (.png or .exr).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake brdf-spheres`: a square (or row, triangle) of shaded spheres.
pub fn spheres(args: SpheresArgs) -> Result<()> {
    let size = args.size;
    if !(2..=4096).contains(&size) {
        bail!("--size {size}: use 2 to 4096 pixels");
    }
    let steps = args.steps;
    check_render(
        &args.manifest,
        memory::grid_bytes(4, steps, size, size),
        || {
            format!(
                "brdf-spheres: up to {} spheres of {size} pixels (--steps {steps})",
                memory::grid_blends(4, steps)
            )
        },
        "lower --steps or --size",
    )?;
    let scene = Scene::open(&args.manifest, None)?;
    let maps = scene.maps()?;
    let b = args.kernel.blend(scene.proxy()?, &maps)?;
    let img = otbake::render::brdf::spheres(&b, args.steps, size, &Default::default())
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    write_image(&args.output, &img)?;
    Ok(())
}

#[derive(clap::Args)]
pub struct ExportArgs {
    /// Manifest of BRDF inputs.
    manifest: PathBuf,
    /// One non-negative weight per input, in manifest order, summing to 1.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_hyphen_values = true
    )]
    weights: Vec<f32>,
    #[command(flatten)]
    kernel: KernelArgs,
    /// Output MERL file (.binary).
    #[arg(short, long)]
    output: PathBuf,
}

/// `otbake brdf-export`: one blend tabulated as a MERL file.
pub fn export(args: ExportArgs) -> Result<()> {
    let scene = Scene::open(&args.manifest, Some(&args.weights))?;
    let maps = scene.maps()?;
    let b = args.kernel.blend(scene.proxy()?, &maps)?;
    otbake::render::brdf::export_merl(&b, &args.weights)?.write(&args.output)?;
    Ok(())
}
