//! The `otbake` command line.

mod cli;

use anyhow::{bail, Result};
use clap::{Parser, Subcommand};
use cli::scene::{input_names, Open, Scene};
use otbake::render::imageio::write_image;
use otbake::render::{render, render_grid, Method, RenderSettings};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "otbake",
    version,
    about = "Bake optimal-transport maps of appearance assets; blend them at run time."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args, Clone, Copy)]
struct ImageArgs {
    /// Image size WxH in pixels (per cell for `grid`).
    #[arg(long, default_value = "256x256", value_parser = parse_size)]
    size: (usize, usize),
    /// Reconstruction: one point query per pixel (exact), or one splat of all points (faster;
    /// separable kernel weights, equal to the queries within a stated tolerance).
    #[arg(long, value_enum, default_value_t = Method::Query)]
    method: Method,
    /// Gaussian kernel standard deviation in pixels (truncated at 3 sigma).
    #[arg(long, default_value_t = 0.5)]
    sigma: f32,
}

impl ImageArgs {
    fn settings(&self) -> Result<RenderSettings> {
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

#[derive(Subcommand)]
enum Command {
    /// Bake the proxy and every map a manifest declares (only what is not current).
    Bake(cli::bake::BakeArgs),
    /// Hermetic single-product bake for build systems: reads only the manifest, the product's inputs
    /// and the proxy archive; writes only OUTPUT (untouched if already current).
    BakeOne(cli::bake::BakeOneArgs),
    /// Print the whole bake as a build graph of `bake-one` actions (Ninja file or JSON).
    Plan(cli::bake::PlanArgs),
    /// Compress an archive with zstd for storage or transfer (the runtime reads uncompressed bytes).
    Pack(cli::bake::PackArgs),
    /// Decompress a packed archive and validate it.
    Unpack(cli::bake::UnpackArgs),
    /// Render one blend of a manifest's inputs as an image (bakes what is missing first).
    Blend {
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
    },
    /// Render a grid of blends: a row (2 inputs), a triangle (3) or a bilinear square (4).
    Grid {
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
    },
    /// Render a texture whose blend weights vary per pixel: perlin:SCALE,SEED, zigzag, or a,b,..
    Texture {
        /// Manifest file.
        manifest: PathBuf,
        /// Weight field: `perlin:SCALE,SEED`, `zigzag`, or constant weights `a,b,..`.
        #[arg(long, value_parser = otbake::render::texture::WeightField::parse)]
        weights: otbake::render::texture::WeightField,
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
    },
    /// Write an input's map as an n × 2d float32 .npy: proxy position, then mapped position (tree order).
    Points {
        /// Manifest file.
        manifest: PathBuf,
        /// Input name.
        #[arg(long)]
        input: String,
        /// Output .npy file.
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Render a θi slice of a BRDF blend on the unit disk (light from the right; paper Fig. 14 right).
    BrdfSlice {
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
        /// A fixed kernel of this standard deviation in unit-cube units (e.g. 0.02), instead of
        /// the default density-adaptive kernel.
        #[arg(long, conflicts_with = "scale")]
        sigma: Option<f32>,
        /// Width of the adaptive kernel in local spacings of the blend.
        #[arg(long, default_value_t = otbake::render::brdf::eval::DEFAULT_ADAPTIVE.scale)]
        scale: f32,
        /// Exposure (default: 99th percentile of the disk's luminance → 1).
        #[arg(long)]
        exposure: Option<f32>,
        /// Output image (.png or .exr).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Render spheres of BRDF blends: a bilinear square for 4 inputs (paper Fig. 14 left).
    BrdfSpheres {
        /// Manifest of BRDF inputs.
        manifest: PathBuf,
        /// Spheres per side.
        #[arg(long, default_value_t = 5)]
        steps: usize,
        /// Sphere diameter in pixels.
        #[arg(long, default_value_t = 64)]
        size: usize,
        /// A fixed kernel of this standard deviation in unit-cube units (e.g. 0.02), instead of
        /// the default density-adaptive kernel.
        #[arg(long, conflicts_with = "scale")]
        sigma: Option<f32>,
        /// Width of the adaptive kernel in local spacings of the blend.
        #[arg(long, default_value_t = otbake::render::brdf::eval::DEFAULT_ADAPTIVE.scale)]
        scale: f32,
        /// Output image (.png or .exr).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Export one BRDF blend as a MERL .binary file.
    BrdfExport {
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
        /// A fixed kernel of this standard deviation in unit-cube units (e.g. 0.02), instead of
        /// the default density-adaptive kernel.
        #[arg(long, conflicts_with = "scale")]
        sigma: Option<f32>,
        /// Width of the adaptive kernel in local spacings of the blend.
        #[arg(long, default_value_t = otbake::render::brdf::eval::DEFAULT_ADAPTIVE.scale)]
        scale: f32,
        /// Output MERL file (.binary).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Write one blend of 3D inputs as a Mitsuba .vol grid (res³ point queries, values in the inputs' units).
    Volume {
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
        #[arg(long, default_value_t = otbake::render::volume::DEFAULT_SIGMA)]
        sigma: f32,
        /// Output grid (.vol).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Ray-march a blend of 3D inputs (emission-absorption through point queries), or a triangle of 3-way blends.
    Render {
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
        #[arg(long, default_value_t = otbake::render::volume::DEFAULT_SIGMA)]
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
    },
    /// Render a blend of 3D inputs on an axis-aligned plane as a grey image.
    Slice {
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
        #[arg(long, value_enum, default_value_t = otbake::render::volume::Axis::Z)]
        axis: otbake::render::volume::Axis,
        /// Position of the plane along the axis, in [0, 1].
        #[arg(long, default_value_t = 0.5)]
        at: f32,
        /// Image side in pixels.
        #[arg(long, default_value_t = 256)]
        size: usize,
        /// Kernel standard deviation in unit-cube units.
        #[arg(long, default_value_t = otbake::render::volume::DEFAULT_SIGMA)]
        sigma: f32,
        /// Grey = value × scale (default: the slice's largest value is white).
        #[arg(long)]
        scale: Option<f32>,
        /// Output image (.png or .exr).
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Describe an archive: header, sizes, keys, validation.
    Inspect(cli::bake::InspectArgs),
    /// Benchmark the solvers (speed against accuracy) on standard cases: Gaussian → Gaussian
    /// (closed form), Gaussian → each shape, uniform → three blobs. Writes bench.csv, bench.png
    /// (time against L2-UVP) and summary.md into --out.
    Bench(cli::bench::BenchArgs),
}

fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("{s:?}: expected WxH, e.g. 256x256"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|&v| (1..=16384).contains(&v))
    };
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("{s:?}: width and height must be 1 to 16384")),
    }
}

fn main() {
    if let Err(e) = run(Cli::parse()) {
        eprintln!("error: {e}");
        let mut source = e.source();
        while let Some(s) = source {
            // thiserror sources are usually already part of the message; print only new text.
            let text = s.to_string();
            if !e.to_string().contains(&text) {
                eprintln!("  caused by: {text}");
            }
            source = s.source();
        }
        std::process::exit(1);
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Bake(args) => cli::bake::bake(args)?,
        Command::BakeOne(args) => cli::bake::bake_one(args)?,
        Command::Plan(args) => cli::bake::plan(args)?,
        Command::Pack(args) => cli::bake::pack(args)?,
        Command::Unpack(args) => cli::bake::unpack(args)?,
        Command::Blend {
            manifest,
            weights,
            image,
            output,
        } => {
            let settings = image.settings()?;
            let scene = Scene::open(&manifest, Some(&weights))?;
            let maps = scene.maps()?;
            let img = render(scene.proxy()?, &maps, &weights, &settings)?;
            write_image(&output, &img)?;
        }
        Command::Grid {
            manifest,
            steps,
            image,
            output,
        } => {
            let settings = image.settings()?;
            let scene = Scene::open(&manifest, None)?;
            let archives = &scene.archives;
            let img = render_grid(archives, steps, &settings)?;
            write_image(&output, &img)?;
        }
        Command::Texture {
            manifest,
            weights,
            size,
            sigma,
            lod,
            output,
        } => {
            if !(sigma.is_finite() && sigma > 0.0) {
                bail!("--sigma {sigma}: use a positive number of pixels");
            }
            let scene = Scene::open(&manifest, None)?;
            let archives = &scene.archives;
            let maps = archives.maps()?;
            if let otbake::render::texture::WeightField::Constant(w) = &weights {
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
                Some(r) => otbake::render::texture::render_lod(
                    archives.proxy()?,
                    &maps,
                    &weights,
                    size.0,
                    size.1,
                    r,
                )?,
                None => otbake::render::texture::render_texture(
                    archives.proxy()?,
                    &maps,
                    &weights,
                    size.0,
                    size.1,
                    sigma,
                )?,
            };
            write_image(&output, &img)?;
        }
        Command::Points {
            manifest,
            input,
            output,
        } => {
            let m = Scene::bake(&manifest, &Open::default())?;
            if m.input_index(&input).is_none() {
                bail!(
                    "--input {input:?} is not an input of {}: use one of {}",
                    manifest.display(),
                    input_names(&m)
                );
            }
            let bytes = otbake::render::points::points_npy(&m, &input)?;
            otbake::fsio::write_atomic(&output, &bytes)?;
        }
        Command::BrdfSlice {
            manifest,
            weights,
            theta_i,
            size,
            sigma,
            scale,
            exposure,
            output,
        } => {
            if !(0.0..90.0).contains(&theta_i) || !(1..=8192).contains(&size) {
                bail!("--theta-i must be in [0, 90) degrees and --size 1 to 8192");
            }
            let scene = Scene::open(&manifest, Some(&weights))?;
            let maps = scene.maps()?;
            let b = brdf_blend(scene.proxy()?, &maps, sigma, scale)?;
            let img =
                otbake::render::brdf::slice(&b, &weights, theta_i.to_radians(), size, exposure)?;
            write_image(&output, &img)?;
        }
        Command::BrdfSpheres {
            manifest,
            steps,
            size,
            sigma,
            scale,
            output,
        } => {
            if !(2..=4096).contains(&size) {
                bail!("--size {size}: use 2 to 4096 pixels");
            }
            let scene = Scene::open(&manifest, None)?;
            let archives = &scene.archives;
            let maps = archives.maps()?;
            let b = brdf_blend(scene.proxy()?, &maps, sigma, scale)?;
            let img = otbake::render::brdf::spheres(&b, steps, size, &Default::default())
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            write_image(&output, &img)?;
        }
        Command::BrdfExport {
            manifest,
            weights,
            sigma,
            scale,
            output,
        } => {
            let scene = Scene::open(&manifest, Some(&weights))?;
            let maps = scene.maps()?;
            let b = brdf_blend(scene.proxy()?, &maps, sigma, scale)?;
            otbake::render::brdf::export_merl(&b, &weights)?.write(&output)?;
        }
        Command::Volume {
            manifest,
            weights,
            res,
            sigma,
            output,
        } => {
            let scene = Scene::open(&manifest, Some(&weights))?;
            let maps = scene.maps()?;
            otbake::render::volume::export(scene.proxy()?, &maps, &weights, res, sigma)?
                .write(&output)?;
        }
        Command::Render {
            manifest,
            weights,
            triangle,
            size,
            sigma,
            azimuth,
            elevation,
            extinction,
            step,
            output,
        } => {
            let settings = otbake::render::volume::RenderSettings {
                size,
                sigma,
                azimuth,
                elevation,
                extinction,
                step,
            };
            let scene = Scene::open(&manifest, weights.as_deref())?;
            let archives = &scene.archives;
            let img = match (weights, triangle) {
                (Some(w), _) => {
                    let maps = archives.maps()?;
                    otbake::render::volume::render(archives.proxy()?, &maps, &w, &settings)?
                }
                (None, Some(steps)) => {
                    otbake::render::volume::render_triangle(archives, steps, &settings)?
                }
                (None, None) => bail!("give --weights a,b,.. or --triangle STEPS"),
            };
            write_image(&output, &img)?;
        }
        Command::Slice {
            manifest,
            weights,
            axis,
            at,
            size,
            sigma,
            scale,
            output,
        } => {
            let scene = Scene::open(&manifest, Some(&weights))?;
            let maps = scene.maps()?;
            let settings = otbake::render::volume::SliceSettings {
                axis,
                at,
                size,
                sigma,
                scale,
            };
            let img = otbake::render::volume::slice(scene.proxy()?, &maps, &weights, &settings)?;
            write_image(&output, &img)?;
        }
        Command::Inspect(args) => cli::bake::inspect(args)?,
        Command::Bench(args) => cli::bench::bench(args)?,
    }
    Ok(())
}

/// The BRDF commands' blend: a fixed kernel if `--sigma` is given, else the adaptive one `--scale`
/// spacings wide (which needs maps baked with spacings).
fn brdf_blend<'a, 'm>(
    proxy: otbake_runtime::Proxy<'a>,
    maps: &'m [otbake_runtime::Map<'a>],
    sigma: Option<f32>,
    scale: f32,
) -> Result<otbake::render::brdf::eval::BrdfBlend<'a, 'm>> {
    use otbake::render::brdf::eval::{BrdfBlend, BrdfBlendError, BrdfKernel, DEFAULT_ADAPTIVE};
    let kernel = match sigma {
        Some(sigma) => BrdfKernel::Fixed(otbake_runtime::Kernel { sigma }),
        None => BrdfKernel::Adaptive(otbake_runtime::AdaptiveKernel {
            scale,
            ..DEFAULT_ADAPTIVE
        }),
    };
    match BrdfBlend::with_kernel(proxy, maps, kernel) {
        Err(BrdfBlendError::Runtime(otbake_runtime::Error::MissingAttribute {
            map,
            attribute: "spacings",
        })) => bail!(
            "map {map} stores no spacings, which the default (density-adaptive) kernel needs: rebake with `spacings = true` in `[storage]`, or pass --sigma 0.02 for a fixed kernel"
        ),
        Err(BrdfBlendError::Runtime(otbake_runtime::Error::BadSigma)) => bail!(
            "--sigma must be a positive number (e.g. 0.02) and --scale a positive number of spacings (e.g. 2)"
        ),
        other => Ok(other?),
    }
}
