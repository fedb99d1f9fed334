//! `otbake fit`: the weights whose blend is closest to a target asset ([`otbake::fit`]).

use super::budget::check_render;
use super::image::ImageArgs;
use super::scene::{Open, Scene};
use anyhow::{Context, Result};
use otbake::fit::{fit as fit_weights, FitTarget};
use otbake::input::DensityChannel;
use otbake::render::imageio::write_image;
use otbake::render::{memory, render};
use otbake::solve::Wrap;
use otbake::Archives;
use std::path::PathBuf;

/// The target's density channel (default: the manifest inputs').
#[derive(Clone, Copy, clap::ValueEnum)]
enum Density {
    Luminance,
    Inverted,
    Alpha,
}

/// The target's domain (default: the manifest's).
#[derive(Clone, Copy, clap::ValueEnum)]
enum WrapArg {
    Clamp,
    Periodic,
}

#[derive(clap::Args)]
pub struct FitArgs {
    /// Manifest file.
    manifest: PathBuf,
    /// The target asset, read like the manifest's inputs (e.g. an image `otbake blend` wrote).
    #[arg(long)]
    target: PathBuf,
    /// The target's density channel (default: the inputs').
    #[arg(long, value_enum)]
    density: Option<Density>,
    /// The target's domain (default: the manifest's; another one is an error).
    #[arg(long, value_enum)]
    wrap: Option<WrapArg>,
    /// Write `{"inputs", "warnings", "weights", "residual", "scale", "relative_residual"}` here.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Also render the fitted blend to this image (.png or .exr; 2D manifests).
    #[arg(long)]
    render: Option<PathBuf>,
    #[command(flatten)]
    image: ImageArgs,
}

/// Bakes what is missing, fits, prints the weights and residual, writes the JSON and the render.
pub fn fit(args: FitArgs) -> Result<()> {
    // The render's size is known now: refuse it before baking and fitting, not after.
    let settings = match &args.render {
        Some(_) => {
            let (w, h) = args.image.size;
            check_render(
                &args.manifest,
                memory::image_bytes(w, h),
                || format!("fit --render: a {w}x{h} image"),
                "lower --size",
            )?;
            Some(args.image.settings()?)
        }
        None => None,
    };
    let m = Scene::bake(&args.manifest, &Open::default())?;
    let archives = Archives::load(&m)?;
    let target = FitTarget {
        path: &args.target,
        density: args.density.map(|d| match d {
            Density::Luminance => DensityChannel::Luminance,
            Density::Inverted => DensityChannel::Inverted,
            Density::Alpha => DensityChannel::Alpha,
        }),
        wrap: args.wrap.map(|w| match w {
            WrapArg::Clamp => Wrap::Clamp,
            WrapArg::Periodic => Wrap::Periodic,
        }),
    };
    let fitted = fit_weights(&m, &archives, &target)?;
    for w in &fitted.warnings {
        eprintln!("warning: target {}: {w}", args.target.display());
    }
    for (input, w) in m.inputs.iter().zip(&fitted.weights) {
        println!("{} {w:.6}", input.name);
    }
    println!(
        "residual {:.6e} (RMS, unit-cube units) = {:.4} of the inputs' spread {:.6e}",
        fitted.residual, fitted.relative_residual, fitted.scale
    );
    if let Some(out) = &args.output {
        let json = serde_json::json!({
            "inputs": m.inputs.iter().map(|i| i.name.as_str()).collect::<Vec<_>>(),
            "warnings": fitted.warnings,
            "weights": fitted.weights,
            "residual": fitted.residual,
            "scale": fitted.scale,
            "relative_residual": fitted.relative_residual,
        });
        let text = serde_json::to_string_pretty(&json)? + "\n";
        otbake::fsio::write_atomic(out, text.as_bytes())
            .with_context(|| format!("writing {}", out.display()))?;
    }
    if let (Some(out), Some(settings)) = (&args.render, settings) {
        // On the simplex in f64; f32 rounding can leave the sum a few ulps off 1.
        let total: f64 = fitted.weights.iter().sum();
        let w: Vec<f32> = fitted.weights.iter().map(|w| (w / total) as f32).collect();
        let maps = archives.maps()?;
        let img = render(archives.proxy()?, &maps, &w, &settings)?;
        write_image(out, &img)?;
    }
    Ok(())
}
