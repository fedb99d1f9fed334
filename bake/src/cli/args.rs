//! The command line's top level: the subcommands, in the order `otbake --help` lists them.
//!
//! Each subcommand's flags live next to the function that runs it, in its family's module.

use super::{bake, bench, brdf, fit, image, volume};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "otbake",
    version,
    about = "Bake optimal-transport maps of appearance assets; blend them at run time."
)]
pub struct Cli {
    /// Memory budget (the help text, with the default for this process, is set in `main`).
    #[arg(long, global = true, value_name = "SIZE", value_parser = super::budget::parse)]
    pub memory: Option<u64>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Bake the proxy and every map a manifest declares (only what is not current).
    Bake(bake::BakeArgs),
    /// Hermetic single-product bake for build systems: reads only the manifest, the product's inputs
    /// and the proxy archive; writes only OUTPUT (untouched if already current).
    BakeOne(bake::BakeOneArgs),
    /// Print the whole bake as a build graph of `bake-one` actions (Ninja file, JSON or Bazel BUILD).
    Plan(bake::PlanArgs),
    /// Compress an archive with zstd for storage or transfer (the runtime reads uncompressed bytes).
    Pack(bake::PackArgs),
    /// Decompress a packed archive and validate it.
    Unpack(bake::UnpackArgs),
    /// Render one blend of a manifest's inputs as an image (bakes what is missing first).
    Blend(image::BlendArgs),
    /// Render a grid of blends: a row (2 inputs), a triangle (3) or a bilinear square (4).
    Grid(image::GridArgs),
    /// Render a texture whose blend weights vary per pixel: perlin:SCALE,SEED, zigzag, or a,b,..
    Texture(image::TextureArgs),
    /// Fit the weights whose blend is closest to a target asset (least squares over the simplex on
    /// the maps' displacement fields); print weights and residual, optionally render the blend.
    Fit(fit::FitArgs),
    /// Write an input's map as an n × 2d float32 .npy: proxy position, then mapped position (tree order).
    Points(image::PointsArgs),
    /// Render a θi slice of a BRDF blend on the unit disk (light from the right; paper Fig. 14 right).
    BrdfSlice(brdf::SliceArgs),
    /// Render spheres of BRDF blends: a bilinear square for 4 inputs (paper Fig. 14 left).
    BrdfSpheres(brdf::SpheresArgs),
    /// Export one BRDF blend as a MERL .binary file.
    BrdfExport(brdf::ExportArgs),
    /// Write one blend of 3D inputs as a Mitsuba .vol grid (res³ point queries, values in the inputs' units).
    Volume(volume::VolumeArgs),
    /// Ray-march a blend of 3D inputs (emission-absorption through point queries), or a triangle of 3-way blends.
    Render(volume::RenderArgs),
    /// Render a blend of 3D inputs on an axis-aligned plane as a grey image.
    Slice(volume::SliceArgs),
    /// Describe an archive: header, sizes, keys, validation.
    Inspect(bake::InspectArgs),
    /// Benchmark the solvers (speed against accuracy) on standard cases: Gaussian → Gaussian
    /// (closed form), Gaussian → each shape, uniform → three blobs. Writes bench.csv, bench.png
    /// (time against L2-UVP) and summary.md into --out.
    Bench(bench::BenchArgs),
}
