//! The `otbake` command line.

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use otbake::bake::{bake, BakeOptions, Status};
use otbake::imageio::write_image;
use otbake::manifest::Manifest;
use otbake::render::{render, render_grid, Archives, Method, RenderSettings};
use std::path::{Path, PathBuf};

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
    /// Reconstruction: one point query per pixel, or one splat of all points.
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
    Bake {
        /// Manifest files.
        #[arg(required = true)]
        manifests: Vec<PathBuf>,
        /// Rebuild even when archives are current.
        #[arg(long)]
        force: bool,
    },
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
    /// Describe an archive: header, sizes, keys, validation.
    Inspect {
        /// Archive file (.otb).
        archive: PathBuf,
    },
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

fn load_and_bake(path: &Path, force: bool, quiet: bool) -> Result<Manifest> {
    let m = Manifest::load(path)?;
    let report = bake(&m, &BakeOptions { force })?;
    if !quiet {
        for p in &report.products {
            let status = match p.status {
                Status::Built => "built ",
                Status::Cached => "cached",
            };
            eprintln!(
                "{status} {:<12} {:>8.2} s  {}  {}",
                p.name,
                p.seconds,
                p.path.display(),
                p.detail
            );
        }
    }
    Ok(m)
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Bake { manifests, force } => {
            for m in &manifests {
                load_and_bake(m, force, false)?;
            }
        }
        Command::Blend {
            manifest,
            weights,
            image,
            output,
        } => {
            let settings = image.settings()?;
            let m = load_and_bake(&manifest, false, true)?;
            let archives = Archives::load(&m)?;
            let maps = archives.maps()?;
            if weights.len() != maps.len() {
                bail!(
                    "--weights has {} values but {} has {} inputs ({}): give one weight per input",
                    weights.len(),
                    manifest.display(),
                    maps.len(),
                    m.inputs
                        .iter()
                        .map(|i| i.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
            let img = render(archives.proxy()?, &maps, &weights, &settings)?;
            write_image(&output, &img)?;
        }
        Command::Grid {
            manifest,
            steps,
            image,
            output,
        } => {
            let settings = image.settings()?;
            let m = load_and_bake(&manifest, false, true)?;
            let archives = Archives::load(&m)?;
            let img = render_grid(&archives, steps, &settings)?;
            write_image(&output, &img)?;
        }
        Command::Points {
            manifest,
            input,
            output,
        } => {
            let m = load_and_bake(&manifest, false, true)?;
            if m.input_index(&input).is_none() {
                bail!(
                    "--input {input:?} is not an input of {}: use one of {}",
                    manifest.display(),
                    m.inputs
                        .iter()
                        .map(|i| i.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
            let bytes = otbake::points::points_npy(&m, &input)?;
            otbake::fsio::write_atomic(&output, &bytes)?;
        }
        Command::Inspect { archive } => {
            let bytes = std::fs::read(&archive)
                .with_context(|| format!("cannot read {}", archive.display()))?;
            print!("{}", otbake::inspect::describe(&bytes));
            otbake::inspect::validate(&bytes)
                .with_context(|| format!("{} is not a valid archive", archive.display()))?;
        }
    }
    Ok(())
}
